//! The scene file: what a user describes (JSON, read with serde_json), its
//! validation, and the names under which its settings appear.
//!
//! Every field is checked on load; an error names the field, the value and
//! what is allowed, and no model is built from an invalid scene.

use std::collections::BTreeMap;
use std::fmt;

use serde::{Deserialize, Serialize};

pub use crate::variables::{guid_of, Experiment, Range};

pub type Names = BTreeMap<String, String>;

/// A complete scene: one FMU.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// The FMU's model identifier: letters, digits and '_' only.
    pub name: String,
    #[serde(default)]
    pub description: String,
    /// `scaled` (dimensionless, as in VSM12 and WB00) or `SI`.
    #[serde(default)]
    pub units: Units,
    pub structure: StructureSpec,
    /// Modal damping of a beam (a chain's damping is `structure.c`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub damping: Option<Damping>,
    #[serde(default)]
    pub loads: Vec<Load>,
    #[serde(default)]
    pub stops: Vec<Stop>,
    #[serde(default)]
    pub sensors: Vec<Sensor>,
    #[serde(default)]
    pub actuators: Vec<Actuator>,
    #[serde(default)]
    pub outputs: OutputChoice,
    #[serde(default)]
    pub initial: Initial,
    #[serde(default)]
    pub solver: Solver,
    /// The default experiment of the FMU (and of `beamstop run`).
    #[serde(default)]
    pub experiment: Experiment,
    /// Renames of the model-wide variables (`energy`, `q[{j}]`, ...).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub names: Names,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum Units {
    /// Dimensionless units (VSM12's `x = X/L`, `w = Z/L`, scaled time; WB00's
    /// chain): every quantity has unit "1".
    #[default]
    #[serde(rename = "scaled")]
    Scaled,
    #[serde(rename = "SI")]
    Si,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum StructureSpec {
    /// An Euler-Bernoulli beam. Scaled units: `L = rho A = EI = 1` (give no
    /// section). SI: `length` [m], `E` [Pa], `I` [m^4], `rho` [kg/m^3], `A` [m^2].
    Beam {
        support: SupportKind,
        modes: usize,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        length: Option<f64>,
        #[serde(default, rename = "E", skip_serializing_if = "Option::is_none")]
        youngs_modulus: Option<f64>,
        #[serde(default, rename = "I", skip_serializing_if = "Option::is_none")]
        second_moment: Option<f64>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        rho: Option<f64>,
        #[serde(default, rename = "A", skip_serializing_if = "Option::is_none")]
        area: Option<f64>,
    },
    /// The uniform N-mass chain of WB00: masses `m`, springs `k` and
    /// dampers `c` from the ground to mass 1 and between neighbours.
    Chain { masses: usize, m: f64, k: f64, c: f64 },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SupportKind {
    PinnedPinned,
    ClampedFree,
    ClampedClamped,
    ClampedPinned,
}

/// Exactly one of: a damping ratio for every mode, one per mode, or a
/// viscous coefficient per unit length `c` (`zeta_j = c / (2 rho A omega_j)`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct Damping {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub zeta: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub zeta_modes: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub viscous: Option<f64>,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub names: Names,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Waveform {
    #[default]
    Sin,
    Cos,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum Load {
    /// `amplitude sin(omega t)` per unit length over the whole span (VSM12 eq. 4).
    DistributedHarmonic {
        name: String,
        amplitude: f64,
        omega: f64,
        #[serde(default)]
        waveform: Waveform,
        #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
        names: Names,
    },
    /// A harmonic point force at `x` (beam) or on `mass` (chain; WB00's
    /// forcing vector `A cos(Omega t)`).
    PointHarmonic {
        name: String,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        x: Option<f64>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        mass: Option<usize>,
        amplitude: f64,
        omega: f64,
        #[serde(default)]
        waveform: Waveform,
        #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
        names: Names,
    },
    /// Harmonic acceleration `amplitude sin(omega t)` of the supports; the
    /// motion is relative to them, stops move with them.
    BaseExcitation {
        name: String,
        amplitude: f64,
        omega: f64,
        #[serde(default)]
        waveform: Waveform,
        #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
        names: Names,
    },
}

/// A point of the structure as written: `x` along a beam or `mass` (from 1)
/// of a chain (the `x` / `mass` fields of loads, stops, sensors, actuators).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Location {
    pub x: Option<f64>,
    pub mass: Option<usize>,
}

impl Stop {
    pub fn at(&self) -> Location {
        Location { x: self.x, mass: self.mass }
    }
}

impl Sensor {
    pub fn at(&self) -> Location {
        Location { x: self.x, mass: self.mass }
    }
}

impl Actuator {
    pub fn at(&self) -> Location {
        Location { x: self.x, mass: self.mass }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Side {
    /// The stop limits `w <= gap` (VSM12: `w(x_i) <= d`).
    #[default]
    Positive,
    /// The stop limits `w >= -gap`.
    Negative,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Stop {
    pub name: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub x: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass: Option<usize>,
    /// Clearance from the undeformed structure (negative: preloaded).
    pub gap: f64,
    #[serde(default)]
    pub side: Side,
    pub law: StopLaw,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub names: Names,
}

/// A stop's law: the contact law types are their own schema
/// (`crate::contact`).
pub use crate::contact::Law as StopLaw;
pub use crate::contact::mode_transfer::{ContactMethod, TransferDamping};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Quantity {
    Displacement,
    Velocity,
    /// `EI w''(x)` (beams only).
    BendingMoment,
}

/// A measuring point: its quantities become outputs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sensor {
    pub name: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub x: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass: Option<usize>,
    pub quantities: Vec<Quantity>,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub names: Names,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ActuatorKind {
    /// A point force input at `x` / `mass`.
    #[default]
    Force,
    /// An acceleration input of the supports.
    BaseAcceleration,
}

/// An input, held constant over each communication step.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Actuator {
    pub name: String,
    #[serde(default)]
    pub kind: ActuatorKind,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub x: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass: Option<usize>,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub names: Names,
}

/// Which model-wide outputs the FMU carries.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputChoice {
    /// Kinetic plus strain energy.
    #[serde(default = "yes")]
    pub energy: bool,
    /// Modal coordinates `q[j]`, `qd[j]`.
    #[serde(default = "yes")]
    pub modal: bool,
    /// WB00's modal forcing energy `FE[j]`, damping energy `DE[j]`
    /// (eq. 8) and the energy lost at impacts, accumulated from the start.
    #[serde(default)]
    pub energy_balance: bool,
    /// Each stop's impulse over the last communication step (`<stop>.impulse`),
    /// for a master that couples the stop to another model.
    #[serde(default = "yes")]
    pub impulse: bool,
}

fn yes() -> bool {
    true
}

impl Default for OutputChoice {
    fn default() -> Self {
        OutputChoice { energy: true, modal: true, energy_balance: false, impulse: true }
    }
}

/// Initial modal coordinates (missing entries are zero), in displacement
/// units: `w(x) = sum_j W~_j(x / L) q_j` with unit-mean-square shapes for
/// beams, `x = sum_j xi_j q_j` with unit-norm eigenvectors for chains.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct Initial {
    #[serde(default)]
    pub q: Vec<f64>,
    #[serde(default)]
    pub qd: Vec<f64>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Solver {
    /// Events are located once the event function is within this distance of
    /// zero (0: to rounding, a few ulps in time).
    #[serde(default)]
    pub event_tolerance: f64,
    /// Events allowed within one communication step before it is discarded.
    #[serde(default = "default_max_events")]
    pub max_events_per_step: u64,
    /// Points of the event search allowed within one communication step
    /// (events included) before it is discarded at the time reached; the
    /// default keeps one step under about a second at any number of modes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_probes_per_step: Option<u64>,
    /// Relative local error the integration of nonlinear contact phases
    /// (Hertz) aims at (closed-form phases are exact regardless).
    #[serde(default = "default_integration_tolerance")]
    pub integration_tolerance: f64,
}

fn default_max_events() -> u64 {
    1_000_000
}

fn default_integration_tolerance() -> f64 {
    1e-10
}

/// Whether a law has a contact state whose phase is integrated.
fn integrated(law: &StopLaw) -> bool {
    law.states().iter().any(|c| law.term(*c) == crate::contact::PhaseTerm::Nonlinear)
}

impl Scene {
    /// Whether some contact phase of the scene is integrated (then
    /// `solver.integration_tolerance` matters).
    pub fn has_integrated_phase(&self) -> bool {
        self.stops.iter().any(|s| integrated(&s.law))
    }
}

/// The tolerance the force collocation is given for
/// `solver.integration_tolerance = asked`: the same down to 1e-7, a
/// twentieth of it at 1e-10 and a hundredth from 1e-11 on, blended
/// geometrically between, no tighter than [`COLLOCATION_TOLERANCE_FLOOR`].
/// Its local error control keeps HertzStop's error within 0.11 to 1.4
/// times the tolerance from 1e-4 to 1e-7 of the gap; the errors a step
/// leaves add up over the contacts and the free flights between them (a
/// rate's error grows into the displacement's), to 4 times the
/// collocation's tolerance at 1e-10 and 35 at 1e-11, and stop falling
/// near 3e-11 (20 modes) from 5e-12 down (report/shared_peer): so that
/// the error stays within about the tolerance asked from 1e-7 down and no
/// larger below 1e-10 than at it.
pub fn collocation_tolerance(asked: f64) -> f64 {
    let share = if asked >= 1e-7 {
        1.0
    } else if asked >= 1e-10 {
        // 1 at 1e-7, 1/20 at 1e-10.
        (asked / 1e-7).powf(20f64.log10() / 3.0)
    } else if asked >= 1e-11 {
        // 1/20 at 1e-10, 1/100 at 1e-11.
        0.05 * (asked / 1e-10).powf(5f64.log10())
    } else {
        0.01
    };
    (share * asked).max(COLLOCATION_TOLERANCE_FLOOR)
}

/// The tightest tolerance the force collocation is given (from 2e-14
/// asked down to the range's floor): about the rounding of its states.
/// HertzStop's tightest runs come within 6.5e-12 (20 modes) and 4.6e-12
/// (32) of the gap of the reference peer's.
const COLLOCATION_TOLERANCE_FLOOR: f64 = 2e-16;

/// The range of `solver.integration_tolerance`.
pub const INTEGRATION_TOLERANCE_RANGE: Range = Range { min: 1e-14, max: 1e-2, min_open: false, max_open: false };

impl Default for Solver {
    fn default() -> Self {
        Solver {
            event_tolerance: 0.0,
            max_events_per_step: default_max_events(),
            max_probes_per_step: None,
            integration_tolerance: default_integration_tolerance(),
        }
    }
}

/// A scene that failed to load or validate.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneError(pub String);

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for SceneError {}

fn err<T>(m: String) -> Result<T, SceneError> {
    Err(SceneError(m))
}

fn check_name(what: &str, name: &str) -> Result<(), SceneError> {
    if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
        return err(format!("{what} = {name:?}: use letters, digits and '_' only"));
    }
    Ok(())
}

fn positive(what: &str, v: Option<f64>) -> Result<f64, SceneError> {
    match v {
        Some(v) => {
            Range::POSITIVE.check(what, v).map_err(SceneError)?;
            Ok(v)
        }
        None => err(format!("{what} is missing: SI beams need length, E, I, rho and A")),
    }
}

/// The section of a beam in SI units: (length, rho A, E I).
pub struct Section {
    pub length: f64,
    pub mass_per_length: f64,
    pub bending_stiffness: f64,
}

impl Scene {
    /// Parses a scene without validating it (see `Scene::from_json`,
    /// which validates against the interface the scene defines).
    pub fn parse(text: &str) -> Result<Scene, SceneError> {
        serde_json::from_str(text).map_err(|e| SceneError(format!("scene: {e}")))
    }

    /// The canonical serialisation: the GUID and the packaged copy derive from it.
    pub fn canonical_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a scene always serialises")
    }

    /// `{xxxxxxxx-xxxx-xxxx-xxxx-xxxxxxxxxxxx}` from the SHA-256 of the canonical
    /// scene and the crate version.
    pub fn guid(&self) -> String {
        guid_of(&self.canonical_json())
    }

    pub fn n_modes(&self) -> usize {
        match &self.structure {
            StructureSpec::Beam { modes, .. } => *modes,
            StructureSpec::Chain { masses, .. } => *masses,
        }
    }

    pub fn is_beam(&self) -> bool {
        matches!(self.structure, StructureSpec::Beam { .. })
    }

    /// The beam's length, mass per length and bending stiffness (1, 1, 1 in
    /// scaled units); `None` for a chain.
    pub fn section(&self) -> Result<Option<Section>, SceneError> {
        let StructureSpec::Beam { length, youngs_modulus, second_moment, rho, area, .. } = &self.structure else {
            return Ok(None);
        };
        match self.units {
            Units::Scaled => {
                for (name, v) in [("length", length), ("E", youngs_modulus), ("I", second_moment), ("rho", rho), ("A", area)] {
                    if v.is_some() {
                        return err(format!(
                            "structure.{name} is given but units = \"scaled\" (L = rho A = EI = 1): remove it or set \"units\": \"SI\""
                        ));
                    }
                }
                Ok(Some(Section { length: 1.0, mass_per_length: 1.0, bending_stiffness: 1.0 }))
            }
            Units::Si => Ok(Some(Section {
                length: positive("structure.length", *length)?,
                mass_per_length: positive("structure.rho", *rho)? * positive("structure.A", *area)?,
                bending_stiffness: positive("structure.E", *youngs_modulus)? * positive("structure.I", *second_moment)?,
            })),
        }
    }

    /// Checks a location belongs to the structure: `x` on a beam, `mass` on a chain.
    pub fn check_location(&self, what: &str, at: &Location) -> Result<(), SceneError> {
        match (&self.structure, at.x, at.mass) {
            (StructureSpec::Beam { .. }, Some(_), None) => Ok(()),
            (StructureSpec::Chain { masses, .. }, None, Some(i)) => {
                if (1..=*masses).contains(&i) {
                    Ok(())
                } else {
                    err(format!("{what}.mass = {i}: allowed masses are 1..={masses}"))
                }
            }
            (StructureSpec::Beam { .. }, _, _) => err(format!("{what}: a point on a beam is given by \"x\" (and no \"mass\")")),
            (StructureSpec::Chain { .. }, _, _) => err(format!("{what}: a point on a chain is given by \"mass\" (and no \"x\")")),
        }
    }

    /// Structural validation: the parts of a scene that fit together (the
    /// values' ranges are checked by `Scene::validate`, in `crate::kinds::modal::interface`).
    pub fn validate_structure(&self) -> Result<(), SceneError> {
        crate::kind::check_scene_name(&self.name).map_err(SceneError)?;
        let n = self.n_modes();
        match &self.structure {
            StructureSpec::Beam { .. } => {
                if !(1..=500).contains(&n) {
                    return err(format!("structure.modes = {n}: allowed range is [1, 500]"));
                }
                self.section()?;
                let Some(d) = &self.damping else {
                    return err("damping is missing: give one of zeta, zeta_modes, viscous".into());
                };
                let given = [d.zeta.is_some(), d.zeta_modes.is_some(), d.viscous.is_some()].iter().filter(|b| **b).count();
                if given != 1 {
                    return err(format!("damping: give exactly one of zeta, zeta_modes, viscous ({given} given)"));
                }
                if let Some(z) = &d.zeta_modes {
                    if z.len() != n {
                        return err(format!("damping.zeta_modes has {} entries: structure.modes = {n} needed", z.len()));
                    }
                }
            }
            StructureSpec::Chain { masses, m, k, c } => {
                if !(1..=500).contains(masses) {
                    return err(format!("structure.masses = {masses}: allowed range is [1, 500]"));
                }
                Range::POSITIVE.check("structure.m", *m).map_err(SceneError)?;
                Range::POSITIVE.check("structure.k", *k).map_err(SceneError)?;
                Range::NON_NEGATIVE.check("structure.c", *c).map_err(SceneError)?;
                if self.damping.is_some() {
                    return err("damping: a chain's damping is structure.c (WB00: C = c E); remove \"damping\"".into());
                }
            }
        }
        if self.initial.q.len() > n {
            return err(format!("initial.q has {} entries: at most {n} (one per mode)", self.initial.q.len()));
        }
        if self.initial.qd.len() > n {
            return err(format!("initial.qd has {} entries: at most {n} (one per mode)", self.initial.qd.len()));
        }
        let mut seen = std::collections::BTreeSet::new();
        let mut unique = |what: String, name: &str| -> Result<(), SceneError> {
            check_name(&what, name)?;
            if !seen.insert(name.to_string()) {
                return err(format!("{what} = {name:?}: element names must be unique"));
            }
            Ok(())
        };
        for (i, l) in self.loads.iter().enumerate() {
            let what = format!("loads[{i}]");
            match l {
                Load::DistributedHarmonic { name, .. } => {
                    unique(format!("{what}.name"), name)?;
                    if !self.is_beam() {
                        return err(format!("{what}: a distributed load needs a beam; on a chain use point_harmonic"));
                    }
                }
                Load::PointHarmonic { name, x, mass, .. } => {
                    unique(format!("{what}.name"), name)?;
                    self.check_location(&what, &Location { x: *x, mass: *mass })?;
                }
                Load::BaseExcitation { name, .. } => unique(format!("{what}.name"), name)?,
            }
        }
        for (i, s) in self.stops.iter().enumerate() {
            unique(format!("stops[{i}].name"), &s.name)?;
            self.check_location(&format!("stops[{i}]"), &s.at())?;
            s.law.validate(&format!("stops[{i}].law")).map_err(SceneError)?;
            if let Some(method) = s.law.mode_transfer().map(|t| t.method) {
                let length = self.section()?.map_or(1.0, |s| s.length);
                let cantilever = matches!(self.structure, StructureSpec::Beam { support: SupportKind::ClampedFree, .. });
                if !cantilever || s.x != Some(length) || self.stops.len() != 1 {
                    return err(format!(
                        "stops[{i}].law.method = {method:?}: mode transfer needs the only stop of a clamped-free beam, at its tip (x = {length}); use \"fim\""
                    ));
                }
                if self.outputs.energy_balance {
                    return err(format!("outputs.energy_balance: not available with stops[{i}].law.method = {method:?}; use \"fim\""));
                }
            }
        }
        if let Some(i) = self.stops.iter().position(|s| integrated(&s.law)) {
            if self.outputs.energy_balance {
                return err(format!("outputs.energy_balance: not available with stops[{i}], whose contact phases are integrated; its own energy outputs give the balance"));
            }
        }
        for (i, s) in self.sensors.iter().enumerate() {
            unique(format!("sensors[{i}].name"), &s.name)?;
            self.check_location(&format!("sensors[{i}]"), &s.at())?;
            if s.quantities.is_empty() {
                return err(format!("sensors[{i}].quantities is empty: list displacement, velocity or bending_moment"));
            }
            if s.quantities.contains(&Quantity::BendingMoment) && !self.is_beam() {
                return err(format!("sensors[{i}].quantities: bending_moment needs a beam"));
            }
        }
        for (i, a) in self.actuators.iter().enumerate() {
            unique(format!("actuators[{i}].name"), &a.name)?;
            match a.kind {
                ActuatorKind::Force => self.check_location(&format!("actuators[{i}]"), &a.at())?,
                ActuatorKind::BaseAcceleration => {
                    if a.at() != Location::default() {
                        return err(format!("actuators[{i}]: a base_acceleration input acts everywhere: remove x / mass"));
                    }
                }
            }
        }
        let e = &self.experiment;
        Range::ANY.check("experiment.start", e.start).map_err(SceneError)?;
        if !(e.stop > e.start) || !e.stop.is_finite() {
            return err(format!("experiment.stop = {}: must be finite and > experiment.start = {}", e.stop, e.start));
        }
        Range::POSITIVE.check("experiment.step", e.step).map_err(SceneError)?;
        Range::NON_NEGATIVE.check("solver.event_tolerance", self.solver.event_tolerance).map_err(SceneError)?;
        INTEGRATION_TOLERANCE_RANGE.check("solver.integration_tolerance", self.solver.integration_tolerance).map_err(SceneError)?;
        if self.solver.max_events_per_step == 0 {
            return err("solver.max_events_per_step = 0: allowed range is [1, 2^64)".into());
        }
        if self.solver.max_probes_per_step == Some(0) {
            return err("solver.max_probes_per_step = 0: allowed range is [1, 2^64)".into());
        }
        Ok(())
    }
}
