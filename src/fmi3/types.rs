//! The C types of fmi3PlatformTypes.h and fmi3FunctionTypes.h.
//!
//! Booleans are taken as bytes and enums as plain `int`: a value a C
//! caller passes in is never undefined behaviour here, whatever it is.
//! cbindgen emits only the function declarations; the types come from the
//! standard headers.

#![allow(non_camel_case_types, non_snake_case)]

use libc::{c_char, c_int, c_void};

pub use crate::fmi::Status;

pub type fmi3Instance = *mut c_void;
pub type fmi3InstanceEnvironment = *mut c_void;
pub type fmi3FMUState = *mut c_void;
pub type fmi3ValueReference = u32;
pub type fmi3Float32 = f32;
pub type fmi3Float64 = f64;
pub type fmi3Int8 = i8;
pub type fmi3UInt8 = u8;
pub type fmi3Int16 = i16;
pub type fmi3UInt16 = u16;
pub type fmi3Int32 = i32;
pub type fmi3UInt32 = u32;
pub type fmi3Int64 = i64;
pub type fmi3UInt64 = u64;
/// C's `bool`, read as a byte (any non-zero is true).
pub type fmi3Boolean = u8;
pub type fmi3Char = c_char;
pub type fmi3String = *const fmi3Char;
pub type fmi3Byte = u8;
pub type fmi3Binary = *const fmi3Byte;
pub type fmi3Clock = u8;
pub type fmi3Status = c_int;
pub type fmi3DependencyKind = c_int;
pub type fmi3IntervalQualifier = c_int;

pub const FMI3_TRUE: fmi3Boolean = 1;
pub const FMI3_FALSE: fmi3Boolean = 0;

pub type fmi3LogMessageCallback =
    Option<unsafe extern "C" fn(instance_environment: fmi3InstanceEnvironment, status: fmi3Status, category: fmi3String, message: fmi3String)>;
pub type fmi3ClockUpdateCallback = Option<unsafe extern "C" fn(instance_environment: fmi3InstanceEnvironment)>;
pub type fmi3IntermediateUpdateCallback = Option<
    unsafe extern "C" fn(
        instance_environment: fmi3InstanceEnvironment,
        intermediate_update_time: fmi3Float64,
        intermediate_variable_set_requested: fmi3Boolean,
        intermediate_variable_get_allowed: fmi3Boolean,
        intermediate_step_finished: fmi3Boolean,
        can_return_early: fmi3Boolean,
        early_return_requested: *mut fmi3Boolean,
        early_return_time: *mut fmi3Float64,
    ),
>;
pub type fmi3LockPreemptionCallback = Option<unsafe extern "C" fn()>;
pub type fmi3UnlockPreemptionCallback = Option<unsafe extern "C" fn()>;

/// The importer's fmi3LogMessageCallback with its environment, as the
/// shared logger's sink (FMI 3.0 messages are plain text, not formats).
pub struct Fmi3Sink {
    pub callback: fmi3LogMessageCallback,
    pub environment: fmi3InstanceEnvironment,
}

// The environment pointer is the importer's, only handed back to its callbacks.
unsafe impl Send for Fmi3Sink {}

impl crate::fmi::logging::Sink for Fmi3Sink {
    fn emit(&self, status: Status, category: &str, message: &str) {
        let Some(callback) = self.callback else { return };
        let text = std::ffi::CString::new(message.replace('\0', "")).unwrap_or_default();
        let cat = std::ffi::CString::new(category).unwrap_or_default();
        // SAFETY: the importer promised a valid callback for the instance's
        // lifetime; every pointer passed is a valid NUL-terminated string.
        unsafe { callback(self.environment, status.raw(), cat.as_ptr(), text.as_ptr()) };
    }
}
