//! The simulation engine of a flexible beam on a rotating hub whose tip may
//! strike a fixed plane (DWZ: Duan, Wang & Zhang, "Impact dynamics of a
//! flexible beam with rotation": Hertz contact `F = K gamma^1.5 + C gamma'`,
//! eqs. 2-4; the equations of motion in [`crate::structure::rotating`]).
//!
//! - [`spec`]: the scene (serde, SI units) and its validation;
//! - [`model`]: the scene in numbers (beam matrices, surface, hub drive);
//! - [`system`]: one phase's equations as a first-order system (state
//!   layout, force, analytic Jacobian);
//! - [`stepper`]: the integrators, DOP853, the exponential integrator or
//!   Radau IIA (`solver.method`);
//! - [`frozen`]: the exponential integrator's frozen linear parts, on a
//!   grid of hub speeds, kept per model;
//! - [`events`]: the contact law's watched functions along a step, for
//!   the shared switch locator ([`crate::solve::switch`]);
//! - [`sim`]: the run ([`RotatingSimulation`]): steps, switches, restarts,
//!   outputs;
//! - `readings`: what the outputs read at one instant, made once;
//! - [`codec`]: the run's versioned encoding, replayed on decode;
//! - [`flow`]: a run with a periodically prescribed hub as a map of its
//!   modal state, and that map's Jacobian (periodic orbits);
//! - [`interface`]: the scene's parameters, input and outputs;
//! - `kind`: the contract's side ([`RotatingKind`], [`RotatingRun`]).
//!
//! Unlike the modal simulation ([`crate::kinds::modal::sim`]), nothing here is closed
//! form: the rotating beam is nonlinear everywhere, so the whole motion is
//! integrated, free flight included.

mod kind;
pub mod codec;
pub mod events;
pub mod frozen;
// The flow map serves the orbits tool only: FMU binaries leave it out.
#[cfg(feature = "tools")]
pub mod flow;
pub mod interface;
pub mod model;
mod readings;
pub mod sim;
pub mod spec;
pub mod stepper;
pub mod system;

pub use codec::ROTATING_STATE_VERSION;
pub use model::{HubMotion, RotatingModel, SpinUp, Swing};
pub use sim::{RotatingEvent, RotatingEventKind, RotatingSimulation, RotatingStats};
pub use spec::RotatingSpec;

pub use kind::{RotatingKind, RotatingRun};
