//! A sign change of a scalar function narrowed by regula falsi, Illinois
//! variant: the next point is the secant's zero between the ends, and an
//! end kept twice in a row has its value halved, so that the bracket
//! closes from both sides. The caller evaluates (its points may carry
//! more than a value, as an orbit corrected onto a branch) and decides
//! when the bracket is narrow enough.

/// Which end of the bracket a point replaced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum End {
    Lo,
    Hi,
}

/// The ends of a bracket, in either order, and the function's values
/// there, of opposite signs.
#[derive(Clone, Copy, Debug)]
pub struct RegulaFalsi {
    pub lo: f64,
    pub hi: f64,
    pub f_lo: f64,
    pub f_hi: f64,
    /// The end the last value replaced (none after a point without one).
    last: Option<End>,
}

impl RegulaFalsi {
    pub fn new((lo, f_lo): (f64, f64), (hi, f_hi): (f64, f64)) -> Self {
        RegulaFalsi { lo, hi, f_lo, f_hi, last: None }
    }

    /// The point to evaluate next: the secant's zero (`bisect`: the
    /// midpoint), the midpoint where that is not strictly between the ends.
    pub fn next(&self, bisect: bool) -> f64 {
        let (lo, hi) = (self.lo, self.hi);
        let x = if bisect { 0.5 * (lo + hi) } else { hi - self.f_hi * (hi - lo) / (self.f_hi - self.f_lo) };
        if x > lo.min(hi) && x < lo.max(hi) && x.is_finite() {
            x
        } else {
            0.5 * (lo + hi)
        }
    }

    /// The value `f` at `x`: `x` replaces the end where the function has
    /// `f`'s sign, and which one is returned; `None` when `f` is zero (the
    /// bracket then unchanged).
    pub fn take(&mut self, x: f64, f: f64) -> Option<End> {
        if f == 0.0 {
            return None;
        }
        let end = if (f < 0.0) == (self.f_lo < 0.0) {
            (self.lo, self.f_lo) = (x, f);
            if self.last == Some(End::Lo) {
                self.f_hi *= 0.5;
            }
            End::Lo
        } else {
            (self.hi, self.f_hi) = (x, f);
            if self.last == Some(End::Hi) {
                self.f_lo *= 0.5;
            }
            End::Hi
        };
        self.last = Some(end);
        Some(end)
    }

    /// `x` becomes the `hi` end where the function has no value: `f_hi`
    /// stays, and no end counts as kept.
    pub fn shrink_hi(&mut self, x: f64) {
        self.hi = x;
        self.last = None;
    }
}
