//! The rotating hub beam as a kind of simulation ([`crate::kinds::rotating`]):
//! scene files with a `beam` and no `structure`, integrated throughout.

use std::any::Any;
use std::sync::{Arc, Mutex, OnceLock};

use serde_json::Value as Json;

use crate::codec::{Reader, Writer};
#[cfg(feature = "tools")]
use crate::kind::{Clearance, Flow, Surface};
use crate::kind::{EventClass, EventRecord, Kind, Reached, Run, Scene, SimError, Work};
use crate::kinds::rotating::interface::{self, RotatingOutput};
use crate::kinds::rotating::model::Shared;
use crate::kinds::rotating::{RotatingEventKind, RotatingModel, RotatingSimulation, RotatingSpec};
use crate::variables::{Experiment, Value, Variables};

pub struct RotatingKind;

impl Kind for RotatingKind {
    fn name(&self) -> &'static str {
        "rotating"
    }

    fn recognizes(&self, scene: &Json) -> bool {
        scene.get("beam").is_some()
    }

    fn load(&self, scene: &Json) -> Result<Box<dyn Scene>, String> {
        let spec: RotatingSpec = serde_json::from_value(scene.clone()).map_err(|e| format!("rotating scene: {e}"))?;
        spec.validate()?;
        let outputs = interface::outputs(&spec).into_iter().map(|(key, _)| key).collect();
        Ok(Box::new(RotatingScene { spec, outputs, model: OnceLock::new(), inherited: Mutex::new(None) }))
    }
}

#[derive(Debug)]
struct RotatingScene {
    spec: RotatingSpec,
    /// What each output (in the variables' order) reads.
    outputs: Arc<[RotatingOutput]>,
    /// The model, built once for every run of this scene.
    model: OnceLock<Result<Arc<RotatingModel>, String>>,
    /// What the model of the scene this one replaced holds for this one's
    /// ([`Scene::inherit`]), for the model when it is built.
    inherited: Mutex<Option<Arc<Shared>>>,
}

impl RotatingScene {
    fn model(&self) -> Result<Arc<RotatingModel>, String> {
        self.model
            .get_or_init(|| {
                let earlier = self.inherited.lock().unwrap_or_else(|e| e.into_inner()).take();
                RotatingModel::new_with(&self.spec, earlier.as_deref()).map(Arc::new)
            })
            .clone()
    }
}

impl Scene for RotatingScene {
    fn name(&self) -> &str {
        &self.spec.name
    }

    fn shared(&self) -> Option<Arc<dyn Any + Send + Sync>> {
        let shared = match self.model.get() {
            Some(Ok(model)) => Some(Arc::new(model.shared())),
            _ => self.inherited.lock().unwrap_or_else(|e| e.into_inner()).clone(),
        };
        shared.map(|s| s as Arc<dyn Any + Send + Sync>)
    }

    fn inherit(&self, shared: Arc<dyn Any + Send + Sync>) {
        if let (Ok(shared), None) = (shared.downcast::<Shared>(), self.model.get()) {
            *self.inherited.lock().unwrap_or_else(|e| e.into_inner()) = Some(shared);
        }
    }

    fn description(&self) -> &str {
        &self.spec.description
    }

    fn experiment(&self) -> Experiment {
        self.spec.experiment()
    }

    fn canonical(&self) -> String {
        serde_json::to_string_pretty(&self.spec).expect("a rotating scene always serialises")
    }

    fn variables(&self) -> Variables {
        Variables {
            parameters: interface::parameters(&self.spec),
            inputs: interface::inputs(&self.spec),
            outputs: interface::outputs(&self.spec).into_iter().map(|(_, o)| o).collect(),
        }
    }

    fn method(&self) -> &'static str {
        "The hub angle and the bending modes (with geometric stiffening in the first-order model) are \
         integrated by an exponential integrator (the modes' linear response exact, the remainder \
         collocated; or as solver.method says) with error control on a step grid that \
         never depends on the communication step; contact onsets, the end of each push and \
         separations are located on every step's dense output, including interior minima of the gap, so a graze \
         inside a step is not missed. Events are reported through the outputs and the \
         <code>logEvents</code> log category."
    }

    fn shortest_period(&self) -> Result<f64, SimError> {
        Ok(self.model().map_err(SimError::Scene)?.shortest_period())
    }

    fn start(&self, start_time: f64, inputs: &[f64]) -> Result<Box<dyn Run>, SimError> {
        let mut sim = RotatingSimulation::new(self.model().map_err(SimError::Scene)?, start_time)?;
        if let Some(&torque) = inputs.first() {
            sim.set_torque(torque)?;
        }
        Ok(Box::new(RotatingRun { sim, outputs: self.outputs.clone() }))
    }

    #[cfg(feature = "tools")]
    fn start_from_state(&self, start_time: f64, inputs: &[f64], state: &[f64]) -> Result<Box<dyn Run>, SimError> {
        let model = self.model().map_err(SimError::Scene)?;
        // What a state is started from for: shooting, which needs the flow.
        if let Some(why) = crate::kinds::rotating::flow::flow_unsupported(&model) {
            return Err(SimError::Unsupported(format!("a run from a given state is for shooting, which needs an exact flow: {why}")));
        }
        let n = model.n_modes();
        if state.len() != 2 * n {
            return Err(SimError::Unsupported(format!("a state of {} coordinates for a beam of {n} modes ([B; B'] has {})", state.len(), 2 * n)));
        }
        if let Some(bad) = state.iter().find(|v| !v.is_finite()) {
            return Err(SimError::Unsupported(format!("a state with the coordinate {bad}: it must be finite")));
        }
        let mut model = (*model).clone();
        model.initial_z.rows_mut(1, n).copy_from_slice(&state[..n]);
        model.initial_zd.rows_mut(1, n).copy_from_slice(&state[n..]);
        let mut sim = RotatingSimulation::new(Arc::new(model), start_time)?;
        if let Some(&torque) = inputs.first() {
            sim.set_torque(torque)?;
        }
        Ok(Box::new(RotatingRun { sim, outputs: self.outputs.clone() }))
    }

    fn decode(&self, inputs: &[f64], r: &mut Reader) -> Result<Box<dyn Run>, String> {
        let sim = RotatingSimulation::decode(self.model()?, r)?;
        let torque = inputs.first().copied().unwrap_or(0.0);
        if sim.torque() != torque {
            return Err(format!("rotating state: torque {} differs from the saved input {torque}", sim.torque()));
        }
        Ok(Box::new(RotatingRun { sim, outputs: self.outputs.clone() }))
    }
}

#[derive(Clone, Debug)]
pub struct RotatingRun {
    pub sim: RotatingSimulation,
    outputs: Arc<[RotatingOutput]>,
}

impl Run for RotatingRun {
    fn time(&self) -> f64 {
        self.sim.time()
    }

    fn earliest_time(&self) -> f64 {
        self.sim.earliest_time()
    }

    fn shortest_period(&self) -> f64 {
        self.sim.model().shortest_period()
    }

    fn advance(&mut self, until: f64, stop_before: Option<&mut dyn FnMut(f64) -> bool>) -> Result<Reached, SimError> {
        self.sim.advance(until, stop_before)
    }

    fn set_inputs(&mut self, inputs: &[f64]) -> Result<(), SimError> {
        inputs.first().map_or(Ok(()), |&u| self.sim.set_torque(u))
    }

    /// The rotating run always keeps its events: they are few.
    fn set_event_recording(&mut self, _on: bool) {}

    fn drain_events(&mut self) -> Vec<EventRecord> {
        self.sim
            .drain_events()
            .into_iter()
            .map(|e| {
                let (class, detail) = match e.kind {
                    RotatingEventKind::Onset { speed } => (EventClass::ContactOnset, format!("speed={speed:e}")),
                    RotatingEventKind::PushEnd { penetration } => (EventClass::PushEnd, format!("penetration={penetration:e}")),
                    RotatingEventKind::PushResumed => (EventClass::PushResumed, String::new()),
                    RotatingEventKind::Separation { peak_force, duration, impulse } => {
                        (EventClass::Separation, format!("peak_force={peak_force:e} duration={duration:e} impulse={impulse:e}"))
                    }
                };
                let speed = match e.kind {
                    RotatingEventKind::Onset { speed } => Some(speed),
                    _ => None,
                };
                EventRecord { time: e.time, class, at: "surface".into(), detail, speed, description: e.describe() }
            })
            .collect()
    }

    fn evaluate(&self, index: usize) -> Value {
        interface::evaluate(self.outputs[index], &self.sim)
    }

    fn encode(&self, w: &mut Writer) {
        self.sim.encode(w);
    }

    fn work(&self) -> Work {
        let stats = self.sim.stats();
        let model = self.sim.model();
        Work { events: stats.events, units: stats.accepted, unit: "integration steps", cap: model.spec.solver.step_budget(model.n_modes()) }
    }

    /// A periodically swinging hub's runs are maps of `[B; B']`
    /// ([`crate::kinds::rotating::flow`]); the others have none.
    #[cfg(feature = "tools")]
    fn flow(&mut self) -> Option<&mut dyn Flow> {
        if self.sim.flow_unsupported().is_some() {
            return None;
        }
        Some(self)
    }
}

#[cfg(feature = "tools")]
impl Flow for RotatingRun {
    fn state(&self) -> nalgebra::DVector<f64> {
        self.sim.flow_state()
    }

    fn advance_with_jacobian(&mut self, t: f64) -> Result<nalgebra::DMatrix<f64>, SimError> {
        self.sim.advance_with_jacobian(t)
    }

    fn clearances(&self) -> Vec<Clearance> {
        self.sim.flow_clearances()
    }

    fn surfaces(&self) -> Vec<Surface> {
        self.sim.flow_surfaces()
    }
}
