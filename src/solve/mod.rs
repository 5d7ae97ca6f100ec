//! Exact propagators and guaranteed event location.
//!
//! Between events every phase is linear: free flight is a set of uncoupled
//! damped oscillators ([`free`]); sticking and compliant contact couple the
//! modes ([`lti`]). Both are propagated in closed form from the state at the
//! last event, and [`events`] finds the next switch of any of them.
//! Nonlinear phases (Hertz contact, rotating beams) are integrated by
//! [`radau`], an L-stable Radau IIA (order 5) with honest Newton checks;
//! a modal phase's Newton systems are solved in O(N) by [`low_rank`].

pub mod complex;
pub mod elementary;
pub mod events;
pub mod forcing;
pub mod free;
pub mod functional;
pub mod lti;
pub mod low_rank;
pub mod modal_state;
pub mod oscillator;
pub mod quadrature;
pub mod radau;
pub mod switch;

pub use complex::C64;
pub use forcing::{Harmonic, ModalForcing};
pub use free::{FreeDynamics, FreeSegment};
pub use functional::{DerivativeBounds, Functional, Jet};
pub use modal_state::ModalState;
pub use oscillator::Oscillator;
