//! Mode transfer (RMTM's MTM and RMTM methods): while a tip stop pushes
//! with a linear spring, the structure moves in the modes of the structure
//! with that spring, both fields projected at every switch. Any law whose
//! pushing force is a linear spring may offer it
//! ([`super::ContactLaw::mode_transfer`]); the structure asks only for
//! this description.

use serde::{Deserialize, Serialize};

/// What mode transfer needs from a stop's law.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModeTransfer {
    /// The spring's stiffness (N/m in SI scenes).
    pub stiffness: f64,
    pub method: ContactMethod,
    pub damping: TransferDamping,
}

/// RMTM's three ways of solving a contact phase of a tip spring stop.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum ContactMethod {
    /// Force integration: the stop's force on the structure's own modes
    /// (`K + k w w^T`), exact for that Galerkin model.
    #[default]
    Fim,
    /// Mode transfer: while in contact, the modes of the cantilever with
    /// the tip spring; both fields projected at every switch.
    Mtm,
    /// Relative mode transfer: the motion after each switch is an
    /// increment, in the new modes, over the shape frozen at the switch.
    Rmtm,
}

impl ContactMethod {
    pub fn is_fim(&self) -> bool {
        *self == ContactMethod::Fim
    }
}

/// The damping of the contact modes under mode transfer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum TransferDamping {
    /// The structure's modal damping ratio on every contact mode (RMTM:
    /// "adding damping" in each basis).
    #[default]
    Modal,
    /// The structure's own damping operator projected on the contact modes,
    /// `T diag(2 zeta omega) T^T`: the damping force integration applies, so
    /// the three methods then solve the same continuum.
    Inherited,
}

impl TransferDamping {
    pub fn is_modal(&self) -> bool {
        *self == TransferDamping::Modal
    }
}

