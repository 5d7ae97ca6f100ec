//! The C boundary both shells share: every entry point runs inside a
//! panic guard (no panic reaches the importer: it becomes an Error status,
//! a logged message and the Error state), and C arrays and strings are
//! read only after their pointers are checked.

use std::cell::{Cell, RefCell};
use std::ffi::CStr;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Once;

use libc::{c_char, c_int, size_t};

use super::instance::{CallResult, Instance};
use super::state::{Call, Status};

fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into())
}

thread_local! {
    /// Set while this thread runs inside an FMI call.
    static IN_CALL: Cell<bool> = const { Cell::new(false) };
    /// Where the last panic inside an FMI call happened.
    static PANIC_LOCATION: RefCell<Option<String>> = const { RefCell::new(None) };
}

/// The panic hook, installed once: it keeps panics off the host's stderr
/// (a host that pipes stderr without reading it would block) and only
/// records where the panic happened; the call's boundary logs one short
/// message through the instance's logger. The FMU's cdylib carries its own
/// copy of the Rust runtime, so the hook sees only this library's panics,
/// and every entry point is guarded. The closure captures nothing: it
/// allocates nothing that a host's dlclose could leak.
fn install_panic_hook() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        std::panic::set_hook(Box::new(|info| {
            if IN_CALL.with(Cell::get) {
                let location = info.location().map(|l| format!("{}:{}", l.file(), l.line()));
                PANIC_LOCATION.with(|p| *p.borrow_mut() = location);
            }
        }));
    });
}

/// Runs `body` inside the panic boundary; `Err` carries the panic's short message.
pub fn guarded<T>(body: impl FnOnce() -> T) -> Result<T, String> {
    install_panic_hook();
    let outer = IN_CALL.with(|c| c.replace(true));
    let result = catch_unwind(AssertUnwindSafe(body));
    IN_CALL.with(|c| c.set(outer));
    result.map_err(|payload| {
        let msg = panic_message(payload.as_ref());
        match PANIC_LOCATION.with(|p| p.borrow_mut().take()) {
            Some(at) => format!("{msg} (at {at})"),
            None => msg,
        }
    })
}

/// A shell's instance: the shared core inside it.
pub trait Shell {
    fn core(&mut self) -> &mut Instance;
}

/// The FMI 2.0 shell is the core itself.
impl Shell for Instance {
    fn core(&mut self) -> &mut Instance {
        self
    }
}

/// Runs `body` on a shell's instance inside the panic boundary, after the
/// one check of the shell's state-machine table.
pub fn run<S: Shell, F: Call>(shell: &mut S, f: F, body: impl FnOnce(&mut S) -> CallResult) -> c_int {
    match guarded(|| shell.core().enter(f).and_then(|()| body(&mut *shell))) {
        Ok(Ok(())) => Status::Ok.raw(),
        Ok(Err(status)) => status.raw(),
        Err(msg) => {
            shell.core().poison(&format!("{}: internal error: {msg}", f.name()));
            Status::Error.raw()
        }
    }
}

/// A slice from a C array, `None` if the pointer is NULL with `n > 0`.
///
/// # Safety
/// A non-null `p` points to `n` valid elements (the caller's obligation).
pub unsafe fn slice<'a, T>(p: *const T, n: size_t) -> Option<&'a [T]> {
    if n == 0 {
        Some(&[])
    } else if p.is_null() {
        None
    } else {
        Some(std::slice::from_raw_parts(p, n))
    }
}

/// # Safety
/// As [`slice`], writable.
pub unsafe fn slice_mut<'a, T>(p: *mut T, n: size_t) -> Option<&'a mut [T]> {
    if n == 0 {
        Some(&mut [])
    } else if p.is_null() {
        None
    } else {
        Some(std::slice::from_raw_parts_mut(p, n))
    }
}

/// # Safety
/// A non-null `p` is a NUL-terminated string.
pub unsafe fn string(p: *const c_char) -> Option<String> {
    if p.is_null() {
        None
    } else {
        Some(CStr::from_ptr(p).to_string_lossy().into_owned())
    }
}

/// The error of a NULL argument.
pub fn null_argument<F: Call>(instance: &Instance, f: F, what: &str) -> Status {
    instance.fail(&format!("{}: {what} is NULL", f.name()))
}
