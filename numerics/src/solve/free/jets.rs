//! Time derivatives at one instant of the free motion: every mode's jet,
//! and a functional's.

use nalgebra::DVector;

use super::FreeDynamics;
use crate::solve::complex::C64;
use crate::solve::functional::{Functional, Jet, NOISE};
use crate::solve::modal_state::ModalState;
use crate::solve::oscillator::Oscillator;

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::forcing::ModalForcing;
    use crate::solve::free::{FreeSegment, Increment};
    use nalgebra::dvector;

    #[test]
    fn displacement_jets_are_the_modal_arrays_sums_bit_for_bit() {
        // Two harmonics (one resonant with mode 1), damping, an offset: the
        // fused sums must give exactly what the modal arrays give.
        let dynamics = super::super::tests::two_harmonic_dynamics();
        let start = ModalState { q: dvector![0.1, 0.2, -0.1], qd: dvector![-0.3, 0.4, 0.2] };
        let seg = FreeSegment::new(&dynamics, 0.4, &start);
        let h = Functional::of_position(1.2, dvector![0.9, -0.6, 0.3]);
        let (mut st, mut inc, mut modal) = (ModalState::zeros(3), Increment::new(3), ModalJet::new(3));
        for t in [0.4, 0.41, 1.7, 12.3] {
            seg.state_and_increment_at(&dynamics, t, &mut st, &mut inc);
            modal.fill_free_rotated(&dynamics, &inc.rotations, &st);
            let expected = modal.functional(&h, t);
            assert_eq!(ModalJet::displacement_jet(&dynamics, &inc.rotations, &st, &h, t), expected, "t = {t}");
        }
        // Without loads varying in time.
        let still = FreeDynamics::new(dynamics.oscillators.clone(), ModalForcing { constant: dvector![0.3, -0.2, 0.1], harmonics: Vec::new() });
        modal.fill_free_rotated(&still, &[], &start);
        assert_eq!(ModalJet::displacement_jet(&still, &[], &start, &h, 0.0), modal.functional(&h, 0.0));
    }
}
