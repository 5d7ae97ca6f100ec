//! The FMU states an instance hands out (GetFMUState and
//! DeSerializeFMUState of both standards): boxed snapshots behind the
//! importer's opaque pointers, each listed in the ledger of the instance
//! that made it, so that freeing the instance frees the states the
//! importer did not free (FMI 3.0 section 2.2.2, fmi3FreeInstance; the
//! FMI 2.0 shell shares the core and so the rule). A state freed through
//! another instance of the same FMU leaves its own instance's ledger.

use std::collections::HashSet;
use std::ffi::c_void;
use std::sync::{Arc, Mutex, Weak};

use super::instance::Snapshot;

type Addresses = Mutex<HashSet<usize>>;

/// The states an instance handed out and the importer has not freed.
pub struct Ledger(Arc<Addresses>);

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
    /// else the importer's earlier state object, overwritten.
    ///
    /// # Safety
    /// `slot` is valid; a non-null `*slot` is a state from [`Self::hand_out`]
    /// not yet freed.
    pub unsafe fn hand_out(&self, slot: *mut *mut c_void, snapshot: Snapshot) {
        if (*slot).is_null() {
            let held = Box::into_raw(Box::new(Held { snapshot, ledger: Arc::downgrade(&self.0) }));
            lock(&self.0).insert(held as usize);
            *slot = held as *mut c_void;
        } else {
            (*((*slot) as *mut Held)).snapshot = snapshot;
        }
    }

    /// How many states are handed out and not freed.
    pub fn live(&self) -> usize {
        lock(&self.0).len()
    }
}

/// The snapshot behind a state pointer.
///
/// # Safety
/// `state` is a non-null state from [`Ledger::hand_out`] not yet freed.
pub unsafe fn snapshot<'a>(state: *mut c_void) -> &'a Snapshot {
    &(*(state as *const Held)).snapshot
}

/// Frees a state (nothing for null) and nulls the importer's pointer.
///
/// # Safety
/// `slot` is valid; a non-null `*slot` is a state from [`Ledger::hand_out`]
/// not yet freed.
pub unsafe fn free(slot: *mut *mut c_void) {
    if (*slot).is_null() {
        return;
    }
    let held = Box::from_raw((*slot) as *mut Held);
    if let Some(ledger) = held.ledger.upgrade() {
        lock(&ledger).remove(&((*slot) as usize));
    }
    *slot = std::ptr::null_mut();
}

impl Drop for Ledger {
    fn drop(&mut self) {
        for address in lock(&self.0).drain() {
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
