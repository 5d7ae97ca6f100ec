//! What the FMI 2.0 and FMI 3.0 co-simulation shells share: one instance
//! core over the simulation contract (`instance`: parameters, inputs,
//! outputs, steps, snapshots), its variable table, the logger, the
//! resource location, the FMU states handed out (`states`), the serialized
//! state, the XML both modelDescriptions write (`xml`) and the panic boundary of the
//! C entry points. Each shell (`crate::fmi2`, `crate::fmi3`) adds only its
//! C signatures, its state-machine table and its modelDescription.xml.

pub mod boundary;
pub mod instance;
pub mod logging;
pub mod resource;
pub mod serialize;
pub mod state;
pub mod states;
pub mod variables;
pub mod xml;

pub use state::{Call, ModelState, Status};
