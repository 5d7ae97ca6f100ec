//! Coupled linear phases: `q'' + D q' + K q = f(t) + W lambda`, `W^T q = d`.
//!
//! Sticking (VSM12 eqs. 29-33) holds some contact points on their stops;
//! a compliant stop in contact adds `k w w^T` to K (the mode-transfer idea of
//! RMTM). Either way the phase is linear and time invariant, but with
//! non-proportional damping: it is reduced to the free coordinates `y`
//! (`q = q_c + Z y`, `Z` an orthonormal basis of the constraint's null space),
//! diagonalised once in complex first-order form, and propagated exactly,
//! `z_k(s) = e^{L_k s} z_k(0) + forced terms` with the `phi1` kernel, which is
//! exact at resonance.
//!
//! The structure of a phase and its decomposition are [`CoupledSystem`]
//! (`system.rs`), the loads and functionals in its complex coordinates
//! [`PhaseLoads`] and [`ProjectedFunctional`] (`loads.rs`), the motion from
//! an anchor [`CoupledSegment`] (`segment.rs`), and what the event search
//! reads off it at one point, [`CoupledSample`] and [`CoordinateBounds`]
//! (`probe.rs`).

mod eigen;
mod loads;
mod probe;
mod segment;
mod system;

pub use loads::{PhaseLoads, ProjectedFunctional};
pub use probe::{CoordinateBounds, CoupledSample};
pub use segment::CoupledSegment;
pub use system::{CoupledSystem, SystemCache};

/// Why a coupled phase could not be set up.
#[derive(Clone, Debug, PartialEq)]
pub enum LtiError {
    Eigen(String),
    IllConditioned(f64),
}

impl std::fmt::Display for LtiError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LtiError::Eigen(e) => write!(f, "eigendecomposition of the contact phase failed: {e}"),
            LtiError::IllConditioned(c) => write!(
                f,
                "the contact phase is nearly defective (eigenvector condition number {c:.3e}); \
                 change the damping slightly"
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{dvector, DMatrix, DVector};

    use crate::solve::complex::C64;
    use crate::solve::forcing::ModalForcing;
    use crate::solve::modal_state::ModalState;

    /// A pinned beam of `n` modes with modal damping held at one point:
    /// `(K, D, W)`, a constant and a harmonic load (60 rad/s, between two
    /// coupled frequencies, one near a resonance), the held position and a
    /// start off the constraint.
    pub(super) fn held_beam(n: usize) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>, ModalForcing, DVector<f64>, ModalState) {
        let pi4 = std::f64::consts::PI.powi(4);
        let k = DMatrix::from_diagonal(&DVector::from_fn(n, |j, _| ((j + 1) as f64).powi(4) * pi4));
        let d = DMatrix::from_diagonal(&DVector::from_fn(n, |j, _| 0.1 * ((j + 1) as f64).powi(2) * std::f64::consts::PI.powi(2)));
        let w = DMatrix::from_fn(n, 1, |j, _| 2f64.sqrt() * ((j + 1) as f64 * std::f64::consts::PI * 0.37).sin());
        let mut forcing = ModalForcing::zero(n);
        forcing.constant = DVector::from_fn(n, |j, _| 0.3 / (j + 1) as f64);
        forcing.add_harmonic(60.0, DVector::from_fn(n, |j, _| C64::new(0.0, -5.0 * (0.5 + j as f64).sin())));
        let start = ModalState { q: DVector::from_fn(n, |j, _| 0.02 / ((j + 1) as f64).powi(2)), qd: DVector::from_fn(n, |j, _| 0.1 * (j as f64).cos()) };
        (k, d, w, forcing, dvector![0.01], start)
    }
}
