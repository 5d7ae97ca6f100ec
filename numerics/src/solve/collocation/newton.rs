//! One attempted step: Newton on the nodal forces, the end state, and
//! the error estimate from the force's defect.

use nalgebra::DVector;

use crate::solve::free::FreeSegment;
use crate::solve::lu::{Lu, Order};
use crate::solve::matvec::mat_vec;
use crate::solve::modal_state::ModalState;
use super::scheme::horner;
use super::shift::ShiftScratch;
use super::{ForceCollocation, NewtonFailure, PointForces, Step, STAGES};

/// Newton's convergence: the last correction moves every contact
/// coordinate by less than this fraction of the tolerance (what is left
/// is a fraction of that correction). HertzStop at 20 and 32 modes:
/// errors the same to two digits from 1e-4 to 1e-12 as with 1e-3, for
/// 0.5 % fewer instructions.
const NEWTON_FRACTION: f64 = 1e-2;
const NEWTON_ITERATIONS: usize = 12;
/// Iterations that keep the first one's Jacobian (a chord: the guess is
/// the last step's force, so the Jacobian moves little), the rest
/// Newton's own: HertzStop at 20 modes and tolerance 1e-9 the same
/// errors for 4 % fewer instructions.
const CHORD_ITERATIONS: usize = 4;
/// A Newton correction this many ulps of a contact coordinate is its rounding.
const ROUNDING: f64 = 8.0 * f64::EPSILON;
/// A held contact's drift over a step this many ulps of its coordinate's
/// terms at the motion's scale is its rounding.
const DRIFT_ROUNDING: f64 = 64.0 * f64::EPSILON;

/// Working arrays of [`ForceCollocation::attempt`] (and of
/// [`ForceCollocation::shift`]), kept between steps.
#[derive(Clone, Debug, Default)]
pub(super) struct Scratch {
    pub(super) pf: Vec<f64>,
    pub(super) pdf: Vec<f64>,
    pub(super) f: DVector<f64>,
    p: DVector<f64>,
    pd: DVector<f64>,
    law: Vec<(f64, f64, f64)>,
    lu: Lu<f64>,
    residual: Vec<f64>,
    /// A Newton correction's move of the contact coordinates and rates.
    moved_p: Vec<f64>,
    moved_v: Vec<f64>,
    defect: Vec<f64>,
    drive: Vec<f64>,
    fb: Vec<f64>,
    /// The step's start and the free motion at its points.
    start: ModalState,
    end: ModalState,
    /// Steps whose storage the next attempts reuse, the latest last (a
    /// rejected attempt's, the last accepted step once replaced, the
    /// previous phase's last step), at most [`SPARE_STEPS`].
    spares: Vec<Step>,
    /// An end state's storage for the next attempt (the state a step
    /// replaced, a rejected attempt's).
    pub(super) spare_state: Option<DVector<f64>>,
    pub(super) shift: ShiftScratch,
}

/// Spare steps kept: a phase's first two steps find one each, the
/// previous phase's last and the spare it left.
const SPARE_STEPS: usize = 2;

/// `v` as `len` zeros (no allocation once the size is known).
fn reset(v: &mut Vec<f64>, len: usize) {
    v.clear();
    v.resize(len, 0.0);
}

/// Everything one attempted step computes.
pub(super) struct Attempt {
    pub(super) y1: DVector<f64>,
    pub(super) step: Step,
    pub(super) error: f64,
}

impl ForceCollocation {
    /// Puts the end state `y` exactly on the held contacts' surfaces,
    /// moving along them (the modes' mass is the identity: the orthogonal
    /// projection of `q` and `q'`, as at a stick): the constraint is
    /// collocated at velocity level, so its position would drift by the
    /// rounding of every step.
    fn onto_held(&self, forces: &impl PointForces, y: &mut DVector<f64>) {
        let held: Vec<usize> = (0..self.contacts.len()).filter(|&c| forces.held(c)).collect();
        if held.is_empty() {
            return;
        }
        let n = self.n;
        let d = nalgebra::DMatrix::from_columns(&held.iter().map(|&c| self.contacts[c].d.clone()).collect::<Vec<_>>());
        let lu = (d.transpose() * &d).lu();
        let p = DVector::from_iterator(held.len(), held.iter().map(|&c| self.coordinate(c, y).0));
        let pd = DVector::from_iterator(held.len(), held.iter().map(|&c| self.coordinate(c, y).1));
        if let (Some(a), Some(b)) = (lu.solve(&p), lu.solve(&pd)) {
            let (dq, dv) = (&d * a, &d * b);
            for j in 0..n {
                y[j] -= dq[j];
                y[n + j] -= dv[j];
            }
        }
    }

    /// Another stepper's working arrays, for this one's attempts, with
    /// its last step and state as spares (it is done with them): spare
    /// steps are taken as storage only (never as a retry of the same
    /// start: their projections are on the other's contacts).
    pub(super) fn adopt_scratch(&mut self, other: &mut ForceCollocation) {
        let mut scratch = std::mem::take(other.scratch.get_mut());
        if let Some(last) = other.last.take() {
            if scratch.spares.len() == SPARE_STEPS {
                scratch.spares.remove(0);
            }
            scratch.spares.push(last);
        }
        for spare in &mut scratch.spares {
            spare.t0 = f64::NAN;
        }
        if scratch.spare_state.is_none() {
            scratch.spare_state = Some(std::mem::replace(&mut other.y, DVector::zeros(0)));
        }
        *self.scratch.get_mut() = scratch;
    }

    /// Keeps `step`'s storage for the next attempts (the oldest spare
    /// dropped past [`SPARE_STEPS`]).
    pub(super) fn recycle(&self, step: Step) {
        let spares = &mut self.scratch.borrow_mut().spares;
        if spares.len() == SPARE_STEPS {
            spares.remove(0);
        }
        spares.push(step);
    }

    /// Keeps a state's storage for the next attempt's end state.
    pub(super) fn recycle_state(&self, y: DVector<f64>) {
        self.scratch.borrow_mut().spare_state = Some(y);
    }

    /// Nodal forces to start Newton from, into `g`: the last step's
    /// polynomial where it covers the node, else the force at `t0`
    /// continued by its slope.
    fn guess(&self, forces: &impl PointForces, t0: f64, y0: &DVector<f64>, h: f64, g: &mut [f64]) {
        let (s, nc) = (self.scheme.s, self.contacts.len());
        for c in 0..nc {
            let (p, pd) = self.coordinate(c, y0);
            let f0 = if forces.held(c) { 0.0 } else { forces.force(c, p, pd).0 };
            for i in 0..s {
                let t = t0 + self.scheme.c[i] * h;
                g[c * s + i] = match &self.last {
                    Some(l) if t >= l.t0 && t <= l.t0 + l.h => horner(&l.force[c], (t - l.t0) / l.h),
                    Some(l) => {
                        let poly = &l.force[c];
                        let slope: f64 = poly.iter().enumerate().skip(1).map(|(m, a)| m as f64 * a).sum::<f64>() / l.h;
                        (f0 + slope * (t - t0)).max(0.0)
                    }
                    None => f0,
                };
            }
        }
    }

    /// One step of size `h` (`cached`: a size of the ladder, whose kernels
    /// are kept).
    pub(super) fn attempt(&self, forces: &impl PointForces, t0: f64, y0: &DVector<f64>, h: f64, cached: bool) -> Result<Attempt, NewtonFailure> {
        let (n, s, nc) = (self.n, self.scheme.s, self.contacts.len());
        let (ns, n_harmonics) = (nc * s, self.dynamics.forcing.harmonics.len());
        self.attempts.set(self.attempts.get() + 1);
        let kernels = self.kernels_for(h, cached, false);
        let r = &kernels.responses;
        let mut guard = self.scratch.borrow_mut();
        let Scratch { pf, pdf, f, p, pd, law, lu, residual, moved_p, moved_v, defect, drive, fb, start, end, spares, spare_state, .. } = &mut *guard;
        if start.q.len() != n {
            (*start, *end) = (ModalState::zeros(n), ModalState::zeros(n));
        }
        start.q.copy_from(&y0.rows(0, n));
        start.qd.copy_from(&y0.rows(n, n));
        // The storage of a spare step, else new; a rejected attempt's free
        // motion and its projections where it started here too (a retry).
        let (mut free, mut force, mut dissipation, mut y0_copy, mut projections, retry) = match spares.pop() {
            Some(Step { t0: t_spare, free, force, dissipation, y0: copy, projections, projected, .. }) => {
                let retry = (t_spare == t0 && copy == *y0).then_some(projected);
                (free, force, dissipation, copy, projections, retry)
            }
            None => (FreeSegment::new(&self.dynamics, t0, start), Vec::new(), Vec::new(), y0.clone(), Vec::new(), None),
        };
        if retry.is_none() {
            free.reset(&self.dynamics, t0, start);
            if y0_copy.len() == y0.len() {
                y0_copy.copy_from(y0);
            } else {
                y0_copy = y0.clone();
            }
        }
        // Free motion of the contact coordinates at the points: at the
        // nodes from the motion projected on each contact (two products
        // per mode), at the end from the state, which is kept.
        reset(pf, nc * (s + 1));
        reset(pdf, nc * (s + 1));
        let free_projected = retry.unwrap_or_else(|| {
            projections.resize_with(nc, Default::default);
            (0..nc).all(|c| free.projected(&self.dynamics, self.contacts[c].d.as_slice(), &mut projections[c]))
        });
        for i in 0..=s {
            let tau = if i < s { self.scheme.c[i] * h } else { h };
            let point_kernels = &kernels.free[i * n..(i + 1) * n];
            if i < s && free_projected {
                let rotations = &kernels.node_rotations[i * n_harmonics..(i + 1) * n_harmonics];
                for c in 0..nc {
                    let (p, pd) = projections[c].at_rotated(&self.dynamics, point_kernels, rotations);
                    pf[c * (s + 1) + i] = p - self.contacts[c].gap;
                    pdf[c * (s + 1) + i] = pd;
                }
                continue;
            }
            free.state_with_kernels(&self.dynamics, t0 + tau, point_kernels, end);
            for c in 0..nc {
                let d = &self.contacts[c].d;
                pf[c * (s + 1) + i] = d.dot(&end.q) - self.contacts[c].gap;
                pdf[c * (s + 1) + i] = d.dot(&end.qd);
            }
        }
        let mono = s + 2;
        let projected = self.projected_for(&kernels, cached);
        let (sm, mp, mv) = (&projected.sm, &projected.mp, &projected.mv);
        // Newton on the nodal forces.
        let tol = self.options.tol;
        let p_tol = |c: usize| NEWTON_FRACTION * tol * self.options.q_scale * self.amax[c];
        let v_tol = |c: usize| NEWTON_FRACTION * tol * self.options.v_scale * self.amax[c];
        if f.len() != ns {
            *f = DVector::zeros(ns);
            *p = DVector::zeros(ns);
            *pd = DVector::zeros(ns);
        }
        self.guess(forces, t0, y0, h, f.as_mut_slice());
        law.clear();
        law.resize(ns, (0.0, 0.0, 0.0));
        reset(residual, ns);
        let mut converged = false;
        for iteration in 0..NEWTON_ITERATIONS {
            let refactor = iteration == 0 || iteration >= CHORD_ITERATIONS;
            mat_vec(mp.as_slice(), f.as_slice(), p.as_mut_slice(), 0.0);
            mat_vec(mv.as_slice(), f.as_slice(), pd.as_mut_slice(), 0.0);
            for c in 0..nc {
                for i in 0..s {
                    let row = c * s + i;
                    p[row] += pf[c * (s + 1) + i];
                    pd[row] += pdf[c * (s + 1) + i];
                    law[row] = if forces.held(c) { (0.0, 0.0, 0.0) } else { forces.force(c, p[row], pd[row]) };
                }
            }
            // A held contact: p' = 0 at the node (the constraint at velocity
            // level: a position-level one would answer a rounding-sized p'
            // at the step's start with a force ~ p' / h), the row scaled to
            // a unit diagonal.
            for row in 0..ns {
                residual[row] = if forces.held(row / s) { pd[row] * (1.0 / mv[(row, row)]) } else { f[row] - law[row].0 };
            }
            if refactor {
                let a = lu.matrix_mut(ns);
                for row in 0..ns {
                    if forces.held(row / s) {
                        let scale = 1.0 / mv[(row, row)];
                        for col in 0..ns {
                            a[(row, col)] = mv[(row, col)] * scale;
                        }
                        continue;
                    }
                    let (_, dp, dpd) = law[row];
                    for col in 0..ns {
                        a[(row, col)] = if row == col { 1.0 } else { 0.0 } - (dp * mp[(row, col)] + dpd * mv[(row, col)]);
                    }
                }
                if !lu.factor(Order::Rows) {
                    return Err(NewtonFailure);
                }
            }
            lu.solve(residual);
            if !residual.iter().all(|x| x.is_finite()) {
                return Err(NewtonFailure);
            }
            // The correction and its effect on the contact coordinates.
            let mut small = true;
            reset(moved_p, ns);
            reset(moved_v, ns);
            mat_vec(mp.as_slice(), residual, moved_p, 0.0);
            mat_vec(mv.as_slice(), residual, moved_v, 0.0);
            for row in 0..ns {
                f[row] -= residual[row];
                let (dp, dv) = (moved_p[row], moved_v[row]);
                // Converged to the tolerance, or to the rounding of the
                // coordinates themselves (a tolerance near 1e-14 asks for less).
                small &= dp.abs() <= p_tol(row / s).max(ROUNDING * p[row].abs()) && dv.abs() <= v_tol(row / s).max(ROUNDING * pd[row].abs());
            }
            if small {
                converged = true;
                break;
            }
        }
        if !converged {
            return Err(NewtonFailure);
        }
        // The converged nodes: coordinates, dissipated power.
        mat_vec(mp.as_slice(), f.as_slice(), p.as_mut_slice(), 0.0);
        mat_vec(mv.as_slice(), f.as_slice(), pd.as_mut_slice(), 0.0);
        force.resize_with(nc, Vec::new);
        dissipation.resize_with(nc, Vec::new);
        // Every entry is set below.
        let mut y1 = match spare_state.take() {
            Some(y) if y.len() == 2 * n + 2 * nc => y,
            _ => DVector::zeros(2 * n + 2 * nc),
        };
        for c in 0..nc {
            let (alpha, beta) = (&mut force[c], &mut dissipation[c]);
            alpha.resize(s, 0.0);
            beta.resize(s, 0.0);
            let mut nodal = [0.0; STAGES];
            let mut power = [0.0; STAGES];
            for i in 0..s {
                let row = c * s + i;
                nodal[i] = f[row];
                power[i] = forces.dissipation_rate(c, p[row] + pf[c * (s + 1) + i], pd[row] + pdf[c * (s + 1) + i], f[row]);
            }
            self.scheme.monomials(&nodal[..s], alpha);
            self.scheme.monomials(&power[..s], beta);
            y1[2 * n + c] = y0[2 * n + c] + h * (0..s).map(|i| self.scheme.b[i] * nodal[i]).sum::<f64>();
            y1[2 * n + nc + c] = y0[2 * n + nc + c] + h * (0..s).map(|i| self.scheme.b[i] * power[i]).sum::<f64>();
        }
        // The end state: free motion plus every mode's response (mode by
        // mode over slices: no index checks in the loops).
        let r_end = &r[s * n * mono..(s + 1) * n * mono];
        {
            let (yq, yv) = y1.as_mut_slice()[..2 * n].split_at_mut(n);
            yq.copy_from_slice(end.q.as_slice());
            yv.copy_from_slice(end.qd.as_slice());
            for (c, alpha) in force.iter().enumerate() {
                let d = self.contacts[c].d.as_slice();
                for (((x, v), rj), &dj) in yq.iter_mut().zip(yv.iter_mut()).zip(r_end.chunks_exact(mono)).zip(d) {
                    for (a, rr) in alpha.iter().zip(rj) {
                        *x -= dj * a * rr[0];
                        *v -= dj * a * rr[1];
                    }
                }
            }
        }
        // Error: the defect at the ends as `w_s(sigma) (D0 (1 - sigma) +
        // D1 sigma)`: the same `D` at both ends where the force is smooth
        // (the superconvergent estimate), different ones where it is not
        // (an onset's `p^1.5`), whose response the estimate then carries.
        let w_end = horner(&self.scheme.node_poly, 1.0);
        let w_start = horner(&self.scheme.node_poly, 0.0);
        reset(defect, nc * mono);
        for c in 0..nc {
            if forces.held(c) {
                // A reaction has no law to miss.
                continue;
            }
            let (p1, pd1) = self.coordinate(c, &y1);
            let (p0, pd0) = self.coordinate(c, y0);
            let d1 = (forces.force(c, p1, pd1).0 - horner(&force[c], 1.0)) / w_end;
            let d0 = (forces.force(c, p0, pd0).0 - horner(&force[c], 0.0)) / w_start;
            for (m, w) in self.scheme.node_poly.iter().enumerate() {
                defect[c * mono + m] += d0 * w;
                defect[c * mono + m + 1] += (d1 - d0) * w;
            }
        }
        // The nodes' response to the defect, fed back through the contacts.
        reset(drive, ns);
        for c in 0..nc {
            for i in 0..s {
                let row = c * s + i;
                let (dp, dpd) = (law[row].1, law[row].2);
                let (mut x, mut v) = (0.0, 0.0);
                for (e, poly) in defect.chunks_exact(mono).enumerate() {
                    for (m, w) in poly.iter().enumerate() {
                        let smv = sm[((c * nc + e) * (s + 1) + i) * mono + m];
                        x += w * smv[0];
                        v += w * smv[1];
                    }
                }
                // A held contact's reaction cancels the defect's push on it.
                drive[row] = if forces.held(c) { -v / mv[(row, row)] } else { dp * x + dpd * v };
            }
        }
        lu.solve(drive);
        let mut error: f64 = 0.0;
        let mut coef = [0.0; STAGES + 2];
        reset(fb, ns);
        for c in 0..nc {
            self.scheme.monomials(&drive[c * s..(c + 1) * s], &mut fb[c * s..(c + 1) * s]);
        }
        // Per contact the load's coefficients (the defect and the
        // feedback), then mode by mode its response at the end.
        for c in 0..nc {
            for m in 0..mono {
                defect[c * mono + m] += if m < s { fb[c * s + m] } else { 0.0 };
            }
        }
        let (y1q, y1v) = y1.as_slice()[..2 * n].split_at(n);
        let (y0q, y0v) = y0.as_slice()[..2 * n].split_at(n);
        for (j, rj) in r_end.chunks_exact(mono).enumerate() {
            coef.iter_mut().for_each(|x| *x = 0.0);
            for (c, load) in defect.chunks_exact(mono).enumerate() {
                let dj = self.contacts[c].d[j];
                for (k, l) in coef.iter_mut().zip(load) {
                    *k -= dj * l;
                }
            }
            let (mut x, mut v) = (0.0, 0.0);
            for (k, rr) in coef.iter().zip(rj) {
                x += k * rr[0];
                v += k * rr[1];
            }
            let sq = tol * (self.options.q_scale + y1q[j].abs().max(y0q[j].abs()));
            let sv = tol * (self.options.v_scale + y1v[j].abs().max(y0v[j].abs()));
            error = error.max(x.abs() / sq).max(v.abs() / sv);
        }
        // A held contact's reaction is a collocated polynomial too: what it
        // misses shows as the constraint's drift over the step (its rate is
        // zero at the nodes only, and their quadrature of it is of the
        // method's order), held to the tolerance as the laws' defects are,
        // not below the coordinate's rounding at the motion's scale.
        // Unchecked, steps as long as a weak compliant stop beside it
        // allows (four periods of the fastest mode) let the held state
        // drift until its reaction changed sign. Below that rounding (the
        // drift over steps of 3e-8 s was 12 ulps of the coordinate at
        // `q_scale` at tolerance 1e-14, whatever the step) the steps fell
        // to that size and the run reached the work cap.
        for c in (0..nc).filter(|&c| forces.held(c)) {
            let (p1, p0) = (self.coordinate(c, &y1).0, self.coordinate(c, y0).0);
            let size: f64 = self.contacts[c].d.iter().zip(&y1.as_slice()[..n]).map(|(dj, q)| dj.abs() * q.abs().max(self.options.q_scale)).sum();
            error = error.max((p1 - p0).abs() / (tol * self.options.q_scale * self.amax[c]).max(DRIFT_ROUNDING * size));
        }
        if !error.is_finite() || !y1.iter().all(|x| x.is_finite()) {
            return Err(NewtonFailure);
        }
        self.onto_held(forces, &mut y1);
        Ok(Attempt { y1, step: Step { t0, h, y0: y0_copy, free, force, dissipation, projections, projected: free_projected }, error })
    }

}
