//! Integrated phases: while a stop whose law's phase is nonlinear (Hertz)
//! is pressed or penetrated, the modal equations are integrated by Radau
//! IIA ([`crate::solve::radau`]) instead of propagated in closed form,
//! every engaged stop acting as a force of its law.
//!
//! The integrator starts at the phase's anchor with a step size that
//! depends only on the anchor, and steps on its own grid: communication
//! times never shorten a step, so the trajectory does not depend on them,
//! and a restored state rebuilds the same steps from its anchor (the
//! state needs no integrator history). Each accepted step's collocation
//! polynomial goes to the switch locator ([`crate::solve::switch`]:
//! samples, interior minima of the gaps and penetrations, bisection), and
//! the state at a switch is recomputed by one Radau step from the step's
//! start (order 5, not the polynomial's 3). The step is also capped at a
//! quarter of the linearised contact period.

use nalgebra::{DMatrix, DVector};

use super::nonlinear::{NonlinearContact, NonlinearPhase};
use super::{Channel, SimError, Simulation};
use crate::contact::{Contact, Watch};
use crate::solve::low_rank::LowRankJacobian;
use crate::solve::radau::{ImplicitSystem, Radau, RadauOptions, Tol};
use crate::solve::switch::{first_switch, DenseWatch};
use crate::solve::{Functional, Jet, ModalState};

/// How one channel is evaluated in an integrated phase.
#[derive(Clone, Debug)]
pub(super) enum Evaluator {
    /// An engaged stop's watch, on contact `i` of the phase.
    Nonlinear { contact: usize, watch: Watch },
    /// A function affine in the modal state (an open stop's gap).
    Affine(Functional),
}

/// The integrated segment: the phase's equations, the integrator, and
/// the last accepted step.
#[derive(Clone, Debug)]
pub(super) struct IntegratedSegment {
    pub phase: NonlinearPhase,
    pub solver: Radau,
    pub evaluators: Vec<Evaluator>,
    /// The last accepted step `[t0, t1]` and the state at its start.
    pub step: Option<(f64, f64, DVector<f64>)>,
    /// The state at a time inside the last step computed by a Radau step
    /// of its own from the step's start (order 5, where the collocation
    /// polynomial has order 3): what the outputs read.
    pub exact: Option<(f64, DVector<f64>)>,
    pub anchor_time: f64,
    pub anchor: DVector<f64>,
}

impl ImplicitSystem for NonlinearPhase {
    fn dim(&self) -> usize {
        NonlinearPhase::dim(self)
    }

    fn rhs(&mut self, t: f64, y: &DVector<f64>, dy: &mut DVector<f64>) {
        NonlinearPhase::rhs(self, t, y.as_slice(), dy.as_mut_slice());
    }

    fn jacobian(&mut self, t: f64, y: &DVector<f64>, jac: &mut DMatrix<f64>) -> bool {
        NonlinearPhase::jacobian(self, t, y.as_slice(), jac);
        true
    }

    fn low_rank_jacobian(&mut self, _t: f64, y: &DVector<f64>, jac: &mut LowRankJacobian) -> bool {
        NonlinearPhase::low_rank_jacobian(self, y.as_slice(), jac);
        true
    }
}

impl IntegratedSegment {
    /// The integrated state `[q; q'; J; E]` at `t` in the last step (the
    /// anchor before the first).
    pub fn y_at(&self, t: f64, out: &mut DVector<f64>) {
        if let Some((te, y)) = &self.exact {
            if *te == t {
                out.copy_from(y);
                return;
            }
        }
        match &self.step {
            Some((t0, _, y0)) if t == *t0 => out.copy_from(y0),
            Some(_) => {
                if self.solver.dense(t, out).is_err() {
                    // Outside the last step (never asked): its nearest end.
                    out.copy_from(self.solver.y());
                }
            }
            None => out.copy_from(&self.anchor),
        }
    }

    pub fn state_at(&self, t: f64, out: &mut ModalState) {
        let n = self.phase.n;
        let mut y = DVector::zeros(self.phase.dim());
        self.y_at(t, &mut y);
        out.q.copy_from(&y.rows(0, n));
        out.qd.copy_from(&y.rows(n, n));
    }

    /// The impulse and dissipated energy of the phase's contact `i` from
    /// the anchor to `t`.
    pub fn totals_at(&self, i: usize, t: f64) -> (f64, f64) {
        let mut y = DVector::zeros(self.phase.dim());
        self.y_at(t, &mut y);
        let (n, nc) = (self.phase.n, self.phase.contacts.len());
        (y[2 * n + i], y[2 * n + nc + i])
    }

    fn evaluate(&self, e: &Evaluator, y: &DVector<f64>) -> f64 {
        match e {
            Evaluator::Nonlinear { contact, watch } => {
                let (p, pd) = self.phase.penetration(*contact, y.as_slice());
                let c = &self.phase.contacts[*contact];
                c.law.watched(*watch, p, pd, c.onset_speed).0
            }
            Evaluator::Affine(h) => {
                let n = self.phase.n;
                h.offset + h.q.iter().zip(y.rows(0, n).iter()).map(|(a, b)| a * b).sum::<f64>()
            }
        }
    }
}

/// The watched functions along the last accepted step, for the switch
/// locator: gaps and penetrations give their rate (`w . q'` from the
/// dense output's derivative).
impl DenseWatch for IntegratedSegment {
    fn count(&self) -> usize {
        self.evaluators.len()
    }

    fn values(&self, t: f64, out: &mut [f64]) {
        let mut y = DVector::zeros(self.phase.dim());
        self.y_at(t, &mut y);
        for (o, e) in out.iter_mut().zip(&self.evaluators) {
            *o = self.evaluate(e, &y);
        }
    }

    fn value(&self, i: usize, t: f64) -> f64 {
        let mut y = DVector::zeros(self.phase.dim());
        self.y_at(t, &mut y);
        self.evaluate(&self.evaluators[i], &y)
    }

    fn rate(&self, i: usize, t: f64) -> Option<f64> {
        let n = self.phase.n;
        let q_rate = |a: &[f64], sign: f64| {
            let mut dy = DVector::zeros(self.phase.dim());
            self.solver.dense_derivative(t, &mut dy).ok()?;
            Some(sign * a.iter().zip(dy.rows(0, n).iter()).map(|(x, d)| x * d).sum::<f64>())
        };
        match &self.evaluators[i] {
            Evaluator::Affine(h) => q_rate(h.q.as_slice(), 1.0),
            Evaluator::Nonlinear { contact, watch } => {
                let g = &self.phase.contacts[*contact].geometry;
                match watch {
                    Watch::Penetration => q_rate(g.w.as_slice(), g.side),
                    Watch::Gap => q_rate(g.w.as_slice(), -g.side),
                    _ => None,
                }
            }
        }
    }
}

impl IntegratedSegment {
    /// Computes and keeps the state at `t` inside the last step to the
    /// method's full order (see [`Self::exact`]).
    pub fn settle_at(&mut self, t: f64) {
        let Some((t0, t1, y0)) = self.step.clone() else { return };
        if t <= t0 || t >= t1 || t > self.solver.t() {
            return;
        }
        let mut y = DVector::zeros(self.phase.dim());
        if one_step(&mut self.phase, t0, &y0, t, &mut y).is_ok() {
            self.exact = Some((t, y));
        }
    }
}

impl Simulation {
    /// The integrated segment of a phase with a nonlinear stop engaged:
    /// every engaged stop of a law with a force is one of its contacts.
    pub(super) fn integrated_segment(&self) -> Result<IntegratedSegment, SimError> {
        let n = self.model.n_modes();
        let omega2 = DVector::from_iterator(n, self.model.oscillators.iter().map(|o| o.omega * o.omega));
        let two_a = DVector::from_iterator(n, self.model.oscillators.iter().map(|o| 2.0 * o.a));
        let mut contacts = Vec::new();
        let mut index = vec![usize::MAX; self.model.stops.len()];
        for (i, (m, s)) in self.model.stops.iter().zip(&self.state.stops).enumerate() {
            if s.contact != Contact::Open && !m.law.rigid() {
                index[i] = contacts.len();
                contacts.push(NonlinearContact { stop: i, law: m.law.clone(), geometry: self.geometries[i].clone(), contact: s.contact, onset_speed: s.onset_speed });
            }
        }
        let evaluators = self
            .channels
            .iter()
            .map(|ch: &Channel| match self.state.stops[ch.stop].contact {
                Contact::Open => Evaluator::Affine(self.gap_functionals[ch.stop].clone()),
                _ => Evaluator::Nonlinear { contact: index[ch.stop], watch: ch.watch },
            })
            .collect();
        // A step no longer than a quarter of the fastest linearised contact
        // period at the larger of the current and a millionth-of-the-gap
        // penetration, nor the structure's shortest period.
        let mut max_step = self.model.shortest_period();
        let slowest = self.model.oscillators.iter().map(|o| o.omega).fold(f64::INFINITY, f64::min);
        let (mut scale_q, mut scale_v) = (0.0f64, 0.0f64);
        for c in &contacts {
            let g = &c.geometry;
            let w2 = g.w.dot(&g.w);
            let w_max = g.w.amax().max(f64::MIN_POSITIVE);
            // Effective mass of the point, 1 / |w|^2; the deepest
            // penetration of a mass that size arriving at the onset speed
            // (the law's depth storing its kinetic energy) sets the scale
            // of the contact.
            let v0 = c.onset_speed.max(g.penetration_rate(&self.state.anchor.qd).abs());
            // No deeper than the motion reaches (a vanishing stiffness
            // would give an infinite depth).
            let reach = g.gap.abs() + g.w.dot(&self.state.anchor.q).abs() + v0 / slowest;
            let depth = c.law.depth(v0, w2).min(reach);
            let p = g.penetration(&self.state.anchor.q).max(depth).max(1e-6 * g.gap.abs());
            let k_lin = c.law.raw_force(p, 0.0, c.onset_speed).1;
            let omega_c = (k_lin * w2).sqrt();
            if omega_c > 0.0 {
                max_step = max_step.min(0.25 * std::f64::consts::TAU / omega_c);
            }
            scale_q = scale_q.max(g.gap.abs().max(depth) / w_max);
            scale_v = scale_v.max(v0 / w_max);
        }
        let mut phase = NonlinearPhase::new(omega2, two_a, self.dynamics.forcing.clone(), contacts);
        let dim = phase.dim();
        let mut anchor = DVector::zeros(dim);
        anchor.rows_mut(0, n).copy_from(&self.state.anchor.q);
        anchor.rows_mut(n, n).copy_from(&self.state.anchor.qd);
        let tol = self.model.integration_tolerance;
        let q_scale = scale_q.max(self.state.anchor.q.amax()).max(f64::MIN_POSITIVE);
        let v_scale = (q_scale * slowest).max(scale_v).max(self.state.anchor.qd.amax()).max(f64::MIN_POSITIVE);
        let mut atol = DVector::zeros(dim);
        atol.rows_mut(0, n).fill(tol * q_scale);
        atol.rows_mut(n, n).fill(tol * v_scale);
        // Impulses and dissipation are integrals of the state, as accurate
        // as it: they need no error control of their own.
        atol.rows_mut(2 * n, dim - 2 * n).fill(1e100);
        let options = RadauOptions { rtol: Tol::Scalar(tol), atol: Tol::Vector(atol), h_max: max_step, max_steps: u64::MAX, ..RadauOptions::default() };
        let solver = Radau::new(&mut phase, self.state.anchor_time, &anchor, options)
            .map_err(|e| integration(self.state.anchor_time, e.to_string()))?;
        Ok(IntegratedSegment { phase, solver, evaluators, step: None, exact: None, anchor_time: self.state.anchor_time, anchor })
    }

    /// Steps the integrated phase until its steps cover `t` (a restored
    /// state replays its phase from the anchor).
    pub(super) fn replay_to(&mut self, t: f64) -> Result<(), SimError> {
        let super::Segment::Integrated(seg) = &mut self.segment else { return Ok(()) };
        while seg.step.as_ref().map_or(seg.anchor_time < t, |s| s.1 < t) {
            take_step(seg)?;
        }
        Ok(())
    }

    /// The event search of an integrated phase from `scan` up to `t_end`:
    /// the first switch with the state there, the channels at zero and the
    /// sample its bracket started at (a search resumed there finds it
    /// again), or `None` when `[scan, t_end]` is clear (then `scan` stays
    /// at or before `t_end`, inside the last step).
    pub(super) fn integrated_search(&mut self, t_end: f64, probes: &mut u64) -> Result<Option<IntegratedSwitch>, SimError> {
        let max_probes = self.model.max_probes_per_step;
        loop {
            let scan = self.state.scan;
            if scan >= t_end && scan > self.state.anchor_time {
                return Ok(None);
            }
            let super::Segment::Integrated(seg) = &mut self.segment else { unreachable!("an integrated segment") };
            if seg.step.as_ref().map_or(true, |s| s.1 <= scan) {
                let weight = crate::model::INTEGRATED_STEP_WEIGHT;
                *probes += weight;
                self.stats.probes += 1;
                if *probes > max_probes {
                    return Err(SimError::TooMuchWork { time: scan, work: *probes - weight, cap: "solver.max_probes_per_step" });
                }
                take_step(seg)?;
            }
            let (t0, t1, _) = seg.step.clone().expect("a step");
            let Some(located) = first_switch(&**seg, t0, t1, scan) else {
                if t1 > t_end {
                    // Clear to beyond t_end; the sample grid is the
                    // step's, so the next search sees the same samples.
                    self.state.scan = self.state.scan.max(t_end);
                    return Ok(None);
                }
                self.state.scan = t1;
                continue;
            };
            let te = located.time;
            if te > t_end {
                self.state.scan = self.state.scan.max(t_end);
                return Ok(None);
            }
            // The state at the switch: one Radau step from the step's start.
            let dim = seg.phase.dim();
            let y0 = seg.step.as_ref().expect("a step").2.clone();
            let mut at = DVector::zeros(dim);
            if te == t1 || te <= t0 || one_step(&mut seg.phase, t0, &y0, te, &mut at).is_err() {
                seg.y_at(te, &mut at);
            } else {
                // The totals the switch closes the phase with come from this
                // state too, as they do when the run stopped here first.
                seg.exact = Some((te, at.clone()));
            }
            let n = seg.phase.n;
            let mut st = ModalState::zeros(n);
            st.q.copy_from(&at.rows(0, n));
            st.qd.copy_from(&at.rows(n, n));
            let at_zero = located
                .at_zero
                .iter()
                .map(|&(c, slope)| {
                    let value = seg.evaluate(&seg.evaluators[c], &at);
                    (c, Jet { d: [value.min(0.0), slope, 0.0, 0.0], noise: [0.0; 4], slack: 0.0 })
                })
                .collect();
            return Ok(Some(IntegratedSwitch { time: te, state: st, at_zero, from: located.from }));
        }
    }
}

/// A switch an integrated phase's search located.
pub(super) struct IntegratedSwitch {
    pub time: f64,
    /// The state there (to the method's full order).
    pub state: ModalState,
    pub at_zero: Vec<(usize, Jet)>,
    /// The sample the switch's bracket started at.
    pub from: f64,
}

/// One Radau step from `(t0, y0)` to `t1` without error control: the state
/// at a switch to the method's full order.
fn one_step(phase: &mut NonlinearPhase, t0: f64, y0: &DVector<f64>, t1: f64, out: &mut DVector<f64>) -> Result<(), crate::solve::radau::RadauError> {
    let options = RadauOptions { h_init: Some(t1 - t0), fixed_step: true, ..RadauOptions::default() };
    let mut solver = Radau::new(phase, t0, y0, options)?;
    solver.step(phase, t1)?;
    out.copy_from(solver.y());
    Ok(())
}

fn take_step(seg: &mut IntegratedSegment) -> Result<(), SimError> {
    let (t0, y0) = (seg.solver.t(), seg.solver.y().clone_owned());
    let (a, b) = seg.solver.step(&mut seg.phase, f64::MAX).map_err(|e| integration(t0, e.to_string()))?;
    debug_assert_eq!(a, t0);
    seg.step = Some((a, b, y0));
    Ok(())
}

/// An integration failure, with what to change.
fn integration(time: f64, message: String) -> SimError {
    SimError::Integration { time, message: format!("{message}; loosen solver.integration_tolerance or check the contact parameters") }
}
