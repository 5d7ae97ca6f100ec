//! A scene of any kind with its current parameter values: what one FMU
//! instance simulates. It keeps the scene file (as JSON, where every
//! parameter sits at its path) and the kind's validated scene read from
//! it, so the layers above read and write parameters the same way for
//! every kind, and ask the kind for runs.

use std::any::Any;
use std::sync::Arc;

use serde_json::Value as Json;

use crate::codec::Reader;
use crate::kind::{kind_of, Kind, Run, Scene, SimError};
use crate::variables::{guid_of, Experiment, Input, Output, Parameter, Variables};

#[derive(Clone)]
pub struct Component {
    kind: &'static dyn Kind,
    /// The scene file with the current values.
    json: Json,
    /// The kind's scene read from `json`, or why the current values do not
    /// form one.
    scene: Result<Arc<dyn Scene>, String>,
    /// Fixed by the scene's structure.
    variables: Arc<Variables>,
    /// What the last valid scene's model computed for the next one
    /// ([`Scene::shared`]), while the current values form none.
    carried: Option<Arc<dyn Any + Send + Sync>>,
}

impl std::fmt::Debug for Component {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Component({} scene {})", self.kind.name(), self.json)
    }
}

impl PartialEq for Component {
    fn eq(&self, other: &Self) -> bool {
        self.kind.name() == other.kind.name() && self.json == other.json
    }
}

impl Component {
    /// Reads and validates a scene file of any registered kind; errors name
    /// the field and what is allowed.
    pub fn from_json(text: &str) -> Result<Component, String> {
        let value: Json = serde_json::from_str(text).map_err(|e| format!("scene: {e}"))?;
        Self::load(kind_of(&value)?, value)
    }

    /// A scene file of the given kind (registered or not).
    pub fn of_kind(kind: &'static dyn Kind, text: &str) -> Result<Component, String> {
        let value: Json = serde_json::from_str(text).map_err(|e| format!("scene: {e}"))?;
        Self::load(kind, value)
    }

    fn load(kind: &'static dyn Kind, value: Json) -> Result<Component, String> {
        crate::contact::check_laws_built(&value)?;
        let scene: Arc<dyn Scene> = Arc::from(kind.load(&value)?);
        crate::kind::check_scene_name(scene.name())?;
        let json = serde_json::from_str(&scene.canonical()).map_err(|e| format!("scene: canonical form: {e}"))?;
        let variables = Arc::new(scene.variables());
        Ok(Component { kind, json, scene: Ok(scene), variables, carried: None })
    }

    /// The kind's scene; an error when the current values do not form one.
    pub fn scene(&self) -> Result<&dyn Scene, String> {
        self.scene.as_deref().map_err(Clone::clone)
    }

    fn valid(&self) -> &dyn Scene {
        // Only a set may leave the values invalid, and the layers above
        // validate after every set; a run is only started from a valid scene.
        self.scene.as_deref().expect("a component's scene is validated before use")
    }

    pub fn kind(&self) -> &'static dyn Kind {
        self.kind
    }

    pub fn name(&self) -> String {
        self.json.get("name").and_then(Json::as_str).map_or_else(|| self.valid().name().to_string(), str::to_string)
    }

    pub fn description(&self) -> String {
        self.valid().description().to_string()
    }

    pub fn experiment(&self) -> Experiment {
        self.valid().experiment()
    }

    /// How the kind computes, in a paragraph.
    pub fn method(&self) -> &'static str {
        self.valid().method()
    }

    /// The scene as packaged (resources/scene.json); what the GUID hashes.
    pub fn canonical_json(&self) -> String {
        self.valid().canonical()
    }

    pub fn guid(&self) -> String {
        guid_of(&self.canonical_json())
    }

    /// Whether the current values form a scene of the kind.
    pub fn validate(&self) -> Result<(), String> {
        self.scene().map(|_| ())
    }

    pub fn variables(&self) -> &Variables {
        &self.variables
    }

    pub fn parameters(&self) -> &[Parameter] {
        &self.variables.parameters
    }

    pub fn inputs(&self) -> &[Input] {
        &self.variables.inputs
    }

    pub fn outputs(&self) -> &[Output] {
        &self.variables.outputs
    }

    /// The value of parameter `index` (of [`Self::parameters`]).
    pub fn get(&self, index: usize) -> f64 {
        crate::fields::get(&self.json, &self.variables.parameters[index].scene_path).unwrap_or(f64::NAN)
    }

    /// Sets parameter `index`; [`Self::validate`] then says whether the
    /// values still form a scene.
    pub fn set(&mut self, index: usize, value: f64) {
        self.set_many([(index, value)]);
    }

    /// Sets several parameters (`(index, value)`) and reads the scene once
    /// (not at all when no value changes: the scene, and what its runs
    /// share, such as a built model, stay).
    pub fn set_many(&mut self, values: impl IntoIterator<Item = (usize, f64)>) {
        let mut written = Ok(false);
        for (index, value) in values {
            let path = &self.variables.parameters[index].scene_path;
            if crate::fields::get(&self.json, path).is_ok_and(|v| v.to_bits() == value.to_bits()) {
                continue;
            }
            written = written.and_then(|_| crate::fields::set(&mut self.json, path, value).map(|()| true));
        }
        if written == Ok(false) && self.scene.is_ok() {
            return;
        }
        let shared = self.scene.as_ref().ok().and_then(|scene| scene.shared()).or_else(|| self.carried.take());
        self.scene = written.and_then(|_| self.kind.load(&self.json).map(Arc::from));
        match (&self.scene, shared) {
            (Ok(scene), Some(shared)) => scene.inherit(shared),
            (Err(_), shared) => self.carried = shared,
            (Ok(_), None) => {}
        }
    }

    /// A run from the scene's initial state at `start_time` (a message
    /// naming the scene fields at fault, and their variables).
    pub fn start(&self, start_time: f64, inputs: &[f64]) -> Result<Box<dyn Run>, String> {
        let scene = self.scene()?;
        self.check_start_time(start_time)?;
        scene.start(start_time, inputs).map_err(|e| self.with_variable_names(e.to_string()))
    }

    /// Whether the clock resolves the scene's shortest period at
    /// `start_time` ([`crate::kind::check_time_resolution`]); values that
    /// do not form a scene are left to the run's own checks.
    pub fn check_start_time(&self, start_time: f64) -> Result<(), String> {
        // Where the clock's resolution is 0 (t = 0) it resolves every
        // (positive) period: no model is built to ask for it. Building it
        // here would cost a whole model build at many modes (0.6e9
        // instructions at 128), paid twice when the importer sets the
        // parameters after fmi2SetupExperiment (fmpy does), since a changed
        // value reloads the scene and its run builds the model again.
        if start_time.abs() * f64::EPSILON == 0.0 {
            return Ok(());
        }
        let Ok(scene) = self.scene() else { return Ok(()) };
        match scene.shortest_period() {
            Ok(period) => crate::kind::check_time_resolution("startTime", start_time, period),
            Err(_) => Ok(()),
        }
    }

    /// A run from the state `[q; q']` at `start_time` (see
    /// [`Scene::start_from_state`]).
    pub fn start_from_state(&self, start_time: f64, inputs: &[f64], state: &[f64]) -> Result<Box<dyn Run>, String> {
        let scene = self.scene()?;
        scene.start_from_state(start_time, inputs, state).map_err(|e| self.with_variable_names(e.to_string()))
    }

    /// Carries a run over to the current (tunable) parameter values.
    pub fn retune(&self, run: &mut dyn Run) -> Result<(), SimError> {
        self.valid().retune(run)
    }

    /// A run restored from [`Run::encode`]'s bytes, validated against the
    /// current values; `inputs` are the inputs the state was saved with.
    pub fn decode(&self, inputs: &[f64], r: &mut Reader) -> Result<Box<dyn Run>, String> {
        self.scene()?.decode(inputs, r)
    }

    /// A message naming scene fields, with the variable each one is.
    fn with_variable_names(&self, message: String) -> String {
        let named: Vec<String> = self
            .variables
            .parameters
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
}

/// Whether `text` names the field `path` (not merely a longer one that
/// starts with it).
fn mentions(text: &str, path: &str) -> bool {
    text.match_indices(path).any(|(at, _)| {
        let next = text[at + path.len()..].chars().next();
        !next.is_some_and(|c| c.is_alphanumeric() || c == '_')
    })
}
