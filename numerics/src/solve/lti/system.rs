//! The structure of one coupled phase and its complex modal
//! decomposition, formed once per phase, and the cache that shares the
//! decompositions between runs of one model.

use std::sync::{Arc, Mutex};

use nalgebra::{DMatrix, DVector};

use super::LtiError;
use crate::solve::complex::C64;
use crate::solve::functional::Functional;
use crate::solve::modal_state::ModalState;

/// The structure of one coupled phase, independent of the load and state.
#[derive(Clone, Debug)]
pub struct CoupledSystem {
    n_modes: usize,
    /// Constraint directions (columns) and their targets `W^T q = d`.
    w: DMatrix<f64>,
    /// `(W^T W)^-1`.
    gram_inv: DMatrix<f64>,
    /// Full stiffness and damping in modal coordinates.
    k: DMatrix<f64>,
    d: DMatrix<f64>,
    /// Orthonormal basis of the free directions (N x n), and `Z^T`
    /// (formed once: every stick projects with it).
    pub(super) z: DMatrix<f64>,
    z_t: DMatrix<f64>,
    /// Eigenvalues and eigenvectors of `[[0, I], [-Z'KZ, -Z'DZ]]`.
    pub(super) eig: DVector<C64>,
    pub(super) v: DMatrix<C64>,
    pub(super) v_inv: DMatrix<C64>,
    /// `1 / L_k` and `|L_k|`, used by every probe.
    pub(super) eig_inv: DVector<C64>,
    pub(super) eig_abs: Vec<f64>,
    /// `eig[k] = conj(eig[k - 1])` exactly: the exponential of a conjugate
    /// pair is computed once.
    pub(super) conjugate_of_previous: Vec<bool>,
    /// Besides, column `k` of `V` is exactly the conjugate of column
    /// `k - 1`: for a real state under real loads coordinate `k` is then
    /// the conjugate of coordinate `k - 1` (rows `k - 1`, `k` of `V^-1` are
    /// conjugates), and a probe computes one coordinate of the pair.
    pub(super) mirrors_previous: Vec<bool>,
    /// The coordinates by increasing `|L_k|` (conjugate pairs adjacent).
    pub(super) by_rate: Vec<usize>,
    /// [`Self::reaction_functionals`], formed once.
    reactions: Vec<Functional>,
}

impl CoupledSystem {
    pub fn new(k: DMatrix<f64>, d: DMatrix<f64>, w: DMatrix<f64>) -> Result<Self, LtiError> {
        let n_modes = k.nrows();
        let m = w.ncols();
        let z = if m == 0 {
            DMatrix::identity(n_modes, n_modes)
        } else {
            let qr = w.clone().qr();
            let q_full = full_q(&qr, n_modes);
            q_full.columns(m, n_modes - m).into_owned()
        };
        let gram_inv = (w.transpose() * &w).try_inverse().unwrap_or_else(|| DMatrix::zeros(m, m));
        let n = n_modes - m;
        let ky = z.transpose() * &k * &z;
        let dy = z.transpose() * &d * &z;
        let (eig, v, v_inv) = if n == 0 {
            (DVector::zeros(0), DMatrix::zeros(0, 0), DMatrix::zeros(0, 0))
        } else {
            // Energy-scaled first-order form: with `Z^T K Z = Q W^2 Q^T`
            // (orthogonal Q) and `u = [W Q^T y; Q^T y']`, the system matrix is
            // `[[0, W], [-W, -Q^T D Q]]`, nearly normal for light damping, so
            // its eigenvectors are well conditioned however far apart the
            // frequencies are (a stop 1e12 times stiffer than the structure
            // included); `[y; y'] = T u` with `T = diag(Q W^-1, Q)`.
            let sym = ky.clone().symmetric_eigen();
            let lowest = sym.eigenvalues.min();
            if !(lowest > 0.0) {
                return Err(LtiError::Eigen(format!("the stiffness of the contact phase is not positive definite (eigenvalue {lowest:e})")));
            }
            let q = refine_symmetric_eigenvectors(&ky, sym.eigenvectors);
            // The eigensolver's eigenvalues carry an absolute error of
            // eps |K| (eps omega_max^2): a relative 1e-10 on the slowest
            // frequency at 20 modes of a cantilever, which accumulates as
            // phase. The Rayleigh quotient of each (accurate) eigenvector is
            // second-order accurate and sums terms of one sign for the
            // dominant part: relative accuracy for every frequency.
            let w_freq = DVector::from_fn(n, |k, _| {
                let v = q.column(k);
                (v.dot(&(&ky * v)) / v.norm_squared()).sqrt()
            });
            let dq = q.transpose() * &dy * &q;
            let a = DMatrix::<f64>::from_fn(2 * n, 2 * n, |i, j| match (i < n, j < n) {
                (true, true) => 0.0,
                (true, false) => {
                    if j - n == i {
                        w_freq[i]
                    } else {
                        0.0
                    }
                }
                (false, true) => {
                    if i - n == j {
                        -w_freq[j]
                    } else {
                        0.0
                    }
                }
                (false, false) => -dq[(i - n, j - n)],
            });
            let (eig, mut vu) = super::eigen::real_eigen(a).map_err(LtiError::Eigen)?;
            for mut column in vu.column_iter_mut() {
                let norm = column.norm();
                column.unscale_mut(norm);
            }
            let vu_inv = vu.clone().lu().try_inverse().ok_or(LtiError::IllConditioned(f64::INFINITY))?;
            let cond = vu.norm() * vu_inv.norm();
            if !(cond < 1e10) {
                return Err(LtiError::IllConditioned(cond));
            }
            // The same for the first-order eigenvalues: the two-sided
            // Rayleigh quotient `(l A r) / (l r)` with the left eigenvectors
            // (rows of the inverse) is second-order accurate. `A U` from the
            // blocks: `[W U_b; -W U_t - D_q U_b]`.
            let damped = real_times_complex(&dq, &vu.rows(n, n).into_owned());
            let au = DMatrix::<C64>::from_fn(2 * n, 2 * n, |i, j| {
                if i < n {
                    vu[(i + n, j)] * w_freq[i]
                } else {
                    -(vu[(i - n, j)] * w_freq[i - n]) - damped[(i - n, j)]
                }
            });
            let eig = DVector::from_fn(2 * n, |k, _| {
                let (mut lr, mut lar) = (C64::new(0.0, 0.0), C64::new(0.0, 0.0));
                for i in 0..2 * n {
                    lr += vu_inv[(k, i)] * vu[(i, k)];
                    lar += vu_inv[(k, i)] * au[(i, k)];
                }
                let refined = lar / lr;
                if refined.re.is_finite() && refined.im.is_finite() && lr.norm() > 0.5 {
                    refined
                } else {
                    eig[k]
                }
            });
            let top = DMatrix::<f64>::from_fn(n, n, |i, j| q[(i, j)] / w_freq[j]);
            let v_top = real_times_complex(&top, &vu.rows(0, n).into_owned());
            let v_bottom = real_times_complex(&q, &vu.rows(n, n).into_owned());
            let scaled_qt = DMatrix::<f64>::from_fn(n, n, |i, j| q[(j, i)] * w_freq[i]);
            let qt = q.transpose();
            let v_inv_left = complex_times_real(&vu_inv.columns(0, n).into_owned(), &scaled_qt);
            let v_inv_right = complex_times_real(&vu_inv.columns(n, n).into_owned(), &qt);
            let v = DMatrix::from_fn(2 * n, 2 * n, |i, j| if i < n { v_top[(i, j)] } else { v_bottom[(i - n, j)] });
            let v_inv = DMatrix::from_fn(2 * n, 2 * n, |i, j| if j < n { v_inv_left[(i, j)] } else { v_inv_right[(i, j - n)] });
            (eig, v, v_inv)
        };
        // A real system's eigenvalues come in conjugate pairs (adjacent from
        // the real Schur form); refined separately they may differ in the
        // last bits: made exact conjugates.
        let mut eig = eig;
        let mut conjugate_of_previous = vec![false; eig.len()];
        for k in 1..eig.len() {
            let (a, b) = (eig[k - 1], eig[k]);
            if !conjugate_of_previous[k - 1] && a.im != 0.0 && (b - a.conj()).norm() <= 1e-12 * a.norm() {
                eig[k] = a.conj();
                conjugate_of_previous[k] = true;
            }
        }
        // The eigensolver returns a complex pair's vectors as exact
        // conjugates (from one real Schur block); checked, not assumed.
        let mirrors_previous: Vec<bool> = (0..eig.len())
            .map(|k| conjugate_of_previous[k] && v.column(k).iter().zip(v.column(k - 1).iter()).all(|(a, b)| *a == b.conj()))
            .collect();
        let eig_inv = eig.map(|l| C64::new(1.0, 0.0) / l);
        let eig_abs: Vec<f64> = eig.iter().map(|l| l.norm()).collect();
        let mut by_rate: Vec<usize> = (0..eig.len()).collect();
        by_rate.sort_by(|&a, &b| eig_abs[a].total_cmp(&eig_abs[b]));
        let reactions = reaction_functionals(&k, &d, &w, &gram_inv);
        let z_t = z.transpose();
        Ok(CoupledSystem { n_modes, w, gram_inv, k, d, z, z_t, eig, v, v_inv, eig_inv, eig_abs, conjugate_of_previous, mirrors_previous, by_rate, reactions })
    }

    pub fn n_modes(&self) -> usize {
        self.n_modes
    }

    /// The fastest rate in the phase, `max |L_k|` (0 when fully constrained).
    pub fn fastest(&self) -> f64 {
        self.eig.iter().map(|l| l.norm()).fold(0.0, f64::max)
    }

    pub(super) fn n_free(&self) -> usize {
        self.z.ncols()
    }

    /// `q_c`, the minimum-norm solution of `W^T q = targets`.
    pub fn q_c(&self, targets: &DVector<f64>) -> DVector<f64> {
        &self.w * (&self.gram_inv * targets)
    }

    /// The constraint reactions `lambda = -(W^T W)^-1 W^T (f - D qd - K q)`
    /// (VSM12 eq. 33, one row per held contact) as functionals.
    pub fn reaction_functionals(&self) -> Vec<Functional> {
        self.reactions.clone()
    }

    /// Projects a state onto the constraints `W^T q = targets`, `W^T qd = 0`.
    pub fn project(&self, targets: &DVector<f64>, state: &mut ModalState) {
        if self.w.ncols() == 0 {
            return;
        }
        // q = q_c + Z Z^T (q - q_c), qd = Z Z^T qd, in the state's own
        // storage (a stick does this; the same products as by operators).
        let q_c = self.q_c(targets);
        state.q -= &q_c;
        let y = &self.z_t * &state.q;
        self.z.mul_to(&y, &mut state.q);
        state.q += &q_c;
        let yd = &self.z_t * &state.qd;
        self.z.mul_to(&yd, &mut state.qd);
    }
}

/// See [`CoupledSystem::reaction_functionals`].
fn reaction_functionals(k: &DMatrix<f64>, d: &DMatrix<f64>, w: &DMatrix<f64>, gram_inv: &DMatrix<f64>) -> Vec<Functional> {
    let wg = w * gram_inv;
    let kq = k * &wg;
    let dq = d * &wg;
    (0..w.ncols())
        .map(|s| Functional { offset: 0.0, q: kq.column(s).into_owned(), qd: Some(dq.column(s).into_owned()), f: Some(-wg.column(s).into_owned()) })
        .collect()
}

/// The contact phases' decompositions, shared by every simulation of one
/// model (its clones hold the same cache): a phase's [`CoupledSystem`]
/// depends only on `K`, `D` and `W`, so a model run many times (a study's
/// repeats, a restart, a benchmark) decomposes each active set once.
/// Entries are found by the matrices themselves, bit for bit: a model
/// changed after it was built never meets a stale one. At most
/// [`SystemCache::CAPACITY`] entries, the oldest dropped first.
#[derive(Clone, Default)]
pub struct SystemCache(Arc<Mutex<Vec<Arc<CoupledSystem>>>>);

impl SystemCache {
    pub const CAPACITY: usize = 64;

    /// The decomposition of `(K, D, W)`, from the cache or built now.
    pub fn get_or_build(&self, k: DMatrix<f64>, d: DMatrix<f64>, w: DMatrix<f64>) -> Result<Arc<CoupledSystem>, LtiError> {
        let same = |s: &CoupledSystem| s.k == k && s.d == d && s.w == w;
        if let Some(s) = self.entries().iter().find(|s| same(s)) {
            return Ok(s.clone());
        }
        let system = Arc::new(CoupledSystem::new(k, d, w)?);
        let mut entries = self.entries();
        if entries.len() >= Self::CAPACITY {
            entries.remove(0);
        }
        entries.push(system.clone());
        Ok(system)
    }

    /// A cache of its own holding the newest `keep` decompositions of this
    /// one (shared, not copied): what a model hands the next one (a sweep's
    /// next point), bounded so that points whose matrices all differ do not
    /// pile up decompositions.
    pub fn newest(&self, keep: usize) -> SystemCache {
        let entries = self.entries();
        let first = entries.len().saturating_sub(keep);
        SystemCache(Arc::new(Mutex::new(entries[first..].to_vec())))
    }

    /// The number of decompositions held.
    pub fn len(&self) -> usize {
        self.entries().len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    fn entries(&self) -> std::sync::MutexGuard<'_, Vec<Arc<CoupledSystem>>> {
        // A panic elsewhere while the lock was held leaves complete entries.
        self.0.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

/// The cache is not part of a model's value: two models are equal whatever
/// they have decomposed.
impl PartialEq for SystemCache {
    fn eq(&self, _other: &Self) -> bool {
        true
    }
}

impl std::fmt::Debug for SystemCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "SystemCache({} decompositions)", self.len())
    }
}

/// `a b` for real `a` and complex `b`, as two real products (nalgebra's
/// real matrix product is blocked; its complex one is not).
fn real_times_complex(a: &DMatrix<f64>, b: &DMatrix<C64>) -> DMatrix<C64> {
    let re = a * b.map(|z| z.re);
    let im = a * b.map(|z| z.im);
    re.zip_map(&im, C64::new)
}

/// `a b` for complex `a` and real `b`.
fn complex_times_real(a: &DMatrix<C64>, b: &DMatrix<f64>) -> DMatrix<C64> {
    let re = a.map(|z| z.re) * b;
    let im = a.map(|z| z.im) * b;
    re.zip_map(&im, C64::new)
}

/// One step of first-order refinement of the eigenvectors of a symmetric
/// matrix: with `M = Q^T (K Q)` nearly diagonal, `q_j += sum_i q_i M_ij /
/// (M_jj - M_ii)`, then orthonormalised. The eigensolver's vectors carry
/// errors of `eps |K| / gap`, which for a graded stiffness (frequencies from
/// 1e2 to 1e5 rad/s) mix the slow modes by 1e-12; the residual `K Q` is
/// formed from the matrix itself, so one step brings them to rounding.
/// Near-degenerate pairs are left alone (their mixing is free).
fn refine_symmetric_eigenvectors(k: &DMatrix<f64>, q: DMatrix<f64>) -> DMatrix<f64> {
    let n = q.ncols();
    let m = q.transpose() * (k * &q);
    let mut step = DMatrix::identity(n, n);
    for j in 0..n {
        for i in 0..n {
            let gap = m[(j, j)] - m[(i, i)];
            if i != j && gap.abs() > 1e-6 * m[(i, i)].abs().max(m[(j, j)].abs()) {
                step[(i, j)] = m[(i, j)] / gap;
            }
        }
    }
    let mut out = q * step;
    // Modified Gram-Schmidt, slowest first (the columns are nearly orthonormal).
    let order: Vec<usize> = {
        let mut o: Vec<usize> = (0..n).collect();
        o.sort_by(|&a, &b| m[(a, a)].total_cmp(&m[(b, b)]));
        o
    };
    for (idx, &j) in order.iter().enumerate() {
        for &i in &order[..idx] {
            let proj = out.column(i).dot(&out.column(j));
            let ci = out.column(i).into_owned();
            out.column_mut(j).axpy(-proj, &ci, 1.0);
        }
        let norm = out.column(j).norm();
        out.column_mut(j).unscale_mut(norm);
    }
    out
}

/// Builds the full orthogonal factor of a QR decomposition (nalgebra keeps a
/// thin one): Householder reflections applied to the identity.
fn full_q(qr: &nalgebra::linalg::QR<f64, nalgebra::Dyn, nalgebra::Dyn>, n: usize) -> DMatrix<f64> {
    let mut q = DMatrix::identity(n, n);
    qr.q_tr_mul(&mut q);
    q.transpose()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::dvector;

    #[test]
    fn the_system_cache_finds_equal_matrices_and_keeps_at_most_its_capacity() {
        let cache = SystemCache::default();
        let system = |w: f64| (DMatrix::from_diagonal(&dvector![1.0, w]), DMatrix::from_diagonal(&dvector![0.1, 0.2]), DMatrix::zeros(2, 0));
        let (k, d, w) = system(4.0);
        let a = cache.get_or_build(k.clone(), d.clone(), w.clone()).unwrap();
        let b = cache.clone().get_or_build(k, d, w).unwrap();
        assert!(Arc::ptr_eq(&a, &b), "a clone of the cache finds the same decomposition");
        for i in 0..SystemCache::CAPACITY + 5 {
            let (k, d, w) = system(5.0 + i as f64);
            cache.get_or_build(k, d, w).unwrap();
        }
        assert_eq!(cache.len(), SystemCache::CAPACITY);
        let (k, d, w) = system(4.0);
        let c = cache.get_or_build(k, d, w).unwrap();
        assert!(!Arc::ptr_eq(&a, &c), "the oldest entry was dropped and rebuilt");
        assert_eq!(a.eig, c.eig, "the same decomposition, rebuilt");
        // The newest entries handed on: shared, and no others.
        let handed = cache.newest(2);
        assert_eq!(handed.len(), 2);
        let (k, d, w) = system(4.0);
        assert!(Arc::ptr_eq(&handed.get_or_build(k, d, w).unwrap(), &c), "the newest is shared");
        // The third newest (the loop's last but one) stays behind.
        let (k, d, w) = system(5.0 + (SystemCache::CAPACITY + 3) as f64);
        let kept = cache.get_or_build(k.clone(), d.clone(), w.clone()).unwrap();
        assert!(!Arc::ptr_eq(&handed.get_or_build(k, d, w).unwrap(), &kept), "an older one is not handed on");
        assert_eq!(handed.len(), 3);
        assert_eq!(cache.len(), SystemCache::CAPACITY, "the cache handed on from is not changed");
    }
}
