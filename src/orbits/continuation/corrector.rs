//! The continuation's problem and Newton's corrector: the scene at a
//! parameter value, the stroboscopic map with its exact Jacobian and the
//! parameter derivative, the scaled coordinates, tangents, the chord
//! corrector, fixed-parameter shooting and the switch at a period doubling.

use std::cell::RefCell;
use std::f64::consts::PI;

use nalgebra::{DMatrix, DVector};

use super::super::profile::profile;
use super::super::shooting::{advance_by_periods, map, minimal_period, shoot, start_from, Orbit, Shooting};
use super::{Continuation, Point};
use crate::component::Component;

/// `G`, its Jacobian and the impacts along the way at `(x, p)`.
pub(super) struct Evaluation {
    pub(super) residual: DVector<f64>,
    pub(super) monodromy: DMatrix<f64>,
    pub(super) by_param: DVector<f64>,
    pub(super) impacts: usize,
    pub(super) period: f64,
}

/// The continuation's state: the problem and its scaling.
pub(super) struct Walker {
    pub(super) base: Component,
    pub(super) param: usize,
    pub(super) forcing: usize,
    pub(super) t0: f64,
    pub(super) range: (f64, f64),
    pub(super) ds_max: f64,
    pub(super) weight_p: f64,
    pub(super) weight_x: f64,
    pub(super) tolerance: f64,
    pub(super) max_points: usize,
    pub(super) evaluations: usize,
    pub(super) scenes: RefCell<Vec<(f64, Component)>>,
    /// The stops' surfaces at the last few parameter values.
    pub(super) surfaces: RefCell<Vec<(f64, Vec<crate::kind::Surface>)>>,
    /// `(parameter, scale, power)`: see [`Continuation::tied`].
    pub(super) tied: Vec<(usize, f64, f64)>,
    /// Orbits found beyond a grazing that does not continue into them:
    /// each starts a branch of its own.
    pub(super) restarts: Vec<Point>,
}

impl Walker {
    /// The scene at parameter value `p` (the last few are kept: a
    /// parameter such as the gap rebuilds the model).
    pub(super) fn scene_at(&self, p: f64) -> Result<Component, String> {
        let mut cache = self.scenes.borrow_mut();
        if let Some((_, scene)) = cache.iter().find(|(v, _)| v.to_bits() == p.to_bits()) {
            return Ok(scene.clone());
        }
        let mut scene = self.base.clone();
        scene.set_many(std::iter::once((self.param, p)).chain(self.tied.iter().map(|&(i, scale, power)| (i, scale * p.powf(power)))));
        scene.validate().map_err(|e| format!("{} = {p}: {e}", self.base.parameters()[self.param].name))?;
        if cache.len() >= 8 {
            cache.remove(0);
        }
        cache.push((p, scene.clone()));
        Ok(scene)
    }

    pub(super) fn forcing_period(&self, scene: &Component) -> f64 {
        2.0 * PI / scene.get(self.forcing)
    }

    pub(super) fn name(&self) -> &str {
        &self.base.parameters()[self.param].name
    }

    /// The orbit found from a simulated transient at `start` (or from the
    /// given start state, for the first start).
    pub(super) fn first_orbit(&mut self, start: f64, settings: &Continuation, first: bool) -> Result<Point, String> {
        let at_start = self.scene_at(start)?;
        let forcing_period = self.forcing_period(&at_start);
        let (guess, periods) = match (&settings.start_state, first) {
            (Some(x), true) => (x.clone(), 1),
            _ => self.settle(&at_start, forcing_period, settings.transient, settings.max_period)?,
        };
        let shooting = Shooting { tolerance: settings.tolerance, max_iterations: 40 };
        let orbit = shoot(&at_start, self.t0, periods as f64 * forcing_period, &guess, shooting)
            .map_err(|e| format!("the first orbit ({periods} forcing periods): {e}"))?;
        let orbit = minimal_period(&at_start, orbit, forcing_period, shooting)?;
        self.point(start, orbit)
    }

    /// The state after the transient and its period (the smallest number
    /// of forcing periods after which the section repeats to 1e-6).
    pub(super) fn settle(&self, scene: &Component, forcing_period: f64, transient: usize, max_period: usize) -> Result<(DVector<f64>, usize), String> {
        let mut run = scene.start(self.t0, &vec![0.0; scene.inputs().len()])?;
        advance_by_periods(run.as_mut(), self.t0 + transient as f64 * forcing_period, forcing_period)?;
        // A scene without an exact flow is refused before (shooting::check_flow).
        let x = run.flow().ok_or("the scene's kind has no exact flow")?.state();
        let mut copy = run.clone();
        let mut best = (f64::INFINITY, 1);
        for m in 1..=max_period {
            copy.advance_to(self.t0 + (transient + m) as f64 * forcing_period).map_err(|e| e.to_string())?;
            let y = copy.flow().expect("the same kind").state();
            let distance = (&y - &x).amax() / x.amax().max(1e-300);
            if distance < 1e-6 {
                return Ok((x, m));
            }
            if distance < best.0 {
                best = (distance, m);
            }
        }
        Ok((x, best.1))
    }

    pub(super) fn evaluate(&mut self, x: &DVector<f64>, p: f64, periods: usize) -> Result<Evaluation, String> {
        let scene = self.scene_at(p)?;
        let period = periods as f64 * self.forcing_period(&scene);
        let (end, monodromy, impacts) = map(&scene, self.t0, period, x)?;
        // Central differences, one-sided where a side changes the impact
        // sequence (near grazing) or leaves the parameter's range.
        let h = 1e-7 * p.abs().max(self.range.1 - self.range.0);
        let (up, down) = (p + h, p - h);
        let image = |q: f64| -> Result<(DVector<f64>, usize), String> {
            let s = self.scene_at(q)?;
            let mut run = start_from(&s, self.t0, x)?;
            run.set_event_recording(true);
            run.drain_events();
            advance_by_periods(run.as_mut(), self.t0 + periods as f64 * self.forcing_period(&s), self.forcing_period(&s))?;
            let impacts = run.drain_events().iter().filter(|e| e.speed.is_some()).count();
            Ok((run.flow().expect("a kind with an exact flow").state(), impacts))
        };
        let by_param = match (image(up), image(down)) {
            (Ok((a, ia)), Ok((b, ib))) if ia == impacts && ib == impacts => (a - b) / (up - down),
            (Ok((a, ia)), _) if ia == impacts => (a - &end) / (up - p),
            (_, Ok((b, ib))) if ib == impacts => (&end - b) / (p - down),
            (Ok((a, _)), Ok((b, _))) => (a - b) / (up - down),
            (Ok((a, _)), Err(_)) => (a - &end) / (up - p),
            (Err(_), Ok((b, _))) => (&end - b) / (p - down),
            (Err(e), Err(_)) => return Err(e),
        };
        self.evaluations += 3;
        Ok(Evaluation { residual: end - x, monodromy, by_param, impacts, period })
    }

    /// `[M - I, G_p]` with the columns scaled to the scaled coordinates.
    pub(super) fn jacobian(&self, monodromy: &DMatrix<f64>, by_param: &DVector<f64>) -> DMatrix<f64> {
        let n = by_param.len();
        let mut j = DMatrix::zeros(n, n + 1);
        j.view_mut((0, 0), (n, n)).copy_from(&((monodromy - DMatrix::identity(n, n)) / self.weight_x));
        j.set_column(n, &(by_param / self.weight_p));
        j
    }

    pub(super) fn scaled(&self, x: &DVector<f64>, p: f64) -> DVector<f64> {
        let n = x.len();
        let mut u = DVector::zeros(n + 1);
        u.rows_mut(0, n).copy_from(&(x * self.weight_x));
        u[n] = p * self.weight_p;
        u
    }

    /// The distance between two points in the scaled coordinates.
    pub(super) fn distance(&self, a: &Point, b: &Point) -> f64 {
        (self.scaled(&a.orbit.state, a.param) - self.scaled(&b.orbit.state, b.param)).norm()
    }

    pub(super) fn unscaled(&self, u: &DVector<f64>) -> (DVector<f64>, f64) {
        let n = u.len() - 1;
        (u.rows(0, n) / self.weight_x, u[n] / self.weight_p)
    }

    /// The unit tangent (scaled) at a point, oriented along `previous`.
    pub(super) fn tangent(&mut self, point: &Point, periods: usize, previous: &DVector<f64>) -> Result<DVector<f64>, String> {
        let e = self.evaluate(&point.orbit.state, point.param, periods)?;
        self.tangent_from(&e, previous)
    }

    pub(super) fn tangent_from(&self, e: &Evaluation, previous: &DVector<f64>) -> Result<DVector<f64>, String> {
        let j = self.jacobian(&e.monodromy, &e.by_param);
        let n = j.nrows();
        let mut a = DMatrix::zeros(n + 1, n + 1);
        a.view_mut((0, 0), (n, n + 1)).copy_from(&j);
        a.row_mut(n).copy_from(&previous.transpose());
        let mut rhs = DVector::zeros(n + 1);
        rhs[n] = 1.0;
        let t = a.lu().solve(&rhs).ok_or("the tangent: the extended Jacobian is singular")?;
        let t = t.normalize();
        Ok(if t.dot(previous) < 0.0 { -t } else { t })
    }

    /// `G` alone (one period of the flow).
    pub(super) fn residual(&mut self, x: &DVector<f64>, p: f64, periods: usize) -> Result<DVector<f64>, String> {
        let scene = self.scene_at(p)?;
        let mut run = start_from(&scene, self.t0, x)?;
        advance_by_periods(run.as_mut(), self.t0 + periods as f64 * self.forcing_period(&scene), self.forcing_period(&scene))?;
        self.evaluations += 1;
        Ok(run.flow().expect("a kind with an exact flow").state() - x)
    }

    /// Newton's matrix: the scaled Jacobian and the hyperplane's normal.
    pub(super) fn newton_matrix(
        &self,
        monodromy: &DMatrix<f64>,
        by_param: &DVector<f64>,
        normal: &DVector<f64>,
    ) -> nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn> {
        let j = self.jacobian(monodromy, by_param);
        let n = j.nrows();
        let mut a = DMatrix::zeros(n + 1, n + 1);
        a.view_mut((0, 0), (n, n + 1)).copy_from(&j);
        a.row_mut(n).copy_from(&normal.transpose());
        a.lu()
    }

    /// Newton from the predictor `u_pred` (scaled) within the hyperplane
    /// normal to `normal`: the orbit, its evaluation, and the iterations.
    /// A chord method: Newton's matrix is taken from `hint` (a nearby
    /// point's evaluation) and recomputed only where the iterates stop
    /// converging fast, then once at the end for the orbit's monodromy.
    pub(super) fn correct(
        &mut self,
        u_pred: &DVector<f64>,
        normal: &DVector<f64>,
        periods: usize,
        hint: Option<&Point>,
    ) -> Result<(Point, Evaluation, usize), String> {
        let (mut x, mut p) = self.unscaled(u_pred);
        let n = x.len();
        let mut residuals: Vec<f64> = Vec::new();
        let mut matrix = hint.filter(|h| h.periods() == periods).map(|h| self.newton_matrix(&h.orbit.monodromy, &h.param_derivative, normal));
        // Whether the matrix was computed at an iterate of this correction.
        let mut own = false;
        // The last iterate whose residual fell, and the step from it.
        let mut from: Option<(DVector<f64>, f64, DVector<f64>)> = None;
        let mut fraction = 1.0;
        for _ in 0..20 {
            let full = if matrix.is_none() { Some(self.evaluate(&x, p, periods)?) } else { None };
            let residual = match &full {
                Some(e) => e.residual.clone(),
                None => self.residual(&x, p, periods)?,
            };
            let size = residual.amax() / x.amax().max(1e-300);
            // Converged, or stalled at the rounding floor of a sensitive
            // orbit (large multipliers amplify the flow's rounding).
            let k = residuals.len();
            let floor = own && k > 2 && size <= 100.0 * self.tolerance && size > 0.5 * residuals[k - 1];
            if size <= self.tolerance || floor {
                residuals.push(size);
                let e = match full {
                    Some(e) => e,
                    None => self.evaluate(&x, p, periods)?,
                };
                let scene = self.scene_at(p)?;
                let orbit = Orbit::new(self.t0, e.period, x.clone(), e.monodromy.clone(), e.impacts, residuals);
                let profile = profile(&scene, self.t0, e.period, periods, &x)?;
                let forcing_period = self.forcing_period(&scene);
                let iterations = orbit.residuals.len() - 1;
                let param_derivative = e.by_param.clone();
                return Ok((Point { param: p, forcing_period, orbit, profile, param_derivative }, e, iterations));
            }
            if let Some(e) = &full {
                matrix = Some(self.newton_matrix(&e.monodromy, &e.by_param, normal));
                own = true;
            }
            let previous = residuals.last().copied();
            if let (Some((x0, p0, step)), Some(last)) = (&from, previous) {
                if size >= last || size.is_nan() {
                    if !own {
                        // A borrowed matrix that does not converge: Newton's
                        // own at the last good iterate.
                        (x, p) = (x0.clone(), *p0);
                        matrix = None;
                        from = None;
                        residuals.pop();
                        continue;
                    }
                    // Damped where the map is not smooth (near grazing the
                    // impacting side's map has a square-root singularity).
                    if fraction > 1.0 / 64.0 {
                        fraction *= 0.5;
                        x = x0 + step.rows(0, n) * (fraction / self.weight_x);
                        p = p0 + step[n] * fraction / self.weight_p;
                        continue;
                    }
                }
            }
            residuals.push(size);
            let k = k + 1;
            if k > 12 || k > 3 && size > 0.5 * residuals[k - 2] {
                break;
            }
            if k > 1 && size > 0.1 * residuals[k - 2] && full.is_none() {
                // Slow: a new matrix here.
                matrix = None;
                residuals.pop();
                continue;
            }
            let mut rhs = DVector::zeros(n + 1);
            rhs.rows_mut(0, n).copy_from(&(-&residual));
            rhs[n] = -normal.dot(&(self.scaled(&x, p) - u_pred));
            let step = matrix.as_ref().expect("set above").solve(&rhs).ok_or("Newton's matrix is singular")?;
            fraction = 1.0;
            let (x0, p0) = (x.clone(), p);
            x += step.rows(0, n) / self.weight_x;
            p += step[n] / self.weight_p;
            from = Some((x0, p0, step));
        }
        let shown: Vec<String> = residuals.iter().map(|r| format!("{r:.1e}")).collect();
        Err(format!("Newton did not converge near {} = {p} (residuals {})", self.name(), shown.join(", ")))
    }

    pub(super) fn point(&mut self, p: f64, orbit: Orbit) -> Result<Point, String> {
        let scene = self.scene_at(p)?;
        let forcing_period = self.forcing_period(&scene);
        let periods = (orbit.period / forcing_period).round() as usize;
        let profile = profile(&scene, self.t0, orbit.period, periods, &orbit.state)?;
        let param_derivative = self.evaluate(&orbit.state, p, periods)?.by_param;
        Ok(Point { param: p, forcing_period, orbit, profile, param_derivative })
    }

    /// Whether the orbit through a point repeats after `periods` forcing
    /// periods (to 1e-6 of its size).
    pub(super) fn has_period(&mut self, point: &Point, periods: usize) -> bool {
        periods >= 1
            && point.periods() % periods == 0
            && self.residual(&point.orbit.state, point.param, periods).is_ok_and(|r| r.amax() <= 1e-6 * point.orbit.state.amax())
    }

    /// The orbit at parameter `p` by Newton in the state alone.
    pub(super) fn at_parameter(&mut self, p: f64, periods: usize, guess: &DVector<f64>) -> Result<Point, String> {
        // The corrector (damped) in the hyperplane of fixed parameter.
        let u = self.scaled(guess, p);
        let mut normal = DVector::zeros(u.len());
        normal[u.len() - 1] = 1.0;
        self.correct(&u, &normal, periods, None).map(|(point, _, _)| point)
    }

    /// Onto the branch of twice the period from a period doubling at
    /// `at`: Newton within the hyperplane normal to the critical
    /// eigenvector, a step along it.
    pub(super) fn switch(&mut self, at: &Point, periods: usize) -> Result<(Point, DVector<f64>), String> {
        let n = at.orbit.state.len();
        let shifted = &at.orbit.monodromy + DMatrix::identity(n, n);
        let svd = shifted.svd(false, true);
        let vt = svd.v_t.ok_or("the critical eigenvector")?;
        let smallest = (0..n).min_by(|&i, &j| svd.singular_values[i].total_cmp(&svd.singular_values[j])).ok_or("an empty state")?;
        let mut v = DVector::zeros(n + 1);
        v.rows_mut(0, n).copy_from(&vt.row(smallest).transpose());
        let u_pred = self.scaled(&at.orbit.state, at.param) + &v * self.ds_max;
        let (point, e, _) = self.correct(&u_pred, &v, periods, None)?;
        if (&point.orbit.state - &at.orbit.state).amax() * self.weight_x < 0.1 * self.ds_max {
            return Err("Newton returned to the period-1 orbit".into());
        }
        let tangent = self.tangent_from(&e, &v)?;
        Ok((point, tangent))
    }
}

/// The state linearly interpolated between two points at parameter `p`.
pub(super) fn interpolate(a: &Point, b: &Point, p: f64) -> DVector<f64> {
    let s = if b.param == a.param { 0.0 } else { ((p - a.param) / (b.param - a.param)).clamp(0.0, 1.0) };
    &a.orbit.state * (1.0 - s) + &b.orbit.state * s
}
