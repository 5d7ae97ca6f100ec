//! Helpers shared by the integration tests.

#![allow(dead_code)]

use beamstop::kinds::modal::{sim::EventKind, scene::Scene, sim::Simulation};

/// A scene of `scenes/` by file stem.
pub fn scene(name: &str) -> Scene {
    let path = format!("{}/scenes/{name}.json", env!("CARGO_MANIFEST_DIR"));
    Scene::from_json(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The impacts recorded since the last drain: (time, approach speed).
pub fn impacts(sim: &mut Simulation) -> Vec<(f64, f64)> {
    sim.drain_events()
        .into_iter()
        .filter_map(|e| match e.kind {
            EventKind::Impact { speed, .. } => Some((e.time, speed)),
            _ => None,
        })
        .collect()
}

/// Runs `model` from t = 0 through `times`, returning the modal state
/// `[q; q']` at each and the simulation at the end.
pub fn run_states(model: beamstop::kinds::modal::model::Model, times: &[f64]) -> (Vec<nalgebra::DVector<f64>>, Simulation) {
    let mut sim = Simulation::new(model, 0.0).unwrap();
    let mut out = Vec::new();
    for &t in times {
        sim.advance_to(t).unwrap();
        let c = sim.current();
        out.push(nalgebra::DVector::from_iterator(2 * c.q.len(), c.q.iter().chain(c.qd.iter()).copied()));
    }
    (out, sim)
}
