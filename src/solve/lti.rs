//! Coupled linear phases: `q'' + D q' + K q = f(t) + W lambda`, `W^T q = d`.
//!
//! Sticking (seed 000 eqs. 29-33) holds some contact points on their stops;
//! a compliant stop in contact adds `k w w^T` to K (the mode-transfer idea of
//! seed 001). Either way the phase is linear and time invariant, but with
//! non-proportional damping: it is reduced to the free coordinates `y`
//! (`q = q_c + Z y`, `Z` an orthonormal basis of the constraint's null space),
//! diagonalised once in complex first-order form, and propagated exactly,
//! `z_k(s) = e^{L_k s} z_k(0) + forced terms` with the `phi1` kernel, which is
//! exact at resonance.

use std::sync::{Arc, Mutex};

use nalgebra::{DMatrix, DVector};

use super::elementary::unit;
use super::forcing::ModalForcing;
use super::free::ModalState;
use super::events::split_certificate;
use super::functional::{DerivativeBounds, Functional, Jet, NOISE};
use super::oscillator::{exp_divdiff2, expm1_c, phi1, C64};

/// Why a coupled phase could not be set up.
#[derive(Clone, Debug, PartialEq)]
pub enum LtiError {
    Eigen(String),
    IllConditioned(f64),
}

impl std::fmt::Display for LtiError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LtiError::Eigen(e) => write!(f, "eigendecomposition of the contact phase failed: {e}"),
            LtiError::IllConditioned(c) => write!(
                f,
                "the contact phase is nearly defective (eigenvector condition number {c:.3e}); \
                 change the damping slightly"
            ),
        }
    }
}

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
    z: DMatrix<f64>,
    z_t: DMatrix<f64>,
    /// Eigenvalues and eigenvectors of `[[0, I], [-Z'KZ, -Z'DZ]]`.
    eig: DVector<C64>,
    v: DMatrix<C64>,
    v_inv: DMatrix<C64>,
    /// `1 / L_k` and `|L_k|`, used by every probe.
    eig_inv: DVector<C64>,
    eig_abs: Vec<f64>,
    /// `eig[k] = conj(eig[k - 1])` exactly: the exponential of a conjugate
    /// pair is computed once.
    conjugate_of_previous: Vec<bool>,
    /// Besides, column `k` of `V` is exactly the conjugate of column
    /// `k - 1`: for a real state under real loads coordinate `k` is then
    /// the conjugate of coordinate `k - 1` (rows `k - 1`, `k` of `V^-1` are
    /// conjugates), and a probe computes one coordinate of the pair.
    mirrors_previous: Vec<bool>,
    /// The coordinates by increasing `|L_k|` (conjugate pairs adjacent).
    by_rate: Vec<usize>,
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
            let a = faer::Mat::<f64>::from_fn(2 * n, 2 * n, |i, j| match (i < n, j < n) {
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
            let e = a.eigen().map_err(|e| LtiError::Eigen(format!("{e:?}")))?;
            let s = e.S();
            let eig = DVector::from_fn(2 * n, |k, _| C64::new(s[k].re, s[k].im));
            // The dense products below run in faer (blocked, O(n^3) once per
            // phase); the result is handed on as nalgebra matrices.
            type Cx = faer::c64;
            let mut vu = e.U().to_owned();
            for j in 0..2 * n {
                let norm = vu.col(j).norm_l2();
                for i in 0..2 * n {
                    vu[(i, j)] = vu[(i, j)] / norm;
                }
            }
            let vu_inv = faer::linalg::solvers::DenseSolveCore::inverse(&vu.partial_piv_lu());
            let cond = vu.norm_l2() * vu_inv.norm_l2();
            if !(cond < 1e10) {
                return Err(LtiError::IllConditioned(cond));
            }
            // The same for the first-order eigenvalues: the two-sided
            // Rayleigh quotient `(l A r) / (l r)` with the left eigenvectors
            // (rows of the inverse) is second-order accurate. `A U` from the
            // blocks: `[W U_b; -W U_t - D_q U_b]`.
            let dq_c = faer::Mat::<Cx>::from_fn(n, n, |i, j| Cx::new(dq[(i, j)], 0.0));
            let damped = &dq_c * vu.subrows(n, n);
            let au = faer::Mat::<Cx>::from_fn(2 * n, 2 * n, |i, j| {
                if i < n {
                    vu[(i + n, j)] * w_freq[i]
                } else {
                    -(vu[(i - n, j)] * w_freq[i - n]) - damped[(i - n, j)]
                }
            });
            let eig = DVector::from_fn(2 * n, |k, _| {
                let (mut lr, mut lar) = (Cx::new(0.0, 0.0), Cx::new(0.0, 0.0));
                for i in 0..2 * n {
                    lr += vu_inv[(k, i)] * vu[(i, k)];
                    lar += vu_inv[(k, i)] * au[(i, k)];
                }
                let refined = lar / lr;
                if refined.re.is_finite() && refined.im.is_finite() && lr.norm() > 0.5 {
                    C64::new(refined.re, refined.im)
                } else {
                    eig[k]
                }
            });
            let qc = faer::Mat::<Cx>::from_fn(n, n, |i, j| Cx::new(q[(i, j)], 0.0));
            let top = faer::Mat::<Cx>::from_fn(n, n, |i, j| Cx::new(q[(i, j)] / w_freq[j], 0.0));
            let v_top = &top * vu.subrows(0, n);
            let v_bottom = &qc * vu.subrows(n, n);
            let scaled_qt = faer::Mat::<Cx>::from_fn(n, n, |i, j| Cx::new(q[(j, i)] * w_freq[i], 0.0));
            let qt = faer::Mat::<Cx>::from_fn(n, n, |i, j| Cx::new(q[(j, i)], 0.0));
            let v_inv_left = vu_inv.subcols(0, n) * &scaled_qt;
            let v_inv_right = vu_inv.subcols(n, n) * &qt;
            let v = DMatrix::from_fn(2 * n, 2 * n, |i, j| {
                let x = if i < n { v_top[(i, j)] } else { v_bottom[(i - n, j)] };
                C64::new(x.re, x.im)
            });
            let v_inv = DMatrix::from_fn(2 * n, 2 * n, |i, j| {
                let x = if j < n { v_inv_left[(i, j)] } else { v_inv_right[(i, j - n)] };
                C64::new(x.re, x.im)
            });
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

    fn n_free(&self) -> usize {
        self.z.ncols()
    }

    /// `q_c`, the minimum-norm solution of `W^T q = targets`.
    pub fn q_c(&self, targets: &DVector<f64>) -> DVector<f64> {
        &self.w * (&self.gram_inv * targets)
    }

    /// The constraint reactions `lambda = -(W^T W)^-1 W^T (f - D qd - K q)`
    /// (seed 000 eq. 33, one row per held contact) as functionals.
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

/// One harmonic load component in the complex modal coordinates, with the
/// steady response `p_k e^{i W t}` of the coordinates far from resonance
/// (`None` near it).
#[derive(Clone, Debug, PartialEq)]
struct ProjectedHarmonic {
    omega: f64,
    g: DVector<C64>,
    steady: Vec<Option<C64>>,
    /// `1 / (L - i W)` where `L` is far from `i W` ([`direct_factor`]).
    factor: Vec<Option<C64>>,
}

/// A harmonic's load rotated to a segment's start: `g e^{i W t0}`, and
/// `g e^{i W t0} / (L - i W)` where `L` is far from `i W`: then the forced
/// part `g e^{i W t} s phi1((L - i W) s)` is `(expm1(L s) - expm1(i W s))
/// g e^{i W t0} / (L - i W)`, which reuses the coordinate's own exponential
/// and one rotation per harmonic.
#[derive(Clone, Debug, Default)]
struct StartedHarmonic {
    g_rot0: DVector<C64>,
    direct: Vec<Option<C64>>,
}

/// The steady response `g / (i W - L)` of `z' = L z + g e^{i W t}`, unless
/// the denominator is small (resonance), where it would amplify rounding.
fn steady_amplitude(g: C64, eig: C64, omega: f64) -> Option<C64> {
    let den = C64::new(0.0, omega) - eig;
    if modulus(den) > 1e-3 * (modulus(eig) + omega.abs()) {
        Some(g / den)
    } else {
        None
    }
}

/// `1 / (L - i W)` where the difference `expm1(L s) - expm1(i W s)` keeps
/// its relative accuracy to within a factor 8 (`|L - i W| > (|L| + |W|) / 8`).
fn direct_factor(eig: C64, omega: f64) -> Option<C64> {
    let den = eig - C64::new(0.0, omega);
    (modulus(den) > 0.125 * (modulus(eig) + omega.abs())).then(|| C64::new(1.0, 0.0) / den)
}

/// `|z|` without `hypot`'s guard against overflow (the coordinates and
/// eigenvalues here are far from it).
fn modulus(z: C64) -> f64 {
    (z.re * z.re + z.im * z.im).sqrt()
}

/// `|.|_1` of a complex number: between its modulus and sqrt 2 times it,
/// and cheaper; the sizes that set rounding levels use it.
fn l1(z: C64) -> f64 {
    z.re.abs() + z.im.abs()
}

/// The complex coordinates, their first three derivatives and the modal
/// loads' at one instant, shared by the jets and bounds of every event
/// function there. Reused from probe to probe (no allocation).
#[derive(Clone, Debug, Default)]
pub struct CoupledSample {
    t: f64,
    /// `z^(m)`, m = 0..=3.
    z: [DVector<C64>; 4],
    /// The size of the terms summed into `z^(m)`: the rounding it carries.
    size: [DVector<f64>; 4],
    /// `(W, e^{i W t})` per harmonic of the segment's loads.
    rotations: Vec<(f64, C64)>,
}

/// Per coordinate, the parts of its derivative bounds that do not change
/// along a segment: `sum |P| W^m` over the steady responses (m = 0..=4),
/// `sum |g| W^m` over the near-resonant loads (m = 0..=3), `sum |P|` over
/// every steady response (`size`, the constant load's included) and the
/// constant load's `|P|` alone (`constant`).
#[derive(Clone, Copy, Debug, Default)]
struct BoundTerms {
    steady: [f64; 5],
    resonant: [f64; 4],
    size: f64,
    constant: f64,
}

/// What every segment of one contact phase shares, whatever its anchor:
/// the loads in the system's complex coordinates, their steady responses
/// and the coordinates' bound terms, for one system, load and origin. A
/// phase entered again (each sticking phase of a chatter sequence, each
/// contact of a spring stop) starts its segment from these in O(N^2)
/// without projecting the loads again.
#[derive(Clone, Debug)]
pub struct PhaseLoads {
    q_c: DVector<f64>,
    g_const: DVector<C64>,
    const_steady: Vec<Option<C64>>,
    harmonics: Vec<ProjectedHarmonic>,
    bound_terms: Vec<BoundTerms>,
}

impl PhaseLoads {
    /// `origin` is the point the motion is measured from: it must satisfy
    /// the constraints `W^T q = targets` (the held stops' positions; for
    /// instance [`CoupledSystem::q_c`]). Choosing it on the surfaces of
    /// pressed compliant stops too keeps their large preload `k target w`
    /// out of the loads: the spring then acts on the small deviation only.
    /// `origin_force` is what the phase's stiffness exerts at the origin
    /// net of any preload the loads leave out (`K origin` when there is none;
    /// the caller forms it without the cancellation `k w (w . origin) - k
    /// w target` would cost).
    pub fn new(sys: &CoupledSystem, forcing: &ModalForcing, origin: &DVector<f64>, origin_force: &DVector<f64>) -> Self {
        let n = sys.n_free();
        let q_c = origin.clone();
        // Loads on y: Z^T (f(t) - K q_c), entering the velocity half.
        // (only the velocity half of the state is loaded: the right half of V^-1)
        let v_inv_loads = sys.v_inv.columns(n, n);
        let lift = |fy: DVector<C64>| -> DVector<C64> { &v_inv_loads * fy };
        let c = sys.z.tr_mul(&(&forcing.constant - origin_force));
        let g_const = lift(c.map(|x| C64::new(x, 0.0)));
        let mut harmonics = Vec::new();
        let mut push = |omega: f64, g: DVector<C64>| {
            let steady = g.iter().zip(sys.eig.iter()).map(|(g, l)| steady_amplitude(*g, *l, omega)).collect();
            let factor = sys.eig.iter().map(|l| direct_factor(*l, omega)).collect();
            harmonics.push(ProjectedHarmonic { omega, g, steady, factor });
        };
        for h in &forcing.harmonics {
            // Re(b e^{i W t}) = (b e^{i W t} + conj(b) e^{-i W t}) / 2.
            let by = DVector::from_fn(n, |i, _| sys.z.column(i).iter().zip(h.amplitude.iter()).map(|(z, b)| b * *z).sum::<C64>());
            let half = C64::new(0.5, 0.0);
            push(h.omega, lift(by.map(|b| b * half)));
            push(-h.omega, lift(by.map(|b| b.conj() * half)));
        }
        let const_steady: Vec<Option<C64>> = g_const.iter().zip(sys.eig.iter()).map(|(g, l)| steady_amplitude(*g, *l, 0.0)).collect();
        let bound_terms = (0..2 * n)
            .map(|k| {
                let mut terms = BoundTerms::default();
                match const_steady[k] {
                    Some(p) => {
                        terms.constant = p.norm();
                        terms.size += terms.constant;
                    }
                    None => terms.resonant[0] += g_const[k].norm(),
                }
                for h in &harmonics {
                    let (mut a, target): (f64, &mut [f64]) = match h.steady[k] {
                        Some(p) => {
                            terms.size += p.norm();
                            (p.norm(), &mut terms.steady)
                        }
                        None => (h.g[k].norm(), &mut terms.resonant),
                    };
                    for m in target.iter_mut() {
                        *m += a;
                        a *= h.omega.abs();
                    }
                }
                terms
            })
            .collect();
        PhaseLoads { q_c, g_const, const_steady, harmonics, bound_terms }
    }

    /// A functional in the complex coordinates: `h = offset + Re(c . z) + f-part`,
    /// with the sizes its bounds use (constant along the phase).
    pub fn project_functional(&self, sys: &CoupledSystem, forcing: &ModalForcing, h: &Functional) -> ProjectedFunctional {
        let n = sys.n_free();
        let aq = sys.z.tr_mul(&h.q);
        let bq = h.qd.as_ref().map(|b| sys.z.tr_mul(b));
        // c_k = V[.., k] . [aq; bq], a column of V at a time; the second of a
        // mirrored pair is the first's conjugate.
        let mut c = DVector::from_element(2 * n, C64::new(0.0, 0.0));
        for (k, column) in sys.v.column_iter().enumerate() {
            if sys.mirrors_previous[k] {
                c[k] = c[k - 1].conj();
                continue;
            }
            let column = column.as_slice();
            let mut s = C64::new(0.0, 0.0);
            for (v, a) in column[..n].iter().zip(aq.iter()) {
                s += v * *a;
            }
            if let Some(b) = &bq {
                for (v, b) in column[n..].iter().zip(b.iter()) {
                    s += v * *b;
                }
            }
            c[k] = s;
        }
        let c_abs = c.iter().map(|c| c.norm()).collect();
        // sum_j |c_j| max |f_j^(m)|, m = 0..=4.
        let load_bounds = std::array::from_fn(|m| {
            h.f.as_ref().map_or(0.0, |cf| cf.iter().enumerate().map(|(j, c)| c.abs() * forcing.bound(j, m as u32)).sum())
        });
        let f_const = h.f.as_ref().map_or(0.0, |cf| cf.dot(&forcing.constant));
        let f_harmonics = match &h.f {
            Some(cf) => forcing.harmonics.iter().map(|hm| hm.amplitude.iter().zip(cf.iter()).map(|(b, c)| b * *c).sum()).collect(),
            None => Vec::new(),
        };
        ProjectedFunctional { offset: h.offset + h.q.dot(&self.q_c), c, c_abs, f: h.f.clone(), f_const, f_harmonics, load_bounds }
    }
}

/// `v` with `n` entries: kept when it has them (its values are then
/// overwritten by the caller), else a new zero vector.
fn sized<T: nalgebra::ComplexField>(v: &mut DVector<T>, n: usize) {
    if v.len() != n {
        *v = DVector::zeros(n);
    }
}

/// The exact motion of a coupled phase from an anchor.
#[derive(Clone, Debug)]
pub struct CoupledSegment {
    pub t0: f64,
    loads: Arc<PhaseLoads>,
    z0: DVector<C64>,
    started: Vec<StartedHarmonic>,
    /// Work space of [`Self::restart`]: `q - q_c`, `Z^T (q - q_c)`, `Z^T qd`.
    offset: DVector<f64>,
    y0: DVector<f64>,
    yd0: DVector<f64>,
}

impl CoupledSegment {
    /// The motion from `(t0, start)` under freshly projected loads (see
    /// [`PhaseLoads::new`] for `origin` and `origin_force`).
    pub fn new(
        sys: &CoupledSystem,
        forcing: &ModalForcing,
        origin: &DVector<f64>,
        origin_force: &DVector<f64>,
        t0: f64,
        start: &ModalState,
    ) -> Self {
        Self::start(sys, Arc::new(PhaseLoads::new(sys, forcing, origin, origin_force)), t0, start)
    }

    /// The motion from `(t0, start)` under a phase's projected loads.
    pub fn start(sys: &CoupledSystem, loads: Arc<PhaseLoads>, t0: f64, start: &ModalState) -> Self {
        let empty = DVector::zeros(0);
        let mut segment = CoupledSegment { t0, loads: loads.clone(), z0: DVector::zeros(0), started: Vec::new(), offset: empty.clone(), y0: empty.clone(), yd0: empty };
        segment.restart(sys, loads, t0, start);
        segment
    }

    /// [`Self::start`] in this segment's storage: a phase entered again
    /// (each stick, each contact) restarts without allocating.
    pub fn restart(&mut self, sys: &CoupledSystem, loads: Arc<PhaseLoads>, t0: f64, start: &ModalState) {
        let n = sys.n_free();
        let len = sys.eig.len();
        self.t0 = t0;
        self.loads = loads;
        let loads = &self.loads;
        // Z^T x by `tr_mul_to`: no transposed copy of Z per phase.
        sized(&mut self.offset, start.q.len());
        self.offset.copy_from(&start.q);
        self.offset -= &loads.q_c;
        sized(&mut self.y0, n);
        sized(&mut self.yd0, n);
        sys.z.tr_mul_to(&self.offset, &mut self.y0);
        sys.z.tr_mul_to(&start.qd, &mut self.yd0);
        let (y0, yd0) = (&self.y0, &self.yd0);
        // z0 = V^-1 [y0; yd0], the real vector taken as such (two real
        // products per entry, not four), column by column; the second
        // coordinate of a mirrored pair is the first's conjugate.
        sized(&mut self.z0, len);
        self.z0.fill(C64::new(0.0, 0.0));
        {
            let z = self.z0.as_mut_slice();
            // Column-major: the columns of V^-1 are contiguous.
            for (i, column) in sys.v_inv.as_slice().chunks_exact(len.max(1)).enumerate() {
                let x = if i < n { y0[i] } else { yd0[i - n] };
                for (zk, v) in z.iter_mut().zip(column) {
                    *zk += v * x;
                }
            }
            for k in 0..len {
                if sys.mirrors_previous[k] {
                    z[k] = z[k - 1].conj();
                }
            }
        }
        self.started.resize_with(loads.harmonics.len(), StartedHarmonic::default);
        for (h, started) in loads.harmonics.iter().zip(&mut self.started) {
            let rotation = unit(h.omega * t0);
            sized(&mut started.g_rot0, h.g.len());
            for (g_rot0, g) in started.g_rot0.iter_mut().zip(h.g.iter()) {
                *g_rot0 = g * rotation;
            }
            started.direct.clear();
            started.direct.extend(started.g_rot0.iter().zip(&h.factor).map(|(g, f)| f.map(|f| g * f)));
        }
    }

    /// The phase's projected loads this motion runs under.
    pub fn loads(&self) -> &Arc<PhaseLoads> {
        &self.loads
    }

    /// `f(W)` for the first 8 harmonics; the loads' harmonics come in
    /// pairs `(+W, -W)`, and for the rotations here `f(-W) = conj f(W)`
    /// exactly (cos is even and sin odd in floating point too), so each
    /// pair costs one evaluation.
    fn per_harmonic(&self, f: impl Fn(f64) -> C64) -> [C64; 8] {
        let mut out = [C64::new(0.0, 0.0); 8];
        let harmonics = &self.loads.harmonics;
        for (i, h) in harmonics.iter().enumerate().take(8) {
            out[i] = if i % 2 == 1 && h.omega == -harmonics[i - 1].omega { out[i - 1].conj() } else { f(h.omega) };
        }
        out
    }

    /// Complex modal coordinates at time `t`.
    fn z_at(&self, sys: &CoupledSystem, t: f64) -> DVector<C64> {
        let mut z = DVector::zeros(sys.eig.len());
        self.z_into(sys, t, &mut z);
        z
    }

    /// `z(t) = e^{L s} z0 + g s phi1(L s) + sum_h g_h e^{i W t} s phi1((L - i W) s)`
    /// (`s = t - t0`) into `out`, with one complex `expm1` per coordinate
    /// and one rotation per harmonic; the near-resonant terms keep `phi1`.
    /// The second coordinate of a mirrored pair is the first's conjugate.
    fn z_into(&self, sys: &CoupledSystem, t: f64, out: &mut DVector<C64>) {
        let s = t - self.t0;
        let rotations = self.per_harmonic(|w| expm1_c(C64::new(0.0, w * s)));
        let mut previous = C64::new(0.0, 0.0);
        let out = out.as_mut_slice();
        for k in 0..sys.eig.len() {
            if sys.mirrors_previous[k] {
                out[k] = out[k - 1].conj();
                previous = previous.conj();
                continue;
            }
            let l = sys.eig[k];
            let ls = l * s;
            let e = if sys.conjugate_of_previous[k] { previous.conj() } else { expm1_c(ls) };
            previous = e;
            let g_const = self.loads.g_const[k];
            let forced_const = if ls.norm_sqr() < 1e-10 { g_const * phi1(ls) * s } else { g_const * e * sys.eig_inv[k] };
            let mut z = self.z0[k] + e * self.z0[k] + forced_const;
            for (i, (h, started)) in self.loads.harmonics.iter().zip(&self.started).enumerate() {
                match (started.direct[k], rotations.get(i)) {
                    (Some(c), Some(r)) => z += c * (e - r),
                    _ => {
                        let mu = (l - C64::new(0.0, h.omega)) * s;
                        z += started.g_rot0[k] * unit(h.omega * s) * phi1(mu) * s;
                    }
                }
            }
            out[k] = z;
        }
    }

    /// `int_{t0}^{t} q ds`, exact: each complex coordinate integrates to
    /// `z0 S phi1(L S) + g S^2 e[0, 0, L S] + sum_h g_h e^{i W t0} S^2 e[0, L S, i W S]`
    /// (`S = t - t0`, `e[..]` the divided differences of the exponential).
    /// The stops' impulses over a phase are linear in it.
    pub fn integral_q(&self, sys: &CoupledSystem, t: f64) -> DVector<f64> {
        let s = t - self.t0;
        let n = sys.n_free();
        let zero = C64::new(0.0, 0.0);
        let iz = DVector::from_fn(sys.eig.len(), |k, _| {
            let ls = sys.eig[k] * s;
            let mut v = self.z0[k] * phi1(ls) * s + self.loads.g_const[k] * exp_divdiff2(zero, ls) * (s * s);
            for h in &self.loads.harmonics {
                let rot0 = unit(h.omega * self.t0);
                v += h.g[k] * rot0 * exp_divdiff2(ls, C64::new(0.0, h.omega * s)) * (s * s);
            }
            v
        });
        let x = &sys.v * iz;
        let y = DVector::from_fn(n, |i, _| x[i].re);
        &self.loads.q_c * s + &sys.z * y
    }

    pub fn state_at(&self, sys: &CoupledSystem, t: f64, out: &mut ModalState) {
        let z = self.z_at(sys, t);
        self.state_from_coordinates(sys, z.as_slice(), out);
    }

    /// [`Self::state_at`], from the coordinates `sample` holds when it was
    /// taken at `t` (the event search's probe at an event): the same
    /// values, not computed twice.
    pub fn state_at_sample(&self, sys: &CoupledSystem, t: f64, sample: &CoupledSample, out: &mut ModalState) {
        if sample.t == t && sample.z[0].len() == sys.eig.len() {
            self.state_from_coordinates(sys, sample.z[0].as_slice(), out);
        } else {
            self.state_at(sys, t, out);
        }
    }

    /// `(q, qd)` from the complex coordinates `z`.
    fn state_from_coordinates(&self, sys: &CoupledSystem, z: &[C64], out: &mut ModalState) {
        let n = sys.n_free();
        // [y; y'] = Re(V z), only the real part formed; a mirrored pair's
        // two products are conjugates, so the first one's real part counts
        // twice (column by column: V is column-major).
        let len = z.len();
        let mut x = vec![0.0; len];
        for (k, column) in sys.v.as_slice().chunks_exact(len.max(1)).enumerate() {
            if sys.mirrors_previous[k] {
                continue;
            }
            let paired = k + 1 < len && sys.mirrors_previous[k + 1];
            let zk = if paired { z[k] * 2.0 } else { z[k] };
            for (xi, v) in x.iter_mut().zip(column) {
                *xi += v.re * zk.re - v.im * zk.im;
            }
        }
        let y = DVector::from_column_slice(&x[..n]);
        let yd = DVector::from_column_slice(&x[n..]);
        out.q = &self.loads.q_c + &sys.z * y;
        out.qd = &sys.z * yd;
    }

    /// [`PhaseLoads::project_functional`] with this segment's loads.
    pub fn project_functional(&self, sys: &CoupledSystem, forcing: &ModalForcing, h: &Functional) -> ProjectedFunctional {
        self.loads.project_functional(sys, forcing, h)
    }

    /// The complex coordinates, their derivatives `z^(m) = L z^(m-1) + g^(m-1)`
    /// and the loads' at time `t`, into `out` (resized on first use).
    pub fn sample_into(&self, sys: &CoupledSystem, t: f64, out: &mut CoupledSample) {
        let len = sys.eig.len();
        if out.z[0].len() != len {
            *out = CoupledSample {
                t,
                z: std::array::from_fn(|_| DVector::zeros(len)),
                size: std::array::from_fn(|_| DVector::zeros(len)),
                rotations: Vec::with_capacity(self.loads.harmonics.len()),
            };
        }
        out.t = t;
        self.z_into(sys, t, &mut out.z[0]);
        // e^{i W t} per harmonic; (i W)^m applied per coordinate.
        out.rotations.clear();
        let first = self.per_harmonic(|w| unit(w * t));
        out.rotations.extend(self.loads.harmonics.iter().enumerate().map(|(i, h)| (h.omega, first.get(i).copied().unwrap_or_else(|| unit(h.omega * t)))));
        let CoupledSample { z, size, rotations, .. } = out;
        let [z0, z1, z2, z3] = z;
        let [s0, s1, s2, s3] = size;
        let (z0, z1, z2, z3) = (z0.as_mut_slice(), z1.as_mut_slice(), z2.as_mut_slice(), z3.as_mut_slice());
        let (s0, s1, s2, s3) = (s0.as_mut_slice(), s1.as_mut_slice(), s2.as_mut_slice(), s3.as_mut_slice());
        for k in 0..len {
            if sys.mirrors_previous[k] {
                (z1[k], z2[k], z3[k]) = (z1[k - 1].conj(), z2[k - 1].conj(), z3[k - 1].conj());
                (s0[k], s1[k], s2[k], s3[k]) = (s0[k - 1], s1[k - 1], s2[k - 1], s3[k - 1]);
                continue;
            }
            let l = sys.eig[k];
            let la = sys.eig_abs[k];
            // g, g', g'' of the loads on coordinate k.
            let (mut g0, mut g1, mut g2) = (self.loads.g_const[k], C64::new(0.0, 0.0), C64::new(0.0, 0.0));
            for (h, (omega, rot)) in self.loads.harmonics.iter().zip(rotations.iter()) {
                let u = h.g[k] * rot;
                g0 += u;
                g1 += C64::new(-omega * u.im, omega * u.re);
                g2 -= u * (omega * omega);
            }
            let z_0 = z0[k];
            let z_1 = l * z_0 + g0;
            let z_2 = l * z_1 + g1;
            z1[k] = z_1;
            z2[k] = z_2;
            z3[k] = l * z_2 + g2;
            let sz0 = l1(z_0);
            let sz1 = la * sz0 + l1(g0);
            let sz2 = la * sz1 + l1(g1);
            s0[k] = sz0;
            s1[k] = sz1;
            s2[k] = sz2;
            s3[k] = la * sz2 + l1(g2);
        }
    }

    /// `h, h', h'', h'''` at the sample's time.
    pub fn jet(&self, p: &ProjectedFunctional, sample: &CoupledSample) -> Jet {
        let mut jet = Jet::default();
        for m in 0..4 {
            let mut value = if m == 0 { p.offset } else { 0.0 };
            let mut size = value.abs();
            for k in 0..p.c.len() {
                value += (p.c[k] * sample.z[m][k]).re;
                size += p.c_abs[k] * sample.size[m][k];
            }
            if p.f.is_some() {
                // c . f^(m) = Re sum_h (c . b_h) (i W)^m e^{i W t} (+ c . f_const)
                if m == 0 {
                    value += p.f_const;
                }
                // The segment's harmonics come in pairs (+W, -W) per load harmonic.
                for (a, (omega, rot)) in p.f_harmonics.iter().zip(sample.rotations.iter().step_by(2)) {
                    let mut x = a * rot;
                    for _ in 0..m {
                        x = C64::new(-omega * x.im, omega * x.re);
                    }
                    value += x.re;
                }
                size += p.load_bounds[m];
            }
            jet.d[m] = value;
            jet.noise[m] = NOISE * size;
        }
        jet.with_time_uncertainty(sample.t)
    }

    /// Per-coordinate bounds on `|z_k|` and `|z_k^(m)|`, m = 2..=4, over
    /// `[t, t + tau]`, into `out`. Each coordinate is its steady response to
    /// the non-resonant loads, known exactly, plus a remainder `r' = L r +
    /// g_res` with `Re L <= 0`: `|r| <= |r(t)| + tau max|g_res|` and
    /// `r^(m) = L^m r + sum_i L^(m-1-i) g_res^(i)`.
    pub fn coordinate_bounds_into(&self, sys: &CoupledSystem, sample: &CoupledSample, tau: f64, out: &mut Vec<CoordinateBounds>) {
        out.clear();
        for k in 0..sample.z[0].len() {
            if sys.mirrors_previous[k] {
                // |conj z| = |z|, and the pair's loads mirror each other.
                let mut mirrored: CoordinateBounds = out[k - 1];
                mirrored.steady = mirrored.steady.conj();
                out.push(mirrored);
                continue;
            }
            let l = sys.eig_abs[k];
            let terms = &self.loads.bound_terms[k];
            let mut zp = self.loads.const_steady[k].unwrap_or(C64::new(0.0, 0.0));
            // The sample's rotations `e^{i W t}`, one per harmonic.
            for (h, (_, rot)) in self.loads.harmonics.iter().zip(&sample.rotations) {
                if let Some(p) = h.steady[k] {
                    zp += p * rot;
                }
            }
            let growth = if sys.eig[k].re > 0.0 { (sys.eig[k].re * tau).exp() } else { 1.0 };
            let dz = sample.z[0][k] - zp;
            let r = growth * ((dz.re * dz.re + dz.im * dz.im).sqrt() + NOISE * terms.size + terms.resonant[0] * tau);
            let powers = [1.0, l, l * l, l * l * l, l * l * l * l];
            // The steady part is at most its constant and harmonic amplitudes.
            let mut bounds = CoordinateBounds { m: [0.0; 3], floor: [0.0; 4], sup: r + terms.constant + terms.steady[0], transient: r, steady: zp };
            for (slot, m) in (2..5).enumerate() {
                let mut b = powers[m] * r;
                for i in 0..m {
                    b += powers[m - 1 - i] * terms.resonant[i];
                }
                bounds.m[slot] = b + terms.steady[m];
            }
            // The rounding level these bounds carry for the coordinate
            // and its first three derivatives.
            for m in 0..4 {
                bounds.floor[m] = growth * NOISE * terms.size * powers[m];
            }
            out.push(bounds);
        }
    }

    /// The split of [`Self::split_step`] into transients and steady
    /// responses; 0 when the transients' amplitude exceeds the value (the
    /// derivatives are only formed where the split can certify).
    fn transient_split_step(&self, p: &ProjectedFunctional, sample: &CoupledSample, coords: &[CoordinateBounds], jet: &Jet, plain: &DerivativeBounds, size: f64) -> f64 {
        let (mut value, mut amp) = (0.0, 0.0);
        for (k, b) in coords.iter().enumerate() {
            value += (p.c[k] * (sample.z[0][k] - b.steady)).re;
            amp += p.c_abs[k] * b.transient;
        }
        if !(jet.d[0] - value - amp > 0.0) {
            return 0.0;
        }
        // The transients' derivatives: the coordinates' less the steady
        // responses' `sum_h P (i W)^m e^{i W t}`.
        let (mut transient, mut steady_m) = ([0.0; 3], [0.0; 3]);
        for (k, c) in p.c.iter().enumerate() {
            let mut steady = [C64::new(0.0, 0.0); 3];
            for (h, &(w, rot)) in self.loads.harmonics.iter().zip(&sample.rotations) {
                if let Some(pk) = h.steady[k] {
                    let mut term = pk * rot;
                    for d in steady.iter_mut() {
                        term = C64::new(-w * term.im, w * term.re);
                        *d += term;
                    }
                }
            }
            for m in 0..3 {
                transient[m] += (c * (sample.z[m + 1][k] - steady[m])).re;
            }
            let terms = &self.loads.bound_terms[k];
            for slot in 0..3 {
                steady_m[slot] += p.c_abs[k] * terms.steady[slot + 2];
            }
        }
        let steady_derivatives = [jet.d[1] - transient[0], jet.d[2] - transient[1], jet.d[3] - transient[2]];
        let m = [steady_m[0] + p.load_bounds[2], steady_m[1] + p.load_bounds[3], steady_m[2] + p.load_bounds[4]];
        let bounds = DerivativeBounds { tau: plain.tau, m, floor: plain.floor };
        split_certificate(jet, value, amp, size + amp, steady_derivatives, &bounds)
    }

    /// Bounds on `|h''|, |h'''|, |h''''|` over `[t, t + tau]`.
    pub fn bounds(&self, p: &ProjectedFunctional, coords: &[CoordinateBounds], tau: f64) -> DerivativeBounds {
        let mut out = DerivativeBounds { tau, m: [0.0; 3], floor: [0.0; 4] };
        for (c, b) in p.c_abs.iter().zip(coords) {
            for slot in 0..3 {
                out.m[slot] += c * b.m[slot];
            }
            for m in 0..4 {
                out.floor[m] += c * b.floor[m];
            }
        }
        for (slot, m) in (2..5).enumerate() {
            out.m[slot] += p.load_bounds[m];
        }
        for m in 0..4 {
            out.floor[m] += NOISE * p.load_bounds[m];
        }
        out
    }

    /// A certified step for `h` (value and derivatives `jet` at the sample,
    /// plain bounds `plain`) from splitting the coordinates by rate, as
    /// [`crate::solve::free::ModalBounds::split_step`] does for free flight:
    /// `h = h_L + h_H` with `h_H` over the fastest coordinates, `h(t + s) >=
    /// h_L(t + s) - sum_H |c_k| max |z_k|`, and `h_L` certified by its own
    /// Taylor bound, whose derivative bounds leave the fast coordinates out.
    /// A contact phase begins with the fast coordinates' transients, whose
    /// `|L|^4` sets the plain bound long after their amplitude stops
    /// mattering. Tries the slowest `1, 2, 4, .., len - 1` coordinates
    /// where that does not part a conjugate pair, and the split of every
    /// coordinate into its transient and its steady response (`h_H =
    /// sum Re(c_k (z_k - zp_k))`, at most `sum |c_k| r_k`; `h_L` moves at
    /// the loads' pace, its derivative bounds `sum |c_k| sum |P| W^m`): a
    /// held beam whose reaction rings at the contact's frequencies steps
    /// at the load's. 0 when no split certifies.
    pub fn split_step(&self, sys: &CoupledSystem, p: &ProjectedFunctional, sample: &CoupledSample, coords: &[CoordinateBounds], jet: &Jet, plain: &DerivativeBounds) -> f64 {
        let len = p.c.len();
        if len < 2 || jet.d[0] <= jet.noise[0] {
            return 0.0;
        }
        // Totals over every coordinate: the value and derivatives of the
        // coordinate part, its amplitude bound and its size.
        let (mut all, mut amp_all, mut size_all) = ([0.0; 4], 0.0, 0.0);
        for k in 0..len {
            for m in 0..4 {
                all[m] += (p.c[k] * sample.z[m][k]).re;
            }
            amp_all += p.c_abs[k] * coords[k].sup;
            size_all += p.c_abs[k] * sample.size[0][k];
        }
        let mut best = self.transient_split_step(p, sample, coords, jet, plain, size_all + amp_all);
        let (mut low, mut low_m, mut amp_low) = ([0.0; 4], [0.0; 3], 0.0);
        let mut next_split = 1;
        for (count, &k) in sys.by_rate.iter().enumerate().take(len - 1) {
            for m in 0..4 {
                low[m] += (p.c[k] * sample.z[m][k]).re;
            }
            for slot in 0..3 {
                low_m[slot] += p.c_abs[k] * coords[k].m[slot];
            }
            amp_low += p.c_abs[k] * coords[k].sup;
            let candidate = count + 1 == next_split || count + 2 == len;
            if count + 1 == next_split {
                next_split *= 2;
            }
            // Never between the two halves of a conjugate pair (equal rates).
            if !candidate || sys.eig_abs[sys.by_rate[count + 1]] <= sys.eig_abs[k] {
                continue;
            }
            // h_L keeps the offset and the load part of h.
            let low_derivatives = [jet.d[1] - (all[1] - low[1]), jet.d[2] - (all[2] - low[2]), jet.d[3] - (all[3] - low[3])];
            let m = [low_m[0] + p.load_bounds[2], low_m[1] + p.load_bounds[3], low_m[2] + p.load_bounds[4]];
            let bounds = DerivativeBounds { tau: plain.tau, m, floor: plain.floor };
            let step = split_certificate(jet, all[0] - low[0], amp_all - amp_low, size_all + amp_all, low_derivatives, &bounds);
            best = best.max(step);
        }
        best
    }
}

/// Bounds on one complex coordinate over `[t, t + tau]`.
#[derive(Clone, Copy, Debug, Default)]
pub struct CoordinateBounds {
    /// `max |z_k^(m)|`, m = 2..=4.
    m: [f64; 3],
    /// The rounding level of `z_k^(m)`, m = 0..=3.
    floor: [f64; 4],
    /// `max |z_k|`.
    sup: f64,
    /// `max |z_k - zp_k|`: the transient (and any near-resonant response).
    transient: f64,
    /// The steady response `zp_k` at the sample.
    steady: C64,
}

/// A functional expressed in a coupled segment's complex coordinates.
#[derive(Clone, Debug)]
pub struct ProjectedFunctional {
    offset: f64,
    c: DVector<C64>,
    /// `|c_k|`.
    c_abs: Vec<f64>,
    f: Option<DVector<f64>>,
    /// `c . f_const` and `c . b_h` per harmonic: the load part in O(1) per probe.
    f_const: f64,
    f_harmonics: Vec<C64>,
    /// `sum_j |f_j| max |d^m f_j / dt^m|`, m = 0..=4: the load part's bounds.
    load_bounds: [f64; 5],
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::events::{certified_step, Certified};
    use nalgebra::dvector;

    /// Independent reference: RK4 on the full constrained equations
    /// `q'' = P (f - D q' - K q)` with `P = I - w w^T / w.w`.
    #[test]
    fn sticking_phase_matches_projected_rk4() {
        let n = 3;
        let k = DMatrix::from_diagonal(&dvector![1.0, 16.0, 81.0]);
        let d = DMatrix::from_diagonal(&dvector![0.1, 0.4, 0.9]);
        let w = DMatrix::from_column_slice(3, 1, &[1.2, -0.7, 0.4]);
        let sys = CoupledSystem::new(k.clone(), d.clone(), w.clone()).unwrap();
        let mut forcing = ModalForcing::zero(n);
        forcing.constant = dvector![0.5, 0.1, -0.2];
        forcing.add_harmonic(3.0, dvector![C64::new(0.0, -1.0), C64::new(0.3, 0.0), C64::new(0.0, 0.2)]);
        let targets = dvector![0.25];
        let mut start = ModalState { q: dvector![0.3, -0.1, 0.05], qd: dvector![0.2, 0.1, -0.4] };
        sys.project(&targets, &mut start);
        assert!((w.column(0).dot(&start.q) - 0.25).abs() < 1e-15);
        let t0 = 0.4;
        let q_c = sys.q_c(&targets);
        let seg = CoupledSegment::new(&sys, &forcing, &q_c, &(&k * &q_c), t0, &start);
        let mut out = ModalState::zeros(n);
        let t1 = 2.9;
        seg.state_at(&sys, t1, &mut out);

        let wv = w.column(0).into_owned();
        let p = DMatrix::identity(n, n) - &wv * wv.transpose() / wv.dot(&wv);
        let mut f = DVector::zeros(n);
        let mut acc = |t: f64, q: &DVector<f64>, v: &DVector<f64>| -> DVector<f64> {
            forcing.derivative(t, 0, &mut f);
            &p * (&f - &d * v - &k * q)
        };
        let steps = 100_000;
        let h = (t1 - t0) / steps as f64;
        let (mut q, mut v) = (start.q.clone(), start.qd.clone());
        for i in 0..steps {
            let t = t0 + i as f64 * h;
            let k1v = acc(t, &q, &v);
            let k1q = v.clone();
            let k2v = acc(t + h / 2.0, &(&q + &k1q * (h / 2.0)), &(&v + &k1v * (h / 2.0)));
            let k2q = &v + &k1v * (h / 2.0);
            let k3v = acc(t + h / 2.0, &(&q + &k2q * (h / 2.0)), &(&v + &k2v * (h / 2.0)));
            let k3q = &v + &k2v * (h / 2.0);
            let k4v = acc(t + h, &(&q + &k3q * h), &(&v + &k3v * h));
            let k4q = &v + &k3v * h;
            q += (k1q + k2q * 2.0 + k3q * 2.0 + k4q) * (h / 6.0);
            v += (k1v + k2v * 2.0 + k3v * 2.0 + k4v) * (h / 6.0);
        }
        assert!((&out.q - &q).norm() < 1e-11, "{} vs {}", out.q, q);
        assert!((&out.qd - &v).norm() < 1e-10);
        assert!((wv.dot(&out.q) - 0.25).abs() < 1e-14);
    }

    /// A pinned beam of `n` modes with modal damping held at one point:
    /// `(K, D, W)`, a constant and a harmonic load (60 rad/s, between two
    /// coupled frequencies, one near a resonance), the held position and a
    /// start off the constraint.
    fn held_beam(n: usize) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>, ModalForcing, DVector<f64>, ModalState) {
        let pi4 = std::f64::consts::PI.powi(4);
        let k = DMatrix::from_diagonal(&DVector::from_fn(n, |j, _| ((j + 1) as f64).powi(4) * pi4));
        let d = DMatrix::from_diagonal(&DVector::from_fn(n, |j, _| 0.1 * ((j + 1) as f64).powi(2) * std::f64::consts::PI.powi(2)));
        let w = DMatrix::from_fn(n, 1, |j, _| 2f64.sqrt() * ((j + 1) as f64 * std::f64::consts::PI * 0.37).sin());
        let mut forcing = ModalForcing::zero(n);
        forcing.constant = DVector::from_fn(n, |j, _| 0.3 / (j + 1) as f64);
        forcing.add_harmonic(60.0, DVector::from_fn(n, |j, _| C64::new(0.0, -5.0 * (0.5 + j as f64).sin())));
        let start = ModalState { q: DVector::from_fn(n, |j, _| 0.02 / ((j + 1) as f64).powi(2)), qd: DVector::from_fn(n, |j, _| 0.1 * (j as f64).cos()) };
        (k, d, w, forcing, dvector![0.01], start)
    }

    /// Many modes, a held point and modal damping (dense projected damping,
    /// conjugate pairs, a load between two coupled frequencies, one near a
    /// resonance): the closed form against RK4 on the constrained equations.
    #[test]
    fn many_mode_sticking_phase_matches_projected_rk4() {
        let n = 24;
        let (k, d, w, forcing, targets, mut start) = held_beam(n);
        let sys = CoupledSystem::new(k.clone(), d.clone(), w.clone()).unwrap();
        assert!(sys.conjugate_of_previous.iter().filter(|&&c| c).count() >= n / 2, "pairs found");
        sys.project(&targets, &mut start);
        let (t0, t1) = (0.2, 0.45);
        let q_c = sys.q_c(&targets);
        let seg = CoupledSegment::new(&sys, &forcing, &q_c, &(&k * &q_c), t0, &start);
        let mut out = ModalState::zeros(n);
        seg.state_at(&sys, t1, &mut out);
        let wv = w.column(0).into_owned();
        let p = DMatrix::identity(n, n) - &wv * wv.transpose() / wv.dot(&wv);
        let mut f = DVector::zeros(n);
        let mut acc = |t: f64, q: &DVector<f64>, v: &DVector<f64>| -> DVector<f64> {
            forcing.derivative(t, 0, &mut f);
            &p * (&f - &d * v - &k * q)
        };
        let steps = 200_000;
        let h = (t1 - t0) / steps as f64;
        let (mut q, mut v) = (start.q.clone(), start.qd.clone());
        for i in 0..steps {
            let t = t0 + i as f64 * h;
            let k1v = acc(t, &q, &v);
            let k1q = v.clone();
            let k2q = &v + &k1v * (h / 2.0);
            let k2v = acc(t + h / 2.0, &(&q + &k1q * (h / 2.0)), &k2q);
            let k3q = &v + &k2v * (h / 2.0);
            let k3v = acc(t + h / 2.0, &(&q + &k2q * (h / 2.0)), &k3q);
            let k4q = &v + &k3v * h;
            let k4v = acc(t + h, &(&q + &k3q * h), &k4q);
            q += (k1q + k2q * 2.0 + k3q * 2.0 + k4q) * (h / 6.0);
            v += (k1v + k2v * 2.0 + k3v * 2.0 + k4v) * (h / 6.0);
        }
        assert!((&out.q - &q).norm() < 1e-10 * q.norm(), "{:e}", (&out.q - &q).norm() / q.norm());
        assert!((&out.qd - &v).norm() < 1e-9 * v.norm(), "{:e}", (&out.qd - &v).norm() / v.norm());
        assert!((wv.dot(&out.q) - 0.01).abs() < 1e-14);
    }

    /// A probe computes one coordinate of each mirrored pair and takes the
    /// other as its conjugate: against the same system with every
    /// coordinate computed on its own (mirroring off), the coordinates,
    /// their derivatives, sizes and bounds, the projected functional, the
    /// start and the modal state agree to rounding, on 24 modes with a held point, dense
    /// projected damping, a constant and a harmonic load.
    #[test]
    fn mirrored_coordinates_match_their_own_computation() {
        let n = 24;
        let (k, d, w, forcing, targets, mut start) = held_beam(n);
        let mirrored = CoupledSystem::new(k.clone(), d, w).unwrap();
        let pairs = mirrored.conjugate_of_previous.iter().filter(|&&c| c).count();
        assert!(pairs >= n / 2 && mirrored.mirrors_previous == mirrored.conjugate_of_previous, "{pairs} pairs, mirrored {:?}", mirrored.mirrors_previous);
        let mut own = mirrored.clone();
        own.mirrors_previous.fill(false);
        mirrored.project(&targets, &mut start);
        let q_c = mirrored.q_c(&targets);
        let h = Functional { offset: 0.3, q: DVector::from_fn(n, |j, _| (j as f64 * 0.7).sin()), qd: Some(DVector::from_fn(n, |j, _| 0.01 * (j as f64).cos())), f: None };
        let close = |a: C64, b: C64, scale: f64| (a - b).norm() <= 1e-13 * scale;
        let (a, b) = ((&mirrored, CoupledSegment::new(&mirrored, &forcing, &q_c, &(&k * &q_c), 0.2, &start)), (&own, CoupledSegment::new(&own, &forcing, &q_c, &(&k * &q_c), 0.2, &start)));
        let z_scale = b.1.z0.iter().map(|z| z.norm()).fold(0.0, f64::max);
        assert!(a.1.z0.iter().zip(b.1.z0.iter()).all(|(x, y)| close(*x, *y, z_scale)));
        let (pa, pb) = (a.1.project_functional(a.0, &forcing, &h), b.1.project_functional(b.0, &forcing, &h));
        let c_scale = pb.c_abs.iter().copied().fold(0.0, f64::max);
        assert!(pa.c.iter().zip(pb.c.iter()).all(|(x, y)| close(*x, *y, c_scale)));
        let (mut sa, mut sb, mut ba, mut bb) = (CoupledSample::default(), CoupledSample::default(), Vec::new(), Vec::new());
        for t in [0.2, 0.2 + 1e-9, 0.21, 0.35, 1.7] {
            a.1.sample_into(a.0, t, &mut sa);
            b.1.sample_into(b.0, t, &mut sb);
            for m in 0..4 {
                let scale = sb.size[m].max();
                for kk in 0..2 * (n - 1) {
                    assert!(close(sa.z[m][kk], sb.z[m][kk], scale), "t = {t}, z^({m})_{kk}: {} vs {}", sa.z[m][kk], sb.z[m][kk]);
                    assert!((sa.size[m][kk] - sb.size[m][kk]).abs() <= 1e-13 * scale);
                }
            }
            let (ja, jb) = (a.1.jet(&pa, &sa), b.1.jet(&pb, &sb));
            for m in 0..4 {
                assert!((ja.d[m] - jb.d[m]).abs() <= ja.noise[m], "t = {t}: h^({m}) {} vs {}", ja.d[m], jb.d[m]);
            }
            // The state, Re(V z), with each pair's first product doubled.
            let (mut qa, mut qb) = (ModalState::zeros(n), ModalState::zeros(n));
            a.1.state_at(a.0, t, &mut qa);
            b.1.state_at(b.0, t, &mut qb);
            // Rounding at the size of the terms summed, max_i sum_k |V_ik z_k|.
            let z = b.1.z_at(b.0, t);
            let terms = (0..2 * (n - 1)).map(|i| (0..z.len()).map(|k| (b.0.v[(i, k)] * z[k]).norm()).sum::<f64>()).fold(0.0, f64::max);
            let (dq, dqd) = ((&qa.q - &qb.q).amax(), (&qa.qd - &qb.qd).amax());
            assert!(dq <= 64.0 * f64::EPSILON * terms && dqd <= 64.0 * f64::EPSILON * terms, "t = {t}: {dq:e}, {dqd:e} against terms of {terms:e}");
            a.1.coordinate_bounds_into(a.0, &sa, 0.1, &mut ba);
            b.1.coordinate_bounds_into(b.0, &sb, 0.1, &mut bb);
            // `|z - z_steady|` carries the rounding of both terms (absolute,
            // at the coordinate's own size), and the m-th derivative's bound
            // takes it times |L|^m.
            for (kk, (x, y)) in ba.iter().zip(&bb).enumerate() {
                let level = 1e-13 * (sb.size[0][kk] + y.sup);
                assert!((x.sup - y.sup).abs() <= level);
                for slot in 0..3 {
                    let tol = level * a.0.eig_abs[kk].powi(slot as i32 + 2);
                    assert!((x.m[slot] - y.m[slot]).abs() <= tol, "t = {t}, coordinate {kk}, slot {slot}: {:?} vs {:?}", x, y);
                }
            }
        }
    }

    /// The exact integral of the coordinates against Gauss-Legendre
    /// quadrature of the exact motion, with a harmonic load near a
    /// resonance of the coupled phase and a stiff coupled mode.
    #[test]
    fn integral_of_the_motion_matches_quadrature() {
        let n = 3;
        let w = dvector![1.0, -0.8, 0.6];
        let k = DMatrix::from_diagonal(&dvector![1.0, 16.0, 81.0]) + &w * w.transpose() * 1e4;
        let d = DMatrix::from_diagonal(&dvector![0.02, 0.1, 0.3]) + &w * w.transpose() * 0.5;
        let sys = CoupledSystem::new(k, d, DMatrix::zeros(n, 0)).unwrap();
        let mut forcing = ModalForcing::zero(n);
        forcing.constant = dvector![0.5, 0.1, -0.2];
        forcing.add_harmonic(3.9, dvector![C64::new(0.0, -1.0), C64::new(0.3, 0.0), C64::new(0.0, 0.2)]);
        let start = ModalState { q: dvector![0.3, -0.1, 0.05], qd: dvector![0.2, 0.1, -0.4] };
        let t0 = 0.4;
        let seg = CoupledSegment::new(&sys, &forcing, &DVector::zeros(n), &DVector::zeros(n), t0, &start);
        let t1 = 3.1;
        let exact = seg.integral_q(&sys, t1);
        let mut sum = DVector::zeros(n);
        let mut st = ModalState::zeros(n);
        crate::solve::quadrature::for_each_node_band_limited(t0, t1, 2.0 * 130.0, |t, wt| {
            seg.state_at(&sys, t, &mut st);
            sum += &st.q * wt;
        });
        assert!((&exact - &sum).norm() < 1e-13 * sum.norm().max(1e-3), "{exact} vs {sum}");
    }

    #[test]
    fn coupled_split_steps_never_pass_a_zero_and_beat_the_plain_bound() {
        // A held phase of four modes (1, 10, 60 and 300 rad/s, light
        // damping) with a constant and a harmonic load, the fast modes set
        // moving as after an impact, and a gap h = 0.0861 - (q1 + .. + q4)
        // that comes within 5e-4 of zero at t = 0.236 (a near graze). Along
        // the exact motion every certified step (plain or split) must keep
        // the gap positive, checked at 4000 points per step; each
        // coordinate must stay within its amplitude bound over the
        // interval (the constant load's steady response included: without
        // it the bound fails at t = 0); the split must certify longer steps
        // while the fast transients decay.
        const OFFSET: f64 = 0.0861;
        let n = 4;
        let k = DMatrix::from_diagonal(&dvector![1.0, 100.0, 3600.0, 90000.0]);
        let d = DMatrix::from_diagonal(&dvector![0.02, 0.2, 3.0, 30.0]);
        let w = DMatrix::from_column_slice(4, 1, &[1.0, 0.3, -0.2, 0.1]);
        let sys = CoupledSystem::new(k.clone(), d, w).unwrap();
        let mut forcing = ModalForcing::zero(n);
        forcing.constant = dvector![0.4, 2.0, -30.0, 200.0];
        forcing.add_harmonic(2.0, dvector![C64::new(0.0, -0.5), C64::new(0.3, 0.0), C64::new(0.0, 0.2), C64::new(1.0, 0.0)]);
        let targets = dvector![0.0];
        let mut start = ModalState { q: dvector![0.0, 0.0, 0.0, 0.0], qd: dvector![0.0, 0.5, 3.0, -2.0] };
        sys.project(&targets, &mut start);
        let q_c = sys.q_c(&targets);
        let seg = CoupledSegment::new(&sys, &forcing, &q_c, &(&k * &q_c), 0.0, &start);
        let h = Functional::of_position(OFFSET, dvector![-1.0, -1.0, -1.0, -1.0]);
        let p = seg.project_functional(&sys, &forcing, &h);
        let gap = |t: f64| {
            let mut st = ModalState::zeros(n);
            seg.state_at(&sys, t, &mut st);
            OFFSET - st.q.sum()
        };
        let tau = 2.0;
        let (mut sample, mut coords) = (CoupledSample::default(), Vec::new());
        let (mut t, mut probes, mut longer) = (0.0, 0, 0);
        while t < 10.0 && probes < 3000 {
            probes += 1;
            seg.sample_into(&sys, t, &mut sample);
            let jet = seg.jet(&p, &sample);
            assert!(jet.d[0] > 1e-4, "the gap closes at {t}");
            seg.coordinate_bounds_into(&sys, &sample, tau, &mut coords);
            let bounds = seg.bounds(&p, &coords, tau);
            // Each coordinate stays within its amplitude bound over the interval.
            for i in 0..=50 {
                let z = seg.z_at(&sys, t + tau * i as f64 / 50.0);
                for (zk, b) in z.iter().zip(&coords) {
                    assert!(zk.norm() <= b.sup * (1.0 + 1e-12), "|z| = {} above its bound {} at {t} + {i} tau / 50", zk.norm(), b.sup);
                }
            }
            let Certified::Clear(plain) = certified_step(&jet, &bounds, false) else { panic!("at zero at {t}") };
            let split = seg.split_step(&sys, &p, &sample, &coords, &jet, &bounds);
            if split > 1.01 * plain {
                longer += 1;
            }
            let s = plain.max(split);
            for i in 1..4000 {
                let x = t + s * i as f64 / 4000.0;
                assert!(gap(x) > -1e-13, "a step from {t} of {s} (split {split}, plain {plain}) passes a zero near {x}");
            }
            t += s;
        }
        assert!(probes < 3000, "{probes} probes to t = {t}");
        assert!(longer > probes / 4, "the split certified a longer step at {longer} of {probes} probes");
    }

    /// A held beam (six modes) rings after the stick at its coupled
    /// frequencies under a slow load (2 rad/s); its reaction is the
    /// sticking phase's event function, searched from t = 0 to 6, every
    /// certified step checked on a dense grid of the exact reaction.
    /// - Constant load -1050: the reaction starts at 58, dips to 11 in the
    ///   ringing and to 36 at the load's trough. Fewer than 25 probes (19;
    ///   the splits by rate alone take 30: the ringing sets their bounds
    ///   until it dies out).
    /// - Constant load -1020: the ringing takes the reaction through zero
    ///   at t = 0.0094, its steady part positive throughout; the search
    ///   stops there (with the transients' amplitude dropped from the
    ///   split, its first step, 0.41, passes that zero: checked).
    #[test]
    fn the_transient_split_steps_at_the_loads_pace_and_never_passes_a_zero() {
        let n = 6;
        let search = |constant: f64, ringing: f64| {
            let (k, d, w, _, targets, mut start) = held_beam(n);
            let sys = CoupledSystem::new(k.clone(), d, w).unwrap();
            let mut forcing = ModalForcing::zero(n);
            forcing.constant = DVector::from_fn(n, |j, _| if j == 0 { constant } else { 0.0 });
            forcing.add_harmonic(2.0, DVector::from_fn(n, |j, _| C64::new(if j == 0 { 1000.0 } else { 0.0 }, 0.0)));
            start.q.fill(0.0);
            start.qd = DVector::from_fn(n, |j, _| ringing * (j as f64 + 0.5).cos());
            sys.project(&targets, &mut start);
            let q_c = sys.q_c(&targets);
            let seg = CoupledSegment::new(&sys, &forcing, &q_c, &(&k * &q_c), 0.0, &start);
            let h = sys.reaction_functionals().remove(0);
            let p = seg.project_functional(&sys, &forcing, &h);
            let reaction = |t: f64| {
                let mut st = ModalState::zeros(n);
                seg.state_at(&sys, t, &mut st);
                let mut f = vec![DVector::zeros(n)];
                forcing.derivatives(t, &mut f);
                h.value(&st, &f[0])
            };
            let tau = 0.5;
            let (mut sample, mut coords) = (CoupledSample::default(), Vec::new());
            let (mut t, mut probes) = (0.0, 0);
            while t < 6.0 && probes < 1000 {
                probes += 1;
                seg.sample_into(&sys, t, &mut sample);
                let jet = seg.jet(&p, &sample);
                seg.coordinate_bounds_into(&sys, &sample, tau, &mut coords);
                let bounds = seg.bounds(&p, &coords, tau);
                let Certified::Clear(plain) = certified_step(&jet, &bounds, false) else { return (probes, t) };
                let s = plain.max(seg.split_step(&sys, &p, &sample, &coords, &jet, &bounds));
                if !(t + s > t) {
                    return (probes, t);
                }
                for i in 1..2000 {
                    let x = t + s * i as f64 / 2000.0;
                    assert!(reaction(x) > -1e-9, "constant {constant}: a step from {t} of {s} passes a zero near {x}");
                }
                t += s;
            }
            (probes, t)
        };
        let (probes, t) = search(-1050.0, 0.25);
        assert!(t >= 6.0 && probes < 25, "{probes} probes to t = {t}");
        let (_, t) = search(-1020.0, 0.25);
        assert!(t > 0.0 && t < 0.05, "stopped at {t}");
    }

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
    }
}
