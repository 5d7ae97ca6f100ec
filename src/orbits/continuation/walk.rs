//! Following a branch: predictor, corrector, step control, and where a
//! branch ends.

use nalgebra::DVector;

use super::corrector::{interpolate, Walker};
use super::grazing::{grazing_ahead, Crossing};
use super::{on_points, Observer, Point, Special, SpecialKind};

impl Walker {
    /// Follows a branch from `first` along `tangent` until it leaves the
    /// range or cannot go on; special points go to `special`, period
    /// doublings to `doublings` as well. Returns the points in walking order.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn walk(
        &mut self,
        branch: usize,
        periods: usize,
        first: Point,
        tangent: DVector<f64>,
        switched: bool,
        others: &[&[Point]],
        special: &mut Vec<Special>,
        doublings: &mut Vec<Point>,
        observer: &mut dyn Observer,
    ) -> Result<Vec<Point>, String> {
        // The scale `tangent` is given in, restored at the end (the other
        // direction of the branch starts in it too).
        let weight_x = self.weight_x;
        let mut points = vec![first];
        let mut tangent = tangent;
        let mut ds = self.ds_max;
        let ds_min = self.ds_max * 1e-6;
        let mut tried_crossing = false;
        let mut small_steps = 0;
        let (lo, hi) = self.range;
        let end = |why: String, at: &Point, special: &mut Vec<Special>| {
            special.push(Special { kind: SpecialKind::End, branch, point: at.clone(), note: why });
        };
        loop {
            if points.len() >= self.max_points {
                end(format!("{} points: the limit", points.len()), points.last().expect("a point"), special);
                break;
            }
            let last = points.last().expect("a point").clone();
            let u_pred = self.scaled(&last.orbit.state, last.param) + &tangent * ds;
            let attempt = self.correct(&u_pred, &tangent, periods, Some(&last)).and_then(|(point, e, iterations)| {
                let next_tangent = self.tangent_from(&e, &tangent)?;
                Ok((point, next_tangent, iterations))
            });
            // Newton cannot cross a grazing well (the map's square root):
            // cross it directly when a step fails with the grazing within
            // reach, or when the steps have collapsed.
            let grazing_near = !tried_crossing
                && points.len() >= 2
                && grazing_ahead(&points[points.len() - 2], &last, self.distance(&points[points.len() - 2], &last)).is_some_and(|s| s < 2.0 * ds);
            // An impact about to pass through the section's phase: the
            // state at t0 jumps to the other side of it.
            let section_near = !tried_crossing
                && points.len() >= 2
                && self.section_ahead(&points[points.len() - 2], &last, self.distance(&points[points.len() - 2], &last)).is_some_and(|s| s < 2.0 * ds);
            let stalled = (ds < self.ds_max * 1e-2 || grazing_near || section_near) && !tried_crossing;
            // A step that loses a rigid impact whose speed was vanishing
            // has crossed a grazing Newton cannot locate from there (where
            // the branch may turn back): the crossing below locates it. (A
            // compliant stop's onset vanishes with the branch going on
            // through its grazing: the step stands.)
            let slow_impact_lost = |p: &Point| {
                let previous = points.len().checked_sub(2).map(|i| &points[i]);
                p.profile.rigid_impacts < last.profile.rigid_impacts
                    && previous.is_some_and(|q| {
                        q.profile.impacts == last.profile.impacts
                            && matches!((q.profile.slowest_impact, last.profile.slowest_impact), (Some(a), Some(b)) if b < a)
                    })
            };
            let (point, next_tangent, iterations) = match attempt {
                // A corrector that moved farther from the predictor than
                // the step itself may have jumped to another branch.
                Ok(found)
                    if found.1.dot(&tangent) > 0.9 && (self.scaled(&found.0.orbit.state, found.0.param) - &u_pred).norm() <= ds && !slow_impact_lost(&found.0)
                        || ds <= ds_min =>
                {
                    found
                }
                Ok(_) | Err(_) if ds > ds_min && !stalled => {
                    ds *= 0.5;
                    continue;
                }
                failed => {
                    let e = failed.err().unwrap_or_else(|| "the branch turns too fast".into());
                    tried_crossing = true;
                    if section_near || self.on_section(&last).is_some_and(|o| o.gap <= 1e-6 * last.orbit.state.amax()) {
                        if let Ok((beyond, next_tangent)) = self.cross_section(&last, &tangent, periods) {
                            observer.point(branch, &beyond);
                            points.push(beyond);
                            tangent = next_tangent;
                            ds = self.ds_max * 0.1;
                            tried_crossing = false;
                            continue;
                        }
                    }
                    // Newton fails at a grazing (the map's square root):
                    // locate it, then restart on the far side.
                    let previous = points.len().checked_sub(2).map(|i| points[i].clone());
                    match self.cross_grazing(previous.as_ref(), &last, &tangent, periods) {
                        Ok(crossing) => {
                            let local = self.report_crossing(branch, &last, &crossing, special);
                            let Crossing { grazing, beyond, tangent: next_tangent, .. } = crossing;
                            points.push(grazing);
                            if !local {
                                self.restarts.push(beyond);
                                end("a grazing without a nearby orbit beyond it".into(), points.last().expect("a point"), special);
                                break;
                            }
                            points.push(beyond);
                            tangent = next_tangent;
                            ds = self.ds_max * 0.1;
                            tried_crossing = false;
                            continue;
                        }
                        Err(_) if ds > ds_min => {
                            ds *= 0.5;
                            continue;
                        }
                        Err(why) => {
                            let why = format!("the branch cannot be followed past {} = {}: {e} ({why})", self.name(), last.param);
                            let (at, why) = self.end_at_grazing(&points, periods, why);
                            if let Some(at) = at {
                                observer.point(branch, &at);
                                special.push(ending_grazing(branch, &at));
                                points.push(at);
                            }
                            end(why, points.last().expect("a point"), special);
                            break;
                        }
                    }
                }
            };
            if !(lo..=hi).contains(&point.param) {
                // The end of the range: the orbit at the bound itself.
                let bound = if point.param > hi { hi } else { lo };
                if last.param == bound {
                    end(format!("the end of the range, {} = {bound}", self.name()), &last, special);
                    break;
                }
                let guess = interpolate(&last, &point, bound);
                match self.at_parameter(bound, periods, &guess) {
                    Ok(at) => {
                        self.detect(branch, periods, (&last, &tangent), (&at, &tangent), switched && points.len() == 1, special, doublings);
                        points.push(at.clone());
                        end(format!("the end of the range, {} = {bound}", self.name()), &at, special);
                    }
                    Err(e) => end(format!("the end of the range, {} = {bound}: {e}", self.name()), &last, special),
                }
                break;
            }
            if periods > 1 && self.has_period(&point, periods / 2) {
                end(format!("the orbit has period {} there: the branch returns to the one it doubled", periods / 2), &last, special);
                break;
            }
            self.detect(branch, periods, (&last, &tangent), (&point, &next_tangent), switched && points.len() == 1, special, doublings);
            // A closed branch (an isola, or a doubled branch that returns
            // to where it was born) ends where it meets itself again.
            let closed = points.len() > 10
                && points[..points.len() - 10].iter().any(|q| q.profile.impacts == point.profile.impacts && self.distance(q, &point) < 0.5 * ds);
            // A branch that runs onto one found before ends where it joins.
            let joins = points.len() > 2 && others.iter().any(|o| on_points(self, o, &point));
            observer.point(branch, &point);
            points.push(point);
            if closed {
                end("the branch closes on itself".into(), points.last().expect("a point"), special);
                break;
            }
            if joins {
                end("the branch joins one found before".into(), points.last().expect("a point"), special);
                break;
            }
            // A branch whose steps stay tiny (its orbits' sensitivity grows
            // without bound) ends there.
            small_steps = if ds < 1e-3 * self.ds_max { small_steps + 1 } else { 0 };
            if small_steps > 20 {
                let at = points.last().expect("a point");
                let largest = at.orbit.multipliers.iter().map(|z| z.norm()).fold(0.0, f64::max);
                let why = format!("the steps stall below 1e-3 of the longest (largest multiplier {largest:.3e})");
                let (at, why) = self.end_at_grazing(&points, periods, why);
                if let Some(at) = at {
                    observer.point(branch, &at);
                    special.push(ending_grazing(branch, &at));
                    points.push(at);
                }
                end(why, points.last().expect("a point"), special);
                break;
            }
            tangent = self.rescaled(next_tangent, points.last().expect("a point"));
            tried_crossing &= ds < 0.1 * self.ds_max;
            ds = match iterations {
                0..=4 => (ds * 1.5).min(self.ds_max),
                5..=7 => ds,
                _ => ds * 0.7,
            };
        }
        self.weight_x = weight_x;
        Ok(points)
    }

    /// Where a branch ends (`why`) with its closest approach to a stop
    /// closing (between its last two points, the same impacts): the end
    /// is that grazing, not wherever Newton or the steps gave out. It is
    /// located on the branch's side ([`Walker::refine_by_gap`]), or, where
    /// Newton finds no orbits of the branch close enough to it (a slow
    /// impact of the branch vanishes there too: the branch meets an orbit
    /// without that impact, such as the one it doubled), on that orbit's
    /// side, where the gap closes as well. The point to end at (if not
    /// the last) and why.
    pub(super) fn end_at_grazing(&mut self, points: &[Point], periods: usize, why: String) -> (Option<Point>, String) {
        let last = points.last().expect("a point").clone();
        let closest = |p: &Point| p.profile.closest.map(|c| c.gap);
        let gap = |p: &Point| closest(p).filter(|_| p.profile.impacts == last.profile.impacts);
        let Some(g1) = gap(&last) else {
            return (None, why);
        };
        // The trend from the latest point at twice the gap (steps that
        // stalled differ by rounding), else from the one before.
        let earlier = points[..points.len() - 1].iter().rev().take_while(|p| gap(p).is_some());
        let Some(previous) = earlier.clone().find(|p| gap(p).is_some_and(|g| g >= 2.0 * g1)).or(earlier.clone().next()).cloned() else {
            return (None, why);
        };
        let Some(g0) = gap(&previous) else {
            return (None, why);
        };
        if !(g1 < g0 && g1 >= 0.0) {
            return (None, why);
        }
        // Closed: to 1e-3 of the gap's trend, or to rounding (1e-10 of the peak).
        let closed = |g: f64, scale: f64| g <= (1e-3 * scale).max(1e-10 * last.profile.peak.abs());
        let at = self.refine_by_gap(&previous, &last, periods).filter(|at| at.param != last.param && gap(at).is_some_and(|g| closed(g, g0)));
        let at = at.or_else(|| {
            // Where the gap extrapolates to zero, the orbit on the other side.
            let zero = last.param - g1 * (last.param - previous.param) / (g1 - g0);
            let s = (zero - last.param) / (last.param - previous.param);
            let guess = &last.orbit.state + (&last.orbit.state - &previous.orbit.state) * s;
            // There, or a little past it (the trend curves).
            let other = [0.0, 0.01, 0.1, 1.0].iter().find_map(|t| {
                let p = zero + t * (zero - last.param);
                self.at_parameter(p, periods, &guess).ok().filter(|o| o.profile.impacts < last.profile.impacts && closest(o).is_some())
            })?;
            let far = self.at_parameter(other.param - (last.param - other.param), periods, &other.orbit.state).ok()?;
            let scale = closest(&other)?.max(closest(&far)?);
            self.refine_by_gap(&far, &other, periods).filter(|at| closest(at).is_some_and(|g| closed(g, 1e-3 * scale)))
        });
        match at {
            Some(at) => {
                let note = format!(
                    "{why}; it ends at the grazing there (impacts per orbit {} -> {}, closest smooth approach {:.3e})",
                    last.profile.impacts,
                    at.profile.impacts,
                    closest(&at).unwrap_or(f64::NAN),
                );
                (Some(at), note)
            }
            None => (None, why),
        }
    }

    /// The state's scale follows the branch's largest orbit so far, as a
    /// diagram's axis does: where `at`'s orbit has grown past twice the
    /// scale, the scale becomes its size and `tangent` is carried over to
    /// it. (With the first orbit's scale, a branch whose orbits grow
    /// tenfold takes steps ten times shorter in the parameter; a scale
    /// that shrank with the orbits would resolve the small ones' relative
    /// changes, which a diagram does not show, at the cost of many points.)
    pub(super) fn rescaled(&mut self, tangent: DVector<f64>, at: &Point) -> DVector<f64> {
        let size = at.size();
        let ratio = size * self.weight_x;
        if !(size > 0.0 && size.is_finite()) || ratio <= 2.0 {
            return tangent;
        }
        let n = at.orbit.state.len();
        self.weight_x = 1.0 / size;
        let mut t = tangent;
        let scaled = t.rows(0, n) / ratio;
        t.rows_mut(0, n).copy_from(&scaled);
        t.normalize()
    }
}

/// The grazing a branch ends at ([`Walker::end_at_grazing`]): a GR of its
/// own (the EP after it says why the branch stops there).
fn ending_grazing(branch: usize, at: &Point) -> Special {
    let gap = at.profile.closest.map_or(f64::NAN, |c| c.gap) + 0.0;
    let note = format!("closest smooth approach {gap:.3e}; no orbit beyond it found: the branch ends here");
    Special { kind: SpecialKind::Grazing, branch, point: at.clone(), note }
}
