//! The equations of a phase with a nonlinear contact (a stop whose law's
//! phase term is nonlinear, pressed or penetrated), integrated instead of
//! solved in closed form.
//!
//! The structure stays linear: `q'' + 2 a q' + omega^2 q = f(t) - sum_i
//! side_i w_i F_i` with each engaged stop's force `F_i(p_i, p_i')` from its
//! law (Hertz: DWZ eqs. 2-4). The integrated state is `[q; q'; J; E]`:
//! besides the modal state it carries, per engaged stop, the impulse `J_i =
//! int F_i dt` and the energy its damping dissipates `E_i = int (F_i -
//! F_spring,i) p_i' dt`, so both come out of the integration to its accuracy.

use crate::contact::{Contact, Geometry, Law};
use crate::solve::collocation::PointForces;

/// An engaged stop in a nonlinear phase: a force of the state.
#[derive(Clone, Debug)]
pub struct NonlinearContact {
    /// The stop's index in the model.
    pub stop: usize,
    pub law: Law,
    pub geometry: Geometry,
    pub contact: Contact,
    pub onset_speed: f64,
}

impl NonlinearContact {
    /// The force and its partial derivatives `(F, dF/dp, dF/dp')`, zero
    /// where the law does not push.
    pub fn force(&self, p: f64, pd: f64) -> (f64, f64, f64) {
        if p <= 0.0 {
            return (0.0, 0.0, 0.0);
        }
        let (f, dp, dpd) = self.law.raw_force(p, pd, self.onset_speed);
        if f > 0.0 {
            (f, dp, dpd)
        } else {
            (0.0, 0.0, 0.0)
        }
    }

    /// The spring's share of the force and its derivative (the rest dissipates).
    pub fn spring_force(&self, p: f64) -> (f64, f64) {
        self.law.spring_force(p)
    }
}

/// The engaged stops of one nonlinear phase: the point forces the
/// collocation stepper solves for.
#[derive(Clone, Debug)]
pub struct NonlinearPhase {
    pub n: usize,
    pub contacts: Vec<NonlinearContact>,
}

impl NonlinearPhase {
    pub fn new(n: usize, contacts: Vec<NonlinearContact>) -> Self {
        NonlinearPhase { n, contacts }
    }

    /// Length of the integrated state `[q; q'; J; E]`.
    pub fn dim(&self) -> usize {
        2 * self.n + 2 * self.contacts.len()
    }

    /// Penetration and its rate of contact `i` in the integrated state `y`.
    pub fn penetration(&self, i: usize, y: &[f64]) -> (f64, f64) {
        let g = &self.contacts[i].geometry;
        let n = self.n;
        (g.side * dot(g.w.as_slice(), &y[..n]) - g.gap, g.side * dot(g.w.as_slice(), &y[n..2 * n]))
    }
}

impl PointForces for NonlinearPhase {
    fn force(&self, i: usize, p: f64, pd: f64) -> (f64, f64, f64) {
        self.contacts[i].force(p, pd)
    }

    /// `E' = (F - F_spring) p'` while the stop pushes.
    fn dissipation_rate(&self, i: usize, p: f64, pd: f64, force: f64) -> f64 {
        if force > 0.0 {
            (force - self.contacts[i].spring_force(p).0) * pd
        } else {
            0.0
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}
