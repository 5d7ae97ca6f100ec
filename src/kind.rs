//! The simulation contract: what a kind of simulation offers the layers
//! above it (the FMI shell, the packager, the command line), in the spirit
//! of the Reference FMUs' `model.h`. A kind reads its scene files
//! ([`Kind`]), a scene declares its variables and starts runs ([`Scene`]),
//! a run advances through its events and keeps a versioned state
//! ([`Run`]). Nothing here knows about FMI.
//!
//! Kinds register themselves with `inventory::submit!` of a
//! [`Registration`] (the beam kinds in [`crate::kinds`]; a crate that
//! builds an FMU of its own kind submits it there), and a scene file goes
//! to the one kind that recognizes it.

use std::any::Any;
use std::fmt;
use std::sync::Arc;

use nalgebra::{DMatrix, DVector};
use serde_json::Value as Json;

use crate::codec::{Reader, Writer};
pub use crate::error::SimError;
use crate::variables::{Experiment, Value, Variables};

/// A kind of simulation: how its scene files are recognized and read.
pub trait Kind: Sync {
    /// A short name, for messages ("modal", "rotating", ...).
    fn name(&self) -> &'static str;
    /// Whether a scene file is of this kind.
    fn recognizes(&self, scene: &Json) -> bool;
    /// The scene, validated; the error names the field and what is allowed.
    fn load(&self, scene: &Json) -> Result<Box<dyn Scene>, String>;
}

/// A kind's entry in the registry (see the module doc).
pub struct Registration(pub &'static dyn Kind);

inventory::collect!(Registration);

/// Every registered kind.
pub fn kinds() -> impl Iterator<Item = &'static dyn Kind> {
    inventory::iter::<Registration>.into_iter().map(|r| r.0)
}

/// The kind of a scene file: the one kind that recognizes it (a file two
/// kinds recognize is refused, naming both).
pub fn kind_of(scene: &Json) -> Result<&'static dyn Kind, String> {
    let mut matching = kinds().filter(|k| k.recognizes(scene));
    match (matching.next(), matching.next()) {
        (Some(kind), None) => Ok(kind),
        (Some(a), Some(b)) => Err(format!(
            "scene: recognized by two kinds, {} and {}: a scene file has the keys of one kind only",
            a.name(),
            b.name()
        )),
        (None, _) => {
            let names: Vec<&str> = kinds().map(|k| k.name()).collect();
            let have = if names.is_empty() { "none".to_string() } else { names.join(", ") };
            if let Some((kind, key)) = crate::kinds::KINDS.iter().find(|(kind, key)| !names.contains(kind) && scene.get(key).is_some()) {
                return Err(format!(
                    "scene: a {kind} scene (it has the key '{key}'), and this binary was built without the {kind} kind (it has: {have}); package the scene with `beamstop package`, which picks a binary that has it"
                ));
            }
            Err(format!("scene: not a scene of any kind this build knows ({have})"))
        }
    }
}

/// Whether `name` can be a scene's name: an FMU's model identifier names
/// its binary and prefixes its C symbols, so it must be a C identifier
/// (every kind's scenes; checked where a scene file is read).
pub fn check_scene_name(name: &str) -> Result<(), String> {
    let identifier = !name.is_empty()
        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        && !name.starts_with(|c: char| c.is_ascii_digit());
    if identifier {
        return Ok(());
    }
    Err(format!("name = {name:?}: must be a C identifier (letters, digits, '_', not starting with a digit)"))
}

/// A validated scene of some kind: its variables, and runs of it.
pub trait Scene: Send + Sync + fmt::Debug {
    fn name(&self) -> &str;
    fn description(&self) -> &str;
    fn experiment(&self) -> Experiment;
    /// The scene file in canonical form: what an FMU carries and its GUID hashes.
    fn canonical(&self) -> String;
    /// Parameters, inputs and outputs (fixed by the scene's structure,
    /// never by a parameter's value).
    fn variables(&self) -> Variables;
    /// How runs of this kind compute, in a paragraph (for documentation).
    fn method(&self) -> &'static str;
    /// The shortest period a run of the scene at its current values must
    /// resolve (as [`Run::shortest_period`]): the clock's resolution must
    /// stay below [`MAX_TIME_RESOLUTION`] of it.
    fn shortest_period(&self) -> Result<f64, SimError>;
    /// A run from the scene's initial state at `start_time`, with the
    /// inputs (in [`Variables::inputs`] order) applied.
    fn start(&self, start_time: f64, inputs: &[f64]) -> Result<Box<dyn Run>, SimError>;
    /// A run from the state `[q; q']` (`state`, in the kind's own
    /// coordinates, as [`Flow::state`] gives them) at `start_time`: what
    /// shooting for periodic orbits starts from. Kinds without an exact
    /// flow need not offer it.
    fn start_from_state(&self, start_time: f64, inputs: &[f64], state: &[f64]) -> Result<Box<dyn Run>, SimError> {
        let _ = (start_time, inputs, state);
        Err(SimError::Unsupported("a run from a given state is for shooting, which needs an exact flow: this kind integrates".into()))
    }
    /// What this scene's runs have computed that is found by its content
    /// and so holds for any scene (the modal kind: its contact phases'
    /// decompositions, found by their matrices bit for bit), for the scene
    /// that replaces this one when a value changes ([`Self::inherit`]):
    /// a sweep's next point or an FMU's new parameters do not compute it
    /// again. `None`: nothing.
    fn shared(&self) -> Option<Arc<dyn Any + Send + Sync>> {
        None
    }
    /// Takes over [`Self::shared`] of the scene this one replaces (before
    /// its first run).
    fn inherit(&self, shared: Arc<dyn Any + Send + Sync>) {
        let _ = shared;
    }
    /// Carries a run of this kind over to this scene's (tunable) values.
    fn retune(&self, run: &mut dyn Run) -> Result<(), SimError> {
        let _ = run;
        Err(SimError::NotAnInput("a parameter during a run: this scene has no tunable parameters".into()))
    }
    /// A run restored from [`Run::encode`]'s bytes and validated against
    /// this scene; `inputs` are the inputs it was saved with. The error
    /// names the field that is wrong.
    fn decode(&self, inputs: &[f64], r: &mut Reader) -> Result<Box<dyn Run>, String>;
}

/// The coarsest time resolution (an ulp of the time), relative to the
/// shortest period a run must resolve, at which a run is started or
/// advanced.
pub const MAX_TIME_RESOLUTION: f64 = 1e-6;

/// Whether the clock resolves `period` at time `t`; if not, why.
pub fn check_time_resolution(what: &str, t: f64, period: f64) -> Result<(), String> {
    let resolution = t.abs() * f64::EPSILON;
    if resolution > MAX_TIME_RESOLUTION * period {
        let t = if t.abs() < 1e16 { format!("{t}") } else { format!("{t:e}") };
        return Err(format!(
            "{what} = {t}: the time's resolution there ({resolution:e}) exceeds {MAX_TIME_RESOLUTION} of the \
             period of the first mode or the load ({period:e}), too coarse to locate impacts; start the experiment nearer t = 0"
        ));
    }
    Ok(())
}

/// Where an advance stopped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reached {
    /// The requested time, every event on the way handled.
    Time,
    /// Just before the discrete change of an event at this time (now the
    /// run's time): [`Run::apply_events`] makes it.
    Event(f64),
}

/// One simulation run.
pub trait Run: Send + fmt::Debug + AnyRun {
    fn time(&self) -> f64;
    /// The earliest time the state refers to: the anchor its motion is
    /// propagated from, the start of a contact it reports. Never before
    /// its run's start: a decoded state is checked against that.
    fn earliest_time(&self) -> f64 {
        self.time()
    }
    /// The shortest period the run must resolve (the time's resolution
    /// must stay well below it).
    fn shortest_period(&self) -> f64;
    /// The one advance every kind implements: to `until`, handling every
    /// event on the way (one exactly at `until` included), except that
    /// with `stop_before`, before the discrete change of each event on the
    /// way (at time `te`) it asks `stop_before(te)` and stops there, just
    /// before the change, when the answer is yes. One call is one advance:
    /// its work cap covers every event it goes through. A recoverable
    /// error leaves a valid state at the time reached. A kind that does
    /// not stop at events handles them all.
    fn advance(&mut self, until: f64, stop_before: Option<&mut dyn FnMut(f64) -> bool>) -> Result<Reached, SimError>;
    /// Advances to `t`, handling every event on the way.
    fn advance_to(&mut self, t: f64) -> Result<(), SimError> {
        self.advance(t, None).map(|_| ())
    }
    /// Advances to `t` or to the next event before it, whichever comes
    /// first, stopping just before the event's discrete change.
    fn advance_to_event(&mut self, t: f64) -> Result<Reached, SimError> {
        self.advance(t, Some(&mut |_| true))
    }
    /// [`Self::advance`] with its question.
    fn advance_until(&mut self, t: f64, stop_before: &mut dyn FnMut(f64) -> bool) -> Result<Reached, SimError> {
        self.advance(t, Some(stop_before))
    }
    /// Makes the discrete change of the events at the current time (after
    /// [`Reached::Event`]); nothing otherwise.
    fn apply_events(&mut self) -> Result<(), SimError> {
        let now = self.time();
        self.advance(now, None).map(|_| ())
    }
    /// Applies the inputs (in [`Variables::inputs`] order).
    fn set_inputs(&mut self, inputs: &[f64]) -> Result<(), SimError>;
    /// Whether events are kept for [`Self::drain_events`].
    fn set_event_recording(&mut self, on: bool);
    /// The events since the last call.
    fn drain_events(&mut self) -> Vec<EventRecord>;
    /// Output `index` (in [`Variables::outputs`] order) now.
    fn evaluate(&self, index: usize) -> Value;
    /// Appends the state, versioned (see [`Scene::decode`]).
    fn encode(&self, w: &mut Writer);
    /// Work counters since the start.
    fn work(&self) -> Work;
    /// The run as a map of its state with the map's Jacobian, for shooting
    /// and continuation: exact for closed-form phases, the integrator's own
    /// map's for integrated ones (the modal kind's Hertz phases, the
    /// rotating beam under a periodic swing: [`crate::kinds::rotating::flow`]);
    /// `None` where the run or a stop's law has none.
    fn flow(&mut self) -> Option<&mut dyn Flow> {
        None
    }
}

/// What every run is besides its kind's answers: a copy (an FMU state),
/// and its concrete type (a scene retunes only its own runs). Every
/// `Run + Clone` has it.
pub trait AnyRun {
    fn boxed_clone(&self) -> Box<dyn Run>;
    fn as_any(&self) -> &dyn Any;
    fn as_any_mut(&mut self) -> &mut dyn Any;
}

impl<T: Run + Clone + 'static> AnyRun for T {
    fn boxed_clone(&self) -> Box<dyn Run> {
        Box::new(self.clone())
    }

    fn as_any(&self) -> &dyn Any {
        self
    }

    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

impl Clone for Box<dyn Run> {
    fn clone(&self) -> Self {
        self.boxed_clone()
    }
}

/// A closed-form kind's flow as a map of its state vector: the state now,
/// and an advance that also returns the derivative of the state reached
/// with respect to the state it started from (through every event, with
/// each event's saltation matrix).
pub trait Flow {
    fn state(&self) -> DVector<f64>;
    fn advance_with_jacobian(&mut self, t: f64) -> Result<DMatrix<f64>, SimError>;
    /// Each stop's clearance now, in the scene's order.
    fn clearances(&self) -> Vec<Clearance>;
    /// Each stop's surface in the state's coordinates, in the scene's order.
    fn surfaces(&self) -> Vec<Surface>;
}

/// Where a stop's surface lies in the state's coordinates `[q; q']`.
#[derive(Clone, Debug, PartialEq)]
pub struct Surface {
    /// The contact point's displacement is `shape . q`.
    pub shape: DVector<f64>,
    /// `shape . q` on the surface.
    pub target: f64,
    /// +1: the stop limits `shape . q <= target`; -1: `shape . q >= target`.
    pub side: f64,
    /// A rigid stop: no state of a run lies beyond it.
    pub rigid: bool,
}

/// How far a contact point is from its stop, and how fast that changes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Clearance {
    /// Positive apart, zero on the surface, negative inside a compliant stop.
    pub gap: f64,
    pub rate: f64,
    /// The contact point's displacement (`w . q`) and velocity.
    pub displacement: f64,
    pub velocity: f64,
}

/// What happened at an event, in the words every kind shares.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EventClass {
    /// A rigid impact (restitution).
    Impact,
    /// Sticking starts on a rigid stop.
    Stick,
    /// A stuck point leaves its stop.
    Release,
    /// A touch at zero velocity without impact.
    Graze,
    /// A compliant stop starts pushing.
    ContactOnset,
    /// A compliant stop's force reaches zero inside it.
    PushEnd,
    /// ... and turns positive again before the point leaves.
    PushResumed,
    /// A compliant contact ends.
    Separation,
}

impl EventClass {
    /// The word a results file uses.
    pub fn word(self) -> &'static str {
        match self {
            EventClass::Impact => "impact",
            EventClass::Stick => "stick",
            EventClass::Release => "release",
            EventClass::Graze => "graze",
            EventClass::ContactOnset => "contact",
            EventClass::PushEnd => "push-end",
            EventClass::PushResumed => "push-resumed",
            EventClass::Separation => "separation",
        }
    }
}

/// One event of a run.
#[derive(Clone, Debug, PartialEq)]
pub struct EventRecord {
    pub time: f64,
    pub class: EventClass,
    /// Where: the stop's name.
    pub at: String,
    /// `key=value` details (speed, restitution, reaction ...).
    pub detail: String,
    /// The approach speed of an impact or a contact onset.
    pub speed: Option<f64>,
    /// One line for a log.
    pub description: String,
}

/// A run's work since its start.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Work {
    pub events: u64,
    /// Units of work, in what `unit` says.
    pub units: u64,
    pub unit: &'static str,
    /// The most units one advance may take (its work cap).
    pub cap: u64,
}
