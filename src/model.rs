//! The model built from a scene: modal oscillators, modal loads, stops with
//! their shape vectors, actuators. Plain numbers, ready for the solver.

use nalgebra::DVector;

use crate::scene::{Load, Scene, SceneError, Side, StopLaw, Structure, SupportKind, Waveform};
use crate::solve::{Functional, ModalForcing, ModalState, Oscillator, C64};
use crate::structure::{Beam, Support};

/// A rigid stop acting on one point of the structure.
#[derive(Clone, Debug, PartialEq)]
pub struct StopModel {
    pub name: String,
    /// `w_j = W_j(x_stop)`: the stop's displacement is `w . q`.
    pub w: DVector<f64>,
    pub gap: f64,
    /// +1: limits `w . q <= gap`; -1: limits `w . q >= -gap`.
    pub side: f64,
    pub restitution: f64,
    pub chatter_eps: f64,
}

impl StopModel {
    /// The value of `w . q` while in contact.
    pub fn target(&self) -> f64 {
        self.side * self.gap
    }

    /// The gap function `side (target - w . q)`, non-negative when admissible.
    pub fn gap_functional(&self) -> Functional {
        Functional::of_position(self.gap, -&self.w * self.side)
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Model {
    pub beam: Beam,
    pub oscillators: Vec<Oscillator>,
    /// Modal loads without the inputs.
    pub loads: ModalForcing,
    pub stops: Vec<StopModel>,
    /// Modal load of a unit force at each actuator.
    pub actuators: Vec<DVector<f64>>,
    pub initial: ModalState,
    pub event_tolerance: f64,
    pub max_events_per_step: u64,
}

impl Model {
    pub fn n_modes(&self) -> usize {
        self.oscillators.len()
    }

    pub fn build(scene: &Scene) -> Result<Model, SceneError> {
        scene.validate()?;
        let beam = match &scene.structure {
            Structure::Beam { support, modes } => Beam::scaled(
                match support {
                    SupportKind::PinnedPinned => Support::PinnedPinned,
                },
                *modes,
            ),
        };
        let n = beam.n_modes;
        let modes = 1..=n;
        let oscillators: Vec<Oscillator> = modes.clone().map(|j| Oscillator::new(beam.omega(j), scene.damping.zeta)).collect();
        let mut loads = ModalForcing::zero(n);
        for load in &scene.loads {
            match load {
                Load::DistributedHarmonic { amplitude, omega, waveform, .. } => {
                    // F sin(W t) = Re(-i F e^{i W t}); F cos(W t) = Re(F e^{i W t}).
                    let phase = match waveform {
                        Waveform::Sin => C64::new(0.0, -1.0),
                        Waveform::Cos => C64::new(1.0, 0.0),
                    };
                    let b = DVector::from_iterator(n, modes.clone().map(|j| phase * (amplitude * beam.shape_integral(j))));
                    loads.add_harmonic(*omega, b);
                }
            }
        }
        let shape_at = |x: f64| DVector::from_iterator(n, modes.clone().map(|j| beam.shape(j, x)));
        let mut stops = Vec::new();
        for (i, s) in scene.stops.iter().enumerate() {
            let w = shape_at(s.x);
            if w.norm() < 1e-8 {
                return Err(SceneError(format!(
                    "stops[{i}].x = {}: every retained mode has a node there, the stop cannot act",
                    s.x
                )));
            }
            let StopLaw::Restitution { restitution, eps } = s.law;
            stops.push(StopModel {
                name: s.name.clone(),
                w,
                gap: s.gap,
                side: match s.side {
                    Side::Positive => 1.0,
                    Side::Negative => -1.0,
                },
                restitution,
                chatter_eps: eps,
            });
        }
        let actuators = scene.actuators.iter().map(|a| shape_at(a.x)).collect();
        let mut initial = ModalState::zeros(n);
        for (j, v) in scene.initial.q.iter().enumerate() {
            initial.q[j] = *v;
        }
        for (j, v) in scene.initial.qd.iter().enumerate() {
            initial.qd[j] = *v;
        }
        Ok(Model {
            beam,
            oscillators,
            loads,
            stops,
            actuators,
            initial,
            event_tolerance: scene.solver.event_tolerance,
            max_events_per_step: scene.solver.max_events_per_step,
        })
    }

    /// Kinetic plus strain energy `sum (qd_j^2 + omega_j^2 q_j^2) / 2`.
    pub fn energy(&self, state: &ModalState) -> f64 {
        self.oscillators
            .iter()
            .enumerate()
            .map(|(j, o)| 0.5 * (state.qd[j] * state.qd[j] + o.omega * o.omega * state.q[j] * state.q[j]))
            .sum()
    }

    /// Modal loads with the actuator forces added (held constant).
    pub fn forcing_with_inputs(&self, inputs: &[f64]) -> ModalForcing {
        let mut f = self.loads.clone();
        for (a, u) in self.actuators.iter().zip(inputs) {
            f.constant.axpy(*u, a, 1.0);
        }
        f
    }

    /// The shortest period of interest: the fundamental or the fastest load.
    pub fn shortest_period(&self) -> f64 {
        let mut w = self.oscillators.first().map(|o| o.omega).unwrap_or(1.0);
        for h in &self.loads.harmonics {
            w = w.max(h.omega);
        }
        2.0 * std::f64::consts::PI / w
    }
}
