//! A variant's FMI 3.0 entry points: beamstop's own files.

#[path = "../../src/fmi3/api.rs"]
pub mod api;
#[path = "../../src/fmi3/absent.rs"]
pub mod absent;
