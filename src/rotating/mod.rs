//! The simulation engine of a flexible beam on a rotating hub whose tip may
//! strike a fixed plane (seed: Duan, Wang & Zhang, "Impact dynamics of a
//! flexible beam with rotation": Hertz contact `F = K gamma^1.5 + C gamma'`,
//! eqs. 2-4; the equations of motion in [`crate::structure::rotating`]).
//!
//! - [`spec`]: the scene (serde, SI units) and its validation;
//! - [`model`]: the scene in numbers (beam matrices, surface, hub drive);
//! - [`system`]: one phase's equations for Radau IIA (state layout, force,
//!   analytic Jacobian);
//! - [`events`]: the switches of the contact law inside a step;
//! - [`sim`]: the run ([`RotatingSimulation`]): steps, switches, restarts,
//!   outputs;
//! - [`codec`]: the run's versioned encoding, replayed on decode;
//! - [`interface`]: the scene's parameters, input and outputs.
//!
//! Unlike the modal simulation ([`crate::sim`]), nothing here is closed
//! form: the rotating beam is nonlinear everywhere, so the whole motion is
//! integrated, free flight included.

use std::fmt;

pub mod codec;
pub mod events;
pub mod interface;
pub mod model;
pub mod sim;
pub mod spec;
pub mod system;

pub use codec::ROTATING_STATE_VERSION;
pub use model::{RotatingModel, SpinUp};
pub use sim::{RotatingEvent, RotatingEventKind, RotatingSimulation, RotatingStats};
pub use spec::RotatingSpec;
pub use system::ContactState;

#[derive(Clone, Debug, PartialEq)]
pub enum RotatingError {
    /// The scene is refused (the message names the field, value and range).
    Spec(String),
    /// A requested time lies before the current one.
    Backwards { now: f64, requested: f64 },
    /// A time or input is NaN or infinite.
    NonFiniteInput { what: &'static str, value: f64 },
    /// The value cannot be set in this scene.
    NotAnInput(String),
    /// The integrator failed (step size, Newton, a mass matrix that lost
    /// definiteness).
    Integration { time: f64, message: String },
    /// More switches than `solver.max_events_per_step` within one advance.
    TooManyEvents { time: f64, count: u64 },
    /// More integration steps than `solver.max_steps_per_step` within one advance.
    TooMuchWork { time: f64, steps: u64 },
    /// A serialized state is refused (the message names the field).
    Decode(String),
    /// The initial state puts the tip deeper into the surface than a run
    /// may start (`limit`: the depth whose stored energy is the beam's
    /// kinetic energy at the speed limit).
    InitialPenetration { penetration: f64, limit: f64 },
}

impl fmt::Display for RotatingError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RotatingError::Spec(m) | RotatingError::Decode(m) => write!(f, "{m}"),
            RotatingError::Backwards { now, requested } => write!(f, "requested time {requested} lies before the current time {now}"),
            RotatingError::NonFiniteInput { what, value } => write!(f, "{what} = {value}: must be finite"),
            RotatingError::NotAnInput(m) => write!(f, "cannot set {m}"),
            RotatingError::Integration { time, message } => write!(
                f,
                "the integration of the rotating beam failed at t = {time}: {message}; loosen solver.tolerance, \
                 check the contact stiffness, or raise hub_inertia if the mass matrix lost definiteness"
            ),
            RotatingError::TooManyEvents { time, count } => {
                write!(f, "{count} contact switches within one step near t = {time}: raise solver.max_events_per_step")
            }
            RotatingError::InitialPenetration { penetration, limit } => write!(
                f,
                "the initial hub angle initial.theta puts the tip {penetration:e} m into the surface, deeper than a run may \
                 start ({limit:e} m: the depth whose stored energy 2/5 K gamma^2.5 equals the beam's kinetic energy at the \
                 speed limit); start with the tip outside the surface or on it"
            ),
            RotatingError::TooMuchWork { time, steps } => write!(
                f,
                "{steps} integration steps within one communication step, stopped at t = {time}: take shorter \
                 communication steps or raise solver.max_steps_per_step"
            ),
        }
    }
}

impl std::error::Error for RotatingError {}
