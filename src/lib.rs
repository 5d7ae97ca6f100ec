//! beamstop: vibro-impacting flexible beams as FMI 2.0 co-simulation units.
//!
//! Data flows one way: [`scene`] (what the user describes) -> [`model`]
//! (modal numbers) -> [`sim`] (state and events) -> [`fmi2`] (the C ABI).
//! The rotating beam has its own scene, model and run in [`rotating`];
//! [`component`] puts both kinds behind one face for the FMI layer.
//! Nothing below `fmi2` knows about FMI.

pub mod codec;
pub mod component;
pub mod contact;
pub mod fmi2;
pub mod interface;
pub mod model;
pub mod package;
pub mod readout;
pub mod rotating;
pub mod scene;
pub mod sim;
pub mod solve;
pub mod structure;
pub mod units;

pub use component::{Component, Run};
pub use model::Model;
pub use scene::Scene;
pub use sim::{Event, EventKind, SimError, Simulation};
