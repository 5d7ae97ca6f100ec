//! Run time, events and event-search points against the number of modes.
//! `cargo run --release --example scaling -- [N ...]`
use std::f64::consts::PI;
use std::time::Instant;

use beamstop::interface::ParamKey;
use beamstop::scene::StructureSpec;
use beamstop::{Model, Scene, Simulation};

fn main() {
    let base = Scene::from_json(&std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/pinned_beam.json")).unwrap()).unwrap();
    let ns: Vec<usize> = std::env::args().skip(1).map(|a| a.parse().unwrap()).collect();
    let ns = if ns.is_empty() { vec![4, 8, 16, 32, 64] } else { ns };
    for &n in &ns {
        for s in ["S2", "S3"] {
            let mut scene = base.clone();
            if let StructureSpec::Beam { modes, .. } = &mut scene.structure {
                *modes = n;
            }
            let t_end = if s == "S2" {
                ParamKey::LoadAmplitude(0).set(&mut scene, 72.0);
                ParamKey::LoadOmega(0).set(&mut scene, 0.7 * PI * PI);
                ParamKey::StopGap(0).set(&mut scene, 1.2);
                ParamKey::Law(0, 1).set(&mut scene, 1e-3);
                60.0 * 2.0 * PI / (0.7 * PI * PI)
            } else {
                20.0
            };
            scene.solver.max_probes_per_step = Some(u64::MAX / 2);
            scene.solver.max_events_per_step = u64::MAX / 2;
            let model = Model::build(&scene).unwrap();
            let mut best = f64::INFINITY;
            let mut stats = None;
            let reps = if n <= 16 { 20 } else if n <= 64 { 3 } else { 1 };
            for _ in 0..reps {
                let t0 = Instant::now();
                let mut sim = Simulation::new(model.clone(), 0.0).unwrap();
                sim.set_event_recording(false);
                sim.advance_to(t_end).unwrap();
                best = best.min(t0.elapsed().as_secs_f64());
                stats = Some((sim.stats(), sim.state().stops[0].impacts, sim.state().stops[0].sticks));
            }
            let (st, imp, sticks) = stats.unwrap();
            println!("{s} N={n:4} time {:10.4} ms  probes {:8} events {:6} impacts {imp:6} sticks {sticks:4}  us/probe {:.3}", best * 1e3, st.probes, st.events, best * 1e6 / st.probes as f64);
        }
    }
}
