//! Free flight: uncoupled modal oscillators under a known load, propagated in
//! closed form from the state at the last event (the segment's anchor).
//!
//! The state at any time is computed from the anchor, never by chaining
//! communication steps, so results do not depend on the step size.

use nalgebra::DVector;

use super::forcing::ModalForcing;
use super::functional::{DerivativeBounds, Functional, Jet, NOISE};
use super::oscillator::{expm1_c, Oscillator, C64};

/// The free dynamics: one oscillator per mode and the modal load.
#[derive(Clone, Debug, PartialEq)]
pub struct FreeDynamics {
    pub oscillators: Vec<Oscillator>,
    pub forcing: ModalForcing,
    /// `forcing.bounds()`, kept with it.
    force_bounds: [DVector<f64>; 5],
}

impl FreeDynamics {
    pub fn new(oscillators: Vec<Oscillator>, forcing: ModalForcing) -> Self {
        let force_bounds = forcing.bounds();
        FreeDynamics { oscillators, forcing, force_bounds }
    }

    pub fn set_forcing(&mut self, forcing: ModalForcing) {
        self.force_bounds = forcing.bounds();
        self.forcing = forcing;
    }
}

#[derive(Clone, Debug, PartialEq)]
enum HarmonicPart {
    /// Steady-state amplitude `P b~`, far from resonance.
    Steady(C64),
    /// Response from rest to `b~ e^{i Omega s}`, near resonance.
    FromRest(C64),
}

#[derive(Clone, Debug, PartialEq)]
struct ModeSegment {
    /// Homogeneous part: `x_h = alpha Ec + beta Es`.
    alpha: f64,
    beta: f64,
    /// Static response to the constant load.
    x_static: f64,
    parts: Vec<HarmonicPart>,
    /// `|x_static| + sum |P b|` and `sum |P b| W^m` (m = 1..=5): bounds on the
    /// derivatives of the steady response, constant along the segment.
    steady_bounds: [f64; 6],
    /// `sum |b| W^m` (m = 0..=4) over the near-resonant harmonics.
    resonant_bounds: [f64; 5],
}

/// Closed-form free motion from an anchor `(t0, q0, qd0)`.
#[derive(Clone, Debug, PartialEq)]
pub struct FreeSegment {
    pub t0: f64,
    modes: Vec<ModeSegment>,
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
        let modes = dynamics
            .oscillators
            .iter()
            .enumerate()
            .map(|(j, osc)| {
                let w2 = osc.omega * osc.omega;
                let x_static = dynamics.forcing.constant[j] / w2;
                let mut x0 = start.q[j] - x_static;
                let mut v0 = start.qd[j];
                let parts: Vec<HarmonicPart> = dynamics
                    .forcing
                    .harmonics
                    .iter()
                    .map(|h| {
                        let b = h.amplitude[j] * C64::from_polar(1.0, h.omega * t0);
                        if osc.near_resonance(h.omega) {
                            HarmonicPart::FromRest(b)
                        } else {
                            let pb = b / osc.dynamic_stiffness(h.omega);
                            x0 -= pb.re;
                            v0 -= (C64::new(0.0, h.omega) * pb).re;
                            HarmonicPart::Steady(pb)
                        }
                    })
                    .collect();
                let mut steady_bounds = [0.0; 6];
                let mut resonant_bounds = [0.0; 5];
                steady_bounds[0] = x_static.abs();
                for (part, h) in parts.iter().zip(&dynamics.forcing.harmonics) {
                    let (magnitude, target): (f64, &mut [f64]) = match part {
                        HarmonicPart::Steady(pb) => (pb.norm(), &mut steady_bounds),
                        HarmonicPart::FromRest(b) => (b.norm(), &mut resonant_bounds),
                    };
                    let mut p = magnitude;
                    for m in target.iter_mut() {
                        *m += p;
                        p *= h.omega;
                    }
                }
                ModeSegment { alpha: x0, beta: v0 + osc.a * x0, x_static, parts, steady_bounds, resonant_bounds }
            })
            .collect();
        FreeSegment { t0, modes }
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

    fn evaluate(&self, dynamics: &FreeDynamics, t: f64, out: &mut ModalState, mut increment: Option<&mut Increment>) {
        let s = t - self.t0;
        // e^{i W s} and, for increments, e^{i W s} - 1 without cancellation,
        // shared by every mode.
        let want_increment = increment.is_some();
        let rotation = |h: &super::forcing::Harmonic| {
            let e = C64::new(0.0, h.omega * s);
            (e.exp(), if want_increment { expm1_c(e) } else { C64::new(0.0, 0.0) })
        };
        let mut buffer = [(C64::new(0.0, 0.0), C64::new(0.0, 0.0)); 8];
        let many: Vec<(C64, C64)>;
        let rotations: &[(C64, C64)] = if dynamics.forcing.harmonics.len() <= buffer.len() {
            for (r, h) in buffer.iter_mut().zip(&dynamics.forcing.harmonics) {
                *r = rotation(h);
            }
            &buffer[..dynamics.forcing.harmonics.len()]
        } else {
            many = dynamics.forcing.harmonics.iter().map(rotation).collect();
            &many
        };
        for (j, (seg, osc)) in self.modes.iter().zip(&dynamics.oscillators).enumerate() {
            let (ec, es, ec_m1) = osc.kernels_and_increment(s);
            let v0 = seg.beta - osc.a * seg.alpha;
            let mut x = seg.alpha * ec + seg.beta * es + seg.x_static;
            let mut v = v0 * ec - (osc.a * v0 + osc.omega * osc.omega * seg.alpha) * es;
            let (mut dx, mut size) = (seg.alpha * ec_m1 + seg.beta * es, (seg.alpha * ec_m1).abs() + (seg.beta * es).abs());
            let (mut xp, mut vp) = (seg.x_static, 0.0);
            for ((part, h), (rot, rot_m1)) in seg.parts.iter().zip(&dynamics.forcing.harmonics).zip(rotations) {
                match part {
                    HarmonicPart::Steady(pb) => {
                        let z = pb * rot;
                        x += z.re;
                        v -= h.omega * z.im;
                        xp += z.re;
                        vp -= h.omega * z.im;
                        if want_increment {
                            let dz = pb * rot_m1;
                            dx += dz.re;
                            size += dz.norm();
                        }
                    }
                    HarmonicPart::FromRest(b) => {
                        let (g, gd) = osc.harmonic_from_rest(h.omega, s, *rot);
                        x += (b * g).re;
                        v += (b * gd).re;
                        dx += (b * g).re;
                        size += (b * g).norm();
                    }
                }
            }
            out.q[j] = x;
            out.qd[j] = v;
            if let Some(inc) = increment.as_deref_mut() {
                inc.dq[j] = dx;
                inc.size[j] = size;
                inc.steady_q[j] = xp;
                inc.steady_qd[j] = vp;
            }
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
}

impl Increment {
    pub fn new(n: usize) -> Self {
        Increment { dq: DVector::zeros(n), size: DVector::zeros(n), steady_q: DVector::zeros(n), steady_qd: DVector::zeros(n) }
    }

    /// `a . dq` and its rounding noise.
    pub fn functional(&self, a: &DVector<f64>) -> (f64, f64) {
        let value = a.dot(&self.dq);
        let size: f64 = a.iter().zip(self.size.iter()).map(|(x, y)| (x * y).abs()).sum();
        (value, NOISE * size)
    }
}

impl FreeSegment {
    /// Bounds on `|q_j^(m)|` over `[t, t + tau]`: the steady response to the
    /// loads far from resonance is known exactly (`|x_p^(m)| <= sum |P b| W^m`),
    /// and what remains obeys the oscillator loaded only by the near-resonant
    /// harmonics, so its energy amplitude `sqrt(r'^2 + omega^2 r^2)` grows by
    /// at most their size per unit time; the equation of motion bounds the
    /// higher derivatives.
    /// `sample` is the state's split made by [`Self::state_and_increment_at`]
    /// at the same time.
    pub fn fill_bounds(&self, dynamics: &FreeDynamics, state: &ModalState, sample: &Increment, tau: f64, out: &mut ModalBounds) {
        for (j, (seg, osc)) in self.modes.iter().zip(&dynamics.oscillators).enumerate() {
            let w = osc.omega;
            let (rq, rv) = (state.q[j] - sample.steady_q[j], state.qd[j] - sample.steady_qd[j]);
            let resonant = &seg.resonant_bounds;
            let amp = (rv * rv + w * w * rq * rq).sqrt() + resonant[0] * tau;
            let mut r = [0.0; 6];
            r[0] = amp / w;
            r[1] = amp;
            for m in 2..6 {
                r[m] = resonant[m - 2] + 2.0 * osc.a * r[m - 1] + w * w * r[m - 2];
            }
            for m in 0..6 {
                out.b[m][j] = r[m] + seg.steady_bounds[m];
            }
        }
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
        self.q[0].copy_from(&state.q);
        self.q[1].copy_from(&state.qd);
        for (j, osc) in dynamics.oscillators.iter().enumerate() {
            let w2 = osc.omega * osc.omega;
            let two_a = 2.0 * osc.a;
            self.scale[0][j] = state.q[j].abs();
            self.scale[1][j] = state.qd[j].abs();
            for m in 2..5 {
                self.q[m][j] = self.f[m - 2][j] - two_a * self.q[m - 1][j] - w2 * self.q[m - 2][j];
                self.scale[m][j] =
                    self.f[m - 2][j].abs() + two_a * self.scale[m - 1][j] + w2 * self.scale[m - 2][j];
            }
        }
    }

    /// `h, h', h'', h'''` of a functional at the jet's time `t`.
    pub fn functional(&self, h: &Functional, t: f64) -> Jet {
        let mut jet = Jet::default();
        for m in 0..4 {
            let mut value = if m == 0 { h.offset } else { 0.0 };
            let mut size = value.abs();
            value += h.q.dot(&self.q[m]);
            size += h.q.iter().zip(self.scale[m].iter()).map(|(a, s)| (a * s).abs()).sum::<f64>();
            if let Some(b) = &h.qd {
                value += b.dot(&self.q[m + 1]);
                size += b.iter().zip(self.scale[m + 1].iter()).map(|(a, s)| (a * s).abs()).sum::<f64>();
            }
            if let Some(c) = &h.f {
                value += c.dot(&self.f[m]);
                size += c.iter().zip(self.f[m].iter()).map(|(a, s)| (a * s).abs()).sum::<f64>();
            }
            jet.d[m] = value;
            jet.noise[m] = NOISE * size;
        }
        jet.with_time_uncertainty(t)
    }
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
        for (k, m) in (2..5).enumerate() {
            let mut s = h.q.iter().zip(self.b[m].iter()).map(|(a, b)| a.abs() * b).sum::<f64>();
            if let Some(bq) = &h.qd {
                s += bq.iter().zip(self.b[m + 1].iter()).map(|(a, b)| a.abs() * b).sum::<f64>();
            }
            if let Some(c) = &h.f {
                s += c.iter().zip(self.f[m].iter()).map(|(a, b)| a.abs() * b).sum::<f64>();
            }
            out.m[k] = s;
        }
        // The rounding level of the displacement part of `h` over the
        // interval: a gap below it (a denormal clearance, say) is zero.
        out.floor[0] = NOISE * h.q.iter().zip(self.b[0].iter()).map(|(a, b)| a.abs() * b).sum::<f64>();
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::dvector;

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
}
