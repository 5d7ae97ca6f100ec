//! The exported C functions of fmi2Functions.h. Each one checks its
//! pointers, enters the panic boundary and calls the safe [`Instance`].
//! No panic crosses into the importer: a panic becomes fmi2Error, a logged
//! message and the Error state.

#![allow(non_snake_case)]
#![allow(clippy::missing_safety_doc)]

use libc::{c_char, size_t};

use beamstop::fmi::boundary::{guarded, null_argument as null, run, slice, slice_mut, string};
use beamstop::fmi::instance::{CallResult, Instance};
use beamstop::fmi::states;
use beamstop::fmi::logging::Logger;
use beamstop::fmi::resource::resource_dir;
use beamstop::fmi::serialize::{deserialize, serialize};

use beamstop::fmi2::state_machine::Function;
use beamstop::fmi2::types::*;

/// Runs `body` on the instance behind `c` inside the panic boundary.
fn call(c: fmi2Component, f: Function, body: impl FnOnce(&mut Instance) -> CallResult) -> fmi2Status {
    if c.is_null() {
        return Status::Error.raw();
    }
    // SAFETY: a non-null component is one fmi2Instantiate returned and
    // fmi2FreeInstance has not freed (the caller's obligation).
    let instance = unsafe { &mut *(c as *mut Instance) };
    run(instance, f, body)
}

fn null_argument(instance: &Instance, f: Function, what: &str) -> Status {
    null(instance, f, what)
}

#[no_mangle]
pub extern "C" fn fmi2GetTypesPlatform() -> *const c_char {
    c"default".as_ptr()
}

#[no_mangle]
pub extern "C" fn fmi2GetVersion() -> *const c_char {
    c"2.0".as_ptr()
}

#[no_mangle]
pub unsafe extern "C" fn fmi2Instantiate(
    instanceName: fmi2String,
    fmuType: fmi2Type,
    fmuGUID: fmi2String,
    fmuResourceLocation: fmi2String,
    functions: *const fmi2CallbackFunctions,
    visible: fmi2Boolean,
    loggingOn: fmi2Boolean,
) -> fmi2Component {
    let _ = visible;
    if functions.is_null() {
        return std::ptr::null_mut();
    }
    let functions = &*functions;
    if functions.logger.is_none() {
        return std::ptr::null_mut();
    }
    let result = guarded(|| -> Result<Instance, (Logger, String)> {
        let name = string(instanceName).unwrap_or_default();
        let sink = Fmi2Sink {
            callback: functions.logger,
            environment: functions.componentEnvironment,
            instance_name: std::ffi::CString::new(name.replace('\0', "")).unwrap_or_default(),
        };
        let logger = Logger::new(Box::new(sink), loggingOn != FMI2_FALSE);
        if name.is_empty() {
            return Err((logger, "fmi2Instantiate: instanceName is NULL or empty".into()));
        }
        if fmuType != FMI2_CO_SIMULATION {
            return Err((logger, format!("fmi2Instantiate: fmuType = {fmuType}: this FMU supports only fmi2CoSimulation (1)")));
        }
        let Some(guid) = string(fmuGUID) else {
            return Err((logger, "fmi2Instantiate: fmuGUID is NULL".into()));
        };
        let Some(location) = string(fmuResourceLocation) else {
            return Err((logger, "fmi2Instantiate: fmuResourceLocation is NULL; the scene is read from the FMU's resources".into()));
        };
        let dir = match resource_dir(&location) {
            Ok(d) => d,
            Err(m) => return Err((logger, format!("fmi2Instantiate: {m}"))),
        };
        Instance::new("fmi2Instantiate", logger, &guid, &dir)
    });
    match result {
        Ok(Ok(instance)) => Box::into_raw(Box::new(instance)) as fmi2Component,
        Ok(Err((logger, message))) => {
            logger.status(Status::Error, &message);
            std::ptr::null_mut()
        }
        Err(_) => std::ptr::null_mut(),
    }
}

#[no_mangle]
pub unsafe extern "C" fn fmi2FreeInstance(c: fmi2Component) {
    if c.is_null() {
        return;
    }
    let _ = guarded(|| drop(Box::from_raw(c as *mut Instance)));
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetDebugLogging(
    c: fmi2Component,
    loggingOn: fmi2Boolean,
    nCategories: size_t,
    categories: *const fmi2String,
) -> fmi2Status {
    call(c, Function::SetDebugLogging, |i| {
        let Some(cats) = slice(categories, nCategories) else {
            return Err(null_argument(i, Function::SetDebugLogging, "categories[]"));
        };
        let mut names = Vec::with_capacity(cats.len());
        for p in cats {
            match string(*p) {
                Some(s) => names.push(s),
                None => return Err(null_argument(i, Function::SetDebugLogging, "a category name")),
            }
        }
        i.set_debug_logging(Function::SetDebugLogging, loggingOn != FMI2_FALSE, &names)
    })
}

#[no_mangle]
pub extern "C" fn fmi2SetupExperiment(
    c: fmi2Component,
    toleranceDefined: fmi2Boolean,
    tolerance: fmi2Real,
    startTime: fmi2Real,
    stopTimeDefined: fmi2Boolean,
    stopTime: fmi2Real,
) -> fmi2Status {
    let _ = (toleranceDefined, tolerance);
    call(c, Function::SetupExperiment, |i| {
        i.setup_experiment(Function::SetupExperiment, startTime, if stopTimeDefined != FMI2_FALSE { Some(stopTime) } else { None })
    })
}

#[no_mangle]
pub extern "C" fn fmi2EnterInitializationMode(c: fmi2Component) -> fmi2Status {
    call(c, Function::EnterInitializationMode, |i| i.enter_initialization_mode(Function::EnterInitializationMode))
}

#[no_mangle]
pub extern "C" fn fmi2ExitInitializationMode(c: fmi2Component) -> fmi2Status {
    call(c, Function::ExitInitializationMode, |i| i.exit_initialization_mode(Function::ExitInitializationMode))
}

#[no_mangle]
pub extern "C" fn fmi2Terminate(c: fmi2Component) -> fmi2Status {
    call(c, Function::Terminate, |i| i.terminate(Function::Terminate))
}

#[no_mangle]
pub extern "C" fn fmi2Reset(c: fmi2Component) -> fmi2Status {
    call(c, Function::Reset, |i| i.reset(Function::Reset))
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetReal(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: size_t,
    value: *mut fmi2Real,
) -> fmi2Status {
    let f = Function::GetReal;
    call(c, f, |i| {
        let (Some(vrs), Some(values)) = (slice(vr, nvr), slice_mut(value, nvr)) else {
            return Err(null_argument(i, f, "vr[] or value[]"));
        };
        i.get_real(f, vrs, values)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetInteger(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: size_t,
    value: *mut fmi2Integer,
) -> fmi2Status {
    let f = Function::GetInteger;
    call(c, f, |i| {
        let (Some(vrs), Some(values)) = (slice(vr, nvr), slice_mut(value, nvr)) else {
            return Err(null_argument(i, f, "vr[] or value[]"));
        };
        i.get_integer(f, vrs, values)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetBoolean(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: size_t,
    value: *mut fmi2Boolean,
) -> fmi2Status {
    let f = Function::GetBoolean;
    call(c, f, |i| {
        let (Some(vrs), Some(values)) = (slice(vr, nvr), slice_mut(value, nvr)) else {
            return Err(null_argument(i, f, "vr[] or value[]"));
        };
        let mut flags = vec![false; vrs.len()];
        i.get_boolean(f, vrs, &mut flags)?;
        for (v, b) in values.iter_mut().zip(flags) {
            *v = if b { FMI2_TRUE } else { FMI2_FALSE };
        }
        Ok(())
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetString(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: size_t,
    value: *mut fmi2String,
) -> fmi2Status {
    let _ = value;
    let f = Function::GetString;
    call(c, f, |i| {
        let Some(vrs) = slice(vr, nvr) else { return Err(null_argument(i, f, "vr[]")) };
        i.no_such_variables(f, vrs, "String variables")
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetReal(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: size_t,
    value: *const fmi2Real,
) -> fmi2Status {
    let f = Function::SetReal;
    call(c, f, |i| {
        let (Some(vrs), Some(values)) = (slice(vr, nvr), slice(value, nvr)) else {
            return Err(null_argument(i, f, "vr[] or value[]"));
        };
        i.set_real(f, vrs, values)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetInteger(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: size_t,
    value: *const fmi2Integer,
) -> fmi2Status {
    let _ = value;
    let f = Function::SetInteger;
    call(c, f, |i| {
        let Some(vrs) = slice(vr, nvr) else { return Err(null_argument(i, f, "vr[]")) };
        i.no_such_variables(f, vrs, "Integer variables that can be set")
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetBoolean(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: size_t,
    value: *const fmi2Boolean,
) -> fmi2Status {
    let _ = value;
    let f = Function::SetBoolean;
    call(c, f, |i| {
        let Some(vrs) = slice(vr, nvr) else { return Err(null_argument(i, f, "vr[]")) };
        i.no_such_variables(f, vrs, "Boolean variables that can be set")
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetString(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: size_t,
    value: *const fmi2String,
) -> fmi2Status {
    let _ = value;
    let f = Function::SetString;
    call(c, f, |i| {
        let Some(vrs) = slice(vr, nvr) else { return Err(null_argument(i, f, "vr[]")) };
        i.no_such_variables(f, vrs, "String variables")
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetFMUstate(c: fmi2Component, FMUstate: *mut fmi2FMUstate) -> fmi2Status {
    let f = Function::GetFMUstate;
    call(c, f, |i| {
        if FMUstate.is_null() {
            return Err(null_argument(i, f, "FMUstate"));
        }
        let snapshot = i.snapshot();
        i.states.hand_out(FMUstate, snapshot).map_err(|m| i.fail(&format!("{}: {m}", f.name())))
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SetFMUstate(c: fmi2Component, FMUstate: fmi2FMUstate) -> fmi2Status {
    let f = Function::SetFMUstate;
    call(c, f, |i| {
        if FMUstate.is_null() {
            return Err(null_argument(i, f, "FMUstate"));
        }
        let snapshot = states::snapshot(FMUstate).map_err(|m| i.fail(&format!("{}: {m}", f.name())))?;
        i.restore(f, snapshot)
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2FreeFMUstate(c: fmi2Component, FMUstate: *mut fmi2FMUstate) -> fmi2Status {
    let f = Function::FreeFMUstate;
    call(c, f, |i| {
        if !FMUstate.is_null() {
            states::free(FMUstate).map_err(|m| i.fail(&format!("{}: {m}", f.name())))?;
        }
        Ok(())
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SerializedFMUstateSize(c: fmi2Component, FMUstate: fmi2FMUstate, size: *mut size_t) -> fmi2Status {
    let f = Function::SerializedFMUstateSize;
    call(c, f, |i| {
        if FMUstate.is_null() || size.is_null() {
            return Err(null_argument(i, f, "FMUstate or size"));
        }
        let snapshot = states::snapshot(FMUstate).map_err(|m| i.fail(&format!("{}: {m}", f.name())))?;
        *size = serialize(snapshot).len();
        Ok(())
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2SerializeFMUstate(
    c: fmi2Component,
    FMUstate: fmi2FMUstate,
    serializedState: *mut fmi2Byte,
    size: size_t,
) -> fmi2Status {
    let f = Function::SerializeFMUstate;
    call(c, f, |i| {
        if FMUstate.is_null() {
            return Err(null_argument(i, f, "FMUstate"));
        }
        let snapshot = states::snapshot(FMUstate).map_err(|m| i.fail(&format!("{}: {m}", f.name())))?;
        let bytes = serialize(snapshot);
        if size < bytes.len() {
            return Err(i.fail(&format!("fmi2SerializeFMUstate: size = {size}: the state needs {} bytes (fmi2SerializedFMUstateSize)", bytes.len())));
        }
        let Some(out) = slice_mut(serializedState as *mut u8, bytes.len()) else {
            return Err(null_argument(i, f, "serializedState"));
        };
        out.copy_from_slice(&bytes);
        Ok(())
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
    c: fmi2Component,
    serializedState: *const fmi2Byte,
    size: size_t,
    FMUstate: *mut fmi2FMUstate,
) -> fmi2Status {
    let f = Function::DeSerializeFMUstate;
    call(c, f, |i| {
        let Some(bytes) = slice(serializedState as *const u8, size) else {
            return Err(null_argument(i, f, "serializedState"));
        };
        if FMUstate.is_null() {
            return Err(null_argument(i, f, "FMUstate"));
        }
        let snapshot = deserialize(i, bytes).map_err(|m| i.fail(&format!("fmi2DeSerializeFMUstate: {m}")))?;
        i.states.hand_out(FMUstate, snapshot).map_err(|m| i.fail(&format!("{}: {m}", f.name())))
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetDirectionalDerivative(
    c: fmi2Component,
    vUnknown_ref: *const fmi2ValueReference,
    nUnknown: size_t,
    vKnown_ref: *const fmi2ValueReference,
    nKnown: size_t,
    dvKnown: *const fmi2Real,
    dvUnknown: *mut fmi2Real,
) -> fmi2Status {
    let _ = (vUnknown_ref, nUnknown, vKnown_ref, nKnown, dvKnown, dvUnknown);
    let f = Function::GetDirectionalDerivative;
    call(c, f, |i| {
        Err(i.fail("fmi2GetDirectionalDerivative: not provided (providesDirectionalDerivative = false)"))
    })
}

/// The Model Exchange functions: declared by fmi2Functions.h, refused here.
fn model_exchange(c: fmi2Component, name: &'static str) -> fmi2Status {
    // The state table allows these in no state: call() refuses them.
    call(c, Function::ModelExchange(name), |_| Ok(()))
}

#[no_mangle]
pub extern "C" fn fmi2EnterEventMode(c: fmi2Component) -> fmi2Status {
    model_exchange(c, "fmi2EnterEventMode")
}

#[no_mangle]
pub extern "C" fn fmi2NewDiscreteStates(c: fmi2Component, fmi2eventInfo: *mut fmi2EventInfo) -> fmi2Status {
    let _ = fmi2eventInfo;
    model_exchange(c, "fmi2NewDiscreteStates")
}

#[no_mangle]
pub extern "C" fn fmi2EnterContinuousTimeMode(c: fmi2Component) -> fmi2Status {
    model_exchange(c, "fmi2EnterContinuousTimeMode")
}

#[no_mangle]
pub extern "C" fn fmi2CompletedIntegratorStep(
    c: fmi2Component,
    noSetFMUStatePriorToCurrentPoint: fmi2Boolean,
    enterEventMode: *mut fmi2Boolean,
    terminateSimulation: *mut fmi2Boolean,
) -> fmi2Status {
    let _ = (noSetFMUStatePriorToCurrentPoint, enterEventMode, terminateSimulation);
    model_exchange(c, "fmi2CompletedIntegratorStep")
}

#[no_mangle]
pub extern "C" fn fmi2SetTime(c: fmi2Component, time: fmi2Real) -> fmi2Status {
    let _ = time;
    model_exchange(c, "fmi2SetTime")
}

#[no_mangle]
pub extern "C" fn fmi2SetContinuousStates(c: fmi2Component, x: *const fmi2Real, nx: size_t) -> fmi2Status {
    let _ = (x, nx);
    model_exchange(c, "fmi2SetContinuousStates")
}

#[no_mangle]
pub extern "C" fn fmi2GetDerivatives(c: fmi2Component, derivatives: *mut fmi2Real, nx: size_t) -> fmi2Status {
    let _ = (derivatives, nx);
    model_exchange(c, "fmi2GetDerivatives")
}

#[no_mangle]
pub extern "C" fn fmi2GetEventIndicators(c: fmi2Component, eventIndicators: *mut fmi2Real, ni: size_t) -> fmi2Status {
    let _ = (eventIndicators, ni);
    model_exchange(c, "fmi2GetEventIndicators")
}

#[no_mangle]
pub extern "C" fn fmi2GetContinuousStates(c: fmi2Component, x: *mut fmi2Real, nx: size_t) -> fmi2Status {
    let _ = (x, nx);
    model_exchange(c, "fmi2GetContinuousStates")
}

#[no_mangle]
pub extern "C" fn fmi2GetNominalsOfContinuousStates(c: fmi2Component, x_nominal: *mut fmi2Real, nx: size_t) -> fmi2Status {
    let _ = (x_nominal, nx);
    model_exchange(c, "fmi2GetNominalsOfContinuousStates")
}

#[no_mangle]
pub extern "C" fn fmi2SetRealInputDerivatives(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: size_t,
    order: *const fmi2Integer,
    value: *const fmi2Real,
) -> fmi2Status {
    let _ = (vr, nvr, order, value);
    let f = Function::SetRealInputDerivatives;
    call(c, f, |i| {
        Err(i.fail("fmi2SetRealInputDerivatives: inputs are held constant over a step (canInterpolateInputs = false)"))
    })
}

#[no_mangle]
pub extern "C" fn fmi2GetRealOutputDerivatives(
    c: fmi2Component,
    vr: *const fmi2ValueReference,
    nvr: size_t,
    order: *const fmi2Integer,
    value: *mut fmi2Real,
) -> fmi2Status {
    let _ = (vr, nvr, order, value);
    let f = Function::GetRealOutputDerivatives;
    call(c, f, |i| {
        Err(i.fail("fmi2GetRealOutputDerivatives: not provided (maxOutputDerivativeOrder = 0)"))
    })
}

#[no_mangle]
pub extern "C" fn fmi2DoStep(
    c: fmi2Component,
    currentCommunicationPoint: fmi2Real,
    communicationStepSize: fmi2Real,
    noSetFMUStatePriorToCurrentPoint: fmi2Boolean,
) -> fmi2Status {
    let _ = noSetFMUStatePriorToCurrentPoint;
    call(c, Function::DoStep, |i| i.do_step(Function::DoStep, currentCommunicationPoint, communicationStepSize, false).map(|_| ()))
}

#[no_mangle]
pub extern "C" fn fmi2CancelStep(c: fmi2Component) -> fmi2Status {
    // Never allowed (doStep is synchronous): call() refuses it.
    call(c, Function::CancelStep, |_| Ok(()))
}

fn unsupported_status(i: &Instance, f: Function, kind: fmi2StatusKind) -> Status {
    i.logger.status(Status::Discard, &format!("{}: status kind {kind} is not provided by this FMU", f.name()));
    Status::Discard
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetStatus(c: fmi2Component, s: fmi2StatusKind, value: *mut fmi2Status) -> fmi2Status {
    let f = Function::GetStatus;
    call(c, f, |i| {
        let _ = value;
        Err(unsupported_status(i, f, s))
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealStatus(c: fmi2Component, s: fmi2StatusKind, value: *mut fmi2Real) -> fmi2Status {
    let f = Function::GetRealStatus;
    call(c, f, |i| {
        if s != FMI2_LAST_SUCCESSFUL_TIME {
            return Err(unsupported_status(i, f, s));
        }
        let t = i.last_successful_time();
        if value.is_null() {
            return Err(null_argument(i, f, "value"));
        }
        *value = t;
        Ok(())
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetIntegerStatus(c: fmi2Component, s: fmi2StatusKind, value: *mut fmi2Integer) -> fmi2Status {
    let f = Function::GetIntegerStatus;
    let _ = value;
    call(c, f, |i| {
        Err(unsupported_status(i, f, s))
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetBooleanStatus(c: fmi2Component, s: fmi2StatusKind, value: *mut fmi2Boolean) -> fmi2Status {
    let f = Function::GetBooleanStatus;
    call(c, f, |i| {
        if s != FMI2_TERMINATED {
            return Err(unsupported_status(i, f, s));
        }
        let t = i.terminated();
        if value.is_null() {
            return Err(null_argument(i, f, "value"));
        }
        *value = if t { FMI2_TRUE } else { FMI2_FALSE };
        Ok(())
    })
}

#[no_mangle]
pub unsafe extern "C" fn fmi2GetStringStatus(c: fmi2Component, s: fmi2StatusKind, value: *mut fmi2String) -> fmi2Status {
    let f = Function::GetStringStatus;
    let _ = value;
    call(c, f, |i| {
        Err(unsupported_status(i, f, s))
    })
}
