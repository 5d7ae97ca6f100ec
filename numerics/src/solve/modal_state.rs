//! The modal state `(q, qd)` every propagator starts from and returns.

use nalgebra::DVector;

/// The modal state `(q, qd)` (empty by default).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ModalState {
    pub q: DVector<f64>,
    pub qd: DVector<f64>,
}

impl ModalState {
    pub fn zeros(n: usize) -> Self {
        ModalState { q: DVector::zeros(n), qd: DVector::zeros(n) }
    }
}
