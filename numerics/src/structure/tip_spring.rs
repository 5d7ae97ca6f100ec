//! A uniform Euler-Bernoulli cantilever (clamped at `x = 0`, free at
//! `x = L`) with a linear spring `k` from its tip to ground: the basis of
//! the contact phase in the mode transfer methods (MTM, and RMTM's own relative one) of the RMTM paper,
//! where the stop is that spring. See `docs/mode_transfer.md`.
//!
//! Dimensionless spring `kappa = k L^3 / EI`. With `xi = x / L` the mode
//! `W~'''' = b^4 W~` satisfies
//!   `W~(0) = W~'(0) = 0`, `W~''(1) = 0`, `W~'''(1) = kappa W~(1)`
//! (the tip shear balances the spring: `EI W'''(L) = k W(L)`), and its
//! frequency is `omega = b^2 sqrt(EI / (mu L^4))`; the mass is the beam's
//! alone, so shapes are normalised as in `beam.rs`: `int_0^L mu W^2 = 1`.
//!
//! As in `beam.rs` the shapes are written with decaying exponentials only,
//! `W~ = a1 cos(b xi) + a2 sin(b xi) + a3 e^{-b (1 - xi)} + a4 e^{-b xi}`,
//! and the frequency equation is divided by `cosh b`, so nothing grows with
//! the mode number.

use std::f64::consts::FRAC_PI_2;

use nalgebra::{DMatrix, Matrix4, Vector4};

use super::beam::{integrate, Beam, Support};
use crate::solve::quadrature::for_each_node;

/// `(sech b, tanh b)` from `e^{-2b}`, finite for every `b >= 0`.
fn sech_tanh(b: f64) -> (f64, f64) {
    let e = (-b).exp();
    let e2 = e * e;
    (2.0 * e / (1.0 + e2), (1.0 - e2) / (1.0 + e2))
}

/// `(G, dG/db)` of the frequency equation
///   `b^3 (1 + cos b cosh b) + kappa (sin b cosh b - cos b sinh b) = 0`
/// divided by `cosh b`:
///   `G(b) = b^3 (cos b + sech b) + kappa (sin b - cos b tanh b)`.
/// `kappa = 0` leaves the cantilever's `cos b + sech b`, `kappa -> inf` the
/// clamped-pinned `sin b - cos b tanh b` (both as in `Support::beta`).
fn frequency_function(kappa: f64, b: f64) -> (f64, f64) {
    let (s, c) = b.sin_cos();
    let (sech, tanh) = sech_tanh(b);
    let b3 = b * b * b;
    let free = c + sech;
    let pinned = s - c * tanh;
    let d_free = -s - sech * tanh;
    let d_pinned = c + s * tanh - c * sech * sech;
    (b3 * free + kappa * pinned, 3.0 * b * b * free + b3 * d_free + kappa * d_pinned)
}

/// `beta_j` (j from 1) of the cantilever with tip spring `kappa >= 0`.
///
/// Adding the spring raises every eigenvalue and pinning the tip is its
/// limit, so the root lies in `[beta_j(clamped-free), beta_j(clamped-pinned)]`
/// (the two interlace: `3.93 < 4.69 < 7.07 < 7.85 ...`), where `G` changes
/// sign; Newton's method is kept inside the shrinking bracket and replaced
/// by bisection whenever it would leave it.
pub fn beta(kappa: f64, j: usize) -> f64 {
    let lo = Support::ClampedFree.beta(j);
    let hi = Support::ClampedPinned.beta(j);
    if kappa == 0.0 {
        return lo;
    }
    if kappa == f64::INFINITY {
        return hi;
    }
    // G / (b^3 + kappa): bounded, to compare the two ends.
    let scaled = |b: f64| frequency_function(kappa, b).0 / (b * b * b + kappa);
    let (g_lo, g_hi) = (scaled(lo), scaled(hi));
    if g_lo == 0.0 || g_hi == 0.0 || g_lo.signum() == g_hi.signum() {
        // The root is within rounding of an end (kappa below ~1e-15 b^3 or
        // above ~1e15 b^3): take the end with the smaller residual.
        return if g_lo.abs() <= g_hi.abs() { lo } else { hi };
    }
    let (mut a, mut z) = (lo, hi); // G(a) has the sign of g_lo, G(z) the other
    // Start from the secant through the ends.
    let mut b = lo + (hi - lo) * g_lo / (g_lo - g_hi);
    for _ in 0..200 {
        let (g, dg) = frequency_function(kappa, b);
        if g == 0.0 {
            return b;
        }
        if g.signum() == g_lo.signum() {
            a = b;
        } else {
            z = b;
        }
        let newton = b - g / dg;
        let next = if newton.is_finite() && newton > a.min(z) && newton < a.max(z) { newton } else { 0.5 * (a + z) };
        if (next - b).abs() <= 2.0 * f64::EPSILON * b || (z - a).abs() <= 4.0 * f64::EPSILON * b {
            return next;
        }
        b = next;
    }
    b
}

/// Values of the four basis functions and their derivatives (each divided
/// by `b^k`) at `xi`: rows k = 0..=3 (as in `beam.rs`).
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

/// One mode in dimensionless form: `beta` and the coefficients of `W~`,
/// normalised to `int_0^1 W~^2 = 1`.
#[derive(Clone, Debug, PartialEq)]
pub struct SpringMode {
    pub beta: f64,
    a: [f64; 4],
}

impl SpringMode {
    pub fn new(kappa: f64, j: usize) -> Self {
        let beta = beta(kappa, j);
        let at0 = basis(beta, 0.0);
        let at1 = basis(beta, 1.0);
        // Tip shear `W~''' = kappa W~`, i.e. `b^3 row3 - kappa row0 = 0`,
        // divided by `b^3 + kappa` so the row stays O(1) for any kappa
        // (`kappa = inf`: the pinned tip `W~(1) = 0`).
        let b3 = beta * beta * beta;
        let (w3, w0) = if kappa.is_finite() { (b3 / (b3 + kappa), kappa / (b3 + kappa)) } else { (0.0, 1.0) };
        let tip: [f64; 4] = std::array::from_fn(|k| w3 * at1[3][k] - w0 * at1[0][k]);
        // Clamped at 0 (W~ = W~' = 0), no moment at 1 (W~'' = 0), tip shear.
        let rows = [at0[0], at0[1], at1[2], tip];
        let m = Matrix4::from_fn(|i, k| rows[i][k]);
        // The null vector: the right singular vector of the smallest singular value.
        let svd = m.svd(false, true);
        let vt = svd.v_t.expect("requested");
        let smallest = (0..4).min_by(|&a, &b| svd.singular_values[a].total_cmp(&svd.singular_values[b])).expect("4 values");
        let v: Vector4<f64> = vt.row(smallest).transpose();
        let mut mode = SpringMode { beta, a: [v[0], v[1], v[2], v[3]] };
        // Unit mean square, by quadrature with ~8 panels per half wave;
        // sign: positive curvature at the clamp (as `beam.rs`).
        let norm = integrate(|xi| mode.derivative(0, xi).powi(2), 8 * (j + 2)).sqrt();
        let sign = if mode.derivative(2, 0.0) < 0.0 { -1.0 } else { 1.0 };
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

    /// `W~(1)`. Once `kappa > b^3` the tip barely moves and the direct sum
    /// `a1 cos b + a2 sin b + a3 + ...` of O(1) terms keeps only an absolute
    /// ~1e-16; the tip condition `W~(1) = W~'''(1) / kappa` keeps it to
    /// relative rounding (so `k W(L)` is right to rounding at any `k`).
    pub fn tip(&self, kappa: f64) -> f64 {
        if kappa > self.beta.powi(3) {
            self.derivative(3, 1.0) / kappa
        } else {
            self.derivative(0, 1.0)
        }
    }

    /// `int_0^1 W~` in closed form:
    /// `(a1 sin b + a2 (1 - cos b) + (a3 + a4) (1 - e^{-b})) / b`.
    pub fn integral(&self) -> f64 {
        let b = self.beta;
        let [a1, a2, a3, a4] = self.a;
        (a1 * b.sin() + a2 * (1.0 - b.cos()) + (a3 + a4) * (1.0 - (-b).exp())) / b
    }
}

/// A uniform cantilever with a tip spring to ground.
#[derive(Clone, Debug, PartialEq)]
pub struct TipSpringCantilever {
    pub length: f64,
    /// Mass per unit length `rho A`.
    pub mass_per_length: f64,
    /// Bending stiffness `E I`.
    pub bending_stiffness: f64,
    /// Tip spring `k` (N/m in SI scenes).
    pub spring: f64,
    pub modes: Vec<SpringMode>,
}

impl TipSpringCantilever {
    pub fn new(n_modes: usize, length: f64, mass_per_length: f64, bending_stiffness: f64, spring: f64) -> Self {
        let kappa = spring * length.powi(3) / bending_stiffness;
        assert!(kappa >= 0.0, "tip spring must be >= 0 (kappa = {kappa})");
        let modes = (1..=n_modes).map(|j| SpringMode::new(kappa, j)).collect();
        TipSpringCantilever { length, mass_per_length, bending_stiffness, spring, modes }
    }

    /// `kappa = k L^3 / EI`.
    pub fn kappa(&self) -> f64 {
        self.spring * self.length.powi(3) / self.bending_stiffness
    }

    pub fn n_modes(&self) -> usize {
        self.modes.len()
    }

    /// Natural circular frequency of mode `j` (from 1).
    pub fn omega(&self, j: usize) -> f64 {
        let b = self.modes[j - 1].beta;
        b * b * (self.bending_stiffness / (self.mass_per_length * self.length.powi(4))).sqrt()
    }

    /// `W(x) = W~(x / L) / sqrt(mu L)`.
    pub fn amplitude(&self) -> f64 {
        1.0 / (self.mass_per_length * self.length).sqrt()
    }

    /// Mass-normalised shape `W_j(x)`.
    pub fn shape(&self, j: usize, x: f64) -> f64 {
        self.amplitude() * self.modes[j - 1].derivative(0, x / self.length)
    }

    /// `W_j(L)` to relative rounding (see `SpringMode::tip`); prefer it to
    /// `shape(j, L)` for the spring force `k W(L)` and the gap.
    pub fn tip(&self, j: usize) -> f64 {
        self.amplitude() * self.modes[j - 1].tip(self.kappa())
    }

    /// Curvature `W_j''(x)`.
    pub fn curvature(&self, j: usize, x: f64) -> f64 {
        self.amplitude() / (self.length * self.length) * self.modes[j - 1].derivative(2, x / self.length)
    }

    /// `int_0^L W_j dx` (the convention of `Beam::shape_integral`).
    pub fn shape_integral(&self, j: usize) -> f64 {
        self.amplitude() * self.length * self.modes[j - 1].integral()
    }
}

/// `T[(k, j)] = int_0^L mu Phi_k W_j dx`: spring modes `Phi_k` (rows)
/// against the plain cantilever modes `W_j` (columns) of `beam`, which must
/// be the same beam (clamped-free, same `L` and `mu`). Then
/// `int mu Phi_k W_j = int_0^1 Phi~_k W~_j d xi`, computed by 16-point
/// Gauss-Legendre panels of width `h` with `(b_max + b'_max) h <= pi / 2`
/// (exact to rounding: `for_each_node_band_limited`'s rule), every
/// integrand being a sum of `cos`, `sin` and exponentials of rate at most
/// `b_k + b_j`.
///
/// A modal state transfers as `p = T q`, `p' = T q'` (to the spring basis)
/// and `q = T^T p` (back): the mass-orthogonal projections of the
/// displacement and velocity fields.
pub fn overlap(spring: &TipSpringCantilever, beam: &Beam) -> DMatrix<f64> {
    assert_eq!(beam.support, Support::ClampedFree, "the plain modes must be the cantilever's");
    let same = |a: f64, b: f64| (a - b).abs() <= 1e-12 * a.abs().max(b.abs());
    assert!(same(spring.length, beam.length) && same(spring.mass_per_length, beam.mass_per_length), "not the same beam");
    let (n, m) = (spring.n_modes(), beam.n_modes());
    let mut t = DMatrix::zeros(n, m);
    if n == 0 || m == 0 {
        return t;
    }
    let rate = spring.modes[n - 1].beta + beam.modes[m - 1].beta;
    let panels = (rate / FRAC_PI_2).ceil().max(1.0) as usize;
    let mut nodes = Vec::with_capacity(16 * panels);
    for_each_node(0.0, 1.0, panels, |xi, w| nodes.push((xi, w)));
    // T += A^T B over blocks of nodes: A = weight * Phi~ (node x k), B = W~ (node x j).
    for block in nodes.chunks(512) {
        let a = DMatrix::from_fn(block.len(), n, |r, k| block[r].1 * spring.modes[k].derivative(0, block[r].0));
        let b = DMatrix::from_fn(block.len(), m, |r, j| beam.modes[j].derivative(0, block[r].0));
        t.gemm_tr(1.0, &a, &b, 1.0);
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DVector;
    use std::f64::consts::PI;

    /// SI beam of the `beam.rs` tests.
    const L: f64 = 0.3;
    const MU: f64 = 0.314;
    const EI: f64 = 2.8;

    fn spring_for(kappa: f64) -> f64 {
        kappa * EI / L.powi(3)
    }

    #[test]
    fn roots_are_bracketed_ordered_and_finite_for_every_kappa() {
        let kappas = [0.0, 1e-300, 1e-12, 1e-3, 0.1, 1.0, 10.0, 100.0, 1e4, 1e6, 1e10, 1e14];
        for j in 1..=300 {
            let (lo, hi) = (Support::ClampedFree.beta(j), Support::ClampedPinned.beta(j));
            let mut previous = 0.0;
            for &kappa in &kappas {
                let b = beta(kappa, j);
                assert!(b.is_finite() && b >= lo && b <= hi, "j {j} kappa {kappa}: {b} not in [{lo}, {hi}]");
                assert!(b >= previous, "j {j}: not increasing with kappa at {kappa}");
                previous = b;
                // Residual of the scaled equation at rounding level.
                let g = frequency_function(kappa, b).0 / (b.powi(3) + kappa);
                assert!(g.abs() < 1e-13 * b, "j {j} kappa {kappa}: residual {g}");
            }
            assert_eq!(beta(0.0, j), lo);
        }
        // The textbook form with cosh (fine for the first modes).
        for kappa in [0.5, 7.0, 300.0] {
            for j in 1..=4 {
                let b = beta(kappa, j);
                let f = b.powi(3) * (1.0 + b.cos() * b.cosh()) + kappa * (b.sin() * b.cosh() - b.cos() * b.sinh());
                assert!(f.abs() < 1e-11 * (b.powi(3) + kappa) * b.cosh(), "{kappa} {j}: {f}");
            }
        }
    }

    #[test]
    fn zero_spring_is_the_cantilever() {
        let beam = Beam::new(Support::ClampedFree, 100, L, MU, EI);
        let cant = TipSpringCantilever::new(100, L, MU, EI, 0.0);
        let a = beam.amplitude();
        for j in 1..=100 {
            assert!((cant.omega(j) / beam.omega(j) - 1.0).abs() < 1e-15, "{j}");
            let b2 = (cant.modes[j - 1].beta / L).powi(2);
            for &xi in &[0.0, 0.013, 0.3, 0.5, 0.77, 0.999, 1.0] {
                let x = xi * L;
                assert!((cant.shape(j, x) - beam.shape(j, x)).abs() < 1e-12 * a, "{j} {xi}");
                assert!((cant.curvature(j, x) - beam.curvature(j, x)).abs() < 1e-12 * a * b2, "{j} {xi}");
            }
            // Closed form against beam.rs's quadrature.
            assert!((cant.shape_integral(j) - beam.shape_integral(j)).abs() < 1e-13 * a * L, "{j}");
        }
    }

    #[test]
    fn stiff_spring_approaches_clamped_pinned() {
        let kappa = 1e14;
        let beam = Beam::new(Support::ClampedPinned, 50, L, MU, EI);
        let stiff = TipSpringCantilever::new(50, L, MU, EI, spring_for(kappa));
        let a = beam.amplitude();
        let mut worst = 0.0f64;
        for j in 1..=50 {
            let (b, b_cp) = (stiff.modes[j - 1].beta, beam.modes[j - 1].beta);
            // G(b_cp) = b^3 (cos + sech) and G' ~ kappa (cos + sin tanh) ~ kappa sqrt 2:
            // the root sits b_cp - b ~ b^3 / (2 kappa) below.
            assert!(b <= b_cp && b_cp - b <= b.powi(3) / kappa, "{j}: {b} {b_cp}");
            for &xi in &[0.1, 0.5, 0.9, 1.0] {
                let d = (stiff.shape(j, xi * L) - beam.shape(j, xi * L)).abs() / a;
                worst = worst.max(d);
                // The tip moves by W~(1) = W~'''(1) / kappa ~ sqrt 2 b^3 / kappa.
                assert!(d < 4.0 * b.powi(3) / kappa + 1e-12, "{j} {xi}: {d}");
            }
        }
        eprintln!("kappa 1e14: largest shape difference from clamped-pinned (j <= 50) {worst:.1e}");
        // An infinite spring is the pinned tip.
        let pinned = TipSpringCantilever::new(50, L, MU, EI, f64::INFINITY);
        for j in 1..=50 {
            assert_eq!(pinned.omega(j), beam.omega(j));
            assert_eq!(pinned.tip(j), 0.0);
            for &xi in &[0.1, 0.5, 0.9] {
                assert!((pinned.shape(j, xi * L) - beam.shape(j, xi * L)).abs() < 1e-12 * a, "{j} {xi}");
            }
        }
    }

    /// Eigenvalues of `diag(omega_i^2) + k w w^T` (i <= M): the roots of the
    /// secular equation `h(l) = 1 / k + sum_i w_i^2 / (omega_i^2 - l)`, one
    /// in each interval `(omega_j^2, omega_{j+1}^2)`, by bisection (exact to
    /// rounding, unlike a dense eigensolver whose error is `eps omega_M^2`).
    fn ritz_eigenvalues(om2: &[f64], w2: &[f64], k: f64, count: usize) -> Vec<f64> {
        let h = |l: f64| 1.0 / k + om2.iter().zip(w2).map(|(o, w)| w / (o - l)).sum::<f64>();
        (0..count)
            .map(|j| {
                let (mut a, mut b) = (om2[j], om2[j + 1]);
                for _ in 0..200 {
                    let c = 0.5 * (a + b);
                    if c <= a || c >= b {
                        break;
                    }
                    if h(c) < 0.0 {
                        a = c;
                    } else {
                        b = c;
                    }
                }
                0.5 * (a + b)
            })
            .collect()
    }

    #[test]
    fn rayleigh_ritz_in_cantilever_modes_converges_from_above_at_the_predicted_rate() {
        let m = 200;
        let beam = Beam::new(Support::ClampedFree, m, L, MU, EI);
        let om2: Vec<f64> = (1..=m).map(|j| beam.omega(j).powi(2)).collect();
        let w2: Vec<f64> = (1..=m).map(|j| beam.shape(j, L).powi(2)).collect();
        // Dense check of the secular solver on a small case.
        {
            let k = spring_for(50.0);
            let mut kmat = DMatrix::from_fn(20, 20, |i, j| k * beam.shape(i + 1, L) * beam.shape(j + 1, L));
            for i in 0..20 {
                kmat[(i, i)] += om2[i];
            }
            let mut dense: Vec<f64> = kmat.symmetric_eigenvalues().iter().copied().collect();
            dense.sort_by(f64::total_cmp);
            let sec = ritz_eigenvalues(&om2[..20], &w2[..20], k, 5);
            for j in 0..5 {
                assert!((dense[j] / sec[j] - 1.0).abs() < 1e-9, "{j}: {} {}", dense[j], sec[j]);
            }
        }
        let c = (EI / (MU * L.powi(4))).sqrt();
        for kappa in [1.0, 100.0, 1e4, 1e14] {
            let k = spring_for(kappa);
            let exact = TipSpringCantilever::new(10, L, MU, EI, k);
            let ritz = ritz_eigenvalues(&om2, &w2, k, 10);
            let (mut line, mut worst_ratio) = (String::new(), 0.0f64);
            for (j, ritz) in ritz.iter().enumerate() {
                let l = exact.omega(j + 1).powi(2);
                // First order: the dropped modes i > M shift the root by
                // R / h' with R = sum_{i>M} w_i^2 / (omega_i^2 - l)
                // (w_i^2 = 4 / (mu L), beta_i = (i - 1/2) pi to e^{-beta}).
                let tail: f64 = (m + 1..m + 400_000).map(|i| 4.0 / (MU * L) / ((((i as f64 - 0.5) * PI).powi(2) * c).powi(2) - l)).sum();
                let slope: f64 = om2.iter().zip(&w2).map(|(o, w)| w / (o - l).powi(2)).sum();
                let predicted = tail / slope;
                let error = ritz - l;
                let rel = error / l;
                line += &format!(" {:.1e}", 0.5 * rel);
                assert!(rel > -1e-14, "kappa {kappa} mode {}: below the continuum ({rel:e})", j + 1);
                if predicted / l > 1e-11 {
                    worst_ratio = worst_ratio.max((error / predicted - 1.0).abs());
                    // (second order: (error / gap to the nearest pole)^1, < 1e-4 here)
                    assert!((error / predicted - 1.0).abs() < 1e-3, "kappa {kappa} mode {}: error {error:e} predicted {predicted:e}", j + 1);
                } else {
                    assert!(rel.abs() < 2e-11, "kappa {kappa} mode {}: {rel:e}", j + 1);
                }
            }
            eprintln!("kappa {kappa:e}: Ritz (M = {m}) frequency error omega_ritz / omega - 1, modes 1..10:{line}; |error / predicted - 1| <= {worst_ratio:.1e}");
        }
    }

    /// The mass and stiffness matrices of the first `n` spring modes by
    /// quadrature, in SI units.
    fn gram(s: &TipSpringCantilever) -> (DMatrix<f64>, DMatrix<f64>) {
        let n = s.n_modes();
        let panels = (2.0 * s.modes[n - 1].beta / FRAC_PI_2).ceil() as usize + 4;
        let mut nodes = Vec::new();
        for_each_node(0.0, s.length, panels, |x, w| nodes.push((x, w)));
        let shapes = DMatrix::from_fn(nodes.len(), n, |r, k| nodes[r].1.sqrt() * s.shape(k + 1, nodes[r].0));
        let curv = DMatrix::from_fn(nodes.len(), n, |r, k| nodes[r].1.sqrt() * s.curvature(k + 1, nodes[r].0));
        let tip = DMatrix::from_fn(n, 1, |k, _| s.tip(k + 1));
        let mass = shapes.tr_mul(&shapes) * s.mass_per_length;
        let stiffness = curv.tr_mul(&curv) * s.bending_stiffness + &tip * tip.transpose() * s.spring;
        (mass, stiffness)
    }

    #[test]
    fn modes_are_mass_and_stiffness_orthogonal() {
        for kappa in [0.1, 100.0, 1e4, 1e14] {
            let s = TipSpringCantilever::new(100, L, MU, EI, spring_for(kappa));
            let (mass, stiffness) = gram(&s);
            let (mut em, mut ek) = (0.0f64, 0.0f64);
            for k in 0..100 {
                for l in 0..100 {
                    let d = if k == l { 1.0 } else { 0.0 };
                    em = em.max((mass[(k, l)] - d).abs());
                    ek = ek.max((stiffness[(k, l)] / (s.omega(k + 1) * s.omega(l + 1)) - d).abs());
                }
            }
            eprintln!("kappa {kappa:e}: max |M - I| {em:.1e}, max |K / (w_k w_l) - I| {ek:.1e} (100 modes)");
            assert!(em < 1e-10 && ek < 1e-10, "kappa {kappa}: {em} {ek}");
        }
    }

    #[test]
    fn boundary_conditions_hold_to_mode_300() {
        for kappa in [0.0, 0.1, 100.0, 1e4, 1e14] {
            let s = TipSpringCantilever::new(300, L, MU, EI, spring_for(kappa));
            for (j, m) in s.modes.iter().enumerate() {
                let b = m.beta;
                let d: Vec<[f64; 2]> = (0..4).map(|k| [m.derivative(k, 0.0), m.derivative(k, 1.0)]).collect();
                assert!(d.iter().flatten().all(|v| v.is_finite()), "kappa {kappa} mode {}", j + 1);
                assert!(d[0][0].abs() < 1e-12 && d[1][0].abs() < 1e-12 * b, "clamp, kappa {kappa} mode {}", j + 1);
                assert!(d[2][1].abs() < 1e-12 * b * b, "moment, kappa {kappa} mode {}", j + 1);
                // W~''' = kappa W~ at the tip, to rounding of either term
                // (W~(1) summed from O(1) terms: absolute rounding ~1e-16).
                let shear = d[3][1] - kappa * d[0][1];
                assert!(shear.abs() < 1e-12 * (b.powi(3) + kappa), "shear, kappa {kappa} mode {}: {shear}", j + 1);
                // Dimensional, with the accurate tip value: EI W'''(L) = k W(L).
                let (w_l, w3_l) = (s.tip(j + 1), s.amplitude() / L.powi(3) * d[3][1]);
                let scale = EI * s.amplitude() * (b / L).powi(3);
                assert!((EI * w3_l - s.spring * w_l).abs() <= 1e-12 * scale, "kappa {kappa} mode {}", j + 1);
                // ... and the direct sum agrees to its rounding (phase b xi to ~b eps).
                let raw = (w_l - s.shape(j + 1, L)).abs() / s.amplitude();
                assert!(raw <= 1e-15 * b, "kappa {kappa} mode {}: {raw:e}", j + 1);
            }
        }
    }

    #[test]
    fn shape_integral_matches_quadrature() {
        let s = TipSpringCantilever::new(100, L, MU, EI, spring_for(100.0));
        for j in 1..=100 {
            let q = L * integrate(|xi| s.shape(j, xi * L), 8 * (j + 3));
            assert!((s.shape_integral(j) - q).abs() < 1e-13 * s.amplitude() * L, "{j}");
        }
    }

    #[test]
    fn overlap_matches_the_closed_form_off_the_diagonal() {
        // (b_k^4 - b_j^4) int Phi~_k W~_j = [Phi~''' W~ - Phi~'' W~' + Phi~' W~'' - Phi~ W~''']_0^1
        //                                 = kappa Phi~_k(1) W~_j(1)
        // (clamped at 0 for both; W~'' = W~''' = 0, Phi~'' = 0, Phi~''' = kappa Phi~ at 1).
        let beam = Beam::new(Support::ClampedFree, 150, L, MU, EI);
        for kappa in [0.1, 100.0, 1e4] {
            let s = TipSpringCantilever::new(150, L, MU, EI, spring_for(kappa));
            let t = overlap(&s, &beam);
            let mut worst = 0.0f64;
            for k in 0..150 {
                for j in 0..150 {
                    if k == j {
                        continue;
                    }
                    let (p, w) = (&s.modes[k], &beam.modes[j]);
                    let want = kappa * p.derivative(0, 1.0) * w.derivative(0, 1.0) / (p.beta.powi(4) - w.beta.powi(4));
                    worst = worst.max((t[(k, j)] - want).abs());
                }
            }
            eprintln!("kappa {kappa:e}: max |T - closed form| off the diagonal {worst:.1e} (150 x 150)");
            assert!(worst < 1e-12, "kappa {kappa}: {worst}");
        }
    }

    #[test]
    fn overlap_is_orthogonal_up_to_truncation() {
        let (n, m) = (60, 300);
        let beam = Beam::new(Support::ClampedFree, m, L, MU, EI);
        for kappa in [0.1, 100.0, 1e4, 1e14] {
            let s = TipSpringCantilever::new(m, L, MU, EI, spring_for(kappa));
            let t = overlap(&s, &beam);
            let rows = t.rows(0, n);
            // Spring modes k <= n in the m cantilever modes: 1 - sum_j T_kj^2
            // is the dropped sum_{j>m} T_kj^2, T_kj = kappa Phi~_k(1) W~_j(1) / (b_k^4 - b_j^4)
            // with W~_j(1)^2 = 4, b_j = (j - 1/2) pi.
            let dropped: Vec<f64> = (0..n)
                .map(|k| {
                    let (b4, p1) = (s.modes[k].beta.powi(4), s.modes[k].derivative(0, 1.0));
                    (m + 1..m + 100_000).map(|j| (kappa * p1 * 2.0 / (b4 - ((j as f64 - 0.5) * PI).powi(4))).powi(2)).sum()
                })
                .collect();
            let ttt = rows * rows.transpose();
            let mut worst = 0.0f64;
            let mut worst_pred = 0.0f64;
            for k in 0..n {
                for l in 0..n {
                    let want = if k == l { 1.0 - dropped[k] } else { 0.0 };
                    // off the diagonal the dropped part is at most sqrt(d_k d_l)
                    let allowed = if k == l { 1e-12 } else { (dropped[k] * dropped[l]).sqrt() + 1e-12 };
                    let e = (ttt[(k, l)] - want).abs();
                    assert!(e < allowed, "kappa {kappa} ({k}, {l}): {e:e} > {allowed:e}");
                    worst = worst.max((ttt[(k, l)] - if k == l { 1.0 } else { 0.0 }).abs());
                }
                worst_pred = worst_pred.max(dropped[k]);
            }
            // The other way: cantilever modes j <= n in the m spring modes.
            let cols = t.columns(0, n);
            let tt = cols.transpose() * cols;
            let mut back = 0.0f64;
            for j in 0..n {
                for l in 0..n {
                    back = back.max((tt[(j, l)] - if j == l { 1.0 } else { 0.0 }).abs());
                }
            }
            eprintln!("kappa {kappa:e}: max |T T^T - I| ({n} spring modes on {m} cantilever modes) {worst:.1e} (predicted dropped {worst_pred:.1e}); max |T^T T - I| the other way {back:.1e}");
            if kappa < 1e6 {
                assert!(back < 1e-12, "kappa {kappa}: {back}");
            } else {
                // A near-pinned basis is slow to rebuild a moving tip: with
                // Phi~_k(1) ~ sqrt 2 b_k^3 / kappa (for b_k^3 << kappa),
                // T_kj ~ 2 sqrt 2 b_k^3 / (b_k^4 - b_j^4) and the dropped
                // sum_{k>m} T_kj^2 ~ 8 / (pi^2 m). The sum to k = 2000
                // (b^3 / kappa < 3e-3) and to infinity bracket it.
                for j in 0..n {
                    let bj4 = beam.modes[j].beta.powi(4);
                    let term = |k: usize| {
                        let b = (k as f64 + 0.25) * PI;
                        8.0 * b.powi(6) / (b.powi(4) - bj4).powi(2)
                    };
                    let low: f64 = (m + 1..=2000).map(term).sum();
                    let high = low + (2001..2_000_000).map(term).sum::<f64>();
                    let deficit = 1.0 - tt[(j, j)];
                    assert!(deficit > 0.97 * low && deficit < 1.03 * high, "mode {}: {deficit:e} not in [{low:e}, {high:e}]", j + 1);
                }
            }
        }
    }

    #[test]
    fn overlap_transfers_projections_and_the_contact_load() {
        // A displacement field f (the static tip-load shape x^2 (3 L - x))
        // with cantilever coordinates c_j = int mu W_j f: its spring
        // coordinates int mu Phi_k f must be (T c)_k (p = T q of MTM).
        let (n, m) = (40, 200);
        let kappa = 300.0;
        let beam = Beam::new(Support::ClampedFree, m, L, MU, EI);
        let s = TipSpringCantilever::new(n, L, MU, EI, spring_for(kappa));
        let t = overlap(&s, &beam);
        let f = |x: f64| x * x * (3.0 * L - x);
        let project = |shape: &dyn Fn(f64) -> f64| MU * L * integrate(|xi| shape(xi * L) * f(xi * L), 800);
        let c = DVector::from_fn(m, |j, _| project(&|x| beam.shape(j + 1, x)));
        let d = DVector::from_fn(n, |k, _| project(&|x| s.shape(k + 1, x)));
        let e = (&t * &c - &d).amax() / d.amax();
        eprintln!("projection of x^2 (3L - x): max |T c - d| / max |d| = {e:.1e}");
        assert!(e < 1e-11, "{e}");
        // Spring modes rebuilt from the cantilever modes: Phi_k = sum_j T_kj W_j.
        // At the tip the dropped part is sum_{j>m} T_kj W_j(L)
        // = kappa Phi~_k(1) sum_{j>m} 4 / (b_k^4 - b_j^4) (times the amplitude).
        for k in [0, 5, 20] {
            let b4 = s.modes[k].beta.powi(4);
            let dropped = s.amplitude() * kappa * s.modes[k].tip(kappa)
                * (m + 1..m + 100_000).map(|j| 4.0 / (b4 - ((j as f64 - 0.5) * PI).powi(4))).sum::<f64>();
            // Inside, |W~_j| <= |W~_j(1)| = 2 bounds the dropped part by the tip's.
            for xi in [0.2, 0.6] {
                let sum: f64 = (0..m).map(|j| t[(k, j)] * beam.shape(j + 1, xi * L)).sum();
                assert!((sum - s.shape(k + 1, xi * L)).abs() < dropped.abs() + 1e-13 * s.amplitude(), "{k} {xi}");
            }
            let sum: f64 = (0..m).map(|j| t[(k, j)] * beam.shape(j + 1, L)).sum();
            let miss = sum - s.tip(k + 1);
            assert!((miss / -dropped - 1.0).abs() < 0.05, "{k}: {miss:e} vs {:e}", -dropped);
            if k == 0 {
                eprintln!("Phi_1(L) from {m} cantilever modes: relative miss {:.1e} (predicted {:.1e})", miss / s.tip(1), -dropped / s.tip(1));
            }
        }
        // The RMTM constant load (docs/mode_transfer.md): for an admissible
        // field v, int EI Phi_k'' v'' + k Phi_k(L) v(L) = omega_k^2 int mu Phi_k v.
        // With v = W_j: int EI Phi_k'' W_j'' + k Phi_k(L) W_j(L) = omega_k^2 T_kj.
        for k in [0, 3, 17] {
            for j in [0, 3, 4, 30] {
                let bend = EI * L * integrate(|xi| s.curvature(k + 1, xi * L) * beam.curvature(j + 1, xi * L), 400);
                let lhs = bend + s.spring * s.shape(k + 1, L) * beam.shape(j + 1, L);
                let rhs = s.omega(k + 1).powi(2) * t[(k, j)];
                assert!((lhs - rhs).abs() < 1e-10 * s.omega(k + 1) * beam.omega(j + 1), "{k} {j}: {lhs} {rhs}");
            }
        }
    }

}
