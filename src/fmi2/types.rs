//! The C types of fmi2TypesPlatform.h and fmi2FunctionTypes.h.
//!
//! The enums are plain `int` aliases: a value a C caller passes in is never
//! undefined behaviour here, whatever it is. cbindgen emits only the
//! function declarations; the types come from the standard headers.

#![allow(non_camel_case_types, non_snake_case)]

use libc::{c_char, c_int, c_uint, c_void, size_t};

pub type fmi2Component = *mut c_void;
pub type fmi2ComponentEnvironment = *mut c_void;
pub type fmi2FMUstate = *mut c_void;
pub type fmi2ValueReference = c_uint;
pub type fmi2Real = f64;
pub type fmi2Integer = c_int;
pub type fmi2Boolean = c_int;
pub type fmi2Char = c_char;
pub type fmi2String = *const fmi2Char;
pub type fmi2Byte = c_char;
pub type fmi2Status = c_int;
pub type fmi2Type = c_int;
pub type fmi2StatusKind = c_int;

pub const FMI2_TRUE: fmi2Boolean = 1;
pub const FMI2_FALSE: fmi2Boolean = 0;

pub const FMI2_CO_SIMULATION: fmi2Type = 1;

pub const FMI2_DO_STEP_STATUS: fmi2StatusKind = 0;
pub const FMI2_PENDING_STATUS: fmi2StatusKind = 1;
pub const FMI2_LAST_SUCCESSFUL_TIME: fmi2StatusKind = 2;
pub const FMI2_TERMINATED: fmi2StatusKind = 3;

pub use crate::fmi::Status;

pub type fmi2CallbackLogger = Option<
    unsafe extern "C" fn(
        component_environment: fmi2ComponentEnvironment,
        instance_name: fmi2String,
        status: fmi2Status,
        category: fmi2String,
        message: fmi2String,
        ...
    ),
>;
pub type fmi2CallbackAllocateMemory = Option<unsafe extern "C" fn(nobj: size_t, size: size_t) -> *mut c_void>;
pub type fmi2CallbackFreeMemory = Option<unsafe extern "C" fn(obj: *mut c_void)>;
pub type fmi2StepFinished = Option<unsafe extern "C" fn(component_environment: fmi2ComponentEnvironment, status: fmi2Status)>;

#[repr(C)]
pub struct fmi2CallbackFunctions {
    pub logger: fmi2CallbackLogger,
    pub allocateMemory: fmi2CallbackAllocateMemory,
    pub freeMemory: fmi2CallbackFreeMemory,
    pub stepFinished: fmi2StepFinished,
    pub componentEnvironment: fmi2ComponentEnvironment,
}

#[repr(C)]
pub struct fmi2EventInfo {
    pub newDiscreteStatesNeeded: fmi2Boolean,
    pub terminateSimulation: fmi2Boolean,
    pub nominalsOfContinuousStatesChanged: fmi2Boolean,
    pub valuesOfContinuousStatesChanged: fmi2Boolean,
    pub nextEventTimeDefined: fmi2Boolean,
    pub nextEventTime: fmi2Real,
}

/// The importer's fmi2CallbackLogger with its environment and the
/// instance's name, as the shared logger's sink.
pub struct Fmi2Sink {
    pub callback: fmi2CallbackLogger,
    pub environment: fmi2ComponentEnvironment,
    pub instance_name: std::ffi::CString,
}

// The environment pointer is the importer's, only handed back to its logger.
unsafe impl Send for Fmi2Sink {}

impl crate::fmi::logging::Sink for Fmi2Sink {
    fn emit(&self, status: Status, category: &str, message: &str) {
        let Some(callback) = self.callback else { return };
        // The logger takes a printf format in which `#<type><vr>#` names
        // a variable (FMI 2.0.4 section 2.1.5): escape '%' and '#'.
        let text = std::ffi::CString::new(message.replace('%', "%%").replace('#', "##").replace('\0', "")).unwrap_or_default();
        let cat = std::ffi::CString::new(category).unwrap_or_default();
        // SAFETY: the importer promised a valid logger for the instance's
        // lifetime; every pointer passed is a valid NUL-terminated string.
        unsafe { callback(self.environment, self.instance_name.as_ptr(), status.raw(), cat.as_ptr(), text.as_ptr()) };
    }
}
