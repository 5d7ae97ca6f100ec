//! The switch locator of every integrated phase: the first zero of a set
//! of watched functions along one accepted step's dense output (the
//! force collocation's, DOP853's or Radau's polynomial), located so that a dip between
//! samples is not missed where it can be seen.
//!
//! **Samples.** The functions are evaluated at [`SAMPLES`] equally spaced
//! points of the step; the first sample where one is negative brackets its
//! zero with the sample before it, and bisection on the dense output
//! locates it to an ulp: the first point past the zero. A function already
//! negative at the bracket's start (by rounding, at the restart after a
//! switch) is placed at the bracket's end, so that a search never moves
//! on by a mere ulp; one at zero and rising there (a geometric function
//! leaving a switch) is bisected from the first point a few ulps on where
//! it is positive, its rounding just after the start not taken for a zero.
//! The bracket always starts at a sample of the step's own grid, so a
//! search resumed inside a step finds bit for bit the zero an
//! uninterrupted one finds.
//!
//! **Between samples.** A function that dips below zero and comes back
//! between two samples (a graze, a rebound inside a sample interval)
//! leaves both samples positive. For the functions that give a rate along
//! the curve (gaps and penetrations: geometric functions) the locator
//! also looks for interior minima: the rate at both ends and the middle of
//! each sample interval, and, when these three fit a parabola whose vertex
//! lies inside, at the vertex too; every change of sign from `-` to `+`
//! is bisected to the minimum, and a negative minimum brackets a zero on
//! its left. Were the curve exactly cubic and the function linear in it,
//! the rate would be quadratic and these points would find every minimum;
//! a miss needs two extrema within about an eighth of a step, a
//! reversal faster than the error control lets the polynomial represent.
//! An interval is not searched when its ends both lie higher above zero
//! than four times the larger rate at its ends times its length (a dip
//! needs a rate beyond four times those), or when the cubic through the
//! ends' values and rates stays above half the lower end (a dip needs the
//! function to leave that cubic by more, within a quarter of a step).
//! Functions without a rate at a sample have no such search there. A
//! compliant stop's force watch (a push's end, a push resumed) gives its
//! rate where it may dip to zero before the next sample: the integrated
//! phases form it from the dense output's acceleration along the contact,
//! and leave it out where the force lies far from zero in a step short
//! against the fastest mode (its dip would need a swing the step's force
//! polynomial does not pass).

/// Samples of the watched functions per accepted step.
pub const SAMPLES: usize = 4;

/// The samples of `[t0, t1]` where [`first_switch`] evaluates every
/// function (`t0` first), with the very expressions it uses: a dense
/// output may prepare its states there.
pub fn grid(t0: f64, t1: f64) -> Vec<f64> {
    std::iter::once(t0).chain((1..=SAMPLES).map(|k| sample(t0, t1, k))).collect()
}

/// Whether `t` is one of [`grid`]'s samples strictly inside `[t0, t1]`
/// (the same expressions, no allocation).
pub fn is_inner_sample(t0: f64, t1: f64, t: f64) -> bool {
    (1..SAMPLES).any(|k| sample(t0, t1, k) == t)
}

/// Sample `k` of `[t0, t1]` (`k = SAMPLES` is `t1`), as [`first_switch`]
/// forms it: a dense output may prepare its values there.
pub fn sample_time(t0: f64, t1: f64, k: usize) -> f64 {
    sample(t0, t1, k)
}

/// Sample `k` of `[t0, t1]` (`k = SAMPLES` is `t1`).
fn sample(t0: f64, t1: f64, k: usize) -> f64 {
    if k == SAMPLES {
        t1
    } else {
        t0 + (t1 - t0) * k as f64 / SAMPLES as f64
    }
}

/// Watched functions along one step's dense output.
pub trait DenseWatch {
    /// How many functions are watched.
    fn count(&self) -> usize;
    /// Every function's value at `t` into `out` (length [`Self::count`]).
    fn values(&self, t: f64, out: &mut [f64]);
    /// Function `i`'s value at `t`.
    fn value(&self, i: usize, t: f64) -> f64;
    /// Function `i`'s rate of change along the curve at `t`, for the
    /// geometric functions whose dips between samples are searched
    /// (`None` for the others).
    fn rate(&self, i: usize, t: f64) -> Option<f64>;
    /// Every function's value and rate at `t`, as [`Self::values`] and
    /// [`Self::rate`] give them: a sample's reads in one pass where the
    /// dense output gives both at once.
    fn values_and_rates(&self, t: f64, values: &mut [f64], rates: &mut [Option<f64>]) {
        self.values(t, values);
        for (i, r) in rates.iter_mut().enumerate() {
            *r = self.rate(i, t);
        }
    }
}

/// Functions whose reads are kept without an allocation (a phase
/// watches a few: its stops' gaps or penetrations).
const INLINE: usize = 8;

/// The watched functions' values and rates at one point.
struct Reads {
    n: usize,
    values: [f64; INLINE],
    rates: [Option<f64>; INLINE],
    /// More functions than [`INLINE`].
    spilled: Option<(Vec<f64>, Vec<Option<f64>>)>,
}

impl Reads {
    fn new(n: usize) -> Self {
        Self { n, values: [0.0; INLINE], rates: [None; INLINE], spilled: (n > INLINE).then(|| (vec![0.0; n], vec![None; n])) }
    }

    fn read(&mut self, watch: &impl DenseWatch, t: f64) {
        let (values, rates) = match &mut self.spilled {
            Some((values, rates)) => (&mut values[..], &mut rates[..]),
            None => (&mut self.values[..self.n], &mut self.rates[..self.n]),
        };
        watch.values_and_rates(t, values, rates);
    }

    fn values(&self) -> &[f64] {
        self.spilled.as_ref().map_or(&self.values[..self.n], |s| &s.0)
    }

    fn rates(&self) -> &[Option<f64>] {
        self.spilled.as_ref().map_or(&self.rates[..self.n], |s| &s.1)
    }
}

/// A located switch.
#[derive(Clone, Debug, PartialEq)]
pub struct Located {
    /// The first point found past the earliest zero.
    pub time: f64,
    /// The functions whose zero lies within a few ulps of it, each with
    /// the slope of the chord that bracketed it (negative).
    pub at_zero: Vec<(usize, f64)>,
    /// The sample the bracket started at.
    pub from: f64,
}

/// The first switch of the step `[t0, t1]` among the samples after
/// `after` (samples at or before it were found clear), or `None`. A
/// search resumed at a located switch's [`Located::from`] finds it again.
pub fn first_switch(watch: &impl DenseWatch, t0: f64, t1: f64, after: f64) -> Option<Located> {
    let n = watch.count();
    if n == 0 {
        return None;
    }
    // The reads at the bracket's start (the last sample searched) and at
    // its end: each sample read once.
    let (mut here, mut there) = (Reads::new(n), Reads::new(n));
    let mut here_read = false;
    let mut previous = t0;
    for k in 1..=SAMPLES {
        let s = sample(t0, t1, k);
        if s <= after {
            previous = s;
            continue;
        }
        if !here_read {
            here.read(watch, previous);
            here_read = true;
        }
        there.read(watch, s);
        let (start, at_sample) = ((here.values(), here.rates()), (there.values(), there.rates()));
        let mut roots: Vec<(usize, f64, f64)> = Vec::new();
        for (i, &vs) in at_sample.0.iter().enumerate() {
            let va = start.0[i];
            // The end of the bracket: the sample, or a negative minimum before it.
            let end = if vs < 0.0 {
                Some((s, vs))
            } else {
                let ends = Ends { a: previous, fa: va, da: start.1[i], b: s, fb: vs, db: at_sample.1[i] };
                negative_minimum(watch, i, ends).map(|tm| (tm, watch.value(i, tm)))
            };
            if let Some((b, vb)) = end {
                // A function already negative at the bracket's start (by
                // rounding, after a switch) is placed at the bracket's end:
                // the search moves on by a sample, never by an ulp.
                let root = if va >= 0.0 { bisect(|t| watch.value(i, t), clear_of_rounding(watch, i, previous, start.1[i], b), b) } else { b };
                let slope = if b > previous { (vb - va.max(0.0)) / (b - previous) } else { -1.0 };
                roots.push((i, root, slope.min(-f64::MIN_POSITIVE)));
            }
        }
        if roots.is_empty() {
            std::mem::swap(&mut here, &mut there);
            previous = s;
            continue;
        }
        let time = roots.iter().map(|r| r.1).fold(f64::INFINITY, f64::min);
        // Functions whose zero lies within a few ulps of the first.
        let close = 4.0 * f64::EPSILON * time.abs().max(f64::MIN_POSITIVE);
        let at_zero = roots.iter().filter(|r| r.1 - time <= close).map(|r| (r.0, r.2)).collect();
        return Some(Located { time, at_zero, from: previous });
    }
    None
}

/// Where the bisection of function `i` on `[a, b]` starts: `a`, or, when
/// the function rises at `a` (a geometric function leaving a switch at
/// its rounding level), the first of `a + 8, 64, 512, ... ulps` (up to a
/// millionth of the bracket) where it is positive. Rising from a value
/// `>= 0`, it has no zero that close: a value below zero there is its
/// rounding (the dense output at `a + ulp` may differ from the state at
/// `a` in the last bits), which a bisection would take for the zero.
fn clear_of_rounding(watch: &impl DenseWatch, i: usize, a: f64, rate_a: Option<f64>, b: f64) -> f64 {
    if !rate_a.is_some_and(|r| r > 0.0) {
        return a;
    }
    let limit = 1e-6 * (b - a);
    let mut step = 8.0 * f64::EPSILON * a.abs().max(b.abs());
    while step <= limit {
        if watch.value(i, a + step) > 0.0 {
            return a + step;
        }
        step *= 8.0;
    }
    a
}

/// The first point in `(a, b]` past which `f` is negative, given
/// `f(b) < 0`: the right end of a bracket narrowed to an ulp (`f(a)` is
/// taken as non-negative). Regula falsi with the Illinois modification;
/// when two points in a row land on one side, the next steps past the
/// secant's estimate by its distance from that side, to bracket the zero
/// tightly from the other; a secant that rounds onto an end (its value at
/// the rounding floor) probes just inside it; a bisection whenever the
/// bracket stops shrinking; once the secant point is known to a few ulps,
/// a bracket of a few ulps around it finished by bisection. About nine
/// evaluations (HertzStop's 42 switches: 374, where plain regula falsi
/// with Illinois took 702 and bisection alone about fifty each).
fn bisect(f: impl Fn(f64) -> f64, mut a: f64, mut b: f64) -> f64 {
    let (mut fa, mut fb) = (f(a).max(0.0), f(b));
    let mut last_width = b - a;
    let mut side = 0i32;
    // The last point was a probe just inside an end the secant rounded
    // onto: a function flat at zero (a clamped force) would make the
    // next probe crawl an ulp at a time, so the next is a bisection.
    let mut probed_end = false;
    loop {
        let m = 0.5 * (a + b);
        if !(m > a && m < b) {
            return b;
        }
        let width = b - a;
        let secant = if fa > fb { b - fb * (width / (fb - fa)) } else { m };
        let ulps = 4.0 * f64::EPSILON * a.abs().max(b.abs());
        let x = if width > 0.5 * last_width && side.abs() > 2 {
            // Slow progress: bisect.
            m
        } else if side.abs() > 1 && secant > a && secant < b {
            // Converging on the zero from one side: step past the secant's
            // estimate by its distance from that side's end, to bracket
            // the zero tightly from the other.
            let past = if side < 0 { secant - (b - secant) } else { secant + (secant - a) };
            if past > a && past < b { past } else { secant }
        } else if secant > a && secant < b {
            secant
        } else if width > 4.0 * ulps && !probed_end {
            // The secant rounds onto an end (its value at the rounding
            // floor): the zero is within an ulp of it, probed just inside.
            if fa < fb.abs() { a } else { b }
        } else {
            m
        };
        last_width = width;
        let near_end = width > 4.0 * ulps && (x - a).min(b - x) < ulps;
        // Never two end probes in a row: bisect instead.
        let x = if near_end && probed_end { m } else { x };
        let near_end = near_end && !probed_end;
        probed_end = false;
        if near_end {
            // Close to an end: probe just inside it to cut the bracket.
            let inside = if x - a < b - x { a + ulps } else { b - ulps };
            probed_end = true;
            let fi = f(inside);
            if fi < 0.0 {
                (b, fb) = (inside, fi);
                side = -1;
            } else {
                (a, fa) = (inside, fi);
                side = 1;
            }
            continue;
        }
        let fx = f(x);
        if fx < 0.0 {
            (b, fb) = (x, fx);
            if side < 0 {
                fa *= 0.5;
            }
            side = if side < 0 { side - 1 } else { -1 };
        } else {
            (a, fa) = (x, fx);
            if side > 0 {
                fb *= 0.5;
            }
            side = if side > 0 { side + 1 } else { 1 };
        }
    }
}

/// The least value on `[0, h]` of the cubic with values `fa`, `fb` and
/// slopes `da`, `db` at its ends.
fn hermite_minimum(fa: f64, da: f64, fb: f64, db: f64, h: f64) -> f64 {
    // p(u) = fa + h da u + c2 u^2 + c3 u^3, u in [0, 1].
    let c2 = 3.0 * (fb - fa) - h * (2.0 * da + db);
    let c3 = 2.0 * (fa - fb) + h * (da + db);
    let p = |u: f64| fa + u * (h * da + u * (c2 + u * c3));
    let mut least = fa.min(fb);
    // p'(u) = h da + 2 c2 u + 3 c3 u^2.
    let (qa, qb, qc) = (3.0 * c3, 2.0 * c2, h * da);
    // The roots without cancellation: q = -(b + sign(b) sqrt(disc)) / 2,
    // then q / a and c / q (either may be missing).
    let disc = qb * qb - 4.0 * qa * qc;
    let roots: [f64; 2] = if disc < 0.0 {
        [-1.0, -1.0]
    } else {
        let q = -0.5 * (qb + qb.signum() * disc.sqrt());
        [if qa != 0.0 { q / qa } else { -1.0 }, if q != 0.0 { qc / q } else { -1.0 }]
    };
    for u in roots {
        if u > 0.0 && u < 1.0 {
            least = least.min(p(u));
        }
    }
    least
}

/// A bracket's ends with a function's values and rates there.
struct Ends {
    a: f64,
    fa: f64,
    da: Option<f64>,
    b: f64,
    fb: f64,
    db: Option<f64>,
}

/// The first interior minimum of function `i` in `(a, b)` that is
/// negative, by the sign changes of its rate (module doc).
fn negative_minimum(watch: &impl DenseWatch, i: usize, ends: Ends) -> Option<f64> {
    let rate = |t: f64| watch.rate(i, t);
    let Ends { a, fa, b, fb, .. } = ends;
    let (da, db) = (ends.da?, ends.db?);
    // Both ends higher above zero than the rates there could take the
    // function down in the interval four times over, or the cubic through
    // the ends' values and rates staying above half the lower end: no dip
    // to look for.
    let fastest = da.abs().max(db.abs());
    if fa.min(fb) > 4.0 * fastest * (b - a) || (fa.min(fb) > 0.0 && hermite_minimum(fa, da, fb, db, b - a) >= 0.5 * fa.min(fb)) {
        return None;
    }
    let m = 0.5 * (a + b);
    let dm = rate(m)?;
    let mut points = vec![(a, da), (m, dm), (b, db)];
    // Parabola through the three: d(u) = dm + (db - da)/2 u + (db - 2 dm + da)/2 u^2, u in [-1, 1].
    let curvature = 0.5 * (db - 2.0 * dm + da);
    if curvature != 0.0 {
        let u = -0.25 * (db - da) / curvature;
        let v = m + u * 0.5 * (b - a);
        if u.abs() < 1.0 && v > a && v < b && v != m {
            points.push((v, rate(v)?));
            points.sort_by(|p, q| p.0.total_cmp(&q.0));
        }
    }
    for pair in points.windows(2) {
        let ((lo, dl), (hi, dh)) = (pair[0], pair[1]);
        if !(dl < 0.0 && dh >= 0.0) {
            continue;
        }
        // The first point where the rate is no longer negative.
        let hi = if dh == 0.0 { hi } else { bisect(|t| -rate(t).unwrap_or(0.0), lo, hi) };
        if watch.value(i, hi) < 0.0 {
            return Some(hi);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Functions of time given in closed form, with their rates.
    struct Curves(Vec<(fn(f64) -> f64, Option<fn(f64) -> f64>)>);

    impl DenseWatch for Curves {
        fn count(&self) -> usize {
            self.0.len()
        }
        fn values(&self, t: f64, out: &mut [f64]) {
            for (o, (f, _)) in out.iter_mut().zip(&self.0) {
                *o = f(t);
            }
        }
        fn value(&self, i: usize, t: f64) -> f64 {
            (self.0[i].0)(t)
        }
        fn rate(&self, i: usize, t: f64) -> Option<f64> {
            self.0[i].1.map(|r| r(t))
        }
    }

    #[test]
    fn the_hermite_minimum_is_the_cubic_s_least_value() {
        // p(t) = (t - 0.6)^2 - 0.01 on [0, 1]: values and slopes at the ends.
        let p = |t: f64| (t - 0.6) * (t - 0.6) - 0.01;
        let d = |t: f64| 2.0 * (t - 0.6);
        assert!((hermite_minimum(p(0.0), d(0.0), p(1.0), d(1.0), 1.0) + 0.01).abs() < 1e-15);
        // Monotone: the lower end.
        assert_eq!(hermite_minimum(1.0, 0.5, 2.0, 1.5, 1.0), 1.0);
        // Scaled interval: t in [2, 2.5], p = (t - 2.3)^2.
        let q = |t: f64| (t - 2.3) * (t - 2.3);
        let dq = |t: f64| 2.0 * (t - 2.3);
        assert!(hermite_minimum(q(2.0), dq(2.0), q(2.5), dq(2.5), 0.5).abs() < 1e-15);
    }

    #[test]
    fn a_function_rising_from_its_rounding_has_no_zero_there() {
        // Zero at the step's start (a switch), rising, its evaluation a
        // rounding below zero just after it, and a true zero at 0.2, in
        // the first sample interval.
        let c = Curves(vec![(|t| if t > 0.0 && t < 1e-14 { -1e-18 } else { t * (0.2 - t) }, Some(|t| 0.2 - 2.0 * t))]);
        let s = first_switch(&c, 0.0, 1.0, 0.0).unwrap();
        assert!((s.time - 0.2).abs() < 1e-15, "{}", s.time);
        // Falling from zero: the zero is at the start (within an ulp).
        let c = Curves(vec![(|t| -t, Some(|_| -1.0))]);
        assert!(first_switch(&c, 0.0, 1.0, 0.0).unwrap().time < 1e-300);
    }

    #[test]
    fn finds_a_sign_change_to_an_ulp() {
        let c = Curves(vec![(|t| 0.3 - t, Some(|_| -1.0))]);
        let s = first_switch(&c, 0.0, 1.0, 0.0).unwrap();
        assert!(s.time >= 0.3 && s.time <= 0.3 + 2.0 * f64::EPSILON, "{}", s.time);
        assert_eq!(s.at_zero.len(), 1);
        assert!((s.at_zero[0].1 + 1.0).abs() < 1e-9, "slope {}", s.at_zero[0].1);
    }

    #[test]
    fn finds_a_dip_between_samples_only_with_a_rate() {
        // Negative on (0.52, 0.53) only: both neighbouring samples (0.5, 0.625) positive.
        let dip = |t: f64| (t - 0.525) * (t - 0.525) - 2.5e-5;
        let rate = |t: f64| 2.0 * (t - 0.525);
        let with_rate = Curves(vec![(dip, Some(rate))]);
        let s = first_switch(&with_rate, 0.0, 1.0, 0.0).expect("the dip");
        assert!((s.time - 0.52).abs() < 1e-12, "{}", s.time);
        let without = Curves(vec![(dip, None)]);
        assert_eq!(first_switch(&without, 0.0, 1.0, 0.0), None);
    }

    #[test]
    fn reports_simultaneous_zeros_and_resumes_on_the_step_s_grid() {
        let c = Curves(vec![(|t| 0.7 - t, None), (|t| 2.0 * (0.7 - t), None), (|t| 0.9 - t, None)]);
        let s = first_switch(&c, 0.0, 1.0, 0.0).unwrap();
        let mut which: Vec<usize> = s.at_zero.iter().map(|z| z.0).collect();
        which.sort();
        assert_eq!(which, vec![0, 1]);
        // Resumed past the first zero, with the third function alone: its
        // zero, bracketed on the step's grid, bit for bit as an
        // uninterrupted search finds it.
        let third = Curves(vec![(|t| 0.9 - t, None)]);
        let later = first_switch(&third, 0.0, 1.0, 0.8).unwrap();
        let from_start = first_switch(&third, 0.0, 1.0, 0.0).unwrap();
        assert!((later.time - 0.9).abs() < 1e-15 && later.at_zero.len() == 1);
        assert_eq!(later.time, from_start.time);
        // Resumed at the sample its bracket started from: found again.
        let again = first_switch(&third, 0.0, 1.0, from_start.from).unwrap();
        assert_eq!(again.time, from_start.time);
    }
}
