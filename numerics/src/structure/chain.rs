//! The N-mass chain of WB00 (Wagg & Bishop 2000, Fig. 1): equal masses
//! m, springs k and dampers c from the ground to mass 1 and between
//! neighbours, mass N free on one side (where the stop acts).
//!
//! `[C] = c[E]`, `[K] = k[E]` with the coupling matrix E (eq. 1), so the
//! damping is proportional: `omega_j = sqrt(lambda_j k / m)`,
//! `zeta_j = (c / 2) sqrt(lambda_j / (k m))` (eqs. 3-4). Mode shapes are
//! mass-normalised, `phi_j = xi_j / sqrt(m)` with `|xi_j| = 1`.

use nalgebra::{DMatrix, SymmetricEigen};

#[derive(Clone, Debug, PartialEq)]
pub struct Chain {
    pub masses: usize,
    pub m: f64,
    pub k: f64,
    pub c: f64,
    /// Eigenvalues of E, ascending.
    lambda: Vec<f64>,
    /// Unit eigenvectors (columns), sign fixed so the last mass moves positively.
    xi: DMatrix<f64>,
}

/// The coupling matrix: tridiagonal (-1, 2, -1), last diagonal entry 1.
pub fn coupling_matrix(n: usize) -> DMatrix<f64> {
    DMatrix::from_fn(n, n, |i, j| {
        if i == j {
            if i + 1 == n {
                1.0
            } else {
                2.0
            }
        } else if i.abs_diff(j) == 1 {
            -1.0
        } else {
            0.0
        }
    })
}

impl Chain {
    pub fn new(masses: usize, m: f64, k: f64, c: f64) -> Self {
        let eig = SymmetricEigen::new(coupling_matrix(masses));
        let mut order: Vec<usize> = (0..masses).collect();
        order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
        let lambda = order.iter().map(|&i| eig.eigenvalues[i]).collect();
        let mut xi = DMatrix::from_fn(masses, masses, |r, col| eig.eigenvectors[(r, order[col])]);
        for mut col in xi.column_iter_mut() {
            let sign = if col[masses - 1] < 0.0 { -1.0 } else { 1.0 };
            col *= sign / col.norm();
        }
        Chain { masses, m, k, c, lambda, xi }
    }

    pub fn n_modes(&self) -> usize {
        self.masses
    }

    pub fn omega(&self, j: usize) -> f64 {
        (self.lambda[j - 1] * self.k / self.m).sqrt()
    }

    /// `zeta_j = (c / 2) sqrt(lambda_j / (k m))` (WB00 eq. 4).
    pub fn zeta(&self, j: usize) -> f64 {
        0.5 * self.c * (self.lambda[j - 1] / (self.k * self.m)).sqrt()
    }

    /// Mass-normalised shape: displacement of mass `i` (from 1) in mode `j`.
    pub fn shape(&self, j: usize, i: usize) -> f64 {
        self.xi[(i - 1, j - 1)] / self.m.sqrt()
    }

    /// `sum_i m phi_j(i)`: the modal participation of a uniform ground
    /// acceleration.
    pub fn mass_participation(&self, j: usize) -> f64 {
        (1..=self.masses).map(|i| self.m * self.shape(j, i)).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn modes_diagonalise_mass_stiffness_and_damping() {
        let chain = Chain::new(5, 2.0, 3.0, 0.4);
        let e = coupling_matrix(5);
        let phi = DMatrix::from_fn(5, 5, |i, j| chain.shape(j + 1, i + 1));
        let mass = phi.transpose() * DMatrix::identity(5, 5) * 2.0 * &phi;
        let stiff = phi.transpose() * (&e * 3.0) * &phi;
        let damp = phi.transpose() * (&e * 0.4) * &phi;
        for i in 0..5 {
            for j in 0..5 {
                let d = if i == j { 1.0 } else { 0.0 };
                assert!((mass[(i, j)] - d).abs() < 1e-13);
                assert!((stiff[(i, j)] - d * chain.omega(i + 1).powi(2)).abs() < 1e-12);
                assert!((damp[(i, j)] - d * 2.0 * chain.zeta(i + 1) * chain.omega(i + 1)).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn two_mass_chain_closed_form() {
        // E = [[2, -1], [-1, 1]]: lambda = (3 -+ sqrt 5) / 2.
        let chain = Chain::new(2, 1.0, 1.0, 0.1);
        assert!((chain.omega(1).powi(2) - (3.0 - 5f64.sqrt()) / 2.0).abs() < 1e-15);
        assert!((chain.omega(2).powi(2) - (3.0 + 5f64.sqrt()) / 2.0).abs() < 1e-15);
    }
}
