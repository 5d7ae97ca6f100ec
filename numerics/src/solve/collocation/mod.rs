//! Force collocation: a linear modal structure under point forces that
//! depend nonlinearly on the motion of their points (Hertz contacts),
//! stepped at the pace of the forces, not of the structure's fastest mode.
//!
//! On a step `[t0, t0 + h]` each contact force is a polynomial of degree
//! `s - 1` in time, fixed by its values at the `s` Gauss-Legendre nodes.
//! Every mode is propagated exactly under those polynomials and the
//! external load ([`FreeSegment`] for the load, [`super::phi`] for the
//! polynomials), so the contact coordinates at the nodes are affine in the
//! nodal forces, and only the `nc * s` nodal forces are solved for:
//! Newton on `F_ci = law(p_c(t_i), p_c'(t_i))`, with a small dense
//! Jacobian. A step costs `O(N s^2)` for the kernels plus `O((nc s)^3)`
//! per Newton iteration; its size follows the force's smoothness
//! (exponential collocation, HO10 sec. 2.3).
//!
//! **Error control.** The collocated force misses the law's force by the
//! defect `d(t) = law(y(t)) - P(t)`, zero at the nodes; it is modelled as
//! `w_s(sigma) (D0 (1 - sigma) + D1 sigma)`, `w_s` the nodes' polynomial,
//! with `D0`, `D1` read from the defect at the step's two ends, and the
//! local error is the exact response of every mode to that load, with the
//! contacts' linearised feedback through the Newton matrix. Where the
//! force is smooth, `D0 = D1` and the response to `w_s` nearly vanishes
//! for modes that barely move over a step (Gauss orthogonality: order `2s`
//! at step ends); fast modes and a changing `D` (an onset's `p^1.5`) are
//! carried by the estimate. An onset whose force grows as `t^a` (Hertz:
//! 1.5) starts with a step of `tol^(1/(a+2))` of the contact's scale, and
//! a state at a switch is reached by pieces shrinking toward it to that
//! fraction ([`ForceCollocation::single_step`]): a separation ends the
//! force in a `t^a` corner no defect estimate sees.
//!
//! **Cost.** Step sizes come from a ladder of `2^(1/4)`, so that steps of
//! one size share their kernels (the responses to the force monomials and
//! the free kernels at the nodes, kept per size); the switch locator
//! reads its samples inside a step as the watched coordinates alone (the
//! free motion's projection and the contacts' responses at that fraction
//! of the step, [`ForceCollocation::watched_coordinates`]), or, when it
//! needs whole states (a held stop's reaction), marches them from one
//! propagator per mode ([`ForceCollocation::prefill`]).
//!
//! The dense output is the exact motion under the step's polynomials; at
//! an interior time it has stage order, so a state the outputs read is
//! recomputed by a step of its own ([`ForceCollocation::single_step`]);
//! a switch's Newton iteration then moves that state by its corrections
//! (a small share of a step) with [`ForceCollocation::shift`], the free
//! motion in closed form and the forces as a line between the ends.

use std::sync::Arc;

use nalgebra::DVector;

use super::free::{FreeDynamics, FreeSegment, Projection};

mod dense;
mod kernels;
mod newton;
mod scheme;
mod sensitivity;
mod shift;

use dense::{Memo, Samples};
pub use kernels::StepKernels;
use kernels::{ladder, Projected};
use newton::Scratch;
use scheme::{horner, Scheme};
pub use sensitivity::Replay;

/// The point forces of a phase, each a function of its point's
/// coordinate `p = d . q - gap` and rate `p'`.
pub trait PointForces {
    /// The force of contact `i` with its partials `(F, dF/dp, dF/dp')`.
    fn force(&self, i: usize, p: f64, pd: f64) -> (f64, f64, f64);
    /// The power contact `i` dissipates at `(p, p')` with force `force`.
    fn dissipation_rate(&self, i: usize, p: f64, pd: f64, force: f64) -> f64;
    /// Whether contact `i` is held on its surface (`p = 0`): its force is
    /// then the constraint's reaction, found by collocating `p = 0` at the
    /// nodes instead of a law (`force` is not asked).
    fn held(&self, i: usize) -> bool {
        let _ = i;
        false
    }
    /// `dF/dv` of contact `i` at `(p, p')`, `v` the law's parameter that
    /// depends on the motion (a hysteretic damping's onset speed); zero
    /// for laws without one. Only a flow's Jacobian asks
    /// ([`ForceCollocation::replay_with_jacobian`]).
    fn parameter_partial(&self, i: usize, p: f64, pd: f64) -> f64 {
        let _ = (i, p, pd);
        0.0
    }
}

/// A point contact: coordinate `p = d . q - gap`, its force `F` loads the
/// modes with `-d F`.
#[derive(Clone, Debug)]
pub struct PointContact {
    pub d: DVector<f64>,
    pub gap: f64,
}

/// Step-size control.
#[derive(Clone, Debug)]
pub struct CollocationOptions {
    /// Relative tolerance, and the absolute one in units of the scales.
    pub tol: f64,
    /// Scale of the modal displacements and velocities.
    pub q_scale: f64,
    pub v_scale: f64,
    pub h_init: f64,
    pub h_max: f64,
    /// The last piece of a step onto a corner (a force ending as `t^a`),
    /// as a fraction of the step: `tol^(1/(a+2))` carries the corner's
    /// error to the tolerance ([`ForceCollocation::single_step`]).
    pub corner_fraction: f64,
}

/// Collocation stages (order 8 at step ends).
pub const STAGES: usize = 4;

/// An accepted (or single) step: what the dense output needs.
#[derive(Clone, Debug)]
pub struct Step {
    pub t0: f64,
    pub h: f64,
    y0: DVector<f64>,
    free: FreeSegment,
    /// Per contact, the force polynomial's monomial coefficients in `sigma`.
    force: Vec<Vec<f64>>,
    /// Per contact, the dissipated power's interpolant, likewise.
    dissipation: Vec<Vec<f64>>,
    /// The free motion projected on each contact's coordinate (when
    /// `projected`: not near a harmonic load's resonance).
    projections: Vec<Projection>,
    projected: bool,
}

impl Step {
    /// The state the step started from.
    pub fn start(&self) -> &DVector<f64> {
        &self.y0
    }
}

/// A step that failed: Newton did not converge.
#[derive(Clone, Debug)]
pub struct NewtonFailure;

/// Why the integration stopped.
#[derive(Clone, Debug, PartialEq)]
pub enum CollocationError {
    StepTooSmall { t: f64, h: f64 },
}

impl std::fmt::Display for CollocationError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CollocationError::StepTooSmall { t, h } => {
                write!(f, "force collocation step fell to {h:e} s at t = {t} s")?;
                // Below a step of 1e-15 of t the time cannot resolve it.
                if *h > 1e-300 && 1e-15 * t.abs() >= *h {
                    write!(f, " (below {:.1e} s, the resolution of the time there: a start time nearer 0 resolves finer steps)", 1e-15 * t.abs())?;
                }
                Ok(())
            }
        }
    }
}

/// Force collocation over one integrated phase: integrated state
/// `[q; q'; J; E]` (impulse and dissipated energy per contact).
#[derive(Clone, Debug)]
pub struct ForceCollocation {
    n: usize,
    /// Shared with the phases before and after it where they are the same.
    dynamics: Arc<FreeDynamics>,
    contacts: Vec<PointContact>,
    /// `d_c[j] d_e[j]` at `(c * nc + e) * n + j`.
    dd: Vec<f64>,
    scheme: &'static Scheme,
    options: CollocationOptions,
    t: f64,
    y: DVector<f64>,
    h: f64,
    last: Option<Step>,
    /// States the dense output gave in the last step, by time (the switch
    /// locator asks for values and rates at the same sample points).
    memo: std::cell::RefCell<Memo>,
    /// The coordinates the switch locator reads (`c . q` along each) and
    /// their values at the last step's samples ([`Self::watched_coordinates`]).
    watched: Vec<DVector<f64>>,
    /// `c_j d_j` per watched direction `c` and contact `d`: `[c * nc + d]`.
    watched_weights: Vec<Vec<f64>>,
    /// The contact whose direction each watched one is, if any.
    watched_contact: Vec<Option<usize>>,
    samples: std::cell::RefCell<Samples>,
    /// The kernels of the step sizes used lately (steps take sizes from a
    /// ladder, so that neighbouring steps share them).
    kernels: std::cell::RefCell<Vec<Arc<StepKernels>>>,
    /// The contact responses of those sizes (this phase's contacts).
    projections: std::cell::RefCell<Vec<Arc<Projected>>>,
    /// The last kernels and contact responses of a size not kept (a
    /// landing's), whose storage the next such size reuses.
    unkept_kernels: std::cell::RefCell<Option<Arc<StepKernels>>>,
    unkept_projections: std::cell::RefCell<Option<Arc<Projected>>>,
    scratch: std::cell::RefCell<Scratch>,
    /// The largest `|d_j|` of each contact.
    amax: Vec<f64>,
    /// Accepted and rejected steps.
    pub accepted: u64,
    pub rejected: u64,
    /// Attempted steps of every kind (accepted, rejected, those of
    /// [`Self::single_step`]): the work a caller's cap counts.
    attempts: std::cell::Cell<u64>,
}

/// Ratio of successive pieces of a step onto a corner.
const GRADING: f64 = 4.0;

impl ForceCollocation {
    /// The step-size control it was made with.
    pub fn options(&self) -> &CollocationOptions {
        &self.options
    }

    pub fn new(dynamics: impl Into<Arc<FreeDynamics>>, contacts: Vec<PointContact>, t0: f64, y0: DVector<f64>, options: CollocationOptions) -> Self {
        let dynamics = dynamics.into();
        let n = dynamics.oscillators.len();
        let nc = contacts.len();
        assert_eq!(y0.len(), 2 * n + 2 * nc, "the integrated state is [q; q'; J; E]");
        let mut dd = vec![0.0; nc * nc * n];
        for c in 0..nc {
            for e in 0..nc {
                for j in 0..n {
                    dd[(c * nc + e) * n + j] = contacts[c].d[j] * contacts[e].d[j];
                }
            }
        }
        let h = options.h_init.min(options.h_max);
        let amax = contacts.iter().map(|c| c.d.amax()).collect();
        ForceCollocation { n, dynamics, contacts, dd, scheme: Scheme::shared(), options, t: t0, y: y0, h, last: None, memo: Default::default(), watched: Vec::new(), watched_weights: Vec::new(), watched_contact: Vec::new(), samples: Default::default(), kernels: Default::default(), projections: Default::default(), unkept_kernels: Default::default(), unkept_projections: Default::default(), scratch: Default::default(), amax, accepted: 0, rejected: 0, attempts: Default::default() }
    }

    /// The free dynamics it steps, for a later phase over the same ones
    /// to share (a copy is some 25 vectors at 20 modes).
    pub fn shared_dynamics(&self) -> &Arc<FreeDynamics> {
        &self.dynamics
    }

    /// Steps attempted so far, of every kind.
    pub fn attempts(&self) -> u64 {
        self.attempts.get()
    }

    pub fn t(&self) -> f64 {
        self.t
    }

    pub fn y(&self) -> &DVector<f64> {
        &self.y
    }

    pub fn last_step(&self) -> Option<&Step> {
        self.last.as_ref()
    }

    /// One accepted step from the current point; returns its ends.
    pub fn step(&mut self, forces: &impl PointForces) -> Result<(f64, f64), CollocationError> {
        let order = (self.scheme.s + 2) as f64;
        let t0 = self.t;
        let mut h = self.h.min(self.options.h_max);
        loop {
            h = ladder(h);
            if !(h > 1e-15 * t0.abs().max(1e-300)) || h < 1e-300 {
                return Err(CollocationError::StepTooSmall { t: t0, h });
            }
            match self.attempt(forces, t0, &self.y, h, true) {
                Ok(a) if a.error <= 1.0 => {
                    let grow = if a.error == 0.0 { 4.0 } else { (0.9 * a.error.powf(-1.0 / order)).clamp(0.2, 4.0) };
                    self.h = (h * grow).min(self.options.h_max);
                    self.t = t0 + h;
                    let replaced = std::mem::replace(&mut self.y, a.y1);
                    self.recycle_state(replaced);
                    if let Some(old) = self.last.replace(a.step) {
                        self.recycle(old);
                    }
                    self.memo.borrow_mut().clear();
                    self.accepted += 1;
                    return Ok((t0, self.t));
                }
                Ok(a) => {
                    self.recycle(a.step);
                    self.recycle_state(a.y1);
                    self.rejected += 1;
                    h *= (0.9 * a.error.powf(-1.0 / order)).clamp(0.1, 0.9);
                }
                Err(NewtonFailure) => {
                    self.rejected += 1;
                    h *= 0.25;
                }
            }
        }
    }

    /// The state at `t1` from `(t0, y0)` (a switch or an output time
    /// inside the last step): one step when its error passes, else steps
    /// under error control landing on `t1` (the last before a separation
    /// ends on the force's `t^a` corner, which a step over the whole
    /// interval may miss: [`Self::approach`]). Warm-started from the last
    /// step's force. `corner`: `t1` may be where a force ends (a switch;
    /// see [`Self::near_corner`]).
    pub fn single_step(&self, forces: &impl PointForces, t0: f64, y0: &DVector<f64>, t1: f64, corner: bool) -> Result<DVector<f64>, NewtonFailure> {
        let (t, y) = if corner { self.approach(forces, t0, y0, t1)? } else { (t0, y0.clone()) };
        self.land(forces, t, y, t1)
    }

    /// The state where the last piece of a step onto a corner at `t1`
    /// starts: pieces of 3/4, 3/16, ... of the interval from `(t0, y0)`
    /// toward `t1` down to `tol^(1/(a+2))` of it, the rest left to
    /// [`Self::land`] (where a force ends there as `t^a`, a separation,
    /// a piece that short carries the corner's error to the tolerance).
    /// Each piece is rounded down to the step ladder (whose kernels recur
    /// from switch to switch), so the rest is longer than that fraction,
    /// and the pieces end where the next would be shorter than a quarter
    /// of the time left (it would shorten the rest by less than that):
    /// the rest is 0.4 to 21 % of the interval at HertzStop's separations
    /// at tolerances 1e-8 to 1e-12 (median 12 % at 1e-10), 25 to 37 % at
    /// 1e-4. Without that end, three more pieces per separation took the
    /// rest to 4 to 15 % at 1e-10 for 2 % more instructions over the run,
    /// and the errors moved either way within a factor of 3 (HertzStop at
    /// 20 and 32 modes, 1e-4 to 1e-12). Pieces graded by the time left
    /// instead, the rest within four times the fraction, left HertzStop's
    /// errors at 20 modes within 4 % (1e-4 to 1e-12) and raised those of
    /// 32 modes at 1e-9 and 1e-10 by 38 and 12 %, at 0.3 to 1.2 % more
    /// instructions: not kept. A time near `t1` past that start is
    /// reached by landing from it too.
    pub fn approach(&self, forces: &impl PointForces, t0: f64, y0: &DVector<f64>, t1: f64) -> Result<(f64, DVector<f64>), NewtonFailure> {
        let (mut t, mut y) = (t0, y0.clone());
        let smallest = self.options.corner_fraction;
        let mut remaining = 1.0;
        while remaining / GRADING > smallest && t1 - t > 0.0 {
            let nominal = remaining * (1.0 - 1.0 / GRADING) * (t1 - t0);
            // The pieces rounded down leave more than their rest: one
            // shorter than a quarter of the time left would shorten the
            // land by less than that.
            if nominal < (t1 - t) / GRADING {
                break;
            }
            // A size of the ladder, whose kernels recur from switch to switch.
            let h_try = ladder(nominal);
            let a = self.attempt(forces, t, &y, h_try, true)?;
            (t, y) = (t + h_try, a.y1);
            self.recycle(a.step);
            remaining /= GRADING;
        }
        Ok((t, y))
    }

    /// The state at `t1` from `(t, y)`: one step when its error passes,
    /// else steps under error control landing on `t1`.
    pub fn land(&self, forces: &impl PointForces, mut t: f64, mut y: DVector<f64>, t1: f64) -> Result<DVector<f64>, NewtonFailure> {
        let order = (self.scheme.s + 2) as f64;
        let mut h = t1 - t;
        for _ in 0..1000 {
            let last = t + h >= t1;
            let h_try = if last { t1 - t } else { h };
            match self.attempt(forces, t, &y, h_try, false) {
                Ok(a) if a.error <= 1.0 => {
                    self.recycle(a.step);
                    if last {
                        return Ok(a.y1);
                    }
                    (t, y) = (t + h_try, a.y1);
                    h = h_try * if a.error == 0.0 { 4.0 } else { (0.9 * a.error.powf(-1.0 / order)).clamp(0.2, 4.0) };
                }
                Ok(a) => {
                    self.recycle(a.step);
                    h = h_try * (0.9 * a.error.powf(-1.0 / order)).clamp(0.1, 0.9);
                }
                Err(NewtonFailure) => h = h_try * 0.25,
            }
            if !(h > 1e-15 * t.abs()) {
                break;
            }
        }
        Err(NewtonFailure)
    }

    /// Whether `t` in the last step may lie at or near a force's corner:
    /// some contact's force polynomial there is below a hundredth of its
    /// largest nodal value (a function of the step alone, so a restore
    /// decides alike).
    pub fn near_corner(&self, t: f64) -> bool {
        let Some(l) = &self.last else { return false };
        let sigma = (t - l.t0) / l.h;
        l.force.iter().any(|poly| {
            let peak = self.scheme.c.iter().map(|c| horner(poly, *c).abs()).fold(0.0f64, f64::max);
            horner(poly, sigma) < 0.01 * peak
        })
    }

    fn coordinate(&self, c: usize, y: &DVector<f64>) -> (f64, f64) {
        let n = self.n;
        let d = &self.contacts[c].d;
        (d.dot(&y.rows(0, n)) - self.contacts[c].gap, d.dot(&y.rows(n, n)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::{ModalForcing, Oscillator};

    /// A Hertz-like force `k p^1.5 (1 + c p')` on one point.
    pub(super) struct Hertzian {
        pub(super) k: f64,
        pub(super) c: f64,
    }

    impl PointForces for Hertzian {
        fn force(&self, _i: usize, p: f64, pd: f64) -> (f64, f64, f64) {
            if p <= 0.0 {
                return (0.0, 0.0, 0.0);
            }
            let f = self.k * p.powf(1.5) * (1.0 + self.c * pd);
            if f <= 0.0 {
                return (0.0, 0.0, 0.0);
            }
            (f, 1.5 * self.k * p.sqrt() * (1.0 + self.c * pd), self.k * p.powf(1.5) * self.c)
        }
        fn dissipation_rate(&self, _i: usize, p: f64, pd: f64, force: f64) -> f64 {
            (force - self.k * p.max(0.0).powf(1.5)) * pd
        }
    }

    /// Three modes with a harmonic load and a point pressed into a
    /// Hertzian stop, against RK4 with tiny steps on the full system.
    #[test]
    fn matches_a_fine_explicit_integration() {
        let oscillators = vec![Oscillator::new(3.0, 0.02), Oscillator::new(40.0, 0.02), Oscillator::new(400.0, 0.05)];
        let mut forcing = ModalForcing::zero(3);
        forcing.constant = DVector::from_vec(vec![60.0, -48.0, 36.0]);
        forcing.add_harmonic(5.0, DVector::from_vec(vec![crate::solve::C64::new(1.0, 0.0), crate::solve::C64::new(0.0, 0.3), crate::solve::C64::new(0.1, 0.0)]));
        let dynamics = FreeDynamics::new(oscillators.clone(), forcing.clone());
        let d = DVector::from_vec(vec![1.0, -0.8, 0.6]);
        let law = Hertzian { k: 3e4, c: 0.3 };
        let y0 = DVector::from_vec(vec![0.01, 0.0, 0.0, 0.5, 0.1, -0.2, 0.0, 0.0]);
        let options = CollocationOptions { tol: 1e-10, q_scale: 0.01, v_scale: 0.5, h_init: 1e-4, h_max: 0.05, corner_fraction: 1e-10f64.powf(2.0 / 7.0) };
        let mut col = ForceCollocation::new(dynamics, vec![PointContact { d: d.clone(), gap: 0.0 }], 0.0, y0.clone(), options);
        let t_end = 0.3;
        while col.t() < t_end {
            col.step(&law).unwrap();
        }
        let mut at = DVector::zeros(8);
        let t1 = col.last_step().unwrap().t0 + 0.5 * col.last_step().unwrap().h;
        col.dense(t1, &mut at).unwrap();
        // RK4 on [q; q'; J; E].
        let rhs = |t: f64, y: &[f64]| -> Vec<f64> {
            let mut f = DVector::zeros(3);
            forcing.derivative(t, 0, &mut f);
            let p = d[0] * y[0] + d[1] * y[1] + d[2] * y[2];
            let pd = d[0] * y[3] + d[1] * y[4] + d[2] * y[5];
            let (fc, _, _) = law.force(0, p, pd);
            let mut dy = vec![0.0; 8];
            for j in 0..3 {
                dy[j] = y[3 + j];
                dy[3 + j] = f[j] - 2.0 * oscillators[j].a * y[3 + j] - oscillators[j].omega.powi(2) * y[j] - d[j] * fc;
            }
            dy[6] = fc;
            dy[7] = law.dissipation_rate(0, p, pd, fc);
            dy
        };
        let integrate = |t_stop: f64| -> Vec<f64> {
            let steps = (t_stop / 2e-6).ceil() as usize;
            let dt = t_stop / steps as f64;
            let mut y = y0.as_slice().to_vec();
            for i in 0..steps {
                let t = i as f64 * dt;
                let k1 = rhs(t, &y);
                let y2: Vec<f64> = y.iter().zip(&k1).map(|(a, k)| a + 0.5 * dt * k).collect();
                let k2 = rhs(t + 0.5 * dt, &y2);
                let y3: Vec<f64> = y.iter().zip(&k2).map(|(a, k)| a + 0.5 * dt * k).collect();
                let k3 = rhs(t + 0.5 * dt, &y3);
                let y4: Vec<f64> = y.iter().zip(&k3).map(|(a, k)| a + dt * k).collect();
                let k4 = rhs(t + dt, &y4);
                for k in 0..8 {
                    y[k] += dt / 6.0 * (k1[k] + 2.0 * k2[k] + 2.0 * k3[k] + k4[k]);
                }
            }
            y
        };
        let want = integrate(col.t());
        for k in 0..8 {
            let scale: f64 = if k < 3 { 0.01 } else { 0.5 };
            assert!((col.y()[k] - want[k]).abs() < 1e-9 * scale.max(want[k].abs()), "end, component {k}: {} vs {}", col.y()[k], want[k]);
        }
        // The dense output (stage order) and a single step to the same time (full order).
        let want_mid = integrate(t1);
        let last = col.last_step().unwrap();
        let single = col.single_step(&law, last.t0, &last.y0, t1, false).unwrap();
        for k in 0..6 {
            let scale: f64 = if k < 3 { 0.01 } else { 0.5 };
            assert!((single[k] - want_mid[k]).abs() < 1e-9 * scale, "single step, component {k}: {} vs {}", single[k], want_mid[k]);
            assert!((at[k] - want_mid[k]).abs() < 1e-6 * scale, "dense, component {k}: {} vs {}", at[k], want_mid[k]);
        }
        assert!(col.accepted < 200, "{} steps", col.accepted);
    }

    /// The watched coordinates at the switch locator's samples and at a
    /// time off them against the dense output's whole state there, step
    /// by step (two directions: the contact's and another); at the
    /// samples and off them their accelerations against the dense rate's
    /// central difference.
    #[test]
    fn watched_coordinates_are_the_dense_outputs() {
        let oscillators = vec![Oscillator::new(3.0, 0.02), Oscillator::new(40.0, 0.02), Oscillator::new(400.0, 0.05)];
        let mut forcing = ModalForcing::zero(3);
        forcing.constant = DVector::from_vec(vec![60.0, -48.0, 36.0]);
        forcing.add_harmonic(5.0, DVector::from_vec(vec![crate::solve::C64::new(1.0, 0.0), crate::solve::C64::new(0.0, 0.3), crate::solve::C64::new(0.1, 0.0)]));
        let dynamics = FreeDynamics::new(oscillators, forcing);
        let d = DVector::from_vec(vec![1.0, -0.8, 0.6]);
        let other = DVector::from_vec(vec![0.3, 0.0, -2.0]);
        let law = Hertzian { k: 3e4, c: 0.3 };
        let y0 = DVector::from_vec(vec![0.01, 0.0, 0.0, 0.5, 0.1, -0.2, 0.0, 0.0]);
        let options = CollocationOptions { tol: 1e-8, q_scale: 0.01, v_scale: 0.5, h_init: 1e-4, h_max: 0.05, corner_fraction: 1e-8f64.powf(2.0 / 7.0) };
        let mut col = ForceCollocation::new(dynamics, vec![PointContact { d: d.clone(), gap: 0.0 }], 0.0, y0, options);
        col.watch_directions(vec![d.clone(), other.clone()]);
        let (mut y, mut got) = (DVector::zeros(8), Vec::new());
        let (mut compared, mut worst, mut worst_off_rate, mut worst_acceleration) = (0, 0.0f64, 0.0f64, 0.0f64);
        while col.t() < 0.2 {
            let (t0, t1) = col.step(&law).unwrap();
            let g = crate::solve::switch::grid(t0, t1);
            let mids: Vec<f64> = g.windows(2).map(|w| 0.5 * (w[0] + w[1])).collect();
            for &t in g[1..g.len() - 1].iter().chain(&mids) {
                assert!(col.watched_coordinates(t, &mut got), "sample {t} of [{t0}, {t1}]");
                col.dense(t, &mut y).unwrap();
                // The acceleration against the dense rate's central difference.
                let delta = 1e-4 * (t1 - t0);
                let (mut before, mut after) = (DVector::zeros(8), DVector::zeros(8));
                col.dense(t - delta, &mut before).unwrap();
                col.dense(t + delta, &mut after).unwrap();
                for (i, (c, &(x, v))) in [&d, &other].iter().zip(&got).enumerate() {
                    let (want_x, want_v) = (c.dot(&y.rows(0, 3)), c.dot(&y.rows(3, 3)));
                    let (scale_x, scale_v) = (c.abs().dot(&y.rows(0, 3).abs()), c.abs().dot(&y.rows(3, 3).abs()));
                    worst = worst.max((x - want_x).abs() / scale_x).max((v - want_v).abs() / scale_v);
                    let want_a = (c.dot(&after.rows(3, 3)) - c.dot(&before.rows(3, 3))) / (2.0 * delta);
                    let a = col.watched_acceleration(t, i).expect("inside the step");
                    worst_acceleration = worst_acceleration.max((a - want_a).abs() / want_a.abs().max(scale_v / (t1 - t0)));
                }
                compared += 1;
            }
            // Off the samples too (a zero's refinement), not at the ends,
            // and a few ulps on (read from the same anchor: the rate is
            // the anchor's).
            let t = 0.3 * t0 + 0.7 * t1;
            for t in [t, t + 3.0 * f64::EPSILON * t, t - 7.0 * f64::EPSILON * t] {
                assert!(col.watched_coordinates(t, &mut got));
                col.dense(t, &mut y).unwrap();
                for (i, (c, &(x, v))) in [&d, &other].iter().zip(&got).enumerate() {
                    let (want_x, want_v) = (c.dot(&y.rows(0, 3)), c.dot(&y.rows(3, 3)));
                    let (scale_x, scale_v) = (c.abs().dot(&y.rows(0, 3).abs()), c.abs().dot(&y.rows(3, 3).abs()));
                    worst = worst.max((x - want_x).abs() / scale_x);
                    worst_off_rate = worst_off_rate.max((v - want_v).abs() / scale_v);
                    let delta = 1e-4 * (t1 - t0);
                    let (mut before, mut after) = (DVector::zeros(8), DVector::zeros(8));
                    col.dense(t - delta, &mut before).unwrap();
                    col.dense(t + delta, &mut after).unwrap();
                    let want_a = (c.dot(&after.rows(3, 3)) - c.dot(&before.rows(3, 3))) / (2.0 * delta);
                    let a = col.watched_acceleration(t, i).expect("inside the step");
                    worst_acceleration = worst_acceleration.max((a - want_a).abs() / want_a.abs().max(scale_v / (t1 - t0)));
                }
            }
            assert!(!col.watched_coordinates(t1, &mut got) && !col.watched_coordinates(t0, &mut got), "the step's ends are not inside it");
        }
        assert!(worst <= 1e-12, "{worst:e} of the terms' size");
        // The anchor's rate, off by the acceleration over 2^-41 of t.
        assert!(worst_off_rate <= 1e-9, "rates off the samples: {worst_off_rate:e} of the terms' size");
        assert!(worst_acceleration <= 1e-6, "accelerations: {worst_acceleration:e}");
        assert!(compared > 100, "{compared} samples");
    }
}


