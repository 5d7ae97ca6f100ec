//! Pseudo-arclength continuation of periodic orbits in one scene
//! parameter, and the special points on the way.
//!
//! An orbit of period `m T` (T the forcing period) is a zero of `G(x, p) =
//! Phi(x; p) - x`, `Phi` the stroboscopic map over `m T` at phase `t0`.
//! Its Jacobian is `[M - I, G_p]`: `M` the exact monodromy matrix, `G_p`
//! by central differences in `p` (a parameter such as the gap rebuilds the
//! model; a forcing frequency also changes the period). Steps are taken in
//! scaled coordinates (the state by its size at the start, the parameter
//! by the range's width): a tangent predictor, then Newton on `G = 0`
//! within the hyperplane normal to the tangent, so a branch goes round its
//! folds. The map is continuous where the impact sequence changes
//! (grazing, a chatter ending in a stick), so a branch continues across it.
//!
//! Special points, detected between consecutive points and located on the
//! branch by regula falsi (Illinois) in the arclength:
//!
//! | type | test function |
//! |---|---|
//! | SN (fold) | the tangent's parameter component changes sign (`det(M - I)` located) |
//! | BP | `det(M - I)` changes sign without a fold |
//! | PD | `det(M + I)` changes sign; the doubled branch is followed from there |
//! | NS | a complex pair of multipliers crosses the unit circle (`|mu| - 1`) |
//! | GR | the impacts per period change: the closest smooth approach to a stop reaches zero (`gap`; `-v^2 / 2 gap''` on the side with the new slow impact) |
//! | ST | the sticks per period change (bisection: a threshold decision) |
//! | EP | where a branch ends, and why |
//!
//! Where the impact sequence changes, the multipliers jump (the saltation
//! matrix of an impact at speed `v` grows as `1/v`): a stability change
//! there is reported on the GR or ST point, not as a smooth bifurcation.

use std::f64::consts::PI;

use nalgebra::{DMatrix, DVector};

use super::profile::{profile, Profile};
use super::shooting::{map, shoot, Orbit, Shooting};
use crate::component::Component;

/// What to continue, and how far.
#[derive(Clone, Debug)]
pub struct Continuation {
    /// The parameter, by its FMU name.
    pub param: String,
    /// The range the branches stay in.
    pub from: f64,
    pub to: f64,
    /// Where orbits are found to start branches from (default: `from`);
    /// an orbit already on a branch starts none.
    pub starts: Vec<f64>,
    /// A start state `[q; q']` at `t0` for the first start (default: the
    /// state after `transient` forcing periods from the scene's initial
    /// state).
    pub start_state: Option<DVector<f64>>,
    /// The longest step is `1 / points` of the scaled arclength (the
    /// range's width is 1): about this many points on a branch across
    /// the range.
    pub points: usize,
    /// Forcing periods simulated before the first orbit is sought.
    pub transient: usize,
    /// The longest period, in forcing periods, sought at the start and
    /// reached by period doubling.
    pub max_period: usize,
    /// At most this many branches (the first, and those switched onto).
    pub max_branches: usize,
    /// The phase of the stroboscopic section.
    pub t0: f64,
    /// The forcing frequency's parameter (default: the first load's).
    pub forcing: Option<String>,
    /// Newton's tolerance on `|G| / |x|`.
    pub tolerance: f64,
    /// Parameters that follow the continued one as power laws: `(name,
    /// scale, power)` sets `name = scale * p^power` at every point (a base
    /// excitation of fixed displacement `Y` has the acceleration amplitude
    /// `-Y omega^2`).
    pub tied: Vec<(String, f64, f64)>,
}

impl Continuation {
    pub fn new(param: &str, from: f64, to: f64) -> Continuation {
        Continuation {
            param: param.into(),
            from,
            to,
            starts: Vec::new(),
            start_state: None,
            points: 200,
            transient: 200,
            max_period: 8,
            max_branches: 8,
            t0: 0.0,
            forcing: None,
            tolerance: 1e-10,
            tied: Vec::new(),
        }
    }
}

/// One continued orbit.
#[derive(Clone, Debug)]
pub struct Point {
    pub param: f64,
    /// The forcing period there.
    pub forcing_period: f64,
    pub orbit: Orbit,
    pub profile: Profile,
    /// How the orbit's image moves with the parameter (`d Phi / d p`, by
    /// central differences).
    pub param_derivative: DVector<f64>,
}

impl Point {
    /// Forcing periods per orbit period.
    pub fn periods(&self) -> usize {
        (self.orbit.period / self.forcing_period).round() as usize
    }
}

/// The points of one branch in arclength order.
#[derive(Clone, Debug)]
pub struct Branch {
    pub index: usize,
    /// The orbit's period in forcing periods.
    pub periods: usize,
    pub points: Vec<Point>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpecialKind {
    SaddleNode,
    BranchPoint,
    PeriodDoubling,
    NeimarkSacker,
    Grazing,
    Sticking,
    End,
}

impl SpecialKind {
    /// The code the special-points table uses.
    pub fn code(self) -> &'static str {
        match self {
            SpecialKind::SaddleNode => "SN",
            SpecialKind::BranchPoint => "BP",
            SpecialKind::PeriodDoubling => "PD",
            SpecialKind::NeimarkSacker => "NS",
            SpecialKind::Grazing => "GR",
            SpecialKind::Sticking => "ST",
            SpecialKind::End => "EP",
        }
    }
}

/// A special point on a branch.
#[derive(Clone, Debug)]
pub struct Special {
    pub kind: SpecialKind,
    pub branch: usize,
    pub point: Point,
    /// What happens there, in a sentence.
    pub note: String,
}

/// Every branch found and its special points.
#[derive(Clone, Debug)]
pub struct Diagram {
    pub param: String,
    pub branches: Vec<Branch>,
    pub special: Vec<Special>,
    /// Map evaluations (each one period of the flow).
    pub evaluations: usize,
}

/// The orbits of a scene over one parameter's range (module doc).
pub fn continue_orbits(scene: &Component, settings: &Continuation) -> Result<Diagram, String> {
    let param = parameter(scene, &settings.param)?;
    let forcing = match &settings.forcing {
        Some(name) => parameter(scene, name)?,
        None => scene
            .parameters()
            .iter()
            .position(|p| p.scene_path.starts_with("loads[") && p.scene_path.ends_with(".omega"))
            .ok_or("the scene has no harmonic load: give the forcing frequency's parameter")?,
    };
    let (lo, hi) = (settings.from.min(settings.to), settings.from.max(settings.to));
    if lo >= hi || !lo.is_finite() || !hi.is_finite() {
        return Err(format!("--param {}={}:{}: the range must have two different finite ends", settings.param, settings.from, settings.to));
    }
    let starts = if settings.starts.is_empty() { vec![settings.from] } else { settings.starts.clone() };
    if let Some(start) = starts.iter().find(|s| !(lo..=hi).contains(*s)) {
        return Err(format!("the start {start} lies outside the range {lo} .. {hi}"));
    }
    let mut walker = Walker {
        base: scene.clone(),
        param,
        forcing,
        t0: settings.t0,
        range: (lo, hi),
        ds_max: 1.0 / settings.points.max(2) as f64,
        weight_p: 1.0 / (hi - lo),
        weight_x: 1.0,
        tolerance: settings.tolerance,
        max_points: 10 * settings.points + 50,
        evaluations: 0,
        scenes: Default::default(),
        restarts: Vec::new(),
        tied: settings.tied.iter().map(|(name, scale, power)| parameter(scene, name).map(|i| (i, *scale, *power))).collect::<Result<_, _>>()?,
    };
    let mut diagram = Diagram { param: settings.param.clone(), branches: Vec::new(), special: Vec::new(), evaluations: 0 };
    // A branch both ways from each start; then each doubled branch.
    let mut queue: Vec<(usize, Point, DVector<f64>, bool)> = Vec::new();
    for (k, &start) in starts.iter().enumerate() {
        let at_start = walker.scene_at(start)?;
        let forcing_period = walker.forcing_period(&at_start);
        let (guess, periods) = match (&settings.start_state, k) {
            (Some(x), 0) => (x.clone(), 1),
            _ => walker.settle(&at_start, forcing_period, settings.transient, settings.max_period)?,
        };
        if k == 0 {
            walker.weight_x = 1.0 / guess.norm().max(1e-12);
        }
        let shooting = Shooting { tolerance: settings.tolerance, max_iterations: 40 };
        let orbit = shoot(&at_start, settings.t0, periods as f64 * forcing_period, &guess, shooting)
            .map_err(|e| format!("the first orbit at {} = {start} ({periods} forcing periods): {e}", settings.param))?;
        let first = walker.point(start, orbit)?;
        walker.restarts.insert(0, first);
        // This start's branch, then those its grazings restart.
        while let Some(first) = walker.restarts.pop() {
            if diagram.branches.len() >= settings.max_branches || diagram.branches.iter().any(|b| on_branch(&walker, b, &first)) {
                continue;
            }
            let index = diagram.branches.len();
            let periods = first.periods();
            let mut increasing = DVector::zeros(first.orbit.state.len() + 1);
            increasing[first.orbit.state.len()] = 1.0;
            let tangent = walker.tangent(&first, periods, &increasing)?;
            let mut others: Vec<&[Point]> = diagram.branches.iter().map(|b| b.points.as_slice()).collect();
            let mut forward = walker.walk(index, periods, first.clone(), tangent.clone(), false, &others, &mut diagram.special, &mut queue)?;
            others.push(&forward);
            let backward = walker.walk(index, periods, first, -tangent, false, &others, &mut diagram.special, &mut queue)?;
            let mut points: Vec<Point> = backward.into_iter().skip(1).rev().collect();
            points.append(&mut forward);
            diagram.branches.push(Branch { index, periods, points });
        }
    }
    let mut next = 0;
    while next < queue.len() && diagram.branches.len() < settings.max_branches {
        let (_, from_point, direction, _) = queue[next].clone();
        next += 1;
        let periods = 2 * from_point.periods();
        if periods > settings.max_period {
            continue;
        }
        let index = diagram.branches.len();
        match walker.switch(&from_point, periods, &direction) {
            Ok((point, tangent)) => {
                let others: Vec<&[Point]> = diagram.branches.iter().map(|b| b.points.as_slice()).collect();
                let points = walker.walk(index, periods, point, tangent, true, &others, &mut diagram.special, &mut queue)?;
                diagram.branches.push(Branch { index, periods, points });
            }
            Err(e) => diagram.special.push(Special {
                kind: SpecialKind::End,
                branch: index,
                point: from_point,
                note: format!("no switch onto the doubled branch: {e}"),
            }),
        }
    }
    diagram.evaluations = walker.evaluations;
    Ok(diagram)
}

/// Whether `point` lies on `branch`: the same period, and its state within
/// 1e-3 (scaled) of the state interpolated between two consecutive points
/// around its parameter value.
fn on_branch(walker: &Walker, branch: &Branch, point: &Point) -> bool {
    on_points(walker, &branch.points, point)
}

fn on_points(walker: &Walker, points: &[Point], point: &Point) -> bool {
    points.windows(2).any(|w| {
        let (a, b) = (&w[0], &w[1]);
        a.periods() == point.periods()
            && (a.param.min(b.param)..=a.param.max(b.param)).contains(&point.param)
            && (interpolate(a, b, point.param) - &point.orbit.state).norm() * walker.weight_x < 1e-3
    })
}

/// The index of the parameter named `name`, or the list of names.
fn parameter(scene: &Component, name: &str) -> Result<usize, String> {
    scene.parameters().iter().position(|p| p.name == name).ok_or_else(|| {
        let names: Vec<&str> = scene.parameters().iter().map(|p| p.name.as_str()).collect();
        format!("the scene has no parameter '{name}' (it has {})", names.join(", "))
    })
}

/// `G`, its Jacobian and the impacts along the way at `(x, p)`.
struct Evaluation {
    residual: DVector<f64>,
    monodromy: DMatrix<f64>,
    by_param: DVector<f64>,
    impacts: usize,
    period: f64,
}

/// The continuation's state: the problem and its scaling.
struct Walker {
    base: Component,
    param: usize,
    forcing: usize,
    t0: f64,
    range: (f64, f64),
    ds_max: f64,
    weight_p: f64,
    weight_x: f64,
    tolerance: f64,
    max_points: usize,
    evaluations: usize,
    scenes: std::sync::Mutex<Vec<(f64, Component)>>,
    /// `(parameter, scale, power)`: see [`Continuation::tied`].
    tied: Vec<(usize, f64, f64)>,
    /// Orbits found beyond a grazing that does not continue into them:
    /// each starts a branch of its own.
    restarts: Vec<Point>,
}

/// A special point located, and what happens there.
type Located = (Point, String);

impl Walker {
    /// The scene at parameter value `p` (the last few are kept: a
    /// parameter such as the gap rebuilds the model).
    fn scene_at(&self, p: f64) -> Result<Component, String> {
        let mut cache = self.scenes.lock().expect("not poisoned");
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

    fn forcing_period(&self, scene: &Component) -> f64 {
        2.0 * PI / scene.get(self.forcing)
    }

    fn name(&self) -> &str {
        &self.base.parameters()[self.param].name
    }

    /// The state after the transient and its period (the smallest number
    /// of forcing periods after which the section repeats to 1e-6).
    fn settle(&self, scene: &Component, forcing_period: f64, transient: usize, max_period: usize) -> Result<(DVector<f64>, usize), String> {
        let mut run = scene.start(self.t0, &vec![0.0; scene.inputs().len()])?;
        run.advance_to(self.t0 + transient as f64 * forcing_period).map_err(|e| e.to_string())?;
        let flow = run.flow().ok_or("the scene's kind has no exact flow (an integrated or mode-transfer phase)")?;
        let x = flow.state();
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

    fn evaluate(&mut self, x: &DVector<f64>, p: f64, periods: usize) -> Result<Evaluation, String> {
        let scene = self.scene_at(p)?;
        let period = periods as f64 * self.forcing_period(&scene);
        let (end, monodromy, impacts) = map(&scene, self.t0, period, x)?;
        // Central differences, one-sided where a side changes the impact
        // sequence (near grazing) or leaves the parameter's range.
        let h = 1e-7 * p.abs().max(self.range.1 - self.range.0);
        let (up, down) = (p + h, p - h);
        let image = |q: f64| -> Result<(DVector<f64>, usize), String> {
            let s = self.scene_at(q)?;
            let mut run = super::shooting::start_from(&s, self.t0, x)?;
            run.set_event_recording(true);
            run.drain_events();
            run.advance_to(self.t0 + periods as f64 * self.forcing_period(&s)).map_err(|e| e.to_string())?;
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
    fn jacobian(&self, monodromy: &DMatrix<f64>, by_param: &DVector<f64>) -> DMatrix<f64> {
        let n = by_param.len();
        let mut j = DMatrix::zeros(n, n + 1);
        j.view_mut((0, 0), (n, n)).copy_from(&((monodromy - DMatrix::identity(n, n)) / self.weight_x));
        j.set_column(n, &(by_param / self.weight_p));
        j
    }

    fn scaled(&self, x: &DVector<f64>, p: f64) -> DVector<f64> {
        let n = x.len();
        let mut u = DVector::zeros(n + 1);
        u.rows_mut(0, n).copy_from(&(x * self.weight_x));
        u[n] = p * self.weight_p;
        u
    }

    fn unscaled(&self, u: &DVector<f64>) -> (DVector<f64>, f64) {
        let n = u.len() - 1;
        (u.rows(0, n) / self.weight_x, u[n] / self.weight_p)
    }

    /// The unit tangent (scaled) at a point, oriented along `previous`.
    fn tangent(&mut self, point: &Point, periods: usize, previous: &DVector<f64>) -> Result<DVector<f64>, String> {
        let e = self.evaluate(&point.orbit.state, point.param, periods)?;
        self.tangent_from(&e, previous)
    }

    fn tangent_from(&self, e: &Evaluation, previous: &DVector<f64>) -> Result<DVector<f64>, String> {
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
    fn residual(&mut self, x: &DVector<f64>, p: f64, periods: usize) -> Result<DVector<f64>, String> {
        let scene = self.scene_at(p)?;
        let mut run = super::shooting::start_from(&scene, self.t0, x)?;
        run.advance_to(self.t0 + periods as f64 * self.forcing_period(&scene)).map_err(|e| e.to_string())?;
        self.evaluations += 1;
        Ok(run.flow().expect("a kind with an exact flow").state() - x)
    }

    /// Newton's matrix: the scaled Jacobian and the hyperplane's normal.
    fn newton_matrix(&self, monodromy: &DMatrix<f64>, by_param: &DVector<f64>, normal: &DVector<f64>) -> nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn> {
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
    fn correct(&mut self, u_pred: &DVector<f64>, normal: &DVector<f64>, periods: usize, hint: Option<&Point>) -> Result<(Point, Evaluation, usize), String> {
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
                    if fraction > 1.0 / 8.0 {
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

    fn point(&mut self, p: f64, orbit: Orbit) -> Result<Point, String> {
        let scene = self.scene_at(p)?;
        let forcing_period = self.forcing_period(&scene);
        let periods = (orbit.period / forcing_period).round() as usize;
        let profile = profile(&scene, self.t0, orbit.period, periods, &orbit.state)?;
        let param_derivative = self.evaluate(&orbit.state, p, periods)?.by_param;
        Ok(Point { param: p, forcing_period, orbit, profile, param_derivative })
    }

    /// Follows a branch from `first` along `tangent` until it leaves the
    /// range or cannot go on; special points go to `special`, period
    /// doublings to `queue` as well. Returns the points in walking order.
    #[allow(clippy::too_many_arguments)]
    fn walk(
        &mut self,
        branch: usize,
        periods: usize,
        first: Point,
        tangent: DVector<f64>,
        switched: bool,
        others: &[&[Point]],
        special: &mut Vec<Special>,
        queue: &mut Vec<(usize, Point, DVector<f64>, bool)>,
    ) -> Result<Vec<Point>, String> {
        let mut points = vec![first];
        let mut tangent = tangent;
        let mut ds = self.ds_max;
        let ds_min = self.ds_max * 1e-6;
        let mut tried_crossing = false;
        let mut small_steps = 0;
        let (lo, hi) = self.range;
        let end = |why: String, at: &Point, special: &mut Vec<Special>| {
            special.push(Special { kind: SpecialKind::End, branch, point: at.clone(), note: why });
        };
        loop {
            if points.len() >= self.max_points {
                end(format!("{} points: the limit", points.len()), points.last().expect("a point"), special);
                break;
            }
            let last = points.last().expect("a point").clone();
            let u_pred = self.scaled(&last.orbit.state, last.param) + &tangent * ds;
            let attempt = self.correct(&u_pred, &tangent, periods, Some(&last)).and_then(|(point, e, iterations)| {
                let next_tangent = self.tangent_from(&e, &tangent)?;
                Ok((point, next_tangent, iterations))
            });
            // Newton cannot cross a grazing well (the map's square root):
            // cross it directly when a step fails with the grazing within
            // reach, or when the steps have collapsed.
            let grazing_near = !tried_crossing
                && points.len() >= 2
                && grazing_ahead(&points[points.len() - 2], &last, (self.scaled(&last.orbit.state, last.param) - self.scaled(&points[points.len() - 2].orbit.state, points[points.len() - 2].param)).norm())
                    .is_some_and(|s| s < 2.0 * ds);
            let stalled = (ds < self.ds_max * 1e-2 || grazing_near) && !tried_crossing;
            let (point, next_tangent, iterations) = match attempt {
                Ok(found) if found.1.dot(&tangent) > 0.9 || ds <= ds_min => found,
                Ok(_) | Err(_) if ds > ds_min && !stalled => {
                    ds *= 0.5;
                    continue;
                }
                failed => {
                    let e = failed.err().unwrap_or_else(|| "the branch turns too fast".into());
                    tried_crossing = true;
                    // Newton fails at a grazing (the map's square root):
                    // locate it, then restart on the far side.
                    let previous = points.len().checked_sub(2).map(|i| points[i].clone());
                    match self.cross_grazing(previous.as_ref(), &last, &tangent, periods) {
                        Ok((grazing, beyond, next_tangent)) => {
                            let local = continues(&grazing, &beyond);
                            let how = if local {
                                format!("continued beyond it from {} = {}", self.name(), beyond.param)
                            } else {
                                format!("no orbit near it beyond; a far one at {} = {} starts another branch", self.name(), beyond.param)
                            };
                            let note = format!(
                                "impacts per orbit {} -> {}{}; {}; {how}",
                                last.profile.impacts,
                                beyond.profile.impacts,
                                stability_change(&last, &beyond),
                                grazing_measure(&grazing),
                            );
                            special.push(Special { kind: SpecialKind::Grazing, branch, point: grazing.clone(), note });
                            if grazing.profile.sticks != beyond.profile.sticks {
                                let note = format!("sticks per orbit {} -> {} at the grazing", grazing.profile.sticks, beyond.profile.sticks);
                                special.push(Special { kind: SpecialKind::Sticking, branch, point: grazing.clone(), note });
                            }
                            points.push(grazing);
                            if !local {
                                self.restarts.push(beyond);
                                end("a grazing without a nearby orbit beyond it".into(), points.last().expect("a point"), special);
                                break;
                            }
                            points.push(beyond);
                            tangent = next_tangent;
                            ds = self.ds_max * 0.1;
                            tried_crossing = false;
                            continue;
                        }
                        Err(_) if ds > ds_min => {
                            ds *= 0.5;
                            continue;
                        }
                        Err(why) => {
                            end(format!("the branch cannot be followed past {} = {}: {e} ({why})", self.name(), last.param), &last, special);
                            break;
                        }
                    }
                }
            };
            if !(lo..=hi).contains(&point.param) {
                // The end of the range: the orbit at the bound itself.
                let bound = if point.param > hi { hi } else { lo };
                if last.param == bound {
                    end(format!("the end of the range, {} = {bound}", self.name()), &last, special);
                    break;
                }
                let guess = interpolate(&last, &point, bound);
                match self.at_parameter(bound, periods, &guess) {
                    Ok(at) => {
                        self.detect(branch, periods, (&last, &tangent), (&at, &tangent), switched && points.len() == 1, special, queue);
                        points.push(at.clone());
                        end(format!("the end of the range, {} = {bound}", self.name()), &at, special);
                    }
                    Err(e) => end(format!("the end of the range, {} = {bound}: {e}", self.name()), &last, special),
                }
                break;
            }
            if periods > 1 && self.has_period(&point, periods / 2) {
                end(format!("the orbit has period {} there: the branch returns to the one it doubled", periods / 2), &last, special);
                break;
            }
            self.detect(branch, periods, (&last, &tangent), (&point, &next_tangent), switched && points.len() == 1, special, queue);
            // A closed branch (an isola, or a doubled branch that returns
            // to where it was born) ends where it meets itself again.
            let u = self.scaled(&point.orbit.state, point.param);
            let closed = points.len() > 10
                && points[..points.len() - 10].iter().any(|q| q.profile.impacts == point.profile.impacts && (self.scaled(&q.orbit.state, q.param) - &u).norm() < 0.5 * ds);
            // A branch that runs onto one found before ends where it joins.
            let joins = points.len() > 2 && others.iter().any(|o| on_points(self, o, &point));
            points.push(point);
            if closed {
                end("the branch closes on itself".into(), points.last().expect("a point"), special);
                break;
            }
            if joins {
                end("the branch joins one found before".into(), points.last().expect("a point"), special);
                break;
            }
            // A branch whose steps stay tiny (its orbits' sensitivity grows
            // without bound) ends there.
            small_steps = if ds < 1e-3 * self.ds_max { small_steps + 1 } else { 0 };
            if small_steps > 20 {
                let at = points.last().expect("a point");
                let largest = at.orbit.multipliers.iter().map(|z| z.norm()).fold(0.0, f64::max);
                end(format!("the steps stall below 1e-3 of the longest (largest multiplier {largest:.3e})"), at, special);
                break;
            }
            tangent = next_tangent;
            tried_crossing &= ds < 0.1 * self.ds_max;
            ds = match iterations {
                0..=4 => (ds * 1.5).min(self.ds_max),
                5..=7 => ds,
                _ => ds * 0.7,
            };
        }
        Ok(points)
    }

    /// Where Newton stalls because the closest smooth approach to a stop
    /// closes (`last`, after `previous`, walking along `tangent`): the
    /// grazing orbit, located by the secant method on that approach's gap
    /// from the side where it is smooth, and the first orbit beyond it (by
    /// Newton in the state at a parameter a little past it, from the
    /// grazing orbit or from a simulated transient), with its tangent.
    fn cross_grazing(&mut self, previous: Option<&Point>, last: &Point, tangent: &DVector<f64>, periods: usize) -> Result<(Point, Point, DVector<f64>), String> {
        let previous = previous.ok_or("no trend to extrapolate")?;
        // From the smooth side the closest approach's gap closes, linearly
        // in the parameter; from the impacting side the slowest impact's
        // speed does, as the square root of the parameter's distance, but
        // linearly in the arclength (the branch's tangent turns to the
        // state there).
        let impacts = last.profile.impacts;
        let gap = move |p: &Point| p.profile.closest.map(|c| c.gap).filter(|_| p.profile.impacts == impacts);
        let speed = move |p: &Point| p.profile.slowest_impact.filter(|_| p.profile.impacts == impacts);
        let closing = |f: &dyn Fn(&Point) -> Option<f64>| matches!((f(previous), f(last)), (Some(a), Some(b)) if b < a && b >= 0.0);
        let by_speed = !closing(&gap) && closing(&speed);
        let psi: &dyn Fn(&Point) -> Option<f64> = if closing(&gap) {
            &gap
        } else if by_speed {
            &speed
        } else {
            return Err("neither a smooth approach to a stop nor an impact's speed is closing".into());
        };
        let u_last = self.scaled(&last.orbit.state, last.param);
        let (mut s0, mut f0) = (-(self.scaled(&previous.orbit.state, previous.param) - &u_last).norm(), psi(previous).expect("checked"));
        let (mut s1, mut f1) = (0.0, psi(last).expect("checked"));
        let mut grazing = last.clone();
        let mut before = previous.clone();
        let scale = psi(previous).expect("checked");
        // The secant method, kept on this side: a trial past the grazing
        // (another impact sequence, or no orbit) bounds the next ones.
        let mut s_beyond = f64::INFINITY;
        for _ in 0..40 {
            if f1.abs() <= 1e-10 * scale || (s1 - s0).abs() <= 1e-15 || (s_beyond - s1).abs() <= 1e-5 * self.ds_max {
                break;
            }
            let mut s = s1 - f1 * (s1 - s0) / (f1 - f0);
            if !(s > s1 && s < s_beyond) {
                s = if s_beyond.is_finite() { 0.5 * (s1 + s_beyond) } else { s1 + 2.0 * (s1 - s0).abs() };
            }
            match self.correct(&(&u_last + tangent * s), tangent, periods, Some(last)) {
                Ok((p, _, _)) if psi(&p).is_some_and(|f| f >= 0.0) => {
                    let f = psi(&p).expect("checked");
                    (s0, f0, s1, f1) = (s1, f1, s, f);
                    before = std::mem::replace(&mut grazing, p);
                }
                _ => s_beyond = s,
            }
        }
        if by_speed && f1 > 1e-10 * scale {
            // The branch turns to the state as the impact's speed vanishes,
            // and the hyperplanes above stop meeting it: on to the zero of
            // the speed's square, linear in the parameter, at fixed values
            // of the parameter.
            grazing = self.refine_by_speed(&before, grazing, periods);
        }
        // Beyond: the orbit with the changed impact sequence nearest to the
        // grazing one, on either side of it (a grazing can also give birth
        // to orbits on the side it came from, which then fold), each side
        // at the nearest parameter value where Newton finds one.
        let sign = tangent[tangent.len() - 1].signum();
        let (lo, hi) = self.range;
        let mut why = String::from("no orbit found beyond it");
        let mut best: Option<(f64, Point, f64)> = None;
        for side in [sign, -sign] {
            'side: for fraction in [0.01, 0.1, 0.5] {
                let p = grazing.param + side * fraction * self.ds_max / self.weight_p;
                if !(lo..=hi).contains(&p) {
                    why = format!("the grazing at {} = {} is at the end of the range", self.name(), grazing.param);
                    break;
                }
                let scene = self.scene_at(p)?;
                let period = periods as f64 * self.forcing_period(&scene);
                let simulated = (|| -> Result<DVector<f64>, String> {
                    let mut run = super::shooting::start_from(&scene, self.t0, &grazing.orbit.state)?;
                    run.advance_to(self.t0 + 100.0 * period).map_err(|e| e.to_string())?;
                    Ok(run.flow().expect("a kind with an exact flow").state())
                })();
                for guess in [Ok(grazing.orbit.state.clone()), simulated] {
                    let Ok(guess) = guess else { continue };
                    match self.at_parameter(p, periods, &guess) {
                        Ok(beyond) if periods > 1 && self.has_period(&beyond, periods / 2) => {
                            why = format!("beyond it at {} = {p}, only an orbit of period {}", self.name(), periods / 2)
                        }
                        Ok(beyond) if beyond.profile.impacts != grazing.profile.impacts => {
                            let distance = (self.scaled(&beyond.orbit.state, beyond.param) - self.scaled(&grazing.orbit.state, grazing.param)).norm();
                            if best.as_ref().map_or(true, |b| distance < b.0) {
                                best = Some((distance, beyond, side));
                            }
                            break 'side;
                        }
                        Ok(_) => why = format!("Newton at {} = {p} returned to the orbit without the new impact", self.name()),
                        Err(e) => why = e,
                    }
                }
            }
        }
        let (_, beyond, side) = best.ok_or(why)?;
        let mut direction = DVector::zeros(tangent.len());
        direction[tangent.len() - 1] = side;
        let next_tangent = self.tangent(&beyond, periods, &direction)?;
        Ok((grazing, beyond, next_tangent))
    }

    /// The grazing approached from the impacting side (`a`, then `b`, on
    /// the branch, the same impacts): the secant method on the slowest
    /// impact's speed squared over the parameter, each orbit by Newton in
    /// the state alone; a value past the grazing bounds the next trials.
    fn refine_by_speed(&mut self, a: &Point, b: Point, periods: usize) -> Point {
        let impacts = b.profile.impacts;
        let square = |p: &Point| p.profile.slowest_impact.filter(|_| p.profile.impacts == impacts).map(|v| v * v);
        let (Some(fa), Some(fb)) = (square(a), square(&b)) else { return b };
        let (mut p0, mut f0, mut p1, mut f1) = (a.param, fa, b.param, fb);
        let mut x0 = a.orbit.state.clone();
        let direction = (p1 - p0).signum();
        let mut beyond = f64::NAN;
        let mut best = b;
        let scale = fa.max(fb);
        for _ in 0..40 {
            if f1 <= 1e-14 * scale || (beyond - p1).abs() <= 1e-13 * p1.abs().max(self.range.1 - self.range.0) || p1 == p0 {
                break;
            }
            let mut p = p1 - f1 * (p1 - p0) / (f1 - f0);
            let inside = |p: f64| (p - p1) * direction > 0.0 && (beyond.is_nan() || (beyond - p) * direction > 0.0);
            if !inside(p) {
                p = if beyond.is_nan() { p1 + 2.0 * (p1 - p0) } else { 0.5 * (p1 + beyond) };
            }
            // The state is smooth in the speed, not in the parameter: the
            // guess goes along the speed the secant line predicts.
            let (v0, v1) = (f0.sqrt(), f1.sqrt());
            let v = (f1 + (p - p1) * (f1 - f0) / (p1 - p0)).max(0.0).sqrt();
            let guess = if v1 != v0 { &best.orbit.state + (&best.orbit.state - &x0) * ((v - v1) / (v1 - v0)) } else { best.orbit.state.clone() };
            match self.at_parameter(p, periods, &guess) {
                Ok(point) if square(&point).is_some() => {
                    (p0, f0, p1, f1) = (p1, f1, p, square(&point).expect("checked"));
                    x0 = std::mem::replace(&mut best, point).orbit.state;
                }
                _ => beyond = p,
            }
        }
        best
    }

    /// Whether the orbit through a point repeats after `periods` forcing
    /// periods (to 1e-6 of its size).
    fn has_period(&mut self, point: &Point, periods: usize) -> bool {
        periods >= 1
            && point.periods() % periods == 0
            && self.residual(&point.orbit.state, point.param, periods).is_ok_and(|r| r.amax() <= 1e-6 * point.orbit.state.amax())
    }

    /// The orbit at parameter `p` by Newton in the state alone.
    fn at_parameter(&mut self, p: f64, periods: usize, guess: &DVector<f64>) -> Result<Point, String> {
        // The corrector (damped) in the hyperplane of fixed parameter.
        let u = self.scaled(guess, p);
        let mut normal = DVector::zeros(u.len());
        normal[u.len() - 1] = 1.0;
        self.correct(&u, &normal, periods, None).map(|(point, _, _)| point)
    }

    /// Special points between consecutive points `a` and `b` (module doc).
    #[allow(clippy::too_many_arguments)]
    fn detect(
        &mut self,
        branch: usize,
        periods: usize,
        (a, tangent_a): (&Point, &DVector<f64>),
        (b, tangent_b): (&Point, &DVector<f64>),
        skip_smooth: bool,
        special: &mut Vec<Special>,
        queue: &mut Vec<(usize, Point, DVector<f64>, bool)>,
    ) {
        let n = a.orbit.state.len();
        let mut found: Vec<(SpecialKind, Result<Located, String>)> = Vec::new();
        let sequence_changed = a.profile.impacts != b.profile.impacts || a.profile.sticks != b.profile.sticks;
        if a.profile.impacts != b.profile.impacts {
            let few = a.profile.impacts.min(b.profile.impacts);
            let reference = if a.profile.impacts == few { a } else { b };
            let curvature = reference.profile.closest.map_or(1.0, |c| c.curvature.max(f64::MIN_POSITIVE));
            let psi = move |p: &Point| -> Option<f64> {
                if p.profile.impacts == few {
                    p.profile.closest.map(|c| c.gap)
                } else if p.profile.impacts > few {
                    p.profile.slowest_impact.map(|v| -v * v / (2.0 * curvature))
                } else {
                    None
                }
            };
            let located = self.locate(a, b, tangent_a, periods, &psi, false);
            found.push((SpecialKind::Grazing, located.map(|p| {
                let note = format!("impacts per orbit {} -> {}{}; {}", a.profile.impacts, b.profile.impacts, stability_change(a, b), grazing_measure(&p));
                (p, note)
            })));
        }
        if a.profile.sticks != b.profile.sticks {
            let sticks_a = a.profile.sticks;
            let psi = move |p: &Point| -> Option<f64> { Some(if p.profile.sticks == sticks_a { 1.0 } else { -1.0 }) };
            let located = self.locate(a, b, tangent_a, periods, &psi, true);
            found.push((SpecialKind::Sticking, located.map(|p| {
                let note = format!("sticks per orbit {} -> {}{}", a.profile.sticks, b.profile.sticks, stability_change(a, b));
                (p, note)
            })));
        }
        if !sequence_changed && !skip_smooth {
            let det = |p: &Point, shift: f64| -> f64 { (&p.orbit.monodromy + DMatrix::identity(n, n) * shift).determinant() };
            let fold = tangent_a[n].signum() != tangent_b[n].signum();
            if det(a, -1.0).signum() != det(b, -1.0).signum() {
                let kind = if fold { SpecialKind::SaddleNode } else { SpecialKind::BranchPoint };
                let psi = move |p: &Point| Some(det(p, -1.0));
                let located = self.locate(a, b, tangent_a, periods, &psi, false);
                found.push((kind, located.map(|p| (p, format!("a multiplier through +1{}", stability_change(a, b))))));
            }
            if det(a, 1.0).signum() != det(b, 1.0).signum() {
                let psi = move |p: &Point| Some(det(p, 1.0));
                let located = self.locate(a, b, tangent_a, periods, &psi, false);
                if let Ok(p) = &located {
                    queue.push((branch, p.clone(), tangent_a.clone(), true));
                }
                found.push((SpecialKind::PeriodDoubling, located.map(|p| (p, format!("a multiplier through -1{}", stability_change(a, b))))));
            }
            let unstable_pairs = |p: &Point| p.orbit.multipliers.iter().filter(|z| z.im > 1e-9 * z.norm() && z.norm() > 1.0).count();
            if unstable_pairs(a) != unstable_pairs(b) && a.orbit.n_unstable.abs_diff(b.orbit.n_unstable) == 2 {
                let psi = |p: &Point| {
                    p.orbit.multipliers.iter().filter(|z| z.im > 1e-9 * z.norm()).map(|z| z.norm() - 1.0).min_by(|x, y| x.abs().total_cmp(&y.abs()))
                };
                let located = self.locate(a, b, tangent_a, periods, &psi, false);
                found.push((SpecialKind::NeimarkSacker, located.map(|p| {
                    let z = p.orbit.multipliers.iter().filter(|z| z.im > 0.0).min_by(|x, y| (x.norm() - 1.0).abs().total_cmp(&(y.norm() - 1.0).abs()));
                    let note = z.map_or(String::new(), |z| format!("a complex pair through the unit circle at angle {:.6} rad", z.arg()));
                    (p, note + &stability_change(a, b))
                })));
            }
        }
        for (kind, located) in found {
            let (point, note) = match located {
                Ok(found) => found,
                // Not located: the nearer of the two points, and why.
                Err(e) => (b.clone(), format!("between {} = {} and {}, not located: {e}", self.name(), a.param, b.param)),
            };
            special.push(Special { kind, branch, point, note });
        }
    }

    /// The zero of `psi` between the consecutive points `a` and `b` of a
    /// branch, by regula falsi (Illinois) on the arclength from `a`, each
    /// trial point corrected onto the branch; `bisect` for a step function.
    fn locate(&mut self, a: &Point, b: &Point, tangent_a: &DVector<f64>, periods: usize, psi: &dyn Fn(&Point) -> Option<f64>, bisect: bool) -> Result<Point, String> {
        let ua = self.scaled(&a.orbit.state, a.param);
        let ub = self.scaled(&b.orbit.state, b.param);
        let span = (&ub - &ua).dot(tangent_a);
        let (mut s_lo, mut s_hi) = (0.0, span);
        let (mut f_lo, mut f_hi) = (psi(a).ok_or("the test function is not defined at the first point")?, psi(b).ok_or("the test function is not defined at the second point")?);
        let (mut best_lo, mut best_hi) = (a.clone(), b.clone());
        let scale = a.param.abs().max(self.range.1 - self.range.0);
        let mut side = 0;
        for _ in 0..60 {
            if (best_hi.param - best_lo.param).abs() <= if bisect { 1e-8 } else { 1e-10 } * scale || (s_hi - s_lo).abs() <= 1e-14 {
                break;
            }
            let mut s = if bisect { 0.5 * (s_lo + s_hi) } else { s_hi - f_hi * (s_hi - s_lo) / (f_hi - f_lo) };
            if !(s > s_lo.min(s_hi) && s < s_lo.max(s_hi) && s.is_finite()) {
                s = 0.5 * (s_lo + s_hi);
            }
            let u_pred = &ua + tangent_a * s;
            let (point, _, _) = self.correct(&u_pred, tangent_a, periods, Some(a))?;
            match psi(&point) {
                None => {
                    // Neither side's sequence: shrink towards the first point.
                    s_hi = s;
                    best_hi = point;
                    side = 0;
                }
                Some(0.0) => return Ok(point),
                Some(f) if (f < 0.0) == (f_lo < 0.0) => {
                    s_lo = s;
                    f_lo = f;
                    best_lo = point;
                    if side == -1 {
                        f_hi *= 0.5;
                    }
                    side = -1;
                }
                Some(f) => {
                    s_hi = s;
                    f_hi = f;
                    best_hi = point;
                    if side == 1 {
                        f_lo *= 0.5;
                    }
                    side = 1;
                }
            }
        }
        Ok(if f_lo.abs() <= f_hi.abs() { best_lo } else { best_hi })
    }

    /// Onto the branch of twice the period from a period doubling at
    /// `at`: Newton within the hyperplane normal to the critical
    /// eigenvector, a step along it (`direction` orients the new branch).
    fn switch(&mut self, at: &Point, periods: usize, _direction: &DVector<f64>) -> Result<(Point, DVector<f64>), String> {
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

/// Whether `beyond` continues the branch through `grazing` (rather than
/// being another orbit Newton found there): a new impact is slow (below a
/// tenth of the orbit's other impacts' speeds), a lost one leaves a close
/// approach (below a tenth of the peak's size).
fn continues(grazing: &Point, beyond: &Point) -> bool {
    if beyond.profile.impacts > grazing.profile.impacts {
        let scale = grazing.profile.slowest_impact.unwrap_or(f64::INFINITY).min(beyond.orbit.state.amax());
        beyond.profile.slowest_impact.is_some_and(|v| v < 0.1 * scale)
    } else {
        beyond.profile.closest.is_some_and(|c| c.gap < 0.1 * beyond.profile.peak.abs())
    }
}

/// How close to grazing a located orbit is: its closest smooth approach
/// to a stop and its slowest impact.
fn grazing_measure(p: &Point) -> String {
    let gap = p.profile.closest.map_or("none".to_string(), |c| format!("{:.3e}", c.gap));
    let speed = p.profile.slowest_impact.map_or("none".to_string(), |v| format!("{v:.3e}"));
    format!("closest smooth approach {gap}, slowest impact {speed}")
}

/// The distance along the branch after `last` (`step` after `previous`)
/// at which the closest smooth approach or the slowest impact, closing
/// linearly, reaches zero.
fn grazing_ahead(previous: &Point, last: &Point, step: f64) -> Option<f64> {
    if previous.profile.impacts != last.profile.impacts {
        return None;
    }
    let ahead = |a: Option<f64>, b: Option<f64>| match (a, b) {
        (Some(a), Some(b)) if b < a && b >= 0.0 => Some(b * step / (a - b)),
        _ => None,
    };
    let gap = ahead(previous.profile.closest.map(|c| c.gap), last.profile.closest.map(|c| c.gap));
    let speed = ahead(previous.profile.slowest_impact, last.profile.slowest_impact);
    match (gap, speed) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// ", stability changes: n unstable multipliers a -> b", when it does.
fn stability_change(a: &Point, b: &Point) -> String {
    if a.orbit.n_unstable == b.orbit.n_unstable {
        String::new()
    } else {
        format!("; unstable multipliers {} -> {}", a.orbit.n_unstable, b.orbit.n_unstable)
    }
}

/// The state linearly interpolated between two points at parameter `p`.
fn interpolate(a: &Point, b: &Point, p: f64) -> DVector<f64> {
    let s = if b.param == a.param { 0.0 } else { ((p - a.param) / (b.param - a.param)).clamp(0.0, 1.0) };
    &a.orbit.state * (1.0 - s) + &b.orbit.state * s
}
