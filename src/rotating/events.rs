//! Locating the switches of the contact law inside one accepted Radau step,
//! on the step's collocation polynomial `u(t)` (a cubic in `t`).
//!
//! Each contact state watches one or two functions of the state, each
//! positive until its switch:
//! - open: the gap `-gamma` (onset when it turns negative);
//! - pressed: the raw force (end of push, `gamma > 0` there) and `gamma`
//!   (separation);
//! - penetrated: the negated raw force (the push resumes) and `gamma`.
//!
//! **Samples.** The watches are evaluated at `SAMPLES` = 8 equally spaced
//! points of the step (the step's start counts as non-negative: it is
//! either the end of a step found clear or the restart at a switch, on the
//! boundary by construction). The first sample interval where one turns
//! negative brackets the switch, which bisection on `u` locates to an ulp.
//!
//! **Between samples.** A tip that dips into the surface and leaves again
//! between two samples (grazing) leaves both samples positive. For the two
//! geometric watches (gap, `gamma`) the search therefore also looks for
//! interior minima: the watch's time derivative along `u` (the gradient of
//! the gap times `u'` from `dense_derivative`) is evaluated at both ends and
//! the middle of each sample interval, and, when these three fit a
//! parabola whose vertex lies inside, at the vertex too; every change of
//! sign from `-` to `+` between consecutive points is bisected to the
//! minimum, and a negative minimum brackets a switch on its left. If `u`
//! were exactly cubic and the gap linear in it, the derivative would be a
//! quadratic: these points then find every minimum. The gap is smooth, not
//! linear, in `u` (rotation, tip shortening), so a miss needs a derivative
//! that changes sign twice within an eighth of a step in a way its
//! three-point parabola does not show (two extrema closer than about a
//! sixteenth of a step): a normal tip velocity reversing twice that fast
//! is beyond what the error control lets the polynomial represent. What
//! the polynomial itself misses (a dip shallower than the local error) is
//! below the tolerance. The force watches have no such search: a push that
//! ends and resumes within one sample interval is not seen, but the force
//! law clamps at zero, so the motion is still right.

use nalgebra::DVector;

use super::system::{ContactPoint, ContactState, Phase};
use crate::solve::radau::Radau;

pub const SAMPLES: usize = 8;

/// A watched function of the contact state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Watch {
    Gap,
    Force,
    Penetration,
    NegatedForce,
}

impl Watch {
    pub fn of(contact: ContactState) -> &'static [Watch] {
        match contact {
            ContactState::Open => &[Watch::Gap],
            ContactState::Pressed => &[Watch::Force, Watch::Penetration],
            ContactState::Penetrated => &[Watch::NegatedForce, Watch::Penetration],
        }
    }

    pub fn value(self, c: &ContactPoint) -> f64 {
        match self {
            Watch::Gap => -c.penetration,
            Watch::Force => c.raw,
            Watch::Penetration => c.penetration,
            Watch::NegatedForce => -c.raw,
        }
    }

    /// `+1` / `-1`: the watch is `+- gap`; 0: not geometric.
    fn gap_sign(self) -> f64 {
        match self {
            Watch::Gap => 1.0,
            Watch::Penetration => -1.0,
            _ => 0.0,
        }
    }
}

/// The last accepted step `[t0, t1]` of `solver`, with the state `y0` at its start.
pub struct StepCurve<'a> {
    pub phase: &'a Phase,
    pub solver: &'a Radau,
    pub t0: f64,
    pub t1: f64,
    pub y0: &'a DVector<f64>,
}

impl StepCurve<'_> {
    /// `u(t)`: exactly `y0` and the step's end at the ends.
    pub fn y(&self, t: f64) -> DVector<f64> {
        if t <= self.t0 {
            return self.y0.clone();
        }
        if t >= self.t1 {
            return self.solver.y().clone();
        }
        let mut out = DVector::zeros(self.y0.len());
        if self.solver.dense(t, &mut out).is_err() {
            out.copy_from(self.solver.y());
        }
        out
    }

    pub fn point(&self, t: f64) -> ContactPoint {
        let y = self.y(t);
        let (z, zd) = self.phase.coords(t, &y);
        self.phase.contact_point(&z, &zd)
    }

    /// `d/dt gap(u(t))`.
    fn gap_rate(&self, t: f64) -> f64 {
        let Some(s) = &self.phase.model.surface else { return 0.0 };
        let y = self.y(t);
        let mut dy = DVector::zeros(y.len());
        if self.solver.dense_derivative(t, &mut dy).is_err() {
            return 0.0;
        }
        let (z, _) = self.phase.coords(t, &y);
        let zdot = self.phase.coords_rate(t, &dy);
        self.phase.model.beam.contact_generalized_force(&z, &s.plane, 1.0).dot(&zdot)
    }

    /// The first `t` in `(a, b]` past which `watch` is negative, given
    /// `watch(a) >= 0 > watch(b)`: the right end of a bisection bracket.
    fn bisect(&self, watch: Watch, mut a: f64, mut b: f64) -> f64 {
        loop {
            let m = 0.5 * (a + b);
            if !(m > a && m < b) {
                return b;
            }
            if watch.value(&self.point(m)) < 0.0 {
                b = m;
            } else {
                a = m;
            }
        }
    }

    /// The first interior minimum of a geometric watch in `(a, b)` that is
    /// negative, by the sign changes of its derivative (module doc).
    fn negative_minimum(&self, watch: Watch, a: f64, b: f64) -> Option<f64> {
        let sign = watch.gap_sign();
        let rate = |t: f64| sign * self.gap_rate(t);
        let m = 0.5 * (a + b);
        let (da, dm, db) = (rate(a), rate(m), rate(b));
        let mut pts = vec![(a, da), (m, dm), (b, db)];
        // Parabola through the three: d(u) = dm + (db - da)/2 u + (db - 2 dm + da)/2 u^2, u in [-1, 1].
        let curv = 0.5 * (db - 2.0 * dm + da);
        if curv != 0.0 {
            let u = -0.25 * (db - da) / curv;
            let v = m + u * 0.5 * (b - a);
            if u.abs() < 1.0 && v > a && v < b && v != m {
                pts.push((v, rate(v)));
                pts.sort_by(|p, q| p.0.total_cmp(&q.0));
            }
        }
        for w in pts.windows(2) {
            let ((mut lo, dl), (mut hi, dh)) = (w[0], w[1]);
            if !(dl < 0.0 && dh >= 0.0) {
                continue;
            }
            loop {
                let mid = 0.5 * (lo + hi);
                if !(mid > lo && mid < hi) {
                    break;
                }
                if rate(mid) < 0.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            if watch.value(&self.point(hi)) < 0.0 {
                return Some(hi);
            }
        }
        None
    }

    /// The first switch in the step: its time (the first point found past
    /// the zero) and the watch, or `None`.
    pub fn first_switch(&self) -> Option<(f64, Watch)> {
        self.phase.model.surface.as_ref()?;
        let watches = Watch::of(self.phase.contact);
        let h = self.t1 - self.t0;
        let mut a = self.t0;
        for k in 1..=SAMPLES {
            let b = if k == SAMPLES { self.t1 } else { self.t0 + h * k as f64 / SAMPLES as f64 };
            let c = self.point(b);
            let mut best: Option<(f64, Watch)> = None;
            for &w in watches {
                let root = if w.value(&c) < 0.0 {
                    Some(self.bisect(w, a, b))
                } else if w.gap_sign() != 0.0 {
                    self.negative_minimum(w, a, b).map(|tm| self.bisect(w, a, tm))
                } else {
                    None
                };
                if let Some(r) = root {
                    if best.map_or(true, |(t, _)| r < t) {
                        best = Some((r, w));
                    }
                }
            }
            if best.is_some() {
                return best;
            }
            a = b;
        }
        None
    }

    /// The largest force on `[t0, end]` along `u` while pressed: its time
    /// (a golden-section search over the sample intervals on either side of
    /// the best sample, also when that is the first or the last: the peak
    /// may lie inside the first or last interval) and value.
    pub fn peak_force(&self, end: f64) -> Option<(f64, f64)> {
        if self.phase.contact != ContactState::Pressed || self.phase.model.surface.is_none() {
            return None;
        }
        let end = end.min(self.t1);
        let h = end - self.t0;
        if h <= 0.0 || h.is_nan() {
            return None;
        }
        let f = |t: f64| self.point(t).force;
        let ts: Vec<f64> = (0..=SAMPLES).map(|k| if k == SAMPLES { end } else { self.t0 + h * k as f64 / SAMPLES as f64 }).collect();
        let fs: Vec<f64> = ts.iter().map(|&t| f(t)).collect();
        let k = (0..ts.len()).fold(0, |best, i| if fs[i] > fs[best] { i } else { best });
        let (mut lo, mut hi) = (ts[k.saturating_sub(1)], ts[(k + 1).min(SAMPLES)]);
        let r = 0.5 * (5f64.sqrt() - 1.0);
        let (mut x1, mut x2) = (hi - r * (hi - lo), lo + r * (hi - lo));
        let (mut f1, mut f2) = (f(x1), f(x2));
        for _ in 0..60 {
            if !(x1 > lo && x2 < hi && x1 < x2) {
                break;
            }
            if f1 >= f2 {
                (hi, x2, f2) = (x2, x1, f1);
                x1 = hi - r * (hi - lo);
                f1 = f(x1);
            } else {
                (lo, x1, f1) = (x1, x2, f2);
                x2 = lo + r * (hi - lo);
                f2 = f(x2);
            }
        }
        let (t, v) = if f1 >= f2 { (x1, f1) } else { (x2, f2) };
        if v >= fs[k] {
            Some((t, v))
        } else {
            Some((ts[k], fs[k]))
        }
    }
}
