//! The scene file: what a user describes (JSON, read with serde_json), its
//! validation, and the names under which its settings appear.
//!
//! Every field is checked on load; an error names the field, the value and
//! what is allowed, and no model is built from an invalid scene.

use std::collections::BTreeMap;
use std::fmt;

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

/// A complete scene: one FMU.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// The FMU's model identifier: letters, digits and '_' only.
    pub name: String,
    #[serde(default)]
    pub description: String,
    pub structure: Structure,
    #[serde(default)]
    pub damping: Damping,
    #[serde(default)]
    pub loads: Vec<Load>,
    #[serde(default)]
    pub stops: Vec<Stop>,
    #[serde(default)]
    pub actuators: Vec<Actuator>,
    #[serde(default)]
    pub initial: Initial,
    #[serde(default)]
    pub solver: Solver,
    /// The default experiment of the FMU (and of `beamstop run`).
    #[serde(default)]
    pub experiment: Experiment,
    /// Renames of the model-wide variables (`energy`, `q[{j}]`, ...).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub names: BTreeMap<String, String>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum Structure {
    /// An Euler-Bernoulli beam in the seeds' scaled units (`L = rho A = EI = 1`).
    Beam { support: SupportKind, modes: usize },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SupportKind {
    PinnedPinned,
}

/// Modal damping ratio, equal for every mode (seed 000: `zeta_j = 0.05`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Damping {
    pub zeta: f64,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub names: BTreeMap<String, String>,
}

impl Default for Damping {
    fn default() -> Self {
        Damping { zeta: 0.0, names: BTreeMap::new() }
    }
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
    /// `F sin(omega t)` per unit length over the whole span (seed 000 eq. 4).
    DistributedHarmonic {
        name: String,
        amplitude: f64,
        omega: f64,
        #[serde(default)]
        waveform: Waveform,
        #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
        names: BTreeMap<String, String>,
    },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Side {
    /// The stop limits `w(x) <= gap` (seed 000: `w(x_i) <= d`).
    #[default]
    Positive,
    /// The stop limits `w(x) >= -gap`.
    Negative,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Stop {
    pub name: String,
    /// Position along the beam.
    pub x: f64,
    /// Clearance from the undeformed beam (negative: preloaded).
    pub gap: f64,
    #[serde(default)]
    pub side: Side,
    pub law: StopLaw,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub names: BTreeMap<String, String>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum StopLaw {
    /// Rigid stop: modal restitution rule (seed 000 eq. 28), chatter threshold
    /// `eps` ending in sticking (seed 000 section 2.2).
    Restitution {
        #[serde(rename = "R")]
        restitution: f64,
        eps: f64,
    },
}

/// A point force input, held over each communication step.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Actuator {
    pub name: String,
    pub x: f64,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub names: BTreeMap<String, String>,
}

/// Initial modal coordinates (missing entries are zero).
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
}

fn default_max_events() -> u64 {
    1_000_000
}

impl Default for Solver {
    fn default() -> Self {
        Solver { event_tolerance: 0.0, max_events_per_step: default_max_events() }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Experiment {
    #[serde(default)]
    pub start: f64,
    pub stop: f64,
    /// Communication step.
    pub step: f64,
}

impl Default for Experiment {
    fn default() -> Self {
        Experiment { start: 0.0, stop: 20.0, step: 0.01 }
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

/// An allowed interval for a real value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range {
    pub min: f64,
    pub max: f64,
    pub min_open: bool,
    pub max_open: bool,
}

impl Range {
    pub const ANY: Range = Range { min: f64::NEG_INFINITY, max: f64::INFINITY, min_open: false, max_open: false };
    pub const NON_NEGATIVE: Range = Range { min: 0.0, max: f64::INFINITY, min_open: false, max_open: false };
    pub const POSITIVE: Range = Range { min: 0.0, max: f64::INFINITY, min_open: true, max_open: false };
    pub const UNIT: Range = Range { min: 0.0, max: 1.0, min_open: false, max_open: false };
    pub const OPEN_UNIT: Range = Range { min: 0.0, max: 1.0, min_open: true, max_open: true };

    pub fn open(min: f64, max: f64) -> Range {
        Range { min, max, min_open: true, max_open: true }
    }

    pub fn contains(&self, v: f64) -> bool {
        if !v.is_finite() {
            return false;
        }
        let above = if self.min_open { v > self.min } else { v >= self.min };
        let below = if self.max_open { v < self.max } else { v <= self.max };
        above && below
    }

    /// Checks `value` and explains a failure: "`what` = value: allowed ...".
    pub fn check(&self, what: &str, value: f64) -> Result<(), String> {
        if self.contains(value) {
            Ok(())
        } else {
            Err(format!("{what} = {value:?}: allowed range is {self} (finite)"))
        }
    }
}

impl fmt::Display for Range {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let lo = if self.min_open || self.min.is_infinite() { '(' } else { '[' };
        let hi = if self.max_open || self.max.is_infinite() { ')' } else { ']' };
        let num = |x: f64| if x.is_infinite() { if x > 0.0 { "inf".to_string() } else { "-inf".to_string() } } else { format!("{x}") };
        write!(f, "{lo}{}, {}{hi}", num(self.min), num(self.max))
    }
}

impl Scene {
    /// Parses and validates a scene; errors name the field and what is allowed.
    pub fn from_json(text: &str) -> Result<Scene, SceneError> {
        let scene: Scene = serde_json::from_str(text).map_err(|e| SceneError(format!("scene: {e}")))?;
        scene.validate()?;
        Ok(scene)
    }

    /// The canonical serialisation: the GUID and the packaged copy derive from it.
    pub fn canonical_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a scene always serialises")
    }

    /// `{xxxxxxxx-xxxx-xxxx-xxxx-xxxxxxxxxxxx}` from the SHA-256 of the canonical
    /// scene and the crate version.
    pub fn guid(&self) -> String {
        let mut hasher = Sha256::new();
        hasher.update(env!("CARGO_PKG_VERSION").as_bytes());
        hasher.update([0u8]);
        hasher.update(self.canonical_json().as_bytes());
        let d = hasher.finalize();
        let hex: String = d.iter().take(16).map(|b| format!("{b:02x}")).collect();
        format!("{{{}-{}-{}-{}-{}}}", &hex[0..8], &hex[8..12], &hex[12..16], &hex[16..20], &hex[20..32])
    }

    pub fn n_modes(&self) -> usize {
        match &self.structure {
            Structure::Beam { modes, .. } => *modes,
        }
    }

    /// Structural validation: everything that cannot change after packaging.
    pub fn validate(&self) -> Result<(), SceneError> {
        let err = |m: String| Err(SceneError(m));
        if self.name.is_empty()
            || !self.name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
            || self.name.starts_with(|c: char| c.is_ascii_digit())
        {
            return err(format!(
                "name = {:?}: must be a C identifier (letters, digits, '_', not starting with a digit)",
                self.name
            ));
        }
        let n = self.n_modes();
        if !(1..=500).contains(&n) {
            return err(format!("structure.modes = {n}: allowed range is [1, 500]"));
        }
        if self.initial.q.len() > n {
            return err(format!("initial.q has {} entries: at most structure.modes = {n}", self.initial.q.len()));
        }
        if self.initial.qd.len() > n {
            return err(format!("initial.qd has {} entries: at most structure.modes = {n}", self.initial.qd.len()));
        }
        let mut seen = std::collections::BTreeSet::new();
        for (i, l) in self.loads.iter().enumerate() {
            let Load::DistributedHarmonic { name, .. } = l;
            check_name(&format!("loads[{i}].name"), name)?;
            if !seen.insert(name.clone()) {
                return err(format!("loads[{i}].name = {name:?}: names must be unique"));
            }
        }
        for (i, s) in self.stops.iter().enumerate() {
            check_name(&format!("stops[{i}].name"), &s.name)?;
            if !seen.insert(s.name.clone()) {
                return err(format!("stops[{i}].name = {:?}: names must be unique", s.name));
            }
        }
        for (i, a) in self.actuators.iter().enumerate() {
            check_name(&format!("actuators[{i}].name"), &a.name)?;
            if !seen.insert(a.name.clone()) {
                return err(format!("actuators[{i}].name = {:?}: names must be unique", a.name));
            }
        }
        // Every value must lie in the range of the parameter that carries it.
        for p in crate::interface::parameters(self) {
            p.range.check(&format!("{} ({})", p.scene_path, p.name), p.key.get(self)).map_err(SceneError)?;
        }
        let e = &self.experiment;
        Range::ANY.check("experiment.start", e.start).map_err(SceneError)?;
        if !(e.stop > e.start) || !e.stop.is_finite() {
            return err(format!("experiment.stop = {}: must be finite and > experiment.start = {}", e.stop, e.start));
        }
        Range::POSITIVE.check("experiment.step", e.step).map_err(SceneError)?;
        let solver_tol = self.solver.event_tolerance;
        Range::NON_NEGATIVE.check("solver.event_tolerance", solver_tol).map_err(SceneError)?;
        if self.solver.max_events_per_step == 0 {
            return err("solver.max_events_per_step = 0: allowed range is [1, 2^64)".into());
        }
        Ok(())
    }
}

fn check_name(what: &str, name: &str) -> Result<(), SceneError> {
    if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
        return Err(SceneError(format!("{what} = {name:?}: use letters, digits and '_' only")));
    }
    Ok(())
}
