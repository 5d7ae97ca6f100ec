//! What an orbit does over one period: its peak and size, its impacts and
//! sticks, and its closest smooth approach to a stop (the grazing test:
//! a new impact appears where that approach reaches zero).

use nalgebra::DVector;

use super::shooting::start_from;
use crate::component::Component;
use crate::kind::{Clearance, EventClass, Run};
use crate::solve::regula_falsi::RegulaFalsi;

/// An orbit over one period.
#[derive(Clone, Debug, PartialEq)]
pub struct Profile {
    /// The largest displacement of the first stop's contact point (at the
    /// samples, the events and the smooth maxima between samples and
    /// between events: a compliant contact's deepest point).
    pub peak: f64,
    /// The root mean square over the period of the state's 2-norm.
    pub norm: f64,
    /// Rigid impacts and compliant contact onsets.
    pub impacts: usize,
    /// The rigid impacts among them (a compliant onset comes and goes
    /// with the branch passing smoothly through its grazing; a rigid
    /// impact's grazing is a crossing of its own).
    pub rigid_impacts: usize,
    /// Sticking onsets on rigid stops.
    pub sticks: usize,
    /// The smallest approach speed of those impacts.
    pub slowest_impact: Option<f64>,
    /// The smallest local minimum of any stop's gap reached in free flight
    /// (without an event): where it is zero, the orbit grazes.
    pub closest: Option<Approach>,
    /// The first stop's displacement at the section's times (`t0 + k T`,
    /// one per forcing period): the Poincare samples of the orbit.
    pub section: Vec<f64>,
}

/// A smooth local minimum of a stop's gap.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Approach {
    pub stop: usize,
    pub time: f64,
    pub gap: f64,
    /// The gap's second time derivative there (positive).
    pub curvature: f64,
}

/// The clearances of a run now (it has an exact flow).
fn clearances(run: &mut Box<dyn Run>) -> Vec<Clearance> {
    run.flow().map(|f| f.clearances()).unwrap_or_default()
}

fn state(run: &mut Box<dyn Run>) -> DVector<f64> {
    run.flow().map(|f| f.state()).unwrap_or_else(|| DVector::zeros(0))
}

/// The profile of the orbit through `x` at `t0` over `period` (`periods`
/// forcing periods), sampled at no fewer than 64 points and 8 per
/// shortest period of the structure (at most 8192), the section's times
/// among them; each smooth minimum of a gap between two samples is then
/// found where the gap's rate is zero.
pub fn profile(scene: &Component, t0: f64, period: f64, periods: usize, x: &DVector<f64>) -> Result<Profile, String> {
    let mut run = start_from(scene, t0, x)?;
    if run.flow().is_none() {
        return Err("the scene's kind has no exact flow".into());
    }
    run.set_event_recording(true);
    run.drain_events();
    let periods = periods.max(1);
    let per_period = ((period / periods as f64 / (run.shortest_period() / 8.0)).ceil() as usize).clamp(64usize.div_ceil(periods), 8192 / periods);
    let samples = per_period * periods;
    let mut before = clearances(&mut run);
    let mut profile = Profile {
        peak: before.first().map_or(f64::NEG_INFINITY, |c| c.displacement),
        norm: 0.0,
        impacts: 0,
        rigid_impacts: 0,
        sticks: 0,
        slowest_impact: None,
        closest: None,
        section: before.first().map(|c| c.displacement).into_iter().collect(),
    };
    let mut square_sum = 0.0;
    for k in 1..=samples {
        let t_a = run.time();
        let at_a = run.clone();
        let t_b = if k == samples { t0 + period } else { t0 + period * k as f64 / samples as f64 };
        run.advance_to(t_b).map_err(|e| e.to_string())?;
        let events = run.drain_events();
        for e in &events {
            match e.class {
                EventClass::Impact | EventClass::ContactOnset => {
                    profile.impacts += 1;
                    profile.rigid_impacts += usize::from(e.class == EventClass::Impact);
                    if let Some(v) = e.speed {
                        profile.slowest_impact = Some(profile.slowest_impact.map_or(v.abs(), |s: f64| s.min(v.abs())));
                    }
                }
                EventClass::Stick => profile.sticks += 1,
                _ => {}
            }
        }
        // The first stop's displacement at each event (an impact's
        // displacement peaks there, between samples).
        for e in &events {
            profile.peak = profile.peak.max(clearance_at(at_a.as_ref(), 0, e.time)?.displacement);
        }
        let after = clearances(&mut run);
        if let Some(first) = after.first() {
            profile.peak = profile.peak.max(first.displacement);
            if k % per_period == 0 && k < samples {
                profile.section.push(first.displacement);
            }
        }
        square_sum += state(&mut run).norm_squared();
        let compliant = |c: EventClass| matches!(c, EventClass::ContactOnset | EventClass::PushEnd | EventClass::PushResumed | EventClass::Separation);
        if !events.is_empty() && events.iter().all(|e| compliant(e.class)) {
            // A compliant contact's deepest point lies between its onset
            // and its separation: the maxima between events (with rigid
            // impacts, the peaks are theirs, counted above).
            let mut times: Vec<f64> = events.iter().map(|e| e.time).filter(|&t| t > t_a && t < t_b).collect();
            times.dedup();
            times.insert(0, t_a);
            times.push(t_b);
            let mut from = clearance_at(at_a.as_ref(), 0, t_a)?;
            for w in times.windows(2) {
                let to = clearance_at(at_a.as_ref(), 0, w[1])?;
                if w[1] > w[0] && from.velocity > 0.0 && to.velocity <= 0.0 {
                    profile.peak = profile.peak.max(smooth_maximum(at_a.as_ref(), w[0], w[1])?);
                }
                from = to;
            }
        }
        if events.is_empty() {
            for (i, (a, b)) in before.iter().zip(&after).enumerate() {
                if a.rate < 0.0 && b.rate >= 0.0 && a.gap > 0.0 && b.gap > 0.0 {
                    let found = smooth_minimum(at_a.as_ref(), i, t_a, t_b)?;
                    if profile.closest.map_or(true, |c| found.gap < c.gap) {
                        profile.closest = Some(found);
                    }
                }
                if i == 0 && a.velocity > 0.0 && b.velocity <= 0.0 {
                    profile.peak = profile.peak.max(smooth_maximum(at_a.as_ref(), t_a, t_b)?);
                }
            }
        }
        before = after;
    }
    profile.norm = (square_sum / samples as f64).sqrt();
    Ok(profile)
}

/// The clearance of stop `i` at `t` of a copy of `run` (at an earlier time).
fn clearance_at(run: &dyn Run, i: usize, t: f64) -> Result<Clearance, String> {
    let mut copy = run.boxed_clone();
    copy.advance_to(t).map_err(|e| e.to_string())?;
    Ok(clearances(&mut copy)[i])
}

/// Where `rate` of stop `i`'s clearance changes sign in `[t_a, t_b]` (no
/// event between): regula falsi, Illinois variant.
fn rate_zero(run: &dyn Run, i: usize, t_a: f64, t_b: f64, rate: fn(&Clearance) -> f64) -> Result<f64, String> {
    let value = |t: f64| Ok::<_, String>((t, rate(&clearance_at(run, i, t)?)));
    let mut bracket = RegulaFalsi::new(value(t_a)?, value(t_b)?);
    for _ in 0..100 {
        let (lo, hi) = (bracket.lo, bracket.hi);
        if hi - lo <= 4.0 * f64::EPSILON * hi.abs().max(lo.abs()) {
            break;
        }
        let (t, f) = value(bracket.next(false))?;
        if bracket.take(t, f).is_none() {
            return Ok(t);
        }
    }
    Ok(if bracket.f_lo.abs() < bracket.f_hi.abs() { bracket.lo } else { bracket.hi })
}

fn smooth_minimum(run: &dyn Run, i: usize, t_a: f64, t_b: f64) -> Result<Approach, String> {
    let time = rate_zero(run, i, t_a, t_b, |c| c.rate)?;
    let gap = clearance_at(run, i, time)?.gap;
    let h = 1e-3 * (t_b - t_a);
    let curvature = (clearance_at(run, i, (time + h).min(t_b))?.rate - clearance_at(run, i, (time - h).max(t_a))?.rate)
        / ((time + h).min(t_b) - (time - h).max(t_a));
    Ok(Approach { stop: i, time, gap, curvature })
}

fn smooth_maximum(run: &dyn Run, t_a: f64, t_b: f64) -> Result<f64, String> {
    let time = rate_zero(run, 0, t_a, t_b, |c| c.velocity)?;
    Ok(clearance_at(run, 0, time)?.displacement)
}
