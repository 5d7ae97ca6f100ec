//! Pseudo-arclength continuation of periodic orbits in one scene
//! parameter, and the special points on the way.
//!
//! An orbit of period `m T` (T the forcing period) is a zero of `G(x, p) =
//! Phi(x; p) - x`, `Phi` the stroboscopic map over `m T` at phase `t0`.
//! Its Jacobian is `[M - I, G_p]`: `M` the exact monodromy matrix, `G_p`
//! by central differences in `p` (a parameter such as the gap rebuilds the
//! model; a forcing frequency also changes the period). Steps are taken in
//! scaled coordinates (the state by the size of its branch's largest
//! orbit so far, the parameter by the range's width): a tangent predictor, then Newton on `G = 0`
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
//!
//! The work is split by job: [`corrector`] holds the problem (the scene at
//! a parameter value, the map, its Jacobian, scaling, Newton's corrector);
//! [`walk`] follows a branch; [`special`] detects and locates special
//! points; [`grazing`] crosses a grazing or ends a branch there.

mod corrector;
mod grazing;
mod section;
mod special;
mod walk;

use nalgebra::DVector;

use super::profile::Profile;
use super::shooting::Orbit;
use crate::component::Component;
use corrector::{interpolate, Walker};

/// What to continue, and how far.
#[derive(Clone, Debug)]
pub struct Continuation {
    /// The parameter, by its FMU name.
    pub param: String,
    /// The range the branches stay in.
    pub from: f64,
    pub to: f64,
    /// Where orbits are found to start branches from (default: `from`,
    /// then `to` if no branch reached it, then the middle of each stretch
    /// wider than a twentieth of the range that no branch spans); an
    /// orbit already on a branch starts none.
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
    /// The forcing frequency's parameter (default: the first load's, or a
    /// swinging hub's `Omega`).
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
    /// The orbit's size, the scale of its state in the continuation's
    /// steps: the RMS of the state's norm over the period
    /// ([`Profile::norm`]), or the state's norm where that is zero.
    pub fn size(&self) -> f64 {
        let size = if self.profile.norm > 0.0 { self.profile.norm } else { self.orbit.state.norm() };
        size.max(1e-300)
    }

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
    /// What was not followed, and why (a start without an orbit, a
    /// doubling beyond the longest period, the branch limit).
    pub notes: Vec<String>,
    /// Map evaluations (each one period of the flow).
    pub evaluations: usize,
}

/// What a continuation reports as it goes: the command line prints its
/// progress and writes each branch's rows as soon as the branch ends.
pub trait Observer {
    /// A branch starts from `first` (its orbit of `periods` forcing periods).
    fn branch_started(&mut self, index: usize, periods: usize, first: &Point) {
        let _ = (index, periods, first);
    }
    /// A point is accepted on branch `branch`.
    fn point(&mut self, branch: usize, point: &Point) {
        let _ = (branch, point);
    }
    /// A branch is finished: its points and its special points.
    fn branch_ended(&mut self, branch: &Branch, special: &[Special]) {
        let _ = (branch, special);
    }
}

/// An observer that does nothing.
pub struct Silent;

impl Observer for Silent {}

/// The orbits of a scene over one parameter's range (module doc).
pub fn continue_orbits(scene: &Component, settings: &Continuation) -> Result<Diagram, String> {
    continue_orbits_observed(scene, settings, &mut Silent)
}

/// [`continue_orbits`], telling `observer` what it does as it goes.
pub fn continue_orbits_observed(scene: &Component, settings: &Continuation, observer: &mut dyn Observer) -> Result<Diagram, String> {
    // Before any transient is simulated: without an exact flow there is
    // nothing to shoot with.
    super::shooting::check_flow(scene, settings.t0)?;
    let param = parameter(scene, &settings.param)?;
    let forcing = match &settings.forcing {
        Some(name) => parameter(scene, name)?,
        None => scene
            .parameters()
            .iter()
            .position(|p| is_forcing_frequency(&p.scene_path))
            .ok_or("the scene has no harmonic load (no loads[k].omega) and no swinging hub (no hub.prescribed.Omega): name the forcing frequency's parameter (--forcing NAME)")?,
    };
    let (lo, hi) = (settings.from.min(settings.to), settings.from.max(settings.to));
    if lo >= hi || !lo.is_finite() || !hi.is_finite() {
        return Err(format!("--param {}={}:{}: the range must have two different finite ends", settings.param, settings.from, settings.to));
    }
    let mut starts = if settings.starts.is_empty() { vec![settings.from] } else { settings.starts.clone() };
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
        surfaces: Default::default(),
        restarts: Vec::new(),
        tied: settings.tied.iter().map(|(name, scale, power)| parameter(scene, name).map(|i| (i, *scale, *power))).collect::<Result<_, _>>()?,
    };
    let mut diagram = Diagram { param: settings.param.clone(), branches: Vec::new(), special: Vec::new(), notes: Vec::new(), evaluations: 0 };
    // Each start's branch both ways, and those its grazings restart; then
    // the branches of twice the period at each period doubling.
    let mut doublings: Vec<Point> = Vec::new();
    let mut k = 0;
    loop {
        if k == starts.len() {
            // Without starts given, the far end too where no branch from
            // `from` reached it (one can end at a grazing with no orbit
            // found beyond it, or where Newton gives out); then the middle
            // of the widest stretch of the range that neither a branch nor
            // a start covers, while one is wider than a twentieth of it
            // (at most as many starts as branches: a stretch may hold no
            // orbit a transient settles on).
            if !settings.starts.is_empty() || diagram.branches.len() >= settings.max_branches || starts.len() > settings.max_branches + 1 {
                break;
            }
            let reached = diagram.branches.iter().any(|b| b.points.iter().any(|p| p.param == settings.to));
            if starts.len() == 1 && !reached {
                starts.push(settings.to);
            } else if let Some(middle) = widest_gap(&diagram.branches, &starts, (lo, hi)).filter(|(width, _)| *width > (hi - lo) / 20.0).map(|(_, m)| m) {
                starts.push(middle);
            } else {
                break;
            }
        }
        let start = starts[k];
        k += 1;
        let first = match walker.first_orbit(start, settings, k == 1) {
            Ok(first) => first,
            Err(e) if k > 1 => {
                diagram.notes.push(format!("the start at {} = {start}: {e}", settings.param));
                continue;
            }
            Err(e) => return Err(e),
        };
        walker.restarts.insert(0, first);
        follow_restarts(&mut walker, &mut diagram, settings.max_branches, &mut doublings, observer)?;
    }
    let mut next = 0;
    while next < doublings.len() && diagram.branches.len() < settings.max_branches {
        let at = doublings[next].clone();
        next += 1;
        let periods = 2 * at.periods();
        if periods > settings.max_period {
            diagram.notes.push(format!("the period doubling at {} = {}: period {periods} is beyond --max-period", settings.param, at.param));
            continue;
        }
        let index = diagram.branches.len();
        walker.weight_x = 1.0 / at.size();
        match walker.switch(&at, periods) {
            Ok((point, tangent)) => {
                observer.branch_started(index, periods, &point);
                let others: Vec<&[Point]> = diagram.branches.iter().map(|b| b.points.as_slice()).collect();
                let points = walker.walk(index, periods, point, tangent, true, &others, &mut diagram.special, &mut doublings, observer)?;
                let branch = Branch { index, periods, points };
                observer.branch_ended(&branch, &branch_special(&diagram.special, index));
                diagram.branches.push(branch);
                // The grazings it crossed without a nearby orbit beyond.
                follow_restarts(&mut walker, &mut diagram, settings.max_branches, &mut doublings, observer)?;
            }
            Err(e) => diagram.notes.push(format!("the period doubling at {} = {}: no switch onto the doubled branch: {e}", settings.param, at.param)),
        }
    }
    if next < doublings.len() || !walker.restarts.is_empty() {
        diagram.notes.push(format!("--max-branches {} reached: not followed further", settings.max_branches));
    }
    diagram.evaluations = walker.evaluations;
    Ok(diagram)
}

/// Follows, both ways, each orbit waiting in `walker.restarts` (a start,
/// or the far orbit of a grazing without a nearby one beyond it) that no
/// branch passes through, up to `max_branches` branches in all (the
/// rest stay waiting: the diagram's note says so).
fn follow_restarts(walker: &mut Walker, diagram: &mut Diagram, max_branches: usize, doublings: &mut Vec<Point>, observer: &mut dyn Observer) -> Result<(), String> {
    while diagram.branches.len() < max_branches {
        let Some(first) = walker.restarts.pop() else { break };
        if diagram.branches.iter().any(|b| on_points(walker, &b.points, &first)) {
            continue;
        }
        let index = diagram.branches.len();
        let periods = first.periods();
        // Each branch scales the state by its largest orbit so far, from its first.
        walker.weight_x = 1.0 / first.size();
        let mut increasing = DVector::zeros(first.orbit.state.len() + 1);
        increasing[first.orbit.state.len()] = 1.0;
        let tangent = walker.tangent(&first, periods, &increasing)?;
        observer.branch_started(index, periods, &first);
        let mut others: Vec<&[Point]> = diagram.branches.iter().map(|b| b.points.as_slice()).collect();
        let mut forward = walker.walk(index, periods, first.clone(), tangent.clone(), false, &others, &mut diagram.special, doublings, observer)?;
        others.push(&forward);
        let backward = walker.walk(index, periods, first, -tangent, false, &others, &mut diagram.special, doublings, observer)?;
        let mut points: Vec<Point> = backward.into_iter().skip(1).rev().collect();
        points.append(&mut forward);
        let branch = Branch { index, periods, points };
        observer.branch_ended(&branch, &branch_special(&diagram.special, index));
        diagram.branches.push(branch);
    }
    Ok(())
}

/// The widest stretch of `range` that no branch spans and no start lies
/// in: its width and its middle.
fn widest_gap(branches: &[Branch], starts: &[f64], range: (f64, f64)) -> Option<(f64, f64)> {
    let mut covered: Vec<(f64, f64)> = branches
        .iter()
        .filter(|b| !b.points.is_empty())
        .map(|b| b.points.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, z), p| (a.min(p.param), z.max(p.param))))
        .chain(starts.iter().map(|&s| (s, s)))
        .collect();
    covered.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut reach = range.0;
    let mut widest: Option<(f64, f64)> = None;
    for (a, z) in covered.into_iter().chain([(range.1, range.1)]) {
        if a > reach && widest.map_or(true, |(w, _)| a - reach > w) {
            widest = Some((a - reach, 0.5 * (a + reach)));
        }
        reach = reach.max(z);
    }
    widest
}

/// Whether a parameter (by its scene path) is a periodic drive's
/// frequency: a harmonic load's `omega`, a harmonic hub swing's `Omega`.
fn is_forcing_frequency(scene_path: &str) -> bool {
    (scene_path.starts_with("loads[") && scene_path.ends_with(".omega")) || scene_path == "hub.prescribed.Omega"
}

/// The special points of branch `index`.
fn branch_special(special: &[Special], index: usize) -> Vec<Special> {
    special.iter().filter(|s| s.branch == index).cloned().collect()
}

/// Whether `point` lies on the branch through `points`: the same period,
/// and its state within 1e-3 (scaled) of the state interpolated between two
/// consecutive points around its parameter value.
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
