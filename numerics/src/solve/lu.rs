//! Dense LU factorisation with partial pivoting, in place: the Newton
//! matrices of the implicit steppers, Radau IIA's real and complex ones
//! ([`super::radau`]) and force collocation's of the nodal forces
//! ([`super::collocation`]).
//!
//! One elimination, real or complex, in two orders of rounding
//! ([`Order`]): each caller keeps, to the bit, the arithmetic its results
//! were recorded with. Both eliminate in the same sequence (every entry
//! `a_ij -= l_ik u_kj` for `k` in turn, the multipliers by the pivot's
//! reciprocal); they differ in the pivot among equals, in whether the
//! factors keep the pivot or its reciprocal, and in the order of the
//! substitutions' sums.

use std::iter::Sum;
use std::ops::{Div, Mul, Sub};

use nalgebra::DMatrix;

use super::C64;

/// An entry of a matrix to factor: `f64` or [`C64`] (whose products and
/// quotients are num-complex's, the textbook formulas RADAU5 writes out).
pub trait Entry: nalgebra::Scalar + Copy + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self> + Sum {
    const ZERO: Self;
    /// The size that picks the pivot: `|x|`, for a complex number
    /// `|re| + |im|` (RADAU5's).
    fn magnitude(self) -> f64;
    /// `1 / x`.
    fn recip(self) -> Self;
}

impl Entry for f64 {
    const ZERO: Self = 0.0;
    fn magnitude(self) -> f64 {
        self.abs()
    }
    fn recip(self) -> Self {
        1.0 / self
    }
}

impl Entry for C64 {
    const ZERO: Self = C64::new(0.0, 0.0);
    fn magnitude(self) -> f64 {
        self.re.abs() + self.im.abs()
    }
    fn recip(self) -> Self {
        self.inv()
    }
}

/// How a factorisation picks its pivots and rounds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Order {
    /// By columns, as RADAU5's DEC and SOL (HW96): the first of the
    /// largest candidates is the pivot, and it must be finite; multipliers
    /// by the pivot's reciprocal; substitutions column by column.
    Columns,
    /// By rows: the last of the largest candidates (in `total_cmp`'s
    /// order, so a NaN is chosen and refused); multipliers by the pivot's
    /// reciprocal, which the factors keep in place of the pivot;
    /// substitutions row by row, each a dot product, the back
    /// substitution's multiplied by that reciprocal (no division in a
    /// solve: force collocation solves four times per factorisation).
    Rows,
}

/// `P A = L U` of a square matrix, kept in its storage (column-major);
/// the storage is reused from factorisation to factorisation.
#[derive(Clone, Debug)]
pub struct Lu<T: Entry> {
    a: DMatrix<T>,
    pivots: Vec<usize>,
    /// The order of the last factorisation, for its solves.
    order: Order,
}

impl<T: Entry> Default for Lu<T> {
    fn default() -> Self {
        Lu { a: DMatrix::from_element(0, 0, T::ZERO), pivots: Vec::new(), order: Order::Columns }
    }
}

/// `$call` with `$n` a literal where it is small (force collocation's
/// Newton matrices: four nodes per contact), so that the loops unroll;
/// the same operations in the same order at every size.
macro_rules! sized {
    ($n:ident, $f:ident($($arg:expr),*)) => {{
        let n = $n;
        match n {
            1 => $f($($arg,)* 1),
            2 => $f($($arg,)* 2),
            3 => $f($($arg,)* 3),
            4 => $f($($arg,)* 4),
            8 => $f($($arg,)* 8),
            _ => $f($($arg,)* n),
        }
    }};
}

impl<T: Entry> Lu<T> {
    /// The matrix to factor next, `n x n`, for the caller to fill (zeros
    /// after a change of size, else the last factors).
    pub fn matrix_mut(&mut self, n: usize) -> &mut DMatrix<T> {
        if self.a.nrows() != n {
            self.a = DMatrix::from_element(n, n, T::ZERO);
            self.pivots = vec![0; n];
        }
        &mut self.a
    }

    /// Factors the matrix in place; `false` when a column has no usable
    /// pivot (singular, or non-finite under [`Order::Columns`]).
    pub fn factor(&mut self, order: Order) -> bool {
        self.order = order;
        let n = self.a.nrows();
        let (a, pivots) = (self.a.as_mut_slice(), self.pivots.as_mut_slice());
        sized!(n, factor_in(a, pivots, order))
    }

    /// `b <- A^-1 b` with the last factors.
    pub fn solve(&self, b: &mut [T]) {
        let (n, a) = (self.a.nrows(), self.a.as_slice());
        let (pivots, order) = (self.pivots.as_slice(), self.order);
        sized!(n, solve_in(a, pivots, b, order))
    }
}


#[inline(always)]
fn factor_in<T: Entry>(a: &mut [T], pivots: &mut [usize], order: Order, n: usize) -> bool {
    let (a, pivots) = (&mut a[..n * n], &mut pivots[..n]);
    for k in 0..n {
        let column = &a[k * n..(k + 1) * n];
        let p = match order {
            Order::Columns => (k..n).fold(k, |p, i| if column[i].magnitude() > column[p].magnitude() { i } else { p }),
            Order::Rows => (k..n).max_by(|&i, &j| column[i].magnitude().total_cmp(&column[j].magnitude())).expect("a row"),
        };
        let largest = column[p].magnitude();
        if !(largest > 0.0 && (order == Order::Rows || largest.is_finite())) {
            return false;
        }
        pivots[k] = p;
        if p != k {
            (0..n).for_each(|j| a.swap(k + j * n, p + j * n));
        }
        let inverse = a[k + k * n].recip();
        if order == Order::Rows {
            a[k + k * n] = inverse;
        }
        a[k * n + k + 1..(k + 1) * n].iter_mut().for_each(|x| *x = *x * inverse);
        for j in k + 1..n {
            let (left, right) = a.split_at_mut(j * n);
            let (lk, cj) = (&left[k * n..(k + 1) * n], &mut right[..n]);
            let ukj = cj[k];
            (k + 1..n).for_each(|i| cj[i] = cj[i] - lk[i] * ukj);
        }
    }
    true
}

#[inline(always)]
fn solve_in<T: Entry>(a: &[T], pivots: &[usize], b: &mut [T], order: Order, n: usize) {
    let (a, pivots, b) = (&a[..n * n], &pivots[..n], &mut b[..n]);
    (0..n).for_each(|k| b.swap(k, pivots[k]));
    match order {
        Order::Columns => {
            for j in 0..n {
                let bj = b[j];
                (j + 1..n).for_each(|i| b[i] = b[i] - a[i + j * n] * bj);
            }
            for j in (0..n).rev() {
                b[j] = b[j] / a[j + j * n];
                let bj = b[j];
                (0..j).for_each(|i| b[i] = b[i] - a[i + j * n] * bj);
            }
        }
        Order::Rows => {
            for i in 0..n {
                let s: T = (0..i).map(|c| a[i + c * n] * b[c]).sum();
                b[i] = b[i] - s;
            }
            for i in (0..n).rev() {
                let s: T = (i + 1..n).map(|c| a[i + c * n] * b[c]).sum();
                b[i] = (b[i] - s) * a[i + i * n];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both orders, real and complex, solve a system with pivoting to
    /// rounding, and refuse a singular one.
    #[test]
    fn solves_and_refuses() {
        let m = [[1e-3, 2.0, -1.0], [4.0, 0.5, 3.0], [-2.0, 1.0, 0.25]];
        let x = [1.0, -2.0, 0.5];
        for order in [Order::Columns, Order::Rows] {
            let mut lu = Lu::<f64>::default();
            lu.matrix_mut(3).copy_from(&DMatrix::from_fn(3, 3, |i, j| m[i][j]));
            assert!(lu.factor(order));
            let mut b: Vec<f64> = (0..3).map(|i| (0..3).map(|j| m[i][j] * x[j]).sum()).collect();
            lu.solve(&mut b);
            assert!(b.iter().zip(&x).all(|(a, e)| (a - e).abs() < 1e-14), "{order:?}: {b:?}");
            let mut lu = Lu::<C64>::default();
            lu.matrix_mut(3).copy_from(&DMatrix::from_fn(3, 3, |i, j| C64::new(m[i][j], 0.1 * (i + 2 * j) as f64)));
            assert!(lu.factor(order));
            let xc: Vec<C64> = x.iter().map(|v| C64::new(*v, -*v)).collect();
            let mut b: Vec<C64> = (0..3).map(|i| (0..3).map(|j| C64::new(m[i][j], 0.1 * (i + 2 * j) as f64) * xc[j]).sum()).collect();
            lu.solve(&mut b);
            assert!(b.iter().zip(&xc).all(|(a, e)| (a - e).norm() < 1e-14), "{order:?}: {b:?}");
            lu.matrix_mut(3).fill(C64::new(1.0, 1.0));
            assert!(!lu.factor(order));
        }
    }
}
