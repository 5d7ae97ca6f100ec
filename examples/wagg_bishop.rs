//! The measurements docs/verification.md quotes against WB00 (Wagg & Bishop
//! 2000; docs/references.md):
//! `cargo run --release --example wagg_bishop`.
//!
//! 1. The two-mass chain (Fig. 2 parameters): the P(1,1) orbit it settles
//!    on, the energy balance of eq. 11 over one period, and r recovered
//!    from eq. 13.
//! 2. The tip-impact cantilever with 1 mode (r = 0.2) and 4 modes
//!    (r = 0.75), and the crossed pairs: amplitude and impact velocity.

use beamstop::kinds::modal::interface::ParamKey;
use beamstop::kinds::modal::{sim::EventKind, model::Model, scene::Scene, sim::Simulation};

fn load(name: &str) -> Scene {
    let path = format!("{}/scenes/{name}.json", env!("CARGO_MANIFEST_DIR"));
    let mut scene = Scene::from_json(&std::fs::read_to_string(path).unwrap()).unwrap();
    // Whole horizons in one call: no cap on the work of a single step.
    scene.solver.max_probes_per_step = Some(u64::MAX);
    scene
}

fn main() {
    let scene = load("wagg_bishop_chain");
    let mut sim = Simulation::new(Model::build(&scene).unwrap(), 0.0).unwrap();
    sim.advance_to(2000.0).unwrap();
    let impacts: Vec<(f64, f64)> = sim
        .drain_events()
        .into_iter()
        .filter_map(|e| match e.kind {
            EventKind::Impact { speed, .. } => Some((e.time, speed)),
            _ => None,
        })
        .collect();
    let n = impacts.len();
    let (ta, _) = impacts[n - 2];
    let (tb, vb) = impacts[n - 1];
    println!("Wagg-Bishop chain (m = k = 1, c = 0.1, x_s = 0.1, A = (0.5, 0), Omega = 0.9, r = 0.7), t = 0..2000:");
    println!("  {n} impacts; last inter-impact times: {:?} (forcing period {:.12})",
        impacts[n - 4..].windows(2).map(|p| format!("{:.12}", p[1].0 - p[0].0)).collect::<Vec<_>>(),
        2.0 * std::f64::consts::PI / 0.9);
    let mut probe = Simulation::new(Model::build(&scene).unwrap(), 0.0).unwrap();
    probe.advance_to(ta).unwrap();
    let a = probe.energy_balance().unwrap().clone();
    let ea = probe.energy();
    probe.advance_to(tb).unwrap();
    let b = probe.energy_balance().unwrap().clone();
    let eb = probe.energy();
    let fe: Vec<f64> = (0..2).map(|j| b.forcing[j] - a.forcing[j]).collect();
    let de: Vec<f64> = (0..2).map(|j| b.damping[j] - a.damping[j]).collect();
    let ie = b.impacts - a.impacts;
    let re: f64 = (0..2).map(|j| fe[j] - de[j]).sum();
    let ke = 0.5 * 1.0 * vb * vb;
    println!("  over the period {ta:.6} .. {tb:.6}: FE = {fe:?}, DE = {de:?}");
    println!("  residual energy RE = sum(FE - DE) = {re:.15}, impact loss IE = {ie:.15}, relative difference {:.2e}", (re - ie).abs() / ie);
    println!("  energy at the two impacts: {ea:.15} / {eb:.15}");
    println!("  impact speed v_N = {vb:.12}, KE_i = {ke:.12}, r = sqrt(1 - RE / KE_i) = {:.12}", (1.0 - re / ke).sqrt());

    let probe = load("wagg_bishop_cantilever_4mode");
    let (amplitude, omega) = (ParamKey::LoadAmplitude(0).get(&probe), ParamKey::LoadOmega(0).get(&probe));
    let period = 2.0 * std::f64::consts::PI / omega;
    // zeta = 0.01 at omega_1 = 3.516: the transient decays by e^-10 in 300 time units
    let (settle, record) = ((300.0 / period).ceil() * period, 30.0 * period);
    println!(
        "Tip-impact cantilever, base excitation {amplitude} sin({omega} t), stop 0.1 below the tip, zeta = 0.01; \
         {:.0} forcing periods settled, {:.0} recorded:",
        settle / period,
        record / period
    );
    for (scene_name, label) in [("wagg_bishop_cantilever_1mode", "1 mode"), ("wagg_bishop_cantilever_4mode", "4 modes")] {
        for r in [0.2, 0.75] {
            let mut s = load(scene_name);
            ParamKey::Law(0, 0).set(&mut s, r);
            let model = Model::build(&s).unwrap();
            let tip = model.sensors[0].w.clone();
            let mut sim = Simulation::new(model, 0.0).unwrap();
            sim.advance_to(settle).unwrap();
            sim.drain_events();
            let (mut max_up, mut t) = (f64::MIN, settle);
            while t < settle + record {
                t = (t + period / 2000.0).min(settle + record);
                sim.advance_to(t).unwrap();
                max_up = max_up.max(tip.dot(&sim.current().q));
            }
            let speeds: Vec<f64> = sim
                .drain_events()
                .into_iter()
                .filter_map(|e| match e.kind {
                    EventKind::Impact { speed, .. } => Some(speed),
                    _ => None,
                })
                .collect();
            let vmax = speeds.iter().cloned().fold(0.0, f64::max);
            let vmin = speeds.iter().cloned().fold(f64::MAX, f64::min);
            println!(
                "  {label:7} r = {r:4}: max upward tip displacement {max_up:.4}, {:.2} impacts per forcing period, impact speed {vmin:.4} .. {vmax:.4}",
                speeds.len() as f64 / (record / period),
            );
        }
    }
}
