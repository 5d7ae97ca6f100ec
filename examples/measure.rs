//! `cargo run --release --example measure CONFIG.json`: the native side of
//! the error-against-run-time report, for modal scenes (it changes the
//! number of modes and reads the modal state, below the kinds' contract). The configuration names a scene and what to change in it:
//!
//! ```json
//! { "scene": "scenes/pinned_beam.json", "set": { "R": 1.0, "F": 0.0 }, "modes": 8,
//!   "event_tolerance": 0.0, "t_end": 20.0, "step": 0.0, "repeats": 20, "dense_dt": 0.001 }
//! ```
//!
//! `set` takes variable names as the FMU shows them. `step` > 0 advances in
//! communication steps of that size (as a master would), 0 in one call.
//! Printed: the median wall time of `repeats` runs (after one warm-up), the
//! impact times, the final modal state, and the first stop's displacement
//! on a grid of spacing `dense_dt` (an untimed run).

use std::path::Path;

use beamstop::kinds::modal::interface;
use beamstop::kinds::modal::scene::{Scene, StructureSpec};
use beamstop::kinds::modal::{sim::EventKind, model::Model, sim::Simulation};
use serde::Deserialize;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Config {
    scene: String,
    #[serde(default)]
    set: std::collections::BTreeMap<String, f64>,
    #[serde(default)]
    modes: Option<usize>,
    #[serde(default)]
    event_tolerance: Option<f64>,
    t_end: f64,
    #[serde(default)]
    step: f64,
    #[serde(default = "one")]
    repeats: usize,
    #[serde(default)]
    dense_dt: f64,
}

fn one() -> usize {
    1
}

fn advance(sim: &mut Simulation, t_end: f64, step: f64) -> Result<(), String> {
    if step > 0.0 {
        let mut k = 0u64;
        loop {
            k += 1;
            let t = (k as f64 * step).min(t_end);
            sim.advance_to(t).map_err(|e| e.to_string())?;
            if t >= t_end {
                return Ok(());
            }
        }
    }
    sim.advance_to(t_end).map_err(|e| e.to_string())
}

fn measure(config: &Path) -> Result<(), String> {
    let text = std::fs::read_to_string(config).map_err(|e| format!("{}: {e}", config.display()))?;
    let cfg: Config = serde_json::from_str(&text).map_err(|e| format!("{}: {e}", config.display()))?;
    let scene_text = std::fs::read_to_string(&cfg.scene).map_err(|e| format!("{}: {e}", cfg.scene))?;
    let mut scene = Scene::from_json(&scene_text).map_err(|e| e.0)?;
    if let Some(n) = cfg.modes {
        match &mut scene.structure {
            StructureSpec::Beam { modes, .. } => *modes = n,
            StructureSpec::Chain { .. } => return Err("modes: a chain has one mode per mass".into()),
        }
        if let Some(d) = scene.damping.as_mut() {
            if let Some(z) = d.zeta_modes.as_mut() {
                z.resize(n, *z.last().unwrap_or(&0.0));
            }
        }
        scene.initial.q.truncate(n);
        scene.initial.qd.truncate(n);
    }
    if let Some(tol) = cfg.event_tolerance {
        scene.solver.event_tolerance = tol;
    }
    // A measurement may take the whole horizon in one call: no work cap.
    scene.solver.max_probes_per_step = Some(u64::MAX);
    let params = interface::parameters(&scene);
    for (name, value) in &cfg.set {
        let p = params.iter().find(|p| &p.name == name).ok_or_else(|| format!("set: no parameter named {name:?}"))?;
        scene.set_field(&p.scene_path, *value)?;
    }
    let model = Model::build(&scene).map_err(|e| e.0)?;
    let start = scene.experiment.start;
    let mut times = Vec::new();
    for r in 0..=cfg.repeats {
        let mut sim = Simulation::new(model.clone(), start).map_err(|e| e.to_string())?;
        sim.set_event_recording(false);
        let clock = std::time::Instant::now();
        advance(&mut sim, cfg.t_end, cfg.step)?;
        let elapsed = clock.elapsed().as_secs_f64();
        if r > 0 {
            times.push(elapsed);
        }
    }
    times.sort_by(f64::total_cmp);
    let median = if times.is_empty() { f64::NAN } else { times[times.len() / 2] };

    // The dense grid: a run of its own, stepped at dense_dt.
    let w = model.stops.first().map(|s| s.geometry.w.clone());
    let mut dense_t = Vec::new();
    let mut dense_w = Vec::new();
    if cfg.dense_dt > 0.0 {
        let mut sim = Simulation::new(model.clone(), start).map_err(|e| e.to_string())?;
        sim.set_event_recording(false);
        let n = (cfg.t_end / cfg.dense_dt).round() as usize;
        for k in 0..=n {
            let t = (start + k as f64 * cfg.dense_dt).min(cfg.t_end);
            sim.advance_to(t).map_err(|e| e.to_string())?;
            dense_t.push(t);
            dense_w.push(w.as_ref().map_or(0.0, |w| w.dot(&sim.current().q)));
        }
    }
    // The events and the final state: the timed configuration, untimed.
    let mut sim = Simulation::new(model.clone(), start).map_err(|e| e.to_string())?;
    advance(&mut sim, cfg.t_end, cfg.step)?;
    let events = sim.drain_events();
    let impacts: Vec<f64> = events.iter().filter(|e| matches!(e.kind, EventKind::Impact { .. })).map(|e| e.time).collect();
    let sticks: Vec<f64> = events.iter().filter(|e| matches!(e.kind, EventKind::Stick { .. })).map(|e| e.time).collect();
    let releases: Vec<f64> = events.iter().filter(|e| matches!(e.kind, EventKind::Release { .. })).map(|e| e.time).collect();
    let c = sim.current();
    let out = serde_json::json!({
        "wall_time_s": median,
        "wall_times_s": times,
        "impacts": impacts,
        "sticks": sticks,
        "releases": releases,
        "final": { "t": sim.time(), "q": c.q.as_slice(), "qd": c.qd.as_slice(), "energy": sim.energy() },
        "dense": { "t": dense_t, "w": dense_w },
        "stats": { "probes": sim.stats().probes, "events": sim.stats().events },
    });
    println!("{out}");
    Ok(())
}

fn main() -> std::process::ExitCode {
    let Some(config) = std::env::args().nth(1) else {
        eprintln!("usage: cargo run --release --example measure CONFIG.json");
        return std::process::ExitCode::from(2);
    };
    match measure(Path::new(&config)) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("measure: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}
