//! Guaranteed event location (Taylor lower bounds from rigorous derivative bounds).
//!
//! Every switch is the first zero of an event function `h` that is
//! non-negative while the phase lasts. From `h` and its derivatives at `t`,
//! and a bound `M` on a higher derivative over `[t, t + tau_max]`, the Taylor
//! lower bound `h + h' s - M2 s^2 / 2` (and its cubic and quartic analogues
//! for departures, where `h` and `h'` vanish) proves `h > 0` on `[t, t + s)`.
//! Advancing by such certified steps can never jump over a zero, not even
//! two zeros inside one step (a rebound, a graze); near a transversal zero
//! the steps converge to it quadratically from the admissible side.

use super::functional::{DerivativeBounds, Jet};

/// What the lower bound says about the event function at the current time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Certified {
    /// `h > 0` on `[t, t + s)`.
    Clear(f64),
    /// `h` is at zero within rounding at `t`: the event is here.
    AtZero,
}

/// Whether the value is at zero within its rounding noise.
pub fn at_zero(jet: &Jet) -> bool {
    jet.d[0] <= jet.noise[0]
}

/// The certified event-free step from `t`.
///
/// `departing` says the state was just put on the boundary `h = 0` by the
/// event handling (after an impact or a release): then a zero value at `t`
/// is the boundary itself, not a new event, and noise-level `h` and `h'` are
/// treated as exact zeros.
pub fn certified_step(jet: &Jet, bounds: &DerivativeBounds, departing: bool) -> Certified {
    let [mut h, mut h1, h2, h3] = jet.d;
    let [m2, m3, m4] = bounds.m;
    let tau_max = bounds.tau;
    let noise = |m: usize| jet.noise[m].max(bounds.floor[m]);
    if h <= jet.noise[0] || (h <= bounds.floor[0] && h1.abs() <= noise(1)) {
        // At zero within rounding, or a value and slope below the level the
        // bounds can resolve (a load a hundred orders of magnitude below the
        // scene's scale): the event is here, or, departing, the boundary.
        if !departing {
            return Certified::AtZero;
        }
        h = 0.0;
        if h1.abs() <= noise(1) {
            h1 = 0.0;
        }
    }
    // Derivatives below the bounds' own rounding level carry no direction.
    let below_floor = |m: usize, v: f64| bounds.floor[m] > jet.noise[m] && v.abs() <= bounds.floor[m];
    let h2 = if below_floor(2, h2) { 0.0 } else { h2 };
    let h3 = if below_floor(3, h3) { 0.0 } else { h3 };
    let mut best = 0.0f64;
    // Quadratic bound: h + h1 s - m2 s^2 / 2 > 0.
    if h > 0.0 || h1 > 0.0 {
        let disc = (h1 * h1 + 2.0 * m2 * h).sqrt();
        let s = if h1 <= 0.0 {
            2.0 * h / (disc - h1)
        } else if m2 > 0.0 {
            (h1 + disc) / m2
        } else {
            f64::INFINITY
        };
        best = best.max(s);
    }
    // Cubic bound while moving away: h + s (h1 + h2 s / 2 - m3 s^2 / 6) > 0.
    if h1 >= 0.0 && (h1 > 0.0 || h2 > jet.noise[2]) {
        let s = if m3 > 0.0 {
            3.0 * (0.5 * h2 + (0.25 * h2 * h2 + 2.0 * m3 * h1 / 3.0).sqrt()) / m3
        } else {
            f64::INFINITY
        };
        best = best.max(s);
    }
    // Quartic bound while moving away: h + h1 s + s^2 (h2 / 2 + h3 s / 6 - m4 s^2 / 24) > 0.
    // It certifies departures where h'' vanishes too (a release, where the
    // reaction and so h'' pass through zero).
    if h1 >= 0.0 {
        let h2c = if h2.abs() <= jet.noise[2] { h2.max(0.0) } else { h2 };
        let quartic = |h2: f64| {
            if m4 > 0.0 {
                let a = h3 / 6.0;
                let disc = a * a + m4 * h2 / 12.0;
                if disc >= 0.0 {
                    12.0 * (a + disc.sqrt()) / m4
                } else {
                    0.0
                }
            } else {
                f64::INFINITY
            }
        };
        if h2c >= 0.0 && (h2c > 0.0 || h3 > jet.noise[3]) {
            best = best.max(quartic(h2c));
        } else if departing && h == 0.0 && h1 == 0.0 && h3 > jet.noise[3] {
            // Leaving the boundary with h'' a hair below zero and h''' > 0:
            // a release located a few ulps before the reaction's zero. The
            // dip s^2 (h2 / 2 + h3 s / 6) < 0 lasts s < 3 |h2| / h3 and is
            // |h2| (3 h2 / h3)^2 / 2 deep at most; within rounding, it is the
            // boundary itself, and the quartic bound certifies beyond it.
            let s_dip = 3.0 * h2c.abs() / h3;
            if 0.5 * h2c.abs() * s_dip * s_dip <= jet.slack.max(jet.noise[0]).max(f64::MIN_POSITIVE) {
                best = best.max(quartic(h2c));
            }
        }
    }
    // Higher-order bounds for any direction: dropping the positive terms
    // leaves `h + min(h1, 0) s + min(h2, 0) s^2 / 2 [+ min(h3, 0) s^3 / 6]
    // - M s^k / k!`, decreasing and concave, whose single root is found from
    // below. Near a transversal zero the cubic one converges cubically.
    if h > 0.0 && h1 < 0.0 && m3 > 0.0 {
        let (c1, c2, c3) = (h1 - noise(1), (h2 - noise(2)).min(0.0), h3 - noise(3));
        let cubic_bound = [h, c1, 0.5 * c2, -m3 / 6.0];
        // The cubic and quartic bounds share their first three
        // coefficients, so part of their roots' brackets.
        let head = root_bracket(&[h, c1, 0.5 * c2]);
        let bracket = extend_bracket(&cubic_bound, head, 3);
        // The quartic bound exceeds the cubic one by `s^3 (4 (m3 + min(c3,
        // 0)) - m4 s) / 24`, so on `s <= 4 (m3 + min(c3, 0)) / m4`; when
        // the cubic's root lies there (it lies below `root_bracket`), the
        // quartic's root is the larger and the cubic need not be solved.
        let dominated = m4 > 0.0 && m4 * bracket < 4.0 * (m3 + c3.min(0.0));
        let cubic = if dominated { 0.0 } else { concave_root_below(&cubic_bound, bracket, jet.noise[0]) };
        best = best.max(cubic);
        if m4 > 0.0 && (dominated || m4 * cubic < 4.0 * m3) {
            // The quartic one converges with order four; it is tried where
            // its remainder is the smaller one at the cubic one's step.
            let quartic_bound = [h, c1, 0.5 * c2, c3.min(0.0) / 6.0, -m4 / 24.0];
            let quartic = concave_root_below(&quartic_bound, extend_bracket(&quartic_bound, head, 3), jet.noise[0]);
            best = best.max(quartic);
            let cube = quartic * quartic * quartic;
            if c3 > 0.0 && c3 * cube > 6.0 * jet.noise[0] && m4 * cube * quartic < 24.0 * jet.noise[0] {
                // Dropping a positive h''' leaves `h''' s^3 / 6` on the
                // table, which near the zero is the whole residual: kept,
                // the bound is no longer concave everywhere but still
                // decreasing near the zero. Only where that term is above
                // the noise and the remainder below it.
                best = best.max(extend_decreasing(&[h, c1, 0.5 * c2, c3 / 6.0, -m4 / 24.0], quartic));
            }
        }
    }
    // Moving away but bending back (h' > 0 > h''): h >= s (h1 + h2 s / 2 +
    // min(h3, 0) s^2 / 6 - m4 s^3 / 24), the bracket concave and decreasing;
    // its root reaches nearly the whole flight when h'' dominates (a short
    // rebound of a chatter sequence).
    if h >= 0.0 && h1 - noise(1) > 0.0 && h2 < 0.0 && m4 > 0.0 && m4 * best < 4.0 * m3 {
        let (c2, c3) = ((h2 - noise(2)).min(0.0), (h3 - noise(3)).min(0.0));
        best = best.max(concave_root(&[h1 - noise(1), 0.5 * c2, c3 / 6.0, -m4 / 24.0], 0.0));
    }
    if departing && h == 0.0 && h1 == 0.0 && h2.abs() <= jet.noise[2] && h3.abs() <= jet.noise[3] {
        // Resting on the boundary: every visible derivative is rounding (a
        // structure at rest on its stop under no load, a reaction that is
        // identically zero). `h >= -m4 s^4 / 24`, and a dip no deeper than
        // the rounding level is the boundary itself; with `m4 = 0` the
        // function stays on the boundary over the whole interval.
        let level = jet.slack.max(jet.noise[0]).max(bounds.floor[0]);
        let s = if m4 > 0.0 { (24.0 * level / m4).sqrt().sqrt() } else { f64::INFINITY };
        best = best.max(s);
    }
    if h > 0.0 && best == 0.0 {
        // h > 0 but no certificate (cannot happen with finite bounds): go slowly.
        best = f64::MIN_POSITIVE;
    }
    Certified::Clear(best.min(tau_max))
}

/// Whether a clear step `s` already reaches within 10 % of where the slope
/// alone meets zero: the search is converging on a zero, and a mode split
/// (which sharpens the bounds, not the slope) adds nothing there.
pub fn converging_on_zero(jet: &Jet, s: f64) -> bool {
    jet.d[1] < 0.0 && s * -jet.d[1] >= 0.9 * jet.d[0]
}

/// The certified step of a split `h = h_L + h_H` (free flight's modes,
/// a contact phase's coordinates): `h(t + s) >= h_L(t + s) - high_amp`
/// with `high_amp >= max |h_H|` over the interval, `h_L(t) = h(t) -
/// high_value`, `low` the derivatives of `h_L` at `t` and `bounds` its
/// derivative bounds; `size` is the magnitude of the sums behind
/// `high_value` and `high_amp`, whose rounding is allowed for. 0 when
/// `h_L - high_amp` is not positive now.
pub fn split_certificate(jet: &Jet, high_value: f64, high_amp: f64, size: f64, low: [f64; 3], bounds: &DerivativeBounds) -> f64 {
    // Rounding of the sums and of the subtractions.
    let margin = jet.noise[0] + 8.0 * f64::EPSILON * size;
    let d0 = jet.d[0] - high_value - high_amp.max(0.0) - margin;
    if d0 <= 0.0 {
        return 0.0;
    }
    let low_jet = Jet { d: [d0, low[0], low[1], low[2]], noise: jet.noise, slack: jet.slack };
    match certified_step(&low_jet, bounds, false) {
        Certified::Clear(s) => s,
        Certified::AtZero => 0.0,
    }
}

/// `p(s) = sum c_k s^k` and `p'(s)` by Horner's rule (unrolled: the
/// degree is a constant).
#[inline(always)]
fn polynomial_and_slope<const N: usize>(c: &[f64; N], s: f64) -> (f64, f64) {
    let (mut p, mut dp) = (0.0, 0.0);
    for &ck in c.iter().rev() {
        dp = dp * s + p;
        p = p * s + ck;
    }
    (p, dp)
}

/// A point past the root of a concave decreasing `p(s) = sum c_k s^k`
/// (`c_0 > 0`, the other coefficients `<= 0`): the root of `c_0 + c_j s^j`
/// for any `j` with `c_j < 0`, as `p <= c_0 + c_j s^j`; the smallest of
/// those. The j-th root (a sqrt, a cbrt) only where the term already
/// exceeds `c_0` at the point so far, so that it lies before it. Not finite
/// when no coefficient is negative.
fn root_bracket<const N: usize>(c: &[f64; N]) -> f64 {
    let b = if c[1] < 0.0 { c[0] / -c[1] } else { f64::INFINITY };
    extend_bracket(c, b, 2)
}

/// [`root_bracket`] of `c` from `b`, the bracket of its first `from`
/// coefficients: polynomials that share those share that part of the
/// work (a chain of divisions and roots that every step waits for).
#[inline(always)]
fn extend_bracket<const N: usize>(c: &[f64; N], mut b: f64, from: usize) -> f64 {
    for j in from..N {
        // b^j by products (the degree is a constant: unrolled, no `powi` call).
        let mut b_j = b;
        for _ in 1..j {
            b_j *= b;
        }
        if c[j] < 0.0 && !(-c[j] * b_j <= c[0]) {
            let ratio = c[0] / -c[j];
            b = b.min(match j {
                2 => ratio.sqrt(),
                3 => ratio.cbrt(),
                4 => ratio.sqrt().sqrt(),
                _ => ratio.powf(1.0 / j as f64),
            });
        }
    }
    b
}

/// A point `s > 0` below the root of `p(s) = sum c_k s^k` with `c_0 > 0`
/// and every other coefficient `<= 0` (the last `< 0`): `p` is decreasing
/// and concave on `s >= 0`, so a chord between a point with `p >= 0` and
/// one past the root meets zero before the root, and Newton's method from
/// a point past the root stays past it. Three rounds from the nearest root
/// of `c_0 + c_j s^j` leave the returned point within a few percent of the
/// root, always on its left (`p > 0`).
fn concave_root<const N: usize>(c: &[f64; N], resolution: f64) -> f64 {
    concave_root_below(c, root_bracket(c), resolution)
}

/// [`concave_root`] given `root_bracket(c)` (a caller that has it already).
fn concave_root_below<const N: usize>(c: &[f64; N], bracket: f64, resolution: f64) -> f64 {
    let eval = |s: f64| polynomial_and_slope(c, s);
    let k = N - 1;
    let mut b = bracket;
    if !(b.is_finite() && b > 0.0) {
        return 0.0;
    }
    let (mut a, mut pa) = (0.0, c[0]);
    let (mut pb, mut db) = eval(b);
    if pb >= 0.0 {
        // The other terms vanish: b is the root.
        return b * (1.0 - 1e-9);
    }
    for _ in 0..3 {
        // Bracketed to rounding: nothing left to gain.
        if pb >= 0.0 || db >= 0.0 || pa <= 0.0 || b - a <= 1e-13 * b {
            break;
        }
        let chord = a + pa * (b - a) / (pa - pb);
        let (pc, _) = eval(chord);
        if pc > 0.0 {
            (a, pa) = (chord, pc);
        }
        let newton = b - pb / db;
        if newton > a && newton < b {
            b = newton;
            (pb, db) = eval(b);
        }
    }
    // The chord lags behind Newton from the right, which converges
    // quadratically: a point 1e-12 before the Newton point, if p is still
    // positive there, lands the step within rounding of the root, and the
    // next point is the event. Worth an evaluation only where the step can
    // end within `resolution` of the zero: the chord's lag leaves more than
    // that, and the remainder term (the bound's own distance from the
    // function) less.
    let converging = (b - a) * -c[1] > resolution && {
        let mut remainder = -c[k];
        for _ in 0..k {
            remainder *= a;
        }
        remainder < resolution
    };
    if converging {
        // b itself when it is on the root within rounding; otherwise the
        // next Newton point, once the step to it is below 1e-6 of b (the
        // one after would be below 1e-12).
        let newton = if pb >= 0.0 {
            Some(b)
        } else if db < 0.0 && -pb < 1e-6 * b * -db {
            Some(b - pb / db)
        } else {
            None
        };
        if let Some((near, pn)) = newton.and_then(|x| just_before(c, x, a)) {
            (a, pa) = (near, pn);
        }
    }
    if pa > 0.0 {
        a
    } else {
        0.0
    }
}

/// A point 1e-12 before `x` (a converged Newton point) and `p` there, if
/// it lies right of `a` and `p` is still positive there.
fn just_before<const N: usize>(c: &[f64; N], x: f64, a: f64) -> Option<(f64, f64)> {
    let near = x * (1.0 - 1e-12);
    if near <= a {
        return None;
    }
    let (p, _) = polynomial_and_slope(c, near);
    (p > 0.0).then_some((near, p))
}

/// A point `x >= start` with `p > 0` on `[0, x)`, for `p(s) = sum c_k s^k`
/// whose coefficients are `<= 0` except `c_0 > 0` and `c_3 > 0`, given
/// such a point `start` (from the concave bound without `c_3`). While
/// `c_1 + 3 c_3 x^2 < 0`, `p' <= c_1 + 3 c_3 s^2 < 0` on `[0, x]` (the other
/// coefficients are not positive), so `p(x) > 0` certifies all of `[0, x)`.
fn extend_decreasing(c: &[f64; 5], start: f64) -> f64 {
    let eval = |s: f64| polynomial_and_slope(c, s);
    // `c1 + 3 c3 x^2` grows with x: once true at b, true left of it.
    let decreasing = |x: f64| c[1] + 3.0 * c[3] * x * x < 0.0;
    let (mut a, (mut pa, da)) = (start, eval(start));
    if !(pa > 0.0 && da < 0.0) {
        return start;
    }
    // Newton from the certified point; past the zero, a chord and Newton
    // from the right narrow the bracket, as in `concave_root`. Only points
    // with `p > 0` where `p` is decreasing are taken.
    let mut b = a - pa / da;
    let mut bracketed = false;
    for _ in 0..3 {
        if !(b > a && decreasing(b)) {
            break;
        }
        let (pb, db) = eval(b);
        if pb > 0.0 {
            (a, pa) = (b, pb);
            if !(db < 0.0) {
                break;
            }
            b = a - pa / db;
            continue;
        }
        bracketed = true;
        let chord = a + pa * (b - a) / (pa - pb);
        let (pc, _) = eval(chord);
        if chord > a && chord < b && pc > 0.0 {
            (a, pa) = (chord, pc);
        }
        let newton = b - pb / db;
        if !(db < 0.0 && newton > a && newton < b) {
            break;
        }
        b = newton;
    }
    if bracketed && decreasing(b) {
        if let Some((near, _)) = just_before(c, b, a) {
            a = near;
        }
    }
    a
}

/// Which way a contact goes when the gap and the normal velocity both vanish:
/// the sign of the first derivative above noise (`h''`, then `h'''`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tendency {
    /// `h` will become negative: the contact is pressed (stick / stay stuck).
    Closing,
    /// `h` will become positive: the contact opens.
    Opening,
    /// `h` and every derivative we can see vanish: nothing moves the
    /// contact either way (at rest on the stop under no load).
    Resting,
}

pub fn tendency_from(jet: &Jet, first: usize) -> Tendency {
    for m in first..4 {
        if jet.d[m] < -jet.noise[m] {
            return Tendency::Closing;
        }
        if jet.d[m] > jet.noise[m] {
            return Tendency::Opening;
        }
    }
    // Identically zero to every order we can see: nothing moves it.
    Tendency::Resting
}

#[cfg(test)]
mod tests {
    use super::*;

    fn jet(d: [f64; 4]) -> Jet {
        Jet { d, noise: [1e-16; 4], slack: 1e-16 }
    }

    #[test]
    fn quadratic_step_stops_short_of_a_zero() {
        // h = 1 - s^2 / 2 (h'' = -1, |h''| <= 1): first zero at sqrt 2.
        let b = DerivativeBounds { tau: 10.0, m: [1.0, 0.0, 0.0], floor: [0.0; 4] };
        match certified_step(&jet([1.0, 0.0, -1.0, 0.0]), &b, false) {
            Certified::Clear(s) => assert!((s - 2f64.sqrt()).abs() < 1e-15),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn departure_uses_the_cubic_bound() {
        // h'' = 1, h''' = 0 and |h'''|, |h''''| <= 1: the cubic bound
        // s^2 / 2 - s^3 / 6 certifies s < 3, the quartic s^2 / 2 - s^4 / 24
        // certifies s < sqrt(12); the larger one is taken.
        let b = DerivativeBounds { tau: 10.0, m: [1.0, 1.0, 1.0], floor: [0.0; 4] };
        match certified_step(&jet([0.0, 0.0, 1.0, 0.0]), &b, true) {
            Certified::Clear(s) => assert!((s - 12f64.sqrt()).abs() < 1e-12, "{s}"),
            other => panic!("{other:?}"),
        }
        let b = DerivativeBounds { tau: 10.0, m: [1.0, 1.0, 1e9], floor: [0.0; 4] };
        match certified_step(&jet([0.0, 0.0, 1.0, 0.0]), &b, true) {
            Certified::Clear(s) => assert!((s - 3.0).abs() < 1e-12, "{s}"),
            other => panic!("{other:?}"),
        }
        assert_eq!(certified_step(&jet([0.0, 0.0, 1.0, 0.0]), &b, false), Certified::AtZero);
    }

    #[test]
    fn tendency_reads_the_first_significant_derivative() {
        assert_eq!(tendency_from(&jet([0.0, 0.0, -2.0, 5.0]), 2), Tendency::Closing);
        assert_eq!(tendency_from(&jet([0.0, 0.0, 0.0, 5.0]), 2), Tendency::Opening);
        assert_eq!(tendency_from(&jet([0.0, 0.0, 1e-17, -1e-17]), 2), Tendency::Resting);
    }

    #[test]
    fn concave_root_stays_left_of_the_root_and_close_to_it() {
        // Decreasing concave polynomials; the root by bisection.
        let cases: [&[f64]; 5] = [
            &[1.0, -2.0, 0.0, -3.0],
            &[0.376, -14.34, 0.0, -540.0],
            &[1e-6, -13.0, -40.0, -500.0],
            &[2.0, 0.0, 0.0, -1e4, -1e6],
            &[0.5, -1.0, -0.5, -0.1, -1e-3],
        ];
        for c in cases {
            let p = |s: f64| c.iter().rev().fold(0.0, |acc, &ck| acc * s + ck);
            let mut hi = 1.0;
            while p(hi) > 0.0 {
                hi *= 2.0;
            }
            let lo = first_zero(p, hi);
            let s = match *c {
                [a, b, c, d] => concave_root(&[a, b, c, d], 0.0),
                [a, b, c, d, e] => concave_root(&[a, b, c, d, e], 0.0),
                _ => unreachable!("cubic and quartic cases"),
            };
            assert!(s <= lo && p(s) > 0.0, "{c:?}: {s} vs root {lo}");
            assert!(s >= 0.95 * lo, "{c:?}: {s} far below the root {lo}");
        }
    }

    #[test]
    fn the_cubic_bound_converges_faster_than_the_quadratic_near_a_zero() {
        // Approaching a transversal zero: h = 1e-3, h' = -1, |h''| <= 10,
        // |h'''| <= 10: the quadratic step leaves ~M2 s^2 / 2 = 5e-6 behind,
        // the cubic ~M3 s^3 / 6 = 1.7e-9.
        let b = DerivativeBounds { tau: 10.0, m: [10.0, 10.0, 0.0], floor: [0.0; 4] };
        let Certified::Clear(s) = certified_step(&jet([1e-3, -1.0, 0.0, 0.0]), &b, false) else { panic!() };
        // The exact first zero of the worst case h = 1e-3 - s - 10 s^3 / 6
        // (h'' = 0 at the probe) is at 9.99998e-4.
        assert!(s < 1e-3 && s > 0.99999e-3, "{s}");
    }

    /// The first zero by bisection of `p` on `(0, hi)`, with `p(hi) <= 0`.
    fn first_zero(p: impl Fn(f64) -> f64, hi: f64) -> f64 {
        let (mut lo, mut hi) = (0.0, hi);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if p(mid) > 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo
    }

    /// Where the cubic bound's root is left unsolved (it lies below
    /// `root_bracket`, inside the range where the quartic bound is the
    /// larger), the quartic bound's root is at least the cubic's: checked
    /// by bisection of both over a grid of values, slopes, curvatures,
    /// third derivatives and derivative bounds, and the certified step
    /// reaches 95 % of the larger root whether or not the cubic was solved.
    #[test]
    fn an_unsolved_cubic_bound_never_beats_the_quartic() {
        let (mut skipped, mut solved) = (0, 0);
        for &h in &[1e-9, 1e-4, 1e-2, 0.3] {
            for &h1 in &[-1e-3, -0.1, -1.0, -30.0] {
                for &h2 in &[0.0f64, -0.5, -20.0, 3.0] {
                    for &h3 in &[-50.0f64, -1.0, 0.0, 2.0, 40.0] {
                        for &(m3, m4) in &[(60.0, 1.0), (60.0, 1e3), (1e3, 1e5), (5.0, 1e4), (100.0, 10.0)] {
                            if h3.abs() > m3 {
                                continue;
                            }
                            let c = [h, h1, 0.5 * h2.min(0.0), -m3 / 6.0];
                            let c3 = h3.min(0.0);
                            let cubic = |s: f64| c[0] + s * (c[1] + s * (c[2] + s * c[3]));
                            let quartic = |s: f64| c[0] + s * (c[1] + s * (c[2] + s * (c3 / 6.0 - s * m4 / 24.0)));
                            let (rc, rq) = (first_zero(cubic, 1e3), first_zero(quartic, 1e3));
                            let b = DerivativeBounds { tau: 1e3, m: [100.0, m3, m4], floor: [0.0; 4] };
                            let Certified::Clear(step) = certified_step(&jet([h, h1, h2, h3]), &b, false) else { panic!("no zero at h = {h}") };
                            let case = format!("h {h} h1 {h1} h2 {h2} h3 {h3} m3 {m3} m4 {m4}: step {step}, roots {rc} (cubic), {rq} (quartic)");
                            // Never short of what the cubic bound alone certifies.
                            assert!(step >= 0.95 * rc, "{case}");
                            if !(m4 * root_bracket(&c) < 4.0 * (m3 + c3)) {
                                solved += 1;
                                continue;
                            }
                            skipped += 1;
                            assert!(rq >= rc, "{case}");
                            // Past the quartic bound's root only where a positive h''' is kept (`extend_decreasing`).
                            assert!(step >= 0.95 * rq && (step <= rq || h3 > 0.0), "{case}");
                        }
                    }
                }
            }
        }
        assert!(skipped > 100 && solved > 100, "skipped {skipped}, solved {solved}");
    }

    #[test]
    fn the_quartic_bound_converges_faster_than_the_cubic_near_a_zero() {
        // h = 1e-2, h' = -1, |h'''| <= 100, |h''''| <= 10: the cubic step
        // leaves ~M3 s^3 / 6 = 1.7e-5 behind, the quartic ~M4 s^4 / 24 = 4e-9.
        // The worst case (fourth derivative -10) has its zero at 1e-2 - 4.2e-9.
        let b = DerivativeBounds { tau: 10.0, m: [100.0, 100.0, 10.0], floor: [0.0; 4] };
        let Certified::Clear(s) = certified_step(&jet([1e-2, -1.0, 0.0, 0.0]), &b, false) else { panic!() };
        let zero = first_zero(|s| 1e-2 - s - 10.0 * s.powi(4) / 24.0, 1.0);
        assert!(s <= zero && s > zero - 1e-8, "{s} vs {zero}");
    }

    #[test]
    fn a_rebound_bending_back_is_certified_to_nearly_its_end() {
        // Leaving the boundary at h' = 1 with h'' = -2 (a flight of 1), and
        // |h''| <= 2.5, |h'''| <= 10, |h''''| <= 1: the quadratic bound gives
        // 0.8, the cubic one 0.53; the quartic one reaches the worst case
        // h = s - s^2 - s^4 / 24, whose zero is at 0.96.
        let b = DerivativeBounds { tau: 10.0, m: [2.5, 10.0, 1.0], floor: [0.0; 4] };
        let Certified::Clear(s) = certified_step(&jet([0.0, 1.0, -2.0, 0.0]), &b, true) else { panic!() };
        let zero = first_zero(|s| s - s * s - s.powi(4) / 24.0, 0.999);
        assert!(s <= zero && s > 0.97 * zero, "{s} vs {zero}");
    }

    #[test]
    fn a_function_resting_on_its_boundary_is_certified() {
        // h = 0 to every visible order, departing: with no bound on h''''
        // it stays on the boundary for the whole interval; with |h''''| <= M
        // a dip of -M s^4 / 24 is rounding while it stays within the noise.
        let zero = Jet { d: [0.0; 4], noise: [0.0; 4], slack: 0.0 };
        let b = DerivativeBounds { tau: 10.0, m: [0.0, 0.0, 0.0], floor: [0.0; 4] };
        assert_eq!(certified_step(&zero, &b, true), Certified::Clear(10.0));
        assert_eq!(certified_step(&zero, &b, false), Certified::AtZero);
        let noisy = Jet { d: [0.0; 4], noise: [1e-16; 4], slack: 1e-16 };
        let b = DerivativeBounds { tau: 10.0, m: [1.0, 1.0, 24.0], floor: [0.0; 4] };
        match certified_step(&noisy, &b, true) {
            Certified::Clear(s) => assert!((s - 1e-4).abs() < 1e-12, "{s}"),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn the_last_step_onto_a_zero_lands_within_rounding_of_it() {
        // The end of a chatter flight (S3 at t = 6.48626): h = 4.9e-10
        // falling at 3.1e-3, noise 3.9e-18, the worst case h'''' = -M4 the
        // function itself (so the bound's root is the zero). The step must
        // end where h is within its noise (the next point is the event)
        // and never pass the zero. Before: with h''' < 0 the chord stopped
        // 2.4e-6 short in relative terms (1.2e-15 of h left); with a large
        // h''' > 0, dropping the cubic term left h''' s^3 / 6 = 1.3e-16.
        let (h, h1, h2, m3, m4) = (4.910960381183141e-10, -0.0031111542684988044, -60.90508587784873, 9919.56, 1.5049e6);
        let noise = [3.9e-18, 3.6e-13, 1.7e-11, 4.5e-11];
        for h3 in [-2810.4, 2810.4, 2.0e5] {
            let p = |s: f64| h + s * (h1 + s * (0.5 * h2 + s * (h3 / 6.0 - s * m4 / 24.0)));
            let b = DerivativeBounds { tau: 1.0, m: [100.0, m3, m4], floor: [0.0; 4] };
            let jet = Jet { d: [h, h1, h2, h3], noise, slack: 1e-16 };
            let Certified::Clear(s) = certified_step(&jet, &b, false) else { panic!() };
            let zero = first_zero(p, 1e-6);
            assert!(s <= zero && p(s) >= 0.0, "h''' = {h3}: {s} passes the zero {zero}");
            assert!(p(s) <= noise[0], "h''' = {h3}: {:e} left at the end of the step", p(s));
        }
    }

    #[test]
    fn extending_a_root_with_a_positive_cubic_term_never_passes_it() {
        // p = c0 + c1 s + c2 s^2 + c3 s^3 + c4 s^4 with c3 > 0: every
        // extension of the concave root without c3 stays left of p's first
        // zero (bisection on a fine grid) and reaches it closely when p is
        // decreasing there.
        let cases: [[f64; 5]; 4] = [
            [1e-3, -1.0, -5.0, 40.0, -1e3],
            [0.5, -1.0, -0.1, 0.3, -0.01],
            [1.0, -0.01, 0.0, 1.0, -1e6],
            [2e-10, -3e-3, -30.0, 470.0, -6.3e4],
        ];
        for c in cases {
            let p = |s: f64| c.iter().rev().fold(0.0, |acc, &ck| acc * s + ck);
            let mut hi = 1e-12;
            while p(hi) > 0.0 {
                hi *= 1.5;
            }
            let zero = first_zero(p, hi);
            let concave = concave_root(&[c[0], c[1], c[2], 0.0, c[4]], 0.0);
            let s = extend_decreasing(&c, concave);
            assert!(s >= concave && s <= zero && p(s) > 0.0, "{c:?}: {s} vs zero {zero}");
            let grid_ok = (1..2000).all(|k| p(s * k as f64 / 2000.0) > 0.0);
            assert!(grid_ok, "{c:?}: p dips below zero before {s}");
            if c[1] + 3.0 * c[3] * zero * zero < 0.0 {
                assert!(s > (1.0 - 1e-9) * zero, "{c:?}: {s} short of the zero {zero}");
            }
        }
    }
}
