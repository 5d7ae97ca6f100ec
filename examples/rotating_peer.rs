//! Error against run time for the rotating hub beam's Hertz tip contact
//! (DWZ: Duan, Wang & Zhang, "Impact dynamics of a flexible beam with
//! rotation"; scene `scenes/rotating_beam.json`: aluminium beam, 6
//! clamped-free modes, first-order model, J_h = 0.05 kg m^2, tip on the
//! plane at t = 0 with theta' = 2 rad/s, Hertz K = 7.6e9 N/m^1.5 with
//! Lankarani-Nikravesh damping e = 0.8), 0 to `T_END` = 0.05 s, which holds
//! the first collision cluster (about a dozen contacts, the last ending near
//! 19 ms) and 30 ms of free flight after it.
//!
//! **beamstop**: `RotatingSimulation` (DOP853 over the whole motion, its
//! default `solver.method`; switches on the dense output) at `solver.tolerance` 1e-4 ..
//! 1e-12, one `advance_to(T_END)`, the events drained.
//!
//! **The peer**: DOP853 (`numerics/src/solve/dop853.rs`, order 8, 7th-order dense output)
//! with its own compiled event loop on the same equations `J(z) z'' = Q`
//! (first-order model, `crate::structure::rotating`; DWZ eq. 15). The model
//! is shared: the peer takes the assembled matrices `M`, `M - D`, `K`,
//! `Gamma`, `C_L`, `w`, `J_h + J_b` from `RotatingModel`, but evaluates the
//! right-hand side itself, without allocation, by block elimination of `J`
//! (`M` is constant: `a = M^-1 Gamma` once, then
//! `theta'' = (Q_th - a.Q_B) / (J_00 - Gamma.a)`, `B'' = M^-1 Q_B - a theta''`),
//! and the tip gap and its gradient from the tip's kinematics
//! (`r_tip = A(theta) [R + L - B^T C_L B / 2, w.B]`, `Q_c = F d gap/dz`).
//! At start-up it is checked against the library's `RotatingBeam::accelerations`
//! at random states in contact (printed; must agree to 1e-11).
//!
//! Phases and switches are those of `src/rotating/events.rs`, with the law
//! `F = K g^1.5 (1 + 3 (1 - e^2) / 4 g' / v0)` (DWZ eqs. 2-4 with
//! Lankarani-Nikravesh damping; `v0` the approach speed at the onset):
//! open (F = 0) watching the gap; pressed (F = raw force) watching the force
//! and the penetration; penetrated (F = 0, g > 0) watching the negated force
//! and the penetration. The force is switched only at switches, so each
//! phase is smooth. After each accepted step the watched functions are
//! sampled at 4 interior dense-output points and at the step's end; the
//! first negative sample brackets a switch that Brent's method locates on
//! the dense output; in the open phase a sign change of the gap rate from -
//! to + between samples (a minimum of the gap) is also located by Brent and
//! a negative gap there brackets an onset (a graze inside a sample
//! interval). The integrator restarts at the switch from the dense-output
//! state with the step it had proposed. The largest force of every contact
//! is taken from the pressed steps' dense output (9 samples, then golden
//! section around the best).
//!
//! Variants: `dop853` (error control only: it must resolve the contact time
//! scale itself) and `dop853cap` (step capped at `3 / omega_max` of the
//! phase: the highest modal frequency in free flight; in contact
//! `sqrt(omega_N^2 + 1.5 K sqrt(p) g.J^-1.g)` (Weyl's bound for the
//! rank-one contact stiffness, `p = (5 m v0^2 / 4 K)^(2/5)` the deepest
//! penetration a mass `m = 1 / g.J^-1.g` reaches at the onset speed `v0`)).
//! Tolerances: rtol = tol, atol = tol times 1e-3 (m for `B`, rad for
//! theta) and 0.1 (m/s, rad/s) for the rates.
//!
//! Measures (computed by `python/beamstop_tools/report/rotating_peers.py` against the
//! reference; this program prints a first table against `dop853cap` at
//! 1e-14): the first contact's peak force, the number of contacts (onsets),
//! the onset times, and at `T_END` the tip position, theta and theta'.
//! Time: the fastest of at least `--reps` runs, short ones repeated until
//! 0.3 s have passed (the machine is shared: the fastest run is the least
//! disturbed one); integration only: the model, with its modal integrals,
//! is built once per tolerance outside the timing.
//!
//! `cargo run --release --example rotating_peer -- [--json PATH] [--reps N] [--quick] [--modes N]`
//! (`--modes`: the scene with N modes, e.g. 32)
//!
//! `--json` writes every run (the measures, the work), the scene's numbers
//! for the scipy runs of `python/beamstop_tools/report/rotating_peers.py`, and the library's
//! `z''` at a few random states (for the independent Python equations).

#[path = "peer/brent.rs"]
mod brent;

use std::sync::Arc;
use std::time::Instant;

use beamstop::contact::{Hertz, ContactDamping};
use beamstop::kinds::rotating::{RotatingEventKind, RotatingModel, RotatingSimulation, RotatingSpec};
use beamstop::structure::rotating::Order;
use brent::brent;
use beamstop::solve::dop853::{self, Dop853, Rhs};
use nalgebra::DVector;
use serde_json::json;

const T_END: f64 = 0.05;
const INTERIOR: usize = 4;
const CAP: f64 = 3.0;
const POS_SCALE: f64 = 1e-3;
const VEL_SCALE: f64 = 0.1;
const BS_TOLS: [f64; 9] = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12];
const PEER_TOLS: [f64; 10] = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13];

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Phase {
    Open,
    Pressed,
    Penetrated,
}

/// The peer's right-hand side on `y = [theta, B, theta', B']`.
#[derive(Clone)]
struct Rot {
    n: usize,
    /// `M^-1` (N x N, row-major), `a = M^-1 Gamma`, `M - D`, `K`, `C_L`, `w`.
    m_inv: Vec<f64>,
    a: Vec<f64>,
    mmd: Vec<f64>,
    k: Vec<f64>,
    c: Vec<f64>,
    w: Vec<f64>,
    /// `J_h + J_b`, `R + L`, `Gamma . a`.
    j0: f64,
    ell: f64,
    ga: f64,
    normal: [f64; 2],
    offset: f64,
    law: Hertz,
    /// omega_N and the stability cap factor (`f64::INFINITY`: no cap).
    omega_n: f64,
    phase: Phase,
    v0: f64,
    mdb: Vec<f64>,
    cb: Vec<f64>,
    qb: Vec<f64>,
    grad: Vec<f64>,
}

/// The contact at one state: gap, its rate, its gradient in `grad`.
struct Gap {
    gap: f64,
    rate: f64,
}

impl Rot {
    fn new(model: &RotatingModel) -> Rot {
        let n = model.n_modes();
        let beam = &model.beam;
        assert_eq!(beam.params.order, Order::First);
        assert!(beam.params.gravity == 0.0 && beam.damping.amax() == 0.0, "the peer has no gravity or modal damping terms");
        let s = model.surface.as_ref().expect("a surface");
        let flat = |m: &nalgebra::DMatrix<f64>| (0..n * n).map(|i| m[(i / n, i % n)]).collect::<Vec<f64>>();
        let m_inv = beam.m.clone().try_inverse().expect("M invertible");
        let a = &m_inv * &beam.gamma;
        Rot {
            n,
            m_inv: flat(&m_inv),
            a: a.iter().copied().collect(),
            mmd: flat(&model.m_minus_d),
            k: flat(&beam.k),
            c: flat(&model.c_tip),
            w: beam.w.iter().copied().collect(),
            j0: beam.params.hub_inertia + beam.j_b,
            ell: model.tip_radius(),
            ga: beam.gamma.dot(&a),
            normal: s.plane.normal,
            offset: s.plane.normal[0] * s.plane.point[0] + s.plane.normal[1] * s.plane.point[1],
            law: match &s.law {
                beamstop::contact::Law::Hertz(h) => h.clone(),
                other => panic!("the peer models a Hertz surface, not {other:?}"),
            },
            omega_n: beam.omega(n),
            phase: Phase::Open,
            v0: 0.0,
            mdb: vec![0.0; n],
            cb: vec![0.0; n],
            qb: vec![0.0; n],
            grad: vec![0.0; n + 1],
        }
    }

    /// Gap `n . (r_tip - p0)`, its rate, and `d gap / dz` into `self.grad`
    /// (`n' = A^T n`; `d gap / d theta = n'_y X - n'_x Y`, `d gap / dB = -n'_x C_L B + n'_y w`).
    fn gap(&mut self, y: &[f64]) -> Gap {
        let n = self.n;
        let b = &y[1..=n];
        let mut x = self.ell;
        let mut yy = 0.0;
        for i in 0..n {
            let mut s = 0.0;
            for j in 0..n {
                s += self.c[i * n + j] * b[j];
            }
            self.cb[i] = s;
            x -= 0.5 * b[i] * s;
            yy += self.w[i] * b[i];
        }
        let (sn, cs) = y[0].sin_cos();
        let [nx, ny] = self.normal;
        let (lx, ly) = (cs * nx + sn * ny, -sn * nx + cs * ny);
        let gap = lx * x + ly * yy - self.offset;
        self.grad[0] = ly * x - lx * yy;
        let mut rate = self.grad[0] * y[n + 1];
        for i in 0..n {
            self.grad[i + 1] = -lx * self.cb[i] + ly * self.w[i];
            rate += self.grad[i + 1] * y[n + 2 + i];
        }
        Gap { gap, rate }
    }

    fn raw(&self, g: &Gap) -> f64 {
        self.law.raw_force(-g.gap, -g.rate, self.v0).0
    }

    /// The watched functions of the phase (non-negative while it holds) and the gap rate.
    fn watched(&mut self, y: &[f64]) -> ([f64; 2], f64) {
        let g = self.gap(y);
        let v = match self.phase {
            Phase::Open => [g.gap, f64::INFINITY],
            Phase::Pressed => [self.raw(&g), -g.gap],
            Phase::Penetrated => [-self.raw(&g), -g.gap],
        };
        (v, g.rate)
    }

    /// The force acting in the current phase.
    fn force(&mut self, y: &[f64]) -> f64 {
        if self.phase != Phase::Pressed {
            return 0.0;
        }
        let g = self.gap(y);
        self.raw(&g).max(0.0)
    }

    /// The phase after watched function `k` of the current one reached zero.
    fn next(&self, k: usize, penetration: f64) -> Phase {
        match (self.phase, k) {
            (Phase::Open, _) => Phase::Pressed,
            (Phase::Pressed, 0) if penetration > 0.0 => Phase::Penetrated,
            (Phase::Penetrated, 0) => Phase::Pressed,
            _ => Phase::Open,
        }
    }

    /// `g . J^-1 g` at `y` (after `gap`): by the same block elimination.
    fn inverse_mass(&mut self, y: &[f64]) -> f64 {
        let n = self.n;
        self.gap(y);
        let b = &y[1..=n];
        let mut j00 = self.j0;
        for i in 0..n {
            let mut s = 0.0;
            for j in 0..n {
                s += self.mmd[i * n + j] * b[j];
            }
            j00 += b[i] * s;
        }
        // J^-1 = [[1/s, -a^T/s], [-a/s, M^-1 + a a^T / s]], s = J00 - Gamma.a.
        let schur = j00 - self.ga;
        let g0 = self.grad[0];
        let gb = &self.grad[1..];
        let ag: f64 = self.a.iter().zip(gb).map(|(a, g)| a * g).sum();
        let mut gmg = 0.0;
        for i in 0..n {
            for j in 0..n {
                gmg += gb[i] * self.m_inv[i * n + j] * gb[j];
            }
        }
        (g0 - ag) * (g0 - ag) / schur + gmg
    }

    /// The step cap of the current phase (`CAP / omega_max`).
    fn cap(&mut self, y: &[f64]) -> f64 {
        let mut w2 = self.omega_n * self.omega_n;
        if self.phase != Phase::Open {
            let inv = self.inverse_mass(y);
            let g = self.gap(y);
            let (kk, v) = (self.law.stiffness, self.v0.max(g.rate.abs()));
            let depth = (1.25 * v * v / (inv * kk)).powf(0.4).max(-g.gap);
            w2 += 1.5 * kk * depth.max(0.0).sqrt() * inv;
        }
        CAP / w2.sqrt()
    }
}

impl Rhs for Rot {
    fn eval(&mut self, _t: f64, y: &[f64], dy: &mut [f64]) {
        let n = self.n;
        let m = n + 1;
        let force = if self.phase == Phase::Pressed {
            let g = self.gap(y);
            self.raw(&g)
        } else {
            0.0
        };
        let (z, zd) = y.split_at(m);
        let (b, bd) = (&z[1..], &zd[1..]);
        let thd = zd[0];
        // (M - D) B, J_00, the Coriolis term.
        let mut j00 = self.j0;
        let mut cor = 0.0;
        for i in 0..n {
            let mut s = 0.0;
            for j in 0..n {
                s += self.mmd[i * n + j] * b[j];
            }
            self.mdb[i] = s;
            j00 += b[i] * s;
            cor += s * bd[i];
        }
        // Q_theta = -2 theta' B^T (M - D) B' + F dgap/dtheta (no torque).
        let mut q0 = -2.0 * thd * cor;
        // Q_B = theta'^2 (M - D) B - K B + F dgap/dB.
        for i in 0..n {
            let mut kb = 0.0;
            for j in 0..n {
                kb += self.k[i * n + j] * b[j];
            }
            self.qb[i] = thd * thd * self.mdb[i] - kb;
        }
        if force != 0.0 {
            q0 += force * self.grad[0];
            for i in 0..n {
                self.qb[i] += force * self.grad[i + 1];
            }
        }
        let aq: f64 = self.a.iter().zip(&self.qb).map(|(a, q)| a * q).sum();
        let thdd = (q0 - aq) / (j00 - self.ga);
        dy[..m].copy_from_slice(zd);
        dy[m] = thdd;
        for i in 0..n {
            let mut s = 0.0;
            for j in 0..n {
                s += self.m_inv[i * n + j] * self.qb[j];
            }
            dy[m + 1 + i] = s - self.a[i] * thdd;
        }
    }
}

/// One run's measures.
#[derive(Clone, Debug, Default)]
struct Run {
    onsets: Vec<f64>,
    onset_speeds: Vec<f64>,
    /// The largest force of each contact (onset to separation).
    peaks: Vec<f64>,
    /// `[theta, theta', tip x, tip y, v_L]` at `T_END`.
    end: [f64; 5],
    /// Peer: step attempts; beamstop: accepted + rejected steps.
    steps: u64,
    /// Accepted steps in contact (pressed or penetrated).
    contact_steps: u64,
    rhs_evals: u64,
}

/// The watched functions and the gap rate from the dense output at `t`.
fn watched_at(s: &mut Dop853<Rot>, t: f64, buf: &mut [f64]) -> ([f64; 2], f64) {
    s.dense(t, buf);
    s.rhs.watched(buf)
}

fn force_at(s: &mut Dop853<Rot>, t: f64, buf: &mut [f64]) -> f64 {
    s.dense(t, buf);
    s.rhs.force(buf)
}

/// The largest force on `[a, b]` of the last step's dense output: 9 samples,
/// then golden section over the intervals next to the best one.
fn step_peak(s: &mut Dop853<Rot>, a: f64, b: f64, buf: &mut [f64]) -> f64 {
    const K: usize = 8;
    let ts: Vec<f64> = (0..=K).map(|i| if i == K { b } else { a + (b - a) * i as f64 / K as f64 }).collect();
    let fs: Vec<f64> = ts.iter().map(|&t| force_at(s, t, buf)).collect();
    let k = (0..=K).fold(0, |best, i| if fs[i] > fs[best] { i } else { best });
    // Both neighbouring intervals (one at an end of the step: the peak may
    // lie inside the first or last interval).
    let (mut lo, mut hi) = (ts[k.saturating_sub(1)], ts[(k + 1).min(K)]);
    let r = 0.5 * (5f64.sqrt() - 1.0);
    let (mut x1, mut x2) = (hi - r * (hi - lo), lo + r * (hi - lo));
    let (mut f1, mut f2) = (force_at(s, x1, buf), force_at(s, x2, buf));
    for _ in 0..80 {
        if !(x1 > lo && x2 < hi && x1 < x2) {
            break;
        }
        if f1 >= f2 {
            (hi, x2, f2) = (x2, x1, f1);
            x1 = hi - r * (hi - lo);
            f1 = force_at(s, x1, buf);
        } else {
            (lo, x1, f1) = (x1, x2, f2);
            x2 = lo + r * (hi - lo);
            f2 = force_at(s, x2, buf);
        }
    }
    fs[k].max(f1).max(f2)
}

fn end_measures(model: &RotatingModel, y: &[f64]) -> [f64; 5] {
    let m = model.n_modes() + 1;
    let z = DVector::from_column_slice(&y[..m]);
    let r = model.beam.tip_position(&z);
    [y[0], y[m], r[0], r[1], model.beam.tip_deflection(&z)]
}

fn peer(model: &RotatingModel, rot: &Rot, y0: &[f64], rtol: f64, atol: &[f64], capped: bool) -> Result<Run, String> {
    let dim = y0.len();
    let mut rhs = rot.clone();
    // The tip starts on the plane moving in (or inside): a contact from t = 0.
    let (_, rate0) = rhs.watched(y0);
    let g0 = rhs.gap(y0);
    let mut run = Run::default();
    if g0.gap < 0.0 || (g0.gap == 0.0 && rate0 < 0.0) {
        rhs.phase = Phase::Pressed;
        rhs.v0 = (-rate0).max(0.0);
        run.onsets.push(0.0);
        run.onset_speeds.push(-rate0);
        run.peaks.push(0.0);
    }
    let mut s = Dop853::new(rhs, 0.0, y0, T_END, rtol, atol, None);
    if capped {
        let cap = s.rhs.cap(y0);
        s.max_step = cap;
        let h = s.next_step_size().min(cap);
        s.restart(0.0, y0, Some(h));
    }
    let mut buf = vec![0.0; dim];
    let tiny = [f64::MIN_POSITIVE; 2];
    let mut g_start = tiny;
    let mut rate_start = s.rhs.watched(y0).1;
    while s.t < T_END {
        let (t0, t1) = s.step().map_err(|e| format!("{e:?} at t = {}", s.t))?;
        if s.rhs.phase != Phase::Open {
            run.contact_steps += 1;
        }
        // Samples: the first negative watched function brackets a switch.
        let mut bracket = None;
        let (mut ta, mut ga, mut ra) = (t0, g_start, rate_start);
        for i in 1..=INTERIOR + 1 {
            let ti = if i == INTERIOR + 1 { t1 } else { t0 + (t1 - t0) * i as f64 / (INTERIOR + 1) as f64 };
            let (gi, ri) = if i == INTERIOR + 1 {
                buf.copy_from_slice(s.y());
                s.rhs.watched(&buf)
            } else {
                watched_at(&mut s, ti, &mut buf)
            };
            if gi[0] < 0.0 || gi[1] < 0.0 {
                bracket = Some((ta, ga, ti, gi));
                break;
            }
            // Open: a minimum of the gap between two samples (rate - to +).
            if s.rhs.phase == Phase::Open && ra < 0.0 && ri > 0.0 {
                let tm = brent(|t| watched_at(&mut s, t, &mut buf).1, ta, ra, ti, ri);
                let (gm, _) = watched_at(&mut s, tm, &mut buf);
                if gm[0] < 0.0 {
                    bracket = Some((ta, ga, tm, gm));
                    break;
                }
            }
            (ta, ga, ra) = (ti, gi, ri);
        }
        let mut t_stop = t1;
        let mut which = 0;
        if let Some((ta, ga, tb, gb)) = bracket {
            t_stop = f64::INFINITY;
            for k in 0..2 {
                if gb[k] < 0.0 {
                    let tk = brent(|t| watched_at(&mut s, t, &mut buf).0[k], ta, ga[k], tb, gb[k]);
                    if tk < t_stop {
                        t_stop = tk;
                        which = k;
                    }
                }
            }
        }
        if s.rhs.phase == Phase::Pressed {
            let p = step_peak(&mut s, t0, t_stop, &mut buf);
            let last = run.peaks.last_mut().expect("a contact");
            *last = last.max(p);
        }
        if bracket.is_some() {
            s.dense(t_stop, &mut buf);
            let g = s.rhs.gap(&buf);
            let next = s.rhs.next(which, -g.gap);
            if s.rhs.phase == Phase::Open {
                s.rhs.v0 = (-g.rate).max(0.0);
                run.onsets.push(t_stop);
                run.onset_speeds.push(-g.rate);
                run.peaks.push(0.0);
            }
            s.rhs.phase = next;
            let mut h = s.next_step_size();
            if capped {
                let cap = s.rhs.cap(&buf);
                s.max_step = cap;
                h = h.min(cap);
            }
            s.restart(t_stop, &buf, Some(h));
            g_start = tiny;
            rate_start = s.rhs.watched(&buf).1;
        } else {
            buf.copy_from_slice(s.y());
            let (g, r) = s.rhs.watched(&buf);
            g_start = g;
            rate_start = r;
        }
    }
    run.end = end_measures(model, s.y());
    run.steps = (s.n_accepted + s.n_rejected) as u64;
    run.rhs_evals = s.n_fev as u64;
    Ok(run)
}

fn beamstop_run(model: &Arc<RotatingModel>) -> Result<Run, String> {
    let mut sim = RotatingSimulation::new(model.clone(), 0.0).map_err(|e| e.to_string())?;
    sim.advance_to(T_END).map_err(|e| e.to_string())?;
    let mut run = Run::default();
    for e in sim.drain_events() {
        match e.kind {
            RotatingEventKind::Onset { speed } => {
                run.onsets.push(e.time);
                run.onset_speeds.push(speed);
            }
            RotatingEventKind::Separation { peak_force, .. } => run.peaks.push(peak_force),
            _ => {}
        }
    }
    let (z, zd) = sim.coordinates();
    let r = sim.tip_position();
    run.end = [z[0], zd[0], r[0], r[1], sim.tip_deflection()];
    let st = sim.stats();
    run.steps = st.accepted + st.rejected;
    run.contact_steps = st.contact_steps;
    Ok(run)
}

/// Times `f` at least `reps` times, and short runs until 0.3 s have
/// passed (at most 200 runs): the fastest run in ms (on a shared machine
/// the least disturbed one), the number of runs and the first result.
fn timed<T>(reps: usize, mut f: impl FnMut() -> Result<T, String>) -> Result<(f64, usize, T), String> {
    let mut first = None;
    let mut times: Vec<f64> = Vec::new();
    while times.len() < reps.max(1) || (times.iter().sum::<f64>() < 0.3 && times.len() < 200) {
        let t = Instant::now();
        let r = f()?;
        times.push(t.elapsed().as_secs_f64());
        first.get_or_insert(r);
    }
    let count = times.len();
    Ok((1e3 * times.iter().copied().fold(f64::INFINITY, f64::min), count, first.unwrap()))
}

fn scene(tol: f64) -> RotatingSpec {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/rotating_beam.json");
    let mut spec = RotatingSpec::from_json(&std::fs::read_to_string(path).unwrap()).unwrap();
    spec.solver.tolerance = tol;
    if let Some(&n) = MODES.get() {
        spec.n_modes = n;
    }
    spec
}

/// `--modes N`: the scene with N modes instead of its own.
static MODES: std::sync::OnceLock<usize> = std::sync::OnceLock::new();

struct Row {
    solver: &'static str,
    tol: f64,
    ms: f64,
    /// Timed runs (0: untimed).
    runs: usize,
    run: Run,
}

/// Largest relative difference of `z''` between the peer's right-hand side
/// and `RotatingBeam::accelerations` (with the library's contact force) at
/// random states, each pressed `1e-5` m into the plane.
fn check_rhs(model: &RotatingModel, rot: &Rot) -> (f64, Vec<serde_json::Value>) {
    let n = model.n_modes();
    let m = n + 1;
    let beam = &model.beam;
    let s = model.surface.as_ref().unwrap();
    let mut seed = 12345u64;
    let mut rnd = || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let (mut worst, mut states) = (0.0f64, Vec::new());
    for _ in 0..5 {
        let mut y = vec![0.0; 2 * m];
        y[0] = 0.05 * rnd();
        for i in 1..m {
            y[i] = 0.02 * rnd() / (i * i) as f64;
        }
        y[m] = 2.0 + rnd();
        for i in 1..m {
            y[m + i] = 2.0 * rnd() / i as f64;
        }
        // Put the tip 1e-5 m inside by turning the hub.
        let z = DVector::from_column_slice(&y[..m]);
        let gap = beam.plane_gap(&z, &s.plane);
        let dgdth = beam.contact_generalized_force(&z, &s.plane, 1.0)[0];
        y[0] -= (gap + 1e-5) / dgdth;
        let (z, zd) = (DVector::from_column_slice(&y[..m]), DVector::from_column_slice(&y[m..]));
        let (gamma, rate) = (-beam.plane_gap(&z, &s.plane), -beam.plane_gap_rate(&z, &zd, &s.plane));
        let v0 = 1.7;
        let f = s.law.raw_force(gamma, rate, v0).0.max(0.0);
        let qc = beam.contact_generalized_force(&z, &s.plane, f);
        let mut zdd = DVector::zeros(m);
        beam.accelerations(&z, &zd, 0.0, Some(&qc), &mut zdd).unwrap();
        let mut r = rot.clone();
        r.phase = Phase::Pressed;
        r.v0 = v0;
        let mut dy = vec![0.0; 2 * m];
        r.eval(0.0, &y, &mut dy);
        let diff = (0..m).map(|i| (dy[m + i] - zdd[i]).abs()).fold(0.0, f64::max) / zdd.amax();
        worst = worst.max(diff);
        states.push(json!({"y": y, "v0": v0, "penetration": gamma, "force": f, "zdd": zdd.as_slice()}));
    }
    (worst, states)
}

fn run_json(r: &Row) -> serde_json::Value {
    json!({
        "solver": r.solver, "tol": r.tol, "ms": if r.runs > 0 { json!(r.ms) } else { json!(null) }, "runs": r.runs,
        "onsets": r.run.onsets, "onset_speeds": r.run.onset_speeds, "peaks": r.run.peaks,
        "theta": r.run.end[0], "theta_dot": r.run.end[1], "tip_x": r.run.end[2], "tip_y": r.run.end[3], "v_l": r.run.end[4],
        "steps": r.run.steps, "contact_steps": r.run.contact_steps, "rhs_evals": r.run.rhs_evals,
    })
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |name: &str| args.iter().position(|a| a == name).map(|i| args.get(i + 1).expect("a value").clone());
    let json_path = arg("--json");
    let reps: usize = arg("--reps").map_or(3, |r| r.parse().expect("--reps N"));
    let quick = args.iter().any(|a| a == "--quick");
    if let Some(n) = arg("--modes") {
        MODES.set(n.parse().expect("--modes N")).expect("set once");
    }

    let (end_err, dense_err, _) = dop853::self_check();
    assert!(end_err < 1e-10 && dense_err < 1e-10, "DOP853 port is wrong");

    let model = Arc::new(RotatingModel::new(&scene(1e-10)).unwrap());
    let n = model.n_modes();
    let m = n + 1;
    let rot = Rot::new(&model);
    let (rhs_diff, states) = check_rhs(&model, &rot);
    println!("peer right-hand side vs RotatingBeam::accelerations at 5 random states in contact: max |dz''| / |z''| = {rhs_diff:.1e}");
    assert!(rhs_diff < 1e-11, "the peer's equations differ from the library's");
    let mut y0 = vec![0.0; 2 * m];
    y0[..m].copy_from_slice(model.initial_z.as_slice());
    y0[m..].copy_from_slice(model.initial_zd.as_slice());
    let atol_for = |tol: f64| {
        let mut a = vec![tol * POS_SCALE; 2 * m];
        for v in &mut a[m..] {
            *v = tol * VEL_SCALE;
        }
        a
    };
    let mut rot_cap = rot.clone();
    rot_cap.phase = Phase::Open;
    println!(
        "{n} modes, omega_N = {:.4e} rad/s, free-flight cap 3/omega_N = {:.3e} s; T_END = {T_END} s",
        model.beam.omega(n),
        CAP / model.beam.omega(n)
    );

    let (bs_tols, peer_tols): (&[f64], &[f64]) = if quick { (&[1e-6, 1e-9], &[1e-6, 1e-9]) } else { (&BS_TOLS, &PEER_TOLS) };
    let mut rows: Vec<Row> = Vec::new();
    let clock = Instant::now();
    for &tol in bs_tols {
        let mdl = Arc::new(RotatingModel::new(&scene(tol)).unwrap());
        match timed(reps, || beamstop_run(&mdl)) {
            Ok((ms, count, run)) => {
                println!("beamstop  {tol:.0e}: {ms:9.2} ms ({count} runs), {} contacts, {} steps ({} in contact)", run.onsets.len(), run.steps, run.contact_steps);
                rows.push(Row { solver: "beamstop", tol, ms, runs: count, run });
            }
            Err(e) => println!("beamstop  {tol:.0e}: failed: {e}"),
        }
    }
    for (solver, capped) in [("dop853", false), ("dop853cap", true)] {
        for &tol in peer_tols {
            let atol = atol_for(tol);
            match timed(reps, || peer(&model, &rot, &y0, tol, &atol, capped)) {
                Ok((ms, count, run)) => {
                    println!(
                        "{solver:<9} {tol:.0e}: {ms:9.2} ms ({count} runs), {} contacts, {} step attempts ({} accepted in contact)",
                        run.onsets.len(),
                        run.steps,
                        run.contact_steps
                    );
                    rows.push(Row { solver, tol, ms, runs: count, run });
                }
                Err(e) => println!("{solver:<9} {tol:.0e}: failed: {e}"),
            }
        }
    }
    // Untimed reference candidates.
    if !quick {
        let mdl = Arc::new(RotatingModel::new(&scene(1e-13)).unwrap());
        match beamstop_run(&mdl) {
            Ok(run) => rows.push(Row { solver: "beamstop", tol: 1e-13, ms: f64::NAN, runs: 0, run }),
            Err(e) => println!("beamstop 1e-13: failed: {e}"),
        }
        for (solver, capped) in [("dop853", false), ("dop853cap", true)] {
            match peer(&model, &rot, &y0, 1e-14, &atol_for(1e-14), capped) {
                Ok(run) => rows.push(Row { solver, tol: 1e-14, ms: f64::NAN, runs: 0, run }),
                Err(e) => println!("{solver} 1e-14: failed: {e}"),
            }
        }
    }
    println!("(all runs: {:.1} s)", clock.elapsed().as_secs_f64());

    let reference = rows
        .iter()
        .filter(|r| r.solver == "dop853cap")
        .min_by(|a, b| a.tol.total_cmp(&b.tol))
        .map(|r| r.run.clone())
        .expect("a reference");
    let ref_tol = rows.iter().filter(|r| r.solver == "dop853cap").map(|r| r.tol).fold(f64::INFINITY, f64::min);
    println!(
        "against dop853cap {ref_tol:.0e}: {} contacts, first peak {:.6} N, end theta {:.12}, tip ({:.12}, {:.12})",
        reference.onsets.len(),
        reference.peaks[0],
        reference.end[0],
        reference.end[2],
        reference.end[3]
    );
    println!("{:<9} {:>6} {:>10} {:>9} {:>10} {:>10} {:>10} {:>8} {:>8}", "solver", "tol", "ms", "contacts", "peak1 rel", "tip /L", "theta", "steps", "contact");
    let length = model.beam.params.length;
    for r in &rows {
        let peak = (r.run.peaks.first().copied().unwrap_or(f64::NAN) - reference.peaks[0]).abs() / reference.peaks[0];
        let tip = (r.run.end[2] - reference.end[2]).hypot(r.run.end[3] - reference.end[3]) / length;
        let th = (r.run.end[0] - reference.end[0]).abs();
        println!(
            "{:<9} {:>6.0e} {:>10.2} {:>9} {peak:>10.2e} {tip:>10.2e} {th:>10.2e} {:>8} {:>8}",
            r.solver,
            r.tol,
            r.ms,
            r.run.onsets.len(),
            r.run.steps,
            r.run.contact_steps
        );
    }

    if let Some(path) = json_path {
        let spec = scene(1e-10);
        let s = model.surface.as_ref().unwrap();
        let beamstop::contact::Law::Hertz(law) = &s.law else { panic!("the peer models a Hertz surface") };
        let alpha = match law.damping {
            ContactDamping::LankaraniNikravesh => 0.75 * (1.0 - law.restitution * law.restitution),
            ContactDamping::HuntCrossley => 1.5 * (1.0 - law.restitution),
            ContactDamping::Linear => 0.0,
        };
        let out = json!({
            "t_end": T_END,
            "reps": reps,
            "pos_scale": POS_SCALE,
            "vel_scale": VEL_SCALE,
            "cap": CAP,
            "scene": serde_json::to_value(&spec).unwrap(),
            "alpha": alpha,
            "omega_n": model.beam.omega(n),
            "rhs_check": {"max_rel_diff": rhs_diff, "states": states},
            "runs": rows.iter().map(run_json).collect::<Vec<_>>(),
        });
        std::fs::write(&path, serde_json::to_string_pretty(&out).unwrap()).expect("json");
        println!("wrote {path}");
    }
}
