//! A run whose hub angle is prescribed as a map of its state, the beam's
//! modal coordinates and rates `x = [B; B']` (the hub is not a state: its
//! angle is the profile's at every time), and that map's Jacobian, for
//! shooting and continuation of periodic orbits under a periodic drive
//! (the harmonic swing, `hub.prescribed.harmonic`).
//!
//! **Internal differentiation.** Nothing here is closed form, so the
//! Jacobian is that of the integration itself, phase by phase (a phase
//! runs from one switch of the contact law to the next). The nominal run
//! records the end of every accepted step ([`RotatingSimulation::trace`],
//! whichever integrator made them: `solver.method`);
//! each phase's transition matrix comes from a *replay*: DOP853 stepped
//! without error control over exactly those step ends from the phase's
//! start, the state at the phase's end (inside a step) taken by DOP853's
//! full-order state there ([`super::stepper::full_order_state`]), together
//! with its variational equations `V' = (df/dy) V` (the phase's analytic
//! Jacobian, [`super::system`]) in the same Runge-Kutta stages: the exact
//! derivative of the replayed map, a fixed composition of Runge-Kutta
//! steps and smooth in its start, which agrees with the flow's derivative
//! to the integration's own tolerance. Central differences of the
//! *simulation* instead see the adaptive step sequence change with the
//! start: a map that jumps by the local error wherever a step is rejected
//! or resized. One thing the nominal steps do not do is resolve a mode
//! the nominal motion barely excites (DOP853's step control follows the
//! error of what moves, up to its stability limit, `h omega_N` about 4):
//! a perturbation does excite it, so the replay splits each step into
//! pieces of at most [`RESOLUTION`] radians of the highest mode. The test
//! compares the variational replay with central differences of the replay
//! (1e-7) and the phase chain with central differences of the simulation.
//!
//! **Switches.** At a switch of the contact law at `t_e`, where the
//! watched function `g` (the gap at an onset, the law's force at the end
//! of a push, the penetration at a separation) is zero, the state does not
//! jump; the vector field may: `S = I + (F+ - F-) Dg / g'` (DBBCK08 sec.
//! 2.5), `F-+` the phases' fields at the switch, `Dg` the watched
//! function's gradient in `x` and `g'` its total rate along `F-` (the
//! prescribed hub makes it depend on time too). A compliant law's force is
//! continuous at its onset (zero at zero penetration) and at the end of a
//! push (zero there by definition), so `F+ = F-` and `S = I`; the matrix
//! is computed from `F+-` all the same, whatever the law. What is not
//! continuous is the onset speed `v0` the hysteretic damping divides by
//! (Lankarani-Nikravesh, Hunt-Crossley): it is the penetration rate at the
//! onset, a state of its own. The Jacobian is propagated for `[x; v0]`:
//! an onset resets `v0 = gamma'(x)`, the row `D gamma' - gamma'' Dg / g'`
//! (the time shift of the onset moves the rate it is read at), and a
//! contact phase's transition has a column for `v0` (its variational
//! equation forced by `df/dv0`, a central difference of the law). A run started inside the surface takes its onset speed from the
//! start state, which the Jacobian holds fixed: put the section where the
//! tip is free.
//!
//! Refused, with the reason: a torque-driven hub (its angle is a state and
//! nothing drives it periodically: its runs have no period to shoot over)
//! and a spin-up (not periodic).

use nalgebra::{DMatrix, DVector};

use super::model::HubMotion;
use super::sim::RotatingSimulation;
use super::stepper::dop853_tolerances;
#[cfg(test)]
use super::stepper::{full_order_state, Method, PhaseRhs};
use super::system::Phase;
use crate::contact::Contact;
use crate::error::SimError;
use crate::kind::{Clearance, Reached, Surface};
use crate::solve::dop853::Dop853;
use crate::solve::radau::RadauOptions;

/// The relative difference step of `df/dv0` (and of the check's
/// differences of the replay).
const H: f64 = 1e-6;
/// The longest replayed piece of a step, in radians of the highest mode
/// (`h omega_N`): DOP853's steps follow the nominal motion's error, in
/// which the highest modes are barely excited, up to its stability limit
/// (`h omega_N` about 4); a perturbation that excites them is resolved
/// to about 1e-6 of its effect at 1 (TappingArm, 0.15 period: the
/// highest mode's column within 1e-4 of the simulation's differences, the
/// others 1e-6 of their size; unsplit, the two highest modes' columns
/// off by 10 % and 100 %).
const RESOLUTION: f64 = 1.0;

impl RotatingSimulation {
    /// Why this run has no flow map with a Jacobian, if it has none.
    pub fn flow_unsupported(&self) -> Option<String> {
        flow_unsupported(&self.model)
    }

    /// `[B; B']` now.
    pub fn flow_state(&self) -> DVector<f64> {
        let n = self.model.n_modes();
        self.current.rows(0, 2 * n).into_owned()
    }

    /// The tip's clearance from the surface now: `gap` and its rate, the
    /// penetration (`displacement`, positive inside) and its rate.
    pub fn flow_clearances(&self) -> Vec<Clearance> {
        if self.model.surface.is_none() {
            return Vec::new();
        }
        let (z, zd) = self.coordinates();
        let c = self.phase.contact_point(&z, &zd);
        vec![Clearance { gap: -c.penetration, rate: -c.rate, displacement: c.penetration, velocity: c.rate }]
    }

    /// The surface linearised at the current time and state: the
    /// penetration is `shape . B - target` to first order.
    pub fn flow_surfaces(&self) -> Vec<Surface> {
        let Some(s) = &self.model.surface else { return Vec::new() };
        let n = self.model.n_modes();
        let (z, zd) = self.coordinates();
        let c = self.phase.contact_point(&z, &zd);
        let (g, _) = self.model.gap_gradient_hessian(&z, &s.plane);
        let shape = -g.rows(1, n).into_owned();
        let target = shape.dot(&z.rows(1, n)) - c.penetration;
        vec![Surface { shape, target, side: 1.0, rigid: false }]
    }

    /// Advances to `t_end` through every switch, as [`Self::advance_to`]
    /// does, and returns the Jacobian of `[B; B']` reached with respect to
    /// `[B; B']` now (module doc). A run in the middle of an integration
    /// step restarts from its state first (a switch-free restart: the step
    /// grid changes, the motion by the integration's error).
    pub fn advance_with_jacobian(&mut self, t_end: f64) -> Result<DMatrix<f64>, SimError> {
        if let Some(why) = self.flow_unsupported() {
            return Err(SimError::Unsupported(format!("the flow's Jacobian: {why}")));
        }
        if t_end < self.time {
            return Err(SimError::Backwards { now: self.time, requested: t_end });
        }
        let dim = 2 * self.model.n_modes();
        if self.step.is_some() || self.time != self.anchor_time {
            let (t, y, contact) = (self.time, self.current.clone(), self.phase.contact);
            self.restart(t, y, contact)?;
        }
        // Rows and columns [x; v0]; the start's v0 is held (module doc).
        let mut m = DMatrix::<f64>::zeros(dim + 1, dim);
        m.view_mut((0, 0), (dim, dim)).fill_with_identity();
        loop {
            let (t_a, y_a, phase) = (self.time, self.current.clone(), self.phase.clone());
            self.trace = Some(Vec::new());
            let reached = self.advance(t_end, Some(&mut |_| true));
            let grid = self.trace.take().unwrap_or_default();
            let reached = reached?;
            let t_b = self.time;
            if t_b > t_a {
                let options = self.options.clone();
                m = tangent_replay(&phase, &options, t_a, &y_a, &grid, t_b)? * m;
            }
            match reached {
                Reached::Time => return Ok(m.rows(0, dim).into_owned()),
                Reached::Event(_) => m = self.apply_switch_with_saltation()? * m,
            }
        }
    }

    /// Makes the pending switch (as [`crate::kind::Run::apply_events`])
    /// and returns its saltation matrix for `[x; v0]` (module doc).
    fn apply_switch_with_saltation(&mut self) -> Result<DMatrix<f64>, SimError> {
        let te = self.time;
        let n = self.model.n_modes();
        let dim = 2 * n;
        let watch = self.step.as_ref().and_then(|s| s.switch).map(|(_, w, _)| w);
        let Some(watch) = watch else {
            return Err(SimError::Unsupported(format!("the flow's Jacobian: no switch pending at t = {te} where the run stopped")));
        };
        let surface = self.model.surface.clone().ok_or_else(|| SimError::Unsupported("the flow's Jacobian: a switch without a surface".into()))?;
        let before = self.phase.clone();
        let y = self.current.clone();
        let f_minus = field(&before, te, &y)?;
        self.apply_switch()?;
        let f_plus = field(&self.phase, te, &self.current)?;
        // The penetration gamma = -gap, its rate and second rate along F-,
        // and their gradients in x = [B; B'] (theta is the profile's).
        let (z, zd) = before.coords(te, &y);
        let c = before.contact_point(&z, &zd);
        let (g, hess) = self.model.gap_gradient_hessian(&z, &surface.plane);
        let hzd = &hess * &zd;
        let mut zdd = DVector::zeros(n + 1);
        zdd[0] = self.model.prescribed().map_or(0.0, |p| p.at(te).2);
        zdd.rows_mut(1, n).copy_from(&f_minus.rows(n, n));
        let rate2 = -(zd.dot(&hzd) + g.dot(&zdd));
        let mut grad_p = DVector::zeros(dim);
        grad_p.rows_mut(0, n).copy_from(&(-g.rows(1, n)));
        let mut grad_rate = DVector::zeros(dim);
        grad_rate.rows_mut(0, n).copy_from(&(-hzd.rows(1, n)));
        grad_rate.rows_mut(n, n).copy_from(&(-g.rows(1, n)));
        let (_, dh_dp, dh_drate) = surface.law.watched(watch, c.penetration, c.rate, before.onset_speed);
        let dg = &grad_p * dh_dp + &grad_rate * dh_drate;
        let g_rate = dh_dp * c.rate + dh_drate * rate2;
        if g_rate == 0.0 || !g_rate.is_finite() {
            return Err(SimError::Unsupported(format!(
                "the flow's Jacobian: the switch at t = {te} is tangential (its function's rate {g_rate:e}): its saltation matrix does not exist (grazing)"
            )));
        }
        let mut s = DMatrix::<f64>::identity(dim + 1, dim + 1);
        let jump = (&f_plus - &f_minus) / g_rate;
        let mut block = s.view_mut((0, 0), (dim, dim));
        block += &jump * dg.transpose();
        if before.contact == Contact::Open && self.phase.contact != Contact::Open {
            // The onset resets v0 to the penetration rate there.
            let row = grad_rate.transpose() - dg.transpose() * (rate2 / g_rate);
            s.view_mut((dim, 0), (1, dim)).copy_from(&row);
            s[(dim, dim)] = 0.0;
        }
        Ok(s)
    }

    /// The discrete change of the pending switch.
    fn apply_switch(&mut self) -> Result<(), SimError> {
        let now = self.time;
        self.advance(now, None).map(|_| ())
    }
}

/// Why a model's runs have no flow map, if they have none.
pub fn flow_unsupported(model: &super::RotatingModel) -> Option<String> {
    match model.prescribed() {
        None => Some(
            "the hub is driven by its torque input: its angle is a state of the run and nothing drives it periodically, \
             so its runs have no period to shoot over (prescribe the hub's motion as a harmonic swing, \
             hub.prescribed.type = harmonic)"
                .into(),
        ),
        Some(HubMotion::SpinUp(_)) => Some("the hub's spin-up is not periodic (prescribe a harmonic swing, hub.prescribed.type = harmonic)".into()),
        Some(HubMotion::Swing(_)) => None,
    }
}

/// `[B'; B'']` of `phase` at `(t, y)`.
fn field(phase: &Phase, t: f64, y: &DVector<f64>) -> Result<DVector<f64>, SimError> {
    let n = phase.n();
    let mut dy = DVector::zeros(y.len());
    phase.fill_rhs(t, y, &mut dy).map_err(|e| SimError::Integration { time: t, message: e })?;
    Ok(dy.rows(0, 2 * n).into_owned())
}

/// The nominal phase's steps (ends `grid`) from `(t_a, y)` replayed to
/// `t_b` (module doc): DOP853 without error control, each step split into
/// pieces of at most [`RESOLUTION`] radians of the highest mode (the
/// variational replay's check).
#[cfg(test)]
fn replay(phase: &Phase, options: &RadauOptions, t_a: f64, y: &DVector<f64>, grid: &[f64], t_b: f64) -> Result<DVector<f64>, SimError> {
    let n = y.len();
    let (rtol, atol) = dop853_tolerances(options, n);
    let omega = phase.model.beam.omega(phase.n());
    let pieces = |h: f64| ((h * omega / RESOLUTION).ceil() as usize).max(1);
    let first = grid.first().copied().unwrap_or(t_b);
    let h0 = ((first.min(t_b) - t_a) / pieces(first.min(t_b) - t_a) as f64).max(f64::MIN_POSITIVE);
    let mut s = Dop853::new(PhaseRhs::new(phase, n), t_a, y.as_slice(), f64::MAX, rtol, &atol, Some(h0));
    let mut t = t_a;
    for &end in grid.iter().take_while(|&&e| e <= t_b) {
        let m = pieces(end - t);
        for j in 1..m {
            s.step_to(t + (end - t) * j as f64 / m as f64);
        }
        s.step_to(end);
        t = end;
    }
    let mut out = Some(DVector::from_column_slice(s.y()));
    if t < t_b {
        // The last piece as the nominal run takes a state inside a step
        // (in contact, shrinking toward t_b).
        let m = pieces(t_b - t);
        for j in 1..m {
            s.step_to(t + (t_b - t) * j as f64 / m as f64);
        }
        let from = s.t;
        out = full_order_state(Method::Dop853, phase, options, from, &DVector::from_column_slice(s.y()), t_b);
    }
    out.filter(|y| y.iter().all(|v| v.is_finite()))
        .ok_or(SimError::Integration { time: t_b, message: "the flow's Jacobian: a replayed step is not finite".into() })
}

/// The phase's equations and their variational equations, `[y; V]` with
/// `V' = (df/dy) V` (`V` column-major, `cols` columns, the last one for
/// the onset speed when `dv0` is set: `V' = (df/dy) V + df/dv0`).
struct Tangent {
    phase: Phase,
    dim: usize,
    cols: usize,
    dv0: bool,
    y: DVector<f64>,
    f: DVector<f64>,
    jac: DMatrix<f64>,
}

impl crate::solve::dop853::Rhs for Tangent {
    fn eval(&mut self, t: f64, y: &[f64], dy: &mut [f64]) {
        let dim = self.dim;
        self.y.copy_from_slice(&y[..dim]);
        let ok = self.phase.fill_rhs(t, &self.y, &mut self.f).is_ok() && self.phase.fill_jacobian(t, &self.y, &mut self.jac).is_ok();
        if !ok {
            dy.fill(f64::NAN);
            return;
        }
        dy[..dim].copy_from_slice(self.f.as_slice());
        let v = nalgebra::DMatrixView::from_slice(&y[dim..], dim, self.cols);
        let mut dv = nalgebra::DMatrixViewMut::from_slice(&mut dy[dim..], dim, self.cols);
        dv.gemm(1.0, &self.jac, &v, 0.0);
        if self.dv0 {
            // df/dv0 by a central difference of the law (smooth in v0 > 0).
            let v0 = self.phase.onset_speed;
            let h = H * v0;
            let mut column = DVector::zeros(dim);
            let mut other = DVector::zeros(dim);
            let mut moved = self.phase.clone();
            moved.onset_speed = v0 + h;
            let up = moved.fill_rhs(t, &self.y, &mut column).is_ok();
            moved.onset_speed = v0 - h;
            let down = moved.fill_rhs(t, &self.y, &mut other).is_ok();
            if !(up && down) {
                dy.fill(f64::NAN);
                return;
            }
            let last = self.cols - 1;
            for i in 0..dim {
                dv[(i, last)] += (column[i] - other[i]) / (2.0 * h);
            }
        }
    }
}

/// [`replay`] with its variational equations: the transition matrix of
/// `y` (and the onset speed's column, in contact) over the same pieces, the
/// derivative of the replayed Runge-Kutta map itself.
fn tangent_replay(phase: &Phase, options: &RadauOptions, t_a: f64, y: &DVector<f64>, grid: &[f64], t_b: f64) -> Result<DMatrix<f64>, SimError> {
    let dim = y.len();
    let n = phase.n();
    let dv0 = phase.contact != Contact::Open && phase.onset_speed > 0.0;
    let cols = 2 * n + 1;
    let mut start = vec![0.0; dim * (1 + cols)];
    start[..dim].copy_from_slice(y.as_slice());
    for k in 0..2 * n {
        start[dim + k * dim + k] = 1.0;
    }
    let (rtol, _) = dop853_tolerances(options, dim);
    let atol = vec![1.0; start.len()];
    let omega = phase.model.beam.omega(n);
    let pieces = |h: f64| ((h * omega / RESOLUTION).ceil() as usize).max(1);
    let rhs = Tangent { phase: phase.clone(), dim, cols, dv0, y: DVector::zeros(dim), f: DVector::zeros(dim), jac: DMatrix::zeros(dim, dim) };
    let first = grid.first().copied().unwrap_or(t_b).min(t_b);
    let h0 = ((first - t_a) / pieces(first - t_a) as f64).max(f64::MIN_POSITIVE);
    let mut s = Dop853::new(rhs, t_a, &start, f64::MAX, rtol, &atol, Some(h0));
    let mut t = t_a;
    let mut ends: Vec<f64> = grid.iter().copied().take_while(|&e| e <= t_b).collect();
    let last_full = ends.last().copied().unwrap_or(t_a);
    if last_full < t_b {
        ends.push(t_b);
    }
    for end in ends {
        let m = pieces(end - t);
        let last_piece = end == t_b && last_full < t_b;
        for j in 1..m {
            s.step_to(t + (end - t) * j as f64 / m as f64);
        }
        if last_piece && phase.contact != Contact::Open {
            // As [`full_order_state`] in contact: pieces shrinking fourfold toward t_b.
            let (t0, smallest) = (s.t, rtol.powf(2.0 / 7.0));
            let mut remaining = 1.0;
            while remaining / 4.0 > smallest {
                s.step_to(t0 + (1.0 - 0.25 * remaining) * (t_b - t0));
                remaining *= 0.25;
            }
        }
        s.step_to(end);
        t = end;
    }
    let out = s.y();
    if !out.iter().all(|v| v.is_finite()) {
        return Err(SimError::Integration { time: t_b, message: "the flow's Jacobian: a replayed step is not finite".into() });
    }
    let v = nalgebra::DMatrixView::from_slice(&out[dim..], dim, cols);
    let mut m = DMatrix::zeros(2 * n + 1, 2 * n + 1);
    m.view_mut((0, 0), (2 * n, 2 * n)).copy_from(&v.view((0, 0), (2 * n, 2 * n)));
    if dv0 {
        m.view_mut((0, 2 * n), (2 * n, 1)).copy_from(&v.view((0, 2 * n), (2 * n, 1)));
    }
    m[(2 * n, 2 * n)] = 1.0;
    Ok(m)
}

/// The transition matrix of one phase for `[x; v0]` ((2N+1) x (2N+1)) by
/// central differences of its replay: the variational replay's check.
#[cfg(test)]
fn phase_transition_by_differences(phase: &Phase, options: &RadauOptions, t_a: f64, y_a: &DVector<f64>, grid: &[f64], t_b: f64) -> Result<DMatrix<f64>, SimError> {
    let n = phase.n();
    let dim = 2 * n;
    let scale_q = y_a.rows(0, n).amax();
    let scale_v = y_a.rows(n, n).amax();
    let mut m = DMatrix::zeros(dim + 1, dim + 1);
    for k in 0..dim {
        let scale = if k < n { scale_q } else { scale_v };
        let h = H * y_a[k].abs().max(scale).max(1e-300);
        let (mut plus, mut minus) = (y_a.clone(), y_a.clone());
        plus[k] += h;
        minus[k] -= h;
        let h2 = plus[k] - minus[k];
        let column = (replay(phase, options, t_a, &plus, grid, t_b)? - replay(phase, options, t_a, &minus, grid, t_b)?) / h2;
        m.view_mut((0, k), (dim, 1)).copy_from(&column.rows(0, dim));
    }
    let v0 = phase.onset_speed;
    if phase.contact != Contact::Open && v0 > 0.0 {
        let h = H * v0;
        let (mut plus, mut minus) = (phase.clone(), phase.clone());
        plus.onset_speed = v0 + h;
        minus.onset_speed = v0 - h;
        let h2 = plus.onset_speed - minus.onset_speed;
        let column = (replay(&plus, options, t_a, y_a, grid, t_b)? - replay(&minus, options, t_a, y_a, grid, t_b)?) / h2;
        m.view_mut((0, dim), (dim, 1)).copy_from(&column.rows(0, dim));
    }
    m[(dim, dim)] = 1.0;
    Ok(m)
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::kinds::rotating::{RotatingModel, RotatingSpec};

    /// The variational replay against central differences of the replay
    /// itself, phase by phase over TappingArm's strike (free flight, the
    /// push with its onset-speed column, free flight again).
    #[test]
    fn variational_replay_matches_differences_of_the_replay() {
        let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/tapping_arm.json")).unwrap();
        let model = Arc::new(RotatingModel::new(&RotatingSpec::from_json(&text).unwrap()).unwrap());
        let mut sim = RotatingSimulation::new(model, 0.0).unwrap();
        sim.advance_to(0.1).unwrap();
        let (t_a, y_a) = (sim.time, sim.current.clone());
        sim.restart(t_a, y_a, sim.phase.contact).unwrap();
        let mut phases = 0;
        while sim.time < 0.13 {
            let (t_a, y_a, phase) = (sim.time, sim.current.clone(), sim.phase.clone());
            sim.trace = Some(Vec::new());
            let reached = sim.advance(0.13, Some(&mut |_| true)).unwrap();
            let grid = sim.trace.take().unwrap();
            let options = sim.options.clone();
            let ours = tangent_replay(&phase, &options, t_a, &y_a, &grid, sim.time).unwrap();
            let theirs = phase_transition_by_differences(&phase, &options, t_a, &y_a, &grid, sim.time).unwrap();
            let off = (&ours - &theirs).amax() / theirs.amax();
            assert!(off < 1e-7, "{:?} phase from {t_a}: {off:e}", phase.contact);
            phases += 1;
            if matches!(reached, Reached::Event(_)) {
                sim.apply_switch().unwrap();
            }
        }
        assert_eq!(phases, 3, "free, pressed, free");
    }
}
