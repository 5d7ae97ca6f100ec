//! The FMI 2.0 co-simulation interface: the only part of beamstop that
//! knows about FMI. `api` holds the C entry points, `instance` their
//! semantics, `state_machine` the table of legal calls, `variables` the
//! value references, `description` the modelDescription.xml.

pub mod api;
pub mod description;
pub mod instance;
pub mod logging;
pub mod resource;
pub mod serialize;
pub mod state_machine;
pub mod types;
pub mod variables;
