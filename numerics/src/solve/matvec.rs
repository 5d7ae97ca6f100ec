//! The matrix-vector product of the integrators' right-hand sides, over
//! nalgebra's column-major storage.
//!
//! Each row's sum runs in the order of the columns from a given start, as
//! a plain column-by-column loop adds (the rows in SIMD lanes), so the
//! bits do not depend on the blocking. Below [`WIDE_ROWS`] rows the row
//! count is a constant of a copy per count: the sums stay in registers
//! for the whole product (the rotating beam's `(N+1)`-row products at 6
//! and 12 modes: 12 and 10 % fewer instructions over its run than the
//! blocked loop). From there four columns are added per pass over `out`:
//! the running sums stay in registers for four products instead of one,
//! and the loads and stores of `out` (what bounds the plain loop) fall to
//! a quarter. The rows are independent lanes, so from [`WIDE_ROWS`] rows
//! on the loop runs compiled with AVX where the processor has it
//! ([`super::wide`]): the same bits, four rows per instruction.

/// `out = start + a x`, `a` column-major with `out.len()` rows and
/// `x.len()` columns; each row summed in the order of `j`.
pub fn mat_vec(a: &[f64], x: &[f64], out: &mut [f64], start: f64) {
    if mat_vec_short(a, x, out, start) {
        return;
    }
    #[cfg(target_arch = "x86_64")]
    if out.len() >= WIDE_ROWS && super::wide::avx() {
        // SAFETY: the processor has AVX (just checked).
        return unsafe { mat_vec_avx(a, x, out, start) };
    }
    mat_vec_body(a, x, out, start)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn mat_vec_avx(a: &[f64], x: &[f64], out: &mut [f64], start: f64) {
    mat_vec_body(a, x, out, start)
}

/// Fewer rows than this run in the baseline build: AVX's four lanes
/// leave more of a short column to the scalar remainder (7 rows: 9 % more
/// instructions over the rotating beam's 6-mode run, 16 % fewer at 64).
const WIDE_ROWS: usize = 16;

/// Below this many rows the sums stay in registers for the whole product
/// (the rows a constant, unrolled: one pass over `a`, none over `out`).
const SHORT_ROWS: usize = WIDE_ROWS;

/// `mat_vec` with the rows a constant, from 1 to `SHORT_ROWS - 1` rows:
/// whether it ran.
fn mat_vec_short(a: &[f64], x: &[f64], out: &mut [f64], start: f64) -> bool {
    macro_rules! rows {
        ($($r:literal)*) => {
            match out.len() {
                $($r => mat_vec_rows::<$r>(a, x, out, start),)*
                _ => return false,
            }
        };
    }
    const _: () = assert!(SHORT_ROWS == 16, "one arm per row count below SHORT_ROWS");
    rows!(1 2 3 4 5 6 7 8 9 10 11 12 13 14 15);
    true
}

#[inline(always)]
fn mat_vec_rows<const R: usize>(a: &[f64], x: &[f64], out: &mut [f64], start: f64) {
    assert_eq!(a.len(), R * x.len(), "mat_vec: a is {} entries for {} x {}", a.len(), R, x.len());
    let mut sums = [start; R];
    for (column, &xj) in a.chunks_exact(R).zip(x) {
        for (s, aij) in sums.iter_mut().zip(column) {
            *s += aij * xj;
        }
    }
    out.copy_from_slice(&sums);
}

#[inline(always)]
fn mat_vec_body(a: &[f64], x: &[f64], out: &mut [f64], start: f64) {
    let rows = out.len();
    assert_eq!(a.len(), rows * x.len(), "mat_vec: a is {} entries for {} x {}", a.len(), rows, x.len());
    out.fill(start);
    let mut blocks = x.chunks_exact(4);
    let mut columns = a.chunks_exact(4 * rows.max(1));
    for (xs, block) in (&mut blocks).zip(&mut columns) {
        let (c0, rest) = block.split_at(rows);
        let (c1, rest) = rest.split_at(rows);
        let (c2, c3) = rest.split_at(rows);
        let [x0, x1, x2, x3] = [xs[0], xs[1], xs[2], xs[3]];
        for ((((o, a0), a1), a2), a3) in out.iter_mut().zip(c0).zip(c1).zip(c2).zip(c3) {
            let mut s = *o;
            s += a0 * x0;
            s += a1 * x1;
            s += a2 * x2;
            s += a3 * x3;
            *o = s;
        }
    }
    let done = x.len() - blocks.remainder().len();
    for (j, &xj) in x.iter().enumerate().skip(done) {
        for (o, aij) in out.iter_mut().zip(&a[j * rows..(j + 1) * rows]) {
            *o += aij * xj;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The same bits as the plain column loop, for every shape up to 9 x 9
    /// (every remainder of the blocking) and from 16 to 23 and 65 rows
    /// (the AVX copy, where the processor has it), and a start of either
    /// sign of 0.
    #[test]
    fn blocked_sums_are_the_plain_loops_bits() {
        let mut seed = 0x9e3779b97f4a7c15u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        for rows in (0..WIDE_ROWS + 8).chain([65]) {
            for cols in (0..10).chain([65]) {
                let a: Vec<f64> = (0..rows * cols).map(|_| next() * 1e3f64.powf(next())).collect();
                let x: Vec<f64> = (0..cols).map(|_| next()).collect();
                for start in [0.0, -0.0] {
                    let mut plain = vec![start; rows];
                    for j in 0..cols {
                        for i in 0..rows {
                            plain[i] += a[j * rows + i] * x[j];
                        }
                    }
                    let mut out = vec![f64::NAN; rows];
                    mat_vec(&a, &x, &mut out, start);
                    let bits = |v: &[f64]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(&out), bits(&plain), "{rows} x {cols}");
                }
            }
        }
    }
}
