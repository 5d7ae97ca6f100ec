//! The equations of a phase with a nonlinear contact (a stop whose law's
//! phase term is nonlinear, pressed or penetrated), integrated instead of
//! solved in closed form.
//!
//! The structure stays linear: `q'' + 2 a q' + omega^2 q = f(t) - sum_i
//! side_i w_i F_i` with each engaged stop's force `F_i(p_i, p_i')` from its
//! law (Hertz: DWZ eqs. 2-4), and each held rigid stop's `F_i` the
//! reaction that keeps it on its surface (`side_i w_i . q'' = 0`; VSM12
//! eq. 33 with the other stops' forces among the loads). The integrated state is `[q; q'; J; E]`:
//! besides the modal state it carries, per engaged stop, the impulse `J_i =
//! int F_i dt` and the energy its damping dissipates `E_i = int (F_i -
//! F_spring,i) p_i' dt`, so both come out of the integration to its accuracy.

use nalgebra::{DMatrix, DVector};

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
    /// A rigid stop held on its surface: its force is the reaction.
    pub held: bool,
}

impl NonlinearContact {
    /// The force and its partial derivatives `(F, dF/dp, dF/dp')`, zero
    /// where the law does not push.
    pub fn force(&self, p: f64, pd: f64) -> (f64, f64, f64) {
        if p <= 0.0 || self.held {
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

    /// The pushes of the held contacts (`F_i` of every contact, zero for
    /// the others) at time `t` in state `y`, given the modal forcing `f`
    /// there and the modes' `omega^2` and `2 a`: the forces that keep
    /// `side_i w_i . q'' = 0` for every held contact (VSM12 eq. 33).
    pub fn reactions(&self, y: &[f64], f: &DVector<f64>, stiffness: &[f64], damping: &[f64]) -> Vec<f64> {
        let accel = self.acceleration_without_holds(y, f, stiffness, damping, false);
        self.held_reactions(&accel)
    }

    /// [`Self::reactions`] with each contact entering its surface (at or
    /// short of it by rounding, moving in) pushing with the law's limit
    /// from inside: a linear damping's `C p'` at an onset, which a hold
    /// beside it answers from that instant.
    pub fn reactions_entering(&self, y: &[f64], f: &DVector<f64>, stiffness: &[f64], damping: &[f64]) -> Vec<f64> {
        let accel = self.acceleration_without_holds(y, f, stiffness, damping, true);
        self.held_reactions(&accel)
    }

    /// `q''` in state `y` (the loads `f` there, the modes' `omega^2` and
    /// `2 a`): the free acceleration less every engaged stop's push, the
    /// held ones' reactions included.
    pub fn acceleration(&self, y: &[f64], f: &DVector<f64>, stiffness: &[f64], damping: &[f64]) -> DVector<f64> {
        let mut accel = self.acceleration_without_holds(y, f, stiffness, damping, false);
        let pushes = self.held_reactions(&accel);
        for (c, push) in self.contacts.iter().zip(pushes) {
            if c.held {
                accel.axpy(-c.geometry.side * push, &c.geometry.w, 1.0);
            }
        }
        accel
    }

    /// `q''` less the held contacts' reactions (`entering`: see
    /// [`Self::reactions_entering`]).
    fn acceleration_without_holds(&self, y: &[f64], f: &DVector<f64>, stiffness: &[f64], damping: &[f64], entering: bool) -> DVector<f64> {
        let n = self.n;
        let mut accel = DVector::from_fn(n, |j, _| f[j] - stiffness[j] * y[j] - damping[j] * y[n + j]);
        for (i, c) in self.contacts.iter().enumerate() {
            if !c.held {
                let (p, pd) = self.penetration(i, y);
                let force = if entering && p <= 0.0 && pd > 0.0 { c.law.raw_force(0.0, pd, c.onset_speed).0.max(0.0) } else { c.force(p, pd).0 };
                accel.axpy(-c.geometry.side * force, &c.geometry.w, 1.0);
            }
        }
        accel
    }

    /// The held contacts' pushes that cancel `accel` along their
    /// directions (zero for the other contacts).
    fn held_reactions(&self, accel: &DVector<f64>) -> Vec<f64> {
        let held: Vec<usize> = (0..self.contacts.len()).filter(|&i| self.contacts[i].held).collect();
        let mut out = vec![0.0; self.contacts.len()];
        if held.is_empty() {
            return out;
        }
        let d = |i: usize| &self.contacts[i].geometry.w * self.contacts[i].geometry.side;
        let gram = DMatrix::from_fn(held.len(), held.len(), |a, b| d(held[a]).dot(&d(held[b])));
        let rhs = DVector::from_fn(held.len(), |a, _| d(held[a]).dot(accel));
        if let Some(x) = gram.lu().solve(&rhs) {
            for (a, &i) in held.iter().enumerate() {
                out[i] = x[a];
            }
        }
        out
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

    fn held(&self, i: usize) -> bool {
        self.contacts[i].held
    }

    /// `dF/dv0` (a hysteretic damping scales with `1 / v0`): a central
    /// difference, exact to `(dv / v0)^2` for a force affine in `1 / v0`.
    fn parameter_partial(&self, i: usize, p: f64, pd: f64) -> f64 {
        let c = &self.contacts[i];
        let v0 = c.onset_speed;
        if c.held || v0 <= 0.0 || c.force(p, pd).0 == 0.0 {
            return 0.0;
        }
        let dv = 1e-6 * v0;
        let at = |v: f64| c.law.raw_force(p, pd, v).0;
        (at(v0 + dv) - at(v0 - dv)) / (2.0 * dv)
    }

    /// `E'` by the contact state's own account, whatever the force at
    /// the node: pressed, the stop stores its spring's energy, so `E' =
    /// (F - F_spring) p'` (the force clamped at zero too, before its
    /// push's end is located); penetrated, it stores none, so `E' = F p'`
    /// (a push resumed before its resumption is located); a reaction does
    /// no work. The balance of the phase's outputs then holds at every
    /// node: by the force's sign alone, a node whose Newton force was a
    /// rounding-sized push in a penetrated stop counted its whole spring
    /// power `-F_spring p'` as dissipated (5.9e-6 of the energy at
    /// tolerance 1e-8 in a scene with two power-law stops).
    fn dissipation_rate(&self, i: usize, p: f64, pd: f64, force: f64) -> f64 {
        let c = &self.contacts[i];
        match c.contact {
            _ if c.held => 0.0,
            Contact::Pressed => (force - c.spring_force(p).0) * pd,
            Contact::Penetrated => force * pd,
            Contact::Open | Contact::Held => 0.0,
        }
    }
}

pub(super) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}
