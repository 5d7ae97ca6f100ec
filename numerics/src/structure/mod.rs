//! Modal bases: natural frequencies and mass-normalised mode shapes of the
//! structures a scene can describe.

pub mod beam;
pub mod chain;
pub mod rotating;
pub mod tip_spring;

pub use beam::{Beam, Support};
pub use chain::Chain;
pub use tip_spring::TipSpringCantilever;

/// Where on a structure something acts or is measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Point {
    /// Distance from the left end of a beam.
    Along(f64),
    /// A mass of a chain (from 1).
    Mass(usize),
}

/// A structure and its retained modes.
#[derive(Clone, Debug, PartialEq)]
pub enum Structure {
    Beam(Beam),
    Chain(Chain),
}

impl Structure {
    pub fn n_modes(&self) -> usize {
        match self {
            Structure::Beam(b) => b.n_modes(),
            Structure::Chain(c) => c.n_modes(),
        }
    }

    pub fn omega(&self, j: usize) -> f64 {
        match self {
            Structure::Beam(b) => b.omega(j),
            Structure::Chain(c) => c.omega(j),
        }
    }

    /// Mass-normalised displacement shape of mode `j` at a point.
    pub fn shape(&self, j: usize, p: Point) -> f64 {
        match (self, p) {
            (Structure::Beam(b), Point::Along(x)) => b.shape(j, x),
            (Structure::Chain(c), Point::Mass(i)) => c.shape(j, i),
            _ => panic!("point {p:?} does not belong to this structure (validated with the scene)"),
        }
    }

    /// Modal load of a uniform acceleration field `a` acting on every mass
    /// element: `-a int mu W_j` (beam) or `-a sum m phi_j` (chain).
    pub fn inertial_participation(&self, j: usize) -> f64 {
        match self {
            Structure::Beam(b) => b.mass_per_length * b.shape_integral(j),
            Structure::Chain(c) => c.mass_participation(j),
        }
    }

    /// The factor from mass-normalised modal coordinates to coordinates in
    /// displacement units (`q = scale q_out`): `sqrt(mu L)` for beams,
    /// `sqrt(m)` for chains.
    pub fn coordinate_scale(&self) -> f64 {
        match self {
            Structure::Beam(b) => (b.mass_per_length * b.length).sqrt(),
            Structure::Chain(c) => c.m.sqrt(),
        }
    }
}
