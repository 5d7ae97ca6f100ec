//! The largest value of a smooth function on an interval: Brent's method
//! (golden section with parabolic interpolation, BRE73 ch. 5), as for the
//! peak force of a push inside one integration step.

/// The golden section's smaller part, `(3 - sqrt 5) / 2`.
const GOLDEN: f64 = 0.381_966_011_250_105_1;

/// A point of `[a, b]` where `f` is largest (to within `xtol`) and the
/// value there, starting from `(x, fx)` inside the bracket (`f` is
/// assumed unimodal on it). About ten evaluations to 1e-8 of the
/// bracket where the golden section alone takes thirty-eight.
pub fn maximize(f: impl Fn(f64) -> f64, mut a: f64, mut b: f64, x: f64, fx: f64, xtol: f64) -> (f64, f64) {
    // Minimize g = -f.
    let (mut x, mut gx) = (x, -fx);
    let (mut w, mut gw, mut v, mut gv) = (x, gx, x, gx);
    let (mut d, mut e): (f64, f64) = (0.0, 0.0);
    for _ in 0..100 {
        let m = 0.5 * (a + b);
        let tol1 = xtol.max(4.0 * f64::EPSILON * x.abs());
        let tol2 = 2.0 * tol1;
        if (x - m).abs() <= tol2 - 0.5 * (b - a) {
            break;
        }
        let mut golden = true;
        if e.abs() > tol1 {
            // The parabola through (x, w, v).
            let r = (x - w) * (gx - gv);
            let mut q = (x - v) * (gx - gw);
            let mut p = (x - v) * q - (x - w) * r;
            q = 2.0 * (q - r);
            if q > 0.0 {
                p = -p;
            } else {
                q = -q;
            }
            let previous = e;
            e = d;
            if p.abs() < (0.5 * q * previous).abs() && p > q * (a - x) && p < q * (b - x) {
                d = p / q;
                let u = x + d;
                if u - a < tol2 || b - u < tol2 {
                    d = tol1.copysign(m - x);
                }
                golden = false;
            }
        }
        if golden {
            e = if x >= m { a - x } else { b - x };
            d = GOLDEN * e;
        }
        let u = if d.abs() >= tol1 { x + d } else { x + tol1.copysign(d) };
        let gu = -f(u);
        if gu <= gx {
            if u >= x {
                a = x;
            } else {
                b = x;
            }
            (v, gv, w, gw, x, gx) = (w, gw, x, gx, u, gu);
        } else {
            if u < x {
                a = u;
            } else {
                b = u;
            }
            if gu <= gw || w == x {
                (v, gv, w, gw) = (w, gw, u, gu);
            } else if gu <= gv || v == x || v == w {
                (v, gv) = (u, gu);
            }
        }
    }
    (x, -gx)
}

#[cfg(test)]
mod tests {
    /// A smooth peak located to the tolerance in few evaluations.
    #[test]
    fn finds_a_smooth_peak() {
        let count = std::cell::Cell::new(0);
        let f = |t: f64| {
            count.set(count.get() + 1);
            (3.0 * t).sin() * (1.0 + 0.1 * t)
        };
        // f' = 0 where tan 3t = -30 (1 + 0.1 t): 3t = pi - atan(30 (1 + 0.1 t)).
        let mut peak: f64 = 0.5;
        for _ in 0..50 {
            peak = (std::f64::consts::PI - (30.0 * (1.0 + 0.1 * peak)).atan()) / 3.0;
        }
        let (x, fx) = super::maximize(f, 0.2, 0.9, 0.5, f(0.5), 1e-9);
        let evaluations = count.get();
        assert!(evaluations <= 20, "{evaluations} evaluations");
        assert!((x - peak).abs() < 1e-8, "{x} against {peak}");
        assert!((fx - f(peak)).abs() < 1e-14, "{fx} against {}", f(peak));
    }
}
