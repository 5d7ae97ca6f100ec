//! beamstop: vibro-impacting flexible beams as FMI 2.0 co-simulation units.
//!
//! Data flows one way: a scene file -> a kind's model -> its simulation
//! -> the FMI layer. [`kind`] is the contract every kind of simulation
//! implements (its scene, its variables, its runs); [`kinds`] holds the
//! ones shipped here, each in a folder of its own and registered in one
//! place: the modal structures ([`kinds::modal`]: scene -> model -> sim,
//! exact between events) and the rotating hub beam ([`kinds::rotating`],
//! integrated). Beside them the shared physics ([`contact`],
//! [`structure`], [`solve`]), [`component`] (a scene of any kind with its
//! current parameter values), the FMI layer ([`fmi`], [`fmi2`], [`fmi3`],
//! [`package`]) and the tools ([`orbits`], the command line), written
//! once against the contract. Nothing below the FMI layer knows about FMI.

// A build of part of the library (an FMU variant: some kinds, laws and
// standards; see Cargo.toml's features) leaves the rest unused: only the
// full build, which the tests and lints use, warns about unused code.
#![cfg_attr(
    not(all(
        feature = "modal",
        feature = "rotating",
        feature = "restitution",
        feature = "spring-dashpot",
        feature = "power-law",
        feature = "fmi2",
        feature = "fmi3",
        feature = "register",
        feature = "tools"
    )),
    allow(dead_code, unused_imports, unused_variables, unused_mut, unreachable_code, unreachable_patterns)
)]

// `beamstop::` paths inside the crate too: the FMI entry points
// (src/fmi2/api.rs, src/fmi3/api.rs and absent.rs) are compiled here for
// the full build and by fmu/ for a variant, from the same files.
extern crate self as beamstop;

pub mod codec;
pub mod component;
pub mod contact;
pub mod error;
pub mod fields;
pub mod fmi;
pub mod fmi2;
pub mod fmi3;
pub mod kind;
pub mod kinds;
#[cfg(feature = "tools")]
pub mod orbits;
#[cfg(feature = "tools")]
pub mod package;
// The numerics (solvers, propagators, event search) and the structures'
// modes live in a crate of their own (numerics/): compiled once, not once
// per FMU variant; their paths stay `beamstop::solve`, `beamstop::structure`.
pub use beamstop_numerics::{solve, structure};
pub mod units;
pub mod variables;

pub use component::Component;
pub use error::SimError;
pub use kind::{Kind, Run};
