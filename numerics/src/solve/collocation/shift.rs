//! A short move of the state along the motion, either way in time: the
//! free motion in closed form and each contact's force as the line
//! through its values at the two ends. What a switch's Newton iteration
//! needs once its corrections are a small share of a step (the
//! separation's time moved by the dense output's error, then by
//! rounding), instead of a collocation step from the approach with
//! kernels of a size no other step shares.

use nalgebra::DVector;

use super::kernels::point_responses;
use super::{ForceCollocation, PointForces};
use crate::solve::free::FreeSegment;
use crate::solve::modal_state::ModalState;

/// The longest shift, in radians of the fastest mode (its phase and
/// decay over the shift).
const MAX_ANGLE: f64 = 1.0;
/// What the force's change over a shift may move a contact coordinate's
/// rate by (as the line's difference from the force held at its start),
/// in the Newton iteration's share of the tolerance: the line's own error
/// is of the next order in the shift.
const CHANGE_FRACTION: f64 = 1e-3;

/// Working arrays of [`ForceCollocation::shift`], kept between shifts (a
/// switch's Newton iteration shifts several times: each formed its own,
/// a dozen allocations).
#[derive(Clone, Debug, Default)]
pub(super) struct ShiftScratch {
    /// Per mode, the free kernels over the shift and the responses.
    kernels: Vec<(f64, f64)>,
    responses: Vec<[[f64; 2]; 2]>,
    start: ModalState,
    free_end: ModalState,
    free: Option<FreeSegment>,
    /// The state moved with the force held (the end's force is read there).
    predicted: DVector<f64>,
    /// Per contact, the force and dissipated power at each end.
    at_start: Vec<(f64, f64)>,
    at_end: Vec<(f64, f64)>,
}

impl ForceCollocation {
    /// The state at `t1` from `(t, y)` (`t1` before `t` too), or `None`
    /// where the shift is not short enough: longer than [`MAX_ANGLE`] of
    /// the fastest mode, a held contact (its reaction is not a law's
    /// force), forces whose change over it moves a contact coordinate's
    /// rate by more than [`CHANGE_FRACTION`] of the Newton iteration's
    /// tolerance, or dissipated powers whose change moves the energy by
    /// more than the tolerance of the modes' kinetic energy. The impulses
    /// and dissipated energies in `y` move by the trapezoidal rule.
    pub fn shift(&self, forces: &impl PointForces, t: f64, y: &DVector<f64>, t1: f64) -> Option<DVector<f64>> {
        let (n, nc) = (self.n, self.contacts.len());
        let delta = t1 - t;
        if delta == 0.0 {
            return Some(y.clone());
        }
        let oscillators = &self.dynamics.oscillators;
        let fastest = oscillators.iter().map(|o| o.omega + o.a).fold(0.0, f64::max);
        if !(fastest * delta.abs() <= MAX_ANGLE) || (0..nc).any(|c| forces.held(c)) {
            return None;
        }
        let mut guard = self.scratch.borrow_mut();
        let ShiftScratch { kernels, responses, start, free_end, free, predicted, at_start, at_end } = &mut guard.shift;
        // Per mode: the free kernels over the shift, and the responses from
        // rest to a unit load and to one rising as (s / delta).
        kernels.clear();
        kernels.resize(n, (0.0, 0.0));
        responses.clear();
        responses.resize(n, [[0.0; 2]; 2]);
        for (j, osc) in oscillators.iter().enumerate() {
            kernels[j] = point_responses(osc, delta, delta, &mut responses[j]);
        }
        if start.q.len() != n {
            (*start, *free_end) = (ModalState::zeros(n), ModalState::zeros(n));
        }
        start.q.copy_from(&y.rows(0, n));
        start.qd.copy_from(&y.rows(n, n));
        let free = match free {
            Some(free) => {
                free.reset(&self.dynamics, t, start);
                free
            }
            None => free.insert(FreeSegment::new(&self.dynamics, t, start)),
        };
        free.state_with_kernels(&self.dynamics, t1, kernels, free_end);
        let law = |c: usize, y: &DVector<f64>| {
            let (p, pd) = self.coordinate(c, y);
            let f = forces.force(c, p, pd).0;
            (f, forces.dissipation_rate(c, p, pd, f))
        };
        // `out` holds `y` on entry.
        let moved = |f0: &[(f64, f64)], f1: &[(f64, f64)], out: &mut DVector<f64>| {
            for j in 0..n {
                let (mut x, mut v) = (free_end.q[j], free_end.qd[j]);
                for c in 0..nc {
                    let (a, b) = (f0[c].0, f1[c].0 - f0[c].0);
                    let dj = self.contacts[c].d[j];
                    x -= dj * (a * responses[j][0][0] + b * responses[j][1][0]);
                    v -= dj * (a * responses[j][0][1] + b * responses[j][1][1]);
                }
                (out[j], out[n + j]) = (x, v);
            }
            for c in 0..nc {
                out[2 * n + c] += 0.5 * delta * (f0[c].0 + f1[c].0);
                out[2 * n + nc + c] += 0.5 * delta * (f0[c].1 + f1[c].1);
            }
        };
        at_start.clear();
        at_start.extend((0..nc).map(|c| law(c, y)));
        if predicted.len() == y.len() {
            predicted.copy_from(y);
        } else {
            *predicted = y.clone();
        }
        moved(at_start, at_start, predicted);
        at_end.clear();
        at_end.extend((0..nc).map(|c| law(c, predicted)));
        let mut y1 = y.clone();
        moved(at_start, at_end, &mut y1);
        // The line's difference from the force held, on each contact's rate
        // (mass-normalised modes: |d|^2 per unit impulse over a short shift),
        // and from the dissipated power held, on the energy (against the
        // modes' kinetic energy at their velocity scale): the power jumps
        // where a push ends inside the surface (a linear damping's force
        // reaching zero, the spring's share still there), which no line
        // follows.
        let (tol, v_scale) = (self.options.tol, self.options.v_scale);
        let short = (0..nc).all(|c| {
            let force = 0.5 * (at_end[c].0 - at_start[c].0).abs() * delta.abs() * self.contacts[c].d.norm_squared();
            let power = 0.5 * (at_end[c].1 - at_start[c].1).abs() * delta.abs();
            force <= CHANGE_FRACTION * tol * v_scale * self.amax[c] && power <= tol * v_scale * v_scale
        });
        short.then_some(y1)
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::Hertzian;
    use super::super::{CollocationOptions, PointContact};
    use super::*;
    use crate::solve::{FreeDynamics, ModalForcing, Oscillator};

    /// Inside a Hertzian contact, a shift against a collocation step to
    /// the same time (to 2.2e-16 of the scales), and back again (the start
    /// within rounding).
    #[test]
    fn a_shift_is_a_short_step() {
        let oscillators = vec![Oscillator::new(3.0, 0.02), Oscillator::new(40.0, 0.02), Oscillator::new(400.0, 0.05)];
        let mut forcing = ModalForcing::zero(3);
        forcing.constant = DVector::from_vec(vec![60.0, -48.0, 36.0]);
        forcing.add_harmonic(5.0, DVector::from_vec(vec![crate::solve::C64::new(1.0, 0.0), crate::solve::C64::new(0.0, 0.3), crate::solve::C64::new(0.1, 0.0)]));
        let dynamics = FreeDynamics::new(oscillators, forcing);
        let d = DVector::from_vec(vec![1.0, -0.8, 0.6]);
        let law = Hertzian { k: 3e4, c: 0.3 };
        let y0 = DVector::from_vec(vec![0.01, 0.0, 0.0, 0.5, 0.1, -0.2, 0.0, 0.0]);
        let options = CollocationOptions { tol: 1e-10, q_scale: 0.01, v_scale: 0.5, h_init: 1e-4, h_max: 0.05, corner_fraction: 1e-10f64.powf(2.0 / 7.0) };
        let mut col = ForceCollocation::new(dynamics, vec![PointContact { d, gap: 0.0 }], 0.0, y0, options);
        let mut inside = 0;
        while col.t() < 0.3 {
            col.step(&law).unwrap();
            let last = col.last_step().unwrap();
            let (t0, y0, h) = (last.t0, last.y0.clone(), last.h);
            for fraction in [1e-6, 1e-4] {
                let t1 = t0 + fraction * h;
                let Some(shifted) = col.shift(&law, t0, &y0, t1) else { continue };
                let stepped = col.single_step(&law, t0, &y0, t1, false).unwrap();
                let back = col.shift(&law, t1, &shifted, t0).expect("the way back is as short");
                if col.coordinate(0, &y0).0 > 0.0 && col.coordinate(0, &stepped).0 > 0.0 {
                    inside += 1;
                }
                for k in 0..8 {
                    let scale: f64 = match k {
                        0..=2 => 0.01,
                        3..=5 => 0.5,
                        _ => y0[k].abs().max(1e-6),
                    };
                    assert!((shifted[k] - stepped[k]).abs() <= 1e-13 * scale, "t {t0} + {fraction} h, component {k}: shift {} against a step {}", shifted[k], stepped[k]);
                    assert!((back[k] - y0[k]).abs() <= 1e-12 * scale, "t {t0}, component {k}: there and back {} against {}", back[k], y0[k]);
                }
            }
        }
        assert!(inside > 20, "{inside} shifts inside the contact");
    }

    /// A spring with linear damping, its force clamped at zero: a push
    /// that ends inside the surface, its dissipated power jumping there.
    struct LinearPush {
        k: f64,
        c: f64,
    }

    impl PointForces for LinearPush {
        fn force(&self, _i: usize, p: f64, pd: f64) -> (f64, f64, f64) {
            let f = self.k * p + self.c * pd;
            if p <= 0.0 || f <= 0.0 {
                return (0.0, 0.0, 0.0);
            }
            (f, self.k, self.c)
        }
        fn dissipation_rate(&self, _i: usize, p: f64, pd: f64, force: f64) -> f64 {
            if force > 0.0 { (force - self.k * p) * pd } else { 0.0 }
        }
    }

    /// Across the end of such a push the power jumps (no line follows it):
    /// refused, though the force's change is negligible; inside the push,
    /// the same shift is taken.
    #[test]
    fn a_shift_across_a_jump_of_power_is_refused() {
        let dynamics = FreeDynamics::new(vec![Oscillator::new(3.0, 0.02)], ModalForcing::zero(1));
        let law = LinearPush { k: 1e6, c: 40.0 };
        let options = CollocationOptions { tol: 1e-12, q_scale: 1e-5, v_scale: 0.1, h_init: 1e-6, h_max: 1e-3, corner_fraction: 1e-12f64.powf(1.0 / 3.0) };
        let p = 1e-6;
        // Just past the push's end (k p + c p' = 0): clamped, no power.
        let past = DVector::from_vec(vec![p, -law.k * p / law.c - 1e-12, 0.0, 0.0]);
        let col = ForceCollocation::new(dynamics, vec![PointContact { d: DVector::from_vec(vec![1.0]), gap: 0.0 }], 0.0, past.clone(), options);
        assert_eq!(law.force(0, past[0], past[1]).0, 0.0);
        assert!(col.shift(&law, 0.0, &past, -1e-11).is_none(), "a shift back into the push");
        let pushing = DVector::from_vec(vec![p, -0.02, 0.0, 0.0]);
        assert!(law.force(0, pushing[0], pushing[1]).0 > 0.0);
        assert!(col.shift(&law, 0.0, &pushing, -1e-11).is_some(), "a shift inside the push");
    }
}
