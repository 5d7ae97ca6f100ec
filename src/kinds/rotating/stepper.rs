//! The rotating beam's integrators behind one interface: DOP853
//! ([`crate::solve::dop853`], explicit, order 8 with a 7th-order dense
//! output; the default) and Radau IIA ([`crate::solve::radau`],
//! L-stable, order 5; for runs whose highest modes make an explicit
//! method's step fall to its stability limit).
//!
//! Both take the phase's tolerances ([`RadauOptions`]: rtol, atol per
//! component, the step cap), step on their own grid, and give a dense
//! output over the last accepted step with its time derivative (the
//! switch locator's rates). A state inside a step to full order is a
//! step of the same method from the step's start, in contact several
//! shrinking toward it ([`full_order_state`]).

use nalgebra::DVector;
use serde::{Deserialize, Serialize};

use super::system::Phase;
use crate::contact::Contact;
use crate::structure::rotating::AccelerationScratch;
use crate::solve::dop853::{Dop853, Rhs};
use crate::solve::radau::{Radau, RadauOptions, Tol};

/// Which integrator a rotating run uses (`solver.method`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// DOP853: the fastest where the step is set by accuracy (the
    /// scenes' 6 to 40 modes over contact-length horizons).
    #[default]
    Dop853,
    /// Radau IIA: steps not limited by the highest modal frequency.
    Radau,
}

/// The phase's equations as DOP853's right-hand side (a copy of the
/// phase: a run restarts the integrator whenever the phase changes).
#[derive(Clone, Debug)]
pub struct PhaseRhs {
    phase: Phase,
    y: DVector<f64>,
    dy: DVector<f64>,
    scratch: AccelerationScratch,
}

impl PhaseRhs {
    fn new(phase: &Phase, n: usize) -> Self {
        PhaseRhs { phase: phase.clone(), y: DVector::zeros(n), dy: DVector::zeros(n), scratch: AccelerationScratch::default() }
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
    Dop853(Box<Dop853<PhaseRhs>>),
    Radau(Box<Radau>),
}

impl Stepper {
    /// An integrator at `(t0, y0)` for `phase` (not stepped).
    pub fn new(method: Method, phase: &Phase, t0: f64, y0: &DVector<f64>, options: &RadauOptions) -> Result<Self, String> {
        match method {
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
            Stepper::Dop853(s) => s.t,
            Stepper::Radau(s) => s.t(),
        }
    }

    /// The state at [`Self::t`].
    pub fn y(&self) -> DVector<f64> {
        match self {
            Stepper::Dop853(s) => DVector::from_column_slice(s.y()),
            Stepper::Radau(s) => s.y().clone(),
        }
    }

    /// One accepted step on the integrator's own grid: `[t0, t1]`.
    pub fn step(&mut self, phase: &mut Phase) -> Result<(f64, f64), String> {
        match self {
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
            Stepper::Dop853(s) => s.dense_at(t, out.as_mut_slice()),
            Stepper::Radau(s) => s.dense(t, out).is_ok(),
        }
    }

    /// Its time derivative; `false` before a step.
    pub fn dense_derivative(&self, t: f64, out: &mut DVector<f64>) -> bool {
        match self {
            Stepper::Dop853(s) => s.dense_derivative_at(t, out.as_mut_slice()),
            Stepper::Radau(s) => s.dense_derivative(t, out).is_ok(),
        }
    }

    /// Accepted and rejected steps so far.
    pub fn counts(&self) -> (u64, u64) {
        match self {
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
    let y = match method {
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
fn dop853_tolerances(options: &RadauOptions, n: usize) -> (f64, Vec<f64>) {
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
