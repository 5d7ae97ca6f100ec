//! Periodic orbits of the closed-form kinds, found directly (issue 33).
//!
//! - [`shooting`]: Newton on the stroboscopic map with the exact monodromy
//!   matrix (the flow's Jacobian through every phase and event,
//!   [`crate::kind::Flow`]), and the orbit's Floquet multipliers.
//! - [`profile`]: what an orbit does over its period (peak, impacts,
//!   sticks, its closest smooth approach to a stop).
//! - [`continuation`]: pseudo-arclength continuation of orbits in any
//!   scene parameter, with its special points (folds, period doubling
//!   with a switch onto the doubled branch, Neimark-Sacker, grazing,
//!   sticking boundaries).
//! - [`table`]: the branches and special points as CSV files.
//!
//! Everything works through the simulation contract: a run starts from a
//! state ([`crate::kind::Scene::start_from_state`]), a parameter is named
//! as its FMU names it, and a kind whose runs have an exact flow
//! ([`crate::kind::Flow`]) serves the rest.

pub mod continuation;
pub mod profile;
pub mod shooting;
pub mod table;

pub use continuation::{continue_orbits, continue_orbits_observed, Branch, Continuation, Diagram, Observer, Point, Silent, Special, SpecialKind};
pub use profile::{profile, Approach, Profile};
pub use shooting::{check_flow, minimal_period, shoot, start_from, strobe, Orbit, Shooting};
