//! beamstop's numerics, apart from its kinds, contact laws and FMI layer
//! (they are re-exported as `beamstop::solve` and `beamstop::structure`):
//! [`solve`] propagates linear modal dynamics in closed form, decomposes
//! contact phases, integrates the nonlinear ones (force collocation,
//! DOP853, Radau, the exponential integrator) and finds events;
//! [`structure`] gives the beams' and chains' modes. A crate of its own so
//! that the FMU variants, which differ only in the kinds and laws they
//! carry, share one build of it; it has no features.

pub mod solve;
pub mod structure;
