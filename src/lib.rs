//! beamstop: vibro-impacting flexible beams as FMI 2.0 co-simulation units.
//!
//! Data flows one way: a scene file -> a kind's model -> its simulation
//! -> the FMI layer. [`kind`] is the contract every kind of simulation
//! implements (its scene, its variables, its runs), [`kinds`] registers
//! the ones shipped here: the modal structures ([`scene`] -> [`model`] ->
//! [`sim`], exact between events) and the rotating hub beam
//! ([`rotating`], integrated). [`component`] holds a scene of any kind
//! with its current parameter values; [`fmi2`], [`package`] and the
//! command line are written once against the contract. Nothing below
//! `fmi2` knows about FMI.

pub mod codec;
pub mod component;
pub mod contact;
pub mod error;
pub mod fields;
pub mod fmi;
pub mod fmi2;
pub mod fmi3;
pub mod interface;
pub mod kind;
pub mod kinds;
pub mod model;
pub mod orbits;
pub mod package;
pub mod readout;
pub mod rotating;
pub mod scene;
pub mod sim;
pub mod solve;
pub mod structure;
pub mod units;
pub mod variables;

pub use component::Component;
pub use error::SimError;
pub use kind::{Kind, Run};
pub use model::Model;
pub use scene::Scene;
pub use sim::{Event, EventKind, Simulation};
