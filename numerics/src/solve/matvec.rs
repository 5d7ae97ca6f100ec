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

/// [`mat_vec`] of one matrix with several vectors: `outs[k] = start + a
/// xs[k]`, each row summed in the order of `j` as [`mat_vec`] sums it (the
/// same bits). From [`WIDE_ROWS`] rows up to [`BATCH`] vectors go through
/// `a` together, eight rows at a time with every vector's sums in
/// registers: `a` is read once per batch instead of once per vector, which
/// bounds the single products at many rows (the rotating beam's `(N+1)^2`
/// products at a step's nodes).
pub fn mat_vecs(a: &[f64], xs: &[&[f64]], outs: &mut [&mut [f64]], start: f64) {
    assert_eq!(xs.len(), outs.len(), "mat_vecs: {} vectors, {} outputs", xs.len(), outs.len());
    let Some(rows) = outs.first().map(|o| o.len()) else { return };
    if rows < WIDE_ROWS || xs.len() == 1 {
        for (x, out) in xs.iter().zip(outs.iter_mut()) {
            mat_vec(a, x, out, start);
        }
        return;
    }
    for (xs, outs) in xs.chunks(BATCH).zip(outs.chunks_mut(BATCH)) {
        macro_rules! batch {
            ($($k:literal)*) => {
                match xs.len() {
                    $($k => {
                        let xs: &[&[f64]; $k] = xs.try_into().expect("a chunk of $k");
                        let outs: &mut [&mut [f64]; $k] = outs.try_into().expect("a chunk of $k");
                        #[cfg(target_arch = "x86_64")]
                        if super::wide::avx() {
                            // SAFETY: the processor has AVX (just checked).
                            unsafe { mat_vecs_avx::<$k>(a, xs, outs, start) };
                            continue;
                        }
                        mat_vecs_body::<$k>(a, xs, outs, start);
                    })*
                    _ => unreachable!("chunks of at most BATCH"),
                }
            };
        }
        const _: () = assert!(BATCH == 6, "one arm per batch size up to BATCH");
        batch!(1 2 3 4 5 6);
    }
}

/// From this many rows [`mat_vecs`] pays over single products for the
/// rotating beam's remainders at a step's nodes (the DWZ scene at 1e-8,
/// fastest of 7 to 9 runs: 48 modes 1.04 times as fast, 64 modes 1.10;
/// 24 and 32 modes 2 % slower, their matrices staying in the first-level
/// cache between single products).
pub const BATCH_ROWS: usize = 40;

/// Vectors per pass of [`mat_vecs`] (the exponential integrator's nodes
/// past the step's start); with eight rows, twelve sums in registers.
const BATCH: usize = 6;

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn mat_vecs_avx<const K: usize>(a: &[f64], xs: &[&[f64]; K], outs: &mut [&mut [f64]; K], start: f64) {
    mat_vecs_body::<K>(a, xs, outs, start)
}

#[inline(always)]
fn mat_vecs_body<const K: usize>(a: &[f64], xs: &[&[f64]; K], outs: &mut [&mut [f64]; K], start: f64) {
    let rows = outs[0].len();
    let cols = xs[0].len();
    assert!(a.len() == rows * cols && xs.iter().all(|x| x.len() == cols) && outs.iter().all(|o| o.len() == rows), "mat_vecs: a is {} entries for {rows} x {cols}", a.len());
    #[inline(always)]
    fn block<const K: usize, const R: usize>(a: &[f64], xs: &[&[f64]; K], outs: &mut [&mut [f64]; K], start: f64, r0: usize) {
        let rows = outs[0].len();
        let mut sums = [[start; R]; K];
        for (j, column) in a.chunks_exact(rows).enumerate() {
            let column: &[f64; R] = column[r0..r0 + R].try_into().expect("R rows");
            for (s, x) in sums.iter_mut().zip(xs) {
                let xj = x[j];
                for (si, aij) in s.iter_mut().zip(column) {
                    *si += aij * xj;
                }
            }
        }
        for (out, s) in outs.iter_mut().zip(&sums) {
            out[r0..r0 + R].copy_from_slice(s);
        }
    }
    let mut r0 = 0;
    while r0 + 8 <= rows {
        block::<K, 8>(a, xs, outs, start, r0);
        r0 += 8;
    }
    if r0 + 4 <= rows {
        block::<K, 4>(a, xs, outs, start, r0);
        r0 += 4;
    }
    while r0 < rows {
        block::<K, 1>(a, xs, outs, start, r0);
        r0 += 1;
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
    /// [`mat_vecs`] gives each vector [`mat_vec`]'s bits, for every batch
    /// size up to two batches and row counts below, at and past the wide
    /// rows (every remainder of the eight-row blocks).
    #[test]
    fn batched_products_are_the_single_ones_bits() {
        let mut seed = 0x2545f4914f6cdd1du64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        for rows in [1, 7, 15, 16, 17, 19, 20, 23, 24, 33, 65] {
            for cols in [1, 5, 16, 33, 65] {
                let a: Vec<f64> = (0..rows * cols).map(|_| next() * 1e3f64.powf(next())).collect();
                for k in 1..=2 * BATCH + 1 {
                    let xs: Vec<Vec<f64>> = (0..k).map(|_| (0..cols).map(|_| next()).collect()).collect();
                    let refs: Vec<&[f64]> = xs.iter().map(|x| &x[..]).collect();
                    let mut outs = vec![vec![f64::NAN; rows]; k];
                    let mut out_refs: Vec<&mut [f64]> = outs.iter_mut().map(|o| &mut o[..]).collect();
                    mat_vecs(&a, &refs, &mut out_refs, -0.0);
                    for (x, out) in xs.iter().zip(&outs) {
                        let mut single = vec![f64::NAN; rows];
                        mat_vec(&a, x, &mut single, -0.0);
                        let bits = |v: &[f64]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
                        assert_eq!(bits(out), bits(&single), "{rows} x {cols}, {k} vectors");
                    }
                }
            }
        }
    }
}
