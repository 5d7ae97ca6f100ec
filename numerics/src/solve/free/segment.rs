//! The closed-form free motion from an anchor, and the displacement since
//! the anchor computed as an increment.

use nalgebra::DVector;

use super::FreeDynamics;
use crate::solve::complex::C64;
use crate::solve::elementary::{sin_cos, unit};
use crate::solve::functional::NOISE;
use crate::solve::modal_state::ModalState;

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

    /// The state at `t >= t0` from the kernels `(Ec, Es)` of every mode at
    /// `t - t0`, computed beforehand (steps of one size share them).
    pub fn state_with_kernels(&self, dynamics: &FreeDynamics, t: f64, kernels: &[(f64, f64)], out: &mut ModalState) {
        let s = t - self.t0;
        if s == 0.0 {
            self.at_anchor(dynamics, out, None);
            return;
        }
        self.evaluate_with(dynamics, s, out, None, Some(kernels));
    }

    fn evaluate_after_anchor(&self, dynamics: &FreeDynamics, s: f64, out: &mut ModalState, increment: Option<&mut Increment>) {
        self.evaluate_with(dynamics, s, out, increment, None);
    }

    /// Every mode's state, each from its kernels, without the increment.
    fn sum_modes(&self, dynamics: &FreeDynamics, s: f64, rotations: &[(C64, C64)], kernels: impl Fn(usize, &crate::solve::Oscillator) -> (f64, f64), out: &mut ModalState) {
        let harmonics = &dynamics.forcing.harmonics;
        let n_harmonics = harmonics.len();
        let n = self.modes.len();
        let (q, qd) = (&mut out.q.as_mut_slice()[..n], &mut out.qd.as_mut_slice()[..n]);
        let oscillators = &dynamics.oscillators[..n];
        let parts = &self.parts[..n * n_harmonics];
        for (j, (seg, osc)) in self.modes.iter().zip(oscillators).enumerate() {
            let (ec, es) = kernels(j, osc);
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
    }

    fn evaluate_with(&self, dynamics: &FreeDynamics, s: f64, out: &mut ModalState, mut increment: Option<&mut Increment>, kernels: Option<&[(f64, f64)]>) {
        // e^{i W s} and e^{i W s} - 1 without cancellation, shared by
        // every mode: one sin_cos of the half angle for both.
        let rotation = |h: &crate::solve::forcing::Harmonic| {
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
            self.sum_modes(dynamics, s, rotations, |j, osc| kernels.map_or_else(|| osc.kernels(s), |k| k[j]), out);
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

/// `e^{i Omega s}` of a harmonic load of angular frequency `omega` from
/// the half angle's sine and cosine (`1 - 2 sin^2`, `2 sin cos`).
pub fn steady_rotation(omega: f64, s: f64) -> C64 {
    let (sh, ch) = sin_cos(0.5 * omega * s);
    C64::new(1.0 - 2.0 * sh * sh, 2.0 * sh * ch)
}

/// A segment's motion projected on one coordinate `c . q`: per mode the
/// weights of its kernels `(Ec, Es)` in the coordinate and its rate, and
/// per harmonic load the projected steady amplitude, so that the
/// coordinate at a time costs two products per mode instead of the modal
/// state ([`FreeSegment::projected`]). Cloned into another field by
/// field, in its storage (a step's samples copy one per step).
#[derive(Debug, Default)]
pub struct Projection {
    /// `(c alpha, c beta)` and `(c v0, -c (a v0 + omega^2 alpha))` per mode.
    position: Vec<[f64; 2]>,
    rate: Vec<[f64; 2]>,
    /// The acceleration's weights, likewise (the rate's differentiated
    /// once more), once [`Self::prepare_accelerations`] formed them.
    acceleration: Vec<[f64; 2]>,
    /// `c . x_static`.
    constant: f64,
    /// `c . P b` per harmonic (steady parts only, rotated to the start).
    steady: Vec<C64>,
}

impl Clone for Projection {
    fn clone(&self) -> Self {
        Projection { position: self.position.clone(), rate: self.rate.clone(), acceleration: self.acceleration.clone(), constant: self.constant, steady: self.steady.clone() }
    }

    fn clone_from(&mut self, source: &Self) {
        self.position.clone_from(&source.position);
        self.rate.clone_from(&source.rate);
        self.acceleration.clone_from(&source.acceleration);
        self.constant = source.constant;
        self.steady.clone_from(&source.steady);
    }
}

impl Projection {
    /// The coordinate and its rate at `t` (`s = t - t0 > 0`) from every
    /// mode's kernels at `s` (`kernels[j]`).
    pub fn at(&self, dynamics: &FreeDynamics, s: f64, kernels: &[(f64, f64)]) -> (f64, f64) {
        let (mut x, mut v) = self.modes_at(kernels);
        for (amplitude, h) in self.steady.iter().zip(&dynamics.forcing.harmonics) {
            let z = amplitude * steady_rotation(h.omega, s);
            x += z.re;
            v -= h.omega * z.im;
        }
        (x, v)
    }

    /// [`Self::at`] with every harmonic load's rotation over `s` given
    /// ([`steady_rotation`]'s, kept per step size at a step's nodes):
    /// the same bits.
    pub fn at_rotated(&self, dynamics: &FreeDynamics, kernels: &[(f64, f64)], rotations: &[C64]) -> (f64, f64) {
        let (mut x, mut v) = self.modes_at(kernels);
        for ((amplitude, h), rotation) in self.steady.iter().zip(&dynamics.forcing.harmonics).zip(rotations) {
            let z = amplitude * rotation;
            x += z.re;
            v -= h.omega * z.im;
        }
        (x, v)
    }

    /// The modes' share of the coordinate and its rate (with the static
    /// part), in the modes' order.
    fn modes_at(&self, kernels: &[(f64, f64)]) -> (f64, f64) {
        let (mut x, mut v) = (self.constant, 0.0);
        for ((p, r), &(ec, es)) in self.position.iter().zip(&self.rate).zip(kernels) {
            x += p[0] * ec + p[1] * es;
            v += r[0] * ec + r[1] * es;
        }
        (x, v)
    }

    /// Forms the acceleration's weights of every mode: the map that takes
    /// `(c alpha, c beta)` to the rate's weights, applied to those.
    pub fn prepare_accelerations(&mut self, dynamics: &FreeDynamics) {
        self.acceleration.clear();
        self.acceleration.extend(self.rate.iter().zip(&dynamics.oscillators).map(|(r, osc)| {
            let r0 = r[1] - osc.a * r[0];
            [r0, -(osc.a * r0 + osc.omega * osc.omega * r[0])]
        }));
    }

    /// Whether [`Self::prepare_accelerations`] formed this motion's
    /// acceleration weights.
    pub fn accelerations_prepared(&self) -> bool {
        self.acceleration.len() == self.rate.len()
    }

    /// The coordinate's acceleration at `s` from every mode's kernels
    /// there (its weights from [`Self::prepare_accelerations`]; the steady
    /// responses' `-Omega^2` times their value).
    pub fn acceleration_at(&self, dynamics: &FreeDynamics, s: f64, kernels: &[(f64, f64)]) -> f64 {
        debug_assert!(self.accelerations_prepared(), "accelerations prepared");
        let mut a = 0.0;
        for (acc, &(ec, es)) in self.acceleration.iter().zip(kernels) {
            a += acc[0] * ec + acc[1] * es;
        }
        for (amplitude, h) in self.steady.iter().zip(&dynamics.forcing.harmonics) {
            a -= h.omega * h.omega * (amplitude * steady_rotation(h.omega, s)).re;
        }
        a
    }
}

impl FreeSegment {
    /// This segment's motion projected on `c . q` into `out`; `false`
    /// where a harmonic load is near resonance (its response from rest is
    /// not a fixed amplitude: the modal states' path then).
    pub fn projected(&self, dynamics: &FreeDynamics, c: &[f64], out: &mut Projection) -> bool {
        let n_harmonics = dynamics.forcing.harmonics.len();
        out.position.clear();
        out.rate.clear();
        out.acceleration.clear();
        out.steady.clear();
        out.steady.resize(n_harmonics, C64::new(0.0, 0.0));
        out.constant = 0.0;
        for (j, (seg, osc)) in self.modes.iter().zip(&dynamics.oscillators).enumerate() {
            let w = c[j];
            let v0 = seg.beta - osc.a * seg.alpha;
            out.position.push([w * seg.alpha, w * seg.beta]);
            out.rate.push([w * v0, -w * (osc.a * v0 + osc.omega * osc.omega * seg.alpha)]);
            out.constant += w * seg.x_static;
            for (part, total) in self.parts[j * n_harmonics..(j + 1) * n_harmonics].iter().zip(out.steady.iter_mut()) {
                match part {
                    HarmonicPart::Steady(pb) => *total += pb * w,
                    HarmonicPart::FromRest(_) => return false,
                }
            }
        }
        true
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::forcing::ModalForcing;
    use crate::solve::oscillator::Oscillator;
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
    fn the_projected_motion_is_the_projection_of_the_modal_states() {
        // Steady harmonic parts (no mode near resonance) and a constant
        // load: the coordinate and its rate against d . q, d . q' of the
        // modal states; a resonant load (from rest) has no projection.
        use crate::solve::{ModalForcing, Oscillator};
        let oscillators = vec![Oscillator::new(1.0, 0.02), Oscillator::new(4.0, 0.1), Oscillator::new(9.0, 2.0)];
        let mut forcing = ModalForcing::zero(3);
        forcing.constant = dvector![0.3, -0.2, 0.1];
        forcing.add_harmonic(2.5, dvector![C64::new(0.4, 0.1), C64::new(-0.3, 0.0), C64::new(0.0, 0.7)]);
        let dynamics = FreeDynamics::new(oscillators.clone(), forcing);
        let start = ModalState { q: dvector![0.1, 0.2, -0.05], qd: dvector![-0.3, 0.4, 1.5] };
        let (t0, d) = (0.7, [0.5, -1.2, 0.8]);
        let seg = FreeSegment::new(&dynamics, t0, &start);
        let mut projection = Projection::default();
        assert!(seg.projected(&dynamics, &d, &mut projection));
        let mut st = ModalState::zeros(3);
        for s in [1e-6, 0.01, 0.3, 2.0, 7.5] {
            let kernels: Vec<(f64, f64)> = oscillators.iter().map(|o| o.kernels(s)).collect();
            let (p, pd) = projection.at(&dynamics, s, &kernels);
            seg.state_at(&dynamics, t0 + s, &mut st);
            let (want_p, want_pd) = ((0..3).map(|j| d[j] * st.q[j]).sum::<f64>(), (0..3).map(|j| d[j] * st.qd[j]).sum::<f64>());
            assert!((p - want_p).abs() <= 1e-14 * (1.0 + want_p.abs()), "s = {s}: {p} vs {want_p}");
            assert!((pd - want_pd).abs() <= 1e-14 * (1.0 + want_pd.abs()), "s = {s}: {pd} vs {want_pd}");
        }
        let resonant = super::super::tests::two_harmonic_dynamics();
        let seg = FreeSegment::new(&resonant, t0, &start);
        assert!(!seg.projected(&resonant, &d, &mut projection));
    }

    #[test]
    fn the_state_at_the_anchor_is_the_anchor_and_agrees_with_the_kernels_there() {
        // Steady and near-resonant (from rest) harmonic parts, a constant load.
        let dynamics = super::super::tests::two_harmonic_dynamics();
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
}
