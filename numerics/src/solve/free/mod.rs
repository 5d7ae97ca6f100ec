//! Free flight: uncoupled modal oscillators under a known load, propagated in
//! closed form from the state at the last event (the segment's anchor).
//!
//! The state at any time is computed from the anchor, never by chaining
//! communication steps, so results do not depend on the step size.
//!
//! This module holds the dynamics and what every segment shares; the
//! motion from an anchor is [`FreeSegment`] (`segment.rs`), the derivatives
//! at one instant [`ModalJet`] (`jets.rs`), and their bounds over an
//! interval with the event search's split steps [`ModalBounds`] and
//! [`FreeSegment::fill_bounds`] (`bounds.rs`).

use nalgebra::DVector;

use super::complex::C64;
use super::forcing::ModalForcing;
use super::oscillator::Oscillator;

mod bounds;
mod jets;
mod segment;

pub use super::modal_state::ModalState;
pub use bounds::ModalBounds;
pub use jets::ModalJet;
pub use segment::{steady_rotation, FreeSegment, Increment, Projection};

/// The free dynamics: one oscillator per mode and the modal load.
#[derive(Clone, Debug, PartialEq)]
pub struct FreeDynamics {
    pub oscillators: Vec<Oscillator>,
    pub forcing: ModalForcing,
    /// `forcing.bounds()`, kept with it.
    force_bounds: [DVector<f64>; 5],
    /// Per mode, what every segment shares: the steady responses' factors
    /// and bounds (the rotation to a segment's start changes neither modulus).
    mode_loads: Vec<ModeLoad>,
}

#[derive(Clone, Debug, PartialEq)]
struct ModeLoad {
    /// The static response to the constant load, `c_j / omega_j^2`.
    x_static: f64,
    /// Per harmonic: `1 / (omega^2 - Omega^2 + 2 i a Omega)` far from
    /// resonance, `None` near it (the response is then taken from rest).
    inverse_stiffness: Vec<Option<C64>>,
    /// `|x_static| + sum |P b|` and `sum |P b| W^m` (m = 1..=5).
    steady_bounds: [f64; 6],
    /// `sum |b| W^m` (m = 0..=4) over the near-resonant harmonics.
    resonant_bounds: [f64; 5],
}

impl FreeDynamics {
    pub fn new(oscillators: Vec<Oscillator>, forcing: ModalForcing) -> Self {
        let force_bounds = forcing.bounds();
        let mode_loads = mode_loads(&oscillators, &forcing);
        FreeDynamics { oscillators, forcing, force_bounds, mode_loads }
    }

    pub fn set_forcing(&mut self, forcing: ModalForcing) {
        self.force_bounds = forcing.bounds();
        self.mode_loads = mode_loads(&self.oscillators, &forcing);
        self.forcing = forcing;
    }

    /// The scale of the motion the loads drive, per mode at most: the
    /// steady response's displacement and rate bounds (a near-resonant
    /// harmonic counted by its static response `|b| / omega^2`, its rate
    /// by `|b| / omega`). Zero without loads.
    pub fn load_scale(&self) -> (f64, f64) {
        self.oscillators.iter().zip(&self.mode_loads).fold((0.0, 0.0), |(q, v), (osc, load)| {
            let w = osc.omega.max(f64::MIN_POSITIVE);
            let resonant = load.resonant_bounds[0];
            (q.max(load.steady_bounds[0] + resonant / (w * w)), v.max(load.steady_bounds[1] + resonant / w))
        })
    }
}

fn mode_loads(oscillators: &[Oscillator], forcing: &ModalForcing) -> Vec<ModeLoad> {
    // Moduli computed once here carry a relative margin for rounding.
    let up = 1.0 + 8.0 * f64::EPSILON;
    oscillators
        .iter()
        .enumerate()
        .map(|(j, osc)| {
            let x_static = forcing.constant[j] / (osc.omega * osc.omega);
            let mut steady_bounds = [0.0; 6];
            let mut resonant_bounds = [0.0; 5];
            steady_bounds[0] = x_static.abs();
            let inverse_stiffness = forcing
                .harmonics
                .iter()
                .map(|h| {
                    let (inverse, magnitude, target): (Option<C64>, f64, &mut [f64]) = if osc.near_resonance(h.omega) {
                        (None, h.amplitude[j].norm() * up, &mut resonant_bounds)
                    } else {
                        let inverse = 1.0 / osc.dynamic_stiffness(h.omega);
                        (Some(inverse), (h.amplitude[j] * inverse).norm() * up, &mut steady_bounds)
                    };
                    let mut p = magnitude;
                    for m in target.iter_mut() {
                        *m += p;
                        p *= h.omega;
                    }
                    inverse
                })
                .collect();
            ModeLoad { x_static, inverse_stiffness, steady_bounds, resonant_bounds }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::dvector;

    /// Three modes (undamped, light, over-critical), a constant load and
    /// two harmonics, one resonant with mode 1 (its response taken from rest).
    pub(super) fn two_harmonic_dynamics() -> FreeDynamics {
        let oscs = vec![Oscillator::new(1.0, 0.0), Oscillator::new(4.0, 0.1), Oscillator::new(9.0, 2.0)];
        let mut forcing = ModalForcing::zero(3);
        forcing.constant = dvector![0.3, -0.2, 0.1];
        forcing.add_harmonic(1.0, dvector![C64::new(0.0, -1.0), C64::new(0.0, -0.5), C64::new(0.2, 0.0)]);
        forcing.add_harmonic(2.5, dvector![C64::new(0.4, 0.1), C64::new(-0.3, 0.0), C64::new(0.0, 0.7)]);
        FreeDynamics::new(oscs, forcing)
    }
}
