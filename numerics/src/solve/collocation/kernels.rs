//! The kernel cache: per step size of the ladder, every mode's responses
//! to the force monomials and its free kernels, and the contact
//! coordinates' responses to the nodal forces.

use std::sync::Arc;

use nalgebra::DMatrix;

use crate::solve::free::steady_rotation;
use crate::solve::phi::phi_columns;
use crate::solve::C64;
use crate::solve::Oscillator;
use crate::solve::switch::SAMPLES;
use super::{ForceCollocation, STAGES};

/// Intervals of the switch locator's grid (its samples).
pub(super) const GRID: usize = SAMPLES;
/// Kernel sets kept.
const KERNEL_SETS: usize = 96;
pub(super) use super::super::step_ladder as ladder;

/// What every step of one size needs, mode by mode: the responses to the
/// force monomials and the free kernels at the nodes and the end, and for
/// the switch grid the propagator over a grid interval.
#[derive(Debug, Default)]
pub struct StepKernels {
    pub(super) h: f64,
    /// `R[(i * n + j) * (s + 2) + m]`: mode `j`'s response at point `i`
    /// (the nodes, then the end) to `sigma^m` from rest, `m = 0..=s`.
    pub(super) responses: Vec<[f64; 2]>,
    /// `(Ec, Es)` at point `i`: `[i * n + j]`.
    pub(super) free: Vec<(f64, f64)>,
    /// Per mode, `e^{A h / GRID}` by rows.
    pub(super) grid_propagator: Vec<[f64; 4]>,
    /// `[j * s + m]`: the response over a grid interval to `u^m`.
    pub(super) grid_responses: Vec<[f64; 2]>,
    /// `(Ec, Es)` at `k h / GRID`: `[(k - 1) * n + j]`, `k = 1..=GRID`.
    pub(super) grid_free: Vec<(f64, f64)>,
    /// Each harmonic load's rotation from the step's start to node `i`
    /// (`[i * harmonics + k]`, [`steady_rotation`]'s).
    pub(super) node_rotations: Vec<C64>,
}

/// `(Ec, Es)` from `phi_0(tau A) b = (Es, Ec - a Es)`.
pub(super) fn kernels_of(phi0: [f64; 2], a: f64) -> (f64, f64) {
    (phi0[1] + a * phi0[0], phi0[0])
}

/// One mode's responses at `tau` into a step of size `h` to the loads
/// `sigma^m` from rest (`sigma = tau / h`, `m < responses.len()`, at most
/// 10): `m! sigma^m tau phi_{m+1}(tau A) b`; returns its free kernels
/// `(Ec, Es)` at `tau`.
pub(super) fn point_responses(osc: &Oscillator, tau: f64, h: f64, responses: &mut [[f64; 2]]) -> (f64, f64) {
    let mut phis = [[0.0; 2]; 12];
    let terms = responses.len();
    phi_columns(osc, tau, &mut phis[..terms + 1]);
    let sigma = tau / h;
    let mut factor = tau;
    for (m, r) in responses.iter_mut().enumerate() {
        *r = [factor * phis[m + 1][0], factor * phis[m + 1][1]];
        factor *= sigma * (m + 1) as f64;
    }
    kernels_of(phis[0], osc.a)
}

/// The contact coordinates' responses for one step size.
#[derive(Debug)]
pub(super) struct Projected {
    h: f64,
    /// To the force monomials, at the nodes and the end:
    /// `[((c * nc + e) * (s + 1) + i) * (s + 2) + m]` (position, rate).
    pub(super) sm: Vec<[f64; 2]>,
    /// To the nodal forces, at the nodes: `[(c, i), (e, k)]`.
    pub(super) mp: DMatrix<f64>,
    pub(super) mv: DMatrix<f64>,
}

impl ForceCollocation {
    /// The kernels of steps of size `h` (with the grid's when `grid`):
    /// from the ladder's cache, or computed (and kept when `keep`).
    pub(super) fn kernels_for(&self, h: f64, keep: bool, grid: bool) -> Arc<StepKernels> {
        {
            let mut cache = self.kernels.borrow_mut();
            if let Some(i) = cache.iter().rposition(|k| k.h == h && (!grid || !k.grid_free.is_empty())) {
                // The most recently used last: the oldest is dropped first.
                let k = cache.remove(i);
                cache.push(k.clone());
                return k;
            }
        }
        // A size not kept in the storage of the last such size's, once
        // no attempt holds it.
        if !keep {
            let mut unkept = self.unkept_kernels.borrow_mut();
            if let Some(kernels) = unkept.as_mut().and_then(Arc::get_mut) {
                self.fill_kernels(h, grid, kernels);
                return unkept.clone().expect("just filled");
            }
        }
        let mut kernels = StepKernels::default();
        self.fill_kernels(h, grid, &mut kernels);
        let kernels = Arc::new(kernels);
        if keep {
            let mut cache = self.kernels.borrow_mut();
            cache.retain(|k| k.h != h);
            if cache.len() >= KERNEL_SETS {
                cache.remove(0);
            }
            cache.push(kernels.clone());
        } else {
            *self.unkept_kernels.borrow_mut() = Some(kernels.clone());
        }
        kernels
    }

    /// Fills `out` (its vectors cleared first) with the kernels of steps
    /// of size `h`, with the grid's when `grid`.
    fn fill_kernels(&self, h: f64, grid: bool, out: &mut StepKernels) {
        let (n, s) = (self.n, self.scheme.s);
        let mut nodes_and_end = [0.0; STAGES + 1];
        for (tau, c) in nodes_and_end.iter_mut().zip(&self.scheme.c) {
            *tau = c * h;
        }
        nodes_and_end[s] = h;
        let points = &nodes_and_end[..=s];
        let mono = s + 2;
        // Filled in order, point by point and mode by mode (no zeroing
        // first: a new size's tables are some 10 kB).
        let StepKernels { h: size, responses, free, grid_propagator, grid_responses, grid_free, node_rotations } = out;
        *size = h;
        responses.clear();
        responses.reserve(points.len() * n * mono);
        free.clear();
        free.reserve(points.len() * n);
        let mut phis = [[0.0; 2]; 8];
        let mut point = [[0.0; 2]; STAGES + 2];
        for &tau in points {
            for osc in &self.dynamics.oscillators {
                free.push(point_responses(osc, tau, h, &mut point[..mono]));
                responses.extend_from_slice(&point[..mono]);
            }
        }
        grid_propagator.clear();
        grid_responses.clear();
        grid_free.clear();
        if grid {
            let delta = h / GRID as f64;
            grid_propagator.resize(n, [0.0; 4]);
            grid_responses.resize(n * s, [0.0; 2]);
            grid_free.resize(GRID * n, (0.0, 0.0));
            for (j, osc) in self.dynamics.oscillators.iter().enumerate() {
                phi_columns(osc, delta, &mut phis[..s + 1]);
                let (ec, es) = kernels_of(phis[0], osc.a);
                grid_propagator[j] = [ec + osc.a * es, es, -osc.omega * osc.omega * es, ec - osc.a * es];
                let mut factor = delta;
                for m in 0..s {
                    grid_responses[j * s + m] = [factor * phis[m + 1][0], factor * phis[m + 1][1]];
                    factor *= (m + 1) as f64;
                }
                for k in 1..=GRID {
                    grid_free[(k - 1) * n + j] = osc.kernels(k as f64 * delta);
                }
            }
        }
        let harmonics = &self.dynamics.forcing.harmonics;
        node_rotations.clear();
        node_rotations.extend(points[..s].iter().flat_map(|&tau| harmonics.iter().map(move |hm| steady_rotation(hm.omega, tau))));
    }

    /// The contact coordinates' responses to the contacts' forces for the
    /// step size of `kernels`, remembered for the sizes of the ladder.
    pub(super) fn projected_for(&self, kernels: &Arc<StepKernels>, cached: bool) -> Arc<Projected> {
        let h = kernels.h;
        {
            let mut cache = self.projections.borrow_mut();
            if let Some(i) = cache.iter().rposition(|p| p.h == h) {
                let p = cache.remove(i);
                cache.push(p.clone());
                return p;
            }
        }
        // A size not kept in the storage of the last such size's, once
        // no attempt holds it.
        if !cached {
            let mut unkept = self.unkept_projections.borrow_mut();
            if let Some(projected) = unkept.as_mut().and_then(Arc::get_mut) {
                self.fill_projected(kernels, projected);
                return unkept.clone().expect("just filled");
            }
        }
        let mut projected = Projected { h, sm: Vec::new(), mp: DMatrix::zeros(0, 0), mv: DMatrix::zeros(0, 0) };
        self.fill_projected(kernels, &mut projected);
        let projected = Arc::new(projected);
        if cached {
            let mut cache = self.projections.borrow_mut();
            if cache.len() >= KERNEL_SETS {
                cache.remove(0);
            }
            cache.push(projected.clone());
        } else {
            *self.unkept_projections.borrow_mut() = Some(projected.clone());
        }
        projected
    }

    /// Fills `out` with the contact coordinates' responses for the step
    /// size of `kernels`.
    fn fill_projected(&self, kernels: &StepKernels, out: &mut Projected) {
        let (n, s, nc) = (self.n, self.scheme.s, self.contacts.len());
        let ns = nc * s;
        let mono = s + 2;
        let r = &kernels.responses;
        let Projected { h, sm, mp, mv } = out;
        *h = kernels.h;
        // Monomial responses of the contact coordinates: S[((c * nc + e) * (s + 1) + i) * mono + m].
        sm.clear();
        sm.resize(nc * nc * (s + 1) * mono, [0.0; 2]);
        for c in 0..nc {
            for e in 0..nc {
                let dd = &self.dd[(c * nc + e) * n..(c * nc + e + 1) * n];
                for i in 0..=s {
                    for m in 0..mono {
                        let (mut x, mut v) = (0.0, 0.0);
                        for (j, w) in dd.iter().enumerate() {
                            let rr = r[(i * n + j) * mono + m];
                            x -= w * rr[0];
                            v -= w * rr[1];
                        }
                        sm[((c * nc + e) * (s + 1) + i) * mono + m] = [x, v];
                    }
                }
            }
        }
        // In the nodal basis at the nodes: mp[(c, i), (e, k)], mv likewise.
        if mp.shape() == (ns, ns) {
            mp.fill(0.0);
            mv.fill(0.0);
        } else {
            (*mp, *mv) = (DMatrix::zeros(ns, ns), DMatrix::zeros(ns, ns));
        }
        for c in 0..nc {
            for e in 0..nc {
                for i in 0..s {
                    for k in 0..s {
                        let (mut x, mut v) = (0.0, 0.0);
                        for m in 0..s {
                            let a = self.scheme.vinv[m * s + k];
                            let smv = sm[((c * nc + e) * (s + 1) + i) * mono + m];
                            x += a * smv[0];
                            v += a * smv[1];
                        }
                        mp[(c * s + i, e * s + k)] = x;
                        mv[(c * s + i, e * s + k)] = v;
                    }
                }
            }
        }
    }

    /// Takes the kernel sets of another stepper over the same structure
    /// and load frequencies (the previous contact phase's, done with
    /// them): its step sizes recur. Its contacts' responses too where it
    /// has the same contacts (positions and directions: the gaps do not
    /// enter them), and its samples' where it also watches the same
    /// directions. Moved, not copied: a contact's start then costs no copy
    /// of them (HertzStop at 20 modes and tolerance 1e-4: 0.6M of 22M
    /// instructions).
    /// Its working arrays too (the attempts' and the samples'), emptied:
    /// a phase then allocates nothing its predecessor had.
    pub fn adopt_kernels(&mut self, other: &mut ForceCollocation) {
        // The kernels hold the harmonic loads' rotations to the nodes: a
        // load's frequency set between the phases makes them stale.
        let (a, b) = (&other.dynamics.forcing.harmonics, &self.dynamics.forcing.harmonics);
        let same_frequencies = a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.omega.to_bits() == y.omega.to_bits());
        if other.dynamics.oscillators == self.dynamics.oscillators && other.scheme.s == self.scheme.s && same_frequencies {
            *self.kernels.get_mut() = std::mem::take(other.kernels.get_mut());
            if other.dd == self.dd {
                *self.projections.get_mut() = std::mem::take(other.projections.get_mut());
                if other.watched == self.watched {
                    self.samples.get_mut().adopt_sizes(other.samples.get_mut());
                }
            }
        }
        self.adopt_scratch(other);
        self.samples.get_mut().adopt_storage(other.samples.get_mut());
        *self.unkept_kernels.get_mut() = other.unkept_kernels.get_mut().take();
        *self.unkept_projections.get_mut() = other.unkept_projections.get_mut().take();
    }

}
