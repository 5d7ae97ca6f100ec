//! The worst case of one communication step under the default cap on
//! event-search points (`solver.max_probes_per_step`): for each number of
//! modes, a load at the fastest frequency the interface admits and a step
//! far too long, in free flight (gap 0.5) and against the stop (gap 0,
//! sticking and chatter). Prints the search points, the time reached and
//! the wall time of the capped step.
//!
//! `cargo run --release --example probe_cost`

use std::time::Instant;

use beamstop::kinds::modal::interface::{Limits, ParamKey};
use beamstop::kinds::modal::scene::StructureSpec;
use beamstop::SimError;
use beamstop::kinds::modal::{model::Model, scene::Scene, sim::Simulation};

fn main() {
    let base = Scene::from_json(&std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/pinned_beam.json")).unwrap()).unwrap();
    println!("{:>5} {:>5} {:>10} {:>12} {:>10}", "modes", "gap", "points", "reached", "wall s");
    for n in [1usize, 4, 16, 64, 200, 500] {
        for gap in [0.5, 0.0] {
            let mut scene = base.clone();
            if let StructureSpec::Beam { modes, .. } = &mut scene.structure {
                *modes = n;
            }
            let omega_max = Limits::of(&scene).load_frequency_range().max;
            ParamKey::LoadOmega(0).set(&mut scene, omega_max);
            ParamKey::StopGap(0).set(&mut scene, gap);
            let model = Model::build(&scene).unwrap();
            let cap = model.max_probes_per_step;
            let mut sim = Simulation::new(model, 0.0).unwrap();
            let t0 = Instant::now();
            let result = sim.advance_to(1e6);
            let wall = t0.elapsed().as_secs_f64();
            let (points, reached) = match result {
                Err(SimError::TooMuchWork { time, work, .. }) => (work, time),
                Err(SimError::TooManyEvents { time, count }) => (count, time),
                Err(e) => panic!("{e}"),
                Ok(()) => (cap, sim.time()),
            };
            println!("{n:>5} {gap:>5} {points:>10} {reached:>12.4e} {wall:>10.3}");
        }
    }
}
