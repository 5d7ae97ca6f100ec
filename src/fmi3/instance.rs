//! One FMI 3.0 co-simulation instance: the shared core and what FMI 3.0
//! adds to it, the options the importer chose at instantiation (event
//! mode, early return, the intermediate-update callback) and what they
//! make of a step.
//!
//! How a step meets an event (docs/fmi.md has the reading of the standard
//! behind it):
//! - early return allowed, event mode used: the step stops just before the
//!   event's discrete change, returns early at the event's own time with
//!   `eventHandlingNeeded`, and the change is made in
//!   fmi3UpdateDiscreteStates;
//! - early return allowed, no event mode: the FMU makes the change itself
//!   and returns early at the event's time (with an intermediate-update
//!   callback, only where the importer asks for it there);
//! - event mode, no early return: events inside the step are handled as
//!   the FMI 2.0 FMU handles them; one exactly at the step's end is left
//!   to event mode (`eventHandlingNeeded`), so that the importer sees the
//!   outputs before and after it;
//! - neither: the step goes over every event as the FMI 2.0 FMU does.

use crate::fmi::boundary::Shell;
use crate::fmi::instance::{CallResult, Instance, Modes, StepEnd};
use crate::fmi::ModelState;

use super::state_machine::Function;
use super::types::{fmi3Boolean, fmi3InstanceEnvironment, fmi3IntermediateUpdateCallback, FMI3_FALSE, FMI3_TRUE};

/// The importer's callback at fmi3InstantiateCoSimulation (its choices of
/// event mode and early return are the core's [`crate::fmi::instance::Modes`]).
pub struct Options {
    pub intermediate_update: fmi3IntermediateUpdateCallback,
    pub environment: fmi3InstanceEnvironment,
}

// The environment pointer is the importer's, only handed back to its callbacks.
unsafe impl Send for Options {}

pub struct Instance3 {
    pub core: Instance,
    pub options: Options,
}

impl Shell for Instance3 {
    fn core(&mut self) -> &mut Instance {
        &mut self.core
    }
}

/// What fmi3DoStep reports besides its status.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stepped {
    pub event_handling_needed: bool,
    pub early_return: bool,
}

impl Instance3 {
    pub fn exit_initialization_mode(&mut self) -> CallResult {
        self.core.exit_initialization_mode(Function::ExitInitializationMode)?;
        if self.core.modes.event_mode_used {
            self.core.set_machine(ModelState::EventMode);
        }
        Ok(())
    }

    pub fn enter_event_mode(&mut self) -> CallResult {
        if !self.core.modes.event_mode_used {
            return Err(self.core.fail("fmi3EnterEventMode: this instance was instantiated with eventModeUsed = false"));
        }
        self.core.set_machine(ModelState::EventMode);
        Ok(())
    }

    pub fn enter_step_mode(&mut self) -> CallResult {
        self.core.set_machine(ModelState::StepMode);
        Ok(())
    }

    /// fmi3UpdateDiscreteStates: makes the pending event's discrete change;
    /// whether one was made.
    pub fn update_discrete_states(&mut self) -> CallResult<bool> {
        self.core.apply_pending(Function::UpdateDiscreteStates)
    }

    /// fmi3DoStep (see the module doc): one advance to the step's end
    /// that stops before the events it must return at.
    pub fn do_step(&mut self, t: f64, h: f64) -> CallResult<Stepped> {
        let f = Function::DoStep;
        let target = self.core.check_step(f, t, h)?;
        let options = &self.options;
        let Modes { event_mode_used, early_return_allowed } = self.core.modes;
        let callback = options.intermediate_update.is_some();
        let mut stop_before = |te: f64| {
            let inside = te < target;
            let requested = intermediate_update(options, te, early_return_allowed && inside);
            if event_mode_used {
                early_return_allowed || !inside
            } else {
                early_return_allowed && inside && (requested || !callback)
            }
        };
        // Stepping from event to event ends bit for bit where one advance
        // does (the contract's promise): stop at events only for a reason.
        let end = if event_mode_used || early_return_allowed || callback {
            self.core.advance(f, target, Some(&mut stop_before))?
        } else {
            self.core.advance(f, target, None)?
        };
        let StepEnd::Event(te) = end else {
            return Ok(Stepped { event_handling_needed: false, early_return: false });
        };
        let inside = te < target;
        if event_mode_used {
            return Ok(Stepped { event_handling_needed: true, early_return: inside });
        }
        // Without event mode the FMU makes the change itself, then returns.
        self.core.apply_pending(f)?;
        Ok(Stepped { event_handling_needed: false, early_return: true })
    }
}

/// Asks the importer's intermediate-update callback at the event at `time`
/// (the FMU has computed up to it); whether it requests an early return.
fn intermediate_update(options: &Options, time: f64, can_return_early: bool) -> bool {
    let Some(callback) = options.intermediate_update else { return false };
    let mut requested: fmi3Boolean = FMI3_FALSE;
    let mut requested_time = time;
    let flag = |b: bool| if b { FMI3_TRUE } else { FMI3_FALSE };
    // SAFETY: the importer promised a valid callback for the instance's
    // lifetime; both out pointers are valid locals. The callback may not
    // call back into this instance (neither getting nor setting variables
    // is allowed, and the boundary refuses any call while one is running).
    unsafe {
        callback(options.environment, time, FMI3_FALSE, FMI3_FALSE, FMI3_TRUE, flag(can_return_early), &mut requested, &mut requested_time)
    };
    can_return_early && requested != FMI3_FALSE
}
