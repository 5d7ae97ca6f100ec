//! Stop laws: what happens at a contact point when it reaches its stop.

pub mod restitution;

pub use restitution::{apply_impact, ImpactRow};
