//! The modal structures (beams, chains) with stops as a kind of
//! simulation ([`crate::kinds::modal::sim`]): scene files with a `structure`, exact
//! between events.

use std::any::Any;
use std::sync::{Arc, Mutex, OnceLock};

use nalgebra::{DMatrix, DVector};
use serde_json::Value as Json;

use crate::codec::{Reader, Writer};
use crate::kinds::modal::interface::{self, OutputKey};
use crate::kind::{Clearance, EventClass, EventRecord, Flow, Kind, Reached, Run, Scene, SimError, Surface, Work};
use crate::kinds::modal::model::{Model, Shared};
use crate::kinds::modal::readout;
use crate::kinds::modal::sim::{EventKind, Simulation};
use crate::variables::{Experiment, Value, Variables};

pub struct ModalKind;

impl Kind for ModalKind {
    fn name(&self) -> &'static str {
        "modal"
    }

    fn recognizes(&self, scene: &Json) -> bool {
        scene.get("structure").is_some()
    }

    fn load(&self, scene: &Json) -> Result<Box<dyn Scene>, String> {
        let scene: crate::kinds::modal::scene::Scene = serde_json::from_value(scene.clone()).map_err(|e| format!("scene: {e}"))?;
        scene.validate().map_err(|e| e.0)?;
        let outputs = interface::outputs(&scene).into_iter().map(|(key, _)| key).collect();
        Ok(Box::new(ModalScene { scene, outputs, model: OnceLock::new(), inherited: Mutex::new(None) }))
    }
}

#[derive(Debug)]
struct ModalScene {
    scene: crate::kinds::modal::scene::Scene,
    /// What each output (in the variables' order) reads.
    outputs: Arc<[OutputKey]>,
    /// The model, built once for every run of this scene (a master that
    /// restores states over and over pays for it once).
    model: OnceLock<Result<Model, String>>,
    /// What the model of the scene this one replaced holds for this one's
    /// ([`Scene::inherit`]), for the model when it is built.
    inherited: Mutex<Option<Shared>>,
}

impl ModalScene {
    fn model(&self) -> Result<Model, SimError> {
        self.model
            .get_or_init(|| {
                let earlier = self.inherited.lock().unwrap_or_else(|e| e.into_inner()).take().unwrap_or_default();
                Model::build_with(&self.scene, earlier).map_err(|e| e.0)
            })
            .clone()
            .map_err(SimError::Scene)
    }
}

impl Scene for ModalScene {
    fn name(&self) -> &str {
        &self.scene.name
    }

    fn shared(&self) -> Option<Arc<dyn Any + Send + Sync>> {
        let shared = match self.model.get() {
            Some(Ok(model)) => Some(model.shared()),
            _ => self.inherited.lock().unwrap_or_else(|e| e.into_inner()).clone(),
        };
        shared.map(|s| Arc::new(s) as Arc<dyn Any + Send + Sync>)
    }

    fn inherit(&self, shared: Arc<dyn Any + Send + Sync>) {
        if let (Some(shared), None) = (shared.downcast_ref::<Shared>(), self.model.get()) {
            *self.inherited.lock().unwrap_or_else(|e| e.into_inner()) = Some(shared.clone());
        }
    }

    fn description(&self) -> &str {
        &self.scene.description
    }

    fn experiment(&self) -> Experiment {
        self.scene.experiment.clone()
    }

    fn canonical(&self) -> String {
        self.scene.canonical_json()
    }

    fn variables(&self) -> Variables {
        Variables {
            parameters: interface::parameters(&self.scene),
            inputs: interface::inputs(&self.scene),
            outputs: interface::outputs(&self.scene).into_iter().map(|(_, o)| o).collect(),
        }
    }

    fn method(&self) -> &'static str {
        "Between events the modal equations are propagated in closed form (contact phases of a \
         nonlinear stop law by force collocation, every mode exact under the force); impacts, chatter, sticking and release are located so that \
         none can be missed, and the trajectory does not depend on the communication step. Events \
         inside a step are reported through the outputs (counters, exact time of the latest impact) \
         and the <code>logEvents</code> log category."
    }

    fn shortest_period(&self) -> Result<f64, SimError> {
        Ok(self.model()?.shortest_period())
    }

    fn start(&self, start_time: f64, inputs: &[f64]) -> Result<Box<dyn Run>, SimError> {
        let mut sim = Simulation::new(self.model()?, start_time)?;
        sim.set_inputs(inputs)?;
        Ok(Box::new(ModalRun { sim, outputs: self.outputs.clone() }))
    }

    fn start_from_state(&self, start_time: f64, inputs: &[f64], state: &[f64]) -> Result<Box<dyn Run>, SimError> {
        let mut model = self.model()?;
        let n = model.n_modes();
        // What a state is started from for: shooting, which needs the flow.
        if let Some(why) = model.flow_unsupported() {
            return Err(SimError::Unsupported(format!("a run from a given state is for shooting, which needs an exact flow: {why}")));
        }
        if state.len() != 2 * n {
            return Err(SimError::Unsupported(format!("a state of {} coordinates for a structure of {n} modes ([q; q'] has {})", state.len(), 2 * n)));
        }
        if let Some(bad) = state.iter().find(|v| !v.is_finite()) {
            return Err(SimError::Unsupported(format!("a state with the coordinate {bad}: it must be finite")));
        }
        model.initial.q.copy_from_slice(&state[..n]);
        model.initial.qd.copy_from_slice(&state[n..]);
        let mut sim = Simulation::new(model, start_time)?;
        sim.set_inputs(inputs)?;
        Ok(Box::new(ModalRun { sim, outputs: self.outputs.clone() }))
    }

    fn retune(&self, run: &mut dyn Run) -> Result<(), SimError> {
        let run = run.as_any_mut().downcast_mut::<ModalRun>().expect("a run of this kind");
        run.sim.set_model(self.model()?)
    }

    fn decode(&self, inputs: &[f64], r: &mut Reader) -> Result<Box<dyn Run>, String> {
        let model = self.model().map_err(|e| e.to_string())?;
        let sim = Simulation::decode(model, inputs.to_vec(), r)?;
        Ok(Box::new(ModalRun { sim, outputs: self.outputs.clone() }))
    }
}

#[derive(Clone, Debug)]
pub struct ModalRun {
    pub sim: Simulation,
    outputs: Arc<[OutputKey]>,
}

impl Run for ModalRun {
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
        self.sim.set_inputs(inputs)
    }

    fn set_event_recording(&mut self, on: bool) {
        self.sim.set_event_recording(on);
    }

    fn drain_events(&mut self) -> Vec<EventRecord> {
        let events = self.sim.drain_events();
        let model = self.sim.model();
        events
            .iter()
            .map(|e| {
                let (class, detail) = match e.kind {
                    EventKind::Impact { speed, restitution, chatter, .. } => {
                        (EventClass::Impact, format!("speed={speed:e} R={restitution}{}", if chatter { " chatter-end" } else { "" }))
                    }
                    EventKind::Stick { reaction, .. } => (EventClass::Stick, format!("reaction={reaction:e}")),
                    EventKind::Release { .. } => (EventClass::Release, String::new()),
                    EventKind::Graze { .. } => (EventClass::Graze, String::new()),
                    EventKind::Contact { speed, .. } => (EventClass::ContactOnset, format!("speed={speed:e}")),
                    EventKind::Separation { penetration, .. } => (EventClass::Separation, format!("penetration={penetration:e}")),
                };
                let speed = match e.kind {
                    EventKind::Impact { speed, .. } | EventKind::Contact { speed, .. } => Some(speed),
                    _ => None,
                };
                EventRecord { time: e.time, class, at: model.stops[e.stop()].name.clone(), detail, speed, description: e.describe(model) }
            })
            .collect()
    }

    fn evaluate(&self, index: usize) -> Value {
        readout::evaluate(self.outputs[index], &self.sim)
    }

    fn encode(&self, w: &mut Writer) {
        self.sim.encode(w);
    }

    fn work(&self) -> Work {
        let stats = self.sim.stats();
        Work { events: stats.events, units: stats.work, unit: "event-search points", cap: self.sim.model().max_probes_per_step }
    }

    fn flow(&mut self) -> Option<&mut dyn Flow> {
        if self.sim.flow_unsupported().is_some() {
            return None;
        }
        Some(self)
    }
}

impl Flow for ModalRun {
    fn state(&self) -> DVector<f64> {
        self.sim.flow_state()
    }

    fn advance_with_jacobian(&mut self, t: f64) -> Result<DMatrix<f64>, SimError> {
        self.sim.advance_with_jacobian(t)
    }

    fn clearances(&self) -> Vec<Clearance> {
        self.sim.clearances()
    }

    fn surfaces(&self) -> Vec<Surface> {
        self.sim
            .model()
            .stops
            .iter()
            .map(|s| Surface { shape: s.geometry.w.clone(), target: s.geometry.target(), side: s.geometry.side, rigid: s.law.rigid() })
            .collect()
    }
}
