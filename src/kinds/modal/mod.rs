//! The modal structures (Euler-Bernoulli beams with any of four supports,
//! mass-spring chains) with stops, as a kind of simulation: scene files
//! with a `structure`, exact between events.
//!
//! - [`scene`]: the scene file (serde) and its validation;
//! - [`model`]: the scene in numbers (modes, stops, loads, sensors);
//! - [`interface`]: the scene's parameters, inputs and outputs;
//! - [`readout`]: the outputs' values from a run;
//! - [`sim`]: the run: closed-form segments between events, the event
//!   search, the event handling, integrated contact phases, the codec;
//! - `kind`: the contract's side ([`ModalKind`], [`ModalRun`]).

mod kind;
pub mod interface;
pub mod model;
pub mod readout;
pub mod scene;
pub mod sim;

pub use kind::{ModalKind, ModalRun};
