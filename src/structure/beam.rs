//! Euler-Bernoulli beams: frequencies `omega_j = beta_j^2 sqrt(EI / (mu L^4))`
//! and shapes normalised so that `int_0^L mu W_j^2 dx = 1` (seed 000 eqs.
//! 10-12). Positions `x` are along the beam, `0 <= x <= L`.

use std::f64::consts::{PI, SQRT_2};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Support {
    PinnedPinned,
}

/// A uniform beam. In the seeds' scaled units `L = mu = EI = 1`.
#[derive(Clone, Debug, PartialEq)]
pub struct Beam {
    pub support: Support,
    pub n_modes: usize,
    pub length: f64,
    /// Mass per unit length `rho A`.
    pub mass_per_length: f64,
    /// Bending stiffness `E I`.
    pub bending_stiffness: f64,
}

impl Beam {
    pub fn scaled(support: Support, n_modes: usize) -> Self {
        Beam { support, n_modes, length: 1.0, mass_per_length: 1.0, bending_stiffness: 1.0 }
    }

    /// The dimensionless wavenumber `beta_j` (`j` from 1).
    pub fn beta(&self, j: usize) -> f64 {
        match self.support {
            Support::PinnedPinned => j as f64 * PI,
        }
    }

    /// Natural circular frequency of mode `j` (from 1).
    pub fn omega(&self, j: usize) -> f64 {
        let b = self.beta(j);
        b * b * (self.bending_stiffness / (self.mass_per_length * self.length.powi(4))).sqrt()
    }

    /// Scale from the dimensionless shape `W~(xi)` (unit mean square) to the
    /// mass-normalised shape `W(x) = W~(x / L) / sqrt(mu L)`.
    fn amplitude(&self) -> f64 {
        1.0 / (self.mass_per_length * self.length).sqrt()
    }

    /// Mass-normalised shape `W_j(x)`.
    pub fn shape(&self, j: usize, x: f64) -> f64 {
        let xi = x / self.length;
        self.amplitude()
            * match self.support {
                Support::PinnedPinned => SQRT_2 * (self.beta(j) * xi).sin(),
            }
    }

    /// Curvature `W_j''(x)`; the bending moment is `EI sum_j W_j'' q_j`.
    pub fn curvature(&self, j: usize, x: f64) -> f64 {
        let xi = x / self.length;
        let b = self.beta(j);
        self.amplitude() / (self.length * self.length)
            * match self.support {
                Support::PinnedPinned => -SQRT_2 * b * b * (b * xi).sin(),
            }
    }

    /// `int_0^L W_j dx`: the modal participation of a uniform load per unit
    /// length (seed 000 eq. 13, `alpha_j`).
    pub fn shape_integral(&self, j: usize) -> f64 {
        let b = self.beta(j);
        self.amplitude()
            * self.length
            * match self.support {
                Support::PinnedPinned => SQRT_2 * (1.0 - (j as f64 * PI).cos()) / b,
            }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Independent check: composite Simpson quadrature of the shapes.
    fn simpson(f: impl Fn(f64) -> f64, a: f64, b: f64, n: usize) -> f64 {
        let h = (b - a) / n as f64;
        let mut s = f(a) + f(b);
        for i in 1..n {
            s += f(a + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
        }
        s * h / 3.0
    }

    #[test]
    fn pinned_shapes_are_mass_normalised_and_orthogonal() {
        let beam = Beam { support: Support::PinnedPinned, n_modes: 6, length: 2.0, mass_per_length: 3.0, bending_stiffness: 5.0 };
        for j in 1..=6 {
            for k in 1..=6 {
                let m = simpson(|x| 3.0 * beam.shape(j, x) * beam.shape(k, x), 0.0, 2.0, 4000);
                assert!((m - if j == k { 1.0 } else { 0.0 }).abs() < 1e-12, "{j} {k} {m}");
            }
            let integral = simpson(|x| beam.shape(j, x), 0.0, 2.0, 4000);
            assert!((integral - beam.shape_integral(j)).abs() < 1e-12);
            // Stiffness: int EI W'' ^2 = omega^2.
            let k = simpson(|x| 5.0 * beam.curvature(j, x).powi(2), 0.0, 2.0, 4000);
            assert!((k / beam.omega(j).powi(2) - 1.0).abs() < 1e-10);
        }
    }
}
