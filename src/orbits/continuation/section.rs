//! An impact passing through the section's phase: the orbit changes
//! smoothly, but its state at `t0` jumps between the two states of the
//! impact instant, the one before the impact (on the stop, approaching)
//! and the one after (on the stop, leaving). Both are the same orbit; the
//! branch is continued from the other one.

use nalgebra::DVector;

use super::super::shooting::start_from;
use super::corrector::Walker;
use crate::kind::Surface;
use super::Point;

/// The section state's distance from the nearest rigid stop and the
/// contact point's speed towards it (positive approaching).
#[derive(Clone, Copy, Debug)]
pub(super) struct OnSection {
    pub(super) gap: f64,
    pub(super) approach: f64,
}

impl Walker {
    /// Where the state at `t0` of the orbit through `point` is relative to
    /// the nearest rigid stop.
    pub(super) fn on_section(&self, point: &Point) -> Option<OnSection> {
        let surfaces = self.surfaces_at(point.param)?;
        let n = point.orbit.state.len() / 2;
        let (q, qd) = (point.orbit.state.rows(0, n), point.orbit.state.rows(n, n));
        surfaces
            .iter()
            .filter(|s| s.rigid && s.shape.len() == n)
            .map(|s| OnSection { gap: s.side * (s.target - s.shape.dot(&q)), approach: s.side * s.shape.dot(&qd) })
            .min_by(|a, b| a.gap.total_cmp(&b.gap))
    }

    /// The stops' surfaces at parameter value `p` (the last few kept).
    fn surfaces_at(&self, p: f64) -> Option<Vec<Surface>> {
        let mut cache = self.surfaces.borrow_mut();
        if let Some((_, s)) = cache.iter().find(|(v, _)| v.to_bits() == p.to_bits()) {
            return Some(s.clone());
        }
        let scene = self.scene_at(p).ok()?;
        let mut run = scene.start(self.t0, &vec![0.0; scene.inputs().len()]).ok()?;
        let surfaces = run.flow()?.surfaces();
        if cache.len() >= 8 {
            cache.remove(0);
        }
        cache.push((p, surfaces.clone()));
        Some(surfaces)
    }

    /// The distance along the branch after `last` (`step` after
    /// `previous`) at which the section state, closing on a rigid stop
    /// linearly, reaches it.
    pub(super) fn section_ahead(&self, previous: &Point, last: &Point, step: f64) -> Option<f64> {
        let (a, b) = (self.on_section(previous)?, self.on_section(last)?);
        (b.gap < a.gap && b.gap >= 0.0).then(|| b.gap * step / (a.gap - b.gap))
    }

    /// The orbit through `last`, whose state at `t0` is about to reach a
    /// rigid stop, continued on the other side of the impact at the
    /// section: its state after the impact (or before it, if `last`'s is
    /// after it) at a parameter a little further along `tangent`, by
    /// Newton in the state from the flow a little past the impact, with
    /// the branch's tangent there.
    pub(super) fn cross_section(&mut self, last: &Point, tangent: &DVector<f64>, periods: usize) -> Result<(Point, DVector<f64>), String> {
        let on = self.on_section(last).ok_or("no rigid stop")?;
        let scene = self.scene_at(last.param)?;
        let period = periods as f64 * self.forcing_period(&scene);
        // Past the impact: it is `gap / approach` away.
        let h = (10.0 * on.gap.max(0.0) / on.approach.abs().max(f64::MIN_POSITIVE)).clamp(1e-7 * period, 1e-3 * period);
        let end = self.t0 + period + if on.approach > 0.0 { h } else { -h };
        let mut run = start_from(&scene, self.t0, &last.orbit.state)?;
        run.advance_to(end).map_err(|e| e.to_string())?;
        let guess = run.flow().ok_or("the scene's kind has no exact flow")?.state();
        let sign = tangent[tangent.len() - 1].signum();
        let (lo, hi) = self.range;
        let mut why = String::from("no orbit found across the impact at the section");
        for fraction in [1e-3, 1e-2, 1e-1] {
            let p = last.param + sign * fraction * self.ds_max / self.weight_p;
            if !(lo..=hi).contains(&p) {
                break;
            }
            match self.at_parameter(p, periods, &guess) {
                Ok(beyond) if beyond.profile.impacts == last.profile.impacts && beyond.profile.sticks == last.profile.sticks => {
                    let across = self.on_section(&beyond).is_some_and(|b| b.approach * on.approach < 0.0);
                    if !across {
                        why = format!("Newton at {} = {p} returned to the state before the impact", self.name());
                        continue;
                    }
                    let mut direction = DVector::zeros(tangent.len());
                    direction[tangent.len() - 1] = sign;
                    let next = self.tangent(&beyond, periods, &direction)?;
                    return Ok((beyond, next));
                }
                Ok(_) => why = format!("Newton at {} = {p} found an orbit with other impacts", self.name()),
                Err(e) => why = e,
            }
        }
        Err(why)
    }
}
