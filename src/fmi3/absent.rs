//! The exported functions of fmi3Functions.h for what this FMU does not
//! have (FMI 3.0.1 requires every one): Model Exchange, Scheduled
//! Execution, clocks, configuration mode, derivatives, and the getters and
//! setters of variable types it has none of. Each is refused with the
//! reason, through the same panic boundary and state table as the others
//! (`api`); the bodies are one macro each, as Reference-FMUs'
//! `NOT_IMPLEMENTED`. The signatures stay spelled out: cbindgen writes the
//! header from them, and the header is compiled against the standard's.

#![allow(non_snake_case, unused_variables)]
#![allow(clippy::missing_safety_doc, clippy::too_many_arguments)]

use libc::size_t;

use beamstop::fmi::boundary::{null_argument, slice};
use beamstop::fmi::logging::Logger;
use beamstop::fmi::Status;

use super::api::{call, check_values, fail, time_vr};
use beamstop::fmi3::state_machine::Function;
use beamstop::fmi3::types::*;

const NO_CLOCKS: &str = "this FMU has no clocks";
const NO_CONFIGURATION: &str = "this FMU has no structural parameters, so no configuration mode";
const NO_MODEL_EXCHANGE: &str = "this FMU implements Co-Simulation only, not Model Exchange";

/// Refuses a function of something this FMU does not have, in every
/// state, with the reason (the state table allows it nowhere).
macro_rules! absent {
    ($instance:expr, $name:literal, $why:expr) => {
        call($instance, Function::Absent($name, $why), |_| Ok(()))
    };
}

/// Refuses an optional function the modelDescription.xml says is not
/// provided (`$flag`: the capability flag and its value).
macro_rules! not_provided {
    ($instance:expr, $function:ident, $flag:literal) => {{
        let f = Function::$function;
        call($instance, f, |i| Err(fail(i, format!("{}: not provided ({})", f.name(), $flag))))
    }};
}

/// A getter or setter of a type this FMU has no variable of (that it may
/// call): refused for any value reference, which the message describes.
unsafe fn absent_type(instance: fmi3Instance, f: Function, vr: *const fmi3ValueReference, n_vr: size_t, n_values: size_t, what: &str) -> fmi3Status {
    call(instance, f, |i| {
        check_values(i, f, n_vr, n_values)?;
        let Some(vrs) = slice(vr, n_vr) else { return Err(null_argument(&i.core, f, "valueReferences[]")) };
        if vrs.first() == Some(&time_vr(i)) {
            return Err(fail(i, format!("{}: this FMU has no {what}; value reference {} is 'time', a Float64", f.name(), time_vr(i))));
        }
        i.core.no_such_variables(f, vrs, what)
    })
}

/// Logs through an importer's callback before an instance exists.
unsafe fn refuse_instantiation(logMessage: fmi3LogMessageCallback, environment: fmi3InstanceEnvironment, message: &str) -> fmi3Instance {
    let logger = Logger::new(Box::new(Fmi3Sink { callback: logMessage, environment }), true);
    logger.status(Status::Error, message);
    std::ptr::null_mut()
}

#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateModelExchange(instanceName: fmi3String, instantiationToken: fmi3String, resourcePath: fmi3String, visible: fmi3Boolean, loggingOn: fmi3Boolean, instanceEnvironment: fmi3InstanceEnvironment, logMessage: fmi3LogMessageCallback) -> fmi3Instance {
    refuse_instantiation(logMessage, instanceEnvironment, "fmi3InstantiateModelExchange: this FMU implements Co-Simulation only, not Model Exchange")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3InstantiateScheduledExecution(instanceName: fmi3String, instantiationToken: fmi3String, resourcePath: fmi3String, visible: fmi3Boolean, loggingOn: fmi3Boolean, instanceEnvironment: fmi3InstanceEnvironment, logMessage: fmi3LogMessageCallback, clockUpdate: fmi3ClockUpdateCallback, lockPreemption: fmi3LockPreemptionCallback, unlockPreemption: fmi3UnlockPreemptionCallback) -> fmi3Instance {
    refuse_instantiation(logMessage, instanceEnvironment, "fmi3InstantiateScheduledExecution: this FMU implements Co-Simulation only, not Scheduled Execution")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetFloat32(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, values: *mut fmi3Float32, nValues: size_t) -> fmi3Status {
    absent_type(instance, Function::Get("fmi3GetFloat32"), valueReferences, nValueReferences, nValues, "Float32 variables")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetInt8(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, values: *mut fmi3Int8, nValues: size_t) -> fmi3Status {
    absent_type(instance, Function::Get("fmi3GetInt8"), valueReferences, nValueReferences, nValues, "Int8 variables")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetUInt8(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, values: *mut fmi3UInt8, nValues: size_t) -> fmi3Status {
    absent_type(instance, Function::Get("fmi3GetUInt8"), valueReferences, nValueReferences, nValues, "UInt8 variables")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetInt16(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, values: *mut fmi3Int16, nValues: size_t) -> fmi3Status {
    absent_type(instance, Function::Get("fmi3GetInt16"), valueReferences, nValueReferences, nValues, "Int16 variables")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetUInt16(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, values: *mut fmi3UInt16, nValues: size_t) -> fmi3Status {
    absent_type(instance, Function::Get("fmi3GetUInt16"), valueReferences, nValueReferences, nValues, "UInt16 variables")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetUInt32(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, values: *mut fmi3UInt32, nValues: size_t) -> fmi3Status {
    absent_type(instance, Function::Get("fmi3GetUInt32"), valueReferences, nValueReferences, nValues, "UInt32 variables")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetInt64(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, values: *mut fmi3Int64, nValues: size_t) -> fmi3Status {
    absent_type(instance, Function::Get("fmi3GetInt64"), valueReferences, nValueReferences, nValues, "Int64 variables")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetUInt64(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, values: *mut fmi3UInt64, nValues: size_t) -> fmi3Status {
    absent_type(instance, Function::Get("fmi3GetUInt64"), valueReferences, nValueReferences, nValues, "UInt64 variables")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetString(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, values: *mut fmi3String, nValues: size_t) -> fmi3Status {
    absent_type(instance, Function::Get("fmi3GetString"), valueReferences, nValueReferences, nValues, "String variables")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetFloat32(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, values: *const fmi3Float32, nValues: size_t) -> fmi3Status {
    absent_type(instance, Function::Set("fmi3SetFloat32"), valueReferences, nValueReferences, nValues, "Float32 variables")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetInt8(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, values: *const fmi3Int8, nValues: size_t) -> fmi3Status {
    absent_type(instance, Function::Set("fmi3SetInt8"), valueReferences, nValueReferences, nValues, "Int8 variables")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetUInt8(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, values: *const fmi3UInt8, nValues: size_t) -> fmi3Status {
    absent_type(instance, Function::Set("fmi3SetUInt8"), valueReferences, nValueReferences, nValues, "UInt8 variables")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetInt16(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, values: *const fmi3Int16, nValues: size_t) -> fmi3Status {
    absent_type(instance, Function::Set("fmi3SetInt16"), valueReferences, nValueReferences, nValues, "Int16 variables")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetUInt16(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, values: *const fmi3UInt16, nValues: size_t) -> fmi3Status {
    absent_type(instance, Function::Set("fmi3SetUInt16"), valueReferences, nValueReferences, nValues, "UInt16 variables")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetInt32(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, values: *const fmi3Int32, nValues: size_t) -> fmi3Status {
    absent_type(instance, Function::Set("fmi3SetInt32"), valueReferences, nValueReferences, nValues, "Int32 variables that can be set")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetUInt32(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, values: *const fmi3UInt32, nValues: size_t) -> fmi3Status {
    absent_type(instance, Function::Set("fmi3SetUInt32"), valueReferences, nValueReferences, nValues, "UInt32 variables")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetInt64(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, values: *const fmi3Int64, nValues: size_t) -> fmi3Status {
    absent_type(instance, Function::Set("fmi3SetInt64"), valueReferences, nValueReferences, nValues, "Int64 variables")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetUInt64(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, values: *const fmi3UInt64, nValues: size_t) -> fmi3Status {
    absent_type(instance, Function::Set("fmi3SetUInt64"), valueReferences, nValueReferences, nValues, "UInt64 variables")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetBoolean(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, values: *const fmi3Boolean, nValues: size_t) -> fmi3Status {
    absent_type(instance, Function::Set("fmi3SetBoolean"), valueReferences, nValueReferences, nValues, "Boolean variables that can be set")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetString(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, values: *const fmi3String, nValues: size_t) -> fmi3Status {
    absent_type(instance, Function::Set("fmi3SetString"), valueReferences, nValueReferences, nValues, "String variables")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetBinary(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, valueSizes: *mut size_t, values: *mut fmi3Binary, nValues: size_t) -> fmi3Status {
    absent_type(instance, Function::Get("fmi3GetBinary"), valueReferences, nValueReferences, nValues, "Binary variables")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetBinary(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, valueSizes: *const size_t, values: *const fmi3Binary, nValues: size_t) -> fmi3Status {
    absent_type(instance, Function::Set("fmi3SetBinary"), valueReferences, nValueReferences, nValues, "Binary variables")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetClock(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, values: *mut fmi3Clock) -> fmi3Status {
    absent!(instance, "fmi3GetClock", NO_CLOCKS)
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetClock(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, values: *const fmi3Clock) -> fmi3Status {
    absent!(instance, "fmi3SetClock", NO_CLOCKS)
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetNumberOfVariableDependencies(instance: fmi3Instance, valueReference: fmi3ValueReference, nDependencies: *mut size_t) -> fmi3Status {
    not_provided!(instance, GetNumberOfVariableDependencies, "providesPerElementDependencies = false; modelDescription.xml lists the dependencies")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetVariableDependencies(instance: fmi3Instance, dependent: fmi3ValueReference, elementIndicesOfDependent: *mut size_t, independents: *mut fmi3ValueReference, elementIndicesOfIndependents: *mut size_t, dependencyKinds: *mut fmi3DependencyKind, nDependencies: size_t) -> fmi3Status {
    not_provided!(instance, GetVariableDependencies, "providesPerElementDependencies = false; modelDescription.xml lists the dependencies")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetDirectionalDerivative(instance: fmi3Instance, unknowns: *const fmi3ValueReference, nUnknowns: size_t, knowns: *const fmi3ValueReference, nKnowns: size_t, seed: *const fmi3Float64, nSeed: size_t, sensitivity: *mut fmi3Float64, nSensitivity: size_t) -> fmi3Status {
    not_provided!(instance, GetDirectionalDerivative, "providesDirectionalDerivatives = false")
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetAdjointDerivative(instance: fmi3Instance, unknowns: *const fmi3ValueReference, nUnknowns: size_t, knowns: *const fmi3ValueReference, nKnowns: size_t, seed: *const fmi3Float64, nSeed: size_t, sensitivity: *mut fmi3Float64, nSensitivity: size_t) -> fmi3Status {
    not_provided!(instance, GetAdjointDerivative, "providesAdjointDerivatives = false")
}

#[no_mangle]
pub extern "C" fn fmi3EnterConfigurationMode(instance: fmi3Instance) -> fmi3Status {
    absent!(instance, "fmi3EnterConfigurationMode", NO_CONFIGURATION)
}

#[no_mangle]
pub extern "C" fn fmi3ExitConfigurationMode(instance: fmi3Instance) -> fmi3Status {
    absent!(instance, "fmi3ExitConfigurationMode", NO_CONFIGURATION)
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetIntervalDecimal(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, intervals: *mut fmi3Float64, qualifiers: *mut fmi3IntervalQualifier) -> fmi3Status {
    absent!(instance, "fmi3GetIntervalDecimal", NO_CLOCKS)
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetIntervalFraction(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, counters: *mut fmi3UInt64, resolutions: *mut fmi3UInt64, qualifiers: *mut fmi3IntervalQualifier) -> fmi3Status {
    absent!(instance, "fmi3GetIntervalFraction", NO_CLOCKS)
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetShiftDecimal(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, shifts: *mut fmi3Float64) -> fmi3Status {
    absent!(instance, "fmi3GetShiftDecimal", NO_CLOCKS)
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetShiftFraction(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, counters: *mut fmi3UInt64, resolutions: *mut fmi3UInt64) -> fmi3Status {
    absent!(instance, "fmi3GetShiftFraction", NO_CLOCKS)
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetIntervalDecimal(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, intervals: *const fmi3Float64) -> fmi3Status {
    absent!(instance, "fmi3SetIntervalDecimal", NO_CLOCKS)
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetIntervalFraction(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, counters: *const fmi3UInt64, resolutions: *const fmi3UInt64) -> fmi3Status {
    absent!(instance, "fmi3SetIntervalFraction", NO_CLOCKS)
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetShiftDecimal(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, shifts: *const fmi3Float64) -> fmi3Status {
    absent!(instance, "fmi3SetShiftDecimal", NO_CLOCKS)
}

#[no_mangle]
pub unsafe extern "C" fn fmi3SetShiftFraction(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, counters: *const fmi3UInt64, resolutions: *const fmi3UInt64) -> fmi3Status {
    absent!(instance, "fmi3SetShiftFraction", NO_CLOCKS)
}

#[no_mangle]
pub extern "C" fn fmi3EvaluateDiscreteStates(instance: fmi3Instance) -> fmi3Status {
    not_provided!(instance, EvaluateDiscreteStates, "providesEvaluateDiscreteStates = false")
}

#[no_mangle]
pub extern "C" fn fmi3EnterContinuousTimeMode(instance: fmi3Instance) -> fmi3Status {
    absent!(instance, "fmi3EnterContinuousTimeMode", NO_MODEL_EXCHANGE)
}

#[no_mangle]
pub extern "C" fn fmi3CompletedIntegratorStep(instance: fmi3Instance, noSetFMUStatePriorToCurrentPoint: fmi3Boolean, enterEventMode: *mut fmi3Boolean, terminateSimulation: *mut fmi3Boolean) -> fmi3Status {
    absent!(instance, "fmi3CompletedIntegratorStep", NO_MODEL_EXCHANGE)
}

#[no_mangle]
pub extern "C" fn fmi3SetTime(instance: fmi3Instance, time: fmi3Float64) -> fmi3Status {
    absent!(instance, "fmi3SetTime", NO_MODEL_EXCHANGE)
}

#[no_mangle]
pub extern "C" fn fmi3SetContinuousStates(instance: fmi3Instance, continuousStates: *const fmi3Float64, nContinuousStates: size_t) -> fmi3Status {
    absent!(instance, "fmi3SetContinuousStates", NO_MODEL_EXCHANGE)
}

#[no_mangle]
pub extern "C" fn fmi3GetContinuousStateDerivatives(instance: fmi3Instance, derivatives: *mut fmi3Float64, nContinuousStates: size_t) -> fmi3Status {
    absent!(instance, "fmi3GetContinuousStateDerivatives", NO_MODEL_EXCHANGE)
}

#[no_mangle]
pub extern "C" fn fmi3GetEventIndicators(instance: fmi3Instance, eventIndicators: *mut fmi3Float64, nEventIndicators: size_t) -> fmi3Status {
    absent!(instance, "fmi3GetEventIndicators", NO_MODEL_EXCHANGE)
}

#[no_mangle]
pub extern "C" fn fmi3GetContinuousStates(instance: fmi3Instance, continuousStates: *mut fmi3Float64, nContinuousStates: size_t) -> fmi3Status {
    absent!(instance, "fmi3GetContinuousStates", NO_MODEL_EXCHANGE)
}

#[no_mangle]
pub extern "C" fn fmi3GetNominalsOfContinuousStates(instance: fmi3Instance, nominals: *mut fmi3Float64, nContinuousStates: size_t) -> fmi3Status {
    absent!(instance, "fmi3GetNominalsOfContinuousStates", NO_MODEL_EXCHANGE)
}

#[no_mangle]
pub extern "C" fn fmi3GetNumberOfEventIndicators(instance: fmi3Instance, nEventIndicators: *mut size_t) -> fmi3Status {
    absent!(instance, "fmi3GetNumberOfEventIndicators", NO_MODEL_EXCHANGE)
}

#[no_mangle]
pub extern "C" fn fmi3GetNumberOfContinuousStates(instance: fmi3Instance, nContinuousStates: *mut size_t) -> fmi3Status {
    absent!(instance, "fmi3GetNumberOfContinuousStates", NO_MODEL_EXCHANGE)
}

#[no_mangle]
pub unsafe extern "C" fn fmi3GetOutputDerivatives(instance: fmi3Instance, valueReferences: *const fmi3ValueReference, nValueReferences: size_t, orders: *const fmi3Int32, values: *mut fmi3Float64, nValues: size_t) -> fmi3Status {
    not_provided!(instance, GetOutputDerivatives, "maxOutputDerivativeOrder = 0")
}

#[no_mangle]
pub extern "C" fn fmi3ActivateModelPartition(instance: fmi3Instance, clockReference: fmi3ValueReference, activationTime: fmi3Float64) -> fmi3Status {
    absent!(instance, "fmi3ActivateModelPartition", "this FMU implements Co-Simulation only, not Scheduled Execution")
}
