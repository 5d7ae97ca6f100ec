//! One run of a rotating hub beam: the whole motion integrated (the
//! equations are nonlinear everywhere) by the exponential integrator,
//! DOP853 or Radau IIA ([`super::stepper`]), restarted at every switch of the contact law and
//! at every change of the torque input.
//!
//! **Step grid.** After a restart the integrator starts from the restart
//! state (the anchor) with options and a first step that depend only on
//! the anchor, and steps on its own grid (`step(sys, f64::MAX)`):
//! communication times never shorten a step. A state asked for inside a
//! step (an output, a switch) is to full order: the exponential
//! integrator's dense output is; DOP853 and Radau take a step of their own
//! from the step's start (their dense outputs have one order less and two;
//! in contact, by pieces shrinking toward it,
//! [`super::stepper::full_order_state`]), so results at a given
//! time do not depend on the communication step, and a restored run
//! rebuilds the same steps from its anchor (`codec.rs`).
//!
//! **Switches** are located on each accepted step's dense output
//! ([`super::events`]: samples, interior minima of the gap, bisection);
//! the first one at or before the requested time is taken: the state there
//! is recomputed to full order, the law switched (onset: the approach
//! speed fixes the hysteretic damping; end of push: the spring energy
//! left is counted as dissipated), and the integration restarted.
//!
//! **Re-anchoring.** After [`REANCHOR_AFTER`] steps without a switch the
//! run restarts from the end of its last step, so a restored state replays
//! at most that many steps.
//!
//! **Step cap.** Open with a surface: the shortest modal period (DOP853
//! and Radau; the exponential integrator's switch search advances
//! conservatively through a longer step instead, [`super::events`]). In
//! contact: also a quarter of the linearised contact period
//! `2 pi / sqrt(1.5 K sqrt(p) / m)`, `m = 1 / (g^T J^-1 g)` the tip's
//! effective mass along the normal (`g` the gap's gradient), `p` the larger
//! of the anchor's penetration and the deepest one a mass `m` arriving at
//! the onset speed reaches, `(5 m v0^2 / 4 K)^(2/5)`. A push starting at
//! the surface (its force growing as `t^1.5`) takes a first step of
//! `tol^(2/7)` of that quarter period; with the exponential integrator, a
//! push whose penetration falls takes steps of at most 3/4 of the time
//! its end lies away at the present rate, down to `tol^(2/5)` of that
//! quarter period, which crosses it ([`RotatingSimulation::release_cap`]).
//! `tol` is what
//! [`super::spec::SolverSpec::integration_rtol`] makes of
//! `solver.tolerance`.

use std::cell::RefMut;
use std::sync::Arc;

use nalgebra::DVector;

use super::events::{CurveRoom, StepCurve};
use super::model::RotatingModel;
use super::readings::{Reading, Readings};
use super::spec::RotatingSpec;
use super::system::{ContactPoint, Phase};
use crate::contact::{Contact, Switch, Watch};
use crate::error::SimError;
use crate::kind::Reached;
use crate::solve::Jet;
use crate::solve::radau::{RadauOptions, Tol};
use super::stepper::{Method, Stepper};

/// What happened at an event.
#[derive(Clone, Debug, PartialEq)]
pub enum RotatingEventKind {
    /// The tip enters the surface at normal speed `speed` (m/s).
    Onset { speed: f64 },
    /// The raw force reached zero inside the surface (the damping would
    /// pull): the push ends with `penetration` left.
    PushEnd { penetration: f64 },
    /// Still inside, the force turned positive again.
    PushResumed,
    /// The tip left the surface: the contact's peak force, duration (from
    /// its onset) and impulse.
    Separation { peak_force: f64, duration: f64, impulse: f64 },
}

#[derive(Clone, Debug, PartialEq)]
pub struct RotatingEvent {
    pub time: f64,
    pub kind: RotatingEventKind,
}

impl RotatingEvent {
    /// One line for a log.
    pub fn describe(&self) -> String {
        let t = self.time;
        match self.kind {
            RotatingEventKind::Onset { speed } => format!("t = {t:?}: the tip strikes the surface at {speed:e} m/s"),
            RotatingEventKind::PushEnd { penetration } => {
                format!("t = {t:?}: the contact force reaches zero {penetration:e} m inside the surface")
            }
            RotatingEventKind::PushResumed => format!("t = {t:?}: the surface pushes again"),
            RotatingEventKind::Separation { peak_force, duration, impulse } => format!(
                "t = {t:?}: the tip leaves the surface (peak force {peak_force:e} N, contact {duration:e} s, impulse {impulse:e} N s)"
            ),
        }
    }
}

/// Work counters (not part of the state).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RotatingStats {
    pub accepted: u64,
    pub rejected: u64,
    /// Accepted steps taken while pressed or penetrated.
    pub contact_steps: u64,
    pub restarts: u64,
    pub events: u64,
    /// Windows of the shortest modal period the switch search searched
    /// one by one in free flight near the surface ([`super::events`]).
    pub switch_windows: u64,
}

/// The last accepted step: `[t0, t1]`, the state at `t0`, its first
/// switch, and its largest force (time, value) before that switch.
#[derive(Clone, Debug)]
pub(super) struct Step {
    pub t0: f64,
    pub t1: f64,
    pub y0: DVector<f64>,
    /// Its time, the watch whose zero it is and the bracketing chord's slope.
    pub switch: Option<(f64, Watch, f64)>,
    pub peak: Option<(f64, f64)>,
}

#[derive(Clone, Debug)]
pub struct RotatingSimulation {
    pub(super) model: Arc<RotatingModel>,
    pub(super) phase: Phase,
    pub(super) solver: Stepper,
    pub(super) options: RadauOptions,
    /// In a contact phase integrated exponentially, the smallest step
    /// the approach to the push's end is held to ([`Self::release_cap`]).
    pub(super) release_floor: Option<f64>,
    pub(super) anchor_time: f64,
    pub(super) anchor: DVector<f64>,
    pub(super) step: Option<Step>,
    pub(super) time: f64,
    pub(super) current: DVector<f64>,
    pub(super) onsets: u64,
    pub(super) impulse_mark: f64,
    /// Largest force of the current or latest contact up to the anchor, and
    /// up to `time`.
    pub(super) peak_before_anchor: f64,
    pub(super) peak: f64,
    /// Onset time and impulse total at the onset of the current or latest contact.
    pub(super) contact_start: f64,
    pub(super) impulse_at_start: f64,
    pub(super) events: Vec<RotatingEvent>,
    pub(super) stats: RotatingStats,
    /// Accepted steps since the anchor (bounds the replay on decode).
    pub(super) steps_since_anchor: u64,
    /// While recorded (the flow's Jacobian, [`super::flow`]): the end of
    /// every accepted step since the last switch.
    pub(super) trace: Option<Vec<f64>>,
    /// What the outputs read now, made once per instant.
    pub(super) readings: Readings,
    /// Working arrays kept across steps: a step's curve's, and the
    /// start state of the step before the last (the next step's room).
    pub(super) curve_room: CurveRoom,
    pub(super) spare_y0: DVector<f64>,
}

pub use crate::solve::REANCHOR_AFTER;

/// The share of the time left to a push's end (at the penetration's
/// present rate) a step may take ([`RotatingSimulation::release_cap`]):
/// pieces shrinking fourfold toward it, as force collocation's toward a
/// switch.
const RELEASE_SHARE: f64 = 0.75;

/// The largest turn of the hub in one step ([`RotatingSimulation::turn_cap`]):
/// an eighth of a turn, a thirty-second between the switch locator's
/// samples.
const MAX_TURN: f64 = std::f64::consts::FRAC_PI_4;

impl RotatingSimulation {
    /// A run of `spec` from its initial state at `start_time`.
    pub fn from_spec(spec: &RotatingSpec, start_time: f64) -> Result<Self, SimError> {
        Self::new(Arc::new(RotatingModel::new(spec).map_err(SimError::Scene)?), start_time)
    }

    /// A run from the model's initial state at `start_time`; a tip inside
    /// the surface, or on it and moving in, starts in contact (an onset).
    pub fn new(model: Arc<RotatingModel>, start_time: f64) -> Result<Self, SimError> {
        if !start_time.is_finite() {
            return Err(SimError::NonFinite { what: "start time", value: start_time });
        }
        let n = model.n_modes();
        let phase = Phase { model: model.clone(), contact: Contact::Open, onset_speed: 0.0, torque: 0.0 };
        let mut y = DVector::zeros(phase.dim());
        match model.prescribed() {
            None => {
                y.rows_mut(0, n + 1).copy_from(&model.initial_z);
                y.rows_mut(n + 1, n + 1).copy_from(&model.initial_zd);
            }
            Some(_) => {
                y.rows_mut(0, n).copy_from(&model.initial_z.rows(1, n));
                y.rows_mut(n, n).copy_from(&model.initial_zd.rows(1, n));
            }
        }
        let options = RadauOptions::default();
        let solver = Stepper::new(model.spec.solver.method, &phase, start_time, &y, &options).map_err(|e| integration(start_time, e))?;
        let mut sim = RotatingSimulation {
            model: model.clone(),
            phase,
            solver,
            options,
            release_floor: None,
            anchor_time: start_time,
            anchor: y.clone(),
            step: None,
            time: start_time,
            current: y.clone(),
            onsets: 0,
            impulse_mark: 0.0,
            peak_before_anchor: 0.0,
            peak: 0.0,
            contact_start: start_time,
            impulse_at_start: 0.0,
            events: Vec::new(),
            stats: RotatingStats::default(),
            steps_since_anchor: 0,
            trace: None,
            readings: Readings::default(),
            curve_room: Default::default(),
            spare_y0: DVector::zeros(0),
        };
        let mut contact = Contact::Open;
        if let Some(s) = &model.surface {
            let (z, zd) = sim.phase.coords(start_time, &y);
            let c = sim.phase.contact_point(&z, &zd);
            let speed = model.spec.speed_range().max;
            let limit = s.law.depth(speed, 1.0 / model.spec.beam_inertia());
            if c.penetration > limit {
                return Err(SimError::InitialPenetration { point: "the tip".into(), penetration: c.penetration, limit, fields: vec!["initial.theta".into()] });
            }
            if c.penetration > 0.0 || (c.penetration == 0.0 && c.rate > 0.0) {
                sim.phase.onset_speed = c.rate.max(0.0);
                // Penetrated only where the law would pull (its own
                // decision, robust to a force that rounds to zero at a
                // subnormal penetration: a force-free start there would
                // book the spring energy at the push's resumption as
                // negative dissipation).
                contact = if c.penetration == 0.0 { Contact::Pressed } else { s.law.initial_contact(c.penetration, c.rate) };
                sim.onsets = 1;
                sim.events.push(RotatingEvent { time: start_time, kind: RotatingEventKind::Onset { speed: c.rate } });
            }
        }
        sim.restart(start_time, y, contact)?;
        Ok(sim)
    }

    /// The integrator's options for a phase starting at `(t, y)`: tolerances scaled by
    /// the motion's size, the step cap (module doc).
    fn phase_options(&self, t: f64, y: &DVector<f64>) -> (RadauOptions, Option<f64>) {
        let m = &self.model;
        let n = m.n_modes();
        let tol = m.spec.solver.integration_rtol();
        let length = m.beam.params.length;
        let ell = m.tip_radius();
        let (z, zd) = self.phase.coords(t, y);
        let mut q = z.rows(1, n).amax().max(1e-4 * length);
        let mut v = zd.rows(1, n).amax().max(q * m.beam.omega(1));
        let mut h_max = f64::INFINITY;
        let mut h_init = None;
        let mut release_floor = None;
        if let Some(s) = &m.surface {
            // The exponential integrator's dense output is exact for the
            // modes' free motion: its switch search samples the step
            // finely instead ([`super::events`]).
            if m.spec.solver.method.resolve() != Method::Exponential {
                h_max = m.shortest_period();
            }
            if self.phase.contact != Contact::Open {
                let c = self.phase.contact_point(&z, &zd);
                let g = m.beam.contact_generalized_force(&z, &s.plane, 1.0);
                let inv_mass = match m.prescribed() {
                    None => m.beam.solve_mass_vector(&z, &g).ok().map(|x| g.dot(&x)),
                    Some(_) => {
                        let gb = g.rows(1, n).into_owned();
                        Some(gb.dot(&m.m_chol.solve(&gb)))
                    }
                };
                if let Some(inv) = inv_mass.filter(|x| *x > 0.0 && x.is_finite()) {
                    let mass = 1.0 / inv;
                    let v0 = self.phase.onset_speed.max(c.rate.abs());
                    // No deeper than the tip's radius (a vanishing K would
                    // give an infinite depth).
                    let depth = s.law.depth(v0, inv).min(ell);
                    let p = c.penetration.max(depth).max(1e-9 * length);
                    let omega_c = (s.law.raw_force(p, 0.0, self.phase.onset_speed).1 / mass).sqrt();
                    if omega_c > 0.0 && omega_c.is_finite() {
                        let quarter = 0.25 * std::f64::consts::TAU / omega_c;
                        h_max = h_max.min(quarter);
                        // A push starting at the surface grows as t^1.5: a
                        // first step of tol^(2/7) of the contact's scale
                        // carries that corner's error to the tolerance.
                        if c.penetration <= 1e-3 * depth {
                            h_init = Some(quarter * tol.powf(2.0 / 7.0).min(0.25));
                        }
                        // A push ends as (t_end - t)^1.5: a step across
                        // that corner errs by about (h / quarter)^(5/2) of
                        // the contact's scale, and one of tol^(2/5) of it
                        // carries the corner's error to the tolerance.
                        if m.spec.solver.method.resolve() == Method::Exponential {
                            release_floor = Some(quarter * tol.powf(2.0 / 5.0).min(0.25));
                        }
                    }
                    let w_max = m.beam.w.amax().max(f64::MIN_POSITIVE);
                    q = q.max(depth / w_max);
                    v = v.max(v0 / w_max);
                }
            }
        }
        let dim = self.phase.dim();
        let mut atol = DVector::from_element(dim, 1e100);
        match m.prescribed() {
            None => {
                atol[0] = tol * q / ell;
                atol.rows_mut(1, n).fill(tol * q);
                atol[n + 1] = tol * v / ell;
                atol.rows_mut(n + 2, n).fill(tol * v);
            }
            Some(_) => {
                atol.rows_mut(0, n).fill(tol * q);
                atol.rows_mut(n, n).fill(tol * v);
            }
        }
        // Free flight reuses the Jacobian while Newton converges fast
        // (RADAU5's rule); contact refreshes it at every step.
        let refresh = self.phase.contact != Contact::Open;
        let options = RadauOptions {
            rtol: Tol::Scalar(tol),
            atol: Tol::Vector(atol),
            h_max,
            h_init,
            max_steps: u64::MAX,
            refresh_jacobian_every_step: refresh,
            ..RadauOptions::default()
        };
        (options, release_floor)
    }

    /// The largest step from `(t, y)`: in a contact phase whose
    /// penetration falls, [`RELEASE_SHARE`] of the time it takes to reach
    /// zero at its present rate (at least [`Self::release_floor`]), so
    /// that the push's end is approached by steps shrinking geometrically
    /// and crossed by one of the floor's size. The exponential
    /// integrator's error estimate (its polynomial's top term) misses
    /// most of that corner's error in a step across it: without the cap,
    /// its error over the DWZ scene at 32 modes was 25 to 250 times
    /// larger from tolerance 1e-6 down, for about as many steps (the
    /// steps it saves by no longer being rejected on the corner, it
    /// spends approaching it).
    fn release_cap(&self, t: f64, y: &DVector<f64>) -> f64 {
        let Some(floor) = self.release_floor else { return f64::INFINITY };
        let (z, zd) = self.phase.coords(t, y);
        let c = self.phase.contact_point(&z, &zd);
        if !(c.penetration > 0.0 && c.rate < 0.0) {
            return f64::INFINITY;
        }
        (RELEASE_SHARE * c.penetration / -c.rate).max(floor)
    }

    /// The largest step from `(t, y)` with a surface: one that turns the
    /// hub by at most [`MAX_TURN`] at its present speed (a prescribed
    /// hub's: at most its profile's over that time). The switch locator
    /// samples a step at [`crate::solve::switch::SAMPLES`] points with the
    /// watched functions' rates, which finds one extremum between two
    /// samples; the tip's position along the surface's normal is a
    /// sinusoid of the hub's angle, with one extremum per half turn.
    /// Where the modes stand still and the contact's force vanishes (a
    /// soft law, a deep free rotation) nothing else holds the exponential
    /// integrator's step: the tip turned through a surface of K = 1e-30
    /// and out again unseen in 7 steps. (The other integrators' steps are
    /// held below the shortest modal period.)
    fn turn_cap(&self, t: f64, y: &DVector<f64>) -> f64 {
        if self.model.surface.is_none() {
            return f64::INFINITY;
        }
        let (_, zd) = self.phase.coords(t, y);
        let mut speed = zd[0].abs();
        if let Some(p) = self.model.prescribed() {
            speed = speed.max(p.speed_bound(t, t + MAX_TURN / speed.max(f64::MIN_POSITIVE)));
        }
        if speed > 0.0 {
            MAX_TURN / speed
        } else {
            f64::INFINITY
        }
    }

    /// A new phase from `(t, y)` in `contact` (the time becomes `t`).
    pub(super) fn restart(&mut self, t: f64, y: DVector<f64>, contact: Contact) -> Result<(), SimError> {
        self.phase.contact = contact;
        let (z, zd) = self.phase.coords(t, &y);
        self.peak = self.peak.max(self.phase.contact_point(&z, &zd).force);
        self.peak_before_anchor = self.peak;
        self.anchor_time = t;
        self.anchor = y.clone();
        self.time = t;
        self.current = y;
        self.stats.restarts += 1;
        self.steps_since_anchor = 0;
        self.start_phase()
    }

    /// The integrator at the anchor (no step taken).
    pub(super) fn start_phase(&mut self) -> Result<(), SimError> {
        self.stats.rejected += self.solver.counts().1;
        (self.options, self.release_floor) = self.phase_options(self.anchor_time, &self.anchor);
        self.step = None;
        self.solver = Stepper::new(self.model.spec.solver.method, &self.phase, self.anchor_time, &self.anchor, &self.options)
            .map_err(|e| integration(self.anchor_time, e))?;
        Ok(())
    }

    /// One accepted step, its first switch and its peak force.
    pub(super) fn take_step(&mut self) -> Result<(), SimError> {
        let t0 = self.solver.t();
        let mut y0 = std::mem::replace(&mut self.spare_y0, DVector::zeros(0));
        if y0.len() == self.solver.y_slice().len() {
            y0.copy_from_slice(self.solver.y_slice());
        } else {
            y0 = self.solver.y();
        }
        let cap = self.release_cap(t0, &y0).min(self.turn_cap(t0, &y0));
        let (a, b) = self
            .solver
            .step(&mut self.phase, cap)
            .map_err(|e| integration(t0, format!("{e} (contact {:?})", self.phase.contact)))?;
        self.stats.accepted += 1;
        self.steps_since_anchor += 1;
        if let Some(trace) = &mut self.trace {
            // Only the flow's Jacobian (the orbits tool) sets it.
            trace.push(b);
        }
        if self.phase.contact != Contact::Open {
            self.stats.contact_steps += 1;
        }
        let curve = StepCurve::new(&self.phase, &self.solver, a, b, &y0, &self.curve_room);
        let switch = curve.first_switch();
        self.stats.switch_windows += curve.windows();
        let mut peak = curve.peak_force(switch.map_or(b, |s| s.0));
        if let Some((tp, _)) = peak {
            // The peak's value from the full-order state there (not the
            // larger of it and the collocation polynomial's value: that
            // would keep the polynomial's overshoot, an error of order 3).
            if tp > a && tp < b {
                if let Some(y) = self.solver.state_inside(&self.phase, &self.options, a, &y0, tp) {
                    let (z, zd) = self.phase.coords(tp, &y);
                    peak = Some((tp, self.phase.contact_point(&z, &zd).force));
                }
            }
        }
        if let Some(old) = self.step.replace(Step { t0: a, t1: b, y0, switch, peak }) {
            self.spare_y0 = old.y0;
        }
        Ok(())
    }

    /// The state at `t` in the last step (the anchor before the first).
    pub(super) fn state_at(&self, t: f64) -> DVector<f64> {
        let Some(s) = &self.step else { return self.anchor.clone() };
        if t >= s.t1 {
            return self.solver.y();
        }
        if t <= s.t0 {
            return s.y0.clone();
        }
        self.solver.state_inside(&self.phase, &self.options, s.t0, &s.y0, t).unwrap_or_else(|| {
            let mut out = DVector::zeros(s.y0.len());
            if !self.solver.dense(t, &mut out) {
                out = self.solver.y();
            }
            out
        })
    }

    /// Moves the time to `t` inside the last step (the peak force follows).
    pub(super) fn pass_to(&mut self, t: f64) {
        if let Some((tp, fp)) = self.step.as_ref().and_then(|s| s.peak) {
            if tp > self.time && tp <= t {
                self.peak = self.peak.max(fp);
            }
        }
        self.time = t;
    }

    /// Advances to `t_end` through every switch on the way (including one at `t_end`).
    pub fn advance_to(&mut self, t_end: f64) -> Result<(), SimError> {
        self.advance(t_end, None).map(|_| ())
    }

    /// The advance of the contract ([`crate::kind::Run::advance`]): to
    /// `t_end`, stopping just before a switch where `stop_before(te)` says
    /// so (an advance to the same time makes it); every other switch is
    /// made. The switch is part of the step a restore replays: a saved
    /// state keeps it. One advance: one work cap.
    pub fn advance(&mut self, t_end: f64, mut stop_before: Option<&mut dyn FnMut(f64) -> bool>) -> Result<Reached, SimError> {
        if !t_end.is_finite() {
            return Err(SimError::NonFinite { what: "requested time", value: t_end });
        }
        if t_end < self.time {
            return Err(SimError::Backwards { now: self.time, requested: t_end });
        }
        if t_end > self.time {
            // The impulse state read from a step's dense output may dip a
            // rounding below zero at a contact's start: the mark (what the
            // last advance's impulse is counted from) never does.
            self.impulse_mark = self.impulse_total().max(0.0);
        }
        let mut count = 0u64;
        let mut steps = 0u64;
        let result = loop {
            if self.step.as_ref().map_or(true, |s| s.t1 <= self.time) {
                if self.time >= t_end {
                    break Ok(());
                }
                steps += 1;
                if steps > self.model.spec.solver.step_budget(self.model.n_modes()) {
                    break Err(SimError::TooMuchWork { time: self.time, work: steps - 1, cap: "solver.max_steps_per_step, in integration steps" });
                }
                if self.steps_since_anchor >= REANCHOR_AFTER {
                    let (t, y) = (self.solver.t(), self.solver.y());
                    if let Err(e) = self.restart(t, y, self.phase.contact) {
                        break Err(e);
                    }
                }
                if let Err(e) = self.take_step() {
                    break Err(e);
                }
            }
            let s = self.step.as_ref().expect("a step");
            let (t1, switch) = (s.t1, s.switch);
            match switch {
                Some((te, _, _)) if te <= t_end && stop_before.as_mut().is_some_and(|f| f(te)) => {
                    self.pass_to(te);
                    self.current = self.state_at(te);
                    return Ok(Reached::Event(te));
                }
                Some((te, watch, slope)) if te <= t_end => {
                    self.pass_to(te);
                    count += 1;
                    self.stats.events += 1;
                    if count > self.model.spec.solver.max_events_per_step {
                        self.current = self.state_at(te);
                        return Err(SimError::TooManyEvents { time: te, count });
                    }
                    if let Err(e) = self.switch(te, watch, slope) {
                        break Err(e);
                    }
                }
                _ if t1 <= t_end => self.pass_to(t1),
                _ => {
                    self.pass_to(t_end);
                    break Ok(());
                }
            }
        };
        self.current = self.state_at(self.time);
        result.map(|()| Reached::Time)
    }

    /// The switch of `watch` at `te` (module doc): the law decides the
    /// next contact state.
    fn switch(&mut self, te: f64, watch: Watch, slope: f64) -> Result<(), SimError> {
        let mut y = self.state_at(te);
        let (z, zd) = self.phase.coords(te, &y);
        let c = self.phase.contact_point(&z, &zd);
        let e = self.phase.extras();
        let law = &self.model.surface.as_ref().expect("switches need a surface").law;
        let jet = Jet { d: [law.watched(watch, c.penetration, c.rate, self.phase.onset_speed).0.min(0.0), slope, 0.0, 0.0], noise: [0.0; 4], slack: 0.0 };
        let from = self.phase.contact;
        let to = match law.on_zero(from, watch, &jet, c.penetration) {
            Switch::To(next) => next,
            // The zero of a function the state watches always ends it here.
            _ => if from == Contact::Open { Contact::Pressed } else { Contact::Open },
        };
        let kind = match (from, to) {
            (Contact::Open, _) => {
                self.phase.onset_speed = c.rate.max(0.0);
                self.onsets += 1;
                self.contact_start = te;
                self.impulse_at_start = y[e];
                self.peak = 0.0;
                RotatingEventKind::Onset { speed: c.rate }
            }
            (Contact::Pressed, Contact::Penetrated) => {
                y[e + 1] += law.energy_left_at_release(c.penetration);
                RotatingEventKind::PushEnd { penetration: c.penetration.max(0.0) }
            }
            (Contact::Penetrated, Contact::Pressed) => {
                y[e + 1] -= law.energy_left_at_release(c.penetration);
                RotatingEventKind::PushResumed
            }
            _ => RotatingEventKind::Separation { peak_force: self.peak, duration: te - self.contact_start, impulse: y[e] - self.impulse_at_start },
        };
        self.events.push(RotatingEvent { time: te, kind });
        self.restart(te, y, to)
    }

    /// Changes the hub torque (N m); a change restarts the integration at
    /// the current time. An error for a prescribed hub.
    pub fn set_torque(&mut self, torque: f64) -> Result<(), SimError> {
        if !torque.is_finite() {
            return Err(SimError::NonFinite { what: "torque", value: torque });
        }
        if self.model.prescribed().is_some() {
            return Err(SimError::NotAnInput("torque: the hub's motion is prescribed (its torque is an output)".into()));
        }
        if torque == self.phase.torque {
            return Ok(());
        }
        self.phase.torque = torque;
        let y = self.current.clone();
        self.restart(self.time, y, self.phase.contact)?;
        self.onset_if_inside()
    }

    /// An open tip that a restart (a torque set) finds inside the surface
    /// and moving further in makes its onset at once. The previous step's
    /// locator placed that onset just after the step's end, to its
    /// accuracy; the new phase's search would start on the wrong side of
    /// the gap's zero and place it late (2.1e-8 s, the tip 2.8e-8 m inside
    /// while open, at tolerance 1e-10: the FMI 3.0 fuzzer, seed 9105).
    fn onset_if_inside(&mut self) -> Result<(), SimError> {
        if self.phase.contact != Contact::Open || self.model.surface.is_none() {
            return Ok(());
        }
        let (z, zd) = self.phase.coords(self.time, &self.current);
        let c = self.phase.contact_point(&z, &zd);
        if c.penetration > 0.0 && c.rate > 0.0 {
            self.switch(self.time, Watch::Gap, -c.rate)?;
        }
        Ok(())
    }

    /// The hub torque input (0 for a prescribed hub), N m.
    pub fn torque(&self) -> f64 {
        self.phase.torque
    }

    pub fn model(&self) -> &RotatingModel {
        &self.model
    }

    pub fn time(&self) -> f64 {
        self.time
    }

    /// The anchor's time (the steps are replayed from there) or the
    /// current contact's start, whichever is earlier.
    pub fn earliest_time(&self) -> f64 {
        self.anchor_time.min(self.contact_start)
    }

    pub fn stats(&self) -> RotatingStats {
        let mut s = self.stats;
        s.rejected += self.solver.counts().1;
        s
    }

    /// The events since the last call.
    pub fn drain_events(&mut self) -> Vec<RotatingEvent> {
        std::mem::take(&mut self.events)
    }

    /// The integrated state now (layout in [`super::system`]).
    pub fn y(&self) -> &DVector<f64> {
        &self.current
    }

    /// The last restart: its time and state.
    pub fn anchor(&self) -> (f64, &DVector<f64>) {
        (self.anchor_time, &self.anchor)
    }

    /// `(z, z') = ([theta, B], [theta', B'])` now.
    pub fn coordinates(&self) -> (DVector<f64>, DVector<f64>) {
        let now = self.now();
        (now.z.clone(), now.zd.clone())
    }

    /// The present instant's readings.
    fn now(&self) -> RefMut<'_, Reading> {
        self.readings.at(&self.phase, self.time, &self.current)
    }

    fn contact_now(&self) -> ContactPoint {
        self.now().point(&self.phase)
    }

    pub fn contact_state(&self) -> Contact {
        self.phase.contact
    }

    pub fn theta(&self) -> f64 {
        self.now().z[0]
    }

    pub fn theta_dot(&self) -> f64 {
        self.now().zd[0]
    }

    /// Tip deflection `v_L` in the rotating frame, m.
    pub fn tip_deflection(&self) -> f64 {
        self.model.beam.tip_deflection(&self.now().z)
    }

    /// Tip position in the fixed frame, m.
    pub fn tip_position(&self) -> [f64; 2] {
        self.now().tip_position(&self.phase)
    }

    /// Tip velocity in the fixed frame, m/s.
    pub fn tip_velocity(&self) -> [f64; 2] {
        let now = self.now();
        self.model.beam.tip_velocity(&now.z, &now.zd)
    }

    /// The force the surface pushes the tip with now, N.
    pub fn contact_force(&self) -> f64 {
        self.contact_now().force
    }

    /// The gap `n . (r_tip - p0)` (negative inside; 0 without a surface), m.
    pub fn gap(&self) -> f64 {
        -self.contact_now().penetration
    }

    /// `max(0, -gap)`, m.
    pub fn penetration(&self) -> f64 {
        self.contact_now().penetration.max(0.0)
    }

    /// Contact onsets since the start.
    pub fn contacts(&self) -> u64 {
        self.onsets
    }

    /// The largest force of the current or latest contact so far, N.
    pub fn peak_force(&self) -> f64 {
        self.peak
    }

    /// `int F dt` since the start, N s.
    pub fn impulse_total(&self) -> f64 {
        self.current[self.phase.extras()]
    }

    /// The impulse of the last advance that moved time, N s.
    pub fn last_impulse(&self) -> f64 {
        (self.impulse_total() - self.impulse_mark).max(0.0)
    }

    /// `int M_O dt`: the contact force's angular impulse about the axis, N m s.
    pub fn angular_impulse_total(&self) -> f64 {
        self.current[self.phase.extras() + 2]
    }

    /// Energy the contact dissipated (damping, and the spring energy left
    /// at the end of a push), J.
    pub fn dissipated_energy(&self) -> f64 {
        self.current[self.phase.extras() + 1]
    }

    /// `2/5 K gamma^2.5` while pressed, J.
    pub fn stored_energy(&self) -> f64 {
        self.phase.stored_energy(&self.contact_now())
    }

    /// Bending moment at the clamp, N m.
    pub fn root_moment(&self) -> f64 {
        self.model.beam.root_moment(&self.now().z)
    }

    /// Kinetic, strain and gravity energy of hub and beam, J.
    pub fn structure_energy(&self) -> f64 {
        self.now().energy(&self.phase)
    }

    /// Structure plus the energy stored in the contact, J.
    pub fn total_energy(&self) -> f64 {
        self.structure_energy() + self.stored_energy()
    }

    /// Angular momentum about the axis, `(J z')_theta`, kg m^2/s.
    pub fn angular_momentum(&self) -> f64 {
        let now = self.now();
        (self.model.beam.mass_matrix(&now.z) * &now.zd)[0]
    }

    /// The hub torque: the input, or what the prescribed motion needs, N m.
    pub fn hub_torque(&self) -> f64 {
        let mut now = self.now();
        let c = now.point(&self.phase);
        self.phase.hub_torque(self.time, &now.z, &now.zd, &c)
    }
}

/// An integration failure, with what to change.
fn integration(time: f64, message: String) -> SimError {
    SimError::Integration {
        time,
        message: format!(
            "{message}; loosen solver.tolerance, check the contact stiffness, or raise hub_inertia if the mass matrix lost definiteness"
        ),
    }
}
