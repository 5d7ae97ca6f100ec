//! The exported C functions of fmi3Functions.h that this FMU implements
//! (the ones of what it does not have are `absent`). Each checks its
//! pointers, enters the shared panic boundary and calls the safe
//! [`Instance3`]. No panic crosses into the importer, and no call enters
//! an instance that is already inside one (an intermediate-update callback
//! calling back).

#![allow(non_snake_case)]
#![allow(clippy::missing_safety_doc, clippy::too_many_arguments)]

use std::cell::{Cell, UnsafeCell};

use libc::{c_char, size_t};

use beamstop::fmi::boundary::{guarded, null_argument, run, slice, slice_mut, string};
use beamstop::fmi::instance::{CallResult, Instance, Modes};
use beamstop::fmi::states;
use beamstop::fmi::logging::{Logger, Sink};
use beamstop::fmi::resource::resource_dir;
use beamstop::fmi::serialize::{deserialize, serialize};

use beamstop::fmi3::instance::{Instance3, Options};
use beamstop::fmi3::state_machine::Function;
use beamstop::fmi3::types::*;

/// What an fmi3Instance points to: the instance and whether a call is
/// running in it (an intermediate-update callback that calls back is
/// refused instead of aliasing the running call's instance).
struct Slot {
    busy: Cell<bool>,
    instance: UnsafeCell<Instance3>,
    /// The importer's logger, for the calls refused while one runs (the
    /// instance's own logger is the running call's then).
    refusals: Fmi3Sink,
}

impl Slot {
    /// Logs why a call made while another runs on the instance is refused.
    fn refuse(&self, name: &str) {
        self.refusals.emit(
            Status::Error,
            "logStatusError",
            &format!("{name}: called while another call runs on this instance (from its intermediate-update callback), refused; make it after that call returns"),
        );
    }
}

/// Runs `body` on the instance behind `c` inside the panic boundary.
pub(super) fn call(c: fmi3Instance, f: Function, body: impl FnOnce(&mut Instance3) -> CallResult) -> fmi3Status {
    if c.is_null() {
        return Status::Error.raw();
    }
    // SAFETY: a non-null instance is one fmi3InstantiateCoSimulation
    // returned and fmi3FreeInstance has not freed (the caller's
    // obligation). Only shared references to the slot exist; the instance
    // inside is borrowed mutably by one call at a time (the busy flag).
    let slot = unsafe { &*(c as *const Slot) };
    if slot.busy.replace(true) {
        slot.refuse(f.name());
        return Status::Error.raw();
    }
    let instance = unsafe { &mut *slot.instance.get() };
    let status = run(instance, f, body);
    slot.busy.set(false);
    status
}

pub(super) fn fail(i: &Instance3, message: String) -> Status {
    i.core.fail(&message)
}

/// The value-array length of scalar variables.
pub(super) fn check_values(i: &Instance3, f: Function, n_vr: size_t, n_values: size_t) -> CallResult {
    if n_values != n_vr {
        return Err(fail(i, format!("{}: nValues = {n_values}: this FMU has only scalar variables, so nValues must equal nValueReferences = {n_vr}", f.name())));
    }
    Ok(())
}

/// The value reference of the independent variable `time` (after the
/// scene's variables, whose references are FMI 2.0's).
pub(super) fn time_vr(i: &Instance3) -> u32 {
    i.core.table().variables.len() as u32
}

#[no_mangle]
pub extern "C" fn fmi3GetVersion() -> *const c_char {
    c"3.0".as_ptr()
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetDebugLogging(
    instance: fmi3Instance,
    loggingOn: fmi3Boolean,
    nCategories: size_t,
    categories: *const fmi3String,
) -> fmi3Status {
    let f = Function::SetDebugLogging;
    call(instance, f, |i| {
        let Some(cats) = slice(categories, nCategories) else {
            return Err(null_argument(&i.core, f, "categories[]"));
        };
        let mut names = Vec::with_capacity(cats.len());
        for p in cats {
            match string(*p) {
                Some(s) => names.push(s),
                None => return Err(null_argument(&i.core, f, "a category name")),
            }
        }
        i.core.set_debug_logging(f, loggingOn != FMI3_FALSE, &names)
    })
}


#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateCoSimulation(
    instanceName: fmi3String,
    instantiationToken: fmi3String,
    resourcePath: fmi3String,
    visible: fmi3Boolean,
    loggingOn: fmi3Boolean,
    eventModeUsed: fmi3Boolean,
    earlyReturnAllowed: fmi3Boolean,
    requiredIntermediateVariables: *const fmi3ValueReference,
    nRequiredIntermediateVariables: size_t,
    instanceEnvironment: fmi3InstanceEnvironment,
    logMessage: fmi3LogMessageCallback,
    intermediateUpdate: fmi3IntermediateUpdateCallback,
) -> fmi3Instance {
    let _ = (visible, requiredIntermediateVariables);
    let f = "fmi3InstantiateCoSimulation";
    let result = guarded(|| -> Result<Instance, (Logger, String)> {
        let logger = Logger::new(Box::new(Fmi3Sink { callback: logMessage, environment: instanceEnvironment }), loggingOn != FMI3_FALSE);
        let name = string(instanceName).unwrap_or_default();
        if name.is_empty() {
            return Err((logger, format!("{f}: instanceName is NULL or empty")));
        }
        if nRequiredIntermediateVariables > 0 {
            return Err((
                logger,
                format!(
                    "{f}: nRequiredIntermediateVariables = {nRequiredIntermediateVariables}: this FMU offers no variables during intermediate updates (it calls the callback with intermediateVariableGetAllowed = false)"
                ),
            ));
        }
        let Some(token) = string(instantiationToken) else {
            return Err((logger, format!("{f}: instantiationToken is NULL")));
        };
        let Some(location) = string(resourcePath) else {
            return Err((logger, format!("{f}: resourcePath is NULL; the scene is read from the FMU's resources")));
        };
        let dir = match resource_dir(&location) {
            Ok(d) => d,
            Err(m) => return Err((logger, format!("{f}: {m}"))),
        };
        Instance::new(f, logger, &token, &dir)
    });
    match result {
        Ok(Ok(mut core)) => {
            core.modes = Modes { event_mode_used: eventModeUsed != FMI3_FALSE, early_return_allowed: earlyReturnAllowed != FMI3_FALSE };
            let options = Options { intermediate_update: intermediateUpdate, environment: instanceEnvironment };
            let refusals = Fmi3Sink { callback: logMessage, environment: instanceEnvironment };
            let slot = Slot { busy: Cell::new(false), instance: UnsafeCell::new(Instance3 { core, options }), refusals };
            Box::into_raw(Box::new(slot)) as fmi3Instance
        }
        Ok(Err((logger, message))) => {
            logger.status(Status::Error, &message);
            std::ptr::null_mut()
        }
        Err(_) => std::ptr::null_mut(),
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi3FreeInstance(instance: fmi3Instance) {
    if instance.is_null() {
        return;
    }
    let slot = &*(instance as *const Slot);
    if slot.busy.get() {
        slot.refuse("fmi3FreeInstance");
        return;
    }
    let _ = guarded(|| drop(Box::from_raw(instance as *mut Slot)));
}

#[no_mangle]
pub extern "C" fn fmi3EnterInitializationMode(
    instance: fmi3Instance,
    toleranceDefined: fmi3Boolean,
    tolerance: fmi3Float64,
    startTime: fmi3Float64,
    stopTimeDefined: fmi3Boolean,
    stopTime: fmi3Float64,
) -> fmi3Status {
    // The integrated phases' tolerance is the parameter
    // solver.integration_tolerance; the closed-form phases need none.
    let _ = (toleranceDefined, tolerance);
    let f = Function::EnterInitializationMode;
    call(instance, f, |i| {
        i.core.setup_experiment(f, startTime, if stopTimeDefined != FMI3_FALSE { Some(stopTime) } else { None })?;
        i.core.enter_initialization_mode(f)
    })
}

#[no_mangle]
pub extern "C" fn fmi3ExitInitializationMode(instance: fmi3Instance) -> fmi3Status {
    call(instance, Function::ExitInitializationMode, |i| i.exit_initialization_mode())
}

#[no_mangle]
pub extern "C" fn fmi3EnterEventMode(instance: fmi3Instance) -> fmi3Status {
    call(instance, Function::EnterEventMode, |i| i.enter_event_mode())
}

#[no_mangle]
pub extern "C" fn fmi3Terminate(instance: fmi3Instance) -> fmi3Status {
    call(instance, Function::Terminate, |i| i.core.terminate(Function::Terminate))
}

#[no_mangle]
pub extern "C" fn fmi3Reset(instance: fmi3Instance) -> fmi3Status {
    call(instance, Function::Reset, |i| i.core.reset(Function::Reset))
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetFloat64(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: size_t,
    values: *mut fmi3Float64,
    nValues: size_t,
) -> fmi3Status {
    let f = Function::Get("fmi3GetFloat64");
    call(instance, f, |i| {
        check_values(i, f, nValueReferences, nValues)?;
        let (Some(vrs), Some(out)) = (slice(valueReferences, nValueReferences), slice_mut(values, nValues)) else {
            return Err(null_argument(&i.core, f, "valueReferences[] or values[]"));
        };
        let time = time_vr(i);
        for (vr, value) in vrs.iter().zip(out.iter_mut()) {
            if *vr == time {
                *value = i.core.time();
            } else {
                i.core.get_real(f, std::slice::from_ref(vr), std::slice::from_mut(value))?;
            }
        }
        Ok(())
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetInt32(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: size_t,
    values: *mut fmi3Int32,
    nValues: size_t,
) -> fmi3Status {
    let f = Function::Get("fmi3GetInt32");
    call(instance, f, |i| {
        check_values(i, f, nValueReferences, nValues)?;
        let (Some(vrs), Some(out)) = (slice(valueReferences, nValueReferences), slice_mut(values, nValues)) else {
            return Err(null_argument(&i.core, f, "valueReferences[] or values[]"));
        };
        i.core.get_integer(f, vrs, out)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetBoolean(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: size_t,
    values: *mut fmi3Boolean,
    nValues: size_t,
) -> fmi3Status {
    let f = Function::Get("fmi3GetBoolean");
    call(instance, f, |i| {
        check_values(i, f, nValueReferences, nValues)?;
        let (Some(vrs), Some(out)) = (slice(valueReferences, nValueReferences), slice_mut(values, nValues)) else {
            return Err(null_argument(&i.core, f, "valueReferences[] or values[]"));
        };
        let mut flags = vec![false; vrs.len()];
        i.core.get_boolean(f, vrs, &mut flags)?;
        for (v, b) in out.iter_mut().zip(flags) {
            *v = if b { FMI3_TRUE } else { FMI3_FALSE };
        }
        Ok(())
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetFloat64(
    instance: fmi3Instance,
    valueReferences: *const fmi3ValueReference,
    nValueReferences: size_t,
    values: *const fmi3Float64,
    nValues: size_t,
) -> fmi3Status {
    let f = Function::Set("fmi3SetFloat64");
    call(instance, f, |i| {
        check_values(i, f, nValueReferences, nValues)?;
        let (Some(vrs), Some(input)) = (slice(valueReferences, nValueReferences), slice(values, nValues)) else {
            return Err(null_argument(&i.core, f, "valueReferences[] or values[]"));
        };
        if vrs.contains(&time_vr(i)) {
            return Err(fail(i, format!("{}: value reference {} is 'time', the independent variable, which cannot be set", f.name(), time_vr(i))));
        }
        i.core.set_real(f, vrs, input)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetFMUState(instance: fmi3Instance, FMUState: *mut fmi3FMUState) -> fmi3Status {
    let f = Function::GetFMUState;
    call(instance, f, |i| {
        if FMUState.is_null() {
            return Err(null_argument(&i.core, f, "FMUState"));
        }
        let snapshot = i.core.snapshot();
        i.core.states.hand_out(FMUState, snapshot).map_err(|m| fail(i, format!("{}: {m}", f.name())))
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetFMUState(instance: fmi3Instance, FMUState: fmi3FMUState) -> fmi3Status {
    let f = Function::SetFMUState;
    call(instance, f, |i| {
        if FMUState.is_null() {
            return Err(null_argument(&i.core, f, "FMUState"));
        }
        let snapshot = states::snapshot(FMUState).map_err(|m| fail(i, format!("{}: {m}", f.name())))?;
        i.core.restore(f, snapshot)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3FreeFMUState(instance: fmi3Instance, FMUState: *mut fmi3FMUState) -> fmi3Status {
    let f = Function::FreeFMUState;
    call(instance, f, |i| {
        if !FMUState.is_null() {
            states::free(FMUState).map_err(|m| fail(i, format!("{}: {m}", f.name())))?;
        }
        Ok(())
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SerializedFMUStateSize(instance: fmi3Instance, FMUState: fmi3FMUState, size: *mut size_t) -> fmi3Status {
    let f = Function::SerializedFMUStateSize;
    call(instance, f, |i| {
        if FMUState.is_null() || size.is_null() {
            return Err(null_argument(&i.core, f, "FMUState or size"));
        }
        let snapshot = states::snapshot(FMUState).map_err(|m| fail(i, format!("{}: {m}", f.name())))?;
        *size = serialize(snapshot).len();
        Ok(())
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SerializeFMUState(instance: fmi3Instance, FMUState: fmi3FMUState, serializedState: *mut fmi3Byte, size: size_t) -> fmi3Status {
    let f = Function::SerializeFMUState;
    call(instance, f, |i| {
        if FMUState.is_null() {
            return Err(null_argument(&i.core, f, "FMUState"));
        }
        let snapshot = states::snapshot(FMUState).map_err(|m| fail(i, format!("{}: {m}", f.name())))?;
        let bytes = serialize(snapshot);
        if size < bytes.len() {
            return Err(fail(i, format!("{}: size = {size}: the state needs {} bytes (fmi3SerializedFMUStateSize)", f.name(), bytes.len())));
        }
        let Some(out) = slice_mut(serializedState, bytes.len()) else {
            return Err(null_argument(&i.core, f, "serializedState"));
        };
        out.copy_from_slice(&bytes);
        Ok(())
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3DeserializeFMUState(instance: fmi3Instance, serializedState: *const fmi3Byte, size: size_t, FMUState: *mut fmi3FMUState) -> fmi3Status {
    let f = Function::DeserializeFMUState;
    call(instance, f, |i| {
        let Some(bytes) = slice(serializedState, size) else {
            return Err(null_argument(&i.core, f, "serializedState"));
        };
        if FMUState.is_null() {
            return Err(null_argument(&i.core, f, "FMUState"));
        }
        let snapshot = deserialize(&i.core, bytes).map_err(|m| fail(i, format!("{}: {m}", f.name())))?;
        // FMI 2.0's state after fmi2CancelStep: no FMI 3.0 instance is ever
        // in it, and one restored into it could call nothing.
        if snapshot.machine == beamstop::fmi::ModelState::StepCanceled {
            return Err(fail(i, format!("{}: serialized state: instance state StepCanceled is FMI 2.0's (fmi2CancelStep); an FMI 3.0 instance is never in it", f.name())));
        }
        i.core.states.hand_out(FMUState, snapshot).map_err(|m| fail(i, format!("{}: {m}", f.name())))
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi3UpdateDiscreteStates(
    instance: fmi3Instance,
    discreteStatesNeedUpdate: *mut fmi3Boolean,
    terminateSimulation: *mut fmi3Boolean,
    nominalsOfContinuousStatesChanged: *mut fmi3Boolean,
    valuesOfContinuousStatesChanged: *mut fmi3Boolean,
    nextEventTimeDefined: *mut fmi3Boolean,
    nextEventTime: *mut fmi3Float64,
) -> fmi3Status {
    let f = Function::UpdateDiscreteStates;
    call(instance, f, |i| {
        let flags = [discreteStatesNeedUpdate, terminateSimulation, nominalsOfContinuousStatesChanged, valuesOfContinuousStatesChanged, nextEventTimeDefined];
        if flags.iter().any(|p| p.is_null()) || nextEventTime.is_null() {
            return Err(null_argument(&i.core, f, "an output argument"));
        }
        let changed = i.update_discrete_states()?;
        for p in flags {
            *p = FMI3_FALSE;
        }
        // The change is a jump of the velocities (a restitution impact,
        // the start of sticking): continuous states in FMI's words.
        *valuesOfContinuousStatesChanged = if changed { FMI3_TRUE } else { FMI3_FALSE };
        *nextEventTime = 0.0;
        Ok(())
    })
}

#[no_mangle]
pub extern "C" fn fmi3EnterStepMode(instance: fmi3Instance) -> fmi3Status {
    call(instance, Function::EnterStepMode, |i| i.enter_step_mode())
}

#[no_mangle]
pub unsafe extern "C" fn fmi3DoStep(
    instance: fmi3Instance,
    currentCommunicationPoint: fmi3Float64,
    communicationStepSize: fmi3Float64,
    noSetFMUStatePriorToCurrentPoint: fmi3Boolean,
    eventHandlingNeeded: *mut fmi3Boolean,
    terminateSimulation: *mut fmi3Boolean,
    earlyReturn: *mut fmi3Boolean,
    lastSuccessfulTime: *mut fmi3Float64,
) -> fmi3Status {
    let _ = noSetFMUStatePriorToCurrentPoint;
    let f = Function::DoStep;
    call(instance, f, |i| {
        if eventHandlingNeeded.is_null() || terminateSimulation.is_null() || earlyReturn.is_null() || lastSuccessfulTime.is_null() {
            return Err(null_argument(&i.core, f, "an output argument"));
        }
        let result = i.do_step(currentCommunicationPoint, communicationStepSize);
        let stepped = result.unwrap_or(beamstop::fmi3::instance::Stepped { event_handling_needed: false, early_return: false });
        *eventHandlingNeeded = if stepped.event_handling_needed { FMI3_TRUE } else { FMI3_FALSE };
        *earlyReturn = if stepped.early_return { FMI3_TRUE } else { FMI3_FALSE };
        *terminateSimulation = FMI3_FALSE;
        *lastSuccessfulTime = i.core.last_successful_time();
        result.map(|_| ())
    })
}
