//! Modal bases: natural frequencies and mass-normalised mode shapes.

pub mod beam;

pub use beam::{Beam, Support};
