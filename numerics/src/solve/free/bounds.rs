//! Bounds on the free motion's derivatives over an interval, and the
//! certified steps the event search takes from them by splitting the
//! motion (by mode, or into transients and steady responses).

use nalgebra::DVector;

use super::{FreeDynamics, FreeSegment, Increment, ModalJet, ModeLoad};
use crate::solve::complex::C64;
use crate::solve::events::split_certificate;
use crate::solve::functional::{DerivativeBounds, Functional, Jet, NOISE};
use crate::solve::modal_state::ModalState;
use crate::solve::oscillator::Oscillator;

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
    use crate::solve::forcing::ModalForcing;
    use nalgebra::dvector;
    use std::f64::consts::PI;

    #[test]
    fn displacement_bounds_are_the_modal_arrays_sums_bit_for_bit() {
        // Two harmonics (one resonant with mode 1), damping, an offset: the
        // fused sums must give exactly what the modal arrays give.
        let dynamics = super::super::tests::two_harmonic_dynamics();
        let start = ModalState { q: dvector![0.1, 0.2, -0.1], qd: dvector![-0.3, 0.4, 0.2] };
        let seg = FreeSegment::new(&dynamics, 0.4, &start);
        let h = Functional::of_position(1.2, dvector![0.9, -0.6, 0.3]);
        let (mut st, mut inc) = (ModalState::zeros(3), Increment::new(3));
        for t in [0.4, 0.41, 1.7, 12.3] {
            seg.state_and_increment_at(&dynamics, t, &mut st, &mut inc);
            let mut bounds = ModalBounds::new(&dynamics);
            seg.fill_bounds(&dynamics, &st, &inc, 0.8, &mut bounds);
            assert_eq!(seg.displacement_bounds(&dynamics, &st, &inc, 0.8, &h), bounds.functional(&h, 0.8), "t = {t}");
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
