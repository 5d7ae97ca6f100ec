//! One FMU instance: the FMI semantics of every call, in safe Rust, for
//! both standards.
//!
//! A shell's C entry points check their state-machine table once, then
//! translate pointers and call these methods with the function they serve
//! (its name starts every message). Bad arguments get an Error status with
//! a message naming the variable, the value and what is allowed, and leave
//! the instance as it was.

use std::path::Path;

use crate::component::Component;
use crate::kind::{check_time_resolution, EventRecord, Reached, Run};
use crate::variables::Value;

use super::logging::Logger;
use super::states::Ledger;
use super::state::{Call, ModelState, Status};
use super::variables::{Binding, VarType, Variable, VariableTable};

/// Everything an FMU state snapshot holds (GetFMUstate): a deep copy.
#[derive(Clone, Debug)]
pub struct Snapshot {
    /// The GUID of the FMU whose instance saved it.
    pub guid: String,
    pub machine: ModelState,
    /// Current values of every parameter, in table order.
    pub parameters: Vec<f64>,
    pub inputs: Vec<f64>,
    pub start_time: f64,
    pub stop_time: Option<f64>,
    pub sim: Option<Box<dyn Run>>,
    pub last_successful_time: f64,
    pub terminated: bool,
    /// The run stands just before an event's discrete change, which the
    /// importer makes in event mode (FMI 3.0's UpdateDiscreteStates).
    pub pending: bool,
    /// The choices of the instance that saved it.
    pub made_with: Modes,
}

/// The importer's choices an instance was made with (FMI 3.0's
/// fmi3InstantiateCoSimulation; an FMI 2.0 instance has neither).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Modes {
    pub event_mode_used: bool,
    pub early_return_allowed: bool,
}

pub struct Instance {
    pub logger: Logger,
    /// The FMU states handed out (freed with the instance).
    pub states: Ledger,
    /// The importer's choices (set by the FMI 3.0 shell at instantiation).
    pub modes: Modes,
    guid: String,
    /// The scene as packaged: the start values.
    packaged: Component,
    /// The scene with the current parameter values.
    scene: Component,
    table: VariableTable,
    inputs: Vec<f64>,
    machine: ModelState,
    start_time: f64,
    stop_time: Option<f64>,
    sim: Option<Box<dyn Run>>,
    /// In initialization mode, a simulation built from the current values
    /// to answer output reads, or why it cannot be built (kept so
    /// that a failure is not recomputed at every read); cleared by any set.
    provisional: Option<Result<Box<dyn Run>, String>>,
    last_successful_time: f64,
    terminated: bool,
    /// See [`Snapshot::pending`].
    pending: bool,
}

/// How a step ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StepEnd {
    /// At the requested time, every event on the way handled.
    Done,
    /// Just before the discrete change of an event at this time.
    Event(f64),
}

/// A failed call: the status to return (the message is already logged).
pub type CallResult<T = ()> = Result<T, Status>;

impl Instance {
    /// Instantiate after the pointer checks (`name`: the function): reads
    /// the scene from the resources and checks the GUID (FMI 3.0: the
    /// instantiation token).
    pub fn new(name: &str, logger: Logger, guid: &str, resources: &Path) -> Result<Instance, (Logger, String)> {
        let file = resources.join("scene.json");
        let text = match std::fs::read_to_string(&file) {
            Ok(t) => t,
            Err(e) => return Err((logger, format!("{name}: cannot read the scene {}: {e}", file.display()))),
        };
        let scene = match Component::from_json(&text) {
            Ok(s) => s,
            Err(e) => return Err((logger, format!("{name}: invalid scene {}: {e}", file.display()))),
        };
        let expected = scene.guid();
        if guid != expected {
            return Err((
                logger,
                format!(
                    "{name}: GUID {guid} does not match this FMU ({expected}); the modelDescription.xml and the binary come from different builds"
                ),
            ));
        }
        let table = VariableTable::new(&scene);
        let inputs = vec![0.0; table.interface.inputs.len()];
        Ok(Instance {
            logger,
            states: Ledger::default(),
            modes: Modes::default(),
            guid: expected,
            packaged: scene.clone(),
            scene,
            table,
            inputs,
            machine: ModelState::Instantiated,
            start_time: 0.0,
            stop_time: None,
            sim: None,
            provisional: None,
            last_successful_time: 0.0,
            terminated: false,
            pending: false,
        })
    }

    pub fn guid(&self) -> &str {
        &self.guid
    }

    pub fn table(&self) -> &VariableTable {
        &self.table
    }

    pub fn machine(&self) -> ModelState {
        self.machine
    }

    /// A transition the shell's standard defines (the core makes the
    /// transitions both standards share).
    pub fn set_machine(&mut self, state: ModelState) {
        self.machine = state;
    }

    /// Checks the shell's state machine table; logs an illegal call.
    pub fn enter<F: Call>(&self, f: F) -> CallResult {
        f.check(self.machine).map_err(|m| self.fail(&m))
    }

    /// After a panic inside a call: the instance can no longer be trusted.
    pub fn poison(&mut self, message: &str) {
        self.machine = ModelState::Error;
        self.logger.status(Status::Error, message);
    }

    /// Logs an error and returns the status to hand back.
    pub fn fail(&self, message: &str) -> Status {
        self.logger.status(Status::Error, message);
        Status::Error
    }

    fn trace(&self, message: &str) {
        self.logger.category("logAll", message);
    }

    pub fn set_debug_logging<F: Call>(&mut self, f: F, on: bool, categories: &[String]) -> CallResult {
        self.logger.set_categories(on, categories).map_err(|m| self.fail(&format!("{}: {m}", f.name())))?;
        self.sync_event_recording();
        Ok(())
    }

    /// Events are only recorded when someone will read them.
    fn sync_event_recording(&mut self) {
        let on = self.logger.wants("logEvents");
        if let Some(sim) = self.sim.as_mut() {
            sim.set_event_recording(on);
        }
    }

    pub fn setup_experiment<F: Call>(&mut self, f: F, start: f64, stop: Option<f64>) -> CallResult {
        let name = f.name();
        if !start.is_finite() {
            return Err(self.fail(&format!("{name}: startTime = {start}: must be finite")));
        }
        if let Some(stop) = stop {
            if !(stop >= start) || !stop.is_finite() {
                return Err(self.fail(&format!("{name}: stopTime = {stop}: must be finite and >= startTime = {start}")));
            }
        }
        // A start the clock cannot resolve is refused now, before any
        // output is computed (the run's start checks it again with the
        // values initialisation ends with).
        if let Err(m) = self.scene.check_start_time(start) {
            return Err(self.fail(&format!("{name}: {m}")));
        }
        self.start_time = start;
        self.stop_time = stop;
        self.last_successful_time = start;
        Ok(())
    }

    pub fn enter_initialization_mode<F: Call>(&mut self, f: F) -> CallResult {
        self.machine = ModelState::InitializationMode;
        self.trace(f.name());
        Ok(())
    }

    fn build_simulation(&self) -> Result<Box<dyn Run>, String> {
        let mut sim = self.scene.start(self.start_time, &self.inputs)?;
        sim.set_event_recording(self.logger.wants("logEvents"));
        Ok(sim)
    }

    /// Builds the run; the instance is then in step mode (a shell that
    /// starts in event mode moves it there).
    pub fn exit_initialization_mode<F: Call>(&mut self, f: F) -> CallResult {
        let built = match self.provisional.take() {
            Some(result) => result,
            None => self.build_simulation(),
        };
        let mut sim = match built {
            Ok(sim) => sim,
            Err(m) => {
                let status = self.fail(&format!("{}: {m}", f.name()));
                self.provisional = Some(Err(m));
                return Err(status);
            }
        };
        // Events settled at the start time (an initial impact, sticking).
        let events = sim.drain_events();
        self.sim = Some(sim);
        self.log_events(&events);
        self.machine = ModelState::StepMode;
        self.pending = false;
        self.last_successful_time = self.start_time;
        self.trace(&format!("{}: simulation ready", f.name()));
        Ok(())
    }

    pub fn terminate<F: Call>(&mut self, f: F) -> CallResult {
        self.machine = ModelState::Terminated;
        // The run ends: an event's change left pending is never made (and
        // a Terminated state with one would not restore).
        self.pending = false;
        self.trace(f.name());
        Ok(())
    }

    pub fn reset<F: Call>(&mut self, f: F) -> CallResult {
        self.scene = self.packaged.clone();
        self.inputs.iter_mut().for_each(|u| *u = 0.0);
        self.machine = ModelState::Instantiated;
        self.start_time = 0.0;
        self.stop_time = None;
        self.sim = None;
        self.provisional = None;
        self.last_successful_time = 0.0;
        self.terminated = false;
        self.pending = false;
        self.trace(&format!("{}: back to Instantiated with the start values", f.name()));
        Ok(())
    }

    fn variable<F: Call>(&self, f: F, vr: u32, ty: VarType) -> CallResult<&Variable> {
        let Some(v) = self.table.get(vr) else {
            return Err(self.fail(&format!(
                "{}: value reference {vr} does not exist (this FMU has 0..={})",
                f.name(),
                self.table.variables.len().saturating_sub(1)
            )));
        };
        if v.ty != ty {
            return Err(self.fail(&format!(
                "{}: value reference {vr} ('{}') is {} {}, not {}",
                f.name(),
                v.name,
                if f.type_name(v.ty).starts_with('I') { "an" } else { "a" },
                f.type_name(v.ty),
                f.type_name(ty)
            )));
        }
        Ok(v)
    }

    /// The simulation that answers output reads in this state.
    fn reading_simulation<F: Call>(&mut self, f: F) -> CallResult<&dyn Run> {
        if self.machine == ModelState::InitializationMode {
            if self.provisional.is_none() {
                self.provisional = Some(self.build_simulation());
            }
            return match self.provisional.as_ref() {
                Some(Ok(sim)) => Ok(sim.as_ref()),
                Some(Err(m)) => Err(self.fail(&format!("{}: outputs cannot be computed: {m}", f.name()))),
                None => unreachable!("set above"),
            };
        }
        match self.sim.as_deref() {
            Some(sim) => Ok(sim),
            None => Err(self.fail(&format!("{}: no simulation (initialisation failed)", f.name()))),
        }
    }

    fn read<F: Call>(&mut self, f: F, vr: u32, ty: VarType) -> CallResult<Value> {
        let binding = self.variable(f, vr, ty)?.binding;
        Ok(match binding {
            Binding::Parameter(i) => Value::Real(self.scene.get(i)),
            Binding::Input(i) => Value::Real(self.inputs[i]),
            Binding::Output(i) => self.reading_simulation(f)?.evaluate(i),
        })
    }

    pub fn get_real<F: Call>(&mut self, f: F, vrs: &[u32], values: &mut [f64]) -> CallResult {
        for (vr, out) in vrs.iter().zip(values.iter_mut()) {
            if let Value::Real(x) = self.read(f, *vr, VarType::Real)? {
                *out = x;
            }
        }
        Ok(())
    }

    pub fn get_integer<F: Call>(&mut self, f: F, vrs: &[u32], values: &mut [i32]) -> CallResult {
        for (vr, out) in vrs.iter().zip(values.iter_mut()) {
            if let Value::Integer(x) = self.read(f, *vr, VarType::Integer)? {
                *out = x.clamp(i32::MIN as i64, i32::MAX as i64) as i32;
            }
        }
        Ok(())
    }

    pub fn get_boolean<F: Call>(&mut self, f: F, vrs: &[u32], values: &mut [bool]) -> CallResult {
        for (vr, out) in vrs.iter().zip(values.iter_mut()) {
            if let Value::Boolean(x) = self.read(f, *vr, VarType::Boolean)? {
                *out = x;
            }
        }
        Ok(())
    }

    /// A getter or setter of a type this FMU has no variable of (that it
    /// may call): any value reference is an error.
    pub fn no_such_variables<F: Call>(&self, f: F, vrs: &[u32], what: &str) -> CallResult {
        match vrs.first() {
            None => Ok(()),
            Some(vr) => {
                let detail = match self.table.get(*vr) {
                    Some(v) => format!("value reference {vr} is '{}', a {} {:?}", v.name, f.type_name(v.ty), v.causality),
                    None => format!("value reference {vr} does not exist"),
                };
                Err(self.fail(&format!("{}: this FMU has no {what}; {detail}", f.name())))
            }
        }
    }

    pub fn set_real<F: Call>(&mut self, f: F, vrs: &[u32], values: &[f64]) -> CallResult {
        let name = f.name();
        // Check every value first: a rejected call changes nothing.
        let mut scene = self.scene.clone();
        let mut inputs = self.inputs.clone();
        let mut parameters = Vec::new();
        for (vr, value) in vrs.iter().zip(values) {
            let v = self.variable(f, *vr, VarType::Real)?;
            match v.binding {
                Binding::Parameter(i) => {
                    let p = &self.table.interface.parameters[i];
                    if self.machine.initialized() && !p.tunable {
                        let prefix = &name[..4];
                        return Err(self.fail(&format!(
                            "{name}: '{}' = {value:?}: '{}' is a fixed parameter, settable only before {prefix}ExitInitializationMode (or after {prefix}Reset); it stays {}",
                            p.name,
                            p.name,
                            self.scene.get(i)
                        )));
                    }
                    if let Err(m) = p.range.check(&format!("'{}'", p.name), *value) {
                        return Err(self.fail(&format!("{name}: {m}")));
                    }
                    parameters.push((i, *value));
                }
                Binding::Input(i) => {
                    let input = &self.table.interface.inputs[i];
                    if let Err(m) = input.range.check(&format!("input '{}'", input.name), *value) {
                        return Err(self.fail(&format!("{name}: {m}")));
                    }
                    inputs[i] = *value;
                }
                Binding::Output(_) => {
                    return Err(self.fail(&format!("{name}: '{}' (value reference {vr}) is an output and cannot be set", v.name)));
                }
            }
        }
        let parameters_changed = !parameters.is_empty();
        if parameters_changed {
            scene.set_many(parameters);
        }
        let inputs_changed = inputs != self.inputs;
        match self.sim.as_mut() {
            // Before initialisation: the scene's own checks (Model::build
            // makes them too, once a simulation exists).
            None if parameters_changed => {
                if let Err(e) = scene.validate() {
                    return Err(self.fail(&format!("{name}: {e}")));
                }
            }
            Some(sim) if parameters_changed || inputs_changed => {
                if let Err(e) = scene.validate() {
                    return Err(self.fail(&format!("{name}: {e}")));
                }
                // Applied to a copy first: a refused change leaves the run as it was.
                let mut updated = sim.clone();
                let model_applied = if parameters_changed { scene.retune(updated.as_mut()) } else { Ok(()) };
                if let Err(e) = model_applied.and_then(|()| updated.set_inputs(&inputs)) {
                    return Err(self.fail(&format!("{name}: {e}")));
                }
                let events = updated.drain_events();
                *sim = updated;
                self.log_events(&events);
            }
            _ => {}
        }
        if parameters_changed || inputs_changed {
            self.provisional = None;
        }
        self.scene = scene;
        self.inputs = inputs;
        Ok(())
    }

    /// A DoStep: advances from `t` (the run's time) by `h`, handling every
    /// event on the way, or (with `until_event`) stops just before the
    /// discrete change of the first event that changes the state, where
    /// [`Self::apply_pending`] makes it. A recoverable failure is a
    /// Discard at the time reached (the step-discarded state), any other
    /// an Error (the error state).
    pub fn do_step<F: Call>(&mut self, f: F, t: f64, h: f64, until_event: bool) -> CallResult<StepEnd> {
        let target = self.check_step(f, t, h)?;
        if until_event {
            self.advance(f, target, Some(&mut |_| true))
        } else {
            self.advance(f, target, None)
        }
    }

    /// The end of a step from `t` by `h` (the checks of a DoStep).
    pub fn check_step<F: Call>(&mut self, f: F, t: f64, h: f64) -> CallResult<f64> {
        let name = f.name();
        let Some(sim) = self.sim.as_mut() else {
            return Err(self.fail(&format!("{name}: no simulation (initialisation did not complete)")));
        };
        let now = sim.time();
        let tol = 1e-9 * now.abs().max(1.0);
        if !t.is_finite() || (t - now).abs() > tol {
            let m = format!("{name}: currentCommunicationPoint = {t} does not match the FMU's time {now}");
            return Err(self.fail(&m));
        }
        if !(h > 0.0) || !h.is_finite() {
            return Err(self.fail(&format!("{name}: communicationStepSize = {h}: must be finite and > 0")));
        }
        let target = (t + h).max(now);
        if target <= now {
            return Err(self.fail(&format!(
                "{name}: communicationStepSize = {h:e} does not move the time {now} (its resolution there is {:e}); take a longer step",
                now.abs().max(f64::MIN_POSITIVE) * f64::EPSILON
            )));
        }
        if let Err(m) = check_time_resolution("t + h", target, sim.shortest_period()) {
            return Err(self.fail(&format!("{name}: {m}")));
        }
        if let Some(stop) = self.stop_time {
            if target > stop + 1e-9 * stop.abs().max(1.0) {
                return Err(self.fail(&format!("{name}: t + h = {target} is past the stopTime = {stop} set at initialisation")));
            }
        }
        Ok(target)
    }

    /// The advance of a step to `target` (checked by [`Self::check_step`]):
    /// see [`Self::do_step`]; it stops before an event where `stop_before`
    /// says so (one advance, one work cap, however many events it makes).
    pub fn advance<F: Call>(&mut self, f: F, target: f64, stop_before: Option<&mut dyn FnMut(f64) -> bool>) -> CallResult<StepEnd> {
        let name = f.name();
        let Some(sim) = self.sim.as_mut() else {
            return Err(self.fail(&format!("{name}: no simulation (initialisation did not complete)")));
        };
        let work_before = sim.work().units;
        // An event left pending (the importer stepped on without event
        // mode) is made first, as a step without event mode would have.
        let mut result = if std::mem::take(&mut self.pending) { sim.apply_events() } else { Ok(()) };
        let mut end = StepEnd::Done;
        if result.is_ok() {
            result = match stop_before {
                Some(stop_before) => sim.advance_until(target, stop_before).map(|reached| {
                    if let Reached::Event(te) = reached {
                        end = StepEnd::Event(te);
                    }
                }),
                None => sim.advance_to(target),
            };
        }
        let events = sim.drain_events();
        let reached = sim.time();
        if self.logger.wants("logAll") {
            // What the step cost, in the units its work cap counts (a
            // fuzzer checks the cap by this, not by the clock).
            let work = sim.work();
            self.trace(&format!("{name}: work {} of {} {} (the step's cap)", work.units - work_before, work.cap, work.unit));
        }
        self.log_events(&events);
        match result {
            Ok(()) => {
                self.last_successful_time = match end {
                    StepEnd::Done => target,
                    StepEnd::Event(te) => te,
                };
                self.pending = matches!(end, StepEnd::Event(_));
                Ok(end)
            }
            Err(e) if e.recoverable() => {
                self.last_successful_time = reached;
                self.machine = ModelState::StepDiscarded;
                self.logger.status(Status::Discard, &format!("{name}: {e}; the step was computed up to t = {reached:?}"));
                Err(Status::Discard)
            }
            Err(e) => {
                self.machine = ModelState::Error;
                Err(self.fail(&format!("{name}: {e}")))
            }
        }
    }

    /// Whether an event's discrete change is pending (see [`Snapshot::pending`]).
    pub fn pending(&self) -> bool {
        self.pending
    }

    /// Makes the discrete change of the pending event (nothing if none is
    /// pending); whether one was made.
    pub fn apply_pending<F: Call>(&mut self, f: F) -> CallResult<bool> {
        if !self.pending {
            return Ok(false);
        }
        let Some(sim) = self.sim.as_mut() else {
            return Err(self.fail(&format!("{}: no simulation", f.name())));
        };
        let result = sim.apply_events();
        let events = sim.drain_events();
        self.log_events(&events);
        // Made or failed, the change is no longer pending (a failure ends
        // in the Error state, which has no event to make).
        self.pending = false;
        match result {
            Ok(()) => Ok(true),
            Err(e) => {
                self.machine = ModelState::Error;
                Err(self.fail(&format!("{}: {e}", f.name())))
            }
        }
    }

    /// The run's time (the start time before one exists).
    pub fn time(&self) -> f64 {
        self.sim.as_ref().map_or(self.start_time, |s| s.time())
    }

    fn log_events(&self, events: &[EventRecord]) {
        if !self.logger.wants("logEvents") {
            return;
        }
        for e in events {
            self.logger.category("logEvents", &e.description);
        }
    }

    pub fn last_successful_time(&self) -> f64 {
        self.last_successful_time
    }

    pub fn terminated(&self) -> bool {
        self.terminated
    }

    pub fn snapshot(&self) -> Snapshot {
        Snapshot {
            guid: self.guid.clone(),
            machine: self.machine,
            parameters: (0..self.table.interface.parameters.len()).map(|i| self.scene.get(i)).collect(),
            inputs: self.inputs.clone(),
            start_time: self.start_time,
            stop_time: self.stop_time,
            sim: self.sim.clone(),
            last_successful_time: self.last_successful_time,
            terminated: self.terminated,
            pending: self.pending,
            made_with: self.modes,
        }
    }

    /// Whether this instance can continue from a state: one saved in event
    /// mode needs event mode. A state saved in step mode with an event's
    /// change pending (the importer stepped on without event mode) is
    /// admitted by any instance: its next step makes the change first, as
    /// the saving instance's would.
    pub fn admits(&self, s: &Snapshot) -> Result<(), String> {
        if self.modes.event_mode_used || s.machine != ModelState::EventMode {
            return Ok(());
        }
        let this = if s.made_with.event_mode_used { "eventModeUsed = true" } else { "no event mode" };
        Err(format!(
            "the state was saved in event mode by an instance made with {this}; this instance has no event mode (FMI 2.0, or FMI 3.0 \
             instantiated with eventModeUsed = false) and cannot continue from it: save states in step mode, or instantiate with eventModeUsed = true"
        ))
    }

    /// SetFMUState: refused (the instance unchanged) unless [`Self::admits`].
    pub fn restore<F: Call>(&mut self, f: F, s: &Snapshot) -> CallResult {
        if s.guid != self.guid {
            return Err(self.fail(&format!("{}: the state belongs to FMU {}, not to this one ({})", f.name(), s.guid, self.guid)));
        }
        if let Err(m) = self.admits(s) {
            return Err(self.fail(&format!("{}: {m}", f.name())));
        }
        let mut scene = self.packaged.clone();
        scene.set_many(s.parameters.iter().copied().enumerate());
        self.scene = scene;
        self.machine = s.machine;
        self.inputs = s.inputs.clone();
        self.start_time = s.start_time;
        self.stop_time = s.stop_time;
        self.sim = s.sim.clone();
        self.provisional = None;
        self.last_successful_time = s.last_successful_time;
        self.terminated = s.terminated;
        self.pending = s.pending;
        self.sync_event_recording();
        Ok(())
    }

    /// The packaged scene with the given parameter values (for restoring
    /// serialized states).
    pub fn scene_with(&self, parameters: &[f64]) -> Component {
        let mut scene = self.packaged.clone();
        scene.set_many(parameters.iter().copied().enumerate());
        scene
    }
}
