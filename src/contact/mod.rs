//! Contact laws: what a stop does to the structure, one type per law.
//!
//! A law owns its parameters and decides, for each contact state, what the
//! stop adds to the phase the structure moves in ([`PhaseTerm`]), which
//! event functions watch for the end of that state ([`Watch`]) and what a
//! zero of one of them does ([`Switch`]). The simulation combines the stops'
//! terms into one phase, linear time-invariant in every law here, and runs
//! one certified event search over every watched function.
//!
//! A law's type is also its scene schema (`{"type": "<law>", ...}`) and
//! lists its own parameters ([`ParamSpec`]), which the interface turns into
//! FMU parameters. Adding a law: a file here with its type, its parameters
//! and these three answers, and a variant in [`Law`] with its arms (the one
//! registration).

pub mod hertz;
pub mod restitution;
pub mod spring_dashpot;

use nalgebra::DVector;
use serde::{Deserialize, Serialize};

pub use hertz::{Hertz, HertzDamping};
pub use restitution::{apply_impact, ImpactRow, Restitution};
pub use spring_dashpot::SpringDashpot;

use crate::solve::events::{tendency_from, Tendency};
use crate::solve::{Functional, Jet};

/// Where a stop acts and how far away it is.
#[derive(Clone, Debug, PartialEq)]
pub struct Geometry {
    /// `w_j = W_j(x_stop)`: the contact point's displacement is `w . q`.
    pub w: DVector<f64>,
    pub gap: f64,
    /// +1: the stop limits `w . q <= gap`; -1: `w . q >= -gap`.
    pub side: f64,
}

impl Geometry {
    /// The value of `w . q` on the stop's surface.
    pub fn target(&self) -> f64 {
        self.side * self.gap
    }

    /// The gap `side (target - w . q)`, non-negative when apart.
    pub fn gap_functional(&self) -> Functional {
        Functional::of_position(self.gap, -&self.w * self.side)
    }

    /// The penetration `p = side w . q - gap` (minus the gap).
    pub fn penetration(&self, q: &DVector<f64>) -> f64 {
        self.side * self.w.dot(q) - self.gap
    }

    /// `p' = side w . qd`.
    pub fn penetration_rate(&self, qd: &DVector<f64>) -> f64 {
        self.side * self.w.dot(qd)
    }
}

/// The state of one contact point.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Contact {
    /// No force; apart from the stop (or on it, leaving).
    Open,
    /// Held on a rigid stop (sticking): a constraint of the phase.
    Held,
    /// Pressed into a compliant stop: its spring and dashpot act.
    Pressed,
    /// Inside a compliant stop's surface without force (its dashpot would
    /// pull): moving freely until the force turns positive again or the
    /// point leaves the surface.
    Penetrated,
}

impl Contact {
    pub fn code(self) -> u8 {
        match self {
            Contact::Open => 0,
            Contact::Held => 1,
            Contact::Pressed => 2,
            Contact::Penetrated => 3,
        }
    }

    pub fn from_code(c: u8) -> Option<Contact> {
        Some(match c {
            0 => Contact::Open,
            1 => Contact::Held,
            2 => Contact::Pressed,
            3 => Contact::Penetrated,
            _ => return None,
        })
    }
}

/// What a stop adds to the equations of the phase.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PhaseTerm {
    None,
    /// `w . q = target` held by a reaction (seed 000 eqs. 29-33).
    Constraint,
    /// `-side w (k p + c p')`: `K += k w w^T`, `D += c w w^T`, `f += k target w`.
    SpringDashpot { k: f64, c: f64 },
    /// A force nonlinear in the state (Hertz): the phase is integrated.
    Nonlinear,
}

/// An event function of a contact state; each is non-negative while the
/// state holds, and its zero is where the law decides.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Watch {
    /// The gap (apart: contact when it closes).
    Gap,
    /// The push of a held stop's reaction, `-side lambda` (release when it
    /// would pull).
    Reaction,
    /// A compliant stop's force `k p + c p'` (release when it reaches 0).
    Force,
    /// Minus that force, while penetrated without force (re-engage).
    NegatedForce,
    /// The penetration, while penetrated without force (back outside).
    Penetration,
}

/// What a zero of a watched function does.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Switch {
    /// Nothing: the function touches zero and leaves it (departing).
    Stay,
    /// The contact state changes without an impulse.
    To(Contact),
    /// A rigid impact (the simulation solves the impulses of every
    /// simultaneous impact together).
    Impact,
    /// Zero velocity on a rigid stop with the load pressing on: hold.
    Stick,
    /// Zero velocity on a rigid stop, leaving it: no impact (recorded).
    Graze,
}

/// A stop's contact law: the registration of every law, and the scene's
/// `law` object (tagged by `type`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Law {
    Restitution(Restitution),
    SpringDashpot(SpringDashpot),
    Hertz(Hertz),
}

/// Which of the structure's limits bounds a law parameter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RangeKind {
    /// [0, 1].
    Unit,
    /// Durations: up to 1000 periods of the slowest mode.
    Duration,
    /// Stop stiffnesses.
    Stiffness,
    /// Stop damping coefficients.
    Damping,
    /// Hertz stiffnesses `K` of `K p^1.5`.
    HertzStiffness,
}

/// One real parameter of a law, as the law describes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamSpec {
    /// The field in the scene's `law` object, and the variable's suffix.
    pub key: &'static str,
    /// `{stop}` stands for the stop's name.
    pub description: &'static str,
    pub unit: crate::units::Unit,
    pub range: RangeKind,
    /// May change between communication steps.
    pub tunable: bool,
}

impl Law {
    pub fn parameters(&self) -> &'static [ParamSpec] {
        match self {
            Law::Restitution(_) => Restitution::PARAMETERS,
            Law::SpringDashpot(_) => SpringDashpot::PARAMETERS,
            Law::Hertz(l) => l.parameters(),
        }
    }

    /// The value of parameter `k` (in the order of [`Self::parameters`]).
    pub fn value_mut(&mut self, k: usize) -> &mut f64 {
        match self {
            Law::Restitution(l) => l.value_mut(k),
            Law::SpringDashpot(l) => l.value_mut(k),
            Law::Hertz(l) => l.value_mut(k),
        }
    }

    pub fn value(&self, k: usize) -> f64 {
        *self.clone().value_mut(k)
    }

    pub fn is_rigid(&self) -> bool {
        matches!(self, Law::Restitution(_))
    }

    /// Whether some contact state of the law makes the phase nonlinear.
    pub fn is_nonlinear(&self) -> bool {
        matches!(self, Law::Hertz(_))
    }

    pub fn term(&self, contact: Contact) -> PhaseTerm {
        match self {
            Law::Restitution(l) => l.term(contact),
            Law::SpringDashpot(l) => l.term(contact),
            Law::Hertz(l) => l.term(contact),
        }
    }

    pub fn watches(&self, contact: Contact) -> &'static [Watch] {
        match self {
            Law::Restitution(l) => l.watches(contact),
            Law::SpringDashpot(l) => l.watches(contact),
            Law::Hertz(l) => l.watches(contact),
        }
    }

    /// The law's decision at a zero of `watch` in state `contact`.
    pub fn on_zero(&self, contact: Contact, watch: Watch, jet: &Jet, geometry: &Geometry, state: &crate::solve::ModalState) -> Switch {
        match self {
            Law::Restitution(l) => l.on_zero(contact, watch, jet),
            Law::SpringDashpot(l) => l.on_zero(contact, watch, jet, geometry, state),
            Law::Hertz(l) => l.on_zero(contact, watch, jet, geometry.penetration(&state.q)),
        }
    }

    /// The contact state of a point at rest in `state` at the start of a run
    /// (`None`: the state is not admissible for this law).
    pub fn initial_contact(&self, geometry: &Geometry, state: &crate::solve::ModalState) -> Option<Contact> {
        match self {
            Law::Restitution(_) => Some(Contact::Open),
            Law::SpringDashpot(l) => Some(l.initial_contact(geometry, state)),
            Law::Hertz(l) => Some(l.initial_contact(geometry.penetration(&state.q), geometry.penetration_rate(&state.qd))),
        }
    }

    /// The force the stop pushes with (>= 0), for a state outside a
    /// constraint (a held stop's force is its reaction); `onset_speed`: the
    /// approach speed at the latest contact onset.
    pub fn force(&self, contact: Contact, geometry: &Geometry, state: &crate::solve::ModalState, onset_speed: f64) -> f64 {
        match (self, contact) {
            (Law::SpringDashpot(l), Contact::Pressed) => l.force(geometry, state),
            (Law::Hertz(l), _) => l.force(contact, geometry.penetration(&state.q), geometry.penetration_rate(&state.qd), onset_speed),
            _ => 0.0,
        }
    }

    /// The value of a watched function (any but a held stop's reaction,
    /// which only the constrained phase knows) at penetration `p` and rate
    /// `pd`, with its derivatives by `p` and `pd`: `(h, dh/dp, dh/dpd)`.
    pub fn watched(&self, watch: Watch, p: f64, pd: f64, onset_speed: f64) -> (f64, f64, f64) {
        let force = || match self {
            Law::SpringDashpot(l) => (l.k * p + l.c * pd, l.k, l.c),
            Law::Hertz(l) => l.raw_force(p, pd, onset_speed),
            Law::Restitution(_) => unreachable!("a rigid stop watches no force"),
        };
        match watch {
            Watch::Gap => (-p, -1.0, 0.0),
            Watch::Penetration => (p, 1.0, 0.0),
            Watch::Force => force(),
            Watch::NegatedForce => {
                let (f, dp, dpd) = force();
                (-f, -dp, -dpd)
            }
            Watch::Reaction => unreachable!("a held stop's reaction is the phase's"),
        }
    }

    /// The contact states this law has.
    pub fn states(&self) -> &'static [Contact] {
        match self {
            Law::Restitution(_) => &[Contact::Open, Contact::Held],
            Law::SpringDashpot(_) | Law::Hertz(_) => &[Contact::Open, Contact::Pressed, Contact::Penetrated],
        }
    }

    /// The force as a functional of the state, for laws whose force is
    /// linear in it while they push (`None` for a rigid stop: its force is
    /// a constraint reaction).
    pub fn force_functional(&self, geometry: &Geometry) -> Option<Functional> {
        match self {
            Law::SpringDashpot(l) => Some(l.force_functional(geometry)),
            Law::Restitution(_) | Law::Hertz(_) => None,
        }
    }

    /// A dashpot's coefficient, when the stop dissipates while pushing.
    pub fn dashpot(&self) -> Option<f64> {
        match self {
            Law::SpringDashpot(l) if l.c > 0.0 => Some(l.c),
            _ => None,
        }
    }

    /// Energy left in the stop when it lets go at penetration `p` (a
    /// spring released inside the surface keeps `k p^2 / 2`).
    pub fn energy_left_at_release(&self, p: f64) -> f64 {
        match self {
            Law::SpringDashpot(l) => 0.5 * l.k * p * p,
            Law::Hertz(l) => l.stored_energy(p),
            Law::Restitution(_) => 0.0,
        }
    }

    /// Elastic energy stored in the stop.
    pub fn stored_energy(&self, contact: Contact, geometry: &Geometry, state: &crate::solve::ModalState) -> f64 {
        match (self, contact) {
            (Law::SpringDashpot(l), Contact::Pressed) => 0.5 * l.k * geometry.penetration(&state.q).max(0.0).powi(2),
            (Law::Hertz(l), Contact::Pressed) => l.stored_energy(geometry.penetration(&state.q)),
            _ => 0.0,
        }
    }
}

/// Whether a function at its zero (value within noise) is closing: its
/// slope is negative, or zero with the next visible derivative negative
/// (resting counts as closing when `resting_closes`).
pub fn closing(jet: &Jet, resting_closes: bool) -> bool {
    if jet.d[1] < -jet.noise[1] {
        return true;
    }
    if jet.d[1] > jet.noise[1] {
        return false;
    }
    match tendency_from(jet, 2) {
        Tendency::Closing => true,
        Tendency::Resting => resting_closes,
        Tendency::Opening => false,
    }
}
