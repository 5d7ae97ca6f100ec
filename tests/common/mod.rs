//! Helpers shared by the integration tests.

#![allow(dead_code)]

use beamstop::{EventKind, Scene, Simulation};

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
