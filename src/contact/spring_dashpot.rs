//! The compliant stop: a linear spring and dashpot that push and never
//! pull, `F = max(0, k p + c p')` with `p` the penetration (the clamped
//! Kelvin-Voigt form; seed 001 models the stop as the spring alone, c = 0).
//!
//! While pressed the stop adds `k w w^T` to the stiffness and `c w w^T` to
//! the damping of the modal equations, and the constant `k target w` to the
//! load: the phase stays linear and is propagated exactly. Its switches:
//! - apart, the gap closes: pressed;
//! - pressed, the force reaches zero: apart if `p <= 0` (always with c = 0),
//!   else penetrated without force (the dashpot would pull);
//! - penetrated, the force turns positive: pressed again; or the point
//!   leaves the surface: apart.

use super::{closing, Contact, Geometry, PhaseTerm, Switch, Watch};
use crate::solve::{Functional, Jet, ModalState};

#[derive(Clone, Debug, PartialEq)]
pub struct SpringDashpot {
    /// Stiffness (N/m in SI scenes).
    pub k: f64,
    /// Damping (N s/m).
    pub c: f64,
}

impl SpringDashpot {
    pub fn term(&self, contact: Contact) -> PhaseTerm {
        match contact {
            Contact::Pressed => PhaseTerm::SpringDashpot { k: self.k, c: self.c },
            _ => PhaseTerm::None,
        }
    }

    pub fn watches(&self, contact: Contact) -> &'static [Watch] {
        match contact {
            Contact::Pressed => &[Watch::Force],
            Contact::Penetrated => &[Watch::NegatedForce, Watch::Penetration],
            Contact::Open | Contact::Held => &[Watch::Gap],
        }
    }

    /// `k p + c p'` as a functional of the modal state.
    pub fn force_functional(&self, g: &Geometry) -> Functional {
        // Without a dashpot the force is a displacement functional, which
        // the free-flight search evaluates as an increment from the anchor.
        let qd = (self.c != 0.0).then(|| &g.w * (self.c * g.side));
        Functional { offset: -self.k * g.gap, q: &g.w * (self.k * g.side), qd, f: None }
    }

    pub fn force(&self, g: &Geometry, state: &ModalState) -> f64 {
        (self.k * g.penetration(&state.q) + self.c * g.penetration_rate(&state.qd)).max(0.0)
    }

    pub fn initial_contact(&self, g: &Geometry, state: &ModalState) -> Contact {
        let p = g.penetration(&state.q);
        if p <= 0.0 {
            Contact::Open
        } else if self.k * p + self.c * g.penetration_rate(&state.qd) > 0.0 {
            Contact::Pressed
        } else {
            Contact::Penetrated
        }
    }

    pub fn on_zero(&self, contact: Contact, watch: Watch, jet: &Jet, g: &Geometry, state: &ModalState) -> Switch {
        match (contact, watch) {
            // The gap closes (or rests closed with the load pressing on:
            // the force grows from zero).
            (Contact::Open, Watch::Gap) if closing(jet, true) => Switch::To(Contact::Pressed),
            (Contact::Pressed, Watch::Force) if closing(jet, false) => {
                if self.c > 0.0 && g.penetration(&state.q) > 0.0 {
                    Switch::To(Contact::Penetrated)
                } else {
                    Switch::To(Contact::Open)
                }
            }
            (Contact::Penetrated, Watch::NegatedForce) if closing(jet, false) => Switch::To(Contact::Pressed),
            (Contact::Penetrated, Watch::Penetration) if closing(jet, false) => Switch::To(Contact::Open),
            _ => Switch::Stay,
        }
    }
}
