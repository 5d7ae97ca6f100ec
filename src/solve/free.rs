//! Free flight: uncoupled modal oscillators under a known load, propagated in
//! closed form from the state at the last event (the segment's anchor).
//!
//! The state at any time is computed from the anchor, never by chaining
//! communication steps, so results do not depend on the step size.

use nalgebra::DVector;

use super::elementary::{sin_cos, unit};
use super::events::split_certificate;
use super::forcing::ModalForcing;
use super::functional::{DerivativeBounds, Functional, Jet, NOISE};
use super::oscillator::{Oscillator, C64};

/// The free dynamics: one oscillator per mode and the modal load.
#[derive(Clone, Debug, PartialEq)]
pub struct FreeDynamics {
    pub oscillators: Vec<Oscillator>,
    pub forcing: ModalForcing,
    /// `forcing.bounds()`, kept with it.
    force_bounds: [DVector<f64>; 5],
    /// Per mode, what every segment shares: the steady responses' factors
    /// and bounds (the rotation to a segment's start changes neither modulus).
    mode_loads: Vec<ModeLoad>,
}

#[derive(Clone, Debug, PartialEq)]
struct ModeLoad {
    /// The static response to the constant load, `c_j / omega_j^2`.
    x_static: f64,
    /// Per harmonic: `1 / (omega^2 - Omega^2 + 2 i a Omega)` far from
    /// resonance, `None` near it (the response is then taken from rest).
    inverse_stiffness: Vec<Option<C64>>,
    /// `|x_static| + sum |P b|` and `sum |P b| W^m` (m = 1..=5).
    steady_bounds: [f64; 6],
    /// `sum |b| W^m` (m = 0..=4) over the near-resonant harmonics.
    resonant_bounds: [f64; 5],
}

impl FreeDynamics {
    pub fn new(oscillators: Vec<Oscillator>, forcing: ModalForcing) -> Self {
        let force_bounds = forcing.bounds();
        let mode_loads = mode_loads(&oscillators, &forcing);
        FreeDynamics { oscillators, forcing, force_bounds, mode_loads }
    }

    pub fn set_forcing(&mut self, forcing: ModalForcing) {
        self.force_bounds = forcing.bounds();
        self.mode_loads = mode_loads(&self.oscillators, &forcing);
        self.forcing = forcing;
    }
}

fn mode_loads(oscillators: &[Oscillator], forcing: &ModalForcing) -> Vec<ModeLoad> {
    // Moduli computed once here carry a relative margin for rounding.
    let up = 1.0 + 8.0 * f64::EPSILON;
    oscillators
        .iter()
        .enumerate()
        .map(|(j, osc)| {
            let x_static = forcing.constant[j] / (osc.omega * osc.omega);
            let mut steady_bounds = [0.0; 6];
            let mut resonant_bounds = [0.0; 5];
            steady_bounds[0] = x_static.abs();
            let inverse_stiffness = forcing
                .harmonics
                .iter()
                .map(|h| {
                    let (inverse, magnitude, target): (Option<C64>, f64, &mut [f64]) = if osc.near_resonance(h.omega) {
                        (None, h.amplitude[j].norm() * up, &mut resonant_bounds)
                    } else {
                        let inverse = 1.0 / osc.dynamic_stiffness(h.omega);
                        (Some(inverse), (h.amplitude[j] * inverse).norm() * up, &mut steady_bounds)
                    };
                    let mut p = magnitude;
                    for m in target.iter_mut() {
                        *m += p;
                        p *= h.omega;
                    }
                    inverse
                })
                .collect();
            ModeLoad { x_static, inverse_stiffness, steady_bounds, resonant_bounds }
        })
        .collect()
}

#[derive(Clone, Debug, PartialEq)]
enum HarmonicPart {
    /// Steady-state amplitude `P b~`, far from resonance.
    Steady(C64),
    /// Response from rest to `b~ e^{i Omega s}`, near resonance.
    FromRest(C64),
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct ModeSegment {
    /// Homogeneous part: `x_h = alpha Ec + beta Es`.
    alpha: f64,
    beta: f64,
    /// Static response to the constant load.
    x_static: f64,
    /// The anchor's own state: the state at `t0` is the anchor, bit for bit.
    q0: f64,
    qd0: f64,
}

/// Closed-form free motion from an anchor `(t0, q0, qd0)`.
#[derive(Clone, Debug, PartialEq)]
pub struct FreeSegment {
    pub t0: f64,
    modes: Vec<ModeSegment>,
    /// Each mode's part of each harmonic load, mode by mode (`modes.len()`
    /// rows of `harmonics` entries).
    parts: Vec<HarmonicPart>,
    /// `e^{i Omega t0}` per harmonic.
    start_rotations: Vec<C64>,
}

/// The modal state `(q, qd)`.
#[derive(Clone, Debug, PartialEq)]
pub struct ModalState {
    pub q: DVector<f64>,
    pub qd: DVector<f64>,
}

impl ModalState {
    pub fn zeros(n: usize) -> Self {
        ModalState { q: DVector::zeros(n), qd: DVector::zeros(n) }
    }
}

impl FreeSegment {
    pub fn new(dynamics: &FreeDynamics, t0: f64, start: &ModalState) -> Self {
        let mut segment = FreeSegment { t0, modes: Vec::new(), parts: Vec::new(), start_rotations: Vec::new() };
        segment.reset(dynamics, t0, start);
        segment
    }

    /// Restarts the segment from a new anchor, in place (the event loop
    /// does this at every impact: no allocation once the sizes are known).
    pub fn reset(&mut self, dynamics: &FreeDynamics, t0: f64, start: &ModalState) {
        self.t0 = t0;
        // Written in place over the previous anchor's entries (plain loops
        // over slices: the event loop resets at every impact).
        let harmonics = &dynamics.forcing.harmonics[..];
        let (n, n_harmonics) = (dynamics.oscillators.len(), harmonics.len());
        let zero = C64::new(0.0, 0.0);
        self.start_rotations.resize(n_harmonics, zero);
        for (rotation, h) in self.start_rotations.iter_mut().zip(harmonics) {
            *rotation = unit(h.omega * t0);
        }
        self.modes.resize(n, ModeSegment { alpha: 0.0, beta: 0.0, x_static: 0.0, q0: 0.0, qd0: 0.0 });
        self.parts.resize(n * n_harmonics, HarmonicPart::Steady(zero));
        let (q, qd) = (start.q.as_slice(), start.qd.as_slice());
        for (j, ((osc, load), seg)) in dynamics.oscillators.iter().zip(&dynamics.mode_loads).zip(self.modes.iter_mut()).enumerate() {
            let x_static = load.x_static;
            let mut x0 = q[j] - x_static;
            let mut v0 = qd[j];
            let parts = &mut self.parts[j * n_harmonics..(j + 1) * n_harmonics];
            for (((h, rotation), inverse), part) in harmonics.iter().zip(&self.start_rotations).zip(&load.inverse_stiffness).zip(parts) {
                let b = h.amplitude.as_slice()[j] * rotation;
                *part = match inverse {
                    None => HarmonicPart::FromRest(b),
                    Some(inverse) => {
                        let pb = b * inverse;
                        x0 -= pb.re;
                        v0 += h.omega * pb.im;
                        HarmonicPart::Steady(pb)
                    }
                };
            }
            *seg = ModeSegment { alpha: x0, beta: v0 + osc.a * x0, x_static, q0: q[j], qd0: qd[j] };
        }
    }

    /// The modal state at time `t >= t0`.
    pub fn state_at(&self, dynamics: &FreeDynamics, t: f64, out: &mut ModalState) {
        self.evaluate(dynamics, t, out, None);
    }

    /// The state at `t`, and the displacement since the anchor
    /// `q(t) - q(t0)` with the size of the terms summed into it: computed
    /// as an increment, it stays accurate relative to itself however small
    /// (the flights of a chatter sequence rise 1e-11 above the stop).
    pub fn state_and_increment_at(&self, dynamics: &FreeDynamics, t: f64, out: &mut ModalState, increment: &mut Increment) {
        self.evaluate(dynamics, t, out, Some(increment));
    }

    fn evaluate(&self, dynamics: &FreeDynamics, t: f64, out: &mut ModalState, increment: Option<&mut Increment>) {
        let s = t - self.t0;
        if s == 0.0 {
            // The probe right after an event: no kernels to evaluate.
            self.at_anchor(dynamics, out, increment);
            return;
        }
        self.evaluate_after_anchor(dynamics, s, out, increment);
    }

    /// [`Self::evaluate`] at the anchor: its state, a zero increment, and
    /// the steady response summed as at any other time.
    fn at_anchor(&self, dynamics: &FreeDynamics, out: &mut ModalState, increment: Option<&mut Increment>) {
        let n = self.modes.len();
        let (q, qd) = (&mut out.q.as_mut_slice()[..n], &mut out.qd.as_mut_slice()[..n]);
        for (j, seg) in self.modes.iter().enumerate() {
            (q[j], qd[j]) = (seg.q0, seg.qd0);
        }
        let Some(inc) = increment else { return };
        inc.rotations.clear();
        inc.rotations.extend_from_slice(&self.start_rotations);
        let harmonics = &dynamics.forcing.harmonics;
        let n_harmonics = harmonics.len();
        let (dq, size) = (&mut inc.dq.as_mut_slice()[..n], &mut inc.size.as_mut_slice()[..n]);
        let (steady_q, steady_qd) = (&mut inc.steady_q.as_mut_slice()[..n], &mut inc.steady_qd.as_mut_slice()[..n]);
        for (j, seg) in self.modes.iter().enumerate() {
            let (mut xp, mut vp) = (seg.x_static, 0.0);
            for (part, h) in self.parts[j * n_harmonics..(j + 1) * n_harmonics].iter().zip(harmonics) {
                if let HarmonicPart::Steady(pb) = part {
                    xp += pb.re;
                    vp -= h.omega * pb.im;
                }
            }
            (dq[j], size[j], steady_q[j], steady_qd[j]) = (0.0, 0.0, xp, vp);
        }
    }

    fn evaluate_after_anchor(&self, dynamics: &FreeDynamics, s: f64, out: &mut ModalState, mut increment: Option<&mut Increment>) {
        // e^{i W s} and e^{i W s} - 1 without cancellation, shared by
        // every mode: one sin_cos of the half angle for both.
        let rotation = |h: &super::forcing::Harmonic| {
            let (sh, ch) = sin_cos(0.5 * h.omega * s);
            let m1 = C64::new(-2.0 * sh * sh, 2.0 * sh * ch);
            (C64::new(1.0 + m1.re, m1.im), m1)
        };
        let harmonics = &dynamics.forcing.harmonics;
        // Up to four harmonics on the stack (the buffer is zeroed at every
        // probe: eight cost S3 1 % of its time), more in a vector.
        let mut buffer = [(C64::new(0.0, 0.0), C64::new(0.0, 0.0)); 4];
        let many: Vec<(C64, C64)>;
        let rotations: &[(C64, C64)] = if harmonics.len() <= buffer.len() {
            for (r, h) in buffer.iter_mut().zip(harmonics) {
                *r = rotation(h);
            }
            &buffer[..harmonics.len()]
        } else {
            many = harmonics.iter().map(rotation).collect();
            &many
        };
        let n_harmonics = harmonics.len();
        let n = self.modes.len();
        let (q, qd) = (&mut out.q.as_mut_slice()[..n], &mut out.qd.as_mut_slice()[..n]);
        let oscillators = &dynamics.oscillators[..n];
        let parts = &self.parts[..n * n_harmonics];
        let Some(inc) = increment.as_deref_mut() else {
            for (j, (seg, osc)) in self.modes.iter().zip(oscillators).enumerate() {
                let (ec, es) = osc.kernels(s);
                let v0 = seg.beta - osc.a * seg.alpha;
                let mut x = seg.alpha * ec + seg.beta * es + seg.x_static;
                let mut v = v0 * ec - (osc.a * v0 + osc.omega * osc.omega * seg.alpha) * es;
                let mode_parts = &parts[j * n_harmonics..(j + 1) * n_harmonics];
                for ((part, h), (rot, _)) in mode_parts.iter().zip(harmonics).zip(rotations) {
                    match part {
                        HarmonicPart::Steady(pb) => {
                            let z = pb * rot;
                            x += z.re;
                            v -= h.omega * z.im;
                        }
                        HarmonicPart::FromRest(b) => {
                            let (g, gd) = osc.harmonic_from_rest(h.omega, s, *rot);
                            x += (b * g).re;
                            v += (b * gd).re;
                        }
                    }
                }
                q[j] = x;
                qd[j] = v;
            }
            return;
        };
        // e^{i Omega t} = e^{i Omega t0} e^{i Omega s}, for the load's derivatives.
        inc.rotations.clear();
        inc.rotations.extend(self.start_rotations.iter().zip(rotations).map(|(a, (r, _))| a * r));
        let dq = &mut inc.dq.as_mut_slice()[..n];
        let size = &mut inc.size.as_mut_slice()[..n];
        let steady_q = &mut inc.steady_q.as_mut_slice()[..n];
        let steady_qd = &mut inc.steady_qd.as_mut_slice()[..n];
        for (j, (seg, osc)) in self.modes.iter().zip(oscillators).enumerate() {
            let (ec, es, ec_m1) = osc.kernels_and_increment(s);
            let v0 = seg.beta - osc.a * seg.alpha;
            let mut x = seg.alpha * ec + seg.beta * es + seg.x_static;
            let mut v = v0 * ec - (osc.a * v0 + osc.omega * osc.omega * seg.alpha) * es;
            let (mut d, mut sz) = (seg.alpha * ec_m1 + seg.beta * es, (seg.alpha * ec_m1).abs() + (seg.beta * es).abs());
            let (mut xp, mut vp) = (seg.x_static, 0.0);
            let mode_parts = &parts[j * n_harmonics..(j + 1) * n_harmonics];
            for ((part, h), (rot, rot_m1)) in mode_parts.iter().zip(harmonics).zip(rotations) {
                match part {
                    HarmonicPart::Steady(pb) => {
                        let z = pb * rot;
                        x += z.re;
                        v -= h.omega * z.im;
                        xp += z.re;
                        vp -= h.omega * z.im;
                        let dz = pb * rot_m1;
                        d += dz.re;
                        // |re| + |im| >= |dz|: a size, without hypot.
                        sz += dz.re.abs() + dz.im.abs();
                    }
                    HarmonicPart::FromRest(b) => {
                        let (g, gd) = osc.harmonic_from_rest(h.omega, s, *rot);
                        let bg = b * g;
                        x += bg.re;
                        v += (b * gd).re;
                        d += bg.re;
                        sz += bg.re.abs() + bg.im.abs();
                    }
                }
            }
            q[j] = x;
            qd[j] = v;
            dq[j] = d;
            size[j] = sz;
            steady_q[j] = xp;
            steady_qd[j] = vp;
        }
    }
}

/// The displacement since a segment's anchor, the size of its terms, and
/// the steady response to the non-resonant loads at the same time.
#[derive(Clone, Debug)]
pub struct Increment {
    pub dq: DVector<f64>,
    pub size: DVector<f64>,
    pub steady_q: DVector<f64>,
    pub steady_qd: DVector<f64>,
    /// `e^{i Omega t}` of each harmonic load at the same time.
    pub rotations: Vec<C64>,
}

impl Increment {
    pub fn new(n: usize) -> Self {
        Increment {
            dq: DVector::zeros(n),
            size: DVector::zeros(n),
            steady_q: DVector::zeros(n),
            steady_qd: DVector::zeros(n),
            rotations: Vec::new(),
        }
    }

    /// `a . dq` and its rounding noise.
    pub fn functional(&self, a: &DVector<f64>) -> (f64, f64) {
        let (mut value, mut size) = (0.0, 0.0);
        for ((x, d), s) in a.as_slice().iter().zip(self.dq.as_slice()).zip(self.size.as_slice()) {
            value += x * d;
            size += (x * s).abs();
        }
        (value, NOISE * size)
    }
}

impl FreeSegment {
    /// [`Self::fill_bounds`] then [`ModalBounds::functional`] for a
    /// displacement functional `offset + a . q`, in the same order (the same
    /// bits), without the per-mode arrays.
    pub fn displacement_bounds(&self, dynamics: &FreeDynamics, state: &ModalState, sample: &Increment, tau: f64, h: &Functional) -> DerivativeBounds {
        debug_assert!(h.qd.is_none() && h.f.is_none());
        let n = dynamics.oscillators.len().min(h.q.len());
        let a = &h.q.as_slice()[..n];
        let (q, qd) = (&state.q.as_slice()[..n], &state.qd.as_slice()[..n]);
        let (sq, sqd) = (&sample.steady_q.as_slice()[..n], &sample.steady_qd.as_slice()[..n]);
        let (mut m, mut level) = ([0.0; 3], 0.0);
        for (j, (load, osc)) in dynamics.mode_loads[..n].iter().zip(&dynamics.oscillators).enumerate() {
            let b = mode_bounds(load, osc, q[j] - sq[j], qd[j] - sqd[j], tau);
            let wa = a[j].abs();
            for k in 0..3 {
                m[k] += wa * b[k + 2];
            }
            level += wa * b[0];
        }
        DerivativeBounds { tau, m, floor: [NOISE * level, 0.0, 0.0, 0.0] }
    }

    /// Bounds on `|q_j^(m)|` over `[t, t + tau]`: the steady response to the
    /// loads far from resonance is known exactly (`|x_p^(m)| <= sum |P b| W^m`),
    /// and what remains obeys the oscillator loaded only by the near-resonant
    /// harmonics, so its energy amplitude `sqrt(r'^2 + omega^2 r^2)` grows by
    /// at most their size per unit time; the equation of motion bounds the
    /// higher derivatives.
    /// `sample` is the state's split made by [`Self::state_and_increment_at`]
    /// at the same time.
    pub fn fill_bounds(&self, dynamics: &FreeDynamics, state: &ModalState, sample: &Increment, tau: f64, out: &mut ModalBounds) {
        let n = dynamics.oscillators.len();
        let (q, qd) = (&state.q.as_slice()[..n], &state.qd.as_slice()[..n]);
        let (sq, sqd) = (&sample.steady_q.as_slice()[..n], &sample.steady_qd.as_slice()[..n]);
        let [b0, b1, b2, b3, b4, b5] = &mut out.b;
        let b = [&mut b0.as_mut_slice()[..n], &mut b1.as_mut_slice()[..n], &mut b2.as_mut_slice()[..n], &mut b3.as_mut_slice()[..n], &mut b4.as_mut_slice()[..n], &mut b5.as_mut_slice()[..n]];
        for (j, (load, osc)) in dynamics.mode_loads[..n].iter().zip(&dynamics.oscillators).enumerate() {
            let bj = mode_bounds(load, osc, q[j] - sq[j], qd[j] - sqd[j], tau);
            for m in 0..6 {
                b[m][j] = bj[m];
            }
        }
    }
}

/// Bounds on `|q_j^(m)|`, m = 0..=5, over `[t, t + tau]` for one mode
/// (see [`FreeSegment::fill_bounds`]): `(rq, rv)` is its state less the
/// steady response to the non-resonant loads.
fn mode_bounds(load: &ModeLoad, osc: &Oscillator, rq: f64, rv: f64, tau: f64) -> [f64; 6] {
    let w = osc.omega;
    let resonant = &load.resonant_bounds;
    let amp = transient_energy_amplitude(load, osc, rq, rv, tau);
    let mut r = [0.0; 6];
    r[0] = amp * osc.inv_omega;
    r[1] = amp;
    for m in 2..6 {
        r[m] = resonant[m - 2] + 2.0 * osc.a * r[m - 1] + w * w * r[m - 2];
    }
    for m in 0..6 {
        r[m] += load.steady_bounds[m];
    }
    r
}

/// A bound over `[t, t + tau]` on the energy amplitude `sqrt(r'^2 + omega^2
/// r^2)` of one mode's transient `r` (its state less the steady response
/// to the loads far from resonance, `(rq, rv)` now): without load it does
/// not grow (damping only takes energy), and the near-resonant loads add
/// at most their size per unit time. `|r| <= amplitude / omega`.
#[inline]
fn transient_energy_amplitude(load: &ModeLoad, osc: &Oscillator, rq: f64, rv: f64, tau: f64) -> f64 {
    let w = osc.omega;
    (rv * rv + w * w * rq * rq).sqrt() + load.resonant_bounds[0] * tau
}

impl FreeSegment {
    /// A certified step for a displacement functional `h = offset + a . q`
    /// (value and derivatives `jet` at the probe, plain bounds `plain`)
    /// from splitting every mode into its transient and its steady
    /// response, as [`crate::solve::lti::CoupledSegment`] does in a contact
    /// phase: `h = h_S + h_T` with `h_T = sum a_j (q_j - qs_j)`, at most
    /// `sum |a_j| A_j / omega_j` over the interval
    /// ([`transient_energy_amplitude`]), and `h_S` the steady responses to
    /// the constant and far-from-resonance loads, which move at the loads'
    /// pace: `|h_S^(m)| <= sum |a_j| sum |P b| W^m`. A long flight far from
    /// the stop, once the impact's ringing has fallen below the clearance,
    /// steps at the load's pace instead of a fraction of the first mode's
    /// period. `sample` is the state's split made by
    /// [`Self::state_and_increment_at`] at the same time; 0 when the
    /// transients' amplitude exceeds the value (the steady derivatives are
    /// only formed where the split can certify).
    pub fn transient_split_step(&self, dynamics: &FreeDynamics, state: &ModalState, sample: &Increment, h: &Functional, jet: &Jet, plain: &DerivativeBounds) -> f64 {
        if h.qd.is_some() || h.f.is_some() {
            return 0.0;
        }
        let n = dynamics.oscillators.len().min(h.q.len());
        let a = &h.q.as_slice()[..n];
        let (q, qd) = (&state.q.as_slice()[..n], &state.qd.as_slice()[..n]);
        let (sq, sqd) = (&sample.steady_q.as_slice()[..n], &sample.steady_qd.as_slice()[..n]);
        let (oscillators, loads) = (&dynamics.oscillators[..n], &dynamics.mode_loads[..n]);
        let (mut value, mut amp, mut size) = (0.0, 0.0, 0.0);
        for j in 0..n {
            let (rq, rv) = (q[j] - sq[j], qd[j] - sqd[j]);
            value += a[j] * rq;
            amp += a[j].abs() * (transient_energy_amplitude(&loads[j], &oscillators[j], rq, rv, plain.tau) / oscillators[j].omega);
            size += (a[j] * q[j]).abs() + (a[j] * sq[j]).abs();
        }
        if !(jet.d[0] - value - amp > 0.0) {
            return 0.0;
        }
        // The steady responses' derivatives: `x_s' = qs'` and
        // `Re(P b (i W)^m e^{i W t})` for m = 2, 3.
        let harmonics = &dynamics.forcing.harmonics;
        let (mut steady, mut m) = ([0.0; 3], [0.0; 3]);
        for j in 0..n {
            steady[0] += a[j] * sqd[j];
            for ((harmonic, inverse), rotation) in harmonics.iter().zip(&loads[j].inverse_stiffness).zip(&sample.rotations) {
                if let Some(inverse) = inverse {
                    let w = harmonic.omega;
                    let z = harmonic.amplitude[j] * inverse * rotation;
                    // (i W)^2 z and (i W)^3 z.
                    let (second, third) = (-w * w * z, C64::new(w * w * w * z.im, -w * w * w * z.re));
                    steady[1] += a[j] * second.re;
                    steady[2] += a[j] * third.re;
                }
            }
            for k in 0..3 {
                m[k] += a[j].abs() * loads[j].steady_bounds[k + 2];
            }
        }
        let bounds = DerivativeBounds { tau: plain.tau, m, floor: plain.floor };
        split_certificate(jet, value, amp, size + amp, steady, &bounds)
    }
}

/// Time derivatives of every modal coordinate at one instant, and the load's.
#[derive(Clone, Debug)]
pub struct ModalJet {
    /// `q^(m)` for m = 0..=4.
    pub q: [DVector<f64>; 5],
    /// `f^(m)` for m = 0..=3.
    pub f: [DVector<f64>; 4],
    /// Magnitude of the terms summed into `q^(m)`, for noise estimates.
    pub scale: [DVector<f64>; 5],
}

impl ModalJet {
    pub fn new(n: usize) -> Self {
        let z = || DVector::zeros(n);
        ModalJet { q: [z(), z(), z(), z(), z()], f: [z(), z(), z(), z()], scale: [z(), z(), z(), z(), z()] }
    }

    /// Fills the jet of the free dynamics from the state at time `t`:
    /// `q'' = f - 2 a q' - omega^2 q` differentiated twice.
    pub fn fill_free(&mut self, dynamics: &FreeDynamics, t: f64, state: &ModalState) {
        dynamics.forcing.derivatives(t, &mut self.f);
        self.fill_from_load(dynamics, state);
    }

    /// As [`Self::fill_free`], with the loads' rotations `e^{i Omega t}`
    /// given (a probe has them from the state's evaluation).
    pub fn fill_free_rotated(&mut self, dynamics: &FreeDynamics, rotations: &[C64], state: &ModalState) {
        dynamics.forcing.derivatives_rotated(rotations, &mut self.f);
        self.fill_from_load(dynamics, state);
    }

    fn fill_from_load(&mut self, dynamics: &FreeDynamics, state: &ModalState) {
        let n = dynamics.oscillators.len().min(self.q[0].len());
        let oscillators = &dynamics.oscillators[..n];
        let (x, v) = (&state.q.as_slice()[..n], &state.qd.as_slice()[..n]);
        // Destructured by hand: `each_mut().map(..)` is an out-of-line call.
        let [f0, f1, f2, _] = &self.f;
        let (f0, f1, f2) = (&f0.as_slice()[..n], &f1.as_slice()[..n], &f2.as_slice()[..n]);
        let [q0, q1, q2, q3, q4] = &mut self.q;
        let (q0, q1, q2, q3, q4) = (&mut q0.as_mut_slice()[..n], &mut q1.as_mut_slice()[..n], &mut q2.as_mut_slice()[..n], &mut q3.as_mut_slice()[..n], &mut q4.as_mut_slice()[..n]);
        let [s0, s1, s2, s3, s4] = &mut self.scale;
        let (s0, s1, s2, s3, s4) = (&mut s0.as_mut_slice()[..n], &mut s1.as_mut_slice()[..n], &mut s2.as_mut_slice()[..n], &mut s3.as_mut_slice()[..n], &mut s4.as_mut_slice()[..n]);
        for j in 0..n {
            let (d, c) = mode_jet(&oscillators[j], x[j], v[j], [f0[j], f1[j], f2[j]]);
            (q0[j], q1[j], q2[j], q3[j], q4[j]) = (d[0], d[1], d[2], d[3], d[4]);
            (s0[j], s1[j], s2[j], s3[j], s4[j]) = (c[0], c[1], c[2], c[3], c[4]);
        }
    }

    /// The jet of a displacement functional `offset + a . q` at time `t`,
    /// straight from the state and the loads' rotations `e^{i Omega t}`:
    /// the sums of [`Self::fill_free_rotated`] then [`Self::functional`],
    /// in the same order (the same bits), without the modal arrays.
    pub fn displacement_jet(dynamics: &FreeDynamics, rotations: &[C64], state: &ModalState, h: &Functional, t: f64) -> Jet {
        debug_assert!(h.qd.is_none() && h.f.is_none());
        let n = dynamics.oscillators.len().min(h.q.len());
        let (a, x, v) = (&h.q.as_slice()[..n], &state.q.as_slice()[..n], &state.qd.as_slice()[..n]);
        let (mut sum, mut size) = ([0.0; 4], [0.0; 4]);
        for j in 0..n {
            let f = dynamics.forcing.mode_derivatives_rotated::<2>(j, rotations);
            let (d, c) = mode_jet(&dynamics.oscillators[j], x[j], v[j], f);
            // `weighted_sums`.
            let w = a[j];
            let wa = w.abs();
            for m in 0..4 {
                sum[m] += w * d[m];
                size[m] += wa * c[m];
            }
        }
        let mut jet = Jet { d: sum, ..Jet::default() };
        jet.d[0] += h.offset;
        size[0] += h.offset.abs();
        for m in 0..4 {
            jet.noise[m] = NOISE * size[m];
        }
        jet.with_time_uncertainty(t)
    }

    /// The value and first three derivatives of a functional at the jet's
    /// time `t`.
    pub fn functional(&self, h: &Functional, t: f64) -> Jet {
        let mut jet = Jet::default();
        let (value, mut size) = weighted_sums(h.q.as_slice(), &self.q[..4], &self.scale[..4]);
        jet.d = value;
        jet.d[0] += h.offset;
        size[0] += h.offset.abs();
        if let Some(b) = &h.qd {
            let (v, s) = weighted_sums(b.as_slice(), &self.q[1..5], &self.scale[1..5]);
            for m in 0..4 {
                jet.d[m] += v[m];
                size[m] += s[m];
            }
        }
        if let Some(c) = &h.f {
            let (v, s) = weighted_sums(c.as_slice(), &self.f, &self.f);
            for m in 0..4 {
                jet.d[m] += v[m];
                size[m] += s[m];
            }
        }
        for m in 0..4 {
            jet.noise[m] = NOISE * size[m];
        }
        jet.with_time_uncertainty(t)
    }
}

/// One mode's `q, q', q'', ...` up to order `K + 1` (at most 4) from its state
/// and the load's derivatives `f, f', ..` (`q'' = f - 2 a q' - omega^2 q`
/// differentiated), and the magnitudes summed into each (higher orders 0).
#[inline]
fn mode_jet<const K: usize>(osc: &Oscillator, x: f64, v: f64, f: [f64; K]) -> ([f64; 5], [f64; 5]) {
    let (w2, two_a) = (osc.omega * osc.omega, 2.0 * osc.a);
    let (mut d, mut c) = ([x, v, 0.0, 0.0, 0.0], [x.abs(), v.abs(), 0.0, 0.0, 0.0]);
    for (m, fm) in f.iter().enumerate().take(3) {
        d[m + 2] = fm - two_a * d[m + 1] - w2 * d[m];
        c[m + 2] = fm.abs() + two_a * c[m + 1] + w2 * c[m];
    }
    (d, c)
}

/// `sum_j a_j x[m]_j` and `sum_j |a_j scale[m]_j|` for m = 0..4, in one pass.
fn weighted_sums(a: &[f64], x: &[DVector<f64>], scale: &[DVector<f64>]) -> ([f64; 4], [f64; 4]) {
    let (x0, x1, x2, x3) = (x[0].as_slice(), x[1].as_slice(), x[2].as_slice(), x[3].as_slice());
    let (s0, s1, s2, s3) = (scale[0].as_slice(), scale[1].as_slice(), scale[2].as_slice(), scale[3].as_slice());
    let n = a.len().min(x0.len()).min(x1.len()).min(x2.len()).min(x3.len());
    let n = n.min(s0.len()).min(s1.len()).min(s2.len()).min(s3.len());
    let mut v = [0.0; 4];
    let mut s = [0.0; 4];
    for j in 0..n {
        let w = a[j];
        v[0] += w * x0[j];
        v[1] += w * x1[j];
        v[2] += w * x2[j];
        v[3] += w * x3[j];
        let wa = w.abs();
        s[0] += wa * s0[j].abs();
        s[1] += wa * s1[j].abs();
        s[2] += wa * s2[j].abs();
        s[3] += wa * s3[j].abs();
    }
    (v, s)
}

/// Bounds on `|q_j^(m)|`, m = 0..=5, over `[t, t + tau]` for the free motion
/// starting from `state`: the modal energy amplitude `sqrt(qd^2 + omega^2 q^2)`
/// grows at most by `|f|` per unit time, and the equation of motion bounds
/// the higher derivatives.
#[derive(Clone, Debug)]
pub struct ModalBounds {
    pub b: [DVector<f64>; 6],
    pub f: [DVector<f64>; 5],
}

impl ModalBounds {
    /// Work space for the bounds of `dynamics`, with its load bounds.
    pub fn new(dynamics: &FreeDynamics) -> Self {
        let n = dynamics.oscillators.len();
        let z = || DVector::zeros(n);
        ModalBounds { b: [z(), z(), z(), z(), z(), z()], f: dynamics.force_bounds.clone() }
    }

    pub fn fill_free(&mut self, dynamics: &FreeDynamics, state: &ModalState, tau: f64) {
        for (j, osc) in dynamics.oscillators.iter().enumerate() {
            for m in 0..5 {
                self.f[m][j] = dynamics.force_bounds[m][j];
            }
            let w = osc.omega;
            let amp = (state.qd[j] * state.qd[j] + w * w * state.q[j] * state.q[j]).sqrt() + self.f[0][j] * tau;
            self.b[0][j] = amp / w;
            self.b[1][j] = amp;
            for m in 2..6 {
                self.b[m][j] = self.f[m - 2][j] + 2.0 * osc.a * self.b[m - 1][j] + w * w * self.b[m - 2][j];
            }
        }
    }

    pub fn functional(&self, h: &Functional, tau: f64) -> DerivativeBounds {
        let mut out = DerivativeBounds { tau, m: [0.0; 3], floor: [0.0; 4] };
        let abs_dot = |a: &DVector<f64>, b: &DVector<f64>| a.as_slice().iter().zip(b.as_slice()).map(|(a, b)| a.abs() * b).sum::<f64>();
        for (k, m) in (2..5).enumerate() {
            let mut s = abs_dot(&h.q, &self.b[m]);
            if let Some(bq) = &h.qd {
                s += abs_dot(bq, &self.b[m + 1]);
            }
            if let Some(c) = &h.f {
                s += abs_dot(c, &self.f[m]);
            }
            out.m[k] = s;
        }
        // The rounding level of the displacement part of `h` over the
        // interval: a gap below it (a denormal clearance, say) is zero.
        out.floor[0] = NOISE * abs_dot(&h.q, &self.b[0]);
        out
    }

    /// A certified step for a position functional `h = offset + a . q`
    /// (value and derivatives `jet` at the probe) from splitting the modes:
    /// `h = h_L + h_H` with `h_L` over modes `0..k` and `h_H` over the rest,
    /// `h(t + s) >= h_L(t + s) - sup |h_H|`, with `sup |h_H| <= sum_{j >= k}
    /// |a_j| B0_j` and `h_L` bounded by its own Taylor bound, whose derivative
    /// bounds leave out the high modes. The highest modes carry the largest
    /// derivative bounds (`omega_j^m` times small amplitudes) and, after an
    /// impact has excited them, limit the plain certificate to steps of a
    /// fraction of their period; split off, they cost only their amplitude.
    /// Tries `k = 1, 2, 4, .., n - 1`; 0 when no split certifies.
    pub fn split_step(&self, modal: &ModalJet, h: &Functional, jet: &Jet, tau: f64) -> f64 {
        let a = h.q.as_slice();
        let n = a.len();
        if n < 2 || h.qd.is_some() || h.f.is_some() || jet.d[0] <= jet.noise[0] {
            return 0.0;
        }
        let (b0, b2, b3, b4) = (self.b[0].as_slice(), self.b[2].as_slice(), self.b[3].as_slice(), self.b[4].as_slice());
        let [q0, q1, q2, q3, _] = &modal.q;
        let q = [q0.as_slice(), q1.as_slice(), q2.as_slice(), q3.as_slice()];
        // Candidate splits, ascending.
        let mut splits = [0usize; 64];
        let mut count = 0;
        let mut k = 1;
        while k < n - 1 && count < 63 {
            splits[count] = k;
            count += 1;
            k *= 2;
        }
        splits[count] = n - 1;
        count += 1;
        // Totals of the high part's current value and amplitude bound.
        let (mut value_all, mut amp_all, mut size_all) = (0.0, 0.0, 0.0);
        for j in 0..n {
            value_all += a[j] * q[0][j];
            amp_all += a[j].abs() * b0[j];
            size_all += (a[j] * q[0][j]).abs();
        }
        let mut low = [0.0; 4];
        let mut low_m = [0.0; 3];
        let mut amp_low = 0.0;
        let mut best = 0.0f64;
        let mut next = 0;
        for j in 0..n {
            let aj = a[j];
            for m in 0..4 {
                low[m] += aj * q[m][j];
            }
            amp_low += aj.abs() * b0[j];
            low_m[0] += aj.abs() * b2[j];
            low_m[1] += aj.abs() * b3[j];
            low_m[2] += aj.abs() * b4[j];
            if next < count && splits[next] == j + 1 {
                next += 1;
                let bounds = DerivativeBounds { tau, m: low_m, floor: [0.0; 4] };
                let step = split_certificate(jet, value_all - low[0], amp_all - amp_low, size_all + amp_all, [low[1], low[2], low[3]], &bounds);
                best = best.max(step);
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::events::{certified_step, Certified};
    use nalgebra::dvector;
    use std::f64::consts::PI;

    /// Three modes (undamped, light, over-critical), a constant load and
    /// two harmonics, one resonant with mode 1 (its response taken from rest).
    fn two_harmonic_dynamics() -> FreeDynamics {
        let oscs = vec![Oscillator::new(1.0, 0.0), Oscillator::new(4.0, 0.1), Oscillator::new(9.0, 2.0)];
        let mut forcing = ModalForcing::zero(3);
        forcing.constant = dvector![0.3, -0.2, 0.1];
        forcing.add_harmonic(1.0, dvector![C64::new(0.0, -1.0), C64::new(0.0, -0.5), C64::new(0.2, 0.0)]);
        forcing.add_harmonic(2.5, dvector![C64::new(0.4, 0.1), C64::new(-0.3, 0.0), C64::new(0.0, 0.7)]);
        FreeDynamics::new(oscs, forcing)
    }

    #[test]
    fn displacement_jets_and_bounds_are_the_modal_arrays_sums_bit_for_bit() {
        // Two harmonics (one resonant with mode 1), damping, an offset: the
        // fused sums must give exactly what the modal arrays give.
        let dynamics = two_harmonic_dynamics();
        let start = ModalState { q: dvector![0.1, 0.2, -0.1], qd: dvector![-0.3, 0.4, 0.2] };
        let seg = FreeSegment::new(&dynamics, 0.4, &start);
        let h = Functional::of_position(1.2, dvector![0.9, -0.6, 0.3]);
        let (mut st, mut inc, mut modal) = (ModalState::zeros(3), Increment::new(3), ModalJet::new(3));
        for t in [0.4, 0.41, 1.7, 12.3] {
            seg.state_and_increment_at(&dynamics, t, &mut st, &mut inc);
            modal.fill_free_rotated(&dynamics, &inc.rotations, &st);
            let expected = modal.functional(&h, t);
            assert_eq!(ModalJet::displacement_jet(&dynamics, &inc.rotations, &st, &h, t), expected, "t = {t}");
            let mut bounds = ModalBounds::new(&dynamics);
            seg.fill_bounds(&dynamics, &st, &inc, 0.8, &mut bounds);
            assert_eq!(seg.displacement_bounds(&dynamics, &st, &inc, 0.8, &h), bounds.functional(&h, 0.8), "t = {t}");
        }
        // Without loads varying in time.
        let still = FreeDynamics::new(dynamics.oscillators.clone(), ModalForcing { constant: dvector![0.3, -0.2, 0.1], harmonics: Vec::new() });
        modal.fill_free_rotated(&still, &[], &start);
        assert_eq!(ModalJet::displacement_jet(&still, &[], &start, &h, 0.0), modal.functional(&h, 0.0));
    }

    #[test]
    fn the_increment_is_the_displacement_since_the_anchor() {
        let oscs = vec![Oscillator::new(1.0, 0.0), Oscillator::new(4.0, 0.1), Oscillator::new(9.0, 2.0)];
        let mut forcing = ModalForcing::zero(3);
        forcing.constant = dvector![0.3, -0.2, 0.1];
        forcing.add_harmonic(1.0, dvector![C64::new(0.0, -1.0), C64::new(0.0, -0.5), C64::new(0.2, 0.0)]);
        let dynamics = FreeDynamics::new(oscs, forcing);
        let start = ModalState { q: dvector![0.1, 0.2, -0.1], qd: dvector![-0.3, 0.4, 0.2] };
        let seg = FreeSegment::new(&dynamics, 0.7, &start);
        let mut out = ModalState::zeros(3);
        let mut inc = Increment::new(3);
        for s in [1e-10, 1e-6, 0.3, 2.0] {
            seg.state_and_increment_at(&dynamics, 0.7 + s, &mut out, &mut inc);
            for j in 0..3 {
                assert!((inc.dq[j] - (out.q[j] - start.q[j])).abs() < 1e-15, "{s} {j}");
            }
            if s == 1e-10 {
                // To first order the increment is qd0 s (s as the segment sees
                // it, t - t0), here exact to ~1e-10 relative.
                let s = (0.7 + s) - 0.7;
                for j in 0..3 {
                    assert!((inc.dq[j] / (start.qd[j] * s) - 1.0).abs() < 1e-9, "{j}: {}", inc.dq[j]);
                }
            }
        }
    }

    #[test]
    fn split_steps_never_pass_a_zero_and_beat_the_plain_bound() {
        // A gap h = 1.5 - (q1 + q2 + q3) over modes of 1, 10 and 100 rad/s, a
        // harmonic load on all, the highest mode excited a little: along the
        // motion, every certified step (plain or split) must end before the
        // gap's first zero, checked on the closed-form motion at 20000
        // points per step; the split must certify longer steps where the
        // high mode is small.
        let oscs = vec![Oscillator::new(1.0, 0.02), Oscillator::new(10.0, 0.02), Oscillator::new(100.0, 0.02)];
        let mut forcing = ModalForcing::zero(3);
        forcing.add_harmonic(0.8, dvector![C64::new(0.0, -1.0), C64::new(0.0, -3.0), C64::new(0.5, 0.0)]);
        let dynamics = FreeDynamics::new(oscs, forcing);
        let start = ModalState { q: dvector![-0.5, 0.01, 0.0], qd: dvector![1.5, 0.0, 0.05] };
        let seg = FreeSegment::new(&dynamics, 0.0, &start);
        let h = Functional::of_position(1.5, dvector![-1.0, -1.0, -1.0]);
        // A long interval: the certificates, not the cap, set the steps.
        let tau = 2.0;
        let gap = |t: f64| {
            let mut st = ModalState::zeros(3);
            seg.state_at(&dynamics, t, &mut st);
            1.5 - st.q.sum()
        };
        let (mut st, mut inc) = (ModalState::zeros(3), Increment::new(3));
        let mut jet_buf = ModalJet::new(3);
        let mut bounds = ModalBounds::new(&dynamics);
        let (mut t, mut probes, mut longer) = (0.0, 0, 0);
        while t < 20.0 && probes < 5000 {
            probes += 1;
            seg.state_and_increment_at(&dynamics, t, &mut st, &mut inc);
            jet_buf.fill_free_rotated(&dynamics, &inc.rotations, &st);
            let jet = jet_buf.functional(&h, t);
            if jet.d[0] <= 1e-12 {
                break; // the first zero, reached
            }
            seg.fill_bounds(&dynamics, &st, &inc, tau, &mut bounds);
            let plain = match crate::solve::events::certified_step(&jet, &bounds.functional(&h, tau), false) {
                crate::solve::events::Certified::Clear(s) => s,
                other => panic!("{other:?} at {t}"),
            };
            let split = bounds.split_step(&jet_buf, &h, &jet, tau);
            if split > 1.01 * plain {
                longer += 1;
            }
            let s = plain.max(split);
            // `h > 0` on `[t, t + s)`, to the rounding of the absolute state.
            for k in 1..20000 {
                let x = t + s * k as f64 / 20000.0;
                assert!(gap(x) > -1e-14, "a step from {t} of {s} (split {split}, plain {plain}) passes a zero near {x}");
            }
            t += s;
        }
        assert!(t < 20.0 && probes < 5000, "the gap closes in this scene: t = {t}, {probes} probes");
        assert!(longer > probes / 4, "the split certified a longer step at {longer} of {probes} probes");
    }

    #[test]
    fn the_state_at_the_anchor_is_the_anchor_and_agrees_with_the_kernels_there() {
        // Steady and near-resonant (from rest) harmonic parts, a constant load.
        let dynamics = two_harmonic_dynamics();
        let start = ModalState { q: dvector![0.1, 0.2, -0.05], qd: dvector![-0.3, 0.4, 1.5] };
        let t0 = 0.7;
        let seg = FreeSegment::new(&dynamics, t0, &start);
        let (mut at, mut general) = (ModalState::zeros(3), ModalState::zeros(3));
        let (mut inc_at, mut inc_general) = (Increment::new(3), Increment::new(3));
        seg.state_and_increment_at(&dynamics, t0, &mut at, &mut inc_at);
        seg.evaluate_after_anchor(&dynamics, 0.0, &mut general, Some(&mut inc_general));
        assert_eq!((&at.q, &at.qd), (&start.q, &start.qd));
        for j in 0..3 {
            let close = |a: f64, b: f64| (a - b).abs() <= 4.0 * f64::EPSILON * b.abs().max(1.0);
            assert!(close(at.q[j], general.q[j]) && close(at.qd[j], general.qd[j]), "mode {j}");
            assert_eq!((inc_at.dq[j], inc_at.size[j]), (0.0, 0.0));
            assert!(close(inc_at.steady_q[j], inc_general.steady_q[j]) && close(inc_at.steady_qd[j], inc_general.steady_qd[j]), "mode {j}");
        }
        assert_eq!(inc_at.rotations, inc_general.rotations);
        let mut plain = ModalState::zeros(3);
        seg.state_at(&dynamics, t0, &mut plain);
        assert_eq!((&plain.q, &plain.qd), (&start.q, &start.qd));
    }

    #[test]
    fn segment_state_matches_direct_oscillator_solution() {
        let oscs = vec![Oscillator::new(1.0, 0.0), Oscillator::new(4.0, 0.1)];
        let mut forcing = ModalForcing::zero(2);
        forcing.constant = dvector![0.3, -0.2];
        // Resonant undamped load on mode 1: Re(-i e^{i t}) = sin t.
        forcing.add_harmonic(1.0, dvector![C64::new(0.0, -1.0), C64::new(0.0, -0.5)]);
        let dynamics = FreeDynamics::new(oscs, forcing);
        let start = ModalState { q: dvector![0.1, 0.2], qd: dvector![-0.3, 0.4] };
        let t0 = 0.7;
        let seg = FreeSegment::new(&dynamics, t0, &start);
        let mut out = ModalState::zeros(2);
        seg.state_at(&dynamics, t0, &mut out);
        assert!((&out.q - &start.q).norm() < 1e-15 && (&out.qd - &start.qd).norm() < 1e-15);
        // Mode 1, undamped, load 0.3 + sin t from t0: compare with the exact solution.
        let t = 5.3;
        seg.state_at(&dynamics, t, &mut out);
        let exact = |t: f64| -> (f64, f64) {
            // x = 0.3 + A cos t + B sin t - (t/2) cos t  (sin t at resonance)
            let (c0, s0) = (t0.cos(), t0.sin());
            // Solve for A, B from x(t0), v(t0).
            let xp = |t: f64| 0.3 - 0.5 * t * t.cos();
            let vp = |t: f64| -0.5 * t.cos() + 0.5 * t * t.sin();
            let (rx, rv) = (0.1 - xp(t0), -0.3 - vp(t0));
            let a = rx * c0 - rv * s0;
            let b = rx * s0 + rv * c0;
            (xp(t) + a * t.cos() + b * t.sin(), vp(t) - a * t.sin() + b * t.cos())
        };
        let (x, v) = exact(t);
        assert!((out.q[0] - x).abs() < 1e-13, "{} {}", out.q[0], x);
        assert!((out.qd[0] - v).abs() < 1e-13);
    }

    /// The transient split of free flight: six pinned-beam modes
    /// (`omega_j = j^2 pi^2`, zeta 0.05) rung by an impact (velocities
    /// `ringing cos(j - 1/2)`, ringing 3 unless said), a load at 1 rad/s
    /// on the odd modes, the clearance `offset - sum sin(j pi 0.4) q_j` of
    /// a stop at x = 0.4; every step checked on a 2000-point grid of the
    /// exact clearance, steps up to 5.
    /// - Offset 1 (never reached): 3 probes over 6 time units, against 18
    ///   for the plain certificate alone.
    /// - Offset 0.25: the ringing takes the clearance through zero at
    ///   t = 0.156, its steady part (at least 0.05) positive throughout; the
    ///   search stops there (with the transients' amplitude dropped from
    ///   the split, a step passes that zero: checked).
    /// - Ringing 0.3 from t = 3.5, offset 0.15: the load, rising, then
    ///   takes the clearance through zero at t = 7.19; the search stops
    ///   there, in 7 probes against 19 (with the steady part's derivative
    ///   bounds dropped, a step passes it: checked).
    #[test]
    fn free_flight_s_transient_split_steps_at_the_loads_pace_and_never_passes_a_zero() {
        let n = 6;
        let oscillators = (1..=n).map(|j| Oscillator::new((j * j) as f64 * PI * PI, 0.05)).collect();
        let mut forcing = ModalForcing::zero(n);
        forcing.add_harmonic(1.0, DVector::from_fn(n, |j, _| C64::new(0.0, if j % 2 == 0 { -20.0 / (j + 1) as f64 } else { 0.0 })));
        let dynamics = FreeDynamics::new(oscillators, forcing);
        let segment = |ringing: f64, t0: f64| FreeSegment::new(&dynamics, t0, &ModalState { q: DVector::zeros(n), qd: DVector::from_fn(n, |j, _| ringing * (j as f64 + 0.5).cos()) });
        let stop = |offset: f64| Functional::of_position(offset, DVector::from_fn(n, |j, _| -((j + 1) as f64 * PI * 0.4).sin()));
        let clearance = |seg: &FreeSegment, h: &Functional, t: f64| {
            let mut st = ModalState::zeros(n);
            seg.state_at(&dynamics, t, &mut st);
            h.value_without_load(&st)
        };
        let search = |ringing: f64, offset: f64, t0: f64, split: bool| {
            let seg = segment(ringing, t0);
            let h = stop(offset);
            let tau = 5.0;
            let (mut st, mut inc) = (ModalState::zeros(n), Increment::new(n));
            let (mut t, mut probes) = (t0, 0);
            while t < t0 + 6.0 && probes < 1000 {
                probes += 1;
                seg.state_and_increment_at(&dynamics, t, &mut st, &mut inc);
                let jet = ModalJet::displacement_jet(&dynamics, &inc.rotations, &st, &h, t);
                let bounds = seg.displacement_bounds(&dynamics, &st, &inc, tau, &h);
                let Certified::Clear(plain) = certified_step(&jet, &bounds, false) else { return (probes, t) };
                let s = if split { plain.max(seg.transient_split_step(&dynamics, &st, &inc, &h, &jet, &bounds)) } else { plain };
                if !(t + s > t) {
                    return (probes, t);
                }
                for i in 1..2000 {
                    let x = t + s * i as f64 / 2000.0;
                    assert!(clearance(&seg, &h, x) > -1e-12, "offset {offset}: a step from {t} of {s} passes a zero near {x}");
                }
                t += s;
            }
            (probes, t)
        };
        let (split, t) = search(3.0, 1.0, 0.0, true);
        let (plain, t_plain) = search(3.0, 1.0, 0.0, false);
        assert!(t >= 6.0 && t_plain >= 6.0 && split <= 5 && 3 * split <= plain, "{split} probes with the split, {plain} without");
        let (_, t) = search(3.0, 0.25, 0.0, true);
        assert!(t > 0.15 && t < 0.16 && clearance(&segment(3.0, 0.0), &stop(0.25), t).abs() < 1e-9, "stopped at {t}");
        let ((split, t), (plain, _)) = (search(0.3, 0.15, 3.5, true), search(0.3, 0.15, 3.5, false));
        assert!(t > 7.0 && t < 7.3 && clearance(&segment(0.3, 3.5), &stop(0.15), t).abs() < 1e-9 && 2 * split < plain, "stopped at {t}, {split} probes, {plain} without the split");
    }
}
