//! The FMU states an instance hands out (GetFMUState and
//! DeSerializeFMUState of both standards): boxed snapshots behind the
//! importer's opaque pointers, each listed in the ledger of the instance
//! that made it, so that freeing the instance frees the states the
//! importer did not free (FMI 3.0 section 2.2.2, fmi3FreeInstance; the
//! FMI 2.0 shell shares the core and so the rule). A state freed through
//! another instance of the same FMU leaves its own instance's ledger.
//!
//! A pointer the importer passes back is looked up among the states this
//! library has handed out and not freed ([`LIVE`]) before it is read: a
//! state already freed (also by freeing the instance that made it) or
//! made by another FMU's library is refused with a message, not read.

use std::collections::{BTreeSet, HashSet};
use std::ffi::c_void;
use std::sync::{Arc, Mutex, Weak};

use super::instance::Snapshot;

type Addresses = Mutex<HashSet<usize>>;

/// The states an instance handed out and the importer has not freed.
pub struct Ledger(Arc<Addresses>);

/// Every state of this library (process-wide: every instance of this
/// FMU) handed out and not freed. Emptied, it holds no allocation, so
/// that nothing of it outlives the library's unloading.
static LIVE: Mutex<BTreeSet<usize>> = Mutex::new(BTreeSet::new());

fn live() -> std::sync::MutexGuard<'static, BTreeSet<usize>> {
    // A panic while the set was held (there is none to have) leaves it intact.
    LIVE.lock().unwrap_or_else(|e| e.into_inner())
}

/// Takes `address` out of [`LIVE`]; whether it was there.
fn forget(address: usize) -> bool {
    let mut live = live();
    let was = live.remove(&address);
    if live.is_empty() {
        // An emptied map may keep its root node: dropped here.
        live.clear();
    }
    was
}

/// Whether `state` is a state of this library not yet freed, else why not.
fn check_live(state: *mut c_void) -> Result<(), String> {
    if live().contains(&(state as usize)) {
        Ok(())
    } else {
        Err(format!("FMU state {state:p} is not one this FMU handed out, or was freed already (by its free call or by freeing the instance that made it)"))
    }
}

/// What an importer's state pointer points to.
struct Held {
    snapshot: Snapshot,
    /// The ledger of the instance that made it.
    ledger: Weak<Addresses>,
}

impl Default for Ledger {
    fn default() -> Self {
        Ledger(Arc::new(Mutex::new(HashSet::new())))
    }
}

impl Ledger {
    /// Puts `snapshot` behind `*slot`: a new state where `*slot` is null,
    /// else the importer's earlier state object, overwritten (refused
    /// unless it is a live state of this FMU).
    ///
    /// # Safety
    /// `slot` is valid.
    pub unsafe fn hand_out(&self, slot: *mut *mut c_void, snapshot: Snapshot) -> Result<(), String> {
        if (*slot).is_null() {
            let held = Box::into_raw(Box::new(Held { snapshot, ledger: Arc::downgrade(&self.0) }));
            lock(&self.0).insert(held as usize);
            live().insert(held as usize);
            *slot = held as *mut c_void;
        } else {
            check_live(*slot)?;
            (*((*slot) as *mut Held)).snapshot = snapshot;
        }
        Ok(())
    }

    /// How many states are handed out and not freed.
    pub fn live(&self) -> usize {
        lock(&self.0).len()
    }
}

/// The snapshot behind a state pointer: refused unless it is a live
/// state of this FMU.
///
/// # Safety
/// `state` is non-null; the snapshot is not freed while the reference lives.
pub unsafe fn snapshot<'a>(state: *mut c_void) -> Result<&'a Snapshot, String> {
    check_live(state)?;
    Ok(&(*(state as *const Held)).snapshot)
}

/// Frees a state (nothing for null) and nulls the importer's pointer;
/// refused (nothing freed) unless it is a live state of this FMU.
///
/// # Safety
/// `slot` is valid.
pub unsafe fn free(slot: *mut *mut c_void) -> Result<(), String> {
    if (*slot).is_null() {
        return Ok(());
    }
    check_live(*slot)?;
    forget((*slot) as usize);
    let held = Box::from_raw((*slot) as *mut Held);
    if let Some(ledger) = held.ledger.upgrade() {
        lock(&ledger).remove(&((*slot) as usize));
    }
    *slot = std::ptr::null_mut();
    Ok(())
}

impl Drop for Ledger {
    fn drop(&mut self) {
        for address in lock(&self.0).drain() {
            forget(address);
            // SAFETY: every address in the ledger is a live `Held` from
            // `hand_out` (freeing one takes it out first).
            drop(unsafe { Box::from_raw(address as *mut Held) });
        }
    }
}

fn lock(addresses: &Addresses) -> std::sync::MutexGuard<'_, HashSet<usize>> {
    // A panic while the set was held (there is none to have) leaves it intact.
    addresses.lock().unwrap_or_else(|e| e.into_inner())
}
