//! Speed, measured with criterion (`cargo bench -p beamstop_bench`):
//! - VSM12's Figure 10 regime (F = 72, omega = 0.7 pi^2, d = 1.2, R = 0.7,
//!   zeta = 0.05, eps = 1e-3) over 60 forcing periods, natively;
//! - the Figure 4 scene (chatter and sticking) over 20 time units;
//! - one fmi2DoStep without an event, through the exported C functions.

use std::f64::consts::PI;
use std::ffi::CString;

use beamstop::fmi2::api::*;
use beamstop::fmi2::types::*;
use beamstop::kinds::modal::interface::ParamKey;
use beamstop::kinds::modal::{model::Model, scene::Scene, sim::Simulation};
use criterion::{criterion_group, criterion_main, Criterion};

fn pinned() -> Scene {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/pinned_beam.json")).unwrap();
    Scene::from_json(&text).unwrap()
}

fn figure10() -> Scene {
    let mut s = pinned();
    ParamKey::LoadAmplitude(0).set(&mut s, 72.0);
    ParamKey::LoadOmega(0).set(&mut s, 0.7 * PI * PI);
    ParamKey::StopGap(0).set(&mut s, 1.2);
    ParamKey::Law(0, 1).set(&mut s, 1e-3);
    s
}

fn run(model: &Model, t_end: f64) -> u64 {
    let mut sim = Simulation::new(model.clone(), 0.0).unwrap();
    sim.set_event_recording(false);
    sim.advance_to(t_end).unwrap();
    sim.state().stops[0].impacts
}

fn native(c: &mut Criterion) {
    let fig10 = Model::build(&figure10()).unwrap();
    let periods60 = 60.0 * 2.0 * PI / (0.7 * PI * PI);
    c.bench_function("figure10_60_periods", |b| b.iter(|| run(&fig10, periods60)));
    let fig4 = Model::build(&pinned()).unwrap();
    c.bench_function("figure4_20_time_units", |b| b.iter(|| run(&fig4, 20.0)));
}

/// A logger that drops every message (defined without the variadic tail,
/// which stable Rust cannot define; the extra arguments are ignored).
unsafe extern "C" fn quiet(_: fmi2ComponentEnvironment, _: fmi2String, _: fmi2Status, _: fmi2String, _: fmi2String) {}

fn do_step(c: &mut Criterion) {
    // A stop far away (the largest gap a scene allows; the static
    // deflection is below 1): no event ever, so this times the step itself.
    let mut scene = pinned();
    ParamKey::StopGap(0).set(&mut scene, 1e3);
    let dir = std::env::temp_dir().join(format!("beamstop-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("scene.json"), scene.canonical_json()).unwrap();
    let name = CString::new("bench").unwrap();
    let guid = CString::new(scene.guid()).unwrap();
    let uri = CString::new(format!("file://{}", dir.display())).unwrap();
    let callbacks = fmi2CallbackFunctions {
        // SAFETY: a C function ignoring trailing variadic arguments.
        logger: unsafe { std::mem::transmute::<unsafe extern "C" fn(_, _, _, _, _), fmi2CallbackLogger>(quiet) },
        allocateMemory: None,
        freeMemory: None,
        stepFinished: None,
        componentEnvironment: std::ptr::null_mut(),
    };
    unsafe {
        let inst = fmi2Instantiate(name.as_ptr(), FMI2_CO_SIMULATION, guid.as_ptr(), uri.as_ptr(), &callbacks, 0, 0);
        assert!(!inst.is_null());
        assert_eq!(fmi2SetupExperiment(inst, 0, 0.0, 0.0, 0, 0.0), 0);
        assert_eq!(fmi2EnterInitializationMode(inst), 0);
        assert_eq!(fmi2ExitInitializationMode(inst), 0);
        let mut t = 0.0;
        let h = 1e-3;
        c.bench_function("fmi2DoStep_without_event", |b| {
            b.iter(|| {
                assert_eq!(fmi2DoStep(inst, t, h, 1), 0);
                t += h;
            })
        });
        fmi2FreeInstance(inst);
    }
    let _ = std::fs::remove_dir_all(dir);
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).measurement_time(std::time::Duration::from_secs(3));
    targets = native, do_step
}
criterion_main!(benches);
