//! The response of one damped modal oscillator to a polynomial load from
//! rest, through the exponential-integral functions `phi_k`.
//!
//! For `z' = A z + b u(tau)`, `z = (x, x')`, `A = [[0, 1], [-omega^2, -2a]]`,
//! `b = (0, 1)`, the load `(tau / h)^m` from rest gives
//! `z(tau) = m! sigma^m tau phi_{m+1}(tau A) b` with `sigma = tau / h` and
//! `phi_k(X) = sum_i X^i / (i + k)!` (HO10 eq. 2.10): the closed-form modal
//! flow under a polynomial load, the kernel of force collocation.
//!
//! `phi_k(tau A) b` is computed without cancellation in every regime:
//! - `|lambda| tau >= 2` (every eigenvalue far from 0): upward,
//!   `phi_{k+1} b = X^{-1} (phi_k b - b / k!)` from `phi_0 b = e^X b`, with
//!   `e^X b - b` from the kernels' `Ec - 1`;
//! - smaller: the Taylor series of the highest `phi` (a few terms), then
//!   downward, `phi_k b = X phi_{k+1} b + b / k!`, down to `phi_0 b`
//!   (no sine, cosine or exponential on this path);
//! - strongly over-damped (two well-separated real rates): per eigenvalue,
//!   the scalar `phi_k` by the same two recurrences.

use super::oscillator::Oscillator;

/// `phi_k(tau A) b` for `k = 0..out.len()`, `out[k] = (displacement,
/// velocity)`.
pub fn phi_columns(osc: &Oscillator, tau: f64, out: &mut [[f64; 2]]) {
    phi_columns_with(osc, tau, || osc.kernels_and_increment(tau), out)
}

/// [`phi_columns`] with the oscillator's kernels at `tau` (`(Ec, Es, Ec -
/// 1)`, [`Oscillator::kernels_and_increment`]) from `kernels`, asked for
/// only where they are used (a caller that has them already).
pub fn phi_columns_with(osc: &Oscillator, tau: f64, kernels: impl FnOnce() -> (f64, f64, f64), out: &mut [[f64; 2]]) {
    let kmax = out.len() - 1;
    let (w2, a) = (osc.omega * osc.omega, osc.a);
    if !osc.is_underdamped() {
        // Rates -a -+ mu.
        let mu = ((a - osc.omega) * (a + osc.omega)).max(0.0).sqrt();
        if mu > 0.1 * a {
            return overdamped(a, mu, tau, out);
        }
    }
    if osc.omega * tau >= 2.0 {
        let (ec, es, ec_m1) = kernels();
        out[0] = [es, ec - a * es];
        // phi_0 b - b.
        let mut v = [es, ec_m1 - a * es];
        let mut fact = 1.0;
        for k in 0..kmax {
            // X^{-1} v = (1 / tau) (-(2 a v0 + v1) / omega^2, v0).
            let next = [-(2.0 * a * v[0] + v[1]) / (w2 * tau), v[0] / tau];
            out[k + 1] = next;
            fact *= (k + 1) as f64;
            v = [next[0], next[1] - 1.0 / fact];
        }
        return;
    }
    // Taylor series of phi_kmax(X) b: terms (omega tau)^i / (i + kmax)!
    // relative to the sum, Horner from the last one kept (`tau < 0` too:
    // a step back).
    let r = (osc.omega * tau + 2.0 * a * tau).abs();
    let terms = series_terms(r, kmax);
    let x_times = |v: [f64; 2]| [tau * v[1], -tau * (w2 * v[0] + 2.0 * a * v[1])];
    let mut u = [0.0, inv_fact(terms + kmax)];
    for &f in INV_FACT[kmax..kmax + terms].iter().rev() {
        let xu = x_times(u);
        u = [xu[0], xu[1] + f];
    }
    out[kmax] = u;
    // Down to phi_0 b = e^X b too: no sine, cosine or exponential here.
    for k in (0..kmax).rev() {
        let xu = x_times(out[k + 1]);
        out[k] = [xu[0], xu[1] + INV_FACT[k]];
    }
}

/// Terms of the series of `phi_kmax` kept at `|X| ~ r`: the fewest after
/// which the next one, `r^terms kmax! / (terms + kmax)!` relative to the
/// first, is at most 1e-18 (at most 60). Read from a table of the largest
/// `r` each count covers where `kmax` is in it (the phis of force
/// collocation, `kmax <= 11`) rather than formed term by term, a serial
/// chain of multiplications as long as the series.
fn series_terms(r: f64, kmax: usize) -> usize {
    if let Some(limits) = series_limits().get(kmax) {
        return limits.iter().position(|&limit| r <= limit).map_or(MAX_TERMS, |i| i + 1);
    }
    let mut terms = 0usize;
    let mut size = 1.0;
    while size > 1e-18 && terms < MAX_TERMS {
        terms += 1;
        // By the reciprocal: a division per term took half the time.
        size *= r * INV[terms + kmax];
    }
    terms
}

/// The most terms a series keeps.
const MAX_TERMS: usize = 60;
/// The `kmax` the table of [`series_terms`] covers.
const TABLED: usize = 12;

/// `[kmax][terms - 1]`: the largest `r` whose series needs at most
/// `terms` terms, `(1e-18 (terms + kmax)! / kmax!)^(1 / terms)` (rising
/// with `terms`).
fn series_limits() -> &'static [[f64; MAX_TERMS]; TABLED] {
    static LIMITS: std::sync::OnceLock<[[f64; MAX_TERMS]; TABLED]> = std::sync::OnceLock::new();
    LIMITS.get_or_init(|| {
        let mut limits = [[0.0; MAX_TERMS]; TABLED];
        for (kmax, row) in limits.iter_mut().enumerate() {
            // ln((terms + kmax)! / kmax!), term by term.
            let mut log_ratio = 0.0;
            for (i, limit) in row.iter_mut().enumerate() {
                let terms = i + 1;
                log_ratio += ((terms + kmax) as f64).ln();
                *limit = ((1e-18f64.ln() + log_ratio) / terms as f64).exp();
            }
        }
        limits
    })
}

/// `1 / k!` for `k < 80`.
const INV_FACT: [f64; 80] = {
    let mut t = [1.0; 80];
    let mut k = 1;
    while k < 80 {
        t[k] = t[k - 1] / k as f64;
        k += 1;
    }
    t
};

/// `1 / k` for `0 < k < 80`.
const INV: [f64; 80] = {
    let mut t = [0.0; 80];
    let mut k = 1;
    while k < 80 {
        t[k] = 1.0 / k as f64;
        k += 1;
    }
    t
};

fn inv_fact(k: usize) -> f64 {
    INV_FACT[k]
}

/// Over-damped with rates `l1 = -a + mu`, `l2 = -a - mu` well apart:
/// `phi_k(X) b = (phi_k(tau l1) v1 - phi_k(tau l2) v2) / (l1 - l2)` with
/// the eigenvectors `v = (1, l)`.
fn overdamped(a: f64, mu: f64, tau: f64, out: &mut [[f64; 2]]) {
    // The slow rate without cancellation: l1 = -omega^2 / (a + mu).
    let l2 = -a - mu;
    let l1 = (a - mu) * (a + mu) / l2;
    let kmax = out.len() - 1;
    let mut p1 = [0.0; 16];
    let mut p2 = [0.0; 16];
    scalar_phis(tau * l1, &mut p1[..=kmax]);
    scalar_phis(tau * l2, &mut p2[..=kmax]);
    let d = l1 - l2;
    for k in 0..=kmax {
        out[k] = [(p1[k] - p2[k]) / d, (p1[k] * l1 - p2[k] * l2) / d];
    }
}

/// The scalar `phi_k(z)`, `k = 0..out.len()`, real `z`.
fn scalar_phis(z: f64, out: &mut [f64]) {
    let kmax = out.len() - 1;
    if z.abs() >= 1.0 {
        out[0] = z.exp();
        let mut fact = 1.0;
        for k in 0..kmax {
            out[k + 1] = (out[k] - 1.0 / fact) / z;
            fact *= (k + 1) as f64;
        }
        return;
    }
    let mut u = 0.0;
    for i in (0..30).rev() {
        u = z * u + inv_fact(i + kmax);
    }
    out[kmax] = u;
    for k in (0..kmax).rev() {
        out[k] = z * out[k + 1] + inv_fact(k);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `phi_k(tau A) b` by the Taylor series summed in pairs of f64
    /// (double-double): an independent reference for moderate `omega tau`.
    fn reference(osc: &Oscillator, tau: f64, k: usize) -> [f64; 2] {
        use twofloat_like::Dd;
        let (w2, a) = (Dd::from(osc.omega * osc.omega), Dd::from(osc.a));
        let t = Dd::from(tau);
        let mut term = [Dd::from(0.0), Dd::from(1.0)];
        let mut fact = Dd::from(1.0);
        for i in 1..=k {
            fact = fact * Dd::from(i as f64);
        }
        let mut sum = [term[0] / fact, term[1] / fact];
        for i in 1..150 {
            term = [t * term[1], Dd::from(0.0) - t * (w2 * term[0] + Dd::from(2.0) * a * term[1])];
            fact = fact * Dd::from((i + k) as f64);
            sum = [sum[0] + term[0] / fact, sum[1] + term[1] / fact];
        }
        [sum[0].hi(), sum[1].hi()]
    }

    /// Just enough double-double arithmetic for the reference.
    mod twofloat_like {
        #[derive(Clone, Copy)]
        pub struct Dd(f64, f64);
        impl Dd {
            pub fn hi(self) -> f64 {
                self.0 + self.1
            }
        }
        impl From<f64> for Dd {
            fn from(x: f64) -> Self {
                Dd(x, 0.0)
            }
        }
        fn two_sum(a: f64, b: f64) -> (f64, f64) {
            let s = a + b;
            let bb = s - a;
            (s, (a - (s - bb)) + (b - bb))
        }
        impl std::ops::Add for Dd {
            type Output = Dd;
            fn add(self, o: Dd) -> Dd {
                let (s, e) = two_sum(self.0, o.0);
                let (h, l) = two_sum(s, e + self.1 + o.1);
                Dd(h, l)
            }
        }
        impl std::ops::Sub for Dd {
            type Output = Dd;
            fn sub(self, o: Dd) -> Dd {
                self + Dd(-o.0, -o.1)
            }
        }
        impl std::ops::Mul for Dd {
            type Output = Dd;
            fn mul(self, o: Dd) -> Dd {
                let p = self.0 * o.0;
                let e = self.0.mul_add(o.0, -p);
                let (h, l) = two_sum(p, e + self.0 * o.1 + self.1 * o.0);
                Dd(h, l)
            }
        }
        impl std::ops::Div for Dd {
            type Output = Dd;
            fn div(self, o: Dd) -> Dd {
                let q1 = self.0 / o.0;
                let r = self - o * Dd(q1, 0.0);
                let q2 = r.0 / o.0;
                let (h, l) = two_sum(q1, q2);
                Dd(h, l)
            }
        }
    }

    /// The table's term counts are the product's: the first count whose
    /// next term, `r^terms kmax! / (terms + kmax)!`, is at most 1e-18
    /// (away from the boundaries, where the two roundings may differ).
    #[test]
    fn tabled_term_counts_are_the_products() {
        for kmax in 0..TABLED {
            for i in 0..400 {
                let r = 10f64.powf(-12.0 + 14.0 * i as f64 / 400.0);
                let (mut terms, mut size) = (0usize, 1.0f64);
                while size > 1e-18 && terms < MAX_TERMS {
                    terms += 1;
                    size *= r / (terms + kmax) as f64;
                }
                let near_boundary = (size / 1e-18 - 1.0).abs() < 1e-9 || (size * (terms + kmax) as f64 / r / 1e-18 - 1.0).abs() < 1e-9;
                assert!(near_boundary || series_terms(r, kmax) == terms, "kmax {kmax}, r {r:e}: {} terms, the product {terms}", series_terms(r, kmax));
            }
        }
    }

    #[test]
    fn every_regime_matches_the_series_in_double_double() {
        // Under-damped, near-critical and over-damped, omega tau across
        // both sides of the switch between recurrences.
        for &(omega, zeta) in &[(1.0, 0.0), (1.0, 0.02), (1.0, 0.7), (1.0, 1.0), (1.0, 1.05), (1.0, 3.0), (1.0, 30.0)] {
            let osc = Oscillator::new(omega, zeta);
            for &tau in &[1e-6, 1e-3, 0.1, 0.5, 1.0, 1.9, 2.1, 3.0, 6.0, 12.0] {
                // The alternating series loses digits beyond omega tau ~ 6
                // and for fast over-damped rates: the reference holds there
                // only to its own rounding, measured against the size of
                // its largest term.
                let fast = (osc.a + ((osc.a - omega) * (osc.a + omega)).max(0.0).sqrt()).max(omega) * tau;
                if fast > 12.0 {
                    continue;
                }
                let mut out = [[0.0; 2]; 7];
                phi_columns(&osc, tau, &mut out);
                let tol = 1e-13 * fast.exp().max(1.0);
                for (k, got) in out.iter().enumerate() {
                    let want = reference(&osc, tau, k);
                    // Displacement and velocity in one unit: omega x.
                    let size = (omega * want[0]).abs().max(want[1].abs());
                    let errs = [omega * (got[0] - want[0]).abs(), (got[1] - want[1]).abs()];
                    for c in 0..2 {
                        assert!(errs[c] <= tol * size, "omega {omega} zeta {zeta} tau {tau} k {k} c {c}: {} vs {}", got[c], want[c]);
                    }
                }
            }
        }
    }

    /// A step back (`tau < 0`, as a switch's shift may take) within a
    /// radian of the oscillator: the Taylor path, against the series.
    #[test]
    fn a_step_back_matches_the_series_in_double_double() {
        for &(omega, zeta) in &[(1.0, 0.0), (1.0, 0.02), (1.0, 0.7), (1.0, 1.0)] {
            let osc = Oscillator::new(omega, zeta);
            for &tau in &[-1e-6, -1e-3, -0.1, -0.5, -1.0] {
                let mut out = [[0.0; 2]; 7];
                phi_columns(&osc, tau, &mut out);
                for (k, got) in out.iter().enumerate() {
                    let want = reference(&osc, tau, k);
                    let size = (omega * want[0]).abs().max(want[1].abs());
                    let errs = [omega * (got[0] - want[0]).abs(), (got[1] - want[1]).abs()];
                    for c in 0..2 {
                        assert!(errs[c] <= 1e-14 * size, "omega {omega} zeta {zeta} tau {tau} k {k} c {c}: {} vs {}", got[c], want[c]);
                    }
                }
            }
        }
    }

    #[test]
    fn polynomial_loads_match_a_fine_numerical_solution() {
        // x'' + 2 a x' + w^2 x = (t / h)^m from rest, by RK4 with tiny steps.
        for &(omega, zeta) in &[(50.0, 0.02), (0.3, 0.0), (5.0, 4.0)] {
            let osc = Oscillator::new(omega, zeta);
            let h = 0.37;
            for m in 0..5usize {
                let f = |t: f64, x: [f64; 2]| [x[1], (t / h).powi(m as i32) - 2.0 * osc.a * x[1] - omega * omega * x[0]];
                let steps = 20000;
                let dt = h / steps as f64;
                let mut x = [0.0, 0.0];
                for i in 0..steps {
                    let t = i as f64 * dt;
                    let k1 = f(t, x);
                    let k2 = f(t + 0.5 * dt, [x[0] + 0.5 * dt * k1[0], x[1] + 0.5 * dt * k1[1]]);
                    let k3 = f(t + 0.5 * dt, [x[0] + 0.5 * dt * k2[0], x[1] + 0.5 * dt * k2[1]]);
                    let k4 = f(t + dt, [x[0] + dt * k3[0], x[1] + dt * k3[1]]);
                    for c in 0..2 {
                        x[c] += dt / 6.0 * (k1[c] + 2.0 * k2[c] + 2.0 * k3[c] + k4[c]);
                    }
                }
                let mut out = [[0.0; 2]; 6];
                phi_columns(&osc, h, &mut out);
                let fact: f64 = (1..=m).map(|i| i as f64).product();
                let got = [fact * h * out[m + 1][0], fact * h * out[m + 1][1]];
                for c in 0..2 {
                    assert!((got[c] - x[c]).abs() <= 1e-9 * x[c].abs().max(1e-3 / omega.max(1.0)), "omega {omega} m {m} c {c}: {} vs {}", got[c], x[c]);
                }
            }
        }
    }
}
