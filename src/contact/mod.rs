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
pub mod impact;
pub mod mode_transfer;
pub mod power_law;
pub mod restitution;
pub mod spring_dashpot;

use nalgebra::DVector;
use serde::{Deserialize, Serialize};

pub use hertz::Hertz;
pub use impact::{apply_impact, energy_loss, ImpactRow};
pub use mode_transfer::{ContactMethod, ModeTransfer, TransferDamping};
pub use power_law::PowerLaw;
pub use restitution::Restitution;
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
    /// `w . q = target` held by a reaction (VSM12 eqs. 29-33).
    Constraint,
    /// A force linear in the penetration and its rate, `-side w (k p +
    /// c p')` with `k` the stiffness and `c` the damping: `K += k w w^T`,
    /// `D += c w w^T`, `f += k target w`; the phase stays closed-form.
    Linear { stiffness: f64, damping: f64 },
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

/// One real parameter of a law, as the law describes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamSpec {
    /// The field in the scene's `law` object, and the variable's suffix.
    pub key: &'static str,
    /// `{stop}` stands for the stop's name.
    pub description: &'static str,
    /// Its unit, which also says which of the structure's limits bound
    /// it (a kind's `law_range`): [0, 1] for a ratio, durations, stiffness
    /// (N/m^n by its exponent), damping.
    pub unit: crate::units::Unit,
    /// May change between communication steps.
    pub tunable: bool,
}

/// A stop output a law provides (beside every stop's displacement,
/// velocity and impulse), evaluated by the simulation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum StopOutput {
    /// Impacts (rigid) or contact onsets (compliant) since the start.
    Impacts,
    /// Time of the latest impact or onset.
    LastImpact,
    Sticking,
    Sticks,
    StuckTime,
    /// A held stop's reaction.
    Reaction,
    /// The force pushing now.
    Force,
    Penetration,
    /// Whether the stop pushes.
    Contact,
    StoredEnergy,
    DissipatedEnergy,
}

/// How a law describes one of its outputs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LawOutput {
    pub what: StopOutput,
    /// The variable's suffix (`stop.<suffix>`).
    pub suffix: &'static str,
    /// `{stop}` stands for the stop's name.
    pub description: &'static str,
    pub unit: crate::units::Unit,
    pub kind: crate::variables::OutputType,
    /// Changes only at events.
    pub discrete: bool,
    /// How it reads on a rotating beam's surface, where the law is the
    /// tip's (`{force}` as in `description`), or `None` where a surface
    /// has no such output.
    pub surface: Option<&'static str>,
}

/// The force watch ([`ContactLaw::watched_force`]) of a law `K s(p) (1 +
/// h p') + C p'` (`s(p)`: `p^n` inside the surface, 0 beyond it): with a
/// linear dashpot (`C != 0`) the raw force from `raw`, already `C p'`
/// beyond the surface and `C v0` at an onset; otherwise the force over
/// `s(p)`, `K (1 + h p')` (`h`: the hysteresis factor, 0 undamped). Its
/// sign is the force's inside the surface, and unlike the force it does
/// not vanish where the point meets or leaves the surface: the force's
/// `p^n` would put a dip for the switch locator to search in every
/// contact's first and last sample intervals, and beyond the surface it
/// keeps the sign of a push that ended between two samples, the point's
/// exit among them.
pub(crate) fn push_watch(damping: ContactDamping, coefficient: f64, stiffness: f64, h: f64, pd: f64, raw: impl FnOnce() -> (f64, f64, f64)) -> (f64, f64, f64) {
    if damping.is_linear() && coefficient != 0.0 {
        raw()
    } else {
        (stiffness * (1.0 + h * pd), 0.0, stiffness * h)
    }
}

/// What a stop does: the contract every contact law implements, each in
/// its own file, registered in [`Law`]. The structure never needs to know
/// which law a stop has: it asks the law what the stop adds to a phase,
/// which functions watch for the end of a contact state, what a zero of
/// one does, and what the stop pushes with, stores and dissipates.
pub trait ContactLaw: Send + Sync + std::fmt::Debug {
    /// Its real parameters, in order.
    fn parameters(&self) -> Vec<ParamSpec>;
    /// What it needs beyond each parameter's own range (a field that one
    /// variant of the law takes and another does not); the error names
    /// the field, with `path` the law's place in the scene.
    fn validate(&self, path: &str) -> Result<(), String> {
        let _ = path;
        Ok(())
    }
    /// The contact states the law has.
    fn states(&self) -> &'static [Contact];
    /// What the stop adds to the equations of a phase in `contact`.
    fn term(&self, contact: Contact) -> PhaseTerm;
    /// The event functions of `contact`, each non-negative while it holds.
    fn watches(&self, contact: Contact) -> &'static [Watch];
    /// A watched function (any but a held stop's reaction, which only the
    /// constrained phase knows) at penetration `p` and rate `pd`, with its
    /// derivatives by `p` and `pd`: `(h, dh/dp, dh/dpd)`.
    fn watched(&self, watch: Watch, p: f64, pd: f64, onset_speed: f64) -> (f64, f64, f64) {
        match watch {
            Watch::Gap => (-p, -1.0, 0.0),
            Watch::Penetration => (p, 1.0, 0.0),
            Watch::Force => self.watched_force(p, pd, onset_speed),
            Watch::NegatedForce => {
                let (f, dp, dpd) = self.watched_force(p, pd, onset_speed);
                (-f, -dp, -dpd)
            }
            Watch::Reaction => unreachable!("a held stop's reaction is the phase's"),
        }
    }
    /// The decision at a zero of `watch` in `contact` (`jet`: the function's
    /// derivatives there, `p`: the penetration).
    fn on_zero(&self, contact: Contact, watch: Watch, jet: &Jet, p: f64) -> Switch;
    /// The contact state of a point starting at penetration `p`, rate `pd`.
    fn initial_contact(&self, p: f64, pd: f64) -> Contact;
    /// Whether a start inside the stop is impossible (a rigid stop).
    fn rigid(&self) -> bool {
        false
    }
    /// The unclamped force at penetration `p` and rate `pd` with its
    /// derivatives (compliant laws; `onset_speed`: the approach speed at
    /// the latest onset).
    fn raw_force(&self, p: f64, pd: f64, onset_speed: f64) -> (f64, f64, f64) {
        let _ = (p, pd, onset_speed);
        unreachable!("a rigid stop's force is a constraint reaction")
    }
    /// The force watch's function (compliant laws), with its derivatives
    /// by `p` and `pd`: any function whose sign is the unclamped force's
    /// inside the surface, defined beyond it too (its zero is a push's end
    /// inside the surface); the raw force unless the law has a better one
    /// ([`push_watch`]).
    fn watched_force(&self, p: f64, pd: f64, onset_speed: f64) -> (f64, f64, f64) {
        self.raw_force(p, pd, onset_speed)
    }
    /// The force the stop pushes with (>= 0) in `contact`, outside a constraint.
    fn force(&self, contact: Contact, p: f64, pd: f64, onset_speed: f64) -> f64 {
        match contact {
            Contact::Pressed => self.raw_force(p, pd, onset_speed).0.max(0.0),
            _ => 0.0,
        }
    }
    /// The spring's share of the force at penetration `p` (the rest
    /// dissipates) and its derivative by `p`.
    fn spring_force(&self, p: f64) -> (f64, f64) {
        let _ = p;
        (0.0, 0.0)
    }
    /// The force as a functional of the modal state, for laws whose force
    /// is linear in it while they push (`None` otherwise).
    fn force_functional(&self, geometry: &Geometry) -> Option<Functional> {
        let _ = geometry;
        None
    }
    /// A dashpot's coefficient, when the stop dissipates while its phase is linear.
    fn dashpot(&self) -> Option<f64> {
        None
    }
    /// The exponent `a` of the force's least smooth change at the start or
    /// end of a push, `F ~ t^a` there (integrated laws: Hertz's onset
    /// grows as `t^1.5`, a force reaching zero inside the surface has a
    /// kink, `a = 1`); an integrated phase's steps onto such a corner
    /// shrink to `tol^(1/(a+2))` of the contact's scale.
    fn corner_exponent(&self) -> f64 {
        1.0
    }
    /// Elastic energy stored at penetration `p` in `contact`.
    fn stored_energy(&self, contact: Contact, p: f64) -> f64 {
        let _ = (contact, p);
        0.0
    }
    /// How deep a point of mass `1 / inverse_mass` arriving at `speed`
    /// goes, the penetration storing its kinetic energy: the scale of a
    /// contact (infinite for a rigid stop).
    fn depth(&self, speed: f64, inverse_mass: f64) -> f64 {
        let _ = (speed, inverse_mass);
        f64::INFINITY
    }
    /// Energy left in the stop when it lets go at penetration `p`.
    fn energy_left_at_release(&self, p: f64) -> f64 {
        self.stored_energy(Contact::Pressed, p)
    }
    /// The restitution an impact at time `t` uses (rigid laws; `None`:
    /// the law does not impact).
    fn restitution(&self, t: f64, previous_impact: Option<f64>, speed: f64, negligible: f64) -> Option<f64> {
        let _ = (t, previous_impact, speed, negligible);
        None
    }
    /// Mode transfer for a tip spring (RMTM's MTM and RMTM methods): the
    /// spring's stiffness, the method and the damping of the contact modes.
    fn mode_transfer(&self) -> Option<ModeTransfer> {
        None
    }
    /// The stop outputs this law provides.
    fn outputs(&self) -> &'static [LawOutput];
    /// The formulas its output descriptions quote: the force and the
    /// stored energy.
    fn formulas(&self) -> (&'static str, &'static str) {
        ("", "")
    }
}

/// The registration of every law: the scene's `law` object, tagged by
/// `type`. A new law is a file implementing [`ContactLaw`] and a variant
/// here with its arm in `deref`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Law {
    #[cfg(feature = "restitution")]
    Restitution(Restitution),
    #[cfg(feature = "spring-dashpot")]
    SpringDashpot(SpringDashpot),
    #[cfg(feature = "power-law")]
    Hertz(Hertz),
    #[cfg(feature = "power-law")]
    PowerLaw(PowerLaw),
}

impl std::ops::Deref for Law {
    type Target = dyn ContactLaw;

    fn deref(&self) -> &(dyn ContactLaw + 'static) {
        match self {
            #[cfg(feature = "restitution")]
            Law::Restitution(l) => l,
            #[cfg(feature = "spring-dashpot")]
            Law::SpringDashpot(l) => l,
            #[cfg(feature = "power-law")]
            Law::Hertz(l) => l,
            #[cfg(feature = "power-law")]
            Law::PowerLaw(l) => l,
            #[cfg(not(any(feature = "restitution", feature = "spring-dashpot", feature = "power-law")))]
            _ => unreachable!("a build without contact laws reads no law"),
        }
    }
}

impl Law {
    /// The law's scene name, its `"type"`.
    pub fn name(&self) -> &'static str {
        match self {
            #[cfg(feature = "restitution")]
            Law::Restitution(_) => "restitution",
            #[cfg(feature = "spring-dashpot")]
            Law::SpringDashpot(_) => "spring_dashpot",
            #[cfg(feature = "power-law")]
            Law::Hertz(_) => "hertz",
            #[cfg(feature = "power-law")]
            Law::PowerLaw(_) => "power_law",
            #[cfg(not(any(feature = "restitution", feature = "spring-dashpot", feature = "power-law")))]
            _ => unreachable!("a build without contact laws reads no law"),
        }
    }
}

/// Every law's scene name and whether this build carries it (the features
/// `restitution`, `spring-dashpot` and `power-law`, which has both Hertz
/// and the power law: see Cargo.toml).
pub const LAWS: [(&str, bool); 4] = [
    ("restitution", cfg!(feature = "restitution")),
    ("spring_dashpot", cfg!(feature = "spring-dashpot")),
    ("hertz", cfg!(feature = "power-law")),
    ("power_law", cfg!(feature = "power-law")),
];

/// The law types a scene file uses: the `type` of every object under a
/// `law` key, each once, in the order met, with where it was met.
pub fn laws_in(scene: &serde_json::Value) -> Vec<(String, String)> {
    fn walk(v: &serde_json::Value, path: &str, out: &mut Vec<(String, String)>) {
        match v {
            serde_json::Value::Object(map) => {
                for (key, value) in map {
                    let here = if path.is_empty() { key.clone() } else { format!("{path}.{key}") };
                    if key == "law" {
                        if let Some(t) = value.get("type").and_then(|t| t.as_str()) {
                            if !out.iter().any(|(name, _)| name == t) {
                                out.push((t.to_string(), format!("{here}.type")));
                            }
                        }
                    }
                    walk(value, &here, out);
                }
            }
            serde_json::Value::Array(items) => {
                for (i, item) in items.iter().enumerate() {
                    walk(item, &format!("{path}[{i}]"), out);
                }
            }
            _ => {}
        }
    }
    let mut out = Vec::new();
    walk(scene, "", &mut out);
    out
}

/// Refuses a scene that uses a law this build does not carry, naming the
/// field, the law and the laws it has (an FMU binary built for another
/// scene; `beamstop package` picks one that carries it).
pub fn check_laws_built(scene: &serde_json::Value) -> Result<(), String> {
    for (name, field) in laws_in(scene) {
        if LAWS.iter().any(|(known, built)| *known == name && !built) {
            let have: Vec<&str> = LAWS.iter().filter(|(_, built)| *built).map(|(n, _)| *n).collect();
            return Err(format!(
                "{field} = \"{name}\": this binary was built without the {name} law (it has: {}); package the scene with `beamstop package`, which picks a binary that has it",
                if have.is_empty() { "none".to_string() } else { have.join(", ") }
            ));
        }
    }
    Ok(())
}

/// The damping of a compliant stop whose spring is `K p^n` (Hertz, power
/// law): DWZ's linear `C p'`, or a hysteretic one that vanishes with the
/// penetration and so keeps the force continuous at the onset.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ContactDamping {
    /// `C p'` (DWZ): the force jumps by `C v0` at the onset.
    #[default]
    Linear,
    /// Hunt & Crossley (HC75) as calibrated by Marhefka & Orin (MO99):
    /// `K p^n * 3 (1 - e) / 2 * p' / v0`.
    HuntCrossley,
    /// Lankarani & Nikravesh (LN90): `K p^n * 3 (1 - e^2) / 4 * p' / v0`.
    LankaraniNikravesh,
}

impl ContactDamping {
    pub fn is_linear(&self) -> bool {
        *self == ContactDamping::Linear
    }

    /// The hysteretic damping's factor of `p'` (`alpha / v0`, with `v0`
    /// the approach speed at the onset and `e` the restitution aimed at),
    /// 0 for the linear damping.
    pub fn hysteresis(self, e: f64, onset_speed: f64) -> f64 {
        let alpha = match self {
            ContactDamping::Linear => return 0.0,
            ContactDamping::HuntCrossley => 1.5 * (1.0 - e),
            ContactDamping::LankaraniNikravesh => 0.75 * (1.0 - e * e),
        };
        // An onset at (nearly) no speed has no hysteresis to scale: 0, not
        // an infinite factor (whose product with a zero spring is NaN).
        let factor = if onset_speed > 0.0 { alpha / onset_speed } else { 0.0 };
        if factor.is_finite() {
            factor
        } else {
            0.0
        }
    }

    /// Only the linear damping takes a coefficient `C` (`path`: the law's
    /// place in the scene).
    pub fn check_coefficient(self, path: &str, c: f64) -> Result<(), String> {
        if !self.is_linear() && c != 0.0 {
            return Err(format!("{path}.C = {c:?}: only the linear damping takes C (the {self:?} damping takes e); allowed value 0"));
        }
        Ok(())
    }
}

/// The contact states of a compliant stop: apart, pressed (pushing),
/// penetrated without force.
pub const COMPLIANT_STATES: &[Contact] = &[Contact::Open, Contact::Pressed, Contact::Penetrated];

/// The outputs of a compliant stop (`{force}` and `{stored}` stand for
/// the law's formulas, [`ContactLaw::formulas`]).
pub const COMPLIANT_OUTPUTS: &[LawOutput] = {
    use crate::units::Unit;
    use crate::variables::OutputType::{Boolean, Integer, Real};
    &[
        LawOutput {
            what: StopOutput::Force,
            suffix: "force",
            description: "Force of stop '{stop}', max(0, {force}) while in contact (>= 0, pushing the structure away)",
            unit: Unit::Newton,
            kind: Real,
            discrete: false,
            surface: Some("Force the surface pushes the tip with, max(0, {force}), p its penetration"),
        },
        LawOutput {
            what: StopOutput::Penetration,
            suffix: "penetration",
            description: "Penetration p of stop '{stop}' (negative: the clearance left)",
            unit: Unit::Metre,
            kind: Real,
            discrete: false,
            surface: Some("Penetration gamma of the tip into the surface (0 outside)"),
        },
        LawOutput {
            what: StopOutput::Contact,
            suffix: "contact",
            description: "Whether stop '{stop}' pushes (in contact)",
            unit: Unit::One,
            kind: Boolean,
            discrete: true,
            surface: Some("Whether the surface pushes the tip"),
        },
        LawOutput {
            what: StopOutput::Impacts,
            suffix: "contacts",
            description: "Number of contact onsets at stop '{stop}' since the start",
            unit: Unit::One,
            kind: Integer,
            discrete: true,
            surface: Some("Number of contact onsets since the start"),
        },
        LawOutput {
            what: StopOutput::LastImpact,
            suffix: "t_last_contact",
            description: "Exact time of the latest contact onset at stop '{stop}' (the start time before the first)",
            unit: Unit::Second,
            kind: Real,
            discrete: true,
            surface: None,
        },
        LawOutput {
            what: StopOutput::StoredEnergy,
            suffix: "E_stored",
            description: "Elastic energy stored in stop '{stop}' in contact ({stored})",
            unit: Unit::Joule,
            kind: Real,
            discrete: false,
            surface: None,
        },
        LawOutput {
            what: StopOutput::DissipatedEnergy,
            suffix: "E_dissipated",
            description: "Energy dissipated in stop '{stop}' since the start (its dashpot, and the spring energy left when contact ends inside the surface)",
            unit: Unit::Joule,
            kind: Real,
            discrete: false,
            surface: Some("Energy the contact dissipated since the start (its damping, and the spring energy left when a push ends inside the surface)"),
        },
    ]
};

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
