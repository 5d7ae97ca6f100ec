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
//! carried by the estimate. An onset starts with a step of `tol^(2/7)` of
//! the contact's scale, and a state at a switch is reached by pieces
//! shrinking toward it ([`ForceCollocation::single_step`]): a separation
//! ends the force in a `p^1.5` corner no defect estimate sees.
//!
//! **Cost.** Step sizes come from a ladder of `2^(1/4)`, so that steps of
//! one size share their kernels (the responses to the force monomials and
//! the free kernels at the nodes, kept per size); the switch locator's
//! samples are marched from one propagator per mode.
//!
//! The dense output is the exact motion under the step's polynomials; at
//! an interior time it has stage order, so a state the outputs read is
//! recomputed by a step of its own ([`ForceCollocation::single_step`]).

use std::sync::Arc;

use nalgebra::{DMatrix, DVector};

use super::free::{FreeDynamics, FreeSegment};
use super::modal_state::ModalState;
use super::phi::phi_columns;
use super::switch::SAMPLES;

/// The point forces of a phase, each a function of its point's
/// coordinate `p = d . q - gap` and rate `p'`.
pub trait PointForces {
    /// The force of contact `i` with its partials `(F, dF/dp, dF/dp')`.
    fn force(&self, i: usize, p: f64, pd: f64) -> (f64, f64, f64);
    /// The power contact `i` dissipates at `(p, p')` with force `force`.
    fn dissipation_rate(&self, i: usize, p: f64, pd: f64, force: f64) -> f64;
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

/// Gauss-Legendre nodes on `[0, 1]` and the polynomials built on them.
#[derive(Clone, Debug)]
struct Scheme {
    s: usize,
    c: Vec<f64>,
    b: Vec<f64>,
    /// Monomial coefficients of the Lagrange basis: `vinv[m * s + k]` is
    /// the coefficient of `sigma^m` in `l_k`.
    vinv: Vec<f64>,
    /// Monomial coefficients of `w_s(sigma) = prod (sigma - c_i)`.
    node_poly: Vec<f64>,
}

/// Collocation stages (order 8 at step ends).
pub const STAGES: usize = 4;

impl Scheme {
    fn gauss(s: usize) -> Self {
        let (x, w): (Vec<f64>, Vec<f64>) = match s {
            3 => (vec![-0.7745966692414834, 0.0, 0.7745966692414834], vec![5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0]),
            4 => (
                vec![-0.8611363115940526, -0.3399810435848563, 0.3399810435848563, 0.8611363115940526],
                vec![0.3478548451374538, 0.6521451548625461, 0.6521451548625461, 0.3478548451374538],
            ),
            5 => (
                vec![-0.906179845938664, -0.5384693101056831, 0.0, 0.5384693101056831, 0.906179845938664],
                vec![0.2369268850561891, 0.4786286704993665, 0.5688888888888889, 0.4786286704993665, 0.2369268850561891],
            ),
            6 => (
                vec![-0.9324695142031521, -0.6612093864662645, -0.2386191860831909, 0.2386191860831909, 0.6612093864662645, 0.9324695142031521],
                vec![0.1713244923791704, 0.3607615730481386, 0.467913934572691, 0.467913934572691, 0.3607615730481386, 0.1713244923791704],
            ),
            _ => panic!("Gauss-Legendre nodes for 3 to 6 stages only"),
        };
        let c: Vec<f64> = x.iter().map(|x| 0.5 * (1.0 + x)).collect();
        let b: Vec<f64> = w.iter().map(|w| 0.5 * w).collect();
        let v = DMatrix::from_fn(s, s, |i, m| c[i].powi(m as i32));
        let inv = v.try_inverse().expect("distinct nodes");
        // inv[(m, k)]: coefficient m of the polynomial that is 1 at node k.
        let vinv = (0..s * s).map(|idx| inv[(idx / s, idx % s)]).collect();
        let mut node_poly = vec![1.0];
        for ci in &c {
            let mut next = vec![0.0; node_poly.len() + 1];
            for (m, a) in node_poly.iter().enumerate() {
                next[m + 1] += a;
                next[m] -= ci * a;
            }
            node_poly = next;
        }
        Scheme { s, c, b, vinv, node_poly }
    }

    /// Monomial coefficients `alpha[m] = sum_k vinv[m][k] values[k]`.
    fn monomials(&self, values: &[f64], out: &mut [f64]) {
        let s = self.s;
        for (m, o) in out.iter_mut().enumerate() {
            *o = (0..s).map(|k| self.vinv[m * s + k] * values[k]).sum();
        }
    }
}

fn horner(coeffs: &[f64], x: f64) -> f64 {
    coeffs.iter().rev().fold(0.0, |acc, a| acc * x + a)
}

/// The coefficients in `u` of `p(sigma + ratio u)`, `p` given by its
/// monomial coefficients.
fn taylor_shift(p: &[f64], sigma: f64, ratio: f64, out: &mut [f64]) {
    // Horner in the shifted variable: synthetic division by (x - sigma).
    out.copy_from_slice(p);
    let d = out.len();
    for i in 0..d {
        for k in (i..d - 1).rev() {
            out[k] += sigma * out[k + 1];
        }
    }
    let mut scale = 1.0;
    for o in out.iter_mut() {
        *o *= scale;
        scale *= ratio;
    }
}

/// A small dense LU with partial pivoting, in place (the Newton matrix
/// of one step: 4 rows per contact).
#[derive(Clone, Debug, Default)]
struct SmallLu {
    n: usize,
    a: Vec<f64>,
    pivots: Vec<usize>,
}

impl SmallLu {
    /// Room for an `n x n` matrix.
    fn resize(&mut self, n: usize) {
        self.n = n;
        self.a.resize(n * n, 0.0);
        self.pivots.resize(n, 0);
    }

    /// Factors `a`; `false` when singular.
    fn factor(&mut self) -> bool {
        let n = self.n;
        for k in 0..n {
            let p = (k..n).max_by(|&i, &j| self.a[i * n + k].abs().total_cmp(&self.a[j * n + k].abs())).expect("a row");
            if !(self.a[p * n + k].abs() > 0.0) {
                return false;
            }
            self.pivots[k] = p;
            if p != k {
                for c in 0..n {
                    self.a.swap(k * n + c, p * n + c);
                }
            }
            let pivot = self.a[k * n + k];
            for i in k + 1..n {
                let factor = self.a[i * n + k] / pivot;
                self.a[i * n + k] = factor;
                for c in k + 1..n {
                    self.a[i * n + c] -= factor * self.a[k * n + c];
                }
            }
        }
        true
    }

    /// `b <- A^-1 b`.
    fn solve(&self, b: &mut [f64]) {
        let n = self.n;
        for k in 0..n {
            b.swap(k, self.pivots[k]);
        }
        for i in 0..n {
            let s: f64 = (0..i).map(|c| self.a[i * n + c] * b[c]).sum();
            b[i] -= s;
        }
        for i in (0..n).rev() {
            let s: f64 = (i + 1..n).map(|c| self.a[i * n + c] * b[c]).sum();
            b[i] = (b[i] - s) / self.a[i * n + i];
        }
    }
}

/// `int_0^sigma` of the polynomial with monomial coefficients `coeffs`.
fn integral(coeffs: &[f64], sigma: f64) -> f64 {
    coeffs.iter().enumerate().rev().fold(0.0, |acc, (m, a)| acc * sigma + a / (m + 1) as f64) * sigma
}

/// Intervals of the switch locator's grid (its samples).
const GRID: usize = SAMPLES;
/// Kernel sets kept.
const KERNEL_SETS: usize = 48;
/// Step sizes are powers of `2^(1 / LADDER)`.
const LADDER: f64 = 4.0;

/// The largest step size of the ladder not above `h`.
fn ladder(h: f64) -> f64 {
    (f64::floor(h.log2() * LADDER) / LADDER).exp2()
}

/// What every step of one size needs, mode by mode: the responses to the
/// force monomials and the free kernels at the nodes and the end, and for
/// the switch grid the propagator over a grid interval.
#[derive(Debug)]
pub struct StepKernels {
    h: f64,
    /// `R[(i * n + j) * (s + 2) + m]`: mode `j`'s response at point `i`
    /// (the nodes, then the end) to `sigma^m` from rest, `m = 0..=s`.
    responses: Vec<[f64; 2]>,
    /// `(Ec, Es)` at point `i`: `[i * n + j]`.
    free: Vec<(f64, f64)>,
    /// Per mode, `e^{A h / GRID}` by rows.
    grid_propagator: Vec<[f64; 4]>,
    /// `[j * s + m]`: the response over a grid interval to `u^m`.
    grid_responses: Vec<[f64; 2]>,
    /// `(Ec, Es)` at `k h / GRID`: `[(k - 1) * n + j]`, `k = 1..=GRID`.
    grid_free: Vec<(f64, f64)>,
}

/// `(Ec, Es)` from `phi_0(tau A) b = (Es, Ec - a Es)`.
fn kernels_of(phi0: [f64; 2], a: f64) -> (f64, f64) {
    (phi0[1] + a * phi0[0], phi0[0])
}

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
            CollocationError::StepTooSmall { t, h } => write!(f, "force collocation step fell to {h:e} s at t = {t} s"),
        }
    }
}

/// The contact coordinates' responses for one step size.
#[derive(Debug)]
struct Projected {
    h: f64,
    /// To the force monomials, at the nodes and the end:
    /// `[((c * nc + e) * (s + 1) + i) * (s + 2) + m]` (position, rate).
    sm: Vec<[f64; 2]>,
    /// To the nodal forces, at the nodes: `[(c, i), (e, k)]`.
    mp: DMatrix<f64>,
    mv: DMatrix<f64>,
}

/// Working arrays of [`ForceCollocation::attempt`], kept between steps.
#[derive(Clone, Debug, Default)]
struct Scratch {
    pf: Vec<f64>,
    pdf: Vec<f64>,
    f: DVector<f64>,
    p: DVector<f64>,
    pd: DVector<f64>,
    law: Vec<(f64, f64, f64)>,
    lu: SmallLu,
    residual: Vec<f64>,
    defect: Vec<f64>,
    drive: Vec<f64>,
    fb: Vec<f64>,
    /// The step's start and the free motion at its points.
    start: ModalState,
    end: ModalState,
    /// A step whose storage the next attempt reuses (a rejected attempt's,
    /// the last accepted step once replaced).
    spare: Option<Step>,
}

/// Dense states by time, the oldest overwritten first; cleared without
/// freeing (a step's worth of states is refilled every step).
#[derive(Clone, Debug, Default)]
struct Memo {
    slots: Vec<(f64, DVector<f64>)>,
    next: usize,
}

impl Memo {
    fn clear(&mut self) {
        self.slots.iter_mut().for_each(|s| s.0 = f64::NAN);
        self.next = 0;
    }

    fn find(&self, t: f64) -> Option<&DVector<f64>> {
        self.slots.iter().find(|(tm, _)| *tm == t).map(|(_, y)| y)
    }

    /// The storage for the state at `t` (every entry set by the caller).
    fn slot(&mut self, t: f64, dim: usize) -> &mut DVector<f64> {
        let k = self.next;
        self.next = (k + 1) % MEMO;
        if k == self.slots.len() {
            self.slots.push((t, DVector::zeros(dim)));
        }
        let slot = &mut self.slots[k];
        slot.0 = t;
        if slot.1.len() != dim {
            slot.1 = DVector::zeros(dim);
        }
        &mut slot.1
    }
}

/// `v` as `len` zeros (no allocation once the size is known).
fn reset(v: &mut Vec<f64>, len: usize) {
    v.clear();
    v.resize(len, 0.0);
}

/// Everything one attempted step computes.
struct Attempt {
    y1: DVector<f64>,
    step: Step,
    error: f64,
}

/// Force collocation over one integrated phase: integrated state
/// `[q; q'; J; E]` (impulse and dissipated energy per contact).
#[derive(Clone, Debug)]
pub struct ForceCollocation {
    n: usize,
    dynamics: FreeDynamics,
    contacts: Vec<PointContact>,
    /// `d_c[j] d_e[j]` at `(c * nc + e) * n + j`.
    dd: Vec<f64>,
    scheme: Scheme,
    options: CollocationOptions,
    t: f64,
    y: DVector<f64>,
    h: f64,
    last: Option<Step>,
    /// States the dense output gave in the last step, by time (the switch
    /// locator asks for values and rates at the same sample points).
    memo: std::cell::RefCell<Memo>,
    /// The kernels of the step sizes used lately (steps take sizes from a
    /// ladder, so that neighbouring steps share them).
    kernels: std::cell::RefCell<Vec<Arc<StepKernels>>>,
    /// The contact responses of those sizes (this phase's contacts).
    projections: std::cell::RefCell<Vec<Arc<Projected>>>,
    scratch: std::cell::RefCell<Scratch>,
    /// The largest `|d_j|` of each contact.
    amax: Vec<f64>,
    /// Accepted and rejected steps.
    pub accepted: u64,
    pub rejected: u64,
}

/// Newton's convergence: the last correction moves every contact
/// coordinate by less than this fraction of the tolerance.
const NEWTON_FRACTION: f64 = 1e-3;
const NEWTON_ITERATIONS: usize = 12;
/// Ratio of successive pieces of a step onto a corner.
const GRADING: f64 = 4.0;
/// Dense states remembered per step: the switch locator's samples and
/// midpoints.
const MEMO: usize = 48;

impl ForceCollocation {
    pub fn new(dynamics: FreeDynamics, contacts: Vec<PointContact>, t0: f64, y0: DVector<f64>, options: CollocationOptions) -> Self {
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
        ForceCollocation { n, dynamics, contacts, dd, scheme: Scheme::gauss(STAGES), options, t: t0, y: y0, h, last: None, memo: Default::default(), kernels: Default::default(), projections: Default::default(), scratch: Default::default(), amax, accepted: 0, rejected: 0 }
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
        let (t0, y0) = (self.t, self.y.clone());
        let mut h = self.h.min(self.options.h_max);
        loop {
            h = ladder(h);
            if !(h > 1e-15 * t0.abs().max(1e-300)) || h < 1e-300 {
                return Err(CollocationError::StepTooSmall { t: t0, h });
            }
            let guess = self.guess(forces, t0, &y0, h);
            match self.attempt(forces, t0, &y0, h, &guess, true) {
                Ok(a) if a.error <= 1.0 => {
                    let grow = if a.error == 0.0 { 4.0 } else { (0.9 * a.error.powf(-1.0 / order)).clamp(0.2, 4.0) };
                    self.h = (h * grow).min(self.options.h_max);
                    self.t = t0 + h;
                    self.y = a.y1;
                    if let Some(old) = self.last.replace(a.step) {
                        self.recycle(old);
                    }
                    self.memo.borrow_mut().clear();
                    self.accepted += 1;
                    return Ok((t0, self.t));
                }
                Ok(a) => {
                    self.recycle(a.step);
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
    /// ends on the force's `p^1.5` corner, which a step over the whole
    /// interval may miss). Warm-started from the last step's force.
    /// `corner`: `t1` may be where a force ends (a switch; see
    /// [`Self::near_corner`]).
    pub fn single_step(&self, forces: &impl PointForces, t0: f64, y0: &DVector<f64>, t1: f64, corner: bool) -> Result<DVector<f64>, NewtonFailure> {
        let order = (self.scheme.s + 2) as f64;
        let (mut t, mut y) = (t0, y0.clone());
        // Pieces shrinking fourfold toward a corner at t1: where a force
        // ends there as t^a (a separation), the last, tol^(1/(a+2)) of
        // the interval long, carries the corner's error to the tolerance.
        let smallest = if corner { self.options.corner_fraction } else { 1.0 };
        let mut remaining = 1.0;
        while remaining / GRADING > smallest && t1 - t > 0.0 {
            // A size of the ladder, whose kernels recur from switch to switch.
            let h_try = ladder(remaining * (1.0 - 1.0 / GRADING) * (t1 - t0));
            let guess = self.guess(forces, t, &y, h_try);
            let a = self.attempt(forces, t, &y, h_try, &guess, true)?;
            (t, y) = (t + h_try, a.y1);
            self.recycle(a.step);
            remaining /= GRADING;
        }
        let mut h = t1 - t;
        for _ in 0..1000 {
            let last = t + h >= t1;
            let h_try = if last { t1 - t } else { h };
            let guess = self.guess(forces, t, &y, h_try);
            match self.attempt(forces, t, &y, h_try, &guess, false) {
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

    /// Keeps `step`'s storage for the next attempt.
    fn recycle(&self, step: Step) {
        self.scratch.borrow_mut().spare = Some(step);
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

    /// Nodal forces to start Newton from: the last step's polynomial where
    /// it covers the node, else the force at `t0` continued by its slope.
    fn guess(&self, forces: &impl PointForces, t0: f64, y0: &DVector<f64>, h: f64) -> Vec<f64> {
        let (s, nc) = (self.scheme.s, self.contacts.len());
        let mut g = vec![0.0; nc * s];
        for c in 0..nc {
            let (p, pd) = self.coordinate(c, y0);
            let f0 = forces.force(c, p, pd).0;
            for i in 0..s {
                let t = t0 + self.scheme.c[i] * h;
                g[c * s + i] = match &self.last {
                    Some(l) if t >= l.t0 && t <= l.t0 + l.h => horner(&l.force[c], (t - l.t0) / l.h),
                    Some(l) => {
                        let poly = &l.force[c];
                        let slope: f64 = poly.iter().enumerate().skip(1).map(|(m, a)| m as f64 * a).sum::<f64>() / l.h;
                        (f0 + slope * (t - t0)).max(0.0)
                    }
                    None => f0,
                };
            }
        }
        g
    }

    fn coordinate(&self, c: usize, y: &DVector<f64>) -> (f64, f64) {
        let n = self.n;
        let d = &self.contacts[c].d;
        (d.dot(&y.rows(0, n)) - self.contacts[c].gap, d.dot(&y.rows(n, n)))
    }

    /// The kernels of steps of size `h`: from the ladder's cache, or
    /// computed (with the grid's when `grid`, and kept).
    fn kernels_for(&self, h: f64, grid: bool) -> Arc<StepKernels> {
        if let Some(k) = self.kernels.borrow().iter().find(|k| k.h == h && (!grid || !k.grid_free.is_empty())) {
            return k.clone();
        }
        let (n, s) = (self.n, self.scheme.s);
        let points: Vec<f64> = self.scheme.c.iter().map(|c| c * h).chain(std::iter::once(h)).collect();
        let mono = s + 2;
        let mut responses = vec![[0.0; 2]; points.len() * n * mono];
        let mut free = vec![(0.0, 0.0); points.len() * n];
        let mut phis = [[0.0; 2]; 8];
        for (i, &tau) in points.iter().enumerate() {
            let sigma = tau / h;
            for (j, osc) in self.dynamics.oscillators.iter().enumerate() {
                phi_columns(osc, tau, &mut phis[..mono + 1]);
                free[i * n + j] = kernels_of(phis[0], osc.a);
                // m! sigma^m tau phi_{m+1}.
                let mut factor = tau;
                let base = (i * n + j) * mono;
                for m in 0..mono {
                    responses[base + m] = [factor * phis[m + 1][0], factor * phis[m + 1][1]];
                    factor *= sigma * (m + 1) as f64;
                }
            }
        }
        let (mut grid_propagator, mut grid_responses, mut grid_free) = (Vec::new(), Vec::new(), Vec::new());
        if grid {
            let delta = h / GRID as f64;
            grid_propagator = vec![[0.0; 4]; n];
            grid_responses = vec![[0.0; 2]; n * s];
            grid_free = vec![(0.0, 0.0); GRID * n];
            for (j, osc) in self.dynamics.oscillators.iter().enumerate() {
                phi_columns(osc, delta, &mut phis[..s + 1]);
                let (ec, es) = kernels_of(phis[0], osc.a);
                grid_propagator[j] = [ec + osc.a * es, es, -osc.omega * osc.omega * es, ec - osc.a * es];
                let mut factor = delta;
                for m in 0..s {
                    grid_responses[j * s + m] = [factor * phis[m + 1][0], factor * phis[m + 1][1]];
                    factor *= (m + 1) as f64;
                }
                for k in 1..=GRID {
                    grid_free[(k - 1) * n + j] = osc.kernels(k as f64 * delta);
                }
            }
        }
        let kernels = Arc::new(StepKernels { h, responses, free, grid_propagator, grid_responses, grid_free });
        if grid {
            let mut cache = self.kernels.borrow_mut();
            cache.retain(|k| k.h != h);
            if cache.len() >= KERNEL_SETS {
                cache.remove(0);
            }
            cache.push(kernels.clone());
        }
        kernels
    }

    /// The contact coordinates' responses to the contacts' forces for the
    /// step size of `kernels`, remembered for the sizes of the ladder.
    fn projected_for(&self, kernels: &Arc<StepKernels>, cached: bool) -> Arc<Projected> {
        let h = kernels.h;
        if let Some(p) = self.projections.borrow().iter().find(|p| p.h == h) {
            return p.clone();
        }
        let (n, s, nc) = (self.n, self.scheme.s, self.contacts.len());
        let ns = nc * s;
        let mono = s + 2;
        let r = &kernels.responses;
        // Monomial responses of the contact coordinates: S[((c * nc + e) * (s + 1) + i) * mono + m].
        let mut sm = vec![[0.0; 2]; nc * nc * (s + 1) * mono];
        for c in 0..nc {
            for e in 0..nc {
                let dd = &self.dd[(c * nc + e) * n..(c * nc + e + 1) * n];
                for i in 0..=s {
                    for m in 0..mono {
                        let (mut x, mut v) = (0.0, 0.0);
                        for (j, w) in dd.iter().enumerate() {
                            let rr = r[(i * n + j) * mono + m];
                            x -= w * rr[0];
                            v -= w * rr[1];
                        }
                        sm[((c * nc + e) * (s + 1) + i) * mono + m] = [x, v];
                    }
                }
            }
        }
        // In the nodal basis at the nodes: mp[(c, i), (e, k)], mv likewise.
        let mut mp = DMatrix::zeros(ns, ns);
        let mut mv = DMatrix::zeros(ns, ns);
        for c in 0..nc {
            for e in 0..nc {
                for i in 0..s {
                    for k in 0..s {
                        let (mut x, mut v) = (0.0, 0.0);
                        for m in 0..s {
                            let a = self.scheme.vinv[m * s + k];
                            let smv = sm[((c * nc + e) * (s + 1) + i) * mono + m];
                            x += a * smv[0];
                            v += a * smv[1];
                        }
                        mp[(c * s + i, e * s + k)] = x;
                        mv[(c * s + i, e * s + k)] = v;
                    }
                }
            }
        }
        let projected = Arc::new(Projected { h, sm, mp, mv });
        if cached {
            let mut cache = self.projections.borrow_mut();
            if cache.len() >= KERNEL_SETS {
                cache.remove(0);
            }
            cache.push(projected.clone());
        }
        projected
    }

    /// The kernel sets of another stepper over the same structure (the
    /// previous contact phase's): its step sizes recur.
    pub fn adopt_kernels(&mut self, other: &ForceCollocation) {
        if other.dynamics.oscillators == self.dynamics.oscillators && other.scheme.s == self.scheme.s {
            *self.kernels.borrow_mut() = other.kernels.borrow().clone();
        }
    }

    /// One step of size `h` (`cached`: a size of the ladder, whose kernels
    /// are kept).
    fn attempt(&self, forces: &impl PointForces, t0: f64, y0: &DVector<f64>, h: f64, guess: &[f64], cached: bool) -> Result<Attempt, NewtonFailure> {
        let (n, s, nc) = (self.n, self.scheme.s, self.contacts.len());
        let ns = nc * s;
        let kernels = self.kernels_for(h, cached);
        let r = &kernels.responses;
        let mut guard = self.scratch.borrow_mut();
        let Scratch { pf, pdf, f, p, pd, law, lu, residual, defect, drive, fb, start, end, spare } = &mut *guard;
        if start.q.len() != n {
            (*start, *end) = (ModalState::zeros(n), ModalState::zeros(n));
        }
        start.q.copy_from(&y0.rows(0, n));
        start.qd.copy_from(&y0.rows(n, n));
        // The storage of a spare step, else new.
        let (mut free, mut force, mut dissipation, mut y0_copy) = match spare.take() {
            Some(Step { free, force, dissipation, y0: copy, .. }) => (free, force, dissipation, copy),
            None => (FreeSegment::new(&self.dynamics, t0, start), Vec::new(), Vec::new(), y0.clone()),
        };
        free.reset(&self.dynamics, t0, start);
        if y0_copy.len() == y0.len() {
            y0_copy.copy_from(y0);
        } else {
            y0_copy = y0.clone();
        }
        // Free motion of the contact coordinates at the points; the
        // state at the last (the step's end) is kept.
        reset(pf, nc * (s + 1));
        reset(pdf, nc * (s + 1));
        for i in 0..=s {
            let tau = if i < s { self.scheme.c[i] * h } else { h };
            free.state_with_kernels(&self.dynamics, t0 + tau, &kernels.free[i * n..(i + 1) * n], end);
            for c in 0..nc {
                let d = &self.contacts[c].d;
                pf[c * (s + 1) + i] = d.dot(&end.q) - self.contacts[c].gap;
                pdf[c * (s + 1) + i] = d.dot(&end.qd);
            }
        }
        let mono = s + 2;
        let projected = self.projected_for(&kernels, cached);
        let (sm, mp, mv) = (&projected.sm, &projected.mp, &projected.mv);
        // Newton on the nodal forces.
        let tol = self.options.tol;
        let p_tol = |c: usize| NEWTON_FRACTION * tol * self.options.q_scale * self.amax[c];
        let v_tol = |c: usize| NEWTON_FRACTION * tol * self.options.v_scale * self.amax[c];
        if f.len() != ns {
            *f = DVector::zeros(ns);
            *p = DVector::zeros(ns);
            *pd = DVector::zeros(ns);
        }
        f.copy_from_slice(guess);
        law.clear();
        law.resize(ns, (0.0, 0.0, 0.0));
        lu.resize(ns);
        reset(residual, ns);
        let mut converged = false;
        for _ in 0..NEWTON_ITERATIONS {
            mp.mul_to(f, p);
            mv.mul_to(f, pd);
            for c in 0..nc {
                for i in 0..s {
                    let row = c * s + i;
                    p[row] += pf[c * (s + 1) + i];
                    pd[row] += pdf[c * (s + 1) + i];
                    law[row] = forces.force(c, p[row], pd[row]);
                }
            }
            for row in 0..ns {
                let (fl, dp, dpd) = law[row];
                residual[row] = f[row] - fl;
                for col in 0..ns {
                    lu.a[row * ns + col] = if row == col { 1.0 } else { 0.0 } - (dp * mp[(row, col)] + dpd * mv[(row, col)]);
                }
            }
            if !lu.factor() {
                return Err(NewtonFailure);
            }
            lu.solve(residual);
            if !residual.iter().all(|x| x.is_finite()) {
                return Err(NewtonFailure);
            }
            // The correction and its effect on the contact coordinates.
            let mut small = true;
            for row in 0..ns {
                f[row] -= residual[row];
                let (mut dp, mut dv) = (0.0, 0.0);
                for col in 0..ns {
                    dp += mp[(row, col)] * residual[col];
                    dv += mv[(row, col)] * residual[col];
                }
                small &= dp.abs() <= p_tol(row / s) && dv.abs() <= v_tol(row / s);
            }
            if small {
                converged = true;
                break;
            }
        }
        if !converged {
            return Err(NewtonFailure);
        }
        // The converged nodes: coordinates, dissipated power.
        mp.mul_to(f, p);
        mv.mul_to(f, pd);
        force.resize_with(nc, Vec::new);
        dissipation.resize_with(nc, Vec::new);
        let mut y1 = DVector::zeros(2 * n + 2 * nc);
        for c in 0..nc {
            let (alpha, beta) = (&mut force[c], &mut dissipation[c]);
            alpha.resize(s, 0.0);
            beta.resize(s, 0.0);
            let mut nodal = [0.0; STAGES];
            let mut power = [0.0; STAGES];
            for i in 0..s {
                let row = c * s + i;
                nodal[i] = f[row];
                power[i] = forces.dissipation_rate(c, p[row] + pf[c * (s + 1) + i], pd[row] + pdf[c * (s + 1) + i], f[row]);
            }
            self.scheme.monomials(&nodal[..s], alpha);
            self.scheme.monomials(&power[..s], beta);
            y1[2 * n + c] = y0[2 * n + c] + h * (0..s).map(|i| self.scheme.b[i] * nodal[i]).sum::<f64>();
            y1[2 * n + nc + c] = y0[2 * n + nc + c] + h * (0..s).map(|i| self.scheme.b[i] * power[i]).sum::<f64>();
        }
        // The end state: free motion plus every mode's response.
        for j in 0..n {
            let (mut x, mut v) = (end.q[j], end.qd[j]);
            let base = (s * n + j) * mono;
            for (c, alpha) in force.iter().enumerate() {
                let dj = self.contacts[c].d[j];
                for (m, a) in alpha.iter().enumerate() {
                    let rr = r[base + m];
                    x -= dj * a * rr[0];
                    v -= dj * a * rr[1];
                }
            }
            y1[j] = x;
            y1[n + j] = v;
        }
        // Error: the defect at the ends as `w_s(sigma) (D0 (1 - sigma) +
        // D1 sigma)`: the same `D` at both ends where the force is smooth
        // (the superconvergent estimate), different ones where it is not
        // (an onset's `p^1.5`), whose response the estimate then carries.
        let w_end = horner(&self.scheme.node_poly, 1.0);
        let w_start = horner(&self.scheme.node_poly, 0.0);
        reset(defect, nc * mono);
        for c in 0..nc {
            let (p1, pd1) = self.coordinate(c, &y1);
            let (p0, pd0) = self.coordinate(c, y0);
            let d1 = (forces.force(c, p1, pd1).0 - horner(&force[c], 1.0)) / w_end;
            let d0 = (forces.force(c, p0, pd0).0 - horner(&force[c], 0.0)) / w_start;
            for (m, w) in self.scheme.node_poly.iter().enumerate() {
                defect[c * mono + m] += d0 * w;
                defect[c * mono + m + 1] += (d1 - d0) * w;
            }
        }
        // The nodes' response to the defect, fed back through the contacts.
        reset(drive, ns);
        for c in 0..nc {
            for i in 0..s {
                let row = c * s + i;
                let (dp, dpd) = (law[row].1, law[row].2);
                let (mut x, mut v) = (0.0, 0.0);
                for (e, poly) in defect.chunks_exact(mono).enumerate() {
                    for (m, w) in poly.iter().enumerate() {
                        let smv = sm[((c * nc + e) * (s + 1) + i) * mono + m];
                        x += w * smv[0];
                        v += w * smv[1];
                    }
                }
                drive[row] = dp * x + dpd * v;
            }
        }
        lu.solve(drive);
        let mut error: f64 = 0.0;
        let mut coef = [0.0; STAGES + 2];
        reset(fb, ns);
        for c in 0..nc {
            self.scheme.monomials(&drive[c * s..(c + 1) * s], &mut fb[c * s..(c + 1) * s]);
        }
        for j in 0..n {
            coef.iter_mut().for_each(|x| *x = 0.0);
            for c in 0..nc {
                let dj = self.contacts[c].d[j];
                for m in 0..mono {
                    coef[m] -= dj * (defect[c * mono + m] + if m < s { fb[c * s + m] } else { 0.0 });
                }
            }
            let base = (s * n + j) * mono;
            let (mut x, mut v) = (0.0, 0.0);
            for m in 0..mono {
                x += coef[m] * r[base + m][0];
                v += coef[m] * r[base + m][1];
            }
            let sq = tol * (self.options.q_scale + y1[j].abs().max(y0[j].abs()));
            let sv = tol * (self.options.v_scale + y1[n + j].abs().max(y0[n + j].abs()));
            error = error.max(x.abs() / sq).max(v.abs() / sv);
        }
        if !error.is_finite() || !y1.iter().all(|x| x.is_finite()) {
            return Err(NewtonFailure);
        }
        Ok(Attempt { y1, step: Step { t0, h, y0: y0_copy, free, force, dissipation }, error })
    }

    /// The integrated state at `t` in the last step under its
    /// polynomials (the step's start before the first step: `None`).
    pub fn dense(&self, t: f64, out: &mut DVector<f64>) -> Option<()> {
        let l = self.last.as_ref()?;
        if !(t >= l.t0 && t <= l.t0 + l.h) {
            return None;
        }
        if t == self.t {
            out.copy_from(&self.y);
            return Some(());
        }
        if let Some(y) = self.memo.borrow().find(t) {
            out.copy_from(y);
            return Some(());
        }
        self.evaluate(l, t, out);
        self.memo.borrow_mut().slot(t, out.len()).copy_from(out);
        Some(())
    }

    /// Prepares the dense states at `times` in the last step, close to
    /// equally spaced from its start (the switch locator's grid): the
    /// contact response is marched from point to point (one propagator
    /// per mode for the whole grid), the free motion taken from the
    /// segment.
    pub fn prefill(&self, times: &[f64]) {
        let Some(l) = self.last.as_ref() else { return };
        let (n, s, nc) = (self.n, self.scheme.s, self.contacts.len());
        let intervals = times.len().saturating_sub(1);
        if intervals == 0 || times[0] != l.t0 {
            return;
        }
        if intervals != GRID {
            return;
        }
        let ratio = 1.0 / intervals as f64;
        let kernels = self.kernels_for(l.h, true);
        let (prop, resp) = (&kernels.grid_propagator, &kernels.grid_responses);
        let mut z = vec![[0.0; 2]; n];
        let mut shifted = vec![vec![0.0; s]; nc];
        let mut st = ModalState::zeros(n);
        let mut memo = self.memo.borrow_mut();
        for (k, &t) in times.iter().enumerate() {
            if k > 0 {
                // The load over [tau_{k-1}, tau_k] in u = (tau - tau_{k-1}) / delta.
                let sigma = (k - 1) as f64 * ratio;
                for (c, alpha) in l.force.iter().enumerate() {
                    taylor_shift(alpha, sigma, ratio, &mut shifted[c]);
                }
                for j in 0..n {
                    let e = prop[j];
                    let (x, v) = (z[j][0], z[j][1]);
                    let mut next = [e[0] * x + e[1] * v, e[2] * x + e[3] * v];
                    for (c, gamma) in shifted.iter().enumerate() {
                        let dj = self.contacts[c].d[j];
                        for m in 0..s {
                            let r = resp[j * s + m];
                            next[0] -= dj * gamma[m] * r[0];
                            next[1] -= dj * gamma[m] * r[1];
                        }
                    }
                    z[j] = next;
                }
            }
            if t == l.t0 || t == self.t || memo.find(t).is_some() {
                continue;
            }
            l.free.state_with_kernels(&self.dynamics, t, &kernels.grid_free[(k - 1) * n..k * n], &mut st);
            let y = memo.slot(t, 2 * n + 2 * nc);
            for j in 0..n {
                y[j] = st.q[j] + z[j][0];
                y[n + j] = st.qd[j] + z[j][1];
            }
            let sigma = (t - l.t0) / l.h;
            for c in 0..nc {
                y[2 * n + c] = l.y0[2 * n + c] + l.h * integral(&l.force[c], sigma);
                y[2 * n + nc + c] = l.y0[2 * n + nc + c] + l.h * integral(&l.dissipation[c], sigma);
            }

        }
    }

    fn evaluate(&self, l: &Step, t: f64, out: &mut DVector<f64>) {
        let (n, s, nc) = (self.n, self.scheme.s, self.contacts.len());
        let tau = t - l.t0;
        let mut st = ModalState::zeros(n);
        l.free.state_at(&self.dynamics, t, &mut st);
        let mut r = vec![[0.0; 2]; n * (s + 1)];
        let mut phis = [[0.0; 2]; 8];
        if tau > 0.0 {
            let sigma = tau / l.h;
            for (j, osc) in self.dynamics.oscillators.iter().enumerate() {
                phi_columns(osc, tau, &mut phis[..s + 1]);
                let mut factor = tau;
                for m in 0..s {
                    r[j * (s + 1) + m] = [factor * phis[m + 1][0], factor * phis[m + 1][1]];
                    factor *= sigma * (m + 1) as f64;
                }
            }
        }
        for j in 0..n {
            let (mut x, mut v) = (st.q[j], st.qd[j]);
            if tau > 0.0 {
                for (c, alpha) in l.force.iter().enumerate() {
                    let dj = self.contacts[c].d[j];
                    for (m, a) in alpha.iter().enumerate() {
                        let rr = r[j * (s + 1) + m];
                        x -= dj * a * rr[0];
                        v -= dj * a * rr[1];
                    }
                }
            }
            out[j] = x;
            out[n + j] = v;
        }
        let sigma = tau / l.h;
        for c in 0..nc {
            out[2 * n + c] = l.y0[2 * n + c] + l.h * integral(&l.force[c], sigma);
            out[2 * n + nc + c] = l.y0[2 * n + nc + c] + l.h * integral(&l.dissipation[c], sigma);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::{ModalForcing, Oscillator};

    /// A Hertz-like force `k p^1.5 (1 + c p')` on one point.
    struct Hertzian {
        k: f64,
        c: f64,
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
}

