//! The linear part the exponential integrator propagates exactly
//! ([`crate::solve::exponential`]), frozen on a grid of hub speeds and
//! angles and kept per model: phases that start near one point of the
//! grid share its modes, its modal equations and the modes' responses
//! per step size.
//!
//! The frozen part is `J0 z'' + C z' + K0 z` with the undeflected mass
//! matrix and `K0 = K - w^2 (M - D) - g s S` at a grid point `(w^2, g s)`
//! near the phase's hub speed squared and `g sin(theta)`. The grid's
//! spacing is [`GRID`] of the first clamped mode's `omega^2`: what the
//! frozen part leaves to the remainder (`(theta'^2 - w^2) H p`, and
//! gravity's alike) stays within that share of the slow modes' stiffness,
//! well inside what the hub speed's own swing leaves within a phase (the
//! DWZ hub swings between -3.6 and 3.2 rad/s). A grid point is a pure
//! function of the phase's start state, so a run replayed from its
//! anchor (a restored FMU state) freezes at the same point, bit for bit.

use std::sync::{Arc, Mutex};

use nalgebra::{DMatrix, DVector};

use super::system::Phase;
use crate::solve::exponential::LinearModes;
use crate::structure::rotating::{FrozenPart, ModalEquations};

/// The grid's spacing in `omega_1^2` (the first clamped mode's).
pub const GRID: f64 = 1e-2;

/// Frozen parts kept per model at most (the oldest are dropped).
const KEPT: usize = 8;

/// A grid point: `w^2` and `g s` in grid spacings.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct FrozenKey {
    speed: i64,
    gravity: i64,
}

/// One frozen linear part: its modes and the modal equations' products.
#[derive(Debug)]
pub struct Frozen {
    pub modes: Arc<LinearModes>,
    pub equations: ModalEquations,
}

/// The frozen parts built so far for one model (shared by its runs and
/// their copies: each is a pure function of the model and its key).
#[derive(Clone, Default)]
pub struct FrozenMemo(Arc<Mutex<Vec<(FrozenKey, Arc<Frozen>)>>>);

impl std::fmt::Debug for FrozenMemo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let kept = self.0.lock().map(|v| v.len()).unwrap_or(0);
        f.debug_struct("FrozenMemo").field("kept", &kept).finish()
    }
}

impl Phase {
    /// The frozen part for a phase starting at `(t, y)`.
    pub fn frozen(&self, t: f64, y: &DVector<f64>) -> Result<Arc<Frozen>, String> {
        let (theta, theta_dot) = {
            let (z, zd) = self.coords(t, y);
            (z[0], zd[0])
        };
        let beam = &self.model.beam;
        let spacing = GRID * beam.omega(1).powi(2);
        let gravity_per_length = beam.params.gravity / beam.params.length;
        let on_grid = |x: f64| {
            let k = (x / spacing).round();
            if k.is_finite() { k.clamp(i64::MIN as f64, i64::MAX as f64) as i64 } else { 0 }
        };
        let key = FrozenKey { speed: on_grid(theta_dot * theta_dot), gravity: on_grid(gravity_per_length * theta.sin()) };
        let memo = &self.model.frozen;
        if let Some(found) = memo.0.lock().unwrap_or_else(|e| e.into_inner()).iter().find(|e| e.0 == key) {
            return Ok(found.1.clone());
        }
        let speed2 = key.speed as f64 * spacing;
        let sin_theta = if gravity_per_length != 0.0 { (key.gravity as f64 * spacing / gravity_per_length).clamp(-1.0, 1.0) } else { 0.0 };
        let frozen = Arc::new(self.build_frozen(speed2, sin_theta)?);
        let mut kept = memo.0.lock().unwrap_or_else(|e| e.into_inner());
        if kept.len() == KEPT {
            kept.remove(0);
        }
        kept.push((key, frozen.clone()));
        Ok(frozen)
    }

    /// The frozen part at hub speed squared `speed2` and `sin(theta) =
    /// sin_theta`: the bending modes with that speed's centrifugal
    /// stiffening and gravity's axial load, the hub (when torque-driven)
    /// through the undeflected mass matrix; everything else (the
    /// deflection's share of `J`, Coriolis terms, the hub speed's change,
    /// contact) is the remainder's.
    fn build_frozen(&self, speed2: f64, sin_theta: f64) -> Result<Frozen, String> {
        let n = self.n();
        let beam = &self.model.beam;
        let stiffness = &beam.k - &self.model.m_minus_d * speed2 - &self.model.s_geo * (beam.params.gravity * sin_theta);
        let modes = match self.model.prescribed() {
            Some(_) => LinearModes::new(&beam.m, &stiffness, &beam.damping)?,
            None => {
                let mass = beam.mass_matrix(&DVector::zeros(n + 1));
                let border = |b: &DMatrix<f64>| DMatrix::from_fn(n + 1, n + 1, |i, j| if i == 0 || j == 0 { 0.0 } else { b[(i - 1, j - 1)] });
                LinearModes::new(&mass, &border(&stiffness), &border(&beam.damping))?
            }
        };
        let equations = beam.modal_equations(FrozenPart {
            phi: modes.phi(),
            psi: modes.psi(),
            omega2: modes.omega2(),
            damping: modes.damping(),
            theta_dot_sq: speed2,
            sin_theta,
            prescribed: self.prescribed(),
        });
        Ok(Frozen { modes: Arc::new(modes), equations })
    }
}
