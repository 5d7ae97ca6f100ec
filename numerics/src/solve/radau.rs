//! L-stable implicit integration: Radau IIA, 3 stages, order 5.
//!
//! Source: HW96 (Hairer & Wanner, *Solving Ordinary Differential Equations
//! II*, 2nd ed. 1996; docs/references.md), sec. IV.8, and their Fortran
//! code RADAU5: coefficients, the embedded error estimate filtered by
//! `(I - h gamma0 J)^-1`, the step rule with Gustafsson's predictive
//! controller, the Newton contraction estimate `theta`, starting values
//! and dense output from the collocation polynomial of the last step,
//! transformed tolerances `0.1 rtol^(2/3)`.
//!
//! Newton's linear systems `(I - h A (x) J) dZ = R` are solved as in
//! RADAU5 (sec. IV.8, (8.15)-(8.18)): with `W = (T^-1 (x) I) Z` they split
//! into one real `n x n` system `(gamma/h I - J)` and one complex one
//! `((alpha + i beta)/h I - J)`; the real LU also filters the error
//! estimate (`gamma/h = 1/(h gamma0)`). The iterate, its norm and the
//! residual stay in `Z` coordinates.
//!
//! Departures, all for honesty at non-smooth onsets (Hertz contact):
//! - Newton is accepted only after the theta rule says "converged" AND one
//!   more evaluation shows the next increment below the Newton tolerance and
//!   the raw collocation residual `Z - h (A (x) I) F(Z)` below the local
//!   tolerance in every component (plus a rounding allowance). The stages
//!   returned are exactly the checked ones.
//! - On slow convergence or divergence the Jacobian is refreshed at the
//!   current point and the step retried; only then is the step reduced.
//!   By default `J` is recomputed at every step.

use nalgebra::{DMatrix, DVector};
use std::fmt;

use super::lu::{Lu, Order};
use super::C64;

/// The problem `y' = f(t, y)`.
pub trait ImplicitSystem {
    fn dim(&self) -> usize;
    /// `dy = f(t, y)`.
    fn rhs(&mut self, t: f64, y: &DVector<f64>, dy: &mut DVector<f64>);
    /// `jac = df/dy` at `(t, y)`; return `false` (the default) to have the
    /// solver difference `rhs` instead (one-sided, `n` evaluations).
    fn jacobian(&mut self, _t: f64, _y: &DVector<f64>, _jac: &mut DMatrix<f64>) -> bool {
        false
    }
}

/// A tolerance, the same for all components or one per component.
#[derive(Clone, Debug)]
pub enum Tol {
    Scalar(f64),
    Vector(DVector<f64>),
}

impl From<f64> for Tol {
    fn from(v: f64) -> Self {
        Tol::Scalar(v)
    }
}

#[derive(Clone, Debug)]
pub struct RadauOptions {
    pub rtol: Tol,
    pub atol: Tol,
    pub h_max: f64,
    /// A step below `max(h_min, 16 eps |t|)` is an error.
    pub h_min: f64,
    /// First step after construction or a restart; `None`: estimated.
    pub h_init: Option<f64>,
    /// Step attempts (accepted + rejected) allowed since the last (re)start.
    pub max_steps: u64,
    pub max_newton_iter: usize,
    pub refresh_jacobian_every_step: bool,
    /// No error control: every step has length `h_init` (required), the
    /// last one up to `t_end`; a Newton failure is an error. For order tests.
    pub fixed_step: bool,
}

impl Default for RadauOptions {
    fn default() -> Self {
        RadauOptions {
            rtol: Tol::Scalar(1e-8),
            atol: Tol::Scalar(1e-10),
            h_max: f64::INFINITY,
            h_min: 0.0,
            h_init: None,
            max_steps: 100_000,
            max_newton_iter: 8,
            refresh_jacobian_every_step: true,
            fixed_step: false,
        }
    }
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RadauStats {
    pub rhs_evals: u64,
    pub jacobians: u64,
    pub lu_decompositions: u64,
    pub accepted: u64,
    pub rejected: u64,
    pub newton_failures: u64,
    pub newton_iterations: u64,
}

#[derive(Clone, Debug, PartialEq)]
pub enum RadauError {
    InvalidInput(&'static str),
    /// `f` or its Jacobian is NaN or infinite at the accepted point `t`, or
    /// only a step below the minimum avoided non-finite stage values.
    NonFinite { t: f64 },
    StepSizeTooSmall { t: f64, h: f64 },
    TooManySteps { t: f64, steps: u64 },
    SingularMatrix { t: f64, h: f64 },
    /// Fixed-step mode only.
    NewtonFailure { t: f64, h: f64 },
}

impl fmt::Display for RadauError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RadauError::InvalidInput(m) => write!(f, "invalid input: {m}"),
            RadauError::NonFinite { t } => write!(f, "non-finite right-hand side or Jacobian at t = {t}"),
            RadauError::StepSizeTooSmall { t, h } => write!(f, "step size {h} too small at t = {t}"),
            RadauError::TooManySteps { t, steps } => write!(f, "{steps} steps taken, limit reached at t = {t}"),
            RadauError::SingularMatrix { t, h } => write!(f, "singular Newton matrix at t = {t}, h = {h}"),
            RadauError::NewtonFailure { t, h } => write!(f, "Newton failed at t = {t} with fixed step {h}"),
        }
    }
}

impl std::error::Error for RadauError {}

const EPS: f64 = f64::EPSILON;
const SQ6: f64 = 2.449_489_742_783_178;
const C: [f64; 3] = [(4.0 - SQ6) / 10.0, (4.0 + SQ6) / 10.0, 1.0];
const A: [[f64; 3]; 3] = [
    [(88.0 - 7.0 * SQ6) / 360.0, (296.0 - 169.0 * SQ6) / 1800.0, (-2.0 + 3.0 * SQ6) / 225.0],
    [(296.0 + 169.0 * SQ6) / 1800.0, (88.0 + 7.0 * SQ6) / 360.0, (-2.0 - 3.0 * SQ6) / 225.0],
    [(16.0 - SQ6) / 36.0, (16.0 + SQ6) / 36.0, 1.0 / 9.0],
];
/// Error estimate `gamma0 h f(y0) + sum gamma0 DD_i Z_i` (RADAU5's DD1..3).
const DD: [f64; 3] = [-(13.0 + 7.0 * SQ6) / 3.0, (-13.0 + 7.0 * SQ6) / 3.0, -1.0 / 3.0];
/// RADAU5's transformation: `TI A^-1 T = diag(GAMMA, [[ALPHA, -BETA], [BETA, ALPHA]])`,
/// `TI = T^-1` (checked in `radau_transformation`).
#[allow(clippy::excessive_precision)]
const T: [[f64; 3]; 3] = [
    [9.123_239_487_089_294_279_2e-2, -0.141_255_295_020_954_208_43, -3.002_919_410_514_742_449_2e-2],
    [0.241_717_932_707_107_018_96, 0.204_129_352_293_799_931_99, 0.382_942_112_757_261_937_79],
    [0.966_048_182_615_092_936_19, 1.0, 0.0],
];
#[allow(clippy::excessive_precision)]
const TI: [[f64; 3]; 3] = [
    [4.325_579_890_063_155_351_0, 0.339_199_251_815_809_869_54, 0.541_770_539_935_874_871_19],
    [-4.178_718_591_551_904_727_3, -0.327_682_820_761_062_387_08, 0.476_623_554_500_550_451_96],
    [-0.502_872_634_945_786_875_95, 2.571_926_949_855_605_429_2, -0.596_039_204_828_224_924_97],
];
const GAMMA: f64 = 3.637_834_252_744_496;
const ALPHA: f64 = 2.681_082_873_627_752;
const BETA: f64 = 3.050_430_199_247_411;
const SAFE: f64 = 0.9;
const THET: f64 = 0.001;

/// The real eigenvalue of `A` (`1 / GAMMA`).
#[cfg(test)]
fn gamma0() -> f64 {
    (6.0 + 81f64.cbrt() - 9f64.cbrt()) / 30.0
}

fn finite(v: &DVector<f64>) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// Radau IIA integrator; the system is passed to each call, so the caller
/// keeps it (and may change it at an event, then `restart`).
#[derive(Clone, Debug)]
pub struct Radau {
    n: usize,
    opts: RadauOptions,
    /// User tolerances (initial step) and RADAU5's transformed ones.
    rtol_u: DVector<f64>,
    atol_u: DVector<f64>,
    rtol: DVector<f64>,
    atol: DVector<f64>,
    fnewt: f64,
    t: f64,
    y: DVector<f64>,
    /// `f(t, y)`.
    f0: DVector<f64>,
    h: f64,
    jac: DMatrix<f64>,
    /// `jac` holds a Jacobian / one taken at `(t, y)`; a new one is wanted.
    jac_valid: bool,
    jac_fresh: bool,
    want_jac: bool,
    /// LU of `GAMMA/h I - J` (`= I/(h gamma0) - J`, also the error filter)
    /// and of `(ALPHA + i BETA)/h I - J`, for step `lu_h`.
    e1: Lu<f64>,
    e2: Lu<C64>,
    lu_h: f64,
    /// Stage increments `Z`, `F(Z)`, residual / increment, work (all `3n`).
    z: DVector<f64>,
    fz: DVector<f64>,
    dz: DVector<f64>,
    w3: DVector<f64>,
    /// Work (all `n`).
    w23: Vec<C64>,
    ytmp: DVector<f64>,
    ftmp: DVector<f64>,
    scal: DVector<f64>,
    f2: DVector<f64>,
    err_v: DVector<f64>,
    /// Dense output: `u(s) = yc + s (d1 + (s - c2 + 1) (d2 + (s - c1 + 1) d3))`,
    /// `s = (t - t_new) / h`, with `d1, d2, d3` stacked in `cd`.
    yc: DVector<f64>,
    cd: DVector<f64>,
    dense_span: Option<(f64, f64)>,
    first: bool,
    reject: bool,
    faccon: f64,
    theta: f64,
    hacc: f64,
    erracc: f64,
    attempts: u64,
    stats: RadauStats,
}

impl Radau {
    pub fn new(
        sys: &mut dyn ImplicitSystem,
        t0: f64,
        y0: &DVector<f64>,
        opts: RadauOptions,
    ) -> Result<Self, RadauError> {
        let n = sys.dim();
        if n == 0 || y0.len() != n {
            return Err(RadauError::InvalidInput("y0 length differs from dim() or is zero"));
        }
        let expand = |t: &Tol| match t {
            Tol::Scalar(v) => Ok(DVector::from_element(n, *v)),
            Tol::Vector(v) if v.len() == n => Ok(v.clone()),
            Tol::Vector(_) => Err(RadauError::InvalidInput("tolerance vector length differs from dim()")),
        };
        let (rtol_u, atol_u) = (expand(&opts.rtol)?, expand(&opts.atol)?);
        if rtol_u.iter().any(|r| !(1e-14..1.0).contains(r)) || atol_u.iter().any(|&a| !(a > 0.0 && a.is_finite())) {
            return Err(RadauError::InvalidInput("need 1e-14 <= rtol < 1 and finite atol > 0"));
        }
        if !(opts.h_max > 0.0) || !(opts.h_min >= 0.0) || opts.max_newton_iter < 2 {
            return Err(RadauError::InvalidInput("need h_max > 0, h_min >= 0, max_newton_iter >= 2"));
        }
        if opts.h_init.is_some_and(|h| !(h > 0.0 && h.is_finite())) || (opts.fixed_step && opts.h_init.is_none()) {
            return Err(RadauError::InvalidInput("h_init must be positive and finite (and given for fixed_step)"));
        }
        // RADAU5: the estimate is O(h^4), so tolerances are mapped to 0.1 rtol^(2/3).
        let rtol = rtol_u.map(|r| 0.1 * r.powf(2.0 / 3.0));
        let atol = atol_u.component_mul(&rtol).component_div(&rtol_u);
        let r1 = rtol.min();
        let (v, v3) = (DVector::zeros(n), DVector::zeros(3 * n));
        let m = n;
        let mut s = Radau {
            fnewt: (10.0 * EPS / r1).max(0.03f64.min(r1.sqrt())),
            n, rtol_u, atol_u, rtol, atol, t: t0, y: y0.clone(), f0: v.clone(), h: 0.0,
            jac: DMatrix::zeros(m, m),
            jac_valid: false, jac_fresh: false, want_jac: false,
            e1: Lu::default(),
            e2: Lu::default(),
            lu_h: f64::NAN,
            w23: vec![C64::new(0.0, 0.0); n],
            z: v3.clone(), fz: v3.clone(), dz: v3.clone(), w3: v3.clone(), cd: v3,
            ytmp: v.clone(), ftmp: v.clone(), scal: v.clone(), f2: v.clone(), err_v: v.clone(), yc: v,
            dense_span: None, first: true, reject: false, faccon: 1.0, theta: 1.0, hacc: 0.0, erracc: 0.0, attempts: 0,
            stats: RadauStats::default(),
            opts,
        };
        s.restart(sys, t0, y0, s.opts.h_init)?;
        Ok(s)
    }

    /// Continue from `(t, y)` as a fresh start: no history, no Jacobian, no
    /// dense output; first step `h` or an estimate.
    pub fn restart(
        &mut self,
        sys: &mut dyn ImplicitSystem,
        t: f64,
        y: &DVector<f64>,
        h: Option<f64>,
    ) -> Result<(), RadauError> {
        if sys.dim() != self.n || y.len() != self.n {
            return Err(RadauError::InvalidInput("dimension mismatch"));
        }
        if !t.is_finite() || !finite(y) || h.is_some_and(|h| !(h > 0.0 && h.is_finite())) {
            return Err(RadauError::InvalidInput("t, y and h must be finite (h > 0)"));
        }
        self.t = t;
        self.y.copy_from(y);
        sys.rhs(t, &self.y, &mut self.f0);
        self.stats.rhs_evals += 1;
        if !finite(&self.f0) {
            return Err(RadauError::NonFinite { t });
        }
        (self.jac_valid, self.jac_fresh, self.want_jac, self.lu_h) = (false, false, false, f64::NAN);
        (self.first, self.reject, self.faccon, self.theta, self.attempts) = (true, false, 1.0, 1.0, 0);
        self.dense_span = None;
        self.h = match h {
            Some(h) => h,
            None => self.initial_step(sys),
        }
        .min(self.opts.h_max);
        Ok(())
    }

    /// Hairer's starting step (order 5) from user tolerances and one Euler step.
    fn initial_step(&mut self, sys: &mut dyn ImplicitSystem) -> f64 {
        let n = self.n as f64;
        let (mut d0, mut d1) = (0.0, 0.0);
        for i in 0..self.n {
            self.scal[i] = self.atol_u[i] + self.rtol_u[i] * self.y[i].abs();
            d0 += (self.y[i] / self.scal[i]).powi(2);
            d1 += (self.f0[i] / self.scal[i]).powi(2);
        }
        let (d0, d1) = ((d0 / n).sqrt(), (d1 / n).sqrt());
        let mut h0 = if d0 < 1e-5 || d1 < 1e-5 { 1e-6 } else { 0.01 * d0 / d1 };
        h0 = h0.min(self.opts.h_max);
        for i in 0..self.n {
            self.ytmp[i] = self.y[i] + h0 * self.f0[i];
        }
        sys.rhs(self.t + h0, &self.ytmp, &mut self.ftmp);
        self.stats.rhs_evals += 1;
        let mut d2 = 0.0;
        for i in 0..self.n {
            d2 += ((self.ftmp[i] - self.f0[i]) / self.scal[i]).powi(2);
        }
        let d2 = (d2 / n).sqrt() / h0;
        let dm = d1.max(d2);
        let h1 = if !dm.is_finite() { h0 * 1e-3 } else if dm <= 1e-15 { (h0 * 1e-3).max(1e-6) } else { (0.01 / dm).powf(1.0 / 6.0) };
        (100.0 * h0).min(h1).max(1e-3 * h0)
    }

    pub fn t(&self) -> f64 { self.t }
    pub fn y(&self) -> &DVector<f64> { &self.y }
    /// Step size proposed for the next step.
    pub fn h(&self) -> f64 { self.h }
    pub fn stats(&self) -> RadauStats { self.stats }
    /// `(t_old, t_new)` of the last accepted step, the span of `dense`.
    pub fn last_step(&self) -> Option<(f64, f64)> { self.dense_span }

    fn eval_jac(&mut self, sys: &mut dyn ImplicitSystem) -> Result<(), RadauError> {
        self.stats.jacobians += 1;
        if !sys.jacobian(self.t, &self.y, &mut self.jac) {
            for j in 0..self.n {
                self.ytmp.copy_from(&self.y);
                let d = (EPS * self.y[j].abs().max(1e-5)).sqrt();
                self.ytmp[j] += d;
                sys.rhs(self.t, &self.ytmp, &mut self.ftmp);
                self.stats.rhs_evals += 1;
                for i in 0..self.n {
                    self.jac[(i, j)] = (self.ftmp[i] - self.f0[i]) / d;
                }
            }
        }
        if self.jac.iter().any(|v| !v.is_finite()) {
            return Err(RadauError::NonFinite { t: self.t });
        }
        (self.jac_valid, self.jac_fresh, self.want_jac, self.lu_h) = (true, true, false, f64::NAN);
        Ok(())
    }

    /// Factorise `GAMMA/h I - J` and `(ALPHA + i BETA)/h I - J`, which
    /// together solve `(I - h A (x) J) dZ = R` (Hairer & Wanner IV.8).
    fn factor(&mut self, h: f64) -> bool {
        let n = self.n;
        self.stats.lu_decompositions += 1;
        let (e1, e2) = (self.e1.matrix_mut(n), self.e2.matrix_mut(n));
        for ((x, z), j) in e1.iter_mut().zip(e2.iter_mut()).zip(self.jac.iter()) {
            (*x, *z) = (-j, C64::new(-j, 0.0));
        }
        for i in 0..n {
            e1[(i, i)] += GAMMA / h;
            e2[(i, i)] = C64::new(e2[(i, i)].re + ALPHA / h, BETA / h);
        }
        let ok = self.e1.factor(Order::Columns) && self.e2.factor(Order::Columns);
        self.lu_h = if ok { h } else { f64::NAN };
        ok
    }

    /// `dz <- (I - h A (x) J)^-1 dz` through `W = (TI (x) I) Z`:
    /// `(Lambda/h (x) I - I (x) J) dW = (Lambda TI (x) I) R / h`, `dZ = (T (x) I) dW`.
    fn solve(&mut self, h: f64) {
        let n = self.n;
        for k in 0..n {
            let r = [self.dz[k], self.dz[n + k], self.dz[2 * n + k]];
            let v: [f64; 3] = std::array::from_fn(|i| (TI[i][0] * r[0] + TI[i][1] * r[1] + TI[i][2] * r[2]) / h);
            self.w3[k] = GAMMA * v[0];
            self.w3[n + k] = ALPHA * v[1] - BETA * v[2];
            self.w3[2 * n + k] = BETA * v[1] + ALPHA * v[2];
        }
        let (w1, w23) = self.w3.as_mut_slice().split_at_mut(n);
        let (w2, w3) = w23.split_at_mut(n);
        self.e1.solve(w1);
        for (z, (re, im)) in self.w23.iter_mut().zip(w2.iter().zip(w3.iter())) {
            *z = C64::new(*re, *im);
        }
        self.e2.solve(&mut self.w23);
        for (z, (re, im)) in self.w23.iter().zip(w2.iter_mut().zip(w3.iter_mut())) {
            (*re, *im) = (z.re, z.im);
        }
        for k in 0..n {
            let w = [self.w3[k], self.w3[n + k], self.w3[2 * n + k]];
            for i in 0..3 {
                self.dz[i * n + k] = T[i][0] * w[0] + T[i][1] * w[1] + T[i][2] * w[2];
            }
        }
    }

    /// Newton on the stage increments `Z`. `Ok(iterations)`, or
    /// `Err((step factor, non-finite values met))`.
    fn newton(&mut self, sys: &mut dyn ImplicitSystem, h: f64) -> Result<usize, (f64, bool)> {
        let (n, nit) = (self.n, self.opts.max_newton_iter);
        if self.first || self.dense_span.is_none() {
            self.z.fill(0.0);
        } else {
            let q = h / self.dense_span.map_or(h, |(a, b)| b - a);
            for i in 0..3 {
                let s = C[i] * q;
                for k in 0..n {
                    let (d1, d2, d3) = (self.cd[k], self.cd[n + k], self.cd[2 * n + k]);
                    self.z[i * n + k] = s * (d1 + (s - C[1] + 1.0) * (d2 + (s - C[0] + 1.0) * d3));
                }
            }
        }
        self.faccon = self.faccon.max(EPS).powf(0.8);
        let (mut dynold, mut thqold, mut pending) = (1.0, 1.0, false);
        for newt in 1..=nit {
            self.stats.newton_iterations += 1;
            for i in 0..3 {
                for k in 0..n {
                    self.ytmp[k] = self.y[k] + self.z[i * n + k];
                }
                sys.rhs(self.t + C[i] * h, &self.ytmp, &mut self.ftmp);
                self.stats.rhs_evals += 1;
                if !finite(&self.ftmp) {
                    return Err((0.5, true));
                }
                self.fz.rows_mut(i * n, n).copy_from(&self.ftmp);
            }
            for i in 0..3 {
                for k in 0..n {
                    let hf: f64 = (0..3).map(|j| A[i][j] * self.fz[j * n + k]).sum();
                    self.dz[i * n + k] = h * hf - self.z[i * n + k];
                }
            }
            let (raw_ok, noise) = if pending { self.residual_ok(h) } else { (false, 0.0) };
            self.solve(h);
            let mut dyno = 0.0;
            for i in 0..3 * n {
                dyno += (self.dz[i] / self.scal[i % n]).powi(2);
            }
            let dyno = (dyno / (3 * n) as f64).sqrt();
            if !dyno.is_finite() {
                return Err((0.5, true));
            }
            if newt > 1 {
                let thq = dyno / dynold;
                self.theta = if newt == 2 { thq } else { (thq * thqold).sqrt() };
                thqold = thq;
                if self.theta < 0.99 {
                    self.faccon = self.theta / (1.0 - self.theta);
                }
            }
            if pending && raw_ok && dyno <= self.fnewt.max(8.0 * noise) {
                return Ok(newt);
            }
            if newt > 1 {
                if self.theta >= 0.99 {
                    return Err((0.5, false));
                }
                if newt < nit {
                    let left = (nit - 1 - newt) as i32;
                    let dyth = self.faccon * dyno * self.theta.powi(left) / self.fnewt;
                    if dyth >= 1.0 {
                        let qnewt = dyth.clamp(1e-4, 20.0);
                        return Err(((0.8 * qnewt.powf(-1.0 / (4.0 + left as f64))).min(0.8), false));
                    }
                }
            }
            dynold = dyno.max(EPS);
            self.z += &self.dz;
            pending = self.faccon * dyno <= self.fnewt;
        }
        Err((0.5, false))
    }

    /// Raw residual `R = h A F(Z) - Z` (in `dz`) against the local tolerance
    /// per component, plus a rounding allowance `64 nu`,
    /// `nu = eps (|y| + |Z| + h |A| (|F| + |J| |Y|))`. Also returns the RMS
    /// of `nu / scal`, the rounding floor of the Newton increments.
    fn residual_ok(&mut self, h: f64) -> (bool, f64) {
        let n = self.n;
        self.w3.fill(0.0);
        for j in 0..3 {
            for l in 0..n {
                let yl = (self.y[l] + self.z[j * n + l]).abs();
                for k in 0..n {
                    self.w3[j * n + k] += self.jac[(k, l)].abs() * yl;
                }
            }
        }
        let (mut ok, mut noise) = (true, 0.0);
        for i in 0..3 {
            for k in 0..n {
                let s: f64 = (0..3).map(|j| A[i][j].abs() * (self.fz[j * n + k].abs() + self.w3[j * n + k])).sum();
                let nu = EPS * (self.z[i * n + k].abs() + self.y[k].abs() + h * s);
                ok &= self.dz[i * n + k].abs() <= self.scal[k] + 64.0 * nu;
                noise += (nu / self.scal[k]).powi(2);
            }
        }
        (ok, (noise / (3 * n) as f64).sqrt())
    }

    /// `err_v <- (GAMMA/h I - J)^-1 err_v`.
    fn filter_error(&mut self) {
        self.e1.solve(self.err_v.as_mut_slice());
    }

    /// RADAU5's filtered embedded estimate (ESTRAD), RMS-scaled.
    fn error_estimate(&mut self, sys: &mut dyn ImplicitSystem, h: f64) -> f64 {
        let n = self.n;
        let rms = |v: &DVector<f64>, sc: &DVector<f64>| {
            let s: f64 = v.iter().zip(sc.iter()).map(|(a, b)| (a / b).powi(2)).sum();
            (s / n as f64).sqrt().max(1e-10)
        };
        for k in 0..n {
            self.f2[k] = (DD[0] * self.z[k] + DD[1] * self.z[n + k] + DD[2] * self.z[2 * n + k]) / h;
            self.err_v[k] = self.f0[k] + self.f2[k];
        }
        self.filter_error();
        let mut err = rms(&self.err_v, &self.scal);
        if err >= 1.0 && (self.first || self.reject) {
            for k in 0..n {
                self.ytmp[k] = self.y[k] + self.err_v[k];
            }
            sys.rhs(self.t, &self.ytmp, &mut self.ftmp);
            self.stats.rhs_evals += 1;
            for k in 0..n {
                self.err_v[k] = self.ftmp[k] + self.f2[k];
            }
            self.filter_error();
            err = rms(&self.err_v, &self.scal);
        }
        if err.is_finite() {
            err
        } else {
            f64::INFINITY
        }
    }

    /// One accepted step, not beyond `t_end`; returns `(t_old, t_new)`.
    pub fn step(&mut self, sys: &mut dyn ImplicitSystem, t_end: f64) -> Result<(f64, f64), RadauError> {
        if sys.dim() != self.n {
            return Err(RadauError::InvalidInput("system dimension changed"));
        }
        if !(t_end > self.t && t_end.is_finite()) {
            return Err(RadauError::InvalidInput("t_end must be finite and beyond t"));
        }
        let nit = self.opts.max_newton_iter as f64;
        for k in 0..self.n {
            self.scal[k] = self.atol[k] + self.rtol[k] * self.y[k].abs();
        }
        let (mut nsing, mut nonfinite) = (0, false);
        loop {
            let t = self.t;
            if self.attempts >= self.opts.max_steps {
                return Err(RadauError::TooManySteps { t, steps: self.attempts });
            }
            let h_prop = self.h.min(self.opts.h_max);
            let (mut h, last) = (h_prop, t + h_prop * 1.0001 >= t_end);
            if last {
                h = t_end - t;
            } else if !(h > self.opts.h_min.max(16.0 * EPS * t.abs())) {
                return Err(if nonfinite { RadauError::NonFinite { t } } else { RadauError::StepSizeTooSmall { t, h } });
            }
            self.attempts += 1;
            if !self.jac_valid || self.want_jac || (self.opts.refresh_jacobian_every_step && !self.jac_fresh) {
                self.eval_jac(sys)?;
            }
            if self.lu_h != h && !self.factor(h) {
                nsing += 1;
                if nsing >= 5 {
                    return Err(RadauError::SingularMatrix { t, h });
                }
                (self.h, self.reject) = (0.5 * h, true);
                continue;
            }
            let newt = match self.newton(sys, h) {
                Ok(newt) => newt,
                Err((fac, nf)) => {
                    self.stats.newton_failures += 1;
                    nonfinite = nf;
                    if self.opts.fixed_step {
                        return Err(if nf { RadauError::NonFinite { t } } else { RadauError::NewtonFailure { t, h } });
                    }
                    if !self.jac_fresh && !nf {
                        (self.want_jac, self.h) = (true, h); // refresh J at the current point, same h
                    } else {
                        self.h = h * fac;
                    }
                    self.reject = true;
                    continue;
                }
            };
            nonfinite = false;
            let err = if self.opts.fixed_step { 0.0 } else { self.error_estimate(sys, h) };
            let fac = SAFE.min(SAFE * (1.0 + 2.0 * nit) / (newt as f64 + 2.0 * nit));
            let mut quot = (1.0 / 8.0f64).max(5.0f64.min(err.powf(0.25) / fac));
            if err >= 1.0 {
                self.h = if self.first { 0.1 * h } else { h / quot };
                self.reject = true;
                self.stats.rejected += 1;
                continue;
            }
            if !self.first {
                let gus = (self.hacc / h) * (err * err / self.erracc).powf(0.25) / SAFE;
                quot = quot.max(gus.clamp(1.0 / 8.0, 5.0));
            }
            (self.hacc, self.erracc) = (h, err.max(1e-2));
            let mut hnew = h / quot;
            // Accept: dense output in RADAU5's divided-difference form.
            let n = self.n;
            let (c1m1, c2m1) = (C[0] - 1.0, C[1] - 1.0);
            for k in 0..n {
                let (z1, z2, z3) = (self.z[k], self.z[n + k], self.z[2 * n + k]);
                let d1 = (z2 - z3) / c2m1;
                let ak = (z1 - z2) / (C[0] - C[1]);
                let acont3 = (ak - z1 / C[0]) / C[1];
                let d2 = (ak - d1) / c1m1;
                (self.cd[k], self.cd[n + k], self.cd[2 * n + k]) = (d1, d2, d2 - acont3);
                self.y[k] += z3;
            }
            self.yc.copy_from(&self.y);
            self.f0.copy_from(&self.fz.rows(2 * n, n)); // f at the checked last stage = new point
            let t_new = if last { t_end } else { t + h };
            self.dense_span = Some((t, t_new));
            self.t = t_new;
            self.stats.accepted += 1;
            self.jac_fresh = false;
            self.want_jac = self.opts.refresh_jacobian_every_step || self.theta > THET;
            if self.reject {
                hnew = hnew.min(h);
            } else if last && hnew >= h {
                hnew = hnew.max(h_prop); // a step cut short to hit t_end does not shrink the next
            }
            (self.first, self.reject) = (false, false);
            let qt = hnew / h;
            if self.opts.fixed_step || (!self.want_jac && (1.0..=1.2).contains(&qt) && !last) {
                hnew = if self.opts.fixed_step { self.h } else { h };
            }
            self.h = hnew.min(self.opts.h_max);
            return Ok((t, t_new));
        }
    }

    fn dense_s(&self, t: f64, len: usize) -> Result<(f64, f64), RadauError> {
        let (a, b) = self.dense_span.ok_or(RadauError::InvalidInput("no step taken since the last (re)start"))?;
        let h = b - a;
        if len != self.n {
            return Err(RadauError::InvalidInput("output length differs from dim()"));
        }
        if !(t >= a - 1e-9 * h && t <= b + 1e-9 * h) {
            return Err(RadauError::InvalidInput("t outside the last step"));
        }
        Ok(((t - b) / h, h))
    }

    /// The collocation polynomial of the last step at `t` in `[t_old, t_new]`.
    pub fn dense(&self, t: f64, out: &mut DVector<f64>) -> Result<(), RadauError> {
        let (s, _) = self.dense_s(t, out.len())?;
        let (n, c1m1, c2m1) = (self.n, C[0] - 1.0, C[1] - 1.0);
        for k in 0..n {
            let (d1, d2, d3) = (self.cd[k], self.cd[n + k], self.cd[2 * n + k]);
            out[k] = self.yc[k] + s * (d1 + (s - c2m1) * (d2 + (s - c1m1) * d3));
        }
        Ok(())
    }

    /// Time derivative of the collocation polynomial at `t`.
    pub fn dense_derivative(&self, t: f64, out: &mut DVector<f64>) -> Result<(), RadauError> {
        let (s, h) = self.dense_s(t, out.len())?;
        let (n, c1m1, c2m1) = (self.n, C[0] - 1.0, C[1] - 1.0);
        for k in 0..n {
            let (d1, d2, d3) = (self.cd[k], self.cd[n + k], self.cd[2 * n + k]);
            let q = d2 + (s - c1m1) * d3;
            let p = d1 + (s - c2m1) * q;
            out[k] = (p + s * (q + (s - c2m1) * d3)) / h;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Sys<F, J>(usize, F, J);
    #[rustfmt::skip]
    impl<F, J> ImplicitSystem for Sys<F, J>
    where F: FnMut(f64, &DVector<f64>, &mut DVector<f64>), J: FnMut(f64, &DVector<f64>, &mut DMatrix<f64>) -> bool {
        fn dim(&self) -> usize { self.0 }
        fn rhs(&mut self, t: f64, y: &DVector<f64>, dy: &mut DVector<f64>) { (self.1)(t, y, dy) }
        fn jacobian(&mut self, t: f64, y: &DVector<f64>, jac: &mut DMatrix<f64>) -> bool { (self.2)(t, y, jac) }
    }
    /// (A constructor, so that the closures get higher-ranked signatures.)
    fn sys<F, J>(n: usize, f: F, j: J) -> Sys<F, J>
    where
        F: FnMut(f64, &DVector<f64>, &mut DVector<f64>),
        J: FnMut(f64, &DVector<f64>, &mut DMatrix<f64>) -> bool,
    {
        Sys(n, f, j)
    }
    fn opts(rtol: f64, atol: Tol) -> RadauOptions {
        RadauOptions { rtol: rtol.into(), atol, ..Default::default() }
    }
    fn v(x: &[f64]) -> DVector<f64> {
        DVector::from_column_slice(x)
    }
    fn run_to(r: &mut Radau, s: &mut dyn ImplicitSystem, t_end: f64) {
        while r.t() < t_end {
            r.step(s, t_end).unwrap();
        }
    }

    #[test]
    fn radau_constants() {
        for i in 0..3 {
            for p in 1..=3 {
                let lhs: f64 = (0..3).map(|j| A[i][j] * C[j].powi(p - 1)).sum::<f64>() * p as f64;
                assert!((lhs - C[i].powi(p)).abs() < 1e-15, "C(3) fails at {i},{p}");
            }
        }
        let g = gamma0();
        let m = DMatrix::from_fn(3, 3, |i, j| A[i][j] - if i == j { g } else { 0.0 });
        assert!(m.determinant().abs() < 1e-15);
    }

    /// RADAU5's `T`, `TI`, `GAMMA`, `ALPHA`, `BETA` from `A`: `TI = T^-1`
    /// and `TI A^-1 T` is the real block-diagonal form of `A^-1`.
    #[test]
    fn radau_transformation() {
        let a = DMatrix::from_fn(3, 3, |i, j| A[i][j]);
        let ainv = a.clone().try_inverse().unwrap();
        let (t, ti) = (DMatrix::from_fn(3, 3, |i, j| T[i][j]), DMatrix::from_fn(3, 3, |i, j| TI[i][j]));
        let lam = DMatrix::from_row_slice(3, 3, &[GAMMA, 0.0, 0.0, 0.0, ALPHA, -BETA, 0.0, BETA, ALPHA]);
        let e_inv = (&ti * &t - DMatrix::identity(3, 3)).abs().max();
        let e_diag = (&ti * &ainv * &t - &lam).abs().max();
        // Eigenvalues of A^-1 from its invariants: trace, determinant, and the
        // sum of principal 2x2 minors.
        let m2 = |i: usize, j: usize| ainv[(i, i)] * ainv[(j, j)] - ainv[(i, j)] * ainv[(j, i)];
        let e_eig = [
            (ainv.trace() - (GAMMA + 2.0 * ALPHA)) / ainv.trace(),
            (ainv.determinant() - GAMMA * (ALPHA * ALPHA + BETA * BETA)) / ainv.determinant(),
            (m2(0, 1) + m2(0, 2) + m2(1, 2) - (2.0 * GAMMA * ALPHA + ALPHA * ALPHA + BETA * BETA)) / 60.0,
            GAMMA * gamma0() - 1.0,
        ];
        eprintln!("transformation: |TI T - I| {e_inv:.1e}, |TI A^-1 T - Lambda| {e_diag:.1e}, invariants {e_eig:.1?}");
        assert!(e_inv < 1e-14 && e_diag < 1e-14 && e_eig.iter().all(|e| e.abs() < 1e-14));
    }

    /// Test 1: y' = Q D Q^T y, D = -(1, 10, ..., 1e8), against the matrix exponential.
    #[test]
    fn radau_linear_stiff_vs_exponential() {
        let n = 9;
        let q = DMatrix::from_fn(n, n, |i, j| ((i * n + j) as f64 * 0.7 + 0.3).sin()).qr().q();
        let lam = DVector::from_fn(n, |i, _| -(10f64).powi(i as i32));
        let a = &q * DMatrix::from_diagonal(&lam) * q.transpose();
        let a2 = a.clone();
        let mut s = sys(n, move |_, y, dy| dy.gemv(1.0, &a, y, 0.0), move |_, _, j| {
            j.copy_from(&a2);
            true
        });
        let y0 = DVector::from_fn(n, |i, _| 1.0 + 0.1 * i as f64);
        let mut r = Radau::new(&mut s, 0.0, &y0, opts(1e-10, 1e-14.into())).unwrap();
        let qy0 = q.transpose() * &y0;
        let mut worst: f64 = 0.0;
        for t_out in [1e-6, 1e-3, 1.0, 5.0] {
            run_to(&mut r, &mut s, t_out);
            let exact = &q * DVector::from_fn(n, |i, _| qy0[i] * (lam[i] * t_out).exp());
            worst = worst.max((r.y() - &exact).norm() / exact.norm());
        }
        let st = r.stats();
        eprintln!("linear stiff: rel err {worst:.2e}, final h {:.3e}, {st:?}", r.h());
        assert!(worst < 1e-8);
        assert!(st.accepted < 300 && r.h() * 1e8 > 1e6);
    }

    /// Test 2: Fixed steps on a limit cycle (closed form): order 5 at the grid.
    #[test]
    fn radau_order_five() {
        let exact = |t: f64| {
            let r = (1.0 / (1.0 + 3.0 * (-2.0 * t).exp())).sqrt(); // r0 = 1/2
            v(&[r * t.cos(), r * t.sin()])
        };
        let mut errs = vec![];
        for nsteps in [8, 16, 32, 64] {
            let mut s = sys(2, |_, y, dy| {
                let g = 1.0 - y[0] * y[0] - y[1] * y[1];
                dy[0] = -y[1] + y[0] * g;
                dy[1] = y[0] + y[1] * g;
            }, |_, _, _| false);
            let o = RadauOptions { fixed_step: true, h_init: Some(4.0 / nsteps as f64), max_newton_iter: 40, ..opts(1e-13, 1e-13.into()) };
            let mut r = Radau::new(&mut s, 0.0, &v(&[0.5, 0.0]), o).unwrap();
            run_to(&mut r, &mut s, 4.0);
            assert_eq!(r.stats().accepted, nsteps);
            errs.push((r.y() - exact(4.0)).norm());
        }
        let orders: Vec<f64> = errs.windows(2).map(|w| (w[0] / w[1]).log2()).collect();
        eprintln!("order: errors {errs:?}, observed orders {orders:.3?}");
        assert!(orders.iter().all(|p| (4.6..5.4).contains(p)));
    }

    /// Test 3: Van der Pol, eps = 1e-6, y(0) = (2, 0), y(2) from Hairer's test set.
    #[test]
    fn radau_van_der_pol_stiff() {
        let e = 1e-6;
        let mut s = sys(2, move |_, y, dy| {
            dy[0] = y[1];
            dy[1] = ((1.0 - y[0] * y[0]) * y[1] - y[0]) / e;
        }, move |_, y, j| {
            j.copy_from_slice(&[0.0, (-2.0 * y[0] * y[1] - 1.0) / e, 1.0, (1.0 - y[0] * y[0]) / e]);
            true
        });
        let reference = v(&[1.706167732170483, -0.8928097010247975]);
        for tol in [1e-6, 1e-10] {
            let mut r = Radau::new(&mut s, 0.0, &v(&[2.0, 0.0]), opts(tol, tol.into())).unwrap();
            run_to(&mut r, &mut s, 2.0);
            let err = (r.y() - &reference).abs().max();
            eprintln!("van der Pol tol {tol:e}: max abs err {err:.2e}, {:?}", r.stats());
            assert!(err < 10.0 * tol);
        }
    }

    /// Test 4: Dense output inside steps of x'' = -w^2 x against the closed form.
    #[test]
    fn radau_dense_output() {
        let w = 2.0 * std::f64::consts::PI;
        let mut s = sys(2, move |_, y, dy| {
            dy[0] = y[1];
            dy[1] = -w * w * y[0];
        }, move |_, _, j| {
            j.copy_from_slice(&[0.0, -w * w, 1.0, 0.0]);
            true
        });
        let mut r = Radau::new(&mut s, 0.0, &v(&[1.0, 0.0]), opts(1e-9, 1e-12.into())).unwrap();
        assert!(r.dense(0.0, &mut v(&[0.0, 0.0])).is_err());
        let (mut u, mut du) = (v(&[0.0, 0.0]), v(&[0.0, 0.0]));
        let (mut e_grid, mut e_dense, mut e_deriv): (f64, f64, f64) = (0.0, 0.0, 0.0);
        while r.t() < 3.0 {
            let (a, b) = r.step(&mut s, 3.0).unwrap();
            e_grid = e_grid.max((r.y()[0] - (w * b).cos()).abs());
            for k in 1..10 {
                let t = a + (b - a) * k as f64 / 10.0;
                r.dense(t, &mut u).unwrap();
                r.dense_derivative(t, &mut du).unwrap();
                e_dense = e_dense.max((u[0] - (w * t).cos()).abs()).max((u[1] + w * (w * t).sin()).abs() / w);
                e_deriv = e_deriv.max((du[0] - u[1]).abs() / w).max((du[1] + w * w * (w * t).cos()).abs() / (w * w));
            }
        }
        eprintln!("dense: grid err {e_grid:.2e}, dense err {e_dense:.2e}, derivative err {e_deriv:.2e}, {:?}", r.stats());
        assert!(e_grid < 1e-8 && e_dense < 1e-7 && e_deriv < 1e-5);
    }

    /// Mass on a one-sided Hertz spring from contact onset (x = 0, v = v0) to
    /// the return to x = 0, found by bisection on the dense output. Returns
    /// (exit velocity error, max energy error, accepted steps, worst
    /// collocation defect, newton failures).
    fn hertz(k: f64, x0: f64, frozen: bool, jump: Option<f64>) -> (f64, f64, u64, f64, u64) {
        let (m, v0, rtol) = (1.0, 1.0, 1e-11);
        let xc = (m * v0 * v0 / k).powf(0.4);
        let force = move |x: f64| match jump {
            Some(f1) => if x > 0.0 { f1 } else { 0.0 },
            None => k * x.max(0.0).powf(1.5),
        };
        let mut s = sys(2, move |_, y, dy| {
            dy[0] = y[1];
            dy[1] = -force(y[0]) / m;
        }, move |_, y, j| {
            let kx = if frozen || jump.is_some() { 0.0 } else { 1.5 * k * y[0].max(0.0).sqrt() / m };
            j.copy_from_slice(&[0.0, -kx, 1.0, 0.0]);
            true
        });
        let energy = |y: &DVector<f64>| 0.5 * m * y[1] * y[1] + if jump.is_some() { 0.0 } else { 0.4 * k * y[0].max(0.0).powf(2.5) };
        let atol = Tol::Vector(v(&[1e-2 * rtol * xc, 1e-2 * rtol * v0]));
        let o = RadauOptions { refresh_jacobian_every_step: !frozen, ..opts(rtol, atol) };
        let mut r = Radau::new(&mut s, 0.0, &v(&[x0, v0]), o).unwrap();
        let (e0, mut worst_e, mut defect): (f64, f64, f64) = (energy(r.y()), 0.0, 0.0);
        let (mut u, mut y_old) = (v(&[0.0, 0.0]), r.y().clone());
        let mut contact = x0 >= 0.0;
        loop {
            let (a, b) = r.step(&mut s, 1e3).unwrap();
            defect = defect.max(collocation_defect(&r, &mut s, &y_old, [xc, v0], rtol));
            y_old.copy_from(r.y());
            if r.y()[0] > 0.0 || !contact {
                contact |= r.y()[0] > 0.0;
                if jump.is_none() {
                    worst_e = worst_e.max((energy(r.y()) - e0).abs() / e0);
                }
                continue;
            }
            let (mut lo, mut hi) = (a, b);
            while lo < hi && 0.5 * (lo + hi) > lo && 0.5 * (lo + hi) < hi {
                r.dense(0.5 * (lo + hi), &mut u).unwrap();
                *(if u[0] > 0.0 { &mut lo } else { &mut hi }) = 0.5 * (lo + hi);
            }
            r.dense(hi, &mut u).unwrap();
            let st = r.stats();
            return ((u[1] + v0).abs() / v0, worst_e, st.accepted, defect, st.newton_failures);
        }
    }

    /// The collocation equations of the last step, checked from outside:
    /// the dense polynomial starts at `y_old` and its derivative (verified
    /// against a closed form in `radau_dense_output`) equals `f` at the nodes
    /// `t0 + c_i h`. Returns the worst `h |u' - f|` in units of
    /// `rtol^(2/3) (|u| + scale)` (the solver's own bound is 0.1 of that).
    fn collocation_defect(r: &Radau, s: &mut dyn ImplicitSystem, y_old: &DVector<f64>, sc: [f64; 2], rtol: f64) -> f64 {
        let (a, b) = r.last_step().unwrap();
        let (mut u, mut du, mut f) = (v(&[0.0, 0.0]), v(&[0.0, 0.0]), v(&[0.0, 0.0]));
        r.dense(a, &mut u).unwrap();
        assert!((&u - y_old).abs().max() <= 1e-12 * (1.0 + y_old.abs().max()));
        let mut worst: f64 = 0.0;
        for c in [(4.0 - 6f64.sqrt()) / 10.0, (4.0 + 6f64.sqrt()) / 10.0, 1.0] {
            let t = a + c * (b - a);
            r.dense(t, &mut u).unwrap();
            r.dense_derivative(t, &mut du).unwrap();
            s.rhs(t, &u, &mut f);
            for k in 0..2 {
                worst = worst.max((b - a) * (du[k] - f[k]).abs() / (rtol.powf(2.0 / 3.0) * (u[k].abs() + sc[k])));
            }
        }
        worst
    }

    /// Test 5: Hertz contact: energy, exit velocity, no step collapse with K.
    #[test]
    fn radau_hertz_contact_scale_invariant() {
        let (ev6, ee6, n6, d6, _) = hertz(1e6, 0.0, false, None);
        let (ev12, ee12, n12, d12, _) = hertz(1e12, 0.0, false, None);
        eprintln!("hertz K=1e6: exit err {ev6:.2e}, energy err {ee6:.2e}, {n6} steps, defect {d6:.2e}");
        eprintln!("hertz K=1e12: exit err {ev12:.2e}, energy err {ee12:.2e}, {n12} steps, defect {d12:.2e}");
        assert!(ev6.max(ev12).max(ee6).max(ee12) < 1e-8);
        assert!(n6 <= 2 * n12 && n12 <= 2 * n6);
    }

    /// Test 6: Newton honesty. Contact entered from free flight with the
    /// Jacobian frozen at its free-flight value (which is also what a refresh
    /// at each step start gives for the step crossing the onset): stages in
    /// contact make simplified Newton fail; it must be detected, and every
    /// accepted step must satisfy the collocation equations. Then a force
    /// jump (0 to 1e4 at x = 0, exact exit velocity -v0).
    #[test]
    fn radau_newton_honesty() {
        let (ev, ee, n, d, nf) = hertz(1e12, -1e-2, true, None);
        eprintln!("frozen J, K=1e12: exit err {ev:.2e}, energy err {ee:.2e}, {n} steps, defect {d:.2e}, newton failures {nf}");
        assert!(ev < 1e-8 && ee < 1e-8 && d < 1.0 && nf > 0);
        let (ev, _, n, d, nf) = hertz(1.0, -0.5, false, Some(1e4));
        eprintln!("force jump 1e4: exit err {ev:.2e}, {n} steps, defect {d:.2e}, newton failures {nf}");
        assert!(ev < 1e-8 && d < 1.0);
    }

    /// No panics: bad input and NaN give errors.
    #[test]
    fn radau_errors_not_panics() {
        let mut s = sys(1, |_, y, dy| dy[0] = if y[0] > 1.0 { f64::NAN } else { 1.0 }, |_, _, _| false);
        let bad = RadauOptions { rtol: Tol::Vector(v(&[1e-6, 1e-6])), ..Default::default() };
        assert!(matches!(Radau::new(&mut s, 0.0, &v(&[0.0]), bad), Err(RadauError::InvalidInput(_))));
        assert!(Radau::new(&mut s, 0.0, &v(&[0.0, 1.0]), Default::default()).is_err());
        assert!(matches!(Radau::new(&mut s, 0.0, &v(&[2.0]), Default::default()), Err(RadauError::NonFinite { .. })));
        let mut r = Radau::new(&mut s, 0.0, &v(&[0.0]), Default::default()).unwrap();
        assert!(r.step(&mut s, 0.0).is_err() && r.step(&mut s, f64::NAN).is_err());
        let e = loop {
            if let Err(e) = r.step(&mut s, 2.0) {
                break e;
            }
        };
        eprintln!("NaN beyond y = 1: {e} ({:?})", r.stats());
        assert!(matches!(e, RadauError::NonFinite { t } if (t - 1.0).abs() < 1e-6));
        let few = RadauOptions { max_steps: 3, ..Default::default() };
        let mut r = Radau::new(&mut s, 0.0, &v(&[0.0]), few).unwrap();
        assert!(matches!((0..5).map(|_| r.step(&mut s, 0.9)).find(|x| x.is_err()), Some(Err(RadauError::TooManySteps { .. }))));
    }
}
