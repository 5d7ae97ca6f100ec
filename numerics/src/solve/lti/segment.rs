//! The exact motion of a coupled phase from an anchor: the complex
//! coordinates in closed form, the modal state and its time integral.

use std::cell::RefCell;
use std::sync::Arc;

use nalgebra::DVector;

use super::{CoupledSample, CoupledSystem, PhaseLoads, ProjectedFunctional};
use crate::solve::complex::C64;
use crate::solve::elementary::unit;
use crate::solve::forcing::ModalForcing;
use crate::solve::functional::Functional;
use crate::solve::modal_state::ModalState;
use crate::solve::oscillator::{exp_divdiff2, expm1_c, phi1};

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
    pub(super) loads: Arc<PhaseLoads>,
    pub(super) z0: DVector<C64>,
    started: Vec<StartedHarmonic>,
    /// Work space of [`Self::restart`]: `q - q_c`, `Z^T (q - q_c)`, `Z^T qd`.
    offset: DVector<f64>,
    y0: DVector<f64>,
    yd0: DVector<f64>,
    /// The last [`Self::integral_q`], by time: a stop's impulse is asked
    /// for at a communication point's end and again as the next one's
    /// start (a run's outputs, then its next step's mark).
    integral: RefCell<Option<(f64, DVector<f64>)>>,
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
        let mut segment = CoupledSegment {
            t0,
            loads: loads.clone(),
            z0: DVector::zeros(0),
            started: Vec::new(),
            offset: empty.clone(),
            y0: empty.clone(),
            yd0: empty,
            integral: RefCell::new(None),
        };
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
        self.integral = RefCell::new(None);
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
    pub(super) fn per_harmonic(&self, f: impl Fn(f64) -> C64) -> [C64; 8] {
        let mut out = [C64::new(0.0, 0.0); 8];
        let harmonics = &self.loads.harmonics;
        for (i, h) in harmonics.iter().enumerate().take(8) {
            out[i] = if i % 2 == 1 && h.omega == -harmonics[i - 1].omega { out[i - 1].conj() } else { f(h.omega) };
        }
        out
    }

    /// Complex modal coordinates at time `t`.
    pub(super) fn z_at(&self, sys: &CoupledSystem, t: f64) -> DVector<C64> {
        let mut z = DVector::zeros(sys.eig.len());
        self.z_into(sys, t, &mut z);
        z
    }

    /// `z(t) = e^{L s} z0 + g s phi1(L s) + sum_h g_h e^{i W t} s phi1((L - i W) s)`
    /// (`s = t - t0`) into `out`, with one complex `expm1` per coordinate
    /// and one rotation per harmonic; the near-resonant terms keep `phi1`.
    /// The second coordinate of a mirrored pair is the first's conjugate.
    pub(super) fn z_into(&self, sys: &CoupledSystem, t: f64, out: &mut DVector<C64>) {
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
        if let Some((at, iq)) = self.integral.borrow().as_ref() {
            if at.to_bits() == t.to_bits() {
                return iq.clone();
            }
        }
        let iq = self.integral_q_uncached(sys, t);
        *self.integral.borrow_mut() = Some((t, iq.clone()));
        iq
    }

    fn integral_q_uncached(&self, sys: &CoupledSystem, t: f64) -> DVector<f64> {
        let s = t - self.t0;
        let n = sys.n_free();
        let zero = C64::new(0.0, 0.0);
        let rot0: Vec<C64> = self.loads.harmonics.iter().map(|h| unit(h.omega * self.t0)).collect();
        let iz = DVector::from_fn(sys.eig.len(), |k, _| {
            let ls = sys.eig[k] * s;
            let mut v = self.z0[k] * phi1(ls) * s + self.loads.g_const[k] * exp_divdiff2(zero, ls) * (s * s);
            for (h, rot0) in self.loads.harmonics.iter().zip(&rot0) {
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
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::lti::tests::held_beam;
    use nalgebra::{dvector, DMatrix};

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
}
