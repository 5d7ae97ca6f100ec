//! The equations of a phase with a nonlinear contact (a stop whose law's
//! phase term is nonlinear, pressed or penetrated), integrated instead of
//! solved in closed form.
//!
//! The structure stays linear: `q'' + 2 a q' + omega^2 q = f(t) - sum_i
//! side_i w_i F_i` with each engaged stop's force `F_i(p_i, p_i')` from its
//! law (Hertz: DWZ eqs. 2-4). The integrated state is `[q; q'; J; E]`:
//! besides the modal state it carries, per engaged stop, the impulse `J_i =
//! int F_i dt` and the energy its damping dissipates `E_i = int (F_i -
//! F_spring,i) p_i' dt`, so both come out of the integration to its accuracy.

use nalgebra::{DMatrix, DVector};

use crate::contact::{Contact, Geometry, Law};
use crate::solve::low_rank::LowRankJacobian;
use crate::solve::ModalForcing;

/// An engaged stop in a nonlinear phase: a force of the state.
#[derive(Clone, Debug)]
pub struct NonlinearContact {
    /// The stop's index in the model.
    pub stop: usize,
    pub law: Law,
    pub geometry: Geometry,
    pub contact: Contact,
    pub onset_speed: f64,
}

impl NonlinearContact {
    /// The force and its partial derivatives `(F, dF/dp, dF/dp')`, zero
    /// where the law does not push.
    pub fn force(&self, p: f64, pd: f64) -> (f64, f64, f64) {
        if p <= 0.0 {
            return (0.0, 0.0, 0.0);
        }
        let (f, dp, dpd) = self.law.raw_force(p, pd, self.onset_speed);
        if f > 0.0 {
            (f, dp, dpd)
        } else {
            (0.0, 0.0, 0.0)
        }
    }

    /// The spring's share of the force and its derivative (the rest dissipates).
    pub fn spring_force(&self, p: f64) -> (f64, f64) {
        self.law.spring_force(p)
    }
}

/// The modal equations of one nonlinear phase as a first-order system.
#[derive(Clone, Debug)]
pub struct NonlinearPhase {
    pub n: usize,
    pub omega2: DVector<f64>,
    pub two_a: DVector<f64>,
    pub forcing: ModalForcing,
    pub contacts: Vec<NonlinearContact>,
    f: DVector<f64>,
}

impl NonlinearPhase {
    pub fn new(omega2: DVector<f64>, two_a: DVector<f64>, forcing: ModalForcing, contacts: Vec<NonlinearContact>) -> Self {
        let n = omega2.len();
        NonlinearPhase { n, omega2, two_a, forcing, contacts, f: DVector::zeros(n) }
    }

    /// Length of the integrated state.
    pub fn dim(&self) -> usize {
        2 * self.n + 2 * self.contacts.len()
    }

    /// `dy = F(t, y)`.
    pub fn rhs(&mut self, t: f64, y: &[f64], dy: &mut [f64]) {
        let n = self.n;
        let (q, rest) = y.split_at(n);
        let qd = &rest[..n];
        self.forcing.derivative(t, 0, &mut self.f);
        dy[..n].copy_from_slice(qd);
        for j in 0..n {
            dy[n + j] = self.f[j];
        }
        for j in 0..n {
            dy[n + j] -= self.omega2[j] * q[j] + self.two_a[j] * qd[j];
        }
        let nc = self.contacts.len();
        for (i, c) in self.contacts.iter().enumerate() {
            let g = &c.geometry;
            let p = g.side * dot(g.w.as_slice(), q) - g.gap;
            let pd = g.side * dot(g.w.as_slice(), qd);
            let (force, _, _) = c.force(p, pd);
            for j in 0..n {
                dy[n + j] -= g.side * g.w[j] * force;
            }
            dy[2 * n + i] = force;
            dy[2 * n + nc + i] = if force > 0.0 { (force - c.spring_force(p).0) * pd } else { 0.0 };
        }
    }

    /// `dF/dy`.
    pub fn jacobian(&mut self, _t: f64, y: &[f64], jac: &mut DMatrix<f64>) {
        let n = self.n;
        let nc = self.contacts.len();
        jac.fill(0.0);
        for j in 0..n {
            jac[(j, n + j)] = 1.0;
        }
        for j in 0..n {
            jac[(n + j, j)] = -self.omega2[j];
            jac[(n + j, n + j)] = -self.two_a[j];
        }
        let (q, rest) = y.split_at(n);
        let qd = &rest[..n];
        for (i, c) in self.contacts.iter().enumerate() {
            let g = &c.geometry;
            let p = g.side * dot(g.w.as_slice(), q) - g.gap;
            let pd = g.side * dot(g.w.as_slice(), qd);
            let (force, dp, dpd) = c.force(p, pd);
            // dp/dq = side w, dp'/dq' = side w; side^2 = 1.
            for j in 0..n {
                for m in 0..n {
                    let wjm = g.w[j] * g.w[m];
                    jac[(n + j, m)] -= dp * wjm;
                    jac[(n + j, n + m)] -= dpd * wjm;
                }
                jac[(2 * n + i, j)] = dp * g.side * g.w[j];
                jac[(2 * n + i, n + j)] = dpd * g.side * g.w[j];
            }
            if force > 0.0 {
                // E' = (F - F_spring) p'.
                let (spring, dspring) = c.spring_force(p);
                for j in 0..n {
                    jac[(2 * n + nc + i, j)] = (dp - dspring) * pd * g.side * g.w[j];
                    jac[(2 * n + nc + i, n + j)] = (dpd * pd + (force - spring)) * g.side * g.w[j];
                }
            }
        }
    }

    /// `dF/dy` in low-rank modal form (the same entries as [`Self::jacobian`]).
    pub fn low_rank_jacobian(&self, y: &[f64], jac: &mut LowRankJacobian) {
        let n = self.n;
        let nc = self.contacts.len();
        if jac.omega2.len() != n || jac.w.len() != nc {
            jac.omega2 = self.omega2.as_slice().to_vec();
            jac.two_a = self.two_a.as_slice().to_vec();
            jac.w = self.contacts.iter().map(|c| c.geometry.w.as_slice().to_vec()).collect();
            jac.fp = vec![0.0; nc];
            jac.fpd = vec![0.0; nc];
            jac.rows = vec![(0, 0.0, 0.0); 2 * nc];
        }
        for (i, c) in self.contacts.iter().enumerate() {
            let (p, pd) = self.penetration(i, y);
            let (force, dp, dpd) = c.force(p, pd);
            let side = c.geometry.side;
            jac.fp[i] = dp;
            jac.fpd[i] = dpd;
            jac.rows[i] = (i, dp * side, dpd * side);
            jac.rows[nc + i] = if force > 0.0 {
                // E' = (F - F_spring) p'.
                let (spring, dspring) = c.spring_force(p);
                (i, (dp - dspring) * pd * side, (dpd * pd + (force - spring)) * side)
            } else {
                (i, 0.0, 0.0)
            };
        }
    }

    /// Penetration and its rate of contact `i` in the integrated state `y`.
    pub fn penetration(&self, i: usize, y: &[f64]) -> (f64, f64) {
        let g = &self.contacts[i].geometry;
        let n = self.n;
        (g.side * dot(g.w.as_slice(), &y[..n]) - g.gap, g.side * dot(g.w.as_slice(), &y[n..2 * n]))
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::{Hertz, HertzDamping};

    #[test]
    fn jacobian_matches_finite_differences() {
        let n = 3;
        let w = DVector::from_vec(vec![1.0, -0.7, 0.4]);
        let contact = NonlinearContact {
            stop: 0,
            law: Law::Hertz(Hertz { stiffness: 2e6, damping_coefficient: 0.0, damping: HertzDamping::LankaraniNikravesh, restitution: 0.5 }),
            geometry: Geometry { w, gap: 1e-3, side: 1.0 },
            contact: Contact::Pressed,
            onset_speed: 0.3,
        };
        let mut phase = NonlinearPhase::new(
            DVector::from_vec(vec![1.0, 30.0, 200.0]),
            DVector::from_vec(vec![0.01, 0.1, 0.3]),
            ModalForcing::zero(n),
            vec![contact],
        );
        let y = vec![2e-3, 1e-4, -2e-4, 0.1, -0.05, 0.02, 0.0, 0.0];
        let dim = phase.dim();
        let mut jac = DMatrix::zeros(dim, dim);
        phase.jacobian(0.0, &y, &mut jac);
        let (mut a, mut b) = (vec![0.0; dim], vec![0.0; dim]);
        for k in 0..dim {
            let h = 1e-7 * y[k].abs().max(1e-4);
            let (mut yp, mut ym) = (y.clone(), y.clone());
            yp[k] += h;
            ym[k] -= h;
            phase.rhs(0.0, &yp, &mut a);
            phase.rhs(0.0, &ym, &mut b);
            for r in 0..dim {
                let fd = (a[r] - b[r]) / (2.0 * h);
                let scale = jac[(r, k)].abs().max(1e-3);
                assert!((fd - jac[(r, k)]).abs() <= 1e-5 * scale, "({r},{k}): {fd} vs {}", jac[(r, k)]);
            }
        }
    }
}
