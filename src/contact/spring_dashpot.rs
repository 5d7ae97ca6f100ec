//! The compliant stop: a linear spring and dashpot that push and never
//! pull, `F = max(0, k p + c p')` with `p` the penetration (the clamped
//! Kelvin-Voigt form; RMTM models the stop as the spring alone, c = 0).
//!
//! While pressed the stop adds `k w w^T` to the stiffness and `c w w^T` to
//! the damping of the modal equations, and the constant `k target w` to the
//! load: the phase stays linear and is propagated exactly. Its switches:
//! - apart, the gap closes: pressed;
//! - pressed, the force reaches zero: apart if `p <= 0` (always with c = 0),
//!   else penetrated without force (the dashpot would pull);
//! - penetrated, the force turns positive: pressed again; or the point
//!   leaves the surface: apart.

use serde::{Deserialize, Serialize};

use super::mode_transfer::{ContactMethod, ModeTransfer, TransferDamping};
use super::{closing, COMPLIANT_OUTPUTS, COMPLIANT_STATES, Contact, ContactLaw, Geometry, LawOutput, ParamSpec, PhaseTerm, Switch, Watch};
use crate::solve::{Functional, Jet};
use crate::units::Unit;

/// Scene schema: `{"type": "spring_dashpot", "k": ..., "c": ..., "method":
/// "fim" | "mtm" | "rmtm", "transfer_damping": "modal" | "inherited"}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpringDashpot {
    /// Stiffness (N/m in SI scenes).
    pub k: f64,
    /// Damping (N s/m).
    pub c: f64,
    /// How contact phases are represented (RMTM's three methods).
    #[serde(default, skip_serializing_if = "ContactMethod::is_fim")]
    pub method: ContactMethod,
    /// With mode transfer: how the contact modes are damped.
    #[serde(default, skip_serializing_if = "TransferDamping::is_modal")]
    pub transfer_damping: TransferDamping,
}

impl SpringDashpot {
    pub const PARAMETERS: &'static [ParamSpec] = &[
        ParamSpec {
            key: "k",
            description: "Stiffness of the compliant stop '{stop}' (force k p + c p', p the penetration)",
            unit: Unit::NewtonPerMetre,
            tunable: true,
        },
        ParamSpec {
            key: "c",
            description: "Damping of the compliant stop '{stop}' (the stop pushes, never pulls)",
            unit: Unit::NewtonSecondPerMetre,
            tunable: true,
        },
    ];
}

impl ContactLaw for SpringDashpot {
    fn parameters(&self) -> Vec<ParamSpec> {
        Self::PARAMETERS.to_vec()
    }

    fn validate(&self, path: &str) -> Result<(), String> {
        if !self.method.is_fim() && self.c != 0.0 {
            return Err(format!(
                "{path}.c = {}: mode transfer (method {:?}) models a spring stop alone: c must be 0 (use method \"fim\" for a dashpot)",
                self.c, self.method
            ));
        }
        Ok(())
    }

    fn states(&self) -> &'static [Contact] {
        COMPLIANT_STATES
    }

    fn term(&self, contact: Contact) -> PhaseTerm {
        match contact {
            Contact::Pressed => PhaseTerm::Linear { stiffness: self.k, damping: self.c },
            _ => PhaseTerm::None,
        }
    }

    fn watches(&self, contact: Contact) -> &'static [Watch] {
        match contact {
            Contact::Pressed => &[Watch::Force],
            Contact::Penetrated => &[Watch::NegatedForce, Watch::Penetration],
            Contact::Open | Contact::Held => &[Watch::Gap],
        }
    }

    fn on_zero(&self, contact: Contact, watch: Watch, jet: &Jet, p: f64) -> Switch {
        match (contact, watch) {
            // The gap closes (or rests closed with the load pressing on:
            // the force grows from zero).
            (Contact::Open, Watch::Gap) if closing(jet, true) => Switch::To(Contact::Pressed),
            (Contact::Pressed, Watch::Force) if closing(jet, false) => {
                if self.c > 0.0 && p > 0.0 {
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

    fn initial_contact(&self, p: f64, pd: f64) -> Contact {
        if p <= 0.0 {
            Contact::Open
        } else if self.k * p + self.c * pd > 0.0 {
            Contact::Pressed
        } else {
            Contact::Penetrated
        }
    }

    fn raw_force(&self, p: f64, pd: f64, _onset_speed: f64) -> (f64, f64, f64) {
        (self.k * p + self.c * pd, self.k, self.c)
    }

    fn spring_force(&self, p: f64) -> (f64, f64) {
        (self.k * p, self.k)
    }

    /// `k p + c p'` as a functional of the modal state.
    fn force_functional(&self, g: &Geometry) -> Option<Functional> {
        // Without a dashpot the force is a displacement functional, which
        // the free-flight search evaluates as an increment from the anchor.
        let qd = (self.c != 0.0).then(|| &g.w * (self.c * g.side));
        Some(Functional { offset: -self.k * g.gap, q: &g.w * (self.k * g.side), qd, f: None })
    }

    fn dashpot(&self) -> Option<f64> {
        (self.c > 0.0).then_some(self.c)
    }

    fn stored_energy(&self, contact: Contact, p: f64) -> f64 {
        match contact {
            Contact::Pressed => 0.5 * self.k * p.max(0.0).powi(2),
            _ => 0.0,
        }
    }

    /// `v sqrt(m / k)`, from `k p^2 / 2 = m v^2 / 2`.
    fn depth(&self, speed: f64, inverse_mass: f64) -> f64 {
        speed / (self.k * inverse_mass).sqrt()
    }

    /// A spring released inside the surface keeps `k p^2 / 2`.
    fn energy_left_at_release(&self, p: f64) -> f64 {
        0.5 * self.k * p * p
    }

    fn mode_transfer(&self) -> Option<ModeTransfer> {
        (!self.method.is_fim()).then_some(ModeTransfer { stiffness: self.k, method: self.method, damping: self.transfer_damping })
    }

    fn outputs(&self) -> &'static [LawOutput] {
        COMPLIANT_OUTPUTS
    }

    fn formulas(&self) -> (&'static str, &'static str) {
        ("k p + c p'", "k p^2 / 2")
    }
}
