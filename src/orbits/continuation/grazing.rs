//! Crossing a grazing: the stroboscopic map has a square-root singularity
//! on the impacting side (NOR91), where Newton stalls. The grazing orbit
//! is located on the side it is smooth on, and the orbit with the changed
//! impact sequence sought just beyond it.

use nalgebra::DVector;

use super::super::shooting::start_from;
use super::corrector::Walker;
use super::special::stability_change;
use super::{Point, Special, SpecialKind};

/// A grazing crossed: the grazing orbit, the first orbit beyond it and
/// the tangent there, and, when the grazing was approached from the
/// impacting side, where the slow impact's speed squared (linear in the
/// parameter) extrapolates to zero.
pub(super) struct Crossing {
    pub(super) grazing: Point,
    pub(super) beyond: Point,
    pub(super) tangent: DVector<f64>,
    pub(super) estimate: Option<f64>,
}

impl Walker {
    /// Reports a crossing from `last` through `grazing` to `beyond` (GR,
    /// and ST when the sticks change too); whether `beyond` continues the
    /// branch.
    pub(super) fn report_crossing(&self, branch: usize, last: &Point, crossing: &Crossing, special: &mut Vec<Special>) -> bool {
        let (grazing, beyond) = (&crossing.grazing, &crossing.beyond);
        let local = continues(grazing, beyond);
        let how = if local {
            format!("continued beyond it from {} = {}", self.name(), beyond.param)
        } else {
            format!("no orbit near it beyond; a far one at {} = {} starts another branch", self.name(), beyond.param)
        };
        let note = format!(
            "impacts per orbit {} -> {}{}; {}{}; {how}",
            last.profile.impacts,
            beyond.profile.impacts,
            stability_change(last, beyond),
            grazing_measure(grazing),
            crossing.estimate.map_or(String::new(), |p| format!(" (its speed squared extrapolates to zero at {} = {p})", self.name())),
        );
        special.push(Special { kind: SpecialKind::Grazing, branch, point: grazing.clone(), note });
        if grazing.profile.sticks != beyond.profile.sticks {
            let note = format!("sticks per orbit {} -> {} at the grazing", grazing.profile.sticks, beyond.profile.sticks);
            special.push(Special { kind: SpecialKind::Sticking, branch, point: grazing.clone(), note });
        }
        local
    }

    /// Where Newton stalls because the closest smooth approach to a stop
    /// closes, or the slowest impact's speed vanishes (`last`, after
    /// `previous`, walking along `tangent`): the grazing orbit, located by
    /// the secant method on that gap or speed from the side it is
    /// measured on, and the orbit with the changed impact sequence nearest
    /// to it just beyond (by Newton in the state at a parameter a little
    /// past it on either side, from the grazing orbit or from a simulated
    /// transient), with its tangent.
    pub(super) fn cross_grazing(
        &mut self,
        previous: Option<&Point>,
        last: &Point,
        tangent: &DVector<f64>,
        periods: usize,
    ) -> Result<Crossing, String> {
        let previous = previous.ok_or("no trend to extrapolate")?;
        // From the smooth side the closest approach's gap closes, linearly
        // in the parameter; from the impacting side the slowest impact's
        // speed does, as the square root of the parameter's distance, but
        // linearly in the arclength (the branch's tangent turns to the
        // state there).
        let impacts = last.profile.impacts;
        let gap = move |p: &Point| p.profile.closest.map(|c| c.gap).filter(|_| p.profile.impacts == impacts);
        let speed = move |p: &Point| p.profile.slowest_impact.filter(|_| p.profile.impacts == impacts);
        let closing = |f: &dyn Fn(&Point) -> Option<f64>| matches!((f(previous), f(last)), (Some(a), Some(b)) if b < a && b >= 0.0);
        let by_speed = !closing(&gap) && closing(&speed);
        let psi: &dyn Fn(&Point) -> Option<f64> = if closing(&gap) {
            &gap
        } else if by_speed {
            &speed
        } else {
            return Err("neither a smooth approach to a stop nor an impact's speed is closing".into());
        };
        let u_last = self.scaled(&last.orbit.state, last.param);
        let (mut s0, mut f0) = (-(self.scaled(&previous.orbit.state, previous.param) - &u_last).norm(), psi(previous).expect("checked"));
        let (mut s1, mut f1) = (0.0, psi(last).expect("checked"));
        let mut grazing = last.clone();
        let mut before = previous.clone();
        let scale = psi(previous).expect("checked");
        // Past a grazing approached from the smooth side the new impact's
        // speed squared grows linearly too: -v^2 / 2 gap'' continues the
        // gap through zero.
        let curvature = last.profile.closest.map_or(1.0, |c| c.curvature.max(f64::MIN_POSITIVE));
        let past = move |p: &Point| p.profile.slowest_impact.filter(|_| p.profile.impacts == impacts + 1).map(|v| -v * v / (2.0 * curvature));
        // The secant method from this side; a trial past the grazing bounds
        // the next ones (regula falsi, Illinois, where the gap's
        // continuation is known there; bisection otherwise).
        let (mut s_beyond, mut f_beyond) = (f64::INFINITY, None::<f64>);
        let mut side = 0;
        for _ in 0..40 {
            if f1.abs() <= 1e-10 * scale || (s1 - s0).abs() <= 1e-15 || (s_beyond - s1).abs() <= 1e-9 * self.ds_max {
                break;
            }
            let mut s = match f_beyond {
                Some(fb) => s1 - f1 * (s1 - s_beyond) / (f1 - fb),
                None => s1 - f1 * (s1 - s0) / (f1 - f0),
            };
            if !(s > s1 && s < s_beyond) {
                s = if s_beyond.is_finite() { 0.5 * (s1 + s_beyond) } else { s1 + 2.0 * (s1 - s0).abs() };
            }
            match self.correct(&(&u_last + tangent * s), tangent, periods, Some(last)) {
                Ok((p, _, _)) if psi(&p).is_some_and(|f| f >= 0.0) => {
                    let f = psi(&p).expect("checked");
                    (s0, f0, s1, f1) = (s1, f1, s, f);
                    before = std::mem::replace(&mut grazing, p);
                    if side == 1 {
                        f_beyond = f_beyond.map(|fb| 0.5 * fb);
                    }
                    side = 1;
                }
                Ok((p, _, _)) if !by_speed && past(&p).is_some() => {
                    (s_beyond, f_beyond) = (s, past(&p));
                    if side == -1 {
                        f1 *= 0.5;
                    }
                    side = -1;
                }
                _ => (s_beyond, f_beyond, side) = (s, None, 0),
            }
        }
        let mut estimate = None;
        if by_speed && f1 > 1e-10 * scale {
            // The branch turns to the state as the impact's speed vanishes,
            // and the hyperplanes above stop meeting it: on to the zero of
            // the speed's square, linear in the parameter, at fixed values
            // of the parameter.
            let (refined, extrapolated) = self.refine_by_speed(&before, grazing, periods);
            grazing = refined;
            estimate = extrapolated;
        }
        // Beyond: the orbit with the changed impact sequence nearest to the
        // grazing one, on either side of it (a grazing can also give birth
        // to orbits on the side it came from, which then fold), each side
        // at the nearest parameter value where Newton finds one.
        let sign = tangent[tangent.len() - 1].signum();
        let (lo, hi) = self.range;
        let mut why = String::from("no orbit found beyond it");
        let mut best: Option<(f64, Point, f64)> = None;
        for side in [sign, -sign] {
            'side: for fraction in [0.01, 0.1, 0.5] {
                let p = grazing.param + side * fraction * self.ds_max / self.weight_p;
                if !(lo..=hi).contains(&p) {
                    why = format!("the grazing at {} = {} is at the end of the range", self.name(), grazing.param);
                    break;
                }
                let scene = self.scene_at(p)?;
                let period = periods as f64 * self.forcing_period(&scene);
                let simulated = (|| -> Result<DVector<f64>, String> {
                    let mut run = start_from(&scene, self.t0, &grazing.orbit.state)?;
                    super::super::shooting::advance_by_periods(run.as_mut(), self.t0 + 100.0 * period, period)?;
                    Ok(run.flow().expect("a kind with an exact flow").state())
                })();
                for guess in [Ok(grazing.orbit.state.clone()), simulated] {
                    let Ok(guess) = guess else { continue };
                    match self.at_parameter(p, periods, &guess) {
                        Ok(beyond) if periods > 1 && self.has_period(&beyond, periods / 2) => {
                            why = format!("beyond it at {} = {p}, only an orbit of period {}", self.name(), periods / 2)
                        }
                        Ok(beyond) if beyond.profile.impacts != grazing.profile.impacts => {
                            let distance = (self.scaled(&beyond.orbit.state, beyond.param) - self.scaled(&grazing.orbit.state, grazing.param)).norm();
                            if best.as_ref().map_or(true, |b| distance < b.0) {
                                best = Some((distance, beyond, side));
                            }
                            break 'side;
                        }
                        Ok(_) => why = format!("Newton at {} = {p} returned to the orbit without the new impact", self.name()),
                        Err(e) => why = e,
                    }
                }
            }
        }
        let (_, beyond, mut side) = best.ok_or(why)?;
        // Approached from the impacting side, the grazing is located only
        // as well as Newton finds orbits with a vanishing impact (the
        // map's square root); where the orbit beyond has lost that impact
        // its closest approach closes linearly in the parameter: the
        // grazing is located on that side, and the orbit without the
        // impact goes on away from it, whichever side of the impacting
        // branch's end that is (the two may lie on one side: the branch
        // then turns back at the grazing).
        if by_speed && beyond.profile.impacts < grazing.profile.impacts {
            if let Some((located, away)) = self.locate_from_smooth_side(&grazing, &beyond, periods) {
                grazing = located;
                side = away;
            }
        }
        let mut direction = DVector::zeros(tangent.len());
        direction[tangent.len() - 1] = side;
        let next_tangent = self.tangent(&beyond, periods, &direction)?;
        Ok(Crossing { grazing, beyond, tangent: next_tangent, estimate })
    }

    /// The grazing approached from the impacting side (`a`, then `b`, on
    /// the branch, the same impacts): the secant method on the slowest
    /// impact's speed squared over the parameter, each orbit by Newton in
    /// the state alone; a value past the grazing bounds the next trials.
    /// Returns the last orbit found and where the secant line of its last
    /// two points reaches zero.
    pub(super) fn refine_by_speed(&mut self, a: &Point, b: Point, periods: usize) -> (Point, Option<f64>) {
        let impacts = b.profile.impacts;
        let square = |p: &Point| p.profile.slowest_impact.filter(|_| p.profile.impacts == impacts).map(|v| v * v);
        let (Some(fa), Some(fb)) = (square(a), square(&b)) else {
            return (b, None);
        };
        let (mut p0, mut f0, mut p1, mut f1) = (a.param, fa, b.param, fb);
        let mut x0 = a.orbit.state.clone();
        let direction = (p1 - p0).signum();
        let mut beyond = f64::NAN;
        let mut best = b;
        let scale = fa.max(fb);
        for _ in 0..40 {
            if f1 <= 1e-14 * scale || (beyond - p1).abs() <= 1e-13 * p1.abs().max(self.range.1 - self.range.0) || p1 == p0 {
                break;
            }
            let mut p = p1 - f1 * (p1 - p0) / (f1 - f0);
            let inside = |p: f64| (p - p1) * direction > 0.0 && (beyond.is_nan() || (beyond - p) * direction > 0.0);
            if !inside(p) {
                p = if beyond.is_nan() { p1 + 2.0 * (p1 - p0) } else { 0.5 * (p1 + beyond) };
            }
            // The state is smooth in the speed, not in the parameter: the
            // guess goes along the speed the secant line predicts.
            let (v0, v1) = (f0.sqrt(), f1.sqrt());
            let v = (f1 + (p - p1) * (f1 - f0) / (p1 - p0)).max(0.0).sqrt();
            let guess = if v1 != v0 { &best.orbit.state + (&best.orbit.state - &x0) * ((v - v1) / (v1 - v0)) } else { best.orbit.state.clone() };
            match self.at_parameter(p, periods, &guess) {
                Ok(point) if square(&point).is_some() => {
                    (p0, f0, p1, f1) = (p1, f1, p, square(&point).expect("checked"));
                    x0 = std::mem::replace(&mut best, point).orbit.state;
                }
                _ => beyond = p,
            }
        }
        let estimate = (f1 != f0).then(|| p1 - f1 * (p1 - p0) / (f1 - f0));
        (best, estimate)
    }
}

impl Walker {
    /// The grazing of the smooth orbit `near` (found beside the end
    /// `grazing` of an impacting branch): a second smooth orbit as far
    /// again on the side where the closest approach opens, then the gap's
    /// zero by [`Self::refine_by_gap`]. Returns it and the side (+-1 in
    /// the parameter) on which the smooth orbits lie.
    fn locate_from_smooth_side(&mut self, grazing: &Point, near: &Point, periods: usize) -> Option<(Point, f64)> {
        let impacts = near.profile.impacts;
        let gap = |p: &Point| p.profile.closest.filter(|_| p.profile.impacts == impacts).map(|c| c.gap).filter(|g| *g >= 0.0);
        let g_near = gap(near)?;
        let step = (near.param - grazing.param).abs();
        let outward = (near.param - grazing.param).signum();
        for away in [outward, -outward] {
            let p = near.param + away * step;
            if !(self.range.0..=self.range.1).contains(&p) {
                continue;
            }
            let Ok(far) = self.at_parameter(p, periods, &near.orbit.state) else { continue };
            if gap(&far).is_some_and(|g| g > g_near) {
                return self.refine_by_gap(&far, near, periods).map(|located| (located, away));
            }
        }
        None
    }

    /// The grazing orbit where the closest approach to a stop of the
    /// orbits through `far` and then `near` (the same impacts) closes: the
    /// secant method on that gap, linear in the parameter, each orbit by
    /// Newton in the state at a fixed parameter; a value where Newton
    /// finds no orbit with that gap bounds the next trials. `None` if
    /// either has no closest approach.
    pub(super) fn refine_by_gap(&mut self, far: &Point, near: &Point, periods: usize) -> Option<Point> {
        let impacts = near.profile.impacts;
        let gap = |p: &Point| p.profile.closest.filter(|_| p.profile.impacts == impacts).map(|c| c.gap).filter(|g| *g >= 0.0);
        let (g0, g1) = (gap(far)?, gap(near)?);
        let beyond = near;
        let (mut p0, mut f0, mut x0) = (far.param, g0, far.orbit.state.clone());
        let (mut p1, mut f1) = (beyond.param, g1);
        let mut best = beyond.clone();
        let mut closest = (beyond.clone(), g1);
        let scale = g0.max(g1);
        let width = p1.abs().max(self.range.1 - self.range.0);
        let mut bound = f64::NAN;
        for _ in 0..40 {
            // The gap closed, or the parameter resolved (the gap's rounding
            // is about 1e-16 of the displacement).
            if f1 <= 1e-12 * scale || (p1 - p0).abs() <= 1e-13 * width || (bound - p1).abs() <= 1e-13 * width {
                break;
            }
            let mut p = if f1 != f0 { p1 - f1 * (p1 - p0) / (f1 - f0) } else { f64::NAN };
            let direction = (p1 - p0).signum();
            let inside = |p: f64| (p - p1) * direction > 0.0 && (bound.is_nan() || (bound - p) * direction > 0.0);
            if !inside(p) {
                p = if bound.is_nan() { p1 + (p1 - p0) } else { 0.5 * (p1 + bound) };
            }
            let guess = &best.orbit.state + (&best.orbit.state - &x0) * ((p - p1) / (p1 - p0));
            match self.at_parameter(p, periods, &guess) {
                Ok(point) if gap(&point).is_some() => {
                    (p0, f0, p1, f1) = (p1, f1, p, gap(&point).expect("checked"));
                    if f1 < closest.1 {
                        closest = (point.clone(), f1);
                    }
                    x0 = std::mem::replace(&mut best, point).orbit.state;
                }
                _ => bound = p,
            }
        }
        // The gap is resolved to rounding: the smallest found.
        Some(closest.0)
    }
}

/// Whether `beyond` continues the branch through `grazing` (rather than
/// being another orbit Newton found there): a new impact is slow (below a
/// tenth of the orbit's other impacts' speeds), a lost one leaves a close
/// approach (below a tenth of the peak's size).
pub(super) fn continues(grazing: &Point, beyond: &Point) -> bool {
    if beyond.profile.impacts > grazing.profile.impacts {
        let scale = grazing.profile.slowest_impact.unwrap_or(f64::INFINITY).min(beyond.orbit.state.amax());
        beyond.profile.slowest_impact.is_some_and(|v| v < 0.1 * scale)
    } else {
        beyond.profile.closest.is_some_and(|c| c.gap < 0.1 * beyond.profile.peak.abs())
    }
}

/// How close to grazing a located orbit is: its closest smooth approach
/// to a stop and its slowest impact.
pub(super) fn grazing_measure(p: &Point) -> String {
    let gap = p.profile.closest.map_or("none".to_string(), |c| format!("{:.3e}", c.gap));
    let speed = p.profile.slowest_impact.map_or("none".to_string(), |v| format!("{v:.3e}"));
    format!("closest smooth approach {gap}, slowest impact {speed}")
}

/// The distance along the branch after `last` (`step` after `previous`)
/// at which the closest smooth approach or the slowest impact, closing
/// linearly, reaches zero.
pub(super) fn grazing_ahead(previous: &Point, last: &Point, step: f64) -> Option<f64> {
    if previous.profile.impacts != last.profile.impacts {
        return None;
    }
    let ahead = |a: Option<f64>, b: Option<f64>| match (a, b) {
        (Some(a), Some(b)) if b < a && b >= 0.0 => Some(b * step / (a - b)),
        _ => None,
    };
    let gap = ahead(previous.profile.closest.map(|c| c.gap), last.profile.closest.map(|c| c.gap));
    let speed = ahead(previous.profile.slowest_impact, last.profile.slowest_impact);
    match (gap, speed) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}
