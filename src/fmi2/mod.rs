//! The FMI 2.0 co-simulation shell over the shared core (`crate::fmi`):
//! `api` holds the C entry points, `state_machine` the table of legal
//! calls, `types` the C types, `description` the modelDescription.xml.

#[cfg(feature = "fmi2")]
pub mod api;
pub mod description;
pub mod state_machine;
pub mod types;
