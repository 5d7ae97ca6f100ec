//! Run time against the number of modes (GitHub issue 10, item 5), for a
//! rigid stop and a spring stop, natively:
//!
//! - `rigid`: S2, the pinned beam of VSM12 (Vyasarayani, Sandhu & McPhee
//!   2012) at F = 72, Omega = 0.7 pi^2, d = 1.2, restitution 0.7 with
//!   eps = 1e-3, 60 forcing periods: impacts, chatter and sticking (the
//!   sticking phases run on the coupled path);
//! - `spring`: `scenes/spring_stop_hard.json` (RMTM's cantilever with a
//!   hard linear spring stop, kappa = 100), 60 forcing periods: every
//!   contact phase runs on the coupled path.
//!
//! `cargo run --release --example scaling -- [--csv FILE] [N ...]` prints,
//! per case and N, the model build time (modes, projections), the run time
//! (minimum over repeats of `Simulation::new` + `advance_to`), the event
//! search points, the events and the contacts. `python/beamstop_tools/report/scaling.py`
//! plots the CSV.
use std::f64::consts::PI;
use std::io::Write;
use std::time::Instant;

use beamstop::kinds::modal::interface::ParamKey;
use beamstop::kinds::modal::scene::StructureSpec;
use beamstop::kinds::modal::{model::Model, scene::Scene, sim::Simulation};

fn scene_text(file: &str) -> String {
    let path = format!("{}/scenes/{file}", env!("CARGO_MANIFEST_DIR"));
    std::fs::read_to_string(&path).expect("scene file")
}

fn scene(file: &str) -> Scene {
    Scene::from_json(&scene_text(file)).expect("valid scene")
}

/// The case's scene at `n` modes and its end time.
fn case(name: &str, n: usize) -> (Scene, f64) {
    let (mut scene, t_end) = match name {
        "rigid" => {
            let mut s = scene("pinned_beam.json");
            ParamKey::LoadAmplitude(0).set(&mut s, 72.0);
            ParamKey::LoadOmega(0).set(&mut s, 0.7 * PI * PI);
            ParamKey::StopGap(0).set(&mut s, 1.2);
            ParamKey::Law(0, 1).set(&mut s, 1e-3);
            (s, 60.0 * 2.0 * PI / (0.7 * PI * PI))
        }
        "spring" => {
            let s = scene("spring_stop_hard.json");
            let json: serde_json::Value = serde_json::from_str(&scene_text("spring_stop_hard.json")).expect("JSON");
            let omega = json["loads"][0]["omega"].as_f64().expect("a harmonic load");
            (s, 60.0 * 2.0 * PI / omega)
        }
        other => panic!("unknown case {other}"),
    };
    if let StructureSpec::Beam { modes, .. } = &mut scene.structure {
        *modes = n;
    }
    // A measurement, not a co-simulation step: no work cap.
    scene.solver.max_probes_per_step = Some(u64::MAX / 2);
    scene.solver.max_events_per_step = u64::MAX / 2;
    (scene, t_end)
}

fn main() {
    let mut args = std::env::args().skip(1);
    let mut csv: Option<std::fs::File> = None;
    let mut ns = Vec::new();
    while let Some(a) = args.next() {
        if a == "--csv" {
            let path = args.next().expect("--csv FILE");
            csv = Some(std::fs::File::create(&path).expect("writable CSV"));
        } else {
            ns.push(a.parse::<usize>().unwrap_or_else(|_| panic!("not a mode count: {a}")));
        }
    }
    if ns.is_empty() {
        ns = vec![4, 8, 16, 32, 64, 128, 256, 500];
    }
    if let Some(f) = csv.as_mut() {
        writeln!(f, "case,modes,build_s,run_s,first_s,probes,events,contacts").unwrap();
    }
    for &n in &ns {
        for name in ["rigid", "spring"] {
            let (scene, t_end) = case(name, n);
            let t0 = Instant::now();
            let model = Model::build(&scene).expect("model");
            let build = t0.elapsed().as_secs_f64();
            let mut best = f64::INFINITY;
            let mut first = None;
            let mut spent = 0.0;
            let mut result = None;
            // At least 3 repeats and 0.3 s, at most 1 repeat past 3 s.
            while result.is_none() || (spent < 0.3 || result.as_ref().map_or(0, |(r, _)| *r) < 3) && best < 3.0 {
                let t0 = Instant::now();
                let mut sim = Simulation::new(model.clone(), 0.0).expect("simulation");
                sim.set_event_recording(false);
                sim.advance_to(t_end).expect("run");
                let dt = t0.elapsed().as_secs_f64();
                best = best.min(dt);
                // The first run also decomposes the contact phases' systems,
                // which the model then keeps for its later simulations.
                first.get_or_insert(dt);
                spent += dt;
                let contacts: u64 = sim.state().stops.iter().map(|s| s.impacts).sum();
                let reps = result.as_ref().map_or(0, |(r, _)| *r) + 1;
                result = Some((reps, (sim.stats(), contacts)));
            }
            let (_, (stats, contacts)) = result.expect("one run");
            let first = first.expect("one run");
            println!(
                "{name:6} N={n:4}  build {:9.2} ms  run {:10.3} ms  first run {:10.3} ms  probes {:7}  events {:5}  contacts {contacts:5}  us/probe {:8.3}",
                build * 1e3,
                best * 1e3,
                first * 1e3,
                stats.probes,
                stats.events,
                best * 1e6 / stats.probes.max(1) as f64
            );
            if let Some(f) = csv.as_mut() {
                writeln!(f, "{name},{n},{build:.6e},{best:.6e},{first:.6e},{},{},{contacts}", stats.probes, stats.events).unwrap();
            }
        }
    }
}
