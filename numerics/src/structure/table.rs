//! Process-wide tables of the dimensionless quantities every model build
//! starts from (a beam's mode shapes and their integrals): pure functions
//! of a support and a mode count or index, so a process makes each once.
//! A parameter sweep instantiates the same structure again and again with
//! other dimensions, materials or stops; the dimensionless part it shares.

use std::collections::HashMap;
use std::hash::Hash;
use std::sync::{Arc, Mutex, OnceLock};

/// Values by key, each made on first request and shared after.
pub struct Table<K, V>(OnceLock<Mutex<HashMap<K, Arc<V>>>>);

impl<K: Eq + Hash, V> Table<K, V> {
    pub const fn new() -> Self {
        Table(OnceLock::new())
    }

    /// The value of `key`: the one made before, or `make()` (outside the
    /// lock: two threads asking at once may both make it, and one is kept;
    /// the values are equal, being pure functions of the key).
    pub fn get_or_make(&self, key: K, make: impl FnOnce() -> V) -> Arc<V> {
        let table = self.0.get_or_init(Default::default);
        if let Some(found) = table.lock().unwrap_or_else(|e| e.into_inner()).get(&key) {
            return found.clone();
        }
        let made = Arc::new(make());
        table.lock().unwrap_or_else(|e| e.into_inner()).entry(key).or_insert(made).clone()
    }
}

impl<K: Eq + Hash, V> Default for Table<K, V> {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_value_is_made_once_and_shared() {
        static SQUARES: Table<u32, u64> = Table::new();
        let mut made = 0;
        let a = SQUARES.get_or_make(7, || {
            made += 1;
            49
        });
        let b = SQUARES.get_or_make(7, || {
            made += 1;
            0
        });
        assert_eq!((*a, *b, made), (49, 49, 1));
        assert!(Arc::ptr_eq(&a, &b));
        assert_eq!(*SQUARES.get_or_make(8, || 64), 64);
    }
}
