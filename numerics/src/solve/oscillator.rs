//! Exact solution of one damped modal oscillator
//! `x'' + 2 zeta omega x' + omega^2 x = f(t)` (VSM12 eq. 13, WB00 eq. 4).
//!
//! Every formula here is free of catastrophic cancellation, whatever the
//! damping (zero, critical, strongly over-critical) and however close the
//! forcing is to resonance (the classical closed forms, rewritten with
//! `expm1` and `phi1(z) = (e^z - 1) / z`).

use super::elementary::{exp_m1, sin_cos};
pub use super::complex::C64;

/// `expm1` of a complex argument, accurate for small `|z|`.
pub fn expm1_c(z: C64) -> C64 {
    let em = exp_m1(z.re);
    // One sin_cos of the half angle: sin y = 2 sin(y/2) cos(y/2),
    // cos y - 1 = -2 sin^2(y/2).
    let (sh, ch) = sin_cos(0.5 * z.im);
    let cy_m1 = -2.0 * sh * sh;
    // e^x cos y - 1 = expm1(x) cos y + (cos y - 1): no cancellation for x <= 0.
    C64::new(em * (1.0 + cy_m1) + cy_m1, (em + 1.0) * (2.0 * sh * ch))
}

/// `phi1(z) = (e^z - 1) / z`, the exponential integral kernel.
pub fn phi1(z: C64) -> C64 {
    // |z| < 1e-5, without a hypot.
    if z.norm_sqr() < 1e-10 {
        C64::new(1.0, 0.0) + z * 0.5 + z * z / 6.0
    } else {
        expm1_c(z) / z
    }
}

/// The second divided difference of the exponential, `e[0, x, y] =
/// (phi1(x) - phi1(y)) / (x - y)`, continuous at `x = y` (then
/// `phi1'(x)`; at `x = y = 0`, 1/2). It is `int_0^1 int_0^u e^{..}`, the
/// kernel of the time integral of a forced exponential:
/// `int_0^S s e[x s, y s] ds = S^2 e[0, x S, y S]`, with
/// `e[x, y] = (e^x - e^y) / (x - y)`. Accurate to a few ulps relative for
/// `Re x, Re y <= 0` and any size (Opitz: `e[0,x,y] = (e[x,y] - phi1(x)) / y`
/// is free of cancellation once `|y| >= 1`; below, the Taylor series).
pub fn exp_divdiff2(x: C64, y: C64) -> C64 {
    // Moduli compared squared: no hypot (the series runs at every contact).
    let (x, y) = if x.norm_sqr() > y.norm_sqr() { (y, x) } else { (x, y) };
    if y.norm_sqr() >= 1.0 {
        let d = y - x;
        let exy = if d.norm_sqr() > 1.0 {
            (y.exp() - x.exp()) / d
        } else {
            // e^{m} sinh(d/2) / (d/2), m the midpoint.
            let h = d * 0.5;
            let sinhc = if h.norm_sqr() < 1e-6 { C64::new(1.0, 0.0) + h * h / 6.0 + h * h * h * h / 120.0 } else { h.sinh() / h };
            ((x + y) * 0.5).exp() * sinhc
        };
        return (exy - phi1(x)) / y;
    }
    // sum_n h_n(x, y) / (n + 2)!, h_n the complete homogeneous polynomial.
    let mut sum = C64::new(0.0, 0.0);
    let mut xp = C64::new(1.0, 0.0); // x^n
    let mut h = C64::new(1.0, 0.0); // h_n = sum_{i <= n} x^i y^(n-i)
    let mut fact = 2.0;
    for n in 0..40 {
        let term = h / fact;
        sum += term;
        if term.norm_sqr() < 1e-36 * sum.norm_sqr() {
            break;
        }
        xp *= x;
        h = h * y + xp;
        fact *= (n + 3) as f64;
    }
    sum
}

/// `(cos sqrt(q), sin sqrt(q) / sqrt(q), cos sqrt(q) - 1)` continued to
/// `q < 0` as cosh / sinh, with the Taylor series near `q = 0` (critical
/// damping); the last one without cancellation for small `q`.
fn c0_s0(q: f64) -> (f64, f64, f64) {
    if q.abs() < 1e-2 {
        // The Taylor series with the factorials' reciprocals
        // as constants: multiplications, not a chain of divisions (the
        // tiny flights of a chatter sequence land here at every probe).
        const C: [f64; 5] = [-1.0 / 2.0, 1.0 / 24.0, -1.0 / 720.0, 1.0 / 40320.0, -1.0 / 3628800.0];
        const S: [f64; 5] = [-1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0, 1.0 / 362880.0, -1.0 / 39916800.0];
        // Estrin's scheme: independent products, three levels deep.
        let (q2, q4) = (q * q, q * q * (q * q));
        let cm1 = q * ((C[0] + C[1] * q) + q2 * (C[2] + C[3] * q) + q4 * C[4]);
        let s = 1.0 + q * ((S[0] + S[1] * q) + q2 * (S[2] + S[3] * q) + q4 * S[4]);
        (1.0 + cm1, s, cm1)
    } else if q > 0.0 {
        let r = q.sqrt();
        // One sin_cos of the half angle: sin r = 2 sin(r/2) cos(r/2),
        // cos r - 1 = -2 sin^2(r/2).
        let (sh, ch) = sin_cos(0.5 * r);
        let cm1 = -2.0 * sh * sh;
        (1.0 + cm1, 2.0 * sh * ch / r, cm1)
    } else {
        let r = (-q).sqrt();
        let h = (0.5 * r).sinh();
        (r.cosh(), r.sinh() / r, 2.0 * h * h)
    }
}

/// One damped oscillator: frequency `omega > 0`, damping ratio `zeta >= 0`.
#[derive(Clone, Debug, PartialEq)]
pub struct Oscillator {
    pub omega: f64,
    pub zeta: f64,
    /// Decay rate `a = zeta omega`.
    pub a: f64,
    /// `omega^2 (1 - zeta)(1 + zeta)`: positive when under-damped.
    dd: f64,
    /// `sqrt(|dd|)`: the damped frequency, or the over-damped spread `mu`.
    root: f64,
    /// `1 / root` (infinite at critical damping, where it is not used).
    inv_root: f64,
    /// `1 / omega`.
    pub inv_omega: f64,
}

impl Oscillator {
    pub fn new(omega: f64, zeta: f64) -> Self {
        let dd = omega * omega * (1.0 - zeta) * (1.0 + zeta);
        let root = dd.abs().sqrt();
        Oscillator { omega, zeta, a: zeta * omega, dd, root, inv_root: 1.0 / root, inv_omega: 1.0 / omega }
    }

    pub fn is_underdamped(&self) -> bool {
        self.dd > 0.0
    }

    /// Free-response kernels `(Ec, Es)` at time `t >= 0`:
    /// `x = x0 Ec + (v0 + a x0) Es`, `v = v0 Ec - (a v0 + omega^2 x0) Es`.
    pub fn kernels(&self, t: f64) -> (f64, f64) {
        let (ec, es, _) = self.kernels_and_increment(t);
        (ec, es)
    }

    /// `(Ec, Es, Ec - 1)`, the last without cancellation for small `t`:
    /// displacements relative to the anchor stay accurate relative to
    /// themselves (the tiny flights of a chatter sequence).
    #[inline(always)]
    pub fn kernels_and_increment(&self, t: f64) -> (f64, f64, f64) {
        let r = self.root * t;
        if self.dd < 0.0 && r > 2.0 {
            // Strongly over-damped: separate slow and fast rates (the two real rates of an over-damped oscillator).
            let mu = self.root;
            let slow = self.omega * self.omega / (self.a + mu);
            let fast = self.a + mu;
            let es_slow = (-slow * t).exp();
            let ec = 0.5 * (es_slow + (-fast * t).exp());
            let es = es_slow * (-(-2.0 * mu * t).exp_m1()) / (2.0 * mu);
            let ec_m1 = 0.5 * ((-slow * t).exp_m1() + (-fast * t).exp_m1());
            return (ec, es, ec_m1);
        }
        // `t s0 = sin(r) / root`: no division by `r` on the common path.
        let (c0, t_s0, c0m1) = if self.dd > 0.0 && r * r >= 1e-2 {
            // c0_s0(r^2) without taking the square root back.
            let (sh, ch) = sin_cos(0.5 * r);
            let cm1 = -2.0 * sh * sh;
            (1.0 + cm1, 2.0 * sh * ch * self.inv_root, cm1)
        } else {
            let (c0, s0, c0m1) = c0_s0(if self.dd >= 0.0 { r * r } else { -r * r });
            (c0, t * s0, c0m1)
        };
        let em1 = if self.a == 0.0 { 0.0 } else { exp_m1(-self.a * t) };
        let e = 1.0 + em1;
        // e c0 - 1 = (e - 1) c0 + (c0 - 1)
        (e * c0, e * t_s0, em1 * c0 + c0m1)
    }

    /// Free response `(x, v)` at time `t` from `(x0, v0)` at time 0.
    pub fn free(&self, x0: f64, v0: f64, t: f64) -> (f64, f64) {
        let (ec, es) = self.kernels(t);
        (
            x0 * ec + (v0 + self.a * x0) * es,
            v0 * ec - (self.a * v0 + self.omega * self.omega * x0) * es,
        )
    }

    /// Whether the steady-state amplitude `1 / (omega^2 - Omega^2 + 2 i a Omega)`
    /// would amplify rounding by more than 2: then the response to a harmonic
    /// load is taken from [`Self::harmonic_from_rest`] instead.
    pub fn near_resonance(&self, forcing_omega: f64) -> bool {
        self.is_underdamped() && self.zeta < 0.5 && self.dynamic_stiffness(forcing_omega).norm() < 0.5 * self.omega * self.omega
    }

    /// `omega^2 - Omega^2 + 2 i a Omega`.
    pub fn dynamic_stiffness(&self, forcing_omega: f64) -> C64 {
        C64::new(
            (self.omega - forcing_omega) * (self.omega + forcing_omega),
            2.0 * self.a * forcing_omega,
        )
    }

    /// Response `(G, G')` at time `s` to the load `e^{i Omega s}` starting from
    /// rest, `G(s) = int_0^s Es(u) e^{i Omega (s - u)} du`, written as
    /// `e^{i Omega s} (E1 - E2) / (lambda1 - lambda2)` with
    /// `Ek = s phi1((lambda_k - i Omega) s)`: exact at resonance, even undamped.
    /// Under-damped oscillators only.
    pub fn harmonic_from_rest(&self, forcing_omega: f64, s: f64, rotation: C64) -> (C64, C64) {
        debug_assert!(self.is_underdamped());
        let wd = self.root;
        let mu1 = C64::new(-self.a * s, (wd - forcing_omega) * s);
        let mu2 = C64::new(-self.a * s, -(wd + forcing_omega) * s);
        let diff = (phi1(mu1) - phi1(mu2)) * s;
        let g = rotation * diff / C64::new(0.0, 2.0 * wd);
        let (_, es) = self.kernels(s);
        let gd = C64::new(0.0, forcing_omega) * g + es;
        (g, gd)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Independent reference: classical RK4 with a tiny step.
    fn rk4(osc: &Oscillator, x0: f64, v0: f64, t: f64, f: impl Fn(f64) -> f64) -> (f64, f64) {
        let n = 200_000;
        let h = t / n as f64;
        let (mut x, mut v) = (x0, v0);
        let w2 = osc.omega * osc.omega;
        let acc = |t: f64, x: f64, v: f64| f(t) - 2.0 * osc.a * v - w2 * x;
        for i in 0..n {
            let t = i as f64 * h;
            let (k1x, k1v) = (v, acc(t, x, v));
            let (k2x, k2v) = (v + 0.5 * h * k1v, acc(t + 0.5 * h, x + 0.5 * h * k1x, v + 0.5 * h * k1v));
            let (k3x, k3v) = (v + 0.5 * h * k2v, acc(t + 0.5 * h, x + 0.5 * h * k2x, v + 0.5 * h * k2v));
            let (k4x, k4v) = (v + h * k3v, acc(t + h, x + h * k3x, v + h * k3v));
            x += h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
            v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
        }
        (x, v)
    }

    #[test]
    fn free_response_matches_rk4_for_every_damping_regime() {
        for &zeta in &[0.0, 0.05, 0.999_999, 1.0, 1.000_001, 1.5, 30.0] {
            let osc = Oscillator::new(3.0, zeta);
            let (x, v) = osc.free(0.7, -1.3, 2.1);
            let (xr, vr) = rk4(&osc, 0.7, -1.3, 2.1, |_| 0.0);
            assert!((x - xr).abs() < 1e-11 && (v - vr).abs() < 1e-10, "zeta {zeta}: {x} {xr} {v} {vr}");
        }
    }

    #[test]
    fn resonant_response_matches_rk4_undamped_at_exact_resonance() {
        let osc = Oscillator::new(2.0, 0.0);
        let s = 3.7;
        let (g, gd) = osc.harmonic_from_rest(2.0, s, C64::from_polar(1.0, 2.0 * s));
        // Load Re(e^{2 i t}) = cos 2t from rest: x = t sin(2t) / 4.
        let (xr, vr) = rk4(&osc, 0.0, 0.0, s, |t| (2.0 * t).cos());
        assert!((g.re - xr).abs() < 1e-11, "{} {}", g.re, xr);
        assert!((gd.re - vr).abs() < 1e-10);
        assert!((g.re - s * (2.0 * s).sin() / 4.0).abs() < 1e-14);
    }

    #[test]
    fn near_critical_kernels_are_continuous() {
        let below = Oscillator::new(5.0, 1.0 - 1e-12).kernels(0.8);
        let at = Oscillator::new(5.0, 1.0).kernels(0.8);
        let above = Oscillator::new(5.0, 1.0 + 1e-12).kernels(0.8);
        assert!((below.0 - at.0).abs() < 1e-12 && (above.1 - at.1).abs() < 1e-12 && (below.1 - above.1).abs() < 1e-12);
        // Critical damping closed form: Es = t e^{-omega t}.
        assert!((at.1 - 0.8 * (-4.0f64).exp()).abs() < 1e-16);
    }

    #[test]
    fn the_increment_of_ec_is_accurate_for_tiny_times() {
        for zeta in [0.0, 0.3, 1.0, 3.0] {
            let osc = Oscillator::new(7.0, zeta);
            let t = 1e-9;
            let (_, _, inc) = osc.kernels_and_increment(t);
            // Ec = e^{-a t} C0 = 1 - a t + (a^2 - omega^2 (1 - zeta^2)) t^2 / 2 + O(t^3)
            let dd = 49.0 * (1.0 - zeta * zeta);
            let series = -osc.a * t + (osc.a * osc.a - dd) * t * t / 2.0;
            assert!((inc / series - 1.0).abs() < 1e-7, "zeta {zeta}: {inc} vs {series}");
            let (ec, _, inc) = osc.kernels_and_increment(0.8);
            assert!((ec - 1.0 - inc).abs() < 1e-15);
        }
    }

    #[test]
    fn the_short_time_series_matches_the_closed_form_up_to_its_switch() {
        // Below r^2 = 1e-2 the kernels come from the Taylor series; against
        // cos, sin (under-damped) and cosh, sinh (over-damped) directly.
        for (zeta, sign) in [(0.0, 1.0), (0.6, 1.0), (1.8, -1.0)] {
            let osc = Oscillator::new(3.0, zeta);
            let root = (9.0 * (1.0 - zeta * zeta) * sign).sqrt();
            for r in [1e-4, 1e-3, 0.01, 0.05, 0.0999, 0.1001, 0.2] {
                let t = r / root;
                let (c, s) = if sign > 0.0 { (r.cos(), r.sin() / root) } else { (r.cosh(), r.sinh() / root) };
                let e = (-osc.a * t).exp();
                let (ec, es, ec_m1) = osc.kernels_and_increment(t);
                assert!((ec - e * c).abs() <= 4e-16, "zeta {zeta}, r {r}: Ec {ec} vs {}", e * c);
                assert!((es / (e * s) - 1.0).abs() <= 4e-16, "zeta {zeta}, r {r}: Es {es} vs {}", e * s);
                assert!((ec_m1 - (ec - 1.0)).abs() <= 4e-16, "zeta {zeta}, r {r}");
            }
        }
    }

    #[test]
    fn phi1_small_and_large() {
        let z = C64::new(-1e-7, 3e-7);
        let exact = C64::new(1.0, 0.0) + z / 2.0 + z * z / 6.0;
        assert!((phi1(z) - exact).norm() < 1e-16);
        let z = C64::new(-2.0, 1.0);
        assert!((phi1(z) - (z.exp() - 1.0) / z).norm() < 1e-15);
    }

    /// `e[0, x, y]` against its definition as the double integral
    /// `int_0^1 int_0^u e^{x (u - v) + y v} dv du` by Gauss-Legendre, across
    /// small, large, equal and nearly equal arguments.
    #[test]
    fn exp_divdiff2_matches_its_integral() {
        let quad = |x: C64, y: C64| -> C64 {
            // int_0^1 e^{x u} (e^{(y - x) u} ... ) : integrate e[x u, y u] u du (= S^2 e[0,xS,yS] at S = 1).
            let n = 400_000;
            let mut s = C64::new(0.0, 0.0);
            for i in 0..n {
                let u = (i as f64 + 0.5) / n as f64;
                let d = (y - x) * u;
                let e = if d.norm() < 1e-8 { (x * u).exp() } else { ((y * u).exp() - (x * u).exp()) / d };
                s += e * u;
            }
            s / n as f64
        };
        let cases = [
            (C64::new(0.0, 0.0), C64::new(0.0, 0.0)),
            (C64::new(-0.3, 0.7), C64::new(-0.3, 0.7)),
            (C64::new(-0.01, 3.0), C64::new(0.0, 3.0)),
            (C64::new(-0.5, 9.0), C64::new(0.0, -9.0)),
            (C64::new(-2.0, 40.0), C64::new(-2.0, 40.0 + 1e-9)),
            (C64::new(-0.1, 0.5), C64::new(0.0, 2.0)),
        ];
        for (x, y) in cases {
            let (a, b) = (exp_divdiff2(x, y), quad(x, y));
            assert!((a - b).norm() < 1e-8 * b.norm(), "{x} {y}: {a} vs {b}");
        }
        assert!((exp_divdiff2(C64::new(0.0, 0.0), C64::new(0.0, 0.0)) - 0.5).norm() < 1e-16);
        // Far arguments: the closed form (phi1(x) - phi1(y)) / (x - y) is exact enough there.
        let (x, y) = (C64::new(-1e3, 2e5), C64::new(0.0, 1e5));
        let direct = (phi1(x) - phi1(y)) / (x - y);
        assert!((exp_divdiff2(x, y) - direct).norm() < 1e-12 * direct.norm());
        // Nearly equal large arguments: against the derivative phi1'(x) = (e^x - phi1(x)) / x.
        let x = C64::new(-3.0, 1e4);
        let deriv = (x.exp() - phi1(x)) / x;
        assert!((exp_divdiff2(x, x + C64::new(0.0, 1e-12)) - deriv).norm() < 1e-12 * deriv.norm());
    }
}
