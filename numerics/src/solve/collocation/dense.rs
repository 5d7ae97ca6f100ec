//! The dense output: the exact motion under the last step's force
//! polynomials, remembered per step for the switch locator's samples.

use nalgebra::DVector;

use crate::solve::free::Projection;
use crate::solve::modal_state::ModalState;
use crate::solve::switch::sample_time;
use crate::solve::phi::phi_columns;
use super::kernels::{kernels_of, point_responses, GRID};
use super::scheme::{integral, taylor_shift};
use super::{ForceCollocation, Step, STAGES};

/// Dense states remembered per step: the switch locator's samples and
/// midpoints.
const MEMO: usize = 48;

/// Dense states by time, the oldest overwritten first; cleared without
/// freeing (a step's worth of states is refilled every step).
#[derive(Clone, Debug, Default)]
pub(super) struct Memo {
    slots: Vec<(f64, DVector<f64>)>,
    next: usize,
}

impl Memo {
    pub(super) fn clear(&mut self) {
        self.slots.iter_mut().for_each(|s| s.0 = f64::NAN);
        self.next = 0;
    }

    fn find(&self, t: f64) -> Option<&DVector<f64>> {
        self.slots.iter().find(|(tm, _)| *tm == t).map(|(_, y)| y)
    }

    /// The storage for the state at `t` (every entry set by the caller).
    fn slot(&mut self, t: f64, dim: usize) -> &mut DVector<f64> {
        let k = self.next;
        self.next = (k + 1) % MEMO;
        if k == self.slots.len() {
            self.slots.push((t, DVector::zeros(dim)));
        }
        let slot = &mut self.slots[k];
        slot.0 = t;
        if slot.1.len() != dim {
            slot.1 = DVector::zeros(dim);
        }
        &mut slot.1
    }
}

/// The watched coordinates at the last step's samples inside it.
#[derive(Clone, Debug, Default)]
pub(super) struct Samples {
    /// The step they are of (its start and size).
    step: Option<(f64, f64)>,
    /// The samples' times, as the switch locator forms them.
    times: [f64; INNER],
    /// The free motion projected on each watched direction (not
    /// `projected` near a resonance of a harmonic load, where it has no
    /// fixed amplitude).
    projections: Vec<Projection>,
    projected: bool,
    /// Per sample, every direction's `(c . q, c . q')` once asked for.
    values: Vec<Vec<(f64, f64)>>,
    /// Per sample and direction, `c . q''` once asked for.
    accelerations: Vec<Vec<Option<f64>>>,
    /// Per step size (the ladder's recur), what its samples need, the
    /// most recent last.
    sizes: Vec<SampleKernels>,
    /// Room for the kernels at a time off them.
    off: PointKernels,
    /// The last anchor off them ([`anchor`]), whose kernels `off` and
    /// coordinates `off_coordinates` hold (kept, not dropped, at a new
    /// step: a zero's refinement reads at a new anchor every few queries).
    last_off: Option<f64>,
    off_coordinates: Vec<(f64, f64)>,
}

/// Where a query off the samples at `t` is read from: `t` on a grid of
/// `2^-40` of its binade (about 1e-12 of `t`), whose coordinates the
/// query takes moved by their rates over the rest (a zero's refinement
/// to its last ulps asks within one such cell again and again). Over
/// `1e-12 t` the coordinates' curvature adds less than their rounding
/// (HertzStop: `g'' dt^2 / 2` below 1e-19 m against values near 1e-3
/// m); the rates are the anchor's (off by the acceleration over that
/// time: 2.2e-11 of their terms in the unit test; the locator reads
/// rates at its samples). A function of `t` alone, so every run reads a
/// time alike.
fn anchor(t: f64) -> f64 {
    if !(t.is_normal() && t.abs() >= 1e-290) {
        return t;
    }
    let binade = ((t.abs().to_bits() >> 52) & 0x7ff) as i64;
    let cell = f64::from_bits(((binade - 40) as u64) << 52);
    (t / cell).round() * cell
}

/// A mode's acceleration in its response `r = (x, x')` to a load that is
/// `load` at that time: `load - omega^2 x - 2 a x'`.
fn response_acceleration(osc: &crate::solve::Oscillator, r: [f64; 2], load: f64) -> f64 {
    load - osc.omega * osc.omega * r[0] - 2.0 * osc.a * r[1]
}

/// The kernels at one time of a step ([`ForceCollocation::point_kernels`]).
#[derive(Clone, Debug, Default)]
struct PointKernels {
    free: Vec<(f64, f64)>,
    /// `sum_j c_j d_j R_jm` with its rate and acceleration: `[(i * nc +
    /// e) * s + m]`.
    responses: Vec<[f64; 3]>,
    /// Every mode's `R_jm`: `[j * s + m]`.
    modal: Vec<[f64; 2]>,
}

/// What the samples of one step size need: every mode's `(Ec, Es)` at
/// sample `k` (`[k * n + j]`) and the contacts' responses to the force
/// monomials in each watched direction with their rates and
/// accelerations (`[((k * nd + i) * nc + e) * s + m]`), at `(k + 1) h /
/// (2 GRID)`, `k < INNER`.
#[derive(Clone, Debug)]
struct SampleKernels {
    h: f64,
    free: Vec<(f64, f64)>,
    responses: Vec<[f64; 3]>,
}

/// The switch locator's samples strictly inside a step: the grid's inner
/// points and the grid intervals' midpoints.
const INNER: usize = 2 * GRID - 1;

/// Step sizes whose sample kernels [`Samples`] keeps.
const SAMPLE_SIZES: usize = 48;

impl Samples {
    /// Another stepper's sample kernels (the same modes, contacts and
    /// watched directions), taken from it.
    pub(super) fn adopt_sizes(&mut self, other: &mut Samples) {
        self.sizes = std::mem::take(&mut other.sizes);
    }

    /// Another stepper's storage, its contents dropped (no step's samples,
    /// no kernels off them; the sizes' only where [`Self::adopt_sizes`]
    /// takes them): its vectors then need no allocation again.
    pub(super) fn adopt_storage(&mut self, other: &mut Samples) {
        let sizes = std::mem::take(&mut self.sizes);
        *self = std::mem::take(other);
        self.sizes = sizes;
        self.step = None;
        self.last_off = None;
    }
}

impl ForceCollocation {
    /// The directions `c` whose coordinates `c . q` (and rates) the
    /// switch locator reads from [`Self::watched_coordinates`].
    pub fn watch_directions(&mut self, directions: Vec<DVector<f64>>) {
        // The weights of the contacts' modal responses in each direction.
        self.watched_weights = directions
            .iter()
            .flat_map(|c| self.contacts.iter().map(move |contact| c.iter().zip(contact.d.iter()).map(|(cj, dj)| cj * dj).collect()))
            .collect();
        self.watched_contact = directions.iter().map(|c| self.contacts.iter().position(|contact| contact.d == *c)).collect();
        self.watched = directions;
        *self.samples.get_mut() = Samples::default();
    }

    /// Every watched direction's `(c . q, c . q')` at `t` strictly inside
    /// the last step into `out` (`false`: outside it, or a harmonic load
    /// near resonance). The dense output's motion projected: the free
    /// motion through its projection on `c` and the contacts' responses.
    /// At the switch locator's samples (a point of [`crate::solve::switch::grid`] or
    /// the midpoint of two neighbouring ones, formed as the locator forms
    /// them) those responses are kept per step size and direction, so a
    /// sample costs `O(N)` for the free motion and `O(s)` per contact;
    /// elsewhere (a zero's refinement) every mode's kernels at `t`'s
    /// [`anchor`].
    pub fn watched_coordinates(&self, t: f64, out: &mut Vec<(f64, f64)>) -> bool {
        let Some(l) = self.last.as_ref() else { return false };
        if self.watched.is_empty() {
            return false;
        }
        let mut samples = self.samples.borrow_mut();
        self.samples_of(l, &mut samples);
        if !samples.projected {
            return false;
        }
        let Some(k) = samples.times.iter().position(|&s| s == t) else {
            if !(t > l.t0 && t < l.t0 + l.h) {
                return false;
            }
            // Off the samples (a zero's refinement): every mode's kernels
            // at t's anchor, projected as a sample's, moved by their rates
            // to t.
            let (at, coordinates) = self.off_samples(l, t, &mut samples);
            let dt = t - at;
            out.clear();
            out.extend(coordinates.iter().map(|&(x, v)| (x + dt * v, v)));
            return true;
        };
        if samples.values[k].is_empty() {
            let at = self.sample_size(l, &mut samples);
            let (n, s, nc, nd) = (self.n, self.scheme.s, self.contacts.len(), self.watched.len());
            let Samples { projections, values, sizes, .. } = &mut *samples;
            let size = &sizes[at];
            let free = &size.free[k * n..(k + 1) * n];
            let table = &size.responses[k * nd * nc * s..(k + 1) * nd * nc * s];
            self.project(l, t, projections, free, table, &mut values[k]);
        }
        out.clone_from(&samples.values[k]);
        true
    }

    /// Watched direction `i`'s acceleration `c . q''` at `t` strictly
    /// inside the last step, where [`Self::watched_coordinates`] gives its
    /// coordinate (`None` elsewhere): the derivative of its rate under the
    /// step's force polynomials, which a force watch's rate `F_p p' + F_p'
    /// p''` needs. Formed on demand (an `O(N)` sum, like a sample's
    /// coordinates): off the samples at `t`'s anchor, whose acceleration
    /// it takes.
    pub fn watched_acceleration(&self, t: f64, i: usize) -> Option<f64> {
        let l = self.last.as_ref()?;
        if i >= self.watched.len() {
            return None;
        }
        let mut samples = self.samples.borrow_mut();
        self.samples_of(l, &mut samples);
        if !samples.projected {
            return None;
        }
        if !samples.projections[i].accelerations_prepared() {
            samples.projections[i].prepare_accelerations(&self.dynamics);
        }
        let (s, nc) = (self.scheme.s, self.contacts.len());
        let Some(k) = samples.times.iter().position(|&x| x == t) else {
            if !(t > l.t0 && t < l.t0 + l.h) {
                return None;
            }
            let (at, _) = self.off_samples(l, t, &mut samples);
            let Samples { projections, off, .. } = &*samples;
            let responses = &off.responses[i * nc * s..(i + 1) * nc * s];
            return Some(self.acceleration(l, at, &projections[i], &off.free, responses));
        };
        if let Some(a) = samples.accelerations[k][i] {
            return Some(a);
        }
        let at = self.sample_size(l, &mut samples);
        let (n, nd) = (self.n, self.watched.len());
        let Samples { projections, sizes, accelerations, .. } = &mut *samples;
        let size = &sizes[at];
        let free = &size.free[k * n..(k + 1) * n];
        let base = (k * nd + i) * nc * s;
        let a = self.acceleration(l, t, &projections[i], free, &size.responses[base..base + nc * s]);
        accelerations[k][i] = Some(a);
        Some(a)
    }

    /// One direction's `c . q''` at `t` in step `l` from its projection
    /// and the point's kernels (`responses`: that direction's, as
    /// [`Self::point_kernels`]').
    fn acceleration(&self, l: &Step, t: f64, projection: &Projection, free: &[(f64, f64)], responses: &[[f64; 3]]) -> f64 {
        let s = self.scheme.s;
        let mut a = projection.acceleration_at(&self.dynamics, t - l.t0, free);
        for (alpha, r) in l.force.iter().zip(responses.chunks_exact(s)) {
            for (f, rm) in alpha.iter().zip(r) {
                a -= f * rm[2];
            }
        }
        a
    }

    /// The samples of step `l`: their times and the free motion's
    /// projections, formed once per step.
    fn samples_of(&self, l: &Step, samples: &mut Samples) {
        if samples.step != Some((l.t0, l.h)) {
            let t1 = l.t0 + l.h;
            let mut previous = l.t0;
            for k in 1..=GRID {
                let point = sample_time(l.t0, t1, k);
                samples.times[2 * k - 2] = 0.5 * (previous + point);
                if k < GRID {
                    samples.times[2 * k - 1] = point;
                }
                previous = point;
            }
            let Samples { projections, .. } = &mut *samples;
            projections.resize_with(self.watched.len(), Projection::default);
            // A contact's own direction: the step's projection on it.
            let mut projected = true;
            for ((c, p), contact) in self.watched.iter().zip(projections.iter_mut()).zip(&self.watched_contact) {
                projected &= match contact {
                    Some(e) if l.projected => {
                        p.clone_from(&l.projections[*e]);
                        true
                    }
                    _ => l.free.projected(&self.dynamics, c.as_slice(), p),
                };
            }
            samples.projected = projected;
            samples.values.iter_mut().for_each(Vec::clear);
            samples.values.resize(INNER, Vec::new());
            let nd = self.watched.len();
            samples.accelerations.resize(INNER, Vec::new());
            samples.accelerations.iter_mut().for_each(|a| {
                a.clear();
                a.resize(nd, None);
            });
            samples.step = Some((l.t0, l.h));
            samples.last_off = None;
        }
    }

    /// The anchor of `t` (off the samples, inside step `l`) and every
    /// direction's coordinates there, `samples.off` holding its kernels.
    fn off_samples<'a>(&self, l: &Step, t: f64, samples: &'a mut Samples) -> (f64, &'a [(f64, f64)]) {
        let Samples { projections, off, last_off, off_coordinates, .. } = samples;
        let at = Some(anchor(t)).filter(|a| *a > l.t0 && *a < l.t0 + l.h).unwrap_or(t);
        if *last_off != Some(at) {
            self.point_kernels(at - l.t0, l.h, off);
            off_coordinates.clear();
            self.project(l, at, projections, &off.free, &off.responses, off_coordinates);
            *last_off = Some(at);
        }
        (at, off_coordinates)
    }

    /// The index in `samples.sizes` of the sample kernels of step `l`'s
    /// size (formed if new).
    fn sample_size(&self, l: &Step, samples: &mut Samples) -> usize {
        let sizes = &mut samples.sizes;
        match sizes.iter().rposition(|r| r.h == l.h) {
            Some(i) => i,
            None => {
                if sizes.len() == SAMPLE_SIZES {
                    sizes.remove(0);
                }
                sizes.push(self.sample_kernels(l.h));
                sizes.len() - 1
            }
        }
    }

    /// What the samples of steps of size `h` need (each one's
    /// [`Self::point_kernels`]), marched from sample to sample: every
    /// mode's propagator over `delta = h / (2 GRID)` and its responses to
    /// `(u / delta)^i` over it (one set of `phi_k` per mode instead of one
    /// per sample), the monomials `sigma^m` continued across each interval
    /// by the binomial theorem (HertzStop at 20 modes: 2 to 3 % fewer
    /// instructions over its run). The samples' coordinates agree with the
    /// dense output's, whose kernels are each point's own, within 1e-12
    /// of the terms' size (`watched_coordinates_are_the_dense_outputs`).
    fn sample_kernels(&self, h: f64) -> SampleKernels {
        let (n, s, nc, nd) = (self.n, self.scheme.s, self.contacts.len(), self.watched.len());
        let ratio = 1.0 / (2 * GRID) as f64;
        let delta = h * ratio;
        let mut free = vec![(0.0, 0.0); INNER * n];
        // Summed over the modes in their order as each is marched.
        let mut responses = vec![[0.0; 3]; INNER * nd * nc * s];
        // The load sigma^m over the k-th interval in u = (tau - tau_k) /
        // delta: sum_i C(m, i) sigma_k^(m - i) ratio^i u^i (every mode alike).
        let mut shift = [[[0.0; STAGES]; STAGES]; INNER];
        for (k, per_k) in shift.iter_mut().enumerate() {
            let mut unit = [0.0; STAGES];
            for m in 0..s {
                unit[m] = 1.0;
                taylor_shift(&unit[..s], k as f64 * ratio, ratio, &mut per_k[m][..s]);
                unit[m] = 0.0;
            }
        }
        let mut phis = [[0.0; 2]; STAGES + 1];
        for (j, osc) in self.dynamics.oscillators.iter().enumerate() {
            phi_columns(osc, delta, &mut phis[..=s]);
            let (ec, es) = kernels_of(phis[0], osc.a);
            let prop = [ec + osc.a * es, es, -osc.omega * osc.omega * es, ec - osc.a * es];
            let apply = |z: [f64; 2]| [prop[0] * z[0] + prop[1] * z[1], prop[2] * z[0] + prop[3] * z[1]];
            // The responses over one interval to (u / delta)^i.
            let mut g = [[0.0; 2]; STAGES];
            let mut factor = delta;
            for (i, gi) in g.iter_mut().enumerate().take(s) {
                *gi = [factor * phis[i + 1][0], factor * phis[i + 1][1]];
                factor *= (i + 1) as f64;
            }
            // e^{A tau} b = (Es, Ec - a Es), from b at tau = 0.
            let mut column = [0.0, 1.0];
            let mut r = [[0.0; 2]; STAGES];
            for (k, per_k) in shift.iter().enumerate() {
                for (rm, coefficients) in r.iter_mut().zip(per_k).take(s) {
                    let mut next = apply(*rm);
                    for (c, gi) in coefficients.iter().zip(&g).take(s) {
                        next[0] += c * gi[0];
                        next[1] += c * gi[1];
                    }
                    *rm = next;
                }
                column = apply(column);
                free[k * n + j] = (column[1] + osc.a * column[0], column[0]);
                let point = &mut responses[k * nd * nc * s..(k + 1) * nd * nc * s];
                let sigma = (k + 1) as f64 * ratio;
                for (weights, directional) in self.watched_weights.iter().zip(point.chunks_exact_mut(s)) {
                    let w = weights[j];
                    let mut load = 1.0;
                    for (o, x) in directional.iter_mut().zip(&r[..s]) {
                        o[0] += w * x[0];
                        o[1] += w * x[1];
                        o[2] += w * response_acceleration(osc, *x, load);
                        load *= sigma;
                    }
                }
            }
        }
        SampleKernels { h, free, responses }
    }

    /// At `tau` into a step of size `h`: every mode's free kernels, and
    /// the contacts' responses to the force monomials in each watched
    /// direction, `sum_j c_j d_j R_jm(tau)` (`[(i * nc + e) * s + m]`).
    fn point_kernels(&self, tau: f64, h: f64, out: &mut PointKernels) {
        let (n, s, nc, nd) = (self.n, self.scheme.s, self.contacts.len(), self.watched.len());
        out.free.resize(n, (0.0, 0.0));
        out.modal.resize(n * s, [0.0; 2]);
        for ((osc, free), modal) in self.dynamics.oscillators.iter().zip(out.free.iter_mut()).zip(out.modal.chunks_exact_mut(s)) {
            *free = point_responses(osc, tau, h, modal);
        }
        out.responses.clear();
        out.responses.resize(nd * nc * s, [0.0; 3]);
        let sigma = tau / h;
        for (weights, directional) in self.watched_weights.iter().zip(out.responses.chunks_exact_mut(s)) {
            for ((&w, r), osc) in weights.iter().zip(out.modal.chunks_exact(s)).zip(&self.dynamics.oscillators) {
                let mut load = 1.0;
                for (o, rm) in directional.iter_mut().zip(r) {
                    o[0] += w * rm[0];
                    o[1] += w * rm[1];
                    o[2] += w * response_acceleration(osc, *rm, load);
                    load *= sigma;
                }
            }
        }
    }

    /// Every watched direction's `(c . q, c . q')` at `t` in the last
    /// step `l` from its free motion's projections and the point's
    /// kernels (`free`, and `responses` as [`Self::point_kernels`]'), onto
    /// the end of `out`.
    fn project(&self, l: &Step, t: f64, projections: &[Projection], free: &[(f64, f64)], responses: &[[f64; 3]], out: &mut Vec<(f64, f64)>) {
        let (s, nc) = (self.scheme.s, self.contacts.len());
        for (projection, per_contact) in projections.iter().zip(responses.chunks_exact(nc * s)) {
            let (mut x, mut v) = projection.at(&self.dynamics, t - l.t0, free);
            for (alpha, r) in l.force.iter().zip(per_contact.chunks_exact(s)) {
                for (a, rm) in alpha.iter().zip(r) {
                    x -= a * rm[0];
                    v -= a * rm[1];
                }
            }
            out.push((x, v));
        }
    }

    /// The integrated state at `t` in the last step under its
    /// polynomials (the step's start before the first step: `None`).
    pub fn dense(&self, t: f64, out: &mut DVector<f64>) -> Option<()> {
        let l = self.last.as_ref()?;
        if !(t >= l.t0 && t <= l.t0 + l.h) {
            return None;
        }
        if t == self.t {
            out.copy_from(&self.y);
            return Some(());
        }
        if let Some(y) = self.memo.borrow().find(t) {
            out.copy_from(y);
            return Some(());
        }
        self.evaluate(l, t, out);
        self.memo.borrow_mut().slot(t, out.len()).copy_from(out);
        Some(())
    }

    /// Prepares the dense states at `times` in the last step, close to
    /// equally spaced from its start (the switch locator's grid): the
    /// contact response is marched from point to point (one propagator
    /// per mode for the whole grid), the free motion taken from the
    /// segment.
    pub fn prefill(&self, times: &[f64]) {
        let Some(l) = self.last.as_ref() else { return };
        let (n, s, nc) = (self.n, self.scheme.s, self.contacts.len());
        let intervals = times.len().saturating_sub(1);
        if intervals == 0 || times[0] != l.t0 {
            return;
        }
        if intervals != GRID {
            return;
        }
        let ratio = 1.0 / intervals as f64;
        let kernels = self.kernels_for(l.h, true, true);
        let (prop, resp) = (&kernels.grid_propagator, &kernels.grid_responses);
        let mut z = vec![[0.0; 2]; n];
        let mut shifted = vec![[0.0; STAGES]; nc];
        let mut st = ModalState::zeros(n);
        let mut memo = self.memo.borrow_mut();
        for (k, &t) in times.iter().enumerate() {
            if k > 0 {
                // The load over [tau_{k-1}, tau_k] in u = (tau - tau_{k-1}) / delta.
                let sigma = (k - 1) as f64 * ratio;
                for (c, alpha) in l.force.iter().enumerate() {
                    taylor_shift(alpha, sigma, ratio, &mut shifted[c][..s]);
                }
                for (c, gamma) in shifted.iter().enumerate() {
                    // Mode by mode, over slices (no index checks in the loop).
                    let d = self.contacts[c].d.as_slice();
                    for (((zj, e), r), &dj) in z.iter_mut().zip(&prop[..n]).zip(resp.chunks_exact(s)).zip(d) {
                        let (x, v) = (zj[0], zj[1]);
                        let mut next = if c == 0 { [e[0] * x + e[1] * v, e[2] * x + e[3] * v] } else { [x, v] };
                        for (g, rm) in gamma[..s].iter().zip(r) {
                            let w = dj * g;
                            next[0] -= w * rm[0];
                            next[1] -= w * rm[1];
                        }
                        *zj = next;
                    }
                }
                if nc == 0 {
                    for (zj, e) in z.iter_mut().zip(&prop[..n]) {
                        let (x, v) = (zj[0], zj[1]);
                        *zj = [e[0] * x + e[1] * v, e[2] * x + e[3] * v];
                    }
                }
            }
            if t == l.t0 || t == self.t || memo.find(t).is_some() {
                continue;
            }
            l.free.state_with_kernels(&self.dynamics, t, &kernels.grid_free[(k - 1) * n..k * n], &mut st);
            let y = memo.slot(t, 2 * n + 2 * nc);
            for j in 0..n {
                y[j] = st.q[j] + z[j][0];
                y[n + j] = st.qd[j] + z[j][1];
            }
            let sigma = (t - l.t0) / l.h;
            for c in 0..nc {
                y[2 * n + c] = l.y0[2 * n + c] + l.h * integral(&l.force[c], sigma);
                y[2 * n + nc + c] = l.y0[2 * n + nc + c] + l.h * integral(&l.dissipation[c], sigma);
            }

        }
    }

    fn evaluate(&self, l: &Step, t: f64, out: &mut DVector<f64>) {
        let (n, s, nc) = (self.n, self.scheme.s, self.contacts.len());
        let tau = t - l.t0;
        let mut st = ModalState::zeros(n);
        l.free.state_at(&self.dynamics, t, &mut st);
        let mut r = vec![[0.0; 2]; n * (s + 1)];
        if tau > 0.0 {
            for (j, osc) in self.dynamics.oscillators.iter().enumerate() {
                point_responses(osc, tau, l.h, &mut r[j * (s + 1)..j * (s + 1) + s]);
            }
        }
        for j in 0..n {
            let (mut x, mut v) = (st.q[j], st.qd[j]);
            if tau > 0.0 {
                for (c, alpha) in l.force.iter().enumerate() {
                    let dj = self.contacts[c].d[j];
                    for (m, a) in alpha.iter().enumerate() {
                        let rr = r[j * (s + 1) + m];
                        x -= dj * a * rr[0];
                        v -= dj * a * rr[1];
                    }
                }
            }
            out[j] = x;
            out[n + j] = v;
        }
        let sigma = tau / l.h;
        for c in 0..nc {
            out[2 * n + c] = l.y0[2 * n + c] + l.h * integral(&l.force[c], sigma);
            out[2 * n + nc + c] = l.y0[2 * n + nc + c] + l.h * integral(&l.dissipation[c], sigma);
        }
    }
}
