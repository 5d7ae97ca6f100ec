//! Euler-Bernoulli beams: frequencies `omega_j = beta_j^2 sqrt(EI / (mu L^4))`
//! and shapes normalised so that `int_0^L mu W_j^2 dx = 1` (VSM12 eqs.
//! 10-12). Positions `x` run along the beam, `0 <= x <= L`.
//!
//! Shapes are written with decaying exponentials only (as Goncalves,
//! Brennan & Elliott, J. Sound Vib. 301 (2007) 1035-1039, recommend):
//! `W~(xi) = a1 cos(b xi) + a2 sin(b xi) + a3 e^{-b (1 - xi)} + a4 e^{-b xi}`,
//! the four coefficients from the boundary conditions, so no term grows like
//! `cosh(b)`: the textbook `cosh - cos - s (sinh - sin)` loses every digit
//! past mode 12, this form keeps ~1e-14 to mode 500.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};


use nalgebra::{Matrix4, Vector4};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Support {
    PinnedPinned,
    ClampedFree,
    ClampedClamped,
    ClampedPinned,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum End {
    Pinned,
    Clamped,
    Free,
}

impl Support {
    fn ends(self) -> (End, End) {
        match self {
            Support::PinnedPinned => (End::Pinned, End::Pinned),
            Support::ClampedFree => (End::Clamped, End::Free),
            Support::ClampedClamped => (End::Clamped, End::Clamped),
            Support::ClampedPinned => (End::Clamped, End::Pinned),
        }
    }

    /// `beta_j` (j from 1): the j-th root of the characteristic equation,
    /// in a form with no growing hyperbolic function, by Newton's method.
    pub fn beta(self, j: usize) -> f64 {
        let jf = j as f64;
        // (f, f') of the characteristic function and the starting point.
        let (start, f): (f64, fn(f64) -> (f64, f64)) = match self {
            Support::PinnedPinned => return jf * PI,
            // cos b cosh b + 1 = 0  <=>  cos b + sech b = 0
            Support::ClampedFree => ((2.0 * jf - 1.0) * FRAC_PI_2, |b| {
                let sech = 1.0 / b.cosh();
                (b.cos() + sech, -b.sin() - sech * b.tanh())
            }),
            // cos b cosh b - 1 = 0  <=>  cos b - sech b = 0
            Support::ClampedClamped => ((2.0 * jf + 1.0) * FRAC_PI_2, |b| {
                let sech = 1.0 / b.cosh();
                (b.cos() - sech, -b.sin() + sech * b.tanh())
            }),
            // tan b = tanh b  <=>  sin b - cos b tanh b = 0
            Support::ClampedPinned => ((4.0 * jf + 1.0) * FRAC_PI_4, |b| {
                let t = b.tanh();
                (b.sin() - b.cos() * t, b.cos() + b.sin() * t - b.cos() * (1.0 - t * t))
            }),
        };
        let mut b = start;
        for _ in 0..60 {
            let (v, d) = f(b);
            let step = v / d;
            b -= step;
            if step.abs() <= 1e-16 * b {
                break;
            }
        }
        b
    }
}

/// One mode in dimensionless form: `beta` and the coefficients of `W~`,
/// normalised to `int_0^1 W~^2 = 1`.
#[derive(Clone, Debug, PartialEq)]
pub struct DimensionlessMode {
    pub beta: f64,
    a: [f64; 4],
}

/// Values of the four basis functions and their derivatives (each divided
/// by `b^k`) at `xi`: rows k = 0..=3.
fn basis(beta: f64, xi: f64) -> [[f64; 4]; 4] {
    let (s, c) = (beta * xi).sin_cos();
    let e1 = (-beta * (1.0 - xi)).exp();
    let e2 = (-beta * xi).exp();
    [
        [c, s, e1, e2],
        [-s, c, e1, -e2],
        [-c, -s, e1, e2],
        [s, -c, e1, -e2],
    ]
}

fn end_rows(end: End) -> [usize; 2] {
    match end {
        End::Clamped => [0, 1],
        End::Pinned => [0, 2],
        End::Free => [2, 3],
    }
}

/// `int_0^1 f` by composite 16-point Gauss-Legendre on `panels` panels.
pub fn integrate(f: impl Fn(f64) -> f64, panels: usize) -> f64 {
    crate::solve::quadrature::integrate(0.0, 1.0, panels, f)
}

impl DimensionlessMode {
    pub fn new(support: Support, j: usize) -> Self {
        let beta = support.beta(j);
        let (left, right) = support.ends();
        let at0 = basis(beta, 0.0);
        let at1 = basis(beta, 1.0);
        let rows: Vec<[f64; 4]> = end_rows(left).iter().map(|&k| at0[k]).chain(end_rows(right).iter().map(|&k| at1[k])).collect();
        let m = Matrix4::from_fn(|i, k| rows[i][k]);
        // The null vector: the right singular vector of the smallest singular value.
        let svd = m.svd(false, true);
        let vt = svd.v_t.expect("requested");
        let smallest = (0..4).min_by(|&a, &b| svd.singular_values[a].total_cmp(&svd.singular_values[b])).expect("4 values");
        let v: Vector4<f64> = vt.row(smallest).transpose();
        let mut mode = DimensionlessMode { beta, a: [v[0], v[1], v[2], v[3]] };
        // Unit mean square, by quadrature with ~8 panels per half wave.
        let panels = 8 * (j + 2);
        let norm = integrate(|xi| mode.derivative(0, xi).powi(2), panels).sqrt();
        // Sign: positive slope at a pinned left end, positive curvature at a clamped one.
        let k = if left == End::Pinned { 1 } else { 2 };
        let sign = if mode.derivative(k, 0.0) < 0.0 { -1.0 } else { 1.0 };
        for a in mode.a.iter_mut() {
            *a *= sign / norm;
        }
        mode
    }

    /// `d^k W~ / d xi^k` at `xi` (k <= 3).
    pub fn derivative(&self, k: usize, xi: f64) -> f64 {
        let b = basis(self.beta, xi);
        let v: f64 = (0..4).map(|i| self.a[i] * b[k][i]).sum();
        v * self.beta.powi(k as i32)
    }

    /// [`Self::derivative`] for `k = 0..=3` from one evaluation of the
    /// basis (the same values).
    pub fn derivatives(&self, xi: f64) -> [f64; 4] {
        let b = basis(self.beta, xi);
        std::array::from_fn(|k| (0..4).map(|i| self.a[i] * b[k][i]).sum::<f64>() * self.beta.powi(k as i32))
    }
}

/// A uniform beam. In scaled units (VSM12's) `L = mu = EI = 1`.
#[derive(Clone, Debug, PartialEq)]
pub struct Beam {
    pub support: Support,
    pub length: f64,
    /// Mass per unit length `rho A`.
    pub mass_per_length: f64,
    /// Bending stiffness `E I`.
    pub bending_stiffness: f64,
    pub modes: Vec<DimensionlessMode>,
    /// `int_0^1 W~_j` for every mode.
    integrals: Vec<f64>,
}

impl Beam {
    pub fn new(support: Support, n_modes: usize, length: f64, mass_per_length: f64, bending_stiffness: f64) -> Self {
        Self::new_with(support, n_modes, length, mass_per_length, bending_stiffness, None)
    }

    /// [`Self::new`] with the dimensionless modes and their integrals of
    /// `earlier` (pure functions of the support and the mode's number:
    /// those of a beam built before, used when it has the same support and
    /// at least as many modes) instead of computing them again.
    pub fn new_with(support: Support, n_modes: usize, length: f64, mass_per_length: f64, bending_stiffness: f64, earlier: Option<&Beam>) -> Self {
        let (modes, integrals) = match earlier {
            Some(b) if b.support == support && b.modes.len() >= n_modes => (b.modes[..n_modes].to_vec(), b.integrals[..n_modes].to_vec()),
            _ => {
                let modes: Vec<DimensionlessMode> = (1..=n_modes).map(|j| DimensionlessMode::new(support, j)).collect();
                let integrals = modes.iter().enumerate().map(|(j, m)| integrate(|xi| m.derivative(0, xi), 8 * (j + 3))).collect();
                (modes, integrals)
            }
        };
        Beam { support, length, mass_per_length, bending_stiffness, modes, integrals }
    }

    pub fn scaled(support: Support, n_modes: usize) -> Self {
        Beam::new(support, n_modes, 1.0, 1.0, 1.0)
    }

    pub fn n_modes(&self) -> usize {
        self.modes.len()
    }

    /// Natural circular frequency of mode `j` (from 1).
    pub fn omega(&self, j: usize) -> f64 {
        let b = self.modes[j - 1].beta;
        b * b * (self.bending_stiffness / (self.mass_per_length * self.length.powi(4))).sqrt()
    }

    /// From the unit-mean-square shape to the mass-normalised one:
    /// `W(x) = W~(x / L) / sqrt(mu L)`.
    pub fn amplitude(&self) -> f64 {
        1.0 / (self.mass_per_length * self.length).sqrt()
    }

    /// Mass-normalised shape `W_j(x)`.
    pub fn shape(&self, j: usize, x: f64) -> f64 {
        self.amplitude() * self.modes[j - 1].derivative(0, x / self.length)
    }

    /// Curvature `W_j''(x)`; the bending moment is `EI sum_j W_j'' q_j`.
    pub fn curvature(&self, j: usize, x: f64) -> f64 {
        self.amplitude() / (self.length * self.length) * self.modes[j - 1].derivative(2, x / self.length)
    }

    /// `int_0^L W_j dx`: the modal participation of a uniform load per unit
    /// length (VSM12 eq. 13, `alpha_j`).
    pub fn shape_integral(&self, j: usize) -> f64 {
        self.amplitude() * self.length * self.integrals[j - 1]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::SQRT_2;

    #[test]
    fn all_derivatives_at_once_are_each_ones_bits() {
        for support in [Support::PinnedPinned, Support::ClampedFree, Support::ClampedClamped, Support::ClampedPinned] {
            for j in [1, 2, 7, 40] {
                let mode = DimensionlessMode::new(support, j);
                for xi in [0.0, 0.013, 0.5, 0.77, 1.0] {
                    let all = mode.derivatives(xi);
                    for k in 0..4 {
                        assert_eq!(all[k].to_bits(), mode.derivative(k, xi).to_bits(), "{support:?} mode {j} xi {xi} k {k}");
                    }
                }
            }
        }
    }

    /// The textbook closed form for the cantilever (an independent
    /// writing of the same function).
    fn cantilever_note(beta: f64, x: f64) -> f64 {
        let e = (-beta).exp();
        let (s, c) = beta.sin_cos();
        let den = 1.0 + (2.0 * s - e) * e;
        let sigma = (1.0 + (2.0 * c + e) * e) / den;
        -(beta * x).cos() + sigma * (beta * x).sin() + (s - c - e) * (beta * (x - 1.0)).exp() / den
            + (1.0 + sigma) / 2.0 * (-beta * x).exp()
    }

    #[test]
    fn cantilever_roots_match_the_reference_values() {
        let want = [1.8751040687119612, 4.6940911329741746, 7.8547574382376126, 10.995540734875467, 14.137168391046471];
        for (j, w) in want.iter().enumerate() {
            assert!((Support::ClampedFree.beta(j + 1) - w).abs() < 1e-14, "{j}");
        }
        assert!((Support::ClampedFree.beta(10) - 29.845130209102817).abs() < 1e-13);
        assert!((Support::ClampedFree.beta(20) - 61.26105674500097).abs() < 1e-13);
        assert!((Support::ClampedFree.beta(50) - 155.50883635269477).abs() < 1e-12);
    }

    #[test]
    fn cantilever_shapes_match_the_note_to_mode_100() {
        for j in [1, 2, 3, 12, 13, 40, 100] {
            let m = DimensionlessMode::new(Support::ClampedFree, j);
            for &x in &[0.0, 0.1, 0.37, 0.5, 0.83, 0.99, 1.0] {
                let a = m.derivative(0, x);
                let b = cantilever_note(m.beta, x);
                assert!((a - b).abs() < 1e-12, "mode {j} x {x}: {a} vs {b}");
            }
            // Tip value 2 (-1)^(j+1), integral 2 sigma / beta.
            assert!((m.derivative(0, 1.0) - 2.0 * if j % 2 == 1 { 1.0 } else { -1.0 }).abs() < 1e-12);
        }
    }

    #[test]
    fn pinned_shapes_are_the_sines() {
        let beam = Beam::scaled(Support::PinnedPinned, 5);
        for j in 1..=5 {
            for &x in &[0.1, 0.4, 0.77] {
                assert!((beam.shape(j, x) - SQRT_2 * (j as f64 * PI * x).sin()).abs() < 1e-14);
            }
            let alpha = SQRT_2 * (1.0 - (j as f64 * PI).cos()) / (j as f64 * PI);
            assert!((beam.shape_integral(j) - alpha).abs() < 1e-14);
        }
    }

    #[test]
    fn every_support_satisfies_its_boundary_conditions_and_is_orthonormal() {
        for support in [Support::PinnedPinned, Support::ClampedFree, Support::ClampedClamped, Support::ClampedPinned] {
            let modes: Vec<DimensionlessMode> = (1..=30).map(|j| DimensionlessMode::new(support, j)).collect();
            let (left, right) = support.ends();
            for m in &modes {
                let scale = |k: usize| m.beta.powi(k as i32);
                for k in end_rows(left) {
                    assert!(m.derivative(k, 0.0).abs() < 1e-12 * scale(k), "{support:?} b={} k={k} at 0", m.beta);
                }
                for k in end_rows(right) {
                    assert!(m.derivative(k, 1.0).abs() < 1e-12 * scale(k), "{support:?} b={} k={k} at 1", m.beta);
                }
            }
            for (i, a) in modes.iter().enumerate().step_by(7) {
                for (j, b) in modes.iter().enumerate().step_by(5) {
                    let g = integrate(|x| a.derivative(0, x) * b.derivative(0, x), 400);
                    assert!((g - if i == j { 1.0 } else { 0.0 }).abs() < 1e-12, "{support:?} {i} {j} {g}");
                }
            }
        }
    }

    #[test]
    fn si_scaling_of_frequency_shape_and_load() {
        let beam = Beam::new(Support::ClampedFree, 3, 0.3, 0.314, 2.8);
        let b1 = Support::ClampedFree.beta(1);
        assert!((beam.omega(1) - b1 * b1 * (2.8f64 / (0.314 * 0.3f64.powi(4))).sqrt()).abs() < 1e-10);
        for j in 1..=3 {
            let m = integrate(|xi| 0.314 * 0.3 * beam.shape(j, xi * 0.3).powi(2), 200);
            assert!((m - 1.0).abs() < 1e-12);
            let k = integrate(|xi| 2.8 * 0.3 * beam.curvature(j, xi * 0.3).powi(2), 400);
            assert!((k / beam.omega(j).powi(2) - 1.0).abs() < 1e-10);
        }
    }
}
