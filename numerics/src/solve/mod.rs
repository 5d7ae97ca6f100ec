//! Exact propagators and guaranteed event location.
//!
//! Between events every phase is linear: free flight is a set of uncoupled
//! damped oscillators ([`free`]); sticking and compliant contact couple the
//! modes ([`lti`]). Both are propagated in closed form from the state at the
//! last event, and [`events`] finds the next switch of any of them.
//! A modal phase with a nonlinear contact force (Hertz) is stepped by
//! [`collocation`]: the force a polynomial over a step, every mode exact
//! under it ([`phi`]); the rotating beam, nonlinear in its whole state, by
//! [`dop853`] (explicit, order 8) or, where it is stiff, [`radau`], an
//! L-stable Radau IIA (order 5) with honest Newton checks.

pub mod collocation;
pub mod complex;
pub mod dop853;
pub mod elementary;
pub mod events;
pub mod extremum;
pub mod forcing;
pub mod free;
pub mod functional;
pub mod lti;
pub mod exponential;
pub mod lu;
pub mod matvec;
pub mod modal_state;
pub mod oscillator;
pub mod phi;
pub mod quadrature;
pub mod radau;
pub mod regula_falsi;
pub mod switch;
pub mod wide;

/// An integrated phase (the rotating beam, a nonlinear stop's contact)
/// restarts from the end of its last step after this many steps without a
/// switch (a new anchor): a restored state never replays more. The count
/// follows the step sequence alone, so results stay independent of the
/// communication step.
pub const REANCHOR_AFTER: u64 = 2000;

/// Step sizes of the integrators whose steps need per-size kernels (force
/// collocation, exponential integration) are powers of `2^(1 /
/// STEP_LADDER)`: neighbouring steps share those kernels.
pub const STEP_LADDER: f64 = 4.0;

/// The largest step size of the ladder not above `h`.
pub fn step_ladder(h: f64) -> f64 {
    (f64::floor(h.log2() * STEP_LADDER) / STEP_LADDER).exp2()
}

pub use complex::C64;
pub use forcing::{Harmonic, ModalForcing};
pub use free::{FreeDynamics, FreeSegment};
pub use functional::{DerivativeBounds, Functional, Jet};
pub use modal_state::ModalState;
pub use oscillator::Oscillator;
