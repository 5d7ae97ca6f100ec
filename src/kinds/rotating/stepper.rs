//! The rotating beam's integrators behind one interface: the exponential
//! integrator ([`crate::solve::exponential`]: the bending modes' linear
//! response, with the stiffening of a hub speed near the phase's start
//! ([`super::frozen`]), propagated exactly, the remainder collocated;
//! `auto`), DOP853 ([`crate::solve::dop853`], explicit, order 8 with a
//! 7th-order dense output) and Radau IIA ([`crate::solve::radau`],
//! L-stable, order 5).
//!
//! All three take the phase's tolerances ([`RadauOptions`]: rtol, atol per
//! component, the step cap), step on their own grid, and give a dense
//! output over the last accepted step with its time derivative (the
//! switch locator's rates). A state inside a step to full order is the
//! exponential integrator's dense output, or a step of DOP853 or Radau
//! from the step's start, in contact several shrinking toward it
//! ([`full_order_state`]).

use nalgebra::DVector;
use serde::{Deserialize, Serialize};

use super::frozen::Frozen;
use super::system::Phase;
use crate::contact::Contact;
use crate::structure::rotating::{AccelerationScratch, Hub, ModalEquations, ModalPoint};
use crate::solve::dop853::{Dop853, Rhs};
use crate::solve::exponential::{Exponential, ModalRhs};
use crate::solve::matvec::BATCH_ROWS;
use crate::solve::radau::{Radau, RadauOptions, Tol};

/// Which integrator a rotating run uses (`solver.method`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// The exponential integrator, at every number of modes
    /// (scripts/rotating-scaling, DWZ: at equal error faster than DOP853
    /// from 2 modes up, 1.5 times at 6 modes and an error of 1e-8; SpinUpBeam's
    /// 30 s 3 times at its 4 modes).
    #[default]
    Auto,
    /// Exponential: steps set by the remainder (contact, hub speed
    /// changes, nonlinear terms), not by the highest mode.
    Exponential,
    /// DOP853: explicit, its step bounded by the highest mode.
    Dop853,
    /// Radau IIA: steps not limited by the highest modal frequency.
    Radau,
}

impl Method {
    /// The integrator `self` means.
    pub fn resolve(self) -> Method {
        match self {
            Method::Auto => Method::Exponential,
            m => m,
        }
    }
}

/// The phase's equations as DOP853's right-hand side (a copy of the
/// phase: a run restarts the integrator whenever the phase changes).
#[derive(Clone, Debug)]
pub struct PhaseRhs {
    phase: Phase,
    y: DVector<f64>,
    dy: DVector<f64>,
    scratch: AccelerationScratch,
    /// The equations in the exponential integrator's modal coordinates.
    modal: Option<ModalEquations>,
}

impl PhaseRhs {
    pub(super) fn new(phase: &Phase, n: usize) -> Self {
        PhaseRhs { phase: phase.clone(), y: DVector::zeros(n), dy: DVector::zeros(n), scratch: AccelerationScratch::default(), modal: None }
    }

    /// [`Self::new`] with the remainder in the coordinates of `frozen`.
    fn with_frozen(phase: &Phase, n: usize, frozen: &Frozen) -> Self {
        let mut rhs = Self::new(phase, n);
        rhs.modal = Some(frozen.equations.clone());
        rhs
    }
}

impl ModalRhs for PhaseRhs {
    fn modal_remainder(&mut self, t: f64, q: &[f64], g: &mut [f64]) -> bool {
        let Some(modal) = self.modal.as_mut() else { return false };
        if modal_rates(&self.phase, modal, t, q, g).is_err() {
            // J(z) lost definiteness: the step control sees a non-finite value.
            g.fill(f64::NAN);
        }
        true
    }

    /// Below [`BATCH_ROWS`] modal coordinates point by point: the batch
    /// does not pay there.
    fn modal_remainders(&mut self, ts: &[f64], qs: &[&[f64]], gs: &mut [&mut [f64]]) -> bool {
        let Some(modal) = self.modal.as_mut() else { return false };
        if self.phase.extras() / 2 < BATCH_ROWS {
            return ts.iter().zip(qs).zip(gs.iter_mut()).all(|((&t, q), g)| self.modal_remainder(t, q, g));
        }
        modal_rates_at(&self.phase, modal, ts, qs, gs);
        true
    }
}

/// The hub's motion in `phase` at `t`.
fn hub_at(phase: &Phase, t: f64) -> Hub {
    match phase.model.prescribed() {
        Some(profile) => {
            let (theta, theta_dot, theta_ddot) = profile.at(t);
            Hub::Prescribed { theta, theta_dot, theta_ddot }
        }
        None => Hub::Torque(phase.torque),
    }
}

/// The remainder of a phase in modal coordinates `q = [p; p'; P, E, H]`:
/// the modes' `g`, then the running totals' rates as
/// [`Phase::fill_rhs`] gives them.
fn modal_rates(phase: &Phase, modal: &mut ModalEquations, t: f64, q: &[f64], g: &mut [f64]) -> Result<(), String> {
    let m = phase.extras() / 2;
    let hub = hub_at(phase, t);
    let terms = phase.with_pushing_law(|contact| modal.remainder(&phase.model.beam, &q[..m], &q[m..2 * m], hub, contact, &mut g[..m]))?;
    phase.totals_rates(&terms, &mut g[m..m + 3]);
    Ok(())
}

/// [`modal_rates`] at several points (a step's nodes; the products in one
/// pass, [`ModalEquations::remainders`]); a point where `J(z)` lost
/// definiteness gets non-finite values, which the step control sees.
fn modal_rates_at(phase: &Phase, modal: &mut ModalEquations, ts: &[f64], qs: &[&[f64]], gs: &mut [&mut [f64]]) {
    const POINTS: usize = 8;
    let m = phase.extras() / 2;
    for ((ts, qs), gs) in ts.chunks(POINTS).zip(qs.chunks(POINTS)).zip(gs.chunks_mut(POINTS)) {
        let count = ts.len();
        let points: [ModalPoint<'_>; POINTS] = std::array::from_fn(|i| match (ts.get(i), qs.get(i)) {
            (Some(&t), Some(q)) => ModalPoint { p: &q[..m], pd: &q[m..2 * m], hub: hub_at(phase, t) },
            _ => ModalPoint { p: &[], pd: &[], hub: Hub::Torque(0.0) },
        });
        let mut terms = [None; POINTS];
        {
            let mut rows = gs.iter_mut();
            let mut modes: [&mut [f64]; POINTS] = std::array::from_fn(|_| rows.next().map_or(Default::default(), |g| &mut g[..m]));
            phase.with_pushing_law(|contact| modal.remainders(&phase.model.beam, &points[..count], contact, &mut modes[..count], &mut terms[..count]));
        }
        for (g, terms) in gs.iter_mut().zip(&terms) {
            match terms {
                Some(terms) => phase.totals_rates(terms, &mut g[m..m + 3]),
                // J(z) lost definiteness: the step control sees a non-finite value.
                None => g.fill(f64::NAN),
            }
        }
    }
}

impl Rhs for PhaseRhs {
    fn eval(&mut self, t: f64, y: &[f64], dy: &mut [f64]) {
        let ok = if self.phase.prescribed() {
            self.y.copy_from_slice(y);
            let ok = self.phase.fill_rhs(t, &self.y, &mut self.dy).is_ok();
            dy.copy_from_slice(self.dy.as_slice());
            ok
        } else {
            self.phase.fill_rhs_free_hub(y, dy, &mut self.scratch).is_ok()
        };
        if !ok {
            // J(z) lost definiteness: the step control sees a non-finite value.
            dy.fill(f64::NAN);
        }
    }
}

#[derive(Clone, Debug)]
pub enum Stepper {
    Exponential(Box<Exponential<PhaseRhs>>),
    Dop853(Box<Dop853<PhaseRhs>>),
    Radau(Box<Radau>),
}

impl Stepper {
    /// An integrator at `(t0, y0)` for `phase` (not stepped).
    pub fn new(method: Method, phase: &Phase, t0: f64, y0: &DVector<f64>, options: &RadauOptions) -> Result<Self, String> {
        match method.resolve() {
            Method::Auto | Method::Exponential => {
                let n = y0.len();
                let (rtol, atol) = dop853_tolerances(options, n);
                let frozen = phase.frozen(t0, y0)?;
                let solver = Exponential::new(PhaseRhs::with_frozen(phase, n, &frozen), frozen.modes.clone(), t0, y0.as_slice(), rtol, &atol, options.h_init, options.h_max);
                if !solver.y().iter().all(|x| x.is_finite()) {
                    return Err("the start state is not finite".into());
                }
                Ok(Stepper::Exponential(Box::new(solver)))
            }
            Method::Radau => {
                let mut probe = phase.clone();
                Ok(Stepper::Radau(Box::new(Radau::new(&mut probe, t0, y0, options.clone()).map_err(|e| e.to_string())?)))
            }
            Method::Dop853 => {
                let n = y0.len();
                let (rtol, atol) = dop853_tolerances(options, n);
                let rhs = PhaseRhs::new(phase, n);
                let mut solver = Dop853::new(rhs, t0, y0.as_slice(), f64::MAX, rtol, &atol, None);
                solver.max_step = options.h_max;
                // The first step: the phase's (a corner's), else chosen under the cap.
                solver.restart(t0, y0.as_slice(), options.h_init);
                if !solver.y().iter().all(|x| x.is_finite()) {
                    return Err("the start state is not finite".into());
                }
                Ok(Stepper::Dop853(Box::new(solver)))
            }
        }
    }

    pub fn t(&self) -> f64 {
        match self {
            Stepper::Exponential(s) => s.t(),
            Stepper::Dop853(s) => s.t,
            Stepper::Radau(s) => s.t(),
        }
    }

    /// The state at [`Self::t`].
    pub fn y(&self) -> DVector<f64> {
        DVector::from_column_slice(self.y_slice())
    }

    /// [`Self::y`] without a copy.
    pub fn y_slice(&self) -> &[f64] {
        match self {
            Stepper::Exponential(s) => s.y(),
            Stepper::Dop853(s) => s.y(),
            Stepper::Radau(s) => s.y().as_slice(),
        }
    }

    /// One accepted step on the integrator's own grid, `[t0, t1]`; the
    /// exponential integrator's at most `cap` long (its error estimate,
    /// the polynomial's top term, misses much of a force's corner inside
    /// a step: [`super::sim`]'s `release_cap`). DOP853 capped the same way
    /// had no smaller error at 6 modes and 3 % more steps; it is not
    /// capped, nor is Radau.
    pub fn step(&mut self, phase: &mut Phase, cap: f64) -> Result<(f64, f64), String> {
        match self {
            Stepper::Exponential(s) => {
                let max_step = s.max_step;
                s.max_step = max_step.min(cap);
                let span = s.step().map_err(|e| format!("exponential integrator: {e:?}"));
                s.max_step = max_step;
                let span = span?;
                if !s.y().iter().all(|x| x.is_finite()) {
                    return Err("exponential integrator: the state is not finite".into());
                }
                Ok(span)
            }
            Stepper::Dop853(s) => {
                let span = s.step().map_err(|e| format!("DOP853: {e:?}"))?;
                if !s.y().iter().all(|x| x.is_finite()) {
                    return Err("DOP853: the state is not finite".into());
                }
                s.prepare_dense();
                Ok(span)
            }
            Stepper::Radau(s) => s.step(phase, f64::MAX).map_err(|e| e.to_string()),
        }
    }

    /// The dense output over the last step at `t`; `false` before a step.
    pub fn dense(&self, t: f64, out: &mut DVector<f64>) -> bool {
        match self {
            Stepper::Exponential(s) => s.dense(t, out.as_mut_slice()),
            Stepper::Dop853(s) => s.dense_at(t, out.as_mut_slice()),
            Stepper::Radau(s) => s.dense(t, out).is_ok(),
        }
    }

    /// The penetration of the phase's surface and its rate on the dense
    /// output at `t` inside the last step, from the exponential
    /// integrator's modal state (`lp`: room for its products); `None` for
    /// the other integrators, before a step, or without a surface.
    pub fn dense_penetration(&self, phase: &Phase, t: f64, lp: &mut Vec<f64>) -> Option<(f64, f64)> {
        let Stepper::Exponential(s) = self else { return None };
        let modal = s.inner.modal.as_ref()?;
        let surface = phase.model.surface.as_ref()?;
        let hub = hub_at(phase, t);
        let m = phase.extras() / 2;
        s.with_dense_modal(t, |q| modal.penetration(&phase.model.beam, &q[..m], &q[m..2 * m], hub, &surface.plane, lp))
    }

    /// Whether the dense output's velocities are the exact rates of its
    /// coordinates (the exponential integrator's: each mode's response is
    /// exact under the step's polynomial), so that a rate of the
    /// coordinates needs no [`Self::dense_derivative`].
    pub fn velocity_is_rate(&self) -> bool {
        matches!(self, Stepper::Exponential(_))
    }

    /// Its time derivative; `false` before a step.
    pub fn dense_derivative(&self, t: f64, out: &mut DVector<f64>) -> bool {
        match self {
            Stepper::Exponential(s) => s.dense_derivative(t, out.as_mut_slice()),
            Stepper::Dop853(s) => s.dense_derivative_at(t, out.as_mut_slice()),
            Stepper::Radau(s) => s.dense_derivative(t, out).is_ok(),
        }
    }

    /// The state at `t` inside the last step `[t0, t1]` from `y0`, to full
    /// order: the exponential integrator's dense output is; the others
    /// take a step of their own ([`full_order_state`]).
    pub fn state_inside(&self, phase: &Phase, options: &RadauOptions, t0: f64, y0: &DVector<f64>, t: f64) -> Option<DVector<f64>> {
        match self {
            Stepper::Exponential(s) => {
                let mut out = DVector::zeros(y0.len());
                (s.dense(t, out.as_mut_slice()) && out.iter().all(|x| x.is_finite())).then_some(out)
            }
            Stepper::Dop853(_) => full_order_state(Method::Dop853, phase, options, t0, y0, t),
            Stepper::Radau(_) => full_order_state(Method::Radau, phase, options, t0, y0, t),
        }
    }

    /// A bound on the rate of `w . z` over the last step, and one on each
    /// of the first `rates.len()` coordinates' rates into `rates` (the
    /// exponential integrator's and DOP853's; `None` for Radau).
    pub fn speed_bounds(&self, w: &[f64], rates: &mut [f64]) -> Option<f64> {
        match self {
            Stepper::Exponential(s) => s.speed_bound_with_rates(w, rates),
            // The velocities follow the coordinates `w` weighs; half again
            // for the weights' change along the step (the caller's `w` is
            // the gap's gradient at the step's start) and for the rates.
            Stepper::Dop853(s) => {
                let along = s.dense_dot_bound(w, w.len())?;
                if !s.dense_component_bounds(w.len(), rates) {
                    return None;
                }
                rates.iter_mut().for_each(|x| *x *= 1.5);
                Some(1.5 * along)
            }
            Stepper::Radau(_) => None,
        }
    }

    /// Accepted and rejected steps so far.
    pub fn counts(&self) -> (u64, u64) {
        match self {
            Stepper::Exponential(s) => s.counts(),
            Stepper::Dop853(s) => (s.n_accepted as u64, s.n_rejected as u64),
            Stepper::Radau(s) => (s.stats().accepted, s.stats().rejected),
        }
    }
}

/// The state at `t1` inside a step from `(t0, y0)` to the method's full
/// order: one step of `method` without error control; with DOP853 in
/// contact, pieces shrinking fourfold toward `t1` (a push may end there
/// in a `p^1.5` corner).
pub fn full_order_state(method: Method, phase: &Phase, options: &RadauOptions, t0: f64, y0: &DVector<f64>, t1: f64) -> Option<DVector<f64>> {
    if t1 <= t0 || t1.is_nan() || t0.is_nan() {
        return None;
    }
    let y = match method.resolve() {
        Method::Auto | Method::Exponential => return None,
        Method::Radau => {
            let mut phase = phase.clone();
            let o = RadauOptions { h_init: Some(t1 - t0), fixed_step: true, h_max: f64::INFINITY, ..options.clone() };
            let mut solver = Radau::new(&mut phase, t0, y0, o).ok()?;
            solver.step(&mut phase, t1).ok()?;
            solver.y().clone()
        }
        Method::Dop853 => {
            let (rtol, atol) = dop853_tolerances(options, y0.len());
            let n = y0.len();
            let rhs = PhaseRhs::new(phase, n);
            let mut s = Dop853::new(rhs, t0, y0.as_slice(), f64::MAX, rtol, &atol, Some(t1 - t0));
            if phase.contact != Contact::Open {
                // Pieces shrinking fourfold toward `t1`: where a push ends
                // there (its force a `p^1.5` corner), the last, tol^(2/7)
                // of the interval long, carries the corner's error to the
                // tolerance.
                let smallest = rtol.powf(2.0 / 7.0);
                let mut remaining = 1.0;
                while remaining / 4.0 > smallest {
                    s.step_to(t0 + (1.0 - 0.25 * remaining) * (t1 - t0));
                    remaining *= 0.25;
                }
            }
            s.step_to(t1);
            DVector::from_column_slice(s.y())
        }
    };
    y.iter().all(|x| x.is_finite()).then_some(y)
}

/// DOP853's scalar rtol and per-component atol from the phase's options.
pub(super) fn dop853_tolerances(options: &RadauOptions, n: usize) -> (f64, Vec<f64>) {
    let atol = match &options.atol {
        Tol::Scalar(v) => vec![*v; n],
        Tol::Vector(v) => v.as_slice().to_vec(),
    };
    let rtol = match &options.rtol {
        Tol::Scalar(v) => *v,
        Tol::Vector(v) => v.min(),
    };
    (rtol, atol)
}
