//! The sine, cosine and `e^x - 1` of the probe's hot path.
//!
//! Every probe evaluates a sine and cosine per mode and per load harmonic,
//! and `e^x - 1` per mode (the kernels of [`super::oscillator`]), mostly
//! at short arguments (the flights of a chatter sequence). The C library's
//! `sincos` is table-driven and correctly rounded in nearly every case; at
//! about twice its cost. Here:
//! - `sin_cos` is FreeBSD msun's `sincos` (the `k_sin`/`k_cos` minimax
//!   kernels on `|x| <= pi/4`, Cody-Waite reduction beyond), through the
//!   `libm` crate, within 1 ulp, up to `|x| = 2^14`, and the C library's
//!   beyond, where msun's reduction is the slower;
//! - `exp_m1` is the Taylor polynomial to `x^10` for `|x| <= 1/8`
//!   (truncation below `(1/8)^10 / 11! < 3e-17` relative; the leading `x`
//!   is exact and the rest at most `x / 15`, so rounding adds little to
//!   half an ulp), summed by Estrin's scheme (independent products, four
//!   levels deep instead of Horner's ten), and the C library's `expm1`
//!   beyond.

use super::complex::C64;

/// `(sin x, cos x)`, within 1 ulp.
#[inline]
pub fn sin_cos(x: f64) -> (f64, f64) {
    if x.abs() < MSUN_LIMIT {
        libm::sincos(x)
    } else {
        x.sin_cos()
    }
}

/// Past this argument msun's reduction costs more than the C library's
/// whole `sincos` (about 19 against 17 ns at 1e5, 64 against 17 ns at
/// 1.5e6, where its Cody-Waite reduction gives way to the Payne-Hanek one,
/// and 124 ns from 3e6: the highest modes of a 500-mode beam); below it
/// msun's is the cheaper (6.5 against 13 ns at 0.5, 16 against 17 ns at 1e4).
const MSUN_LIMIT: f64 = 16384.0;

/// `e^{i theta}`.
#[inline]
pub fn unit(theta: f64) -> C64 {
    let (s, c) = sin_cos(theta);
    C64::new(c, s)
}

/// `e^x - 1` without cancellation, within 1 ulp.
#[inline]
pub fn exp_m1(x: f64) -> f64 {
    if x.abs() <= 1.0 / 8.0 {
        // 1 / k! for k = 2..=10.
        const C: [f64; 9] = [1.0 / 2.0, 1.0 / 6.0, 1.0 / 24.0, 1.0 / 120.0, 1.0 / 720.0, 1.0 / 5040.0, 1.0 / 40320.0, 1.0 / 362880.0, 1.0 / 3628800.0];
        let x2 = x * x;
        let x4 = x2 * x2;
        let low = (C[0] + C[1] * x) + x2 * (C[2] + C[3] * x);
        let high = (C[4] + C[5] * x) + x2 * (C[6] + C[7] * x) + x4 * C[8];
        x + x2 * (low + x4 * high)
    } else {
        x.exp_m1()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The difference in units of the last place of `reference`.
    fn ulps(value: f64, reference: f64) -> f64 {
        if value == reference {
            return 0.0;
        }
        let ulp = f64::from_bits(reference.abs().to_bits() + 1) - reference.abs();
        (value - reference).abs() / ulp
    }

    /// Arguments spread over `[-scale, scale]` (a low-discrepancy sequence).
    fn arguments(scale: f64) -> impl Iterator<Item = f64> {
        (0..20_000).map(move |i| scale * (2.0 * (i as f64 * 0.618_033_988_749_894_9).fract() - 1.0))
    }

    #[test]
    fn sin_cos_is_within_an_ulp_of_the_c_library_on_both_sides_of_its_switch() {
        // The C library's `sin`/`cos` (glibc: correctly rounded in nearly
        // every case) is the independent reference; two roundings apart at
        // most.
        for scale in [1e-9, 1e-3, 0.5, 0.8, 3.0, 40.0, 1e4, 2e4, 1e6] {
            for x in arguments(scale) {
                let (s, c) = sin_cos(x);
                assert!(ulps(s, x.sin()) <= 2.0 && ulps(c, x.cos()) <= 2.0, "x = {x:e}: ({s:e}, {c:e})");
            }
        }
        assert_eq!(sin_cos(0.0), (0.0, 1.0));
    }

    #[test]
    fn exp_m1_is_within_an_ulp_of_the_c_library_on_both_sides_of_its_switch() {
        for scale in [1e-300, 1e-12, 1e-4, 1.0 / 64.0, 0.1, 0.125, 0.15, 1.0, 30.0] {
            for x in arguments(scale) {
                assert!(ulps(exp_m1(x), x.exp_m1()) <= 2.0, "x = {x:e}");
            }
        }
        assert_eq!(exp_m1(0.0), 0.0);
    }
}
