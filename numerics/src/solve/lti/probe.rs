//! What the event search reads off a coupled segment at one point: the
//! coordinates and their derivatives there, the jets of the event
//! functions, bounds on their derivatives over an interval, and the
//! certified steps from splitting the coordinates.

use nalgebra::DVector;

use super::{CoupledSegment, CoupledSystem, ProjectedFunctional};
use crate::solve::complex::C64;
use crate::solve::elementary::unit;
use crate::solve::events::split_certificate;
use crate::solve::functional::{DerivativeBounds, Jet, NOISE};

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
    pub(super) t: f64,
    /// `z^(m)`, m = 0..=3.
    pub(super) z: [DVector<C64>; 4],
    /// The size of the terms summed into `z^(m)`: the rounding it carries.
    pub(super) size: [DVector<f64>; 4],
    /// `(W, e^{i W t})` per harmonic of the segment's loads.
    pub(super) rotations: Vec<(f64, C64)>,
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

impl CoupledSegment {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::events::{certified_step, Certified};
    use crate::solve::forcing::ModalForcing;
    use crate::solve::functional::Functional;
    use crate::solve::lti::tests::held_beam;
    use crate::solve::modal_state::ModalState;
    use nalgebra::{dvector, DMatrix};

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
}
