//! Composite Gauss-Legendre quadrature.

use std::f64::consts::PI;
use std::sync::OnceLock;

/// Nodes and weights of the N-point rule on [-1, 1], by Newton's method on
/// the Legendre polynomial.
fn rule<const N: usize>() -> ([f64; N], [f64; N]) {
        let n = N;
        let mut x = [0.0; N];
        let mut w = [0.0; N];
        for i in 0..n {
            let mut z = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut dp = 0.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, 0.0);
                for k in 0..n {
                    let p2 = p1;
                    p1 = p0;
                    p0 = ((2 * k + 1) as f64 * z * p1 - k as f64 * p2) / (k + 1) as f64;
                }
                dp = n as f64 * (z * p0 - p1) / (z * z - 1.0);
                let dz = p0 / dp;
                z -= dz;
                if dz.abs() < 1e-16 {
                    break;
                }
            }
            x[i] = z;
            w[i] = 2.0 / ((1.0 - z * z) * dp * dp);
        }
        (x, w)
}

fn gauss16() -> &'static ([f64; 16], [f64; 16]) {
    static RULE: OnceLock<([f64; 16], [f64; 16])> = OnceLock::new();
    RULE.get_or_init(rule::<16>)
}

fn gauss6() -> &'static ([f64; 6], [f64; 6]) {
    static RULE: OnceLock<([f64; 6], [f64; 6])> = OnceLock::new();
    RULE.get_or_init(rule::<6>)
}

fn nodes<const N: usize>(a: f64, b: f64, panels: usize, (x, w): &([f64; N], [f64; N]), f: &mut impl FnMut(f64, f64)) {
    let h = (b - a) / panels as f64;
    for p in 0..panels {
        let mid = a + (p as f64 + 0.5) * h;
        for k in 0..N {
            f(mid + 0.5 * h * x[k], 0.5 * h * w[k]);
        }
    }
}

/// Calls `f(t, weight)` at every node of `panels` 16-point panels on
/// `[a, b]`; the weighted sum of `f` is the integral.
pub fn for_each_node(a: f64, b: f64, panels: usize, mut f: impl FnMut(f64, f64)) {
    nodes(a, b, panels, gauss16(), &mut f);
}

/// The same for an integrand oscillating at most at `omega`, with as few
/// nodes as keep it exact to rounding: one 6-point panel while
/// `omega h <= 0.6` (error ~ (omega h / 2)^12 / 12! < 1e-15), else 16-point
/// panels with `omega h <= pi / 2`.
pub fn for_each_node_band_limited(a: f64, b: f64, omega: f64, mut f: impl FnMut(f64, f64)) {
    let span = b - a;
    if omega * span <= 0.6 {
        nodes(a, b, 1, gauss6(), &mut f);
    } else {
        let panels = (omega * span / (0.5 * PI)).ceil().min(1e8) as usize;
        nodes(a, b, panels.max(1), gauss16(), &mut f);
    }
}

/// `int_a^b f` on `panels` panels.
pub fn integrate(a: f64, b: f64, panels: usize, f: impl Fn(f64) -> f64) -> f64 {
    let mut total = 0.0;
    for_each_node(a, b, panels, |t, w| total += w * f(t));
    total
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_for_polynomials_and_accurate_for_oscillations() {
        assert!((integrate(0.0, 2.0, 1, |x| x.powi(31)) - 2f64.powi(32) / 32.0).abs() < 1e-6);
        let v = integrate(0.0, 10.0, 40, |x| (7.0 * x).sin());
        assert!((v - (1.0 - 70f64.cos()) / 7.0).abs() < 1e-14);
        for (a, b) in [(0.3, 0.35), (0.0, 10.0)] {
            let mut total = 0.0;
            for_each_node_band_limited(a, b, 7.0, |t, w| total += w * (7.0 * t).cos());
            assert!((total - ((7.0 * b).sin() - (7.0 * a).sin()) / 7.0).abs() < 1e-15, "{a} {b}");
        }
    }
}
