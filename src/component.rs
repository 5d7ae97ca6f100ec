//! What one FMU simulates, whichever kind of scene it is: a modal scene
//! (the pinned beam, the cantilevers, the chain; exact between events,
//! [`crate::sim`]) or a beam on a rotating hub (integrated throughout,
//! [`crate::rotating`]). The FMI layer talks only to [`Component`] (the
//! scene with its current parameter values) and [`Run`] (a simulation of
//! it), so adding a kind of scene touches this file and not the FMI layer.
//!
//! A scene file is a rotating-beam scene when it has a `beam` member and no
//! `structure` (see [`crate::rotating::spec`]); otherwise a modal scene.

use std::sync::Arc;

use crate::codec::{Reader, Writer};
use crate::interface::{self, InputKey, Input, Output, OutputKey, ParamKey, Parameter};
use crate::model::Model;
use crate::readout::{self, Value};
use crate::rotating::interface::{self as rotating_interface, HubTorque, RotatingOutput, RotatingParam};
use crate::rotating::{RotatingError, RotatingModel, RotatingSimulation, RotatingSpec};
use crate::scene::{guid_of, Experiment, Scene};
use crate::sim::{SimError, Simulation};

/// A scene of either kind, with its current parameter values.
#[derive(Clone, Debug, PartialEq)]
pub enum Component {
    Modal(Scene),
    Rotating(RotatingSpec),
}

/// A parameter of either kind of scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AnyParam {
    Modal(ParamKey),
    Rotating(RotatingParam),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AnyInput {
    Modal(InputKey),
    Rotating(HubTorque),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AnyOutput {
    Modal(OutputKey),
    Rotating(RotatingOutput),
}

/// The suggested run of a rotating scene without an `experiment`.
const ROTATING_DEFAULT_EXPERIMENT: Experiment = Experiment { start: 0.0, stop: 1.0, step: 1e-3 };

impl Component {
    /// Parses and validates a scene of either kind; errors name the field
    /// and what is allowed.
    pub fn from_json(text: &str) -> Result<Component, String> {
        let value: serde_json::Value = serde_json::from_str(text).map_err(|e| format!("scene: {e}"))?;
        let rotating = value.get("beam").is_some() && value.get("structure").is_none();
        if rotating {
            RotatingSpec::from_json(text).map(Component::Rotating)
        } else {
            Scene::from_json(text).map(Component::Modal).map_err(|e| e.0)
        }
    }

    pub fn name(&self) -> &str {
        match self {
            Component::Modal(s) => &s.name,
            Component::Rotating(s) => &s.name,
        }
    }

    pub fn description(&self) -> &str {
        match self {
            Component::Modal(s) => &s.description,
            Component::Rotating(s) => &s.description,
        }
    }

    pub fn experiment(&self) -> Experiment {
        match self {
            Component::Modal(s) => s.experiment.clone(),
            Component::Rotating(s) => {
                s.experiment.as_ref().map_or(ROTATING_DEFAULT_EXPERIMENT, |e| Experiment { start: e.start, stop: e.stop, step: e.step })
            }
        }
    }

    /// The scene as packaged (resources/scene.json); what the GUID hashes.
    pub fn canonical_json(&self) -> String {
        match self {
            Component::Modal(s) => s.canonical_json(),
            Component::Rotating(s) => serde_json::to_string_pretty(s).expect("a rotating scene always serialises"),
        }
    }

    pub fn guid(&self) -> String {
        match self {
            Component::Modal(s) => s.guid(),
            Component::Rotating(_) => guid_of(&self.canonical_json()),
        }
    }

    /// The scene's own checks (every value within its range).
    pub fn validate(&self) -> Result<(), String> {
        match self {
            Component::Modal(s) => s.validate().map_err(|e| e.0),
            Component::Rotating(s) => s.validate(),
        }
    }

    pub fn parameters(&self) -> Vec<Parameter<AnyParam>> {
        match self {
            Component::Modal(s) => interface::parameters(s).into_iter().map(|p| p.map_key(AnyParam::Modal)).collect(),
            Component::Rotating(s) => rotating_interface::parameters(s).into_iter().map(|p| p.map_key(AnyParam::Rotating)).collect(),
        }
    }

    pub fn inputs(&self) -> Vec<Input<AnyInput>> {
        match self {
            Component::Modal(s) => interface::inputs(s).into_iter().map(|i| i.map_key(AnyInput::Modal)).collect(),
            Component::Rotating(s) => rotating_interface::inputs(s).into_iter().map(|i| i.map_key(AnyInput::Rotating)).collect(),
        }
    }

    pub fn outputs(&self) -> Vec<Output<AnyOutput>> {
        match self {
            Component::Modal(s) => interface::outputs(s).into_iter().map(|o| o.map_key(AnyOutput::Modal)).collect(),
            Component::Rotating(s) => rotating_interface::outputs(s).into_iter().map(|o| o.map_key(AnyOutput::Rotating)).collect(),
        }
    }

    /// The value of a parameter of this scene (one from [`Self::parameters`]).
    pub fn get(&self, key: AnyParam) -> f64 {
        match (self, key) {
            (Component::Modal(s), AnyParam::Modal(k)) => k.get(s),
            (Component::Rotating(s), AnyParam::Rotating(k)) => k.get(s),
            _ => panic!("parameter {key:?} of another kind of scene"),
        }
    }

    pub fn set(&mut self, key: AnyParam, value: f64) {
        match (self, key) {
            (Component::Modal(s), AnyParam::Modal(k)) => k.set(s, value),
            (Component::Rotating(s), AnyParam::Rotating(k)) => k.set(s, value),
            (_, key) => panic!("parameter {key:?} of another kind of scene"),
        }
    }

    /// A run of the scene from its initial state at `start_time`, with the
    /// inputs (in [`Self::inputs`] order) applied.
    pub fn start(&self, start_time: f64, inputs: &[f64]) -> Result<Run, String> {
        self.start_run(start_time, inputs).map_err(|m| self.with_variable_names(m))
    }

    /// A message naming scene fields, with the variable each one is.
    fn with_variable_names(&self, message: String) -> String {
        let named: Vec<String> = self
            .parameters()
            .iter()
            .filter(|p| mentions(&message, &p.scene_path))
            .map(|p| format!("{} is the variable '{}'", p.scene_path, p.name))
            .collect();
        if named.is_empty() {
            message
        } else {
            format!("{message} ({})", named.join(", "))
        }
    }

    fn start_run(&self, start_time: f64, inputs: &[f64]) -> Result<Run, String> {
        match self {
            Component::Modal(s) => {
                let model = Model::build(s).map_err(|e| e.0)?;
                let mut sim = Simulation::new(model, start_time).map_err(|e| e.to_string())?;
                sim.set_inputs(inputs).map_err(|e| e.to_string())?;
                Ok(Run::Modal(sim))
            }
            Component::Rotating(s) => {
                let mut sim = RotatingSimulation::from_spec(s, start_time).map_err(|e| e.to_string())?;
                if let Some(&torque) = inputs.first() {
                    sim.set_torque(torque).map_err(|e| e.to_string())?;
                }
                Ok(Run::Rotating(sim))
            }
        }
    }

    /// Carries a run over to this scene's (tunable) parameter values.
    pub fn retune(&self, run: &mut Run) -> Result<(), String> {
        match (self, run) {
            (Component::Modal(s), Run::Modal(sim)) => {
                let model = Model::build(s).map_err(|e| e.0)?;
                sim.set_model(model).map_err(|e| e.to_string())
            }
            _ => Err("this scene has no tunable parameters".into()),
        }
    }

    /// A run restored from [`Run::encode`]'s bytes and validated against
    /// this scene; `inputs` are the inputs the state was saved with.
    pub fn decode(&self, inputs: &[f64], r: &mut Reader) -> Result<Run, String> {
        match self {
            Component::Modal(s) => {
                let model = Model::build(s).map_err(|e| e.0)?;
                Simulation::decode(model, inputs.to_vec(), r).map(Run::Modal)
            }
            Component::Rotating(s) => {
                let model = Arc::new(RotatingModel::new(s).map_err(|e| e.to_string())?);
                let n = r.u32()? as usize;
                let sim = RotatingSimulation::decode(model, r.take(n)?).map_err(|e| e.to_string())?;
                let torque = inputs.first().copied().unwrap_or(0.0);
                if sim.torque() != torque {
                    return Err(format!("rotating state: torque {} differs from the saved input {torque}", sim.torque()));
                }
                Ok(Run::Rotating(sim))
            }
        }
    }
}

/// Whether `text` names the field `path` (not merely a longer one that
/// starts with it).
fn mentions(text: &str, path: &str) -> bool {
    text.match_indices(path).any(|(at, _)| {
        let next = text[at + path.len()..].chars().next();
        !next.is_some_and(|c| c.is_alphanumeric() || c == '_')
    })
}

/// A simulation of either kind.
#[derive(Clone, Debug)]
pub enum Run {
    Modal(Simulation),
    Rotating(RotatingSimulation),
}

/// Why an advance stopped short.
#[derive(Clone, Debug, PartialEq)]
pub struct RunError {
    pub message: String,
    /// The state is valid at the time reached and a shorter or different
    /// step may succeed (too many events, too much work): the step is
    /// discarded, not the run.
    pub recoverable: bool,
}

impl From<SimError> for RunError {
    fn from(e: SimError) -> Self {
        let recoverable = matches!(e, SimError::TooManyEvents { .. } | SimError::TooMuchWork { .. });
        RunError { message: e.to_string(), recoverable }
    }
}

impl From<RotatingError> for RunError {
    fn from(e: RotatingError) -> Self {
        let recoverable = matches!(e, RotatingError::TooManyEvents { .. } | RotatingError::TooMuchWork { .. });
        RunError { message: e.to_string(), recoverable }
    }
}

impl Run {
    pub fn time(&self) -> f64 {
        match self {
            Run::Modal(s) => s.time(),
            Run::Rotating(s) => s.time(),
        }
    }

    /// The shortest period that events must be resolved against.
    pub fn shortest_period(&self) -> f64 {
        match self {
            Run::Modal(s) => s.model().shortest_period(),
            Run::Rotating(s) => s.model().shortest_period(),
        }
    }

    pub fn advance_to(&mut self, t: f64) -> Result<(), RunError> {
        match self {
            Run::Modal(s) => s.advance_to(t).map_err(RunError::from),
            Run::Rotating(s) => s.advance_to(t).map_err(RunError::from),
        }
    }

    /// Applies the inputs (in [`Component::inputs`] order).
    pub fn set_inputs(&mut self, inputs: &[f64]) -> Result<(), String> {
        match self {
            Run::Modal(s) => s.set_inputs(inputs).map_err(|e| e.to_string()),
            Run::Rotating(s) => inputs.first().map_or(Ok(()), |&u| s.set_torque(u).map_err(|e| e.to_string())),
        }
    }

    /// Whether events are kept for [`Self::drain_events`] (the rotating
    /// run always keeps them: they are few).
    pub fn set_event_recording(&mut self, on: bool) {
        if let Run::Modal(s) = self {
            s.set_event_recording(on);
        }
    }

    /// The events since the last call, one line each.
    pub fn drain_events(&mut self) -> Vec<String> {
        match self {
            Run::Modal(s) => {
                let events = s.drain_events();
                events.iter().map(|e| e.describe(s.model())).collect()
            }
            Run::Rotating(s) => s.drain_events().iter().map(|e| e.describe()).collect(),
        }
    }

    pub fn evaluate(&self, key: AnyOutput) -> Value {
        match (self, key) {
            (Run::Modal(s), AnyOutput::Modal(k)) => readout::evaluate(k, s),
            (Run::Rotating(s), AnyOutput::Rotating(k)) => rotating_interface::evaluate(k, s),
            _ => panic!("output {key:?} of another kind of scene"),
        }
    }

    /// Appends the run's state (see [`Component::decode`]).
    pub fn encode(&self, w: &mut Writer) {
        match self {
            Run::Modal(s) => s.encode(w),
            Run::Rotating(s) => {
                let bytes = s.encode();
                w.u32(bytes.len() as u32);
                w.0.extend_from_slice(&bytes);
            }
        }
    }
}
