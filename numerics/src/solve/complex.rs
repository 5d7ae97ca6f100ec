//! The complex number type of the propagators (its own module, so that
//! [`super::elementary`] and [`super::oscillator`] both use it without
//! importing from each other).

use nalgebra::Complex;

/// A complex number of two `f64`.
pub type C64 = Complex<f64>;
