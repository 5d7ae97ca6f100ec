//! A variant's FMI 2.0 entry points: beamstop's own file.

#[path = "../../src/fmi2/api.rs"]
pub mod api;
