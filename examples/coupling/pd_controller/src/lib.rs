//! `PDController.fmu`: a sampled PD (PID with anti-windup) controller of a
//! hub angle, an FMI 2.0 co-simulation unit. It is the partner of
//! `RotatingBeamImpact.fmu` in the coupling example (examples/coupling/):
//! libcosim couples the two through an OSP system structure.
//!
//! **The law.** At the start `t` of each `fmi2DoStep(t, h)` the controller
//! samples its inputs `theta`, `theta_dot` and computes
//!
//! ```text
//! e = r(t) - theta
//! v = Kp e + Kd (r'(t) - theta_dot) + Ki I
//! torque = clamp(v, -torque_max, torque_max)
//! ```
//!
//! and then integrates `I += e h` unless the output saturates with the
//! error pushing it further (clamping anti-windup). The reference `r(t)`
//! slews from `theta_start` to `theta_ref` over `T_slew` seconds along the
//! minimum-jerk quintic `10 s^3 - 15 s^4 + 6 s^5`, `s = (t - t0) / T_slew`
//! (a step at `t0` when `T_slew = 0`). The output `torque` is this sample,
//! held until the next step: a digital controller whose result is applied
//! one sample after its inputs were read. Before the first step (in
//! initialization mode, and between `fmi2ExitInitializationMode` and the
//! first `fmi2DoStep`) the outputs are the law at the start time with the
//! current inputs and `I = 0`, so a master that propagates initial values
//! (libcosim does) hands the plant a torque for its first step.
//!
//! Ordering: stepped after the plant (Jacobi, libcosim's fixed-step
//! algorithm), the plant's torque over `[t_k, t_k+1]` is the law at
//! `t_k-1`; stepped before it with `theta(t_k)` set first (Gauss-Seidel),
//! the law at `t_k`.
//!
//! The Python mirror of this law, `examples/coupling/pd_slew.py`
//! (`Controller`), performs the same floating-point operations in the same
//! order, so the two give the same torques bit for bit.
//!
//! Dependencies: libc only; the FMI 2.0 C types are declared here.

// `!(x > 0.0)` is meant: it refuses NaN too.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use std::ffi::{c_char, c_int, c_void, CStr};
use std::ptr;

use libc::size_t;

/// The GUID of modelDescription.xml (the two must agree).
pub const GUID: &str = "{3c1d2a7e-8b4f-4e09-a6c5-5d0e9f1b7a42}";
const MODEL_IDENTIFIER: &str = "PDController";

type Status = c_int;
const OK: Status = 0;
const WARNING: Status = 1;
const DISCARD: Status = 2;
const ERROR: Status = 3;

type Logger = unsafe extern "C" fn(*mut c_void, *const c_char, Status, *const c_char, *const c_char, ...);

/// `fmi2CallbackFunctions`.
#[repr(C)]
pub struct CallbackFunctions {
    logger: Option<Logger>,
    allocate_memory: Option<unsafe extern "C" fn(size_t, size_t) -> *mut c_void>,
    free_memory: Option<unsafe extern "C" fn(*mut c_void)>,
    step_finished: Option<unsafe extern "C" fn(*mut c_void, Status)>,
    component_environment: *mut c_void,
}

// ------------------------------------------------------------ variables

/// Value references, in modelDescription.xml's order.
const VR_KP: u32 = 0;
const VR_KD: u32 = 1;
const VR_KI: u32 = 2;
const VR_THETA_REF: u32 = 3;
const VR_THETA_START: u32 = 4;
const VR_T_SLEW: u32 = 5;
const VR_TORQUE_MAX: u32 = 6;
const VR_THETA: u32 = 7;
const VR_THETA_DOT: u32 = 8;
const VR_TORQUE: u32 = 9;
const VR_THETA_R: u32 = 10;
const VR_INTEGRAL: u32 = 11;
const N_PARAMETERS: u32 = 7;

/// The gains and the slew (fixed parameters; modelDescription.xml's start values).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Parameters {
    kp: f64,
    kd: f64,
    ki: f64,
    theta_ref: f64,
    theta_start: f64,
    t_slew: f64,
    torque_max: f64,
}

const DEFAULTS: Parameters =
    Parameters { kp: 50.0, kd: 6.0, ki: 0.0, theta_ref: 0.02, theta_start: -0.5, t_slew: 0.6, torque_max: 10.0 };

impl Parameters {
    fn slot(&mut self, vr: u32) -> Option<&mut f64> {
        Some(match vr {
            VR_KP => &mut self.kp,
            VR_KD => &mut self.kd,
            VR_KI => &mut self.ki,
            VR_THETA_REF => &mut self.theta_ref,
            VR_THETA_START => &mut self.theta_start,
            VR_T_SLEW => &mut self.t_slew,
            VR_TORQUE_MAX => &mut self.torque_max,
            _ => return None,
        })
    }

    fn get(&self, vr: u32) -> Option<f64> {
        let mut copy = *self;
        copy.slot(vr).map(|x| *x)
    }

    /// Why the parameters cannot run, if they cannot.
    fn check(&self) -> Result<(), String> {
        for (name, value) in [("Kp", self.kp), ("Kd", self.kd), ("Ki", self.ki), ("theta_ref", self.theta_ref), ("theta_start", self.theta_start), ("T_slew", self.t_slew)] {
            if !value.is_finite() {
                return Err(format!("{name} = {value}: must be finite"));
            }
        }
        if self.t_slew < 0.0 {
            return Err(format!("T_slew = {}: must be >= 0", self.t_slew));
        }
        if !(self.torque_max > 0.0) {
            return Err(format!("torque_max = {}: must be > 0 (may be infinite)", self.torque_max));
        }
        Ok(())
    }
}

// ------------------------------------------------------------ the controller

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    Instantiated,
    Initialization,
    Stepping,
    Terminated,
    Error,
}

/// Everything a run is (an FMU state is a copy of it).
#[derive(Clone, Debug, PartialEq)]
struct Controller {
    p: Parameters,
    mode: Mode,
    /// Start time of the experiment: the slew's t0.
    t_start: f64,
    /// The current communication point.
    time: f64,
    theta: f64,
    theta_dot: f64,
    /// Whether a step has sampled the inputs (else the outputs follow them).
    sampled: bool,
    torque: f64,
    theta_r: f64,
    /// Integral of the error up to `time`.
    integral: f64,
}

/// One sample of the law.
struct Sample {
    torque: f64,
    reference: f64,
    error: f64,
    /// The integral holds still (anti-windup).
    frozen: bool,
}

impl Controller {
    fn new() -> Self {
        Controller {
            p: DEFAULTS,
            mode: Mode::Instantiated,
            t_start: 0.0,
            time: 0.0,
            theta: 0.0,
            theta_dot: 0.0,
            sampled: false,
            torque: 0.0,
            theta_r: 0.0,
            integral: 0.0,
        }
    }

    /// The reference and its rate at `t`.
    fn reference(&self, t: f64) -> (f64, f64) {
        let p = &self.p;
        if !(p.t_slew > 0.0) {
            return (p.theta_ref, 0.0);
        }
        let s = ((t - self.t_start) / p.t_slew).clamp(0.0, 1.0);
        if s == 1.0 {
            return (p.theta_ref, 0.0);
        }
        let d = p.theta_ref - p.theta_start;
        let shape = s * s * s * (10.0 + s * (-15.0 + s * 6.0));
        let rate = 30.0 * s * s * (1.0 - s) * (1.0 - s) / p.t_slew;
        (p.theta_start + d * shape, d * rate)
    }

    /// The law at `t` with the current inputs and integral.
    fn law(&self, t: f64) -> Sample {
        let p = &self.p;
        let (r, r_dot) = self.reference(t);
        let e = r - self.theta;
        let v = p.kp * e + p.kd * (r_dot - self.theta_dot) + p.ki * self.integral;
        let torque = v.max(-p.torque_max).min(p.torque_max);
        Sample { torque, reference: r, error: e, frozen: torque != v && e * v > 0.0 }
    }

    fn do_step(&mut self, t: f64, h: f64) {
        let s = self.law(t);
        self.torque = s.torque;
        self.theta_r = s.reference;
        if !s.frozen {
            self.integral += s.error * h;
        }
        self.sampled = true;
        self.time = t + h;
    }

    fn get(&self, vr: u32) -> Option<f64> {
        if vr < N_PARAMETERS {
            return self.p.get(vr);
        }
        let unsampled = || self.law(self.t_start);
        Some(match vr {
            VR_THETA => self.theta,
            VR_THETA_DOT => self.theta_dot,
            VR_TORQUE if self.sampled => self.torque,
            VR_TORQUE => unsampled().torque,
            VR_THETA_R if self.sampled => self.theta_r,
            VR_THETA_R => unsampled().reference,
            VR_INTEGRAL => self.integral,
            _ => return None,
        })
    }

    fn set(&mut self, vr: u32, value: f64) -> Result<(), String> {
        if !value.is_finite() && vr != VR_TORQUE_MAX {
            return Err(format!("value reference {vr}: {value} is not finite"));
        }
        match vr {
            VR_THETA => self.theta = value,
            VR_THETA_DOT => self.theta_dot = value,
            _ if vr < N_PARAMETERS => {
                if !matches!(self.mode, Mode::Instantiated | Mode::Initialization) {
                    return Err(format!("value reference {vr} is a fixed parameter: set it before fmi2ExitInitializationMode"));
                }
                if value.is_nan() {
                    return Err(format!("value reference {vr}: NaN"));
                }
                if let Some(slot) = self.p.slot(vr) {
                    *slot = value;
                }
            }
            VR_TORQUE | VR_THETA_R | VR_INTEGRAL => return Err(format!("value reference {vr} is an output: it cannot be set")),
            _ => return Err(format!("no Real variable has value reference {vr}")),
        }
        Ok(())
    }

    // -- FMU state serialisation: a version, the mode, the flag, then every f64.

    fn floats(&self) -> [f64; 14] {
        let p = &self.p;
        [p.kp, p.kd, p.ki, p.theta_ref, p.theta_start, p.t_slew, p.torque_max, self.t_start, self.time, self.theta, self.theta_dot, self.torque, self.theta_r, self.integral]
    }

    fn serialize(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(SERIALIZED_SIZE);
        out.extend_from_slice(&STATE_VERSION.to_le_bytes());
        out.push(self.mode as u8);
        out.push(self.sampled as u8);
        for x in self.floats() {
            out.extend_from_slice(&x.to_le_bytes());
        }
        out
    }

    fn deserialize(bytes: &[u8]) -> Result<Self, String> {
        if bytes.len() != SERIALIZED_SIZE {
            return Err(format!("serialized state of {} bytes, expected {SERIALIZED_SIZE}", bytes.len()));
        }
        let version = u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]);
        if version != STATE_VERSION {
            return Err(format!("serialized state version {version}, this FMU reads {STATE_VERSION}"));
        }
        let mode = match bytes[4] {
            0 => Mode::Instantiated,
            1 => Mode::Initialization,
            2 => Mode::Stepping,
            3 => Mode::Terminated,
            m => return Err(format!("serialized state: mode {m} unknown")),
        };
        let sampled = match bytes[5] {
            0 => false,
            1 => true,
            b => return Err(format!("serialized state: flag {b} is not a Boolean")),
        };
        let mut x = [0.0; 14];
        for (i, chunk) in bytes[6..].chunks_exact(8).enumerate() {
            let mut b = [0u8; 8];
            b.copy_from_slice(chunk);
            x[i] = f64::from_le_bytes(b);
        }
        let p = Parameters { kp: x[0], kd: x[1], ki: x[2], theta_ref: x[3], theta_start: x[4], t_slew: x[5], torque_max: x[6] };
        p.check().map_err(|m| format!("serialized state: {m}"))?;
        if x[7..].iter().any(|v| !v.is_finite()) {
            return Err("serialized state: a non-finite value".into());
        }
        Ok(Controller { p, mode, sampled, t_start: x[7], time: x[8], theta: x[9], theta_dot: x[10], torque: x[11], theta_r: x[12], integral: x[13] })
    }
}

const STATE_VERSION: u32 = 1;
const SERIALIZED_SIZE: usize = 4 + 2 + 14 * 8;

// ------------------------------------------------------------ the instance

struct Instance {
    c: Controller,
    name: Vec<u8>,
    logger: Option<Logger>,
    environment: *mut c_void,
    logging_on: bool,
}

impl Instance {
    /// Sends `message` to the importer's logger (always for errors).
    fn log(&self, status: Status, category: &str, message: &str) {
        if status == OK && !self.logging_on {
            return;
        }
        let Some(logger) = self.logger else { return };
        let mut name = self.name.clone();
        name.push(0);
        let category = cstring(category);
        let message = cstring(message);
        // The message goes through "%s": a '%' in it is never a directive.
        unsafe { logger(self.environment, name.as_ptr().cast(), status, category.as_ptr().cast(), c"%s".as_ptr(), message.as_ptr().cast::<c_char>()) };
    }

    fn fail(&mut self, message: &str) -> Status {
        self.log(ERROR, "logStatusError", message);
        ERROR
    }
}

fn cstring(s: &str) -> Vec<u8> {
    let mut v: Vec<u8> = s.bytes().filter(|&b| b != 0).collect();
    v.push(0);
    v
}

unsafe fn instance<'a>(c: *mut c_void) -> Option<&'a mut Instance> {
    (c as *mut Instance).as_mut()
}

unsafe fn slice<'a, T>(p: *const T, n: size_t) -> Option<&'a [T]> {
    if n == 0 {
        Some(&[])
    } else if p.is_null() {
        None
    } else {
        Some(std::slice::from_raw_parts(p, n))
    }
}

unsafe fn slice_mut<'a, T>(p: *mut T, n: size_t) -> Option<&'a mut [T]> {
    if n == 0 {
        Some(&mut [])
    } else if p.is_null() {
        None
    } else {
        Some(std::slice::from_raw_parts_mut(p, n))
    }
}

/// Runs `f` on the instance, or says why not; a call in error mode fails.
unsafe fn with(c: *mut c_void, what: &str, f: impl FnOnce(&mut Instance) -> Status) -> Status {
    let Some(inst) = instance(c) else { return ERROR };
    if inst.c.mode == Mode::Error {
        return inst.fail(&format!("{what}: the instance is in the error state (only fmi2FreeInstance and fmi2Reset are allowed)"));
    }
    let status = f(inst);
    if status == ERROR {
        inst.c.mode = Mode::Error;
    }
    status
}

// ------------------------------------------------------------ FMI 2.0 functions

#[no_mangle]
pub extern "C" fn fmi2GetTypesPlatform() -> *const c_char {
    c"default".as_ptr()
}

#[no_mangle]
pub extern "C" fn fmi2GetVersion() -> *const c_char {
    c"2.0".as_ptr()
}

/// # Safety
/// FMI 2.0: `c` from fmi2Instantiate, `categories` `n` C strings.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetDebugLogging(c: *mut c_void, logging_on: c_int, n: size_t, categories: *const *const c_char) -> Status {
    with(c, "fmi2SetDebugLogging", |inst| {
        let Some(cats) = slice(categories, n) else { return inst.fail("fmi2SetDebugLogging: categories is NULL") };
        for &cat in cats {
            if cat.is_null() {
                return inst.fail("fmi2SetDebugLogging: a NULL category");
            }
            let name = CStr::from_ptr(cat).to_string_lossy();
            if name != "logStatusError" && name != "logAll" {
                return inst.fail(&format!("fmi2SetDebugLogging: unknown log category '{name}'"));
            }
        }
        inst.logging_on = logging_on != 0;
        OK
    })
}

/// # Safety
/// FMI 2.0: C strings or NULL, `functions` a valid callback table.
#[no_mangle]
pub unsafe extern "C" fn fmi2Instantiate(
    name: *const c_char,
    kind: c_int,
    guid: *const c_char,
    _resource_location: *const c_char,
    functions: *const CallbackFunctions,
    _visible: c_int,
    logging_on: c_int,
) -> *mut c_void {
    let (logger, environment) = match functions.as_ref() {
        Some(f) => (f.logger, f.component_environment),
        None => (None, ptr::null_mut()),
    };
    let name_bytes = if name.is_null() { b"PDController".to_vec() } else { CStr::from_ptr(name).to_bytes().to_vec() };
    let inst = Instance { c: Controller::new(), name: name_bytes, logger, environment, logging_on: logging_on != 0 };
    if kind != 1 {
        inst.log(ERROR, "logStatusError", &format!("fmi2Instantiate: {MODEL_IDENTIFIER} is a co-simulation unit only (fmuType {kind})"));
        return ptr::null_mut();
    }
    let given = if guid.is_null() { String::new() } else { CStr::from_ptr(guid).to_string_lossy().into_owned() };
    if given != GUID {
        inst.log(ERROR, "logStatusError", &format!("fmi2Instantiate: GUID {given} is not this FMU's {GUID}"));
        return ptr::null_mut();
    }
    Box::into_raw(Box::new(inst)).cast()
}

/// # Safety
/// `c` from fmi2Instantiate or NULL; not used afterwards.
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeInstance(c: *mut c_void) {
    if !c.is_null() {
        drop(Box::from_raw(c as *mut Instance));
    }
}

/// # Safety
/// `c` from fmi2Instantiate.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetupExperiment(c: *mut c_void, _tolerance_defined: c_int, _tolerance: f64, start: f64, _stop_defined: c_int, _stop: f64) -> Status {
    with(c, "fmi2SetupExperiment", |inst| {
        if inst.c.mode != Mode::Instantiated {
            return inst.fail("fmi2SetupExperiment: only right after fmi2Instantiate or fmi2Reset");
        }
        if !start.is_finite() {
            return inst.fail(&format!("fmi2SetupExperiment: start time {start} is not finite"));
        }
        inst.c.t_start = start;
        inst.c.time = start;
        OK
    })
}

/// # Safety
/// `c` from fmi2Instantiate.
#[no_mangle]
pub unsafe extern "C" fn fmi2EnterInitializationMode(c: *mut c_void) -> Status {
    with(c, "fmi2EnterInitializationMode", |inst| {
        if inst.c.mode != Mode::Instantiated {
            return inst.fail("fmi2EnterInitializationMode: only once, after fmi2Instantiate or fmi2SetupExperiment");
        }
        inst.c.mode = Mode::Initialization;
        OK
    })
}

/// # Safety
/// `c` from fmi2Instantiate.
#[no_mangle]
pub unsafe extern "C" fn fmi2ExitInitializationMode(c: *mut c_void) -> Status {
    with(c, "fmi2ExitInitializationMode", |inst| {
        if inst.c.mode != Mode::Initialization {
            return inst.fail("fmi2ExitInitializationMode: not in initialization mode");
        }
        if let Err(m) = inst.c.p.check() {
            return inst.fail(&format!("fmi2ExitInitializationMode: {m}"));
        }
        inst.c.mode = Mode::Stepping;
        OK
    })
}

/// # Safety
/// `c` from fmi2Instantiate.
#[no_mangle]
pub unsafe extern "C" fn fmi2Terminate(c: *mut c_void) -> Status {
    with(c, "fmi2Terminate", |inst| {
        if inst.c.mode != Mode::Stepping {
            return inst.fail("fmi2Terminate: only after fmi2ExitInitializationMode");
        }
        inst.c.mode = Mode::Terminated;
        OK
    })
}

/// # Safety
/// `c` from fmi2Instantiate.
#[no_mangle]
pub unsafe extern "C" fn fmi2Reset(c: *mut c_void) -> Status {
    let Some(inst) = instance(c) else { return ERROR };
    inst.c = Controller::new();
    OK
}

/// # Safety
/// FMI 2.0: arrays of `n` elements.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetReal(c: *mut c_void, vr: *const u32, n: size_t, value: *mut f64) -> Status {
    with(c, "fmi2GetReal", |inst| {
        let (Some(vr), Some(value)) = (slice(vr, n), slice_mut(value, n)) else { return inst.fail("fmi2GetReal: NULL array") };
        if inst.c.mode == Mode::Instantiated {
            return inst.fail("fmi2GetReal: not before fmi2EnterInitializationMode");
        }
        for (r, v) in vr.iter().zip(value.iter_mut()) {
            match inst.c.get(*r) {
                Some(x) => *v = x,
                None => return inst.fail(&format!("fmi2GetReal: no Real variable has value reference {r}")),
            }
        }
        OK
    })
}

/// # Safety
/// FMI 2.0: arrays of `n` elements.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetReal(c: *mut c_void, vr: *const u32, n: size_t, value: *const f64) -> Status {
    with(c, "fmi2SetReal", |inst| {
        let (Some(vr), Some(value)) = (slice(vr, n), slice(value, n)) else { return inst.fail("fmi2SetReal: NULL array") };
        if inst.c.mode == Mode::Terminated {
            return inst.fail("fmi2SetReal: the instance is terminated");
        }
        for (r, v) in vr.iter().zip(value) {
            if let Err(m) = inst.c.set(*r, *v) {
                return inst.fail(&format!("fmi2SetReal: {m}"));
            }
        }
        OK
    })
}

/// No Integer, Boolean or String variables: only empty calls succeed.
unsafe fn none_of_type(c: *mut c_void, what: &str, n: size_t, vr: *const u32) -> Status {
    with(c, what, |inst| {
        let Some(vr) = slice(vr, n) else { return inst.fail(&format!("{what}: NULL array")) };
        match vr.first() {
            None => OK,
            Some(r) => inst.fail(&format!("{what}: value reference {r}: {MODEL_IDENTIFIER} has no variable of this type")),
        }
    })
}

/// # Safety
/// FMI 2.0 arrays.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetInteger(c: *mut c_void, vr: *const u32, n: size_t, _value: *mut c_int) -> Status {
    none_of_type(c, "fmi2GetInteger", n, vr)
}

/// # Safety
/// FMI 2.0 arrays.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetInteger(c: *mut c_void, vr: *const u32, n: size_t, _value: *const c_int) -> Status {
    none_of_type(c, "fmi2SetInteger", n, vr)
}

/// # Safety
/// FMI 2.0 arrays.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetBoolean(c: *mut c_void, vr: *const u32, n: size_t, _value: *mut c_int) -> Status {
    none_of_type(c, "fmi2GetBoolean", n, vr)
}

/// # Safety
/// FMI 2.0 arrays.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetBoolean(c: *mut c_void, vr: *const u32, n: size_t, _value: *const c_int) -> Status {
    none_of_type(c, "fmi2SetBoolean", n, vr)
}

/// # Safety
/// FMI 2.0 arrays.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetString(c: *mut c_void, vr: *const u32, n: size_t, _value: *mut *const c_char) -> Status {
    none_of_type(c, "fmi2GetString", n, vr)
}

/// # Safety
/// FMI 2.0 arrays.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetString(c: *mut c_void, vr: *const u32, n: size_t, _value: *const *const c_char) -> Status {
    none_of_type(c, "fmi2SetString", n, vr)
}

/// # Safety
/// `state` a valid pointer.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetFMUstate(c: *mut c_void, state: *mut *mut c_void) -> Status {
    with(c, "fmi2GetFMUstate", |inst| {
        let Some(out) = state.as_mut() else { return inst.fail("fmi2GetFMUstate: NULL") };
        let copy = Box::new(inst.c.clone());
        if let Some(old) = (*out as *mut Controller).as_mut() {
            *old = *copy;
        } else {
            *out = Box::into_raw(copy).cast();
        }
        OK
    })
}

/// # Safety
/// `state` from fmi2GetFMUstate or fmi2DeSerializeFMUstate.
#[no_mangle]
pub unsafe extern "C" fn fmi2SetFMUstate(c: *mut c_void, state: *mut c_void) -> Status {
    let Some(inst) = instance(c) else { return ERROR };
    match (state as *const Controller).as_ref() {
        Some(s) => {
            inst.c = s.clone();
            OK
        }
        None => inst.fail("fmi2SetFMUstate: NULL state"),
    }
}

/// # Safety
/// `state` points to a state from fmi2GetFMUstate, or to NULL.
#[no_mangle]
pub unsafe extern "C" fn fmi2FreeFMUstate(c: *mut c_void, state: *mut *mut c_void) -> Status {
    if instance(c).is_none() {
        return ERROR;
    }
    if let Some(s) = state.as_mut() {
        if !s.is_null() {
            drop(Box::from_raw(*s as *mut Controller));
            *s = ptr::null_mut();
        }
    }
    OK
}

/// # Safety
/// `state` from fmi2GetFMUstate; `size` valid.
#[no_mangle]
pub unsafe extern "C" fn fmi2SerializedFMUstateSize(c: *mut c_void, state: *mut c_void, size: *mut size_t) -> Status {
    with(c, "fmi2SerializedFMUstateSize", |inst| {
        match (state.is_null(), size.as_mut()) {
            (false, Some(s)) => {
                *s = SERIALIZED_SIZE;
                OK
            }
            _ => inst.fail("fmi2SerializedFMUstateSize: NULL"),
        }
    })
}

/// # Safety
/// `state` from fmi2GetFMUstate; `bytes` of `size` bytes.
#[no_mangle]
pub unsafe extern "C" fn fmi2SerializeFMUstate(c: *mut c_void, state: *mut c_void, bytes: *mut c_char, size: size_t) -> Status {
    with(c, "fmi2SerializeFMUstate", |inst| {
        let Some(s) = (state as *const Controller).as_ref() else { return inst.fail("fmi2SerializeFMUstate: NULL state") };
        if size < SERIALIZED_SIZE || bytes.is_null() {
            return inst.fail(&format!("fmi2SerializeFMUstate: a buffer of {size} bytes, {SERIALIZED_SIZE} needed"));
        }
        let data = s.serialize();
        ptr::copy_nonoverlapping(data.as_ptr(), bytes.cast::<u8>(), data.len());
        OK
    })
}

/// # Safety
/// `bytes` of `size` bytes; `state` a valid pointer.
#[no_mangle]
pub unsafe extern "C" fn fmi2DeSerializeFMUstate(c: *mut c_void, bytes: *const c_char, size: size_t, state: *mut *mut c_void) -> Status {
    with(c, "fmi2DeSerializeFMUstate", |inst| {
        let (Some(data), Some(out)) = (slice(bytes.cast::<u8>(), size), state.as_mut()) else {
            return inst.fail("fmi2DeSerializeFMUstate: NULL");
        };
        match Controller::deserialize(data) {
            Ok(s) => {
                if let Some(old) = (*out as *mut Controller).as_mut() {
                    *old = s;
                } else {
                    *out = Box::into_raw(Box::new(s)).cast();
                }
                OK
            }
            // A refused byte string leaves the instance as it was.
            Err(m) => {
                inst.log(ERROR, "logStatusError", &format!("fmi2DeSerializeFMUstate: {m}"));
                DISCARD
            }
        }
    })
}

/// # Safety
/// Not provided (providesDirectionalDerivative = false).
#[no_mangle]
pub unsafe extern "C" fn fmi2GetDirectionalDerivative(c: *mut c_void, _u: *const u32, _nu: size_t, _z: *const u32, _nz: size_t, _dv: *const f64, _dz: *mut f64) -> Status {
    with(c, "fmi2GetDirectionalDerivative", |inst| inst.fail("fmi2GetDirectionalDerivative: not provided"))
}

/// # Safety
/// Not provided (canInterpolateInputs = false, maxOutputDerivativeOrder = 0).
#[no_mangle]
pub unsafe extern "C" fn fmi2SetRealInputDerivatives(c: *mut c_void, _vr: *const u32, _n: size_t, _order: *const c_int, _value: *const f64) -> Status {
    with(c, "fmi2SetRealInputDerivatives", |inst| inst.fail("fmi2SetRealInputDerivatives: the inputs are not interpolated"))
}

/// # Safety
/// Not provided (maxOutputDerivativeOrder = 0).
#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealOutputDerivatives(c: *mut c_void, _vr: *const u32, _n: size_t, _order: *const c_int, _value: *mut f64) -> Status {
    with(c, "fmi2GetRealOutputDerivatives", |inst| inst.fail("fmi2GetRealOutputDerivatives: not provided"))
}

/// # Safety
/// `c` from fmi2Instantiate.
#[no_mangle]
pub unsafe extern "C" fn fmi2DoStep(c: *mut c_void, t: f64, h: f64, _no_prior_state: c_int) -> Status {
    with(c, "fmi2DoStep", |inst| {
        if inst.c.mode != Mode::Stepping {
            return inst.fail("fmi2DoStep: only after fmi2ExitInitializationMode and before fmi2Terminate");
        }
        if !(h > 0.0) || !h.is_finite() || !t.is_finite() {
            return inst.fail(&format!("fmi2DoStep: step from {t} by {h}: both must be finite, the step > 0"));
        }
        // The communication point must be the current time (to rounding of the master's clock).
        if (t - inst.c.time).abs() > 1e-9 * (1.0 + t.abs()) {
            return inst.fail(&format!("fmi2DoStep: communication point {t}, but the controller is at {}", inst.c.time));
        }
        inst.c.do_step(t, h);
        OK
    })
}

/// # Safety
/// `c` from fmi2Instantiate.
#[no_mangle]
pub unsafe extern "C" fn fmi2CancelStep(c: *mut c_void) -> Status {
    with(c, "fmi2CancelStep", |inst| {
        inst.log(WARNING, "logStatusError", "fmi2CancelStep: the controller's steps never run asynchronously");
        WARNING
    })
}

/// A status query: `kind == answerable` writes `answer(instance)` to
/// `value`; anything else concerns asynchronous steps, which this FMU never
/// takes (fmi2Discard).
unsafe fn status_query<T>(c: *mut c_void, what: &str, kind: c_int, answerable: Option<c_int>, value: *mut T, answer: impl FnOnce(&Instance) -> T) -> Status {
    with(c, what, |inst| match value.as_mut() {
        Some(v) if Some(kind) == answerable => {
            *v = answer(inst);
            OK
        }
        _ => {
            inst.log(DISCARD, "logStatusError", &format!("{what}: status kind {kind} not provided (no asynchronous steps)"));
            DISCARD
        }
    })
}

/// # Safety
/// `value` valid. Nothing to report: steps never run asynchronously.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetStatus(c: *mut c_void, kind: c_int, value: *mut c_int) -> Status {
    status_query(c, "fmi2GetStatus", kind, None, value, |_| 0)
}

/// # Safety
/// `value` valid. Only fmi2LastSuccessfulTime (2).
#[no_mangle]
pub unsafe extern "C" fn fmi2GetRealStatus(c: *mut c_void, kind: c_int, value: *mut f64) -> Status {
    status_query(c, "fmi2GetRealStatus", kind, Some(2), value, |inst| inst.c.time)
}

/// # Safety
/// `value` valid. Nothing to report.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetIntegerStatus(c: *mut c_void, kind: c_int, value: *mut c_int) -> Status {
    status_query(c, "fmi2GetIntegerStatus", kind, None, value, |_| 0)
}

/// # Safety
/// `value` valid. Only fmi2Terminated (3): the controller never asks to stop.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetBooleanStatus(c: *mut c_void, kind: c_int, value: *mut c_int) -> Status {
    status_query(c, "fmi2GetBooleanStatus", kind, Some(3), value, |_| 0)
}

/// # Safety
/// `value` valid. Nothing to report.
#[no_mangle]
pub unsafe extern "C" fn fmi2GetStringStatus(c: *mut c_void, kind: c_int, value: *mut *const c_char) -> Status {
    status_query(c, "fmi2GetStringStatus", kind, None, value, |_| ptr::null())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn running() -> Controller {
        let mut c = Controller::new();
        c.mode = Mode::Stepping;
        c
    }

    #[test]
    fn reference_slews_smoothly_from_start_to_target() {
        let c = running();
        let (r0, v0) = c.reference(0.0);
        assert_eq!((r0, v0), (DEFAULTS.theta_start, 0.0));
        let (r1, v1) = c.reference(DEFAULTS.t_slew);
        assert_eq!((r1, v1), (DEFAULTS.theta_ref, 0.0));
        let (rm, vm) = c.reference(0.5 * DEFAULTS.t_slew);
        assert!((rm - 0.5 * (DEFAULTS.theta_start + DEFAULTS.theta_ref)).abs() < 1e-15);
        // peak rate of the quintic: 15/8 of the mean
        let mean = (DEFAULTS.theta_ref - DEFAULTS.theta_start) / DEFAULTS.t_slew;
        assert!((vm - 1.875 * mean).abs() < 1e-12 * mean.abs());
        // the rate is the derivative of the reference
        let (t, dt) = (0.2, 1e-6);
        let fd = (c.reference(t + dt).0 - c.reference(t - dt).0) / (2.0 * dt);
        assert!((fd - c.reference(t).1).abs() < 1e-7);
    }

    #[test]
    fn torque_saturates_and_the_integral_does_not_wind_up() {
        let mut c = running();
        c.p = Parameters { kp: 100.0, kd: 0.0, ki: 50.0, theta_ref: 1.0, theta_start: 1.0, t_slew: 0.0, torque_max: 5.0 };
        c.theta = 0.0;
        for k in 0..100 {
            c.do_step(k as f64 * 0.01, 0.01);
            assert_eq!(c.torque, 5.0);
        }
        assert_eq!(c.integral, 0.0, "saturated with the error pushing on: the integral holds");
        // inside the band the integral runs
        c.theta = 0.99;
        c.do_step(1.0, 0.01);
        assert!((c.torque - 1.0).abs() < 1e-12);
        assert!((c.integral - 1e-4).abs() < 1e-18);
    }

    #[test]
    fn outputs_follow_the_inputs_until_the_first_sample() {
        let mut c = running();
        c.theta = -0.5;
        assert_eq!(c.get(VR_TORQUE), Some(0.0));
        c.theta = -0.6;
        let u = c.get(VR_TORQUE).unwrap();
        assert!((u - DEFAULTS.kp * 0.1).abs() < 1e-12);
        c.do_step(0.0, 1e-3);
        c.theta = -0.4;
        assert_eq!(c.get(VR_TORQUE), Some(u), "held until the next step");
    }

    #[test]
    fn serialization_round_trips_and_refuses_garbage() {
        let mut c = running();
        c.theta = 0.3;
        c.do_step(0.0, 0.01);
        let bytes = c.serialize();
        assert_eq!(bytes.len(), SERIALIZED_SIZE);
        assert_eq!(Controller::deserialize(&bytes).unwrap(), c);
        assert!(Controller::deserialize(&bytes[1..]).is_err());
        let mut bad = bytes.clone();
        bad[4] = 9;
        assert!(Controller::deserialize(&bad).is_err());
    }
}
