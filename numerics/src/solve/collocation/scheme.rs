//! The Gauss-Legendre scheme of force collocation on `[0, 1]` and the
//! polynomial helpers of its monomial coefficients.

use std::sync::OnceLock;

use nalgebra::DMatrix;

use super::STAGES;

/// Gauss-Legendre nodes on `[0, 1]` and the polynomials built on them, in
/// arrays: the one scheme lives in a static ([`Self::shared`]), and heap
/// memory of a static outlives an FMU's library once it is unloaded
/// (valgrind's "definitely lost").
#[derive(Clone, Debug)]
pub(super) struct Scheme {
    pub(super) s: usize,
    pub(super) c: [f64; STAGES],
    pub(super) b: [f64; STAGES],
    /// Monomial coefficients of the Lagrange basis: `vinv[m * s + k]` is
    /// the coefficient of `sigma^m` in `l_k`.
    pub(super) vinv: [f64; STAGES * STAGES],
    /// Monomial coefficients of `w_s(sigma) = prod (sigma - c_i)`.
    pub(super) node_poly: [f64; STAGES + 1],
}

impl Scheme {
    /// The scheme of [`STAGES`] stages, formed once and shared by every
    /// stepper (one per contact phase).
    pub(super) fn shared() -> &'static Scheme {
        static SCHEME: OnceLock<Scheme> = OnceLock::new();
        SCHEME.get_or_init(|| Scheme::gauss(STAGES))
    }

    /// The scheme of `s` = [`STAGES`] stages.
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
        let v = DMatrix::from_fn(s, s, |i, m| power(c[i], m as u32));
        let inv = v.try_inverse().expect("distinct nodes");
        // inv[(m, k)]: coefficient m of the polynomial that is 1 at node k.
        let vinv: Vec<f64> = (0..s * s).map(|idx| inv[(idx / s, idx % s)]).collect();
        let mut node_poly = vec![1.0];
        for ci in &c {
            let mut next = vec![0.0; node_poly.len() + 1];
            for (m, a) in node_poly.iter().enumerate() {
                next[m + 1] += a;
                next[m] -= ci * a;
            }
            node_poly = next;
        }
        fn array<const N: usize>(v: Vec<f64>) -> [f64; N] {
            v.try_into().expect("sized by STAGES")
        }
        Scheme { s, c: array(c), b: array(b), vinv: array(vinv), node_poly: array(node_poly) }
    }

    /// Monomial coefficients `alpha[m] = sum_k vinv[m][k] values[k]`.
    pub(super) fn monomials(&self, values: &[f64], out: &mut [f64]) {
        let s = self.s;
        for (m, o) in out.iter_mut().enumerate() {
            *o = (0..s).map(|k| self.vinv[m * s + k] * values[k]).sum();
        }
    }
}

/// `x^m` by binary powering, as `f64::powi` runs (compiler-rt's
/// `__powidf2`). `powi` of constants is folded by the compiler with one
/// rounding, so the scheme's bits would hang on whether its nodes are
/// known where it is formed.
fn power(mut x: f64, mut m: u32) -> f64 {
    let mut r = 1.0;
    loop {
        if m & 1 == 1 {
            r *= x;
        }
        m /= 2;
        if m == 0 {
            return r;
        }
        x *= x;
    }
}

pub(super) fn horner(coeffs: &[f64], x: f64) -> f64 {
    coeffs.iter().rev().fold(0.0, |acc, a| acc * x + a)
}

/// The coefficients in `u` of `p(sigma + ratio u)`, `p` given by its
/// monomial coefficients.
pub(super) fn taylor_shift(p: &[f64], sigma: f64, ratio: f64, out: &mut [f64]) {
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

/// `int_0^sigma` of the polynomial with monomial coefficients `coeffs`.
pub(super) fn integral(coeffs: &[f64], sigma: f64) -> f64 {
    coeffs.iter().enumerate().rev().fold(0.0, |acc, (m, a)| acc * sigma + a / (m + 1) as f64) * sigma
}
