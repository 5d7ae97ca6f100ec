//! Eigenvalues and eigenvectors of a real square matrix (the first-order
//! form of a non-proportionally damped phase).
//!
//! nalgebra's real Schur form `A = Q T Q^T` (Francis double-shift QR), then
//! the eigenvectors of the quasi-triangular `T` by back substitution, one
//! diagonal block at a time (as LAPACK's `dtrevc`), and `V = Q X`. A complex
//! pair comes from one 2x2 block of `T`: its eigenvalues are exact
//! conjugates, adjacent, the one with positive imaginary part first, and its
//! two vectors are exact conjugates.

use nalgebra::{DMatrix, DVector, Schur};

use crate::solve::complex::C64;

/// The eigenvalues of `a` and their eigenvectors (the columns of the
/// matrix), unnormalised.
pub fn real_eigen(a: DMatrix<f64>) -> Result<(DVector<C64>, DMatrix<C64>), String> {
    let n = a.nrows();
    if n == 0 {
        return Ok((DVector::zeros(0), DMatrix::zeros(0, 0)));
    }
    if a.iter().any(|x| !x.is_finite()) {
        return Err("the matrix has a non-finite entry".into());
    }
    let schur = Schur::try_new(a, f64::EPSILON, 1000 * n).ok_or("the real Schur form did not converge")?;
    let (q, t) = schur.unpack();
    let blocks = diagonal_blocks(&t)?;
    let scale = t.iter().fold(0.0f64, |m, x| m.max(x.abs())).max(f64::MIN_POSITIVE);
    // The smallest pivot a back substitution divides by (LAPACK's smin):
    // a repeated eigenvalue gives a large but finite vector component.
    let smallest_pivot = f64::EPSILON * scale;

    let mut eig = DVector::<C64>::zeros(n);
    let mut xr = DMatrix::<f64>::zeros(n, n);
    let mut xi = DMatrix::<f64>::zeros(n, n);
    for (b, &(k, size)) in blocks.iter().enumerate() {
        let lambdas: Vec<C64> = if size == 1 { vec![C64::new(t[(k, k)], 0.0)] } else { block_eigenvalues(&t, k) };
        let paired = lambdas.len() == 2 && lambdas[0].im != 0.0;
        for (j, &lambda) in lambdas.iter().enumerate() {
            let col = k + j;
            if paired && j == 1 {
                // The conjugate of the previous column, exactly.
                eig[col] = lambda;
                for i in 0..n {
                    xr[(i, col)] = xr[(i, col - 1)];
                    xi[(i, col)] = -xi[(i, col - 1)];
                }
                continue;
            }
            let x = triangular_eigenvector(&t, &blocks[..=b], lambda, smallest_pivot);
            eig[col] = lambda;
            for (i, z) in x.iter().enumerate() {
                xr[(i, col)] = z.re;
                xi[(i, col)] = z.im;
            }
        }
    }
    let vr = &q * xr;
    let vi = &q * xi;
    let v = DMatrix::from_fn(n, n, |i, j| C64::new(vr[(i, j)], vi[(i, j)]));
    Ok((eig, v))
}

/// The diagonal blocks of a quasi-triangular `t`: `(first row, size)`.
fn diagonal_blocks(t: &DMatrix<f64>) -> Result<Vec<(usize, usize)>, String> {
    let n = t.nrows();
    let mut blocks = Vec::new();
    let mut k = 0;
    while k < n {
        if k + 1 < n && t[(k + 1, k)] != 0.0 {
            if k + 2 < n && t[(k + 2, k + 1)] != 0.0 {
                return Err(format!("the real Schur form is not quasi-triangular at row {}", k + 1));
            }
            blocks.push((k, 2));
            k += 2;
        } else {
            blocks.push((k, 1));
            k += 1;
        }
    }
    Ok(blocks)
}

/// The eigenvalues of the 2x2 block of `t` at `k`: a conjugate pair (positive
/// imaginary part first), or two real ones.
fn block_eigenvalues(t: &DMatrix<f64>, k: usize) -> Vec<C64> {
    let (a, b, c, d) = (t[(k, k)], t[(k, k + 1)], t[(k + 1, k)], t[(k + 1, k + 1)]);
    let half_trace = 0.5 * (a + d);
    let half_diff = 0.5 * (a - d);
    let disc = half_diff * half_diff + b * c;
    if disc < 0.0 {
        let im = (-disc).sqrt();
        vec![C64::new(half_trace, im), C64::new(half_trace, -im)]
    } else {
        // Real: the root of larger modulus first, the other from the
        // determinant (no cancellation).
        let s = if half_trace >= 0.0 { disc.sqrt() } else { -disc.sqrt() };
        let root = half_trace + s;
        let other = if root != 0.0 { (a * d - b * c) / root } else { half_trace - s };
        vec![C64::new(root, 0.0), C64::new(other, 0.0)]
    }
}

/// The eigenvector of quasi-triangular `t` for `lambda`, an eigenvalue of
/// the last of `blocks` (the diagonal blocks up to and including it): zero
/// below that block, its null vector in it, and back substitution above.
fn triangular_eigenvector(t: &DMatrix<f64>, blocks: &[(usize, usize)], lambda: C64, smallest_pivot: f64) -> Vec<C64> {
    let &(k, size) = blocks.last().expect("at least the eigenvalue's own block");
    let end = k + size;
    let mut x = vec![C64::new(0.0, 0.0); end];
    if size == 1 {
        x[k] = C64::new(1.0, 0.0);
    } else {
        // A null vector of [[a - l, b], [c, d - l]]: (b, l - a) or (l - d, c),
        // whichever is longer.
        let (a, b, c, d) = (t[(k, k)], t[(k, k + 1)], t[(k + 1, k)], t[(k + 1, k + 1)]);
        let first = (C64::new(b, 0.0), lambda - a);
        let second = (lambda - d, C64::new(c, 0.0));
        let norm = |v: &(C64, C64)| v.0.norm_sqr() + v.1.norm_sqr();
        let chosen = if norm(&first) >= norm(&second) { first } else { second };
        x[k] = chosen.0;
        x[k + 1] = chosen.1;
    }
    for &(r, rsize) in blocks[..blocks.len() - 1].iter().rev() {
        // Right-hand side: -(T x) over the block's rows, from the components
        // already known (right of the block).
        let rhs = |i: usize| -> C64 {
            let mut s = C64::new(0.0, 0.0);
            for l in r + rsize..end {
                s += x[l] * t[(i, l)];
            }
            -s
        };
        if rsize == 1 {
            let pivot = guard(C64::new(t[(r, r)], 0.0) - lambda, smallest_pivot);
            x[r] = rhs(r) / pivot;
        } else {
            // [[a - l, b], [c, d - l]] [x0; x1] = [r0; r1] by Cramer's rule.
            let (a, b, c, d) = (t[(r, r)], t[(r, r + 1)], t[(r + 1, r)], t[(r + 1, r + 1)]);
            let (r0, r1) = (rhs(r), rhs(r + 1));
            let (a, d) = (C64::new(a, 0.0) - lambda, C64::new(d, 0.0) - lambda);
            let det = guard(a * d - C64::new(b * c, 0.0), smallest_pivot * smallest_pivot.max(1.0));
            x[r] = (r0 * d - r1 * b) / det;
            x[r + 1] = (a * r1 - r0 * c) / det;
        }
    }
    let mut full = vec![C64::new(0.0, 0.0); t.nrows()];
    full[..end].copy_from_slice(&x);
    full
}

/// `z`, or a value of modulus `smallest` in its direction when smaller.
fn guard(z: C64, smallest: f64) -> C64 {
    let m = z.norm();
    if m >= smallest {
        z
    } else if m > 0.0 {
        z * (smallest / m)
    } else {
        C64::new(smallest, 0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn residual(a: &DMatrix<f64>, eig: &DVector<C64>, v: &DMatrix<C64>) -> f64 {
        let ac = a.map(|x| C64::new(x, 0.0));
        let mut worst = 0.0f64;
        for k in 0..eig.len() {
            let col = v.column(k).into_owned();
            let r = &ac * &col - &col * eig[k];
            worst = worst.max(r.norm() / (col.norm() * a.norm()));
        }
        worst
    }

    #[test]
    fn a_damped_oscillator_chain_has_conjugate_pairs_and_small_residuals() {
        // [[0, W], [-W, -D]] with a full damping matrix: complex pairs,
        // and real eigenvalues for the overdamped last mode.
        let n = 12;
        let w = DVector::from_fn(n, |i, _| ((i + 1) as f64).powi(2));
        let mut d = DMatrix::from_fn(n, n, |i, j| 0.01 * (((i + 2 * j) as f64).sin() + if i == j { 3.0 } else { 0.0 }));
        d = &d * d.transpose();
        d[(n - 1, n - 1)] += 400.0;
        let a = DMatrix::from_fn(2 * n, 2 * n, |i, j| match (i < n, j < n) {
            (true, true) => 0.0,
            (true, false) => if j - n == i { w[i] } else { 0.0 },
            (false, true) => if i - n == j { -w[j] } else { 0.0 },
            (false, false) => -d[(i - n, j - n)],
        });
        let (eig, v) = real_eigen(a.clone()).unwrap();
        assert!(residual(&a, &eig, &v) < 1e-13, "{}", residual(&a, &eig, &v));
        let mut pairs = 0;
        for k in 1..eig.len() {
            if eig[k - 1].im > 0.0 {
                assert_eq!(eig[k], eig[k - 1].conj());
                assert!(v.column(k).iter().zip(v.column(k - 1).iter()).all(|(a, b)| *a == b.conj()));
                pairs += 1;
            }
        }
        assert_eq!(pairs, n - 1);
        assert_eq!(eig.iter().filter(|l| l.im == 0.0).count(), 2);
    }

    #[test]
    fn a_repeated_eigenvalue_still_gives_finite_vectors() {
        let a = DMatrix::from_row_slice(3, 3, &[2.0, 1.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 2.0]);
        let (eig, v) = real_eigen(a.clone()).unwrap();
        assert!(eig.iter().all(|l| (l - C64::new(2.0, 0.0)).norm() < 1e-14));
        assert!(v.iter().all(|z| z.re.is_finite() && z.im.is_finite()));
        assert!(residual(&a, &eig, &v) < 1e-14);
    }
}
