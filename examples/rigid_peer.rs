//! Error against run time for the rigid stop (restitution, chatter,
//! sticking): beamstop against the strongest compiled peer a skilled user
//! would write, side by side in one process (GitHub issue 10, item 1).
//!
//! Scenes (VSM12: Vyasarayani, Sandhu & McPhee 2012, pinned-pinned beam,
//! 4 modes, stop at x = 0.4, zeta = 0.05, R = 0.7):
//! - `S2`: Figure 10 regime, F = 72, Omega = 0.7 pi^2, d = 1.2, eps = 1e-3,
//!   60 forcing periods from rest (two impacts per period once settled);
//! - `S3`: the default Figure 4 scene (F = 76.8, Omega = 0.1 pi^2, d = 0,
//!   eps = 1e-6) over 20 time units from rest on the stop: releases, chatter
//!   sequences ended by the eps rule, sticking.
//!
//! The peer integrates the same modal system, built by beamstop's public API
//! (`Model::build`: `omega_j`, `a_j`, `w_j = W_j(x_s)`, the harmonic load),
//! written out as a first-order system `y = (q, q')`:
//! - free flight: `q'' = f(t) - 2 a q' - omega^2 q` (VSM12 eq. 14);
//! - impact when the gap `d - w.q` falls through zero: `q'+ = q'- - (1 + r)
//!   (w.q'-) w / (w.w)` (VSM12 eq. 28), `r = R`, or `r = 0` when the
//!   previous impact of the sequence is less than eps ago (the chatter rule);
//!   after an `r = 0` impact the beam sticks if the reaction presses it on
//!   the stop (state projected onto `w.q = d`, `w.q' = 0`);
//! - sticking: the free acceleration projected onto `w.q'' = 0`, reaction
//!   `lambda = (w.(K q + D q') - w.f) / (w.w)` (VSM12 eq. 32), released
//!   when lambda crosses zero upwards.
//! Integrator: DOP853 (`numerics/src/solve/dop853.rs`, scipy's tableau and controller),
//! compiled, no allocation per step. Events: after every accepted step the
//! watched function (gap in free flight, `-lambda` while stuck) is sampled at
//! the step's end (`samples=1`, as scipy's `solve_ivp` does) or also at 4
//! interior dense-output points (`samples=5`, which catches a rebound inside
//! one step); the first negative sample brackets the event, which Brent's
//! method locates on the 7th-order dense output to a few ulp. After an event the known zero at the restart is
//! divided out (`g / (t - t_e)` after an impact or graze, `g / (t - t_e)^2`
//! after a release or an `r = 0` impact), so the next flight, however short,
//! is bracketed by a sign change of its own (the trick that keeps chatter
//! flights of 1e-6 from being lost in the rounding of `g(t_e) = 0`). The
//! integrator restarts at the event with the step size it had proposed.
//! Tolerances: rtol from 1e-3 to 1e-14, atol = rtol and rtol/10 on every
//! component. The first step after an impact is at most a quarter of the
//! ballistic flight time `2 g'/(-g'')` (without it the peer loses the last
//! flights of a chatter sequence, 1e-6 long and 1e-11 high, inside the
//! dense output of a 5e-3 step, and never sticks).
//!
//! beamstop: `Simulation::new` + `advance_to(t_end)` (one call), with event
//! recording, for `event_tolerance` 0 (the default), 1e-12, 1e-11, 1e-10,
//! 1e-9, 1e-8, 1e-7 and 1e-6 (a gap within the tolerance is a contact: the search stops
//! converging there, and the impact puts the point on the stop).
//!
//! Error: the largest difference of the event times (impacts, sticks,
//! releases, matched by index) against the reference, beamstop at
//! `event_tolerance` 0 (whose S2 and S3 events agree with extended-precision
//! references to 1e-15 .. 4e-14, `report/summary.md`); a run with another
//! number of events has no error (it is "wrong", listed with its counts).
//! Timing: the minimum over repeats (at least 5, and at least 0.2 s of runs)
//! of the whole run, set-up included, for both; the whole sweep is timed in
//! three passes and each run keeps its fastest, so that a stretch of a busy
//! shared machine does not land on one solver only. beamstop's runs, a few
//! seconds in all, are timed before the peer's and after each of its four
//! blocks in every pass: 15 stretches, spread like the peer's.
//!
//! The accuracy table: for every level 1e-4 .. 1e-13 (and beamstop's own),
//! the fastest peer run whose error is at most the level, the fastest
//! beamstop run likewise, and their ratio.
//!
//! `cargo run --release --example rigid_peer -- [--csv RUNS.csv]
//! [--levels-csv LEVELS.csv] [--scene S2|S3] [--quick] [--debug-rtol R]`
//! (`--debug-rtol`: one peer run at rtol R printed beside the reference's
//! sticks and releases, nothing timed).
#[path = "peer/brent.rs"]
mod brent;

use std::f64::consts::PI;
use std::io::Write;
use std::time::Instant;

use beamstop::contact::{Contact, Law};
use beamstop::kinds::modal::interface::ParamKey;
use beamstop::kinds::modal::{sim::EventKind, model::Model, scene::Scene, sim::Simulation};
use brent::brent;
use beamstop::solve::dop853::{self, Dop853, Rhs};

const INTERIOR: usize = 4;
const MAX_EVENTS: usize = 100_000;
const LEVELS: [f64; 10] = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13];

/// The modal system with the stop, and the phase.
#[derive(Clone)]
struct Beam {
    n: usize,
    omega2: Vec<f64>,
    two_a: Vec<f64>,
    /// `side * w`: the gap is `gap - w.q`.
    w: Vec<f64>,
    ww: f64,
    gap: f64,
    /// Load `c + fs sin(Omega t) + fc cos(Omega t)`.
    c: Vec<f64>,
    fs: Vec<f64>,
    fc: Vec<f64>,
    omega: f64,
    restitution: f64,
    eps: f64,
    /// `(w K, w D) / (w.w)`: lambda = `lam_row . y - w.f / (w.w)`.
    lam_row: Vec<f64>,
    w_load: [f64; 3],
    stuck: bool,
}

impl Beam {
    fn new(model: &Model) -> Beam {
        let stop = &model.stops[0];
        let Law::Restitution(law) = &stop.law else { panic!("not a rigid stop") };
        assert!(model.transfer.is_none(), "modal coordinates only");
        assert!(model.loads.harmonics.len() <= 1, "one forcing frequency");
        let n = model.oscillators.len();
        let side = stop.geometry.side;
        let w: Vec<f64> = stop.geometry.w.iter().map(|x| side * x).collect();
        let ww = dot(&w, &w);
        let omega2: Vec<f64> = model.oscillators.iter().map(|o| o.omega * o.omega).collect();
        let two_a: Vec<f64> = model.oscillators.iter().map(|o| 2.0 * o.a).collect();
        let c: Vec<f64> = model.loads.constant.iter().copied().collect();
        let (omega, fs, fc) = match model.loads.harmonics.first() {
            // Re(A e^{i W t}) = A.re cos(W t) - A.im sin(W t).
            Some(h) => (h.omega, h.amplitude.iter().map(|a| -a.im).collect(), h.amplitude.iter().map(|a| a.re).collect()),
            None => (0.0, vec![0.0; n], vec![0.0; n]),
        };
        let mut lam_row: Vec<f64> = (0..n).map(|j| w[j] * omega2[j] / ww).collect();
        lam_row.extend((0..n).map(|j| w[j] * two_a[j] / ww));
        let w_load = [dot(&w, &c) / ww, dot(&w, &fs) / ww, dot(&w, &fc) / ww];
        Beam {
            n,
            omega2,
            two_a,
            w,
            ww,
            gap: stop.geometry.gap,
            c,
            fs,
            fc,
            omega,
            restitution: law.restitution,
            eps: law.chatter_eps,
            lam_row,
            w_load,
            stuck: false,
        }
    }

    fn gap_of(&self, y: &[f64]) -> f64 {
        self.gap - dot(&self.w, &y[..self.n])
    }

    /// The reaction as VSM12 eq. 32 writes it (negative: pressed).
    fn lambda(&self, t: f64, y: &[f64]) -> f64 {
        dot(&self.lam_row, y) - self.load_along_w(t)
    }

    fn load_along_w(&self, t: f64) -> f64 {
        let (s, c) = (self.omega * t).sin_cos();
        self.w_load[0] + self.w_load[1] * s + self.w_load[2] * c
    }

    /// Puts the state on the stop at rest along `w`.
    fn project(&self, y: &mut [f64]) {
        let n = self.n;
        let dq = self.gap_of(y) / self.ww;
        let dv = dot(&self.w, &y[n..]) / self.ww;
        for j in 0..n {
            y[j] += dq * self.w[j];
            y[n + j] -= dv * self.w[j];
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

impl Rhs for Beam {
    fn eval(&mut self, t: f64, y: &[f64], dy: &mut [f64]) {
        let n = self.n;
        let (s, c) = (self.omega * t).sin_cos();
        let (q, v) = y.split_at(n);
        let (dq, dv) = dy.split_at_mut(n);
        dq.copy_from_slice(v);
        for j in 0..n {
            dv[j] = self.c[j] + self.fs[j] * s + self.fc[j] * c - self.two_a[j] * v[j] - self.omega2[j] * q[j];
        }
        if self.stuck {
            let along = dot(&self.w, dv) / self.ww;
            for j in 0..n {
                dv[j] -= along * self.w[j];
            }
        }
    }
}

/// The event times of one run.
#[derive(Clone, Default, Debug)]
struct Events {
    impacts: Vec<f64>,
    sticks: Vec<f64>,
    releases: Vec<f64>,
    /// Peer: step attempts; beamstop: event-search probes.
    work: u64,
}

/// The watched function from the dense output at `t`: the gap in free
/// flight, `-lambda` while stuck, divided by `(t - t0)^order` (the known
/// zero at the segment's start).
fn watched(s: &mut Dop853<Beam>, t: f64, t0: f64, order: i32, offset: f64) -> f64 {
    let value = if s.rhs.stuck {
        let lam = {
            let row = std::mem::take(&mut s.rhs.lam_row);
            let v = s.dense_dot(t, &row);
            s.rhs.lam_row = row;
            v
        };
        -(lam - s.rhs.load_along_w(t))
    } else {
        let w = std::mem::take(&mut s.rhs.w);
        let v = s.dense_dot(t, &w);
        s.rhs.w = w;
        s.rhs.gap - v
    };
    if order == 0 { value } else { (value - offset) / (t - t0).powi(order) }
}

fn peer(beam: &Beam, y0: &[f64], start_stuck: bool, t_end: f64, rtol: f64, atol: f64, interior: usize) -> Result<Events, String> {
    let n = beam.n;
    let mut rhs = beam.clone();
    let mut y = y0.to_vec();
    rhs.stuck = start_stuck;
    if start_stuck {
        rhs.project(&mut y);
    }
    let mut s = Dop853::new(rhs, 0.0, &y, t_end, rtol, &[atol], None);
    let mut ev = Events::default();
    if start_stuck {
        ev.sticks.push(0.0);
    }
    let mut ybuf = vec![0.0; 2 * n];
    // The segment's start: time, the order of the watched function's known
    // zero there, and the previous impact of the current chatter sequence.
    let (mut t0, mut order, mut offset) = (0.0, 0, 0.0);
    let mut grazes = 0usize;
    let mut previous: Option<f64> = None;
    let mut g_start = {
        let g = if start_stuck { -s.rhs.lambda(0.0, &y) } else { s.rhs.gap_of(&y) };
        g.max(f64::MIN_POSITIVE)
    };
    while s.t < t_end {
        if ev.impacts.len() + ev.sticks.len() + ev.releases.len() + grazes > MAX_EVENTS {
            return Err(format!("more than {MAX_EVENTS} events at t = {}", s.t));
        }
        let (ta0, tb0) = s.step().map_err(|e| format!("{e:?} at t = {}", s.t))?;
        let mut bracket = None;
        let (mut ta, mut ga) = (ta0, g_start);
        for i in 1..=interior + 1 {
            let ti = if i == interior + 1 { tb0 } else { ta0 + (tb0 - ta0) * i as f64 / (interior + 1) as f64 };
            let gi = watched(&mut s, ti, t0, order, offset);
            if gi < 0.0 {
                bracket = Some((ta, ga, ti, gi));
                break;
            }
            ta = ti;
            ga = gi;
        }
        let Some((ta, ga, tb, gb)) = bracket else {
            g_start = ga;
            continue;
        };
        let te = brent(|t| watched(&mut s, t, t0, order, offset), ta, ga, tb, gb);
        s.dense(te, &mut ybuf);
        let beam = &s.rhs;
        if beam.stuck {
            ev.releases.push(te);
            s.rhs.stuck = false;
            previous = None;
            order = 2;
        } else {
            let vn = dot(&beam.w, &ybuf[n..]);
            let chatter = previous.is_some_and(|p| te - p < beam.eps);
            if vn <= 0.0 && !chatter {
                order = 1; // a graze: the gap touches zero and opens again
                grazes += 1;
            } else {
                let r = if chatter { 0.0 } else { beam.restitution };
                let dv = (1.0 + r) * vn / beam.ww;
                for j in 0..n {
                    ybuf[n + j] -= dv * beam.w[j];
                }
                ev.impacts.push(te);
                previous = Some(te);
                order = if chatter { 2 } else { 1 };
                if chatter && beam.lambda(te, &ybuf) <= 0.0 {
                    beam.project(&mut ybuf);
                    ev.sticks.push(te);
                    s.rhs.stuck = true;
                    previous = None;
                    order = 0;
                }
            }
        }
        if te <= t0 {
            return Err(format!("an event did not advance at t = {te}"));
        }
        t0 = te;
        // The watched function's value at the restart, as integrated (zero
        // up to the error of the located event), is taken out (as scipy
        // users offset their event functions).
        offset = if s.rhs.stuck { 0.0 } else { s.rhs.gap_of(&ybuf) };
        let mut h = s.next_step_size();
        if order == 1 {
            // A skilled user's guard against losing short rebounds in the
            // dense output of a long first step: the first step at most a
            // quarter of the ballistic flight time 2 g' / (-g'').
            let mut acc = vec![0.0; 2 * n];
            s.rhs.eval(te, &ybuf, &mut acc);
            let (g1, g2) = (-dot(&s.rhs.w, &ybuf[n..]), -dot(&s.rhs.w, &acc[n..]));
            if g2 < 0.0 && g1 > 0.0 {
                h = h.min(0.5 * g1 / -g2);
            }
        }
        s.restart(te, &ybuf, Some(h));
        g_start = if order == 0 { (-s.rhs.lambda(te, &ybuf)).max(f64::MIN_POSITIVE) } else { f64::MIN_POSITIVE };
    }
    ev.work = (s.n_accepted + s.n_rejected) as u64;
    Ok(ev)
}

fn beamstop_run(model: &Model, t_end: f64) -> Result<Events, String> {
    let mut sim = Simulation::new(model.clone(), 0.0).map_err(|e| e.to_string())?;
    sim.set_event_recording(true);
    sim.advance_to(t_end).map_err(|e| e.to_string())?;
    let mut ev = Events { work: sim.stats().probes, ..Events::default() };
    for e in sim.drain_events() {
        match e.kind {
            EventKind::Impact { .. } => ev.impacts.push(e.time),
            EventKind::Stick { .. } => ev.sticks.push(e.time),
            EventKind::Release { .. } => ev.releases.push(e.time),
            _ => {}
        }
    }
    Ok(ev)
}

/// The largest event-time difference, `None` if the counts differ.
fn event_error(reference: &Events, run: &Events) -> Option<f64> {
    let sets = [(&reference.impacts, &run.impacts), (&reference.sticks, &run.sticks), (&reference.releases, &run.releases)];
    let mut err: f64 = 0.0;
    for (a, b) in sets {
        if a.len() != b.len() {
            return None;
        }
        for (x, y) in a.iter().zip(b.iter()) {
            err = err.max((x - y).abs());
        }
    }
    Some(err)
}

/// The minimum run time in s over at least `reps` runs and 0.2 s, and the
/// first run's result.
fn timed<T>(reps: usize, mut f: impl FnMut() -> Result<T, String>) -> Result<(f64, T), String> {
    let mut first = None;
    let mut best = f64::INFINITY;
    let mut total = 0.0;
    let mut k = 0;
    while (k < reps && total < 2.0) || (total < 0.2 && k < 1000) {
        let t = Instant::now();
        let r = f()?;
        let dt = t.elapsed().as_secs_f64();
        best = best.min(dt);
        total += dt;
        k += 1;
        if first.is_none() {
            first = Some(r);
        }
    }
    Ok((best, first.unwrap()))
}

struct Case {
    name: &'static str,
    scene: Scene,
    t_end: f64,
}

fn cases() -> Vec<Case> {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/pinned_beam.json")).expect("scene");
    let base = Scene::from_json(&text).expect("valid scene");
    let mut s2 = base.clone();
    ParamKey::LoadAmplitude(0).set(&mut s2, 72.0);
    ParamKey::LoadOmega(0).set(&mut s2, 0.7 * PI * PI);
    ParamKey::StopGap(0).set(&mut s2, 1.2);
    ParamKey::Law(0, 1).set(&mut s2, 1e-3);
    let mut out = vec![
        Case { name: "S2", scene: s2, t_end: 60.0 * 2.0 * PI / (0.7 * PI * PI) },
        Case { name: "S3", scene: base, t_end: 20.0 },
    ];
    for c in &mut out {
        c.scene.solver.max_probes_per_step = Some(u64::MAX / 2);
        c.scene.solver.max_events_per_step = u64::MAX / 2;
    }
    out
}

fn rows_of<'a>(rows: &'a [Row], case: &'a str, solver: &'a str) -> impl Iterator<Item = &'a Row> {
    rows.iter().filter(move |r| r.case == case && r.solver == solver)
}

struct Row {
    case: &'static str,
    solver: String,
    setting: String,
    seconds: f64,
    events: Events,
    error: Option<f64>,
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |name: &str| args.iter().position(|a| a == name).map(|i| args.get(i + 1).expect("a value").clone());
    let quick = args.iter().any(|a| a == "--quick");
    let only = arg("--scene");
    let reps = if quick { 2 } else { 5 };
    let passes = if quick { 1 } else { 3 };

    let (end_err, dense_err, _) = dop853::self_check();
    assert!(end_err < 1e-10 && dense_err < 1e-10, "DOP853 port is wrong");

    let rtols: Vec<f64> = (3..=14).map(|k| 10f64.powi(-k)).collect();
    let mut rows: Vec<Row> = Vec::new();
    for case in cases() {
        if only.as_deref().is_some_and(|o| o != case.name) {
            continue;
        }
        let model = Model::build(&case.scene).expect("model");
        let reference = beamstop_run(&model, case.t_end).expect("reference run");
        let probe = Simulation::new(model.clone(), 0.0).expect("simulation");
        let start_stuck = probe.state().stops[0].contact == Contact::Held;
        println!(
            "{}: {} modes, t_end {:.6}, reference (beamstop, event_tolerance 0): {} impacts, {} sticks, {} releases{}",
            case.name,
            model.oscillators.len(),
            case.t_end,
            reference.impacts.len(),
            reference.sticks.len(),
            reference.releases.len(),
            if start_stuck { ", starts stuck" } else { "" }
        );
        if let Some(rtol) = arg("--debug-rtol") {
            let rtol: f64 = rtol.parse().expect("a number");
            let beam = Beam::new(&model);
            let y0: Vec<f64> = model.initial.q.iter().chain(model.initial.qd.iter()).copied().collect();
            let p = peer(&beam, &y0, start_stuck, case.t_end, rtol, rtol / 10.0, INTERIOR);
            println!("reference sticks {:?}\n releases {:?}", reference.sticks, reference.releases);
            match p {
                Ok(p) => {
                    println!("peer sticks {:?}\n releases {:?}", p.sticks, p.releases);
                    for (k, (a, b)) in reference.impacts.iter().zip(&p.impacts).enumerate() {
                        if (a - b).abs() > 1e-6 {
                            println!("impact {k}: reference {a} peer {b}");
                            break;
                        }
                    }
                }
                Err(e) => println!("peer failed: {e}"),
            }
            continue;
        }
        // beamstop: timed before the peer and after each of its four blocks
        // in every pass (its runs are short), so that its fastest times
        // come from as many stretches of the machine's load as the peer's.
        let mut beamstop_rows: Vec<Row> = Vec::new();
        let time_beamstop = |beamstop_rows: &mut Vec<Row>| {
            for (i, tol) in [0.0, 1e-12, 1e-11, 1e-10, 1e-9, 1e-8, 1e-7, 1e-6].into_iter().enumerate() {
                let mut scene = case.scene.clone();
                scene.solver.event_tolerance = tol;
                let m = Model::build(&scene).expect("model");
                match timed(reps, || beamstop_run(&m, case.t_end)) {
                    Ok((sec, events)) => match beamstop_rows.get_mut(i) {
                        Some(kept) => kept.seconds = kept.seconds.min(sec),
                        None => {
                            let error = event_error(&reference, &events);
                            beamstop_rows.push(Row { case: case.name, solver: "beamstop".into(), setting: format!("event_tolerance={tol:e}"), seconds: sec, events, error });
                        }
                    },
                    Err(e) => panic!("beamstop {tol:e}: failed: {e}"),
                }
            }
        };
        let mut case_rows: Vec<Row> = Vec::new();
        for pass in 0..passes {
            // The k-th run of this pass: new in the first, its fastest time kept after.
            let mut k = 0;
            let mut keep = |row: Row| {
                if pass == 0 {
                    case_rows.push(row);
                } else {
                    let kept = &mut case_rows[k];
                    kept.seconds = kept.seconds.min(row.seconds);
                }
                k += 1;
            };
            time_beamstop(&mut beamstop_rows);
            // The peer.
            let beam = Beam::new(&model);
            let y0: Vec<f64> = model.initial.q.iter().chain(model.initial.qd.iter()).copied().collect();
            for (interior, atol_factor) in [(INTERIOR, 1.0), (INTERIOR, 0.1), (0, 1.0), (0, 0.1)] {
                for &rtol in &rtols {
                    let atol = rtol * atol_factor;
                    let setting = format!("rtol={rtol:.0e} atol=rtol*{atol_factor} samples={}", interior + 1);
                    match timed(reps, || peer(&beam, &y0, start_stuck, case.t_end, rtol, atol, interior)) {
                        Ok((sec, events)) => {
                            let error = event_error(&reference, &events);
                            keep(Row { case: case.name, solver: "dop853".into(), setting, seconds: sec, events, error });
                        }
                        Err(e) => {
                            if pass == 0 {
                                println!("  dop853 {setting}: failed: {e}");
                            }
                            keep(Row { case: case.name, solver: "dop853".into(), setting, seconds: f64::NAN, events: Events::default(), error: None });
                        }
                    }
                }
                if !quick {
                    time_beamstop(&mut beamstop_rows);
                }
            }
        }
        rows.extend(beamstop_rows);
        rows.extend(case_rows);
        println!("  {:<9} {:<32} {:>10} {:>8} {:>7} {:>7} {:>10}", "solver", "setting", "ms", "impacts", "sticks", "work", "error");
        for r in rows.iter().filter(|r| r.case == case.name) {
            let err = r.error.map_or("counts differ".to_string(), |e| format!("{e:.2e}"));
            println!(
                "  {:<9} {:<32} {:>10.4} {:>8} {:>7} {:>7} {:>10}",
                r.solver,
                r.setting,
                1e3 * r.seconds,
                r.events.impacts.len(),
                r.events.sticks.len(),
                r.events.work,
                err
            );
        }
    }

    // The accuracy table.
    let mut level_rows = Vec::new();
    for case in ["S2", "S3"] {
        let of = |solver: &'static str| rows_of(&rows, case, solver);
        if of("beamstop").next().is_none() {
            continue;
        }
        let best = |solver: &'static str, level: f64| {
            of(solver).filter(|r| r.error.is_some_and(|e| e <= level) && r.seconds.is_finite()).min_by(|a, b| a.seconds.total_cmp(&b.seconds))
        };
        let own = of("beamstop").filter(|r| r.setting.starts_with("event_tolerance=0")).map(|r| r.seconds).next().unwrap_or(f64::NAN);
        let peer_best = of("dop853").filter_map(|r| r.error).fold(f64::INFINITY, f64::min);
        println!("{case}: accuracy level -> fastest peer run and fastest beamstop run reaching it (beamstop own: {:.4} ms; best peer error {peer_best:.2e})", 1e3 * own);
        let mut levels: Vec<f64> = LEVELS.to_vec();
        levels.push(peer_best);
        for level in levels {
            let p = best("dop853", level);
            let b = best("beamstop", level);
            let ratio = match (p, b) {
                (Some(p), Some(b)) => p.seconds / b.seconds,
                _ => f64::NAN,
            };
            println!(
                "  {level:8.1e}: peer {:<34} {:>9} ms | beamstop {:<26} {:>8} ms | ratio {ratio:.1}",
                p.map_or("(none reaches it)".into(), |r| r.setting.clone()),
                p.map_or("-".into(), |r| format!("{:.4}", 1e3 * r.seconds)),
                b.map_or("-".into(), |r| r.setting.clone()),
                b.map_or("-".into(), |r| format!("{:.4}", 1e3 * r.seconds)),
            );
            level_rows.push((case, level, p.map(|r| (r.setting.clone(), r.seconds, r.error.unwrap())), b.map(|r| (r.setting.clone(), r.seconds)), ratio));
        }
        // beamstop against the peer at the peer's tightest run.
        let own_ratio = best("dop853", peer_best).map_or(f64::NAN, |p| p.seconds / own);
        println!("  at the peer's best accuracy ({peer_best:.2e}; beamstop at rounding level): ratio {own_ratio:.1}");
    }

    if let Some(path) = arg("--csv") {
        let mut f = std::fs::File::create(&path).expect("csv");
        writeln!(f, "scene,solver,setting,ms,impacts,sticks,releases,work,err_events").unwrap();
        for r in &rows {
            writeln!(
                f,
                "{},{},{},{:.6},{},{},{},{},{}",
                r.case,
                r.solver,
                r.setting,
                1e3 * r.seconds,
                r.events.impacts.len(),
                r.events.sticks.len(),
                r.events.releases.len(),
                r.events.work,
                r.error.map_or("nan".into(), |e| format!("{e:.4e}"))
            )
            .unwrap();
        }
        println!("wrote {path}");
    }
    if let Some(path) = arg("--levels-csv") {
        let mut f = std::fs::File::create(&path).expect("csv");
        writeln!(f, "scene,level,peer_setting,peer_ms,peer_error,beamstop_setting,beamstop_ms,ratio").unwrap();
        for (case, level, p, b, ratio) in &level_rows {
            let (ps, pms, pe) = p.clone().map_or(("".into(), "nan".into(), "nan".into()), |(s, sec, e)| (s, format!("{:.6}", 1e3 * sec), format!("{e:.4e}")));
            let (bs, bms) = b.clone().map_or(("".into(), "nan".into()), |(s, sec)| (s, format!("{:.6}", 1e3 * sec)));
            writeln!(f, "{case},{level:.4e},{ps},{pms},{pe},{bs},{bms},{ratio:.3}").unwrap();
        }
        println!("wrote {path}");
    }
}
