//! A loop of runs to profile: S2 (VSM12's Figure 10 regime, 60 forcing
//! periods) or S3 (the Figure 4 scene, 20 time units) at N modes, `reps`
//! times, printing the event-search points of all runs. Not a benchmark
//! (criterion and `examples/rigid_peer.rs` time things); it gives `perf`
//! and `valgrind --tool=callgrind` a steady workload:
//!
//! `cargo run --release --example profile_loop -- S3 4 300 [event_tolerance]`
//! `cargo run --release --example profile_loop -- scenes/X.json N reps 0 [t_end]`
//! (any modal scene file at N modes, to t_end or its experiment's stop;
//! `FRESH=1`: the model built for every run, as a new FMU instance has it)
//! `valgrind --tool=callgrind target/release/examples/profile_loop S3 4 20`
//! (instructions per run: the difference between 20 and 0 runs, over 20).

use std::f64::consts::PI;

use beamstop::kinds::modal::interface::ParamKey;
use beamstop::kinds::modal::scene::StructureSpec;
use beamstop::kinds::modal::{model::Model, scene::Scene, sim::Simulation};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let which = args.get(1).map_or("S3", String::as_str);
    let modes: usize = args.get(2).map_or(4, |a| a.parse().expect("N, a number of modes"));
    let reps: usize = args.get(3).map_or(100, |a| a.parse().expect("reps, a number of runs"));
    let tolerance: f64 = args.get(4).map_or(0.0, |a| a.parse().expect("event_tolerance, a number"));
    let path = if which.ends_with(".json") {
        which.to_string()
    } else {
        concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/pinned_beam.json").to_string()
    };
    let text = std::fs::read_to_string(&path).expect("a scene file");
    let mut scene = Scene::from_json(&text).expect("a valid scene");
    if let StructureSpec::Beam { modes: m, .. } = &mut scene.structure {
        *m = modes;
    }
    let t_end = match which {
        file if file.ends_with(".json") => args.get(5).map_or(scene.experiment.stop, |a| a.parse().expect("t_end, a time")),
        "S2" => {
            ParamKey::LoadAmplitude(0).set(&mut scene, 72.0);
            ParamKey::LoadOmega(0).set(&mut scene, 0.7 * PI * PI);
            ParamKey::StopGap(0).set(&mut scene, 1.2);
            ParamKey::Law(0, 1).set(&mut scene, 1e-3);
            60.0 * 2.0 * PI / (0.7 * PI * PI)
        }
        "S3" => 20.0,
        other => panic!("scene {other}: S2 or S3"),
    };
    scene.solver.max_probes_per_step = Some(u64::MAX / 2);
    scene.solver.event_tolerance = tolerance;
    let model = Model::build(&scene).expect("model");
    let mut probes = 0;
    let fresh = std::env::var("FRESH").is_ok();
    for _ in 0..reps {
        let model = if fresh { Model::build(&scene).expect("model") } else { model.clone() };
        let mut sim = Simulation::new(model.clone(), 0.0).expect("simulation");
        sim.set_event_recording(false);
        sim.advance_to(t_end).expect("run");
        probes += sim.stats().probes;
    }
    println!("{probes}");
}
