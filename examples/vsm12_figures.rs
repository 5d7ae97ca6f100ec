//! The measurements docs/verification.md quotes against VSM12 (Vyasarayani,
//! Sandhu & McPhee 2012; docs/references.md):
//! `cargo run --release --example vsm12_figures`.
//!
//! 1. Free vibration (F = 0, R = 1, zeta = 0, d = 0, w(x, 0) = -3 sin(pi x)):
//!    first impact time against 1/(2 pi), energy drift over 20 time units.
//! 2. The Figure 4 scene (F = 76.8, omega = 0.1 pi^2, R = 0.7, zeta = 0.05,
//!    x_stop = 0.4, eps = 1e-6): each chatter sequence, its number of
//!    impacts, the ratio of successive inter-impact times, stick and release.

use std::f64::consts::{PI, SQRT_2};

use beamstop::kinds::modal::interface::ParamKey;
use beamstop::kinds::modal::{sim::EventKind, model::Model, scene::Scene, sim::Simulation};

fn main() {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/pinned_beam.json")).unwrap();
    let figure4 = Scene::from_json(&text).unwrap();

    let mut free = figure4.clone();
    ParamKey::LoadAmplitude(0).set(&mut free, 0.0);
    ParamKey::Law(0, 0).set(&mut free, 1.0);
    ParamKey::Zeta.set(&mut free, 0.0);
    ParamKey::InitialQ(0).set(&mut free, -3.0 / SQRT_2);
    let mut sim = Simulation::new(Model::build(&free).unwrap(), 0.0).unwrap();
    let e0 = sim.energy();
    let mut drift = 0.0f64;
    for k in 1..=2000 {
        sim.advance_to(k as f64 * 0.01).unwrap();
        drift = drift.max((sim.energy() - e0).abs() / e0);
    }
    let impacts: Vec<f64> =
        sim.drain_events().iter().filter(|e| matches!(e.kind, EventKind::Impact { .. })).map(|e| e.time).collect();
    println!("free vibration, R = 1, 20 time units sampled every 0.01:");
    println!("  first impact at {:.17}, 1/(2 pi) = {:.17}, difference {:.1e}", impacts[0], 1.0 / (2.0 * PI), impacts[0] - 1.0 / (2.0 * PI));
    println!("  {} impacts, largest relative energy drift {drift:.2e}", impacts.len());

    println!("Figure 4 scene, eps = 1e-6, t = 0..20:");
    let mut sim = Simulation::new(Model::build(&figure4).unwrap(), 0.0).unwrap();
    let clock = std::time::Instant::now();
    sim.advance_to(20.0).unwrap();
    let elapsed = clock.elapsed();
    let mut sequence: Vec<f64> = Vec::new();
    for e in sim.drain_events() {
        match e.kind {
            EventKind::Impact { .. } => sequence.push(e.time),
            EventKind::Stick { reaction, .. } => {
                if sequence.is_empty() {
                    println!("  t = {:.12}: sticking (reaction {reaction:.4})", e.time);
                } else {
                    let gaps: Vec<f64> = sequence.windows(2).map(|p| p[1] - p[0]).collect();
                    let ratios: Vec<f64> = gaps.windows(2).map(|p| p[1] / p[0]).collect();
                    let tail = &ratios[ratios.len().saturating_sub(10)..];
                    let mean = tail.iter().sum::<f64>() / tail.len().max(1) as f64;
                    println!(
                        "  chatter from t = {:.6}: {} impacts (the last with R = 0), last inter-impact time {:.3e}, \
                         mean ratio of successive inter-impact times over the last {} = {mean:.4}; sticking at t = {:.12} (reaction {reaction:.4})",
                        sequence[0],
                        sequence.len(),
                        gaps.last().copied().unwrap_or(f64::NAN),
                        tail.len(),
                        e.time
                    );
                }
                sequence.clear();
            }
            EventKind::Release { .. } => println!("  t = {:.12}: release (reaction changed sign)", e.time),
            EventKind::Graze { .. } => println!("  t = {:.12}: graze", e.time),
            EventKind::Contact { .. } | EventKind::Separation { .. } => unreachable!("the VSM12 beam has a rigid stop"),
        }
    }
    println!("  {} impacts in all, {:.2} ms natively", sim.state().stops[0].impacts, elapsed.as_secs_f64() * 1e3);
}
