//! Error against run time for the Hertz stop's contact phases: beamstop
//! (closed-form free flight, force-collocation contact phases) against the strongest
//! compiled peer, DOP853 with dense output (`numerics/src/solve/dop853.rs`), integrated
//! phase by phase, on `scenes/hertz_stop.json` (20 modes, K = 1.088e10
//! N/m^1.5, Lankarani-Nikravesh e = 0.8), 0.2 s from rest.
//!
//! Both solve the identical modal system, built by beamstop's public API
//! (`Model::build`, `model.oscillators`, `model.stops[0].geometry`,
//! `model.loads.derivative`, the law from `Law::Hertz`):
//! `q_j'' + 2 a_j q_j' + omega_j^2 q_j = f_j(t) - side w_j F` with the
//! penetration `p = side w . q - gap`, `p' = side w . q'`, and in the pressed
//! phase `F = K p^1.5 (1 + alpha p' / v0) + C p'` (`Hertz::raw_force`, `v0`
//! the approach speed at the onset; `alpha = 3 (1 - e^2) / 4` for
//! Lankarani-Nikravesh), zero in the other phases. The peer's phases and
//! switches are those of `src/contact/hertz.rs`:
//!
//! * open (F = 0), watching `-p`: the gap closes -> pressed, `v0 = p'` there;
//! * pressed (F = raw force), watching `F` and `p`: `F` reaches zero ->
//!   penetrated (or open if `p <= 0`); `p` reaches zero -> open;
//! * penetrated (F = 0, `p > 0`), watching `-F` and `p`: the force turns
//!   positive -> pressed (same `v0`); `p` reaches zero -> open.
//!
//! The force is switched on and off only at the switches, so each phase has a
//! smooth right-hand side (the way scipy's `solve_ivp(events=...)` is used
//! phase by phase, but compiled). Events: after every accepted step the
//! watched functions are sampled at 4 interior dense-output points and at the
//! step's end; the first sample with a negative value brackets a switch, which
//! Brent's method locates on the 7th-order dense output to a few ulp; the
//! integrator restarts there from the dense-output state with the step size it
//! had proposed.
//!
//! Variants: `dop853` (scipy's controller, no step cap) and `dop853cap` (step
//! capped at `3 / omega_N`, omega_N the highest modal frequency; see
//! `spring_stop_peer.rs` for why). Tolerances as the spring-stop peer: rtol =
//! tol, atol = `tol * gap / |W_1(L)|` on the q_j and that times `Omega =
//! max(forcing frequency, omega_1)` on the q_j'.
//!
//! beamstop: `Simulation::advance_to` with `integration_tolerance` = tol
//! (the force collocation's rtol); its free flight is closed form whatever
//! the tolerance.
//!
//! Reference: beamstop at integration_tolerance 1e-13 and `dop853cap` at rtol
//! 1e-13 are compared (and every pair of the tight runs, with untimed runs at
//! 1e-14); the default reference is `dop853cap` at rtol 1e-14, which the
//! uncapped peer at 1e-14 (another step sequence) matches to ~4e-13 of the
//! gap while both 1e-13 candidates are 4e-11 to 7e-11 away from it
//! (`--reference beamstop|dop853cap` picks a 1e-13 candidate instead).
//!
//! Error measures: `err/gap` = max over the 2001 grid times of |tip.w - ref| /
//! gap; `onset dt` = the largest time difference between a reference contact
//! onset and the solver's nearest onset (`missed`: reference onsets with no
//! solver onset within 1e-5 s; `extra`: solver onsets matching none).
//! Run time: the median of `--reps` (3) runs over the horizon in one call,
//! as a co-simulation master runs a component for a result it does not
//! sample: beamstop one `advance_to(0.2)` (one fmi2DoStep), the peer the
//! same integration without writing the grid. The grids and events come
//! from one untimed run of each.
//!
//! `cargo run --release --example hertz_peer -- --csv PATH [--dump PATH.json]
//! [--stiffness-csv PATH] [--reps N] [--reference dop853cap14|dop853cap|beamstop]
//! [--modes N]` (`--modes`: the scene with N modes, e.g. 32)
//!
//! `--dump` writes the modal system, the tolerance scales and the reference
//! (grid and onsets) as JSON, for the scipy runs of `python/beamstop_tools/report/hertz.py`.
//! `--stiffness-csv` runs the scene at K = 1e6, 1e8, 1e10, 1e12 and its own K
//! (tol 1e-10) and
//! writes the event-search probes per contact phase (`Simulation::stats`:
//! each probe of an integrated phase is one accepted collocation step; a contact's
//! count also holds the few free-flight probes of the calls that end at its
//! onset and separation).

#[path = "peer/brent.rs"]
mod brent;

use std::io::Write;
use std::time::Instant;

use beamstop::contact::{Hertz, Law};
use beamstop::solve::ModalForcing;
use beamstop::kinds::modal::{sim::EventKind, model::Model, scene::Scene, sim::Simulation};
use brent::brent;
use beamstop::solve::dop853::{self, Dop853, Rhs};
use nalgebra::DVector;

const T_END: f64 = 0.2;
const N_OUT: usize = 2000;
const DT: f64 = T_END / N_OUT as f64;
/// Interior dense-output samples of the watched functions per step.
const INTERIOR: usize = 4;
const CAP: f64 = 3.0;
const BS_TOLS: [f64; 11] = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13, 1e-14];
const PEER_TOLS: [f64; 10] = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13];
/// A solver onset farther than this from every reference onset is extra.
const MATCH: f64 = 1e-5;

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Phase {
    Open,
    Pressed,
    Penetrated,
}

/// The modal system in one phase.
#[derive(Clone)]
struct Beam {
    n: usize,
    omega2: Vec<f64>,
    two_a: Vec<f64>,
    w: Vec<f64>,
    /// `[0; n] ++ w`: `p' = side wv . y`.
    wv: Vec<f64>,
    side: f64,
    gap: f64,
    law: Hertz,
    loads: ModalForcing,
    f: DVector<f64>,
    phase: Phase,
    /// The approach speed at the last onset.
    v0: f64,
}

impl Beam {
    fn new(model: &Model) -> Beam {
        let stop = &model.stops[0];
        let Law::Hertz(law) = &stop.law else { panic!("not a Hertz stop") };
        assert!(model.transfer.is_none());
        let n = model.oscillators.len();
        let w: Vec<f64> = stop.geometry.w.iter().copied().collect();
        let mut wv = vec![0.0; n];
        wv.extend_from_slice(&w);
        Beam {
            n,
            omega2: model.oscillators.iter().map(|o| o.omega * o.omega).collect(),
            two_a: model.oscillators.iter().map(|o| 2.0 * o.a).collect(),
            w,
            wv,
            side: stop.geometry.side,
            gap: stop.geometry.gap,
            law: law.clone(),
            loads: model.loads.clone(),
            f: DVector::zeros(n),
            phase: Phase::Open,
            v0: 0.0,
        }
    }

    fn pen(&self, y: &[f64]) -> (f64, f64) {
        let n = self.n;
        (self.side * dot(&self.w, &y[..n]) - self.gap, self.side * dot(&self.w, &y[n..2 * n]))
    }

    fn raw(&self, p: f64, pd: f64) -> f64 {
        self.law.raw_force(p, pd, self.v0).0
    }

    /// The watched functions of the phase (non-negative while it holds).
    fn watched(&self, p: f64, pd: f64) -> [f64; 2] {
        match self.phase {
            Phase::Open => [-p, f64::INFINITY],
            Phase::Pressed => [self.raw(p, pd), p],
            Phase::Penetrated => [-self.raw(p, pd), p],
        }
    }

    /// The phase after watched function `k` of the current one reached zero.
    fn next(&self, k: usize, p: f64) -> Phase {
        match (self.phase, k) {
            (Phase::Open, _) => Phase::Pressed,
            (Phase::Pressed, 0) if p > 0.0 => Phase::Penetrated,
            (Phase::Penetrated, 0) => Phase::Pressed,
            _ => Phase::Open,
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

impl Rhs for Beam {
    fn eval(&mut self, t: f64, y: &[f64], dy: &mut [f64]) {
        let n = self.n;
        let force = if self.phase == Phase::Pressed {
            let (p, pd) = self.pen(y);
            self.raw(p, pd)
        } else {
            0.0
        };
        self.loads.derivative(t, 0, &mut self.f);
        let (q, v) = y.split_at(n);
        let (dq, dv) = dy.split_at_mut(n);
        dq.copy_from_slice(v);
        let sf = self.side * force;
        for j in 0..n {
            dv[j] = self.f[j] - self.two_a[j] * v[j] - self.omega2[j] * q[j] - sf * self.w[j];
        }
    }
}

/// One solver's run: the tip on the grid, contact onsets, all switches, work.
#[derive(Clone, Default)]
struct Run {
    tip: Vec<f64>,
    onsets: Vec<f64>,
    /// The approach speed `p'` at each onset.
    onset_speeds: Vec<f64>,
    switches: Vec<f64>,
    /// Peer: step attempts; beamstop: event-search probes.
    steps: u64,
    /// Peer: accepted steps in the pressed and penetrated phases.
    contact_steps: u64,
}

/// The watched functions from the dense output at `t`.
fn watched_at(s: &mut Dop853<Beam>, t: f64, w: &[f64], wv: &[f64]) -> [f64; 2] {
    let (side, gap) = (s.rhs.side, s.rhs.gap);
    let p = side * s.dense_dot(t, w) - gap;
    let pd = if s.rhs.phase == Phase::Open { 0.0 } else { side * s.dense_dot(t, wv) };
    s.rhs.watched(p, pd)
}

/// One peer run; `grid`: write the tip on the output grid (timed runs do not).
fn peer(beam: &Beam, y0: &[f64], rtol: f64, atol: &[f64], max_step: f64, grid: bool) -> Result<Run, String> {
    let n = beam.n;
    let w = beam.w.clone();
    let wv = beam.wv.clone();
    let mut rhs = beam.clone();
    let (p0, pd0) = beam.pen(y0);
    rhs.phase = if p0 > 0.0 { Phase::Pressed } else { Phase::Open };
    rhs.v0 = pd0.max(0.0);
    let mut s = Dop853::new(rhs, 0.0, y0, T_END, rtol, atol, None);
    s.max_step = max_step;
    let mut run = Run { tip: vec![0.0; N_OUT + 1], ..Run::default() };
    run.tip[0] = dot(&w, &y0[..n]);
    let mut k_out = 1usize;
    let mut ybuf = vec![0.0; 2 * n];
    // At a restart the watched functions are zero to rounding: a tiny value
    // with the phase's own sign.
    let tiny = [f64::MIN_POSITIVE; 2];
    let clean = |g: [f64; 2]| [g[0].max(f64::MIN_POSITIVE), g[1].max(f64::MIN_POSITIVE)];
    let mut g_start = clean(s.rhs.watched(p0, pd0));
    while s.t < T_END {
        let (t0, t1) = s.step().map_err(|e| format!("{e:?} at t = {}", s.t))?;
        if s.rhs.phase != Phase::Open {
            run.contact_steps += 1;
        }
        // The first sample with a negative watched function brackets a switch.
        let mut bracket = None;
        let (mut ta, mut ga) = (t0, g_start);
        for i in 1..=INTERIOR + 1 {
            let (ti, gi) = if i == INTERIOR + 1 {
                let (p, pd) = s.rhs.pen(s.y());
                (t1, s.rhs.watched(p, pd))
            } else {
                let ti = t0 + (t1 - t0) * i as f64 / (INTERIOR + 1) as f64;
                (ti, watched_at(&mut s, ti, &w, &wv))
            };
            if gi[0] < 0.0 || gi[1] < 0.0 {
                bracket = Some((ta, ga, ti, gi));
                break;
            }
            ta = ti;
            ga = gi;
        }
        let mut t_stop = t1;
        let mut which = 0;
        if let Some((ta, ga, tb, gb)) = bracket {
            t_stop = f64::INFINITY;
            for k in 0..2 {
                if gb[k] < 0.0 {
                    let tk = brent(|t| watched_at(&mut s, t, &w, &wv)[k], ta, ga[k], tb, gb[k]);
                    if tk < t_stop {
                        t_stop = tk;
                        which = k;
                    }
                }
            }
        }
        while grid && k_out <= N_OUT && k_out as f64 * DT <= t_stop {
            run.tip[k_out] = s.dense_dot(k_out as f64 * DT, &w);
            k_out += 1;
        }
        if bracket.is_some() {
            s.dense(t_stop, &mut ybuf);
            let (p, pd) = s.rhs.pen(&ybuf);
            let next = s.rhs.next(which, p);
            if s.rhs.phase == Phase::Open {
                s.rhs.v0 = pd.max(0.0);
                run.onsets.push(t_stop);
                run.onset_speeds.push(pd);
            }
            run.switches.push(t_stop);
            s.rhs.phase = next;
            let h = s.next_step_size();
            s.restart(t_stop, &ybuf, Some(h));
            g_start = tiny;
        } else {
            let (p, pd) = s.rhs.pen(s.y());
            g_start = s.rhs.watched(p, pd);
        }
    }
    if grid && k_out <= N_OUT {
        return Err(format!("output grid incomplete: {k_out}"));
    }
    run.steps = (s.n_accepted + s.n_rejected) as u64;
    Ok(run)
}

fn beamstop_run(model: &Model) -> Result<Run, String> {
    let mut sim = Simulation::new(model.clone(), 0.0).map_err(|e| e.to_string())?;
    sim.set_event_recording(true);
    let mut run = Run { tip: vec![0.0; N_OUT + 1], ..Run::default() };
    run.tip[0] = sim.stop_motion(0).0;
    for k in 1..=N_OUT {
        sim.advance_to(k as f64 * DT).map_err(|e| format!("{e} at t = {}", k as f64 * DT))?;
        run.tip[k] = sim.stop_motion(0).0;
    }
    for e in sim.drain_events() {
        match e.kind {
            EventKind::Contact { speed, .. } => {
                run.onsets.push(e.time);
                run.onset_speeds.push(speed);
                run.switches.push(e.time);
            }
            EventKind::Separation { .. } => run.switches.push(e.time),
            _ => {}
        }
    }
    run.steps = sim.stats().probes;
    Ok(run)
}

/// The timed beamstop run: the horizon in one call (one fmi2DoStep).
fn beamstop_horizon(model: &Model) -> Result<f64, String> {
    let mut sim = Simulation::new(model.clone(), 0.0).map_err(|e| e.to_string())?;
    sim.set_event_recording(false);
    sim.advance_to(T_END).map_err(|e| e.to_string())?;
    Ok(sim.stop_motion(0).0)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn max_err(a: &[f64], b: &[f64], gap: f64) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max) / gap
}

/// (missed, extra, largest onset difference of the matched ones).
fn match_onsets(reference: &[f64], run: &[f64]) -> (usize, usize, f64) {
    let nearest = |t: f64, set: &[f64]| set.iter().map(|p| (p - t).abs()).fold(f64::INFINITY, f64::min);
    let mut missed = 0;
    let mut dt: f64 = 0.0;
    for &t in reference {
        let d = nearest(t, run);
        if d > MATCH {
            missed += 1;
        } else {
            dt = dt.max(d);
        }
    }
    let extra = run.iter().filter(|&&t| nearest(t, reference) > MATCH).count();
    (missed, extra, dt)
}

/// `--modes N`: the scene with N modes instead of its own 20.
static MODES: std::sync::OnceLock<Option<usize>> = std::sync::OnceLock::new();

fn scene_with(tol: f64, stiffness: Option<f64>) -> Model {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/hertz_stop.json");
    let mut scene = Scene::from_json(&std::fs::read_to_string(path).unwrap()).unwrap();
    if let Some(n) = MODES.get().copied().flatten() {
        if let beamstop::kinds::modal::scene::StructureSpec::Beam { modes, .. } = &mut scene.structure {
            *modes = n;
        }
    }
    scene.solver.integration_tolerance = tol;
    // One call may cover a whole contact phase at a tight tolerance.
    scene.solver.max_probes_per_step = Some(u64::MAX);
    if let Some(k) = stiffness {
        let Law::Hertz(h) = &mut scene.stops[0].law else { panic!("not a Hertz stop") };
        h.stiffness = k;
    }
    Model::build(&scene).unwrap()
}

/// Times `f` `reps` times; the median in ms and the first result.
fn timed<T>(reps: usize, mut f: impl FnMut() -> Result<T, String>) -> Result<(f64, T), String> {
    let mut first = None;
    let mut times = Vec::new();
    for _ in 0..reps.max(1) {
        let t = Instant::now();
        let r = f()?;
        times.push(t.elapsed().as_secs_f64());
        if first.is_none() {
            first = Some(r);
        }
    }
    Ok((1e3 * median(times), first.unwrap()))
}

struct Row {
    solver: &'static str,
    tol: f64,
    run: Run,
    ms: f64,
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |name: &str| args.iter().position(|a| a == name).map(|i| args.get(i + 1).expect("a value").clone());
    let csv = arg("--csv");
    let dump = arg("--dump");
    let stiffness_csv = arg("--stiffness-csv");
    let reps: usize = arg("--reps").map_or(3, |r| r.parse().expect("--reps N"));
    let reference_name = arg("--reference").unwrap_or_else(|| "dop853cap14".into());
    MODES.set(arg("--modes").map(|n| n.parse().expect("--modes N"))).expect("set once");

    let (end_err, dense_err, _) = dop853::self_check();
    assert!(end_err < 1e-10 && dense_err < 1e-10, "DOP853 port is wrong");

    let model = scene_with(1e-10, None);
    let beam = Beam::new(&model);
    let n = beam.n;
    let gap = beam.gap;
    let mut y0 = vec![0.0; 2 * n];
    for j in 0..n {
        y0[j] = model.initial.q[j];
        y0[n + j] = model.initial.qd[j];
    }
    let w1 = beam.w[0].abs();
    let omega = model.loads.harmonics.iter().map(|h| h.omega).fold(model.oscillators[0].omega, f64::max);
    let omega_max = model.oscillators.iter().map(|o| o.omega).fold(0.0, f64::max);
    let atol_for = |tol: f64| {
        let mut atol = vec![tol * gap / w1; 2 * n];
        for a in &mut atol[n..] {
            *a *= omega;
        }
        atol
    };
    println!("{n} modes, omega_N = {omega_max:.4e} rad/s, cap 3/omega_N = {:.3e} s, gap {gap} m", CAP / omega_max);

    let mut rows: Vec<Row> = Vec::new();
    let t_all = Instant::now();
    // beamstop.
    for &tol in &BS_TOLS {
        let m = scene_with(tol, None);
        match beamstop_run(&m).and_then(|run| Ok((timed(reps, || beamstop_horizon(&m))?.0, run))) {
            Ok((ms, run)) => {
                println!("beamstop  {tol:.0e}: {ms:9.2} ms, {} onsets, {} probes", run.onsets.len(), run.steps);
                rows.push(Row { solver: "beamstop", tol, run, ms });
            }
            Err(e) => println!("beamstop  {tol:.0e}: failed: {e}"),
        }
    }
    // The peer.
    for (solver, cap) in [("dop853", f64::INFINITY), ("dop853cap", CAP / omega_max)] {
        for &tol in &PEER_TOLS {
            let atol = atol_for(tol);
            match peer(&beam, &y0, tol, &atol, cap, true).and_then(|run| Ok((timed(reps, || peer(&beam, &y0, tol, &atol, cap, false))?.0, run))) {
                Ok((ms, run)) => {
                    println!("{solver:<9} {tol:.0e}: {ms:9.2} ms, {} onsets, {} steps", run.onsets.len(), run.steps);
                    rows.push(Row { solver, tol, run, ms });
                }
                Err(e) => println!("{solver:<9} {tol:.0e}: failed: {e}"),
            }
        }
    }
    println!("(all runs: {:.1} s)", t_all.elapsed().as_secs_f64());

    // The two candidate references and their agreement.
    let find = |solver: &str, tol: f64| rows.iter().find(|r| r.solver == solver && r.tol == tol).map(|r| r.run.clone());
    let bs_ref = find("beamstop", 1e-13).expect("beamstop at 1e-13");
    let peer_ref = find("dop853cap", 1e-13).expect("dop853cap at 1e-13");
    let (m1, x1, dt_ref) = match_onsets(&bs_ref.onsets, &peer_ref.onsets);
    let d_ref = max_err(&bs_ref.tip, &peer_ref.tip, gap);
    let k_first = bs_ref.onsets.first().map_or(N_OUT + 1, |t| (t / DT).floor() as usize + 1);
    let d_pre = max_err(&bs_ref.tip[..k_first], &peer_ref.tip[..k_first], gap);
    println!(
        "references: beamstop 1e-13 vs dop853cap 1e-13: max |dw|/gap {d_ref:.2e} (before the first onset {d_pre:.2e}), onsets {} vs {}, max onset dt {dt_ref:.2e} s, missed {m1}, extra {x1}",
        bs_ref.onsets.len(),
        peer_ref.onsets.len()
    );
    // Self-convergence: untimed runs at 1e-14 (the scenes' floor)
    // and the differences between every pair of the tight runs.
    let mut tight: Vec<(String, Run)> = Vec::new();
    for (solver, tol) in [("beamstop", 1e-12), ("beamstop", 1e-13), ("dop853cap", 1e-12), ("dop853cap", 1e-13), ("dop853", 1e-13)] {
        if let Some(r) = find(solver, tol) {
            tight.push((format!("{solver} {tol:.0e}"), r));
        }
    }
    match beamstop_run(&scene_with(1e-14, None)) {
        Ok(r) => tight.push(("beamstop 1e-14".into(), r)),
        Err(e) => println!("beamstop 1e-14: failed: {e}"),
    }
    for (solver, cap) in [("dop853cap", CAP / omega_max), ("dop853", f64::INFINITY)] {
        match peer(&beam, &y0, 1e-14, &atol_for(1e-14), cap, true) {
            Ok(r) => tight.push((format!("{solver} 1e-14"), r)),
            Err(e) => println!("{solver} 1e-14: failed: {e}"),
        }
    }
    println!("pairwise max |dw|/gap (upper) and max onset dt in s (lower) of the tight runs:");
    print!("{:<16}", "");
    for (a, _) in &tight {
        print!(" {a:>16}");
    }
    println!();
    let mut pairs = Vec::new();
    for (i, (a, ra)) in tight.iter().enumerate() {
        print!("{a:<16}");
        for (j, (b, rb)) in tight.iter().enumerate() {
            let v = if i < j {
                max_err(&ra.tip, &rb.tip, gap)
            } else if i > j {
                match_onsets(&ra.onsets, &rb.onsets).2
            } else {
                0.0
            };
            if i < j {
                pairs.push(serde_json::json!({"a": a, "b": b, "max_dw_over_gap": v, "max_onset_dt": match_onsets(&ra.onsets, &rb.onsets).2}));
            }
            print!(" {:>16}", if i == j { "-".to_string() } else { format!("{v:.2e}") });
        }
        println!();
    }
    let ref_label = match reference_name.as_str() {
        "beamstop" => "beamstop 1e-13",
        "dop853cap" => "dop853cap 1e-13",
        _ => "dop853cap 1e-14",
    };
    let reference = tight.iter().find(|(a, _)| a == ref_label).map(|(_, r)| r.clone()).expect("the reference run");
    println!("reference: {ref_label}; {} contact onsets in [0, {T_END}] s", reference.onsets.len());

    println!("{:<9} {:>6} {:>10} {:>10} {:>10} {:>7} {:>7} {:>6} {:>8} {:>8}", "solver", "tol", "err/gap", "onset dt", "ms", "onsets", "missed", "extra", "steps", "contact");
    for r in &rows {
        let err = max_err(&r.run.tip, &reference.tip, gap);
        let (missed, extra, dt) = match_onsets(&reference.onsets, &r.run.onsets);
        println!(
            "{:<9} {:>6.0e} {err:>10.2e} {dt:>10.2e} {:>10.3} {:>7} {missed:>7} {extra:>6} {:>8} {:>8}",
            r.solver,
            r.tol,
            r.ms,
            r.run.onsets.len(),
            r.run.steps,
            r.run.contact_steps
        );
    }

    if let Some(path) = &csv {
        let mut f = std::fs::File::create(path).expect("csv");
        writeln!(f, "solver,rtol,err_over_gap,onset_err_s,ms,onsets,missed,extra,steps,contact_steps").unwrap();
        for r in &rows {
            let err = max_err(&r.run.tip, &reference.tip, gap);
            let (missed, extra, dt) = match_onsets(&reference.onsets, &r.run.onsets);
            let cs = if r.solver == "beamstop" { String::new() } else { r.run.contact_steps.to_string() };
            writeln!(f, "{},{:.0e},{err:.4e},{dt:.4e},{:.4},{},{missed},{extra},{},{cs}", r.solver, r.tol, r.ms, r.run.onsets.len(), r.run.steps).unwrap();
        }
        println!("wrote {path}");
    }

    if let Some(path) = &dump {
        let Law::Hertz(h) = &model.stops[0].law else { unreachable!() };
        let alpha = match h.damping {
            beamstop::contact::ContactDamping::Linear => 0.0,
            beamstop::contact::ContactDamping::HuntCrossley => 1.5 * (1.0 - h.restitution),
            beamstop::contact::ContactDamping::LankaraniNikravesh => 0.75 * (1.0 - h.restitution * h.restitution),
        };
        let c_lin = if h.damping == beamstop::contact::ContactDamping::Linear { h.damping_coefficient } else { 0.0 };
        let out = serde_json::json!({
            "t_end": T_END,
            "n_out": N_OUT,
            "omega2": beam.omega2,
            "two_a": beam.two_a,
            "w": beam.w,
            "side": beam.side,
            "gap": gap,
            "K": h.stiffness,
            "alpha": alpha,
            "C": c_lin,
            "constant": model.loads.constant.as_slice(),
            "harmonics": model.loads.harmonics.iter().map(|hm| serde_json::json!({
                "omega": hm.omega,
                "re": hm.amplitude.iter().map(|a| a.re).collect::<Vec<_>>(),
                "im": hm.amplitude.iter().map(|a| a.im).collect::<Vec<_>>(),
            })).collect::<Vec<_>>(),
            "q0": model.initial.q.as_slice(),
            "qd0": model.initial.qd.as_slice(),
            "w1": w1,
            "Omega": omega,
            "omega_max": omega_max,
            "reference": {
                "label": ref_label,
                "tip": reference.tip,
                "onsets": reference.onsets,
                "onset_speeds": reference.onset_speeds,
                "switches": reference.switches,
            },
            "reference_check": {
                "max_dw_over_gap": d_ref,
                "max_dw_over_gap_before_first_onset": d_pre,
                "max_onset_dt": dt_ref,
                "onsets_beamstop": bs_ref.onsets.len(),
                "onsets_dop853cap": peer_ref.onsets.len(),
                "pairs": pairs,
            },
        });
        std::fs::write(path, serde_json::to_string(&out).unwrap()).expect("dump");
        println!("wrote {path}");
    }

    if let Some(path) = &stiffness_csv {
        let mut f = std::fs::File::create(path).expect("stiffness csv");
        writeln!(f, "K,contacts,probes_per_contact_mean,probes_per_contact_min,probes_per_contact_max,contact_ms_mean,probes_total,ms").unwrap();
        println!("probes (accepted collocation steps + searches) per contact phase, tol 1e-10:");
        let k_scene = match &model.stops[0].law {
            Law::Hertz(h) => h.stiffness,
            _ => unreachable!(),
        };
        for k in [1e6, 1e8, 1e10, k_scene, 1e12] {
            let m = scene_with(1e-10, Some(k));
            let t = Instant::now();
            let run = match beamstop_run(&m) {
                Ok(r) => r,
                Err(e) => {
                    println!("K = {k:.4e}: failed: {e}");
                    continue;
                }
            };
            let ms = 1e3 * t.elapsed().as_secs_f64();
            // Each contact episode: from its onset to the last separation
            // before the next onset (or the end).
            let mut sim = Simulation::new(m.clone(), 0.0).unwrap();
            let mut per = Vec::new();
            let mut durations = Vec::new();
            for (idx, &on) in run.onsets.iter().enumerate() {
                let next = run.onsets.get(idx + 1).copied().unwrap_or(T_END);
                let off = run.switches.iter().copied().filter(|&t| t > on && t < next).fold(f64::NAN, f64::max);
                let off = if off.is_nan() { T_END } else { off };
                sim.advance_to(on).unwrap();
                let p0 = sim.stats().probes;
                sim.advance_to(off).unwrap();
                per.push((sim.stats().probes - p0) as f64);
                durations.push(off - on);
            }
            let mean = per.iter().sum::<f64>() / per.len().max(1) as f64;
            let min = per.iter().copied().fold(f64::INFINITY, f64::min);
            let max = per.iter().copied().fold(0.0, f64::max);
            let dur = 1e3 * durations.iter().sum::<f64>() / durations.len().max(1) as f64;
            println!("K = {k:.4e}: {} contacts, probes per contact mean {mean:.1} (min {min}, max {max}), mean contact {dur:.4} ms, total probes {}, {ms:.0} ms", per.len(), run.steps);
            writeln!(f, "{k:.4e},{},{mean:.2},{min},{max},{dur:.5},{},{ms:.1}", per.len(), run.steps).unwrap();
        }
        println!("wrote {path}");
    }
}
