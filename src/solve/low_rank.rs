//! The Jacobian of a modal phase with a few nonlinear contacts, kept in its
//! structure, and the shifted systems `(s I - J) x = b` an implicit
//! integrator solves with it, in O(N) instead of a dense O(N^3) LU.
//!
//! The state is `[q; q'; e]` with `N` modes and a few quadrature variables
//! `e` (impulses, dissipated energies). The modal part is block diagonal
//! (`q_i'' = -omega_i^2 q_i - 2 a_i q_i'`) plus one rank-one term per
//! contact `k`, `q'' -= w_k (F_p,k w_k . q + F_pd,k w_k . q')`; every
//! quadrature variable's rate depends on one contact's `w_k . q` and
//! `w_k . q'` and on nothing else. So `s I - J` is block lower triangular:
//! the modal block is `B + U V^T` (`B` 2 x 2 per mode, `u_k = [0; w_k]`,
//! `v_k = [F_p,k w_k; F_pd,k w_k]`), solved by the Woodbury identity with
//! an `nc x nc` capacitance matrix (GVL13 sec. 2.1.4), then the
//! quadrature rows by substitution.

use super::C64 as C;

/// `J = df/dy` of `[q; q'; e]` in low-rank modal form.
#[derive(Clone, Debug, Default)]
pub struct LowRankJacobian {
    pub omega2: Vec<f64>,
    pub two_a: Vec<f64>,
    /// Each contact's direction `w_k` (length `N`).
    pub w: Vec<Vec<f64>>,
    /// `dF_k/dp` and `dF_k/dp'` (the coupling is `-w_k (F_p w_k . q +
    /// F_pd w_k . q')` in the `q''` rows).
    pub fp: Vec<f64>,
    pub fpd: Vec<f64>,
    /// Quadrature row `r`: `e_r' = a_r w_k . q + b_r w_k . q'` (linearised), as `(k, a_r, b_r)`.
    pub rows: Vec<(usize, f64, f64)>,
}

/// `s I - J` factorised for one shift `s`.
#[derive(Clone, Debug, Default)]
pub struct Shifted {
    s: C,
    /// `1 / (s (s + 2 a_i) + omega_i^2)`, per mode.
    inv_det: Vec<C>,
    /// LU (row pivots in `piv`) of the capacitance matrix
    /// `I + V^T B^-1 U`, row-major `nc x nc`.
    capacitance: Vec<C>,
    piv: Vec<usize>,
}

impl LowRankJacobian {
    pub fn modes(&self) -> usize {
        self.omega2.len()
    }

    pub fn dim(&self) -> usize {
        2 * self.modes() + self.rows.len()
    }

    pub fn is_finite(&self) -> bool {
        self.fp.iter().chain(&self.fpd).all(|v| v.is_finite()) && self.rows.iter().all(|r| r.1.is_finite() && r.2.is_finite())
    }

    /// `out = |J| y` for a non-negative `y` (a rounding bound).
    pub fn abs_times(&self, y: &[f64], out: &mut [f64]) {
        let n = self.modes();
        let (yq, rest) = y.split_at(n);
        let yv = &rest[..n];
        let abs_dot = |w: &[f64], x: &[f64]| w.iter().zip(x).map(|(a, b)| a.abs() * b).sum::<f64>();
        let projections: Vec<(f64, f64)> = self.w.iter().map(|w| (abs_dot(w, yq), abs_dot(w, yv))).collect();
        for i in 0..n {
            out[i] = yv[i];
            out[n + i] = self.omega2[i].abs() * yq[i] + self.two_a[i].abs() * yv[i];
        }
        for (k, w) in self.w.iter().enumerate() {
            let coupling = self.fp[k].abs() * projections[k].0 + self.fpd[k].abs() * projections[k].1;
            for i in 0..n {
                out[n + i] += w[i].abs() * coupling;
            }
        }
        for (r, &(k, a, b)) in self.rows.iter().enumerate() {
            out[2 * n + r] = a.abs() * projections[k].0 + b.abs() * projections[k].1;
        }
    }

    /// `s I - J` for the shift `s`, or `None` when it is singular.
    pub fn factor(&self, s: C, out: &mut Shifted) -> bool {
        let (n, nc) = (self.modes(), self.w.len());
        out.s = s;
        out.inv_det.clear();
        for i in 0..n {
            let det = s * (s + self.two_a[i]) + self.omega2[i];
            if det == C::new(0.0, 0.0) {
                return false;
            }
            out.inv_det.push(det.inv());
        }
        // C_kl = delta_kl + (F_p,k + s F_pd,k) sum_i w_ki w_li / det_i.
        out.capacitance.clear();
        for k in 0..nc {
            let gain = C::new(self.fp[k], 0.0) + s * self.fpd[k];
            for l in 0..nc {
                let sum: C = (0..n).map(|i| out.inv_det[i] * (self.w[k][i] * self.w[l][i])).sum();
                out.capacitance.push(if k == l { C::new(1.0, 0.0) } else { C::new(0.0, 0.0) } + gain * sum);
            }
        }
        lu(&mut out.capacitance, nc, &mut out.piv)
    }

    /// Solves `(s I - J) x = b` in place, `b = re + i im`.
    pub fn solve(&self, f: &Shifted, re: &mut [f64], im: &mut [f64]) {
        let (n, nc) = (self.modes(), self.w.len());
        let s = f.s;
        // z = B^-1 b, per mode.
        let mut z: Vec<C> = Vec::with_capacity(2 * n);
        z.resize(2 * n, C::new(0.0, 0.0));
        for i in 0..n {
            let (bq, bv) = (C::new(re[i], im[i]), C::new(re[n + i], im[n + i]));
            z[i] = ((s + self.two_a[i]) * bq + bv) * f.inv_det[i];
            z[n + i] = (s * bv - bq * self.omega2[i]) * f.inv_det[i];
        }
        // y = C^-1 V^T z; x = z - B^-1 U y.
        let mut y: Vec<C> = (0..nc)
            .map(|k| {
                let w = &self.w[k];
                let (pq, pv) = (0..n).fold((C::new(0.0, 0.0), C::new(0.0, 0.0)), |(a, c), i| (a + z[i] * w[i], c + z[n + i] * w[i]));
                pq * self.fp[k] + pv * self.fpd[k]
            })
            .collect();
        lu_solve(&f.capacitance, nc, &f.piv, &mut y);
        for i in 0..n {
            let u: C = (0..nc).map(|l| y[l] * self.w[l][i]).sum::<C>() * f.inv_det[i];
            z[i] -= u;
            z[n + i] -= s * u;
        }
        // The quadrature rows: s x_r - (a_r w_k . x_q + b_r w_k . x_v) = b_r.
        for (r, &(k, a, bb)) in self.rows.iter().enumerate() {
            let w = &self.w[k];
            let (pq, pv) = (0..n).fold((C::new(0.0, 0.0), C::new(0.0, 0.0)), |(x, c), i| (x + z[i] * w[i], c + z[n + i] * w[i]));
            let x = (C::new(re[2 * n + r], im[2 * n + r]) + pq * a + pv * bb) / s;
            re[2 * n + r] = x.re;
            im[2 * n + r] = x.im;
        }
        for j in 0..2 * n {
            re[j] = z[j].re;
            im[j] = z[j].im;
        }
    }
}

/// In-place LU with partial pivoting of a small row-major complex matrix.
fn lu(a: &mut [C], n: usize, piv: &mut Vec<usize>) -> bool {
    piv.clear();
    for k in 0..n {
        let p = (k..n).max_by(|&i, &j| a[i * n + k].norm().total_cmp(&a[j * n + k].norm())).expect("a row");
        piv.push(p);
        if a[p * n + k] == C::new(0.0, 0.0) || !a[p * n + k].norm().is_finite() {
            return false;
        }
        if p != k {
            for j in 0..n {
                a.swap(k * n + j, p * n + j);
            }
        }
        let pivot = a[k * n + k];
        for i in k + 1..n {
            let m = a[i * n + k] / pivot;
            a[i * n + k] = m;
            for j in k + 1..n {
                let akj = a[k * n + j];
                a[i * n + j] -= m * akj;
            }
        }
    }
    true
}

fn lu_solve(a: &[C], n: usize, piv: &[usize], b: &mut [C]) {
    for k in 0..n {
        b.swap(k, piv[k]);
    }
    for i in 0..n {
        for j in 0..i {
            let bj = b[j];
            b[i] -= a[i * n + j] * bj;
        }
    }
    for i in (0..n).rev() {
        for j in i + 1..n {
            let bj = b[j];
            b[i] -= a[i * n + j] * bj;
        }
        b[i] /= a[i * n + i];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The dense `J` of a low-rank Jacobian.
    fn dense(j: &LowRankJacobian) -> Vec<Vec<f64>> {
        let (n, d) = (j.modes(), j.dim());
        let mut m = vec![vec![0.0; d]; d];
        for i in 0..n {
            m[i][n + i] = 1.0;
            m[n + i][i] = -j.omega2[i];
            m[n + i][n + i] = -j.two_a[i];
        }
        for (k, w) in j.w.iter().enumerate() {
            for i in 0..n {
                for l in 0..n {
                    m[n + i][l] -= j.fp[k] * w[i] * w[l];
                    m[n + i][n + l] -= j.fpd[k] * w[i] * w[l];
                }
            }
        }
        for (r, &(k, a, b)) in j.rows.iter().enumerate() {
            for l in 0..n {
                m[2 * n + r][l] = a * j.w[k][l];
                m[2 * n + r][n + l] = b * j.w[k][l];
            }
        }
        m
    }

    #[test]
    fn shifted_solves_match_the_dense_system() {
        let n = 7;
        let j = LowRankJacobian {
            omega2: (0..n).map(|i| (1.0 + i as f64).powi(4) * 3.0).collect(),
            two_a: (0..n).map(|i| 0.02 * (1.0 + i as f64).powi(2)).collect(),
            w: vec![(0..n).map(|i| (0.3 * i as f64).sin() + 0.5).collect(), (0..n).map(|i| 1.0 - 0.1 * i as f64).collect()],
            fp: vec![1e3, 20.0],
            fpd: vec![3.0, 0.0],
            rows: vec![(0, 1e3, 3.0), (1, 20.0, 0.0), (0, -2.0, 5.0), (1, 0.0, 0.0)],
        };
        let d = j.dim();
        let m = dense(&j);
        for s in [C::new(37.0, 0.0), C::new(12.5, 40.0)] {
            let mut f = Shifted::default();
            assert!(j.factor(s, &mut f));
            let (mut re, mut im): (Vec<f64>, Vec<f64>) = ((0..d).map(|i| (i as f64 * 0.7).cos()).collect(), (0..d).map(|i| (i as f64).sin()).collect());
            let (b_re, b_im) = (re.clone(), im.clone());
            j.solve(&f, &mut re, &mut im);
            // Residual of (s I - J) x = b.
            for r in 0..d {
                let mut acc = s * C::new(re[r], im[r]);
                for c in 0..d {
                    acc -= C::new(re[c], im[c]) * m[r][c];
                }
                let err = (acc - C::new(b_re[r], b_im[r])).norm();
                assert!(err < 1e-9 * (1.0 + C::new(b_re[r], b_im[r]).norm()), "row {r}: residual {err:e}");
            }
        }
    }
}
