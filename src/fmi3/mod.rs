//! The FMI 3.0 co-simulation shell over the shared core (`crate::fmi`),
//! beside the FMI 2.0 one: `api` holds the C entry points of
//! fmi3Functions.h this FMU implements, `absent` the ones of what it does
//! not have (refused with the reason), `instance` what event mode and early return make of
//! a step, `state_machine` the table of legal calls, `types` the C types,
//! `description` the modelDescription.xml.

#[cfg(feature = "fmi3")]
pub mod absent;
#[cfg(feature = "fmi3")]
pub mod api;
pub mod description;
pub mod instance;
pub mod state_machine;
pub mod types;
