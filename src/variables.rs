//! What every kind of simulation shows the outside world: its parameters
//! (each at a path in the scene file, with its allowed range and whether
//! it may change during a run), its inputs and its outputs, each with a
//! name, a unit and a description; the values they take; the default
//! experiment; and the GUID of a packaged scene. Nothing here knows about
//! FMI: the FMI layer turns these lists into scalar variables.

use std::fmt;

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

pub use crate::units::Unit;

/// A parameter of a scene: a number at `scene_path` in the scene file
/// (read and written by [`crate::fields`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Parameter {
    pub name: String,
    /// Where the value sits in the scene file (`stops[0].law.R`).
    pub scene_path: String,
    pub description: String,
    pub unit: Unit,
    pub range: Range,
    /// May change between communication steps; otherwise fixed after
    /// initialisation.
    pub tunable: bool,
}

/// An input, held constant over each communication step.
#[derive(Clone, Debug, PartialEq)]
pub struct Input {
    pub name: String,
    pub description: String,
    pub unit: Unit,
    pub range: Range,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputType {
    Real,
    Integer,
    Boolean,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Output {
    pub name: String,
    pub description: String,
    pub unit: Unit,
    pub kind: OutputType,
    /// Changes only at events.
    pub discrete: bool,
}

/// A scene's parameters, inputs and outputs, in the order the runs use
/// (an input's or output's index is its place here).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Variables {
    pub parameters: Vec<Parameter>,
    pub inputs: Vec<Input>,
    pub outputs: Vec<Output>,
}

impl Variables {
    /// Every name, parameters first.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        let p = self.parameters.iter().map(|p| p.name.as_str());
        let i = self.inputs.iter().map(|i| i.name.as_str());
        p.chain(i).chain(self.outputs.iter().map(|o| o.name.as_str()))
    }

    /// An error naming a name used twice.
    pub fn check_unique(&self) -> Result<(), String> {
        let mut names = std::collections::BTreeSet::new();
        for v in self.names() {
            if !names.insert(v) {
                return Err(format!("two variables would be named {v:?}: rename one with \"names\""));
            }
        }
        Ok(())
    }
}

/// The value of an output.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Value {
    Real(f64),
    Integer(i64),
    Boolean(bool),
}

/// The suggested run of a scene (the FMU's DefaultExperiment).
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

/// `{xxxxxxxx-xxxx-xxxx-xxxx-xxxxxxxxxxxx}` from the SHA-256 of the crate
/// version and a scene's canonical text.
pub fn guid_of(canonical: &str) -> String {
    let mut hasher = Sha256::new();
    hasher.update(env!("CARGO_PKG_VERSION").as_bytes());
    hasher.update([0u8]);
    hasher.update(canonical.as_bytes());
    let d = hasher.finalize();
    let hex: String = d.iter().take(16).map(|b| format!("{b:02x}")).collect();
    format!("{{{}-{}-{}-{}-{}}}", &hex[0..8], &hex[8..12], &hex[12..16], &hex[16..20], &hex[20..32])
}

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

    pub fn open(min: f64, max: f64) -> Range {
        Range { min, max, min_open: true, max_open: true }
    }

    pub fn closed(min: f64, max: f64) -> Range {
        Range { min, max, min_open: false, max_open: false }
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
        let num = |x: f64| {
            if x.is_infinite() {
                if x > 0.0 { "inf".to_string() } else { "-inf".to_string() }
            } else {
                format!("{x}")
            }
        };
        write!(f, "{lo}{}, {}{hi}", num(self.min), num(self.max))
    }
}

