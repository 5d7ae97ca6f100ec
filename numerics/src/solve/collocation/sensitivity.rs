//! The Jacobian of the collocation's own map: the state at the end of a
//! given sequence of steps as a function of the state at its start (and
//! of each contact's law parameter, the onset speed a hysteretic damping
//! scales with), for a flow's Jacobian through an integrated phase.
//!
//! The discrete map is differentiated, not the exact flow: on each step
//! the nodal forces `f` solve `R(f, y0) = f - law(p(f, y0), p'(f, y0)) =
//! 0` with the contact coordinates affine in both (`p = pf(y0) + Mp f`),
//! so `df/dy0 = A^{-1} (dF/dp dpf/dy0 + dF/dp' dpf'/dy0)`, `A = I - dF/dp
//! Mp - dF/dp' Mv` the very matrix Newton factors; the end state is the
//! free motion (its homogeneous part the modes' propagators) minus every
//! mode's response to the force polynomial, linear in `f`. A held
//! contact's row is the velocity constraint `p' = 0`, and the end state's
//! projection onto the held surfaces is linear too. The derivative is
//! that of the converged step, so it is as accurate as Newton's
//! convergence (a thousandth of the tolerance) and costs one solve with
//! as many right-hand sides as the state has coordinates per step, far
//! less than differencing the steps (two replays per coordinate).
//!
//! The steps are given (the nominal run's, each halved: see
//! [`ForceCollocation::replay_with_jacobian`]): no error control, which would make the map depend on
//! the start state by accept/reject decisions. The last may be cut into
//! pieces shrinking toward a corner at its end, as
//! [`ForceCollocation::single_step`] does at a separation, and the first
//! toward an onset at its start (finer than for the state: see
//! [`ForceCollocation::replay_with_jacobian`]).

use nalgebra::{DMatrix, DVector};

use super::kernels::ladder;
use super::{ForceCollocation, NewtonFailure, PointForces, GRADING};

/// The end state of a replay and its derivatives.
#[derive(Clone, Debug)]
pub struct Replay {
    /// `[q; q'; J; E]` at the end.
    pub y: DVector<f64>,
    /// `d[q; q'](end) / d[q; q'](start)`.
    pub jacobian: DMatrix<f64>,
    /// `d[q; q'](end) / d(law parameter of contact c)`, one column per contact.
    pub parameter: DMatrix<f64>,
}

impl ForceCollocation {
    /// Steps from `(times[0], y0)` over `times` (each interval one step;
    /// the first graded toward a corner at its start when `corners.0`,
    /// the last toward one at its end when `corners.1`), and the Jacobian
    /// of the end state (module doc). A step whose Newton fails is halved
    /// (at most a few times).
    pub fn replay_with_jacobian(&self, forces: &impl PointForces, times: &[f64], y0: &DVector<f64>, corners: (bool, bool)) -> Result<Replay, NewtonFailure> {
        let (n, nc) = (self.n, self.contacts.len());
        let mut me = self.clone();
        let mut y = y0.clone();
        let mut jac = DMatrix::identity(2 * n, 2 * n);
        let mut par = DMatrix::zeros(2 * n, nc);
        let mut pieces: Vec<(f64, f64)> = times.windows(2).filter(|w| w[1] > w[0]).map(|w| (w[0], w[1])).collect();
        // At a corner the force goes as `t^a` and its partials as
        // `t^(a-1)`: the derivative's error over a last piece of `f` of
        // the step is `f^(a+1)`, so the pieces shrink to `tol^(1/(a+1))`
        // where the state's needs `tol^(1/(a+2))` (the options' fraction).
        let e = self.options.corner_fraction.ln() / self.options.tol.ln();
        let smallest = if e > 0.0 && e < 0.5 { self.options.tol.powf(e / (1.0 - e)) } else { self.options.corner_fraction };
        let graded = |a: f64, b: f64| -> Vec<f64> {
            // Fractions of [a, b] from a corner at b: 3/4, 3/16, ...
            let mut cuts = Vec::new();
            let mut remaining = 1.0;
            while remaining / GRADING > smallest {
                remaining /= GRADING;
                cuts.push(1.0 - remaining);
            }
            let _ = (a, b);
            cuts
        };
        if corners.1 {
            if let Some((a, b)) = pieces.pop() {
                let mut t = a;
                for f in graded(a, b) {
                    let next = a + f * (b - a);
                    if next > t && next < b {
                        pieces.push((t, next));
                        t = next;
                    }
                }
                pieces.push((t, b));
            }
        }
        if corners.0 && !pieces.is_empty() {
            let (a, b) = pieces.remove(0);
            let mut front = Vec::new();
            let mut t = b;
            for f in graded(a, b) {
                let next = b - f * (b - a);
                if next < t && next > a {
                    front.push((next, t));
                    t = next;
                }
            }
            front.push((a, t));
            front.reverse();
            pieces.splice(0..0, front);
        }
        // Each step halved: the step-size control bounds the state's
        // error, and the derivative of a step of that size is less
        // accurate (the one-mass Hertz oscillator over a contact: 1.5e-6
        // against differences of the simulation, halved 2.6e-8).
        let pieces: Vec<(f64, f64)> = pieces.iter().flat_map(|&(a, b)| [(a, a + 0.5 * (b - a)), (a + 0.5 * (b - a), b)]).filter(|(a, b)| b > a).collect();
        for (a, b) in pieces {
            me.replay_piece(forces, a, b, &mut y, &mut jac, &mut par, 0)?;
        }
        Ok(Replay { y, jacobian: jac, parameter: par })
    }

    /// One step `[a, b]` of the replay (halved on a Newton failure).
    #[allow(clippy::too_many_arguments)]
    fn replay_piece(&mut self, forces: &impl PointForces, a: f64, b: f64, y: &mut DVector<f64>, jac: &mut DMatrix<f64>, par: &mut DMatrix<f64>, depth: u32) -> Result<(), NewtonFailure> {
        let h = b - a;
        match self.attempt(forces, a, y, h, ladder(h) == h) {
            Ok(attempt) => {
                let (dy, dp) = self.step_sensitivity(forces, a, y, h);
                *jac = &dy * &*jac;
                *par = &dy * &*par + dp;
                *y = attempt.y1;
                self.last = Some(attempt.step);
                Ok(())
            }
            Err(e) if depth >= 6 => Err(e),
            Err(_) => {
                let mid = a + 0.5 * h;
                self.replay_piece(forces, a, mid, y, jac, par, depth + 1)?;
                self.replay_piece(forces, mid, b, y, jac, par, depth + 1)
            }
        }
    }

    /// The derivatives of the step just attempted (its converged nodal
    /// forces are in the scratch) from `(t0, y0)` over `h`: with respect
    /// to `[q; q']` at its start, and to each contact's law parameter.
    fn step_sensitivity(&self, forces: &impl PointForces, t0: f64, y0: &DVector<f64>, h: f64) -> (DMatrix<f64>, DMatrix<f64>) {
        let _ = (t0, y0);
        let (n, s, nc) = (self.n, self.scheme.s, self.contacts.len());
        let ns = nc * s;
        let mono = s + 2;
        let kernels = self.kernels_for(h, false, false);
        let projected = self.projected_for(&kernels, false);
        let (mp, mv) = (&projected.mp, &projected.mv);
        let scratch = self.scratch.borrow();
        // The converged nodes' coordinates.
        let p = mp * &scratch.f;
        let pd = mv * &scratch.f;
        // The homogeneous propagator of mode j at point i (nodes, then the end).
        let prop = |i: usize, j: usize| -> [f64; 4] {
            let osc = &self.dynamics.oscillators[j];
            let (ec, es) = kernels.free[i * n + j];
            [ec + osc.a * es, es, -osc.omega * osc.omega * es, ec - osc.a * es]
        };
        // A and the right-hand sides.
        let mut a = DMatrix::zeros(ns, ns);
        let mut rhs = DMatrix::zeros(ns, 2 * n + nc);
        for c in 0..nc {
            let d = &self.contacts[c].d;
            for i in 0..s {
                let row = c * s + i;
                let (pc, pdc) = (p[row] + scratch.pf[c * (s + 1) + i], pd[row] + scratch.pdf[c * (s + 1) + i]);
                // d pf / d y0 and d pf' / d y0 at this node.
                let mut gp = DVector::zeros(2 * n);
                let mut gv = DVector::zeros(2 * n);
                for j in 0..n {
                    let e = prop(i, j);
                    gp[j] = d[j] * e[0];
                    gp[n + j] = d[j] * e[1];
                    gv[j] = d[j] * e[2];
                    gv[n + j] = d[j] * e[3];
                }
                if forces.held(c) {
                    let scale = 1.0 / mv[(row, row)];
                    for col in 0..ns {
                        a[(row, col)] = mv[(row, col)] * scale;
                    }
                    for k in 0..2 * n {
                        rhs[(row, k)] = -scale * gv[k];
                    }
                    continue;
                }
                let (_, dfdp, dfdpd) = forces.force(c, pc, pdc);
                for col in 0..ns {
                    a[(row, col)] = if row == col { 1.0 } else { 0.0 } - (dfdp * mp[(row, col)] + dfdpd * mv[(row, col)]);
                }
                for k in 0..2 * n {
                    rhs[(row, k)] = dfdp * gp[k] + dfdpd * gv[k];
                }
                rhs[(row, 2 * n + c)] = forces.parameter_partial(c, pc, pdc);
            }
        }
        let df = a.lu().solve(&rhs).unwrap_or_else(|| DMatrix::zeros(ns, 2 * n + nc));
        // The force polynomials' coefficients per column.
        let mut alpha = DMatrix::zeros(nc * s, 2 * n + nc);
        let mut values = vec![0.0; s];
        let mut coef = vec![0.0; s];
        for col in 0..2 * n + nc {
            for c in 0..nc {
                for i in 0..s {
                    values[i] = df[(c * s + i, col)];
                }
                self.scheme.monomials(&values, &mut coef);
                for m in 0..s {
                    alpha[(c * s + m, col)] = coef[m];
                }
            }
        }
        // The end state: the propagator minus each mode's response.
        let r = &kernels.responses;
        let mut full = DMatrix::zeros(2 * n, 2 * n + nc);
        for j in 0..n {
            let e = prop(s, j);
            full[(j, j)] = e[0];
            full[(j, n + j)] = e[1];
            full[(n + j, j)] = e[2];
            full[(n + j, n + j)] = e[3];
            let base = (s * n + j) * mono;
            for c in 0..nc {
                let dj = self.contacts[c].d[j];
                if dj == 0.0 {
                    continue;
                }
                for m in 0..s {
                    let rr = r[base + m];
                    for col in 0..2 * n + nc {
                        let am = alpha[(c * s + m, col)];
                        full[(j, col)] -= dj * am * rr[0];
                        full[(n + j, col)] -= dj * am * rr[1];
                    }
                }
            }
        }
        // The projection onto the held surfaces (linear: the same for q and q').
        let held: Vec<usize> = (0..nc).filter(|&c| forces.held(c)).collect();
        if !held.is_empty() {
            let dmat = DMatrix::from_columns(&held.iter().map(|&c| self.contacts[c].d.clone()).collect::<Vec<_>>());
            if let Some(inv) = (dmat.transpose() * &dmat).try_inverse() {
                let proj = DMatrix::identity(n, n) - &dmat * inv * dmat.transpose();
                let top = &proj * full.rows(0, n);
                let bottom = &proj * full.rows(n, n);
                full.rows_mut(0, n).copy_from(&top);
                full.rows_mut(n, n).copy_from(&bottom);
            }
        }
        (full.columns(0, 2 * n).into_owned(), full.columns(2 * n, nc).into_owned())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::collocation::{CollocationOptions, PointContact};
    use crate::solve::{FreeDynamics, ModalForcing, Oscillator};

    /// `k p^1.5 (1 + c p' / v)` on one point, `v` the parameter.
    struct Hysteretic {
        k: f64,
        c: f64,
        v: f64,
    }

    impl PointForces for Hysteretic {
        fn force(&self, _i: usize, p: f64, pd: f64) -> (f64, f64, f64) {
            if p <= 0.0 {
                return (0.0, 0.0, 0.0);
            }
            let f = self.k * p.powf(1.5) * (1.0 + self.c * pd / self.v);
            if f <= 0.0 {
                return (0.0, 0.0, 0.0);
            }
            (f, 1.5 * self.k * p.sqrt() * (1.0 + self.c * pd / self.v), self.k * p.powf(1.5) * self.c / self.v)
        }
        fn dissipation_rate(&self, _i: usize, _p: f64, _pd: f64, _force: f64) -> f64 {
            0.0
        }
        fn parameter_partial(&self, i: usize, p: f64, pd: f64) -> f64 {
            let f = self.force(i, p, pd).0;
            if f == 0.0 {
                0.0
            } else {
                -self.k * p.powf(1.5) * self.c * pd / (self.v * self.v)
            }
        }
    }

    /// The replay's Jacobian against central differences of the replay
    /// itself (the same steps from moved start states and parameter).
    #[test]
    fn replay_jacobian_matches_central_differences() {
        let oscillators = vec![Oscillator::new(3.0, 0.02), Oscillator::new(40.0, 0.02), Oscillator::new(400.0, 0.05)];
        let mut forcing = ModalForcing::zero(3);
        forcing.constant = DVector::from_vec(vec![60.0, -48.0, 36.0]);
        let dynamics = FreeDynamics::new(oscillators, forcing);
        let d = DVector::from_vec(vec![1.0, -0.8, 0.6]);
        let law = Hysteretic { k: 3e4, c: 0.2, v: 0.5 };
        let y0 = DVector::from_vec(vec![0.01, 0.0, 0.0, 0.5, 0.1, -0.2, 0.0, 0.0]);
        let options = CollocationOptions { tol: 1e-12, q_scale: 0.01, v_scale: 0.5, h_init: 1e-4, h_max: 0.05, corner_fraction: 1e-12f64.powf(2.0 / 7.0) };
        let mut col = ForceCollocation::new(dynamics, vec![PointContact { d, gap: 0.0 }], 0.0, y0.clone(), options);
        let mut times = vec![0.0];
        while col.t() < 0.05 {
            times.push(col.step(&law).unwrap().1);
        }
        let base = col.replay_with_jacobian(&law, &times, &y0, (false, false)).unwrap();
        for k in 0..7 {
            let scale = if k == 6 { law.v } else { y0.iter().take(6).fold(0.0f64, |m, x| m.max(x.abs())) };
            let h = 1e-6 * scale;
            let run = |sign: f64| {
                let mut y = y0.clone();
                let mut l = Hysteretic { ..law };
                if k < 6 {
                    y[k] += sign * h;
                } else {
                    l.v += sign * h;
                }
                col.replay_with_jacobian(&l, &times, &y, (false, false)).unwrap().y
            };
            let fd = (run(1.0) - run(-1.0)) / (2.0 * h);
            let col_k = if k < 6 { base.jacobian.column(k).into_owned() } else { base.parameter.column(0).into_owned() };
            for r in 0..6 {
                let norm = base.jacobian.row(r).amax().max(1e-12);
                assert!((fd[r] - col_k[r]).abs() < 1e-6 * norm, "d y[{r}] / d x[{k}]: {} vs {}", col_k[r], fd[r]);
            }
        }
    }
}
