//! Newton shooting on the stroboscopic map `x -> Phi(t0 + T; t0, x)` with
//! the exact monodromy matrix, and the orbit's Floquet multipliers.
//!
//! With an exact Jacobian Newton converges quadratically, also on orbits
//! with impacts, chatter and sticking, as long as the sequence of events
//! along the orbit stays the same from one iterate to the next.

use nalgebra::{DMatrix, DVector};

use crate::component::Component;
use crate::kind::{EventClass, Run};
use crate::solve::complex::C64;

/// How far outside the unit circle a multiplier counts as unstable
/// (rounding of the monodromy matrix).
pub const UNIT_CIRCLE: f64 = 1e-9;

/// Newton's settings.
#[derive(Clone, Copy, Debug)]
pub struct Shooting {
    /// Converged when `|Phi(x) - x| <= tolerance * max(|x|, scale)` (max norms).
    pub tolerance: f64,
    pub max_iterations: usize,
}

impl Default for Shooting {
    fn default() -> Self {
        Shooting { tolerance: 1e-12, max_iterations: 30 }
    }
}

/// A periodic orbit through `state` at `t0`.
#[derive(Clone, Debug)]
pub struct Orbit {
    pub t0: f64,
    pub period: f64,
    /// `[q; q']` at `t0`.
    pub state: DVector<f64>,
    /// The Jacobian of the map over one period at the orbit.
    pub monodromy: DMatrix<f64>,
    /// The Floquet multipliers (eigenvalues of the monodromy matrix).
    pub multipliers: Vec<C64>,
    /// Multipliers outside the unit circle.
    pub n_unstable: usize,
    /// Impacts (and compliant contacts) per period.
    pub impacts_per_period: usize,
    /// `|Phi(x) - x| / max(|x|, scale)` at each Newton iterate.
    pub residuals: Vec<f64>,
}

impl Orbit {
    pub(crate) fn new(t0: f64, period: f64, state: DVector<f64>, monodromy: DMatrix<f64>, impacts: usize, residuals: Vec<f64>) -> Orbit {
        let multipliers: Vec<C64> = monodromy.complex_eigenvalues().iter().copied().collect();
        let n_unstable = multipliers.iter().filter(|z| z.norm() > 1.0 + UNIT_CIRCLE).count();
        Orbit { t0, period, state, monodromy, multipliers, n_unstable, impacts_per_period: impacts, residuals }
    }

    pub fn stable(&self) -> bool {
        self.n_unstable == 0
    }
}

/// Whether the scene's runs have an exact flow with its Jacobian, which
/// shooting needs (checked before anything is simulated); if not, which
/// kind or which stop and law lacks it.
pub fn check_flow(scene: &Component, t0: f64) -> Result<(), String> {
    let inputs = vec![0.0; scene.inputs().len()];
    let mut run = scene.start(t0, &inputs)?;
    if run.flow().is_some() {
        return Ok(());
    }
    let why = match scene.start_from_state(t0, &inputs, &[]) {
        // The kind's reason, without its preamble (said here in full).
        Err(e) => e.strip_prefix("a run from a given state is for shooting, which needs an exact flow: ").map(str::to_string).unwrap_or(e),
        Ok(_) => "its runs have no exact flow".into(),
    };
    Err(format!(
        "periodic orbits need the exact flow of the scene's runs and its Jacobian (the monodromy matrix Newton shoots with); \
         the scene '{}' (kind '{}') has none: {why}",
        scene.name(),
        scene.kind().name()
    ))
}

/// How far beyond a rigid stop a state may lie and still count as on it,
/// relative to the size of the contact point's displacement: the
/// precision to which the map's fixed points are computed.
pub const ON_STOP: f64 = 1e-8;

/// A run of `scene` started at `t0` in state `x` (`[q; q']`). A state of
/// the map, not a scene's initial state: one beyond a rigid stop by no
/// more than [`ON_STOP`] is on it, and starts from its projection onto
/// the stop ([`onto_stops`]).
pub fn start_from(scene: &Component, t0: f64, x: &DVector<f64>) -> Result<Box<dyn Run>, String> {
    let inputs = vec![0.0; scene.inputs().len()];
    match scene.start_from_state(t0, &inputs, x.as_slice()) {
        Ok(run) => Ok(run),
        Err(e) => match onto_stops(scene, t0, x) {
            Some(on) => scene.start_from_state(t0, &inputs, on.as_slice()),
            None => Err(e),
        },
    }
}

/// `x` with its displacements moved onto each rigid stop it lies beyond
/// by no more than [`ON_STOP`] (relative), its velocities kept; `None`
/// if it lies beyond none, or beyond one by more.
///
/// The move is the smallest in the kinetic-energy norm (the coordinates
/// are mass-normalised modal ones): `q -= (s . q - target) s / |s|^2`,
/// `s` the stop's shape. The velocity is left to the stop's law: one
/// approaching the stop gets its impact at `t0`, as the orbit arriving
/// there does.
pub fn onto_stops(scene: &Component, t0: f64, x: &DVector<f64>) -> Option<DVector<f64>> {
    let mut run = scene.start(t0, &vec![0.0; scene.inputs().len()]).ok()?;
    let surfaces = run.flow()?.surfaces();
    let n = x.len() / 2;
    let mut q = x.rows(0, n).into_owned();
    let mut moved = false;
    for s in surfaces.iter().filter(|s| s.rigid && s.shape.len() == n) {
        let displacement = s.shape.dot(&q);
        let beyond = s.side * (displacement - s.target);
        let scale = s.target.abs() + s.shape.iter().zip(q.iter()).map(|(a, b)| (a * b).abs()).sum::<f64>();
        if beyond <= 0.0 {
            continue;
        }
        if beyond > ON_STOP * scale {
            return None;
        }
        q -= &s.shape * ((displacement - s.target) / s.shape.norm_squared());
        moved = true;
    }
    let mut on = x.clone();
    on.rows_mut(0, n).copy_from(&q);
    moved.then_some(on)
}

/// Advances `run` to `t_end` by at most `period` per advance: a scene's
/// work cap bounds one advance (an integrated kind's, its integration
/// steps), not the transient or the orbit it is part of.
pub(crate) fn advance_by_periods(run: &mut dyn Run, t_end: f64, period: f64) -> Result<(), String> {
    while run.time() < t_end {
        let next = if period > 0.0 { (run.time() + period).min(t_end) } else { t_end };
        let next = if next <= run.time() { t_end } else { next };
        run.advance_to(next).map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// The state after `periods` periods from the scene's own initial state at
/// `t0`: a guess past the transient.
pub fn strobe(scene: &Component, t0: f64, period: f64, periods: usize) -> Result<DVector<f64>, String> {
    let mut run = scene.start(t0, &vec![0.0; scene.inputs().len()])?;
    advance_by_periods(run.as_mut(), t0 + periods as f64 * period, period)?;
    let flow = run.flow().ok_or("the scene's kind has no exact flow")?;
    Ok(flow.state())
}

/// `Phi(x)`, its Jacobian and the impacts on the way.
pub(crate) fn map(scene: &Component, t0: f64, period: f64, x: &DVector<f64>) -> Result<(DVector<f64>, DMatrix<f64>, usize), String> {
    let mut run = start_from(scene, t0, x)?;
    run.set_event_recording(true);
    run.drain_events();
    let flow = run.flow().ok_or("the scene's kind has no exact flow (mode transfer, or a kind without one)")?;
    let jacobian = flow.advance_with_jacobian(t0 + period).map_err(|e| e.to_string())?;
    let end = flow.state();
    let impacts = run.drain_events().iter().filter(|e| matches!(e.class, EventClass::Impact | EventClass::ContactOnset)).count();
    Ok((end, jacobian, impacts))
}

/// The periodic orbit of period `period` (a multiple of the forcing's)
/// through the state near `guess` at `t0`, by Newton on `Phi(x) = x`.
pub fn shoot(scene: &Component, t0: f64, period: f64, guess: &DVector<f64>, settings: Shooting) -> Result<Orbit, String> {
    let mut x = guess.clone();
    let scale = guess.amax().max(f64::MIN_POSITIVE);
    let mut residuals = Vec::new();
    for _ in 0..=settings.max_iterations {
        let (end, m, impacts) = map(scene, t0, period, &x)?;
        let r = &end - &x;
        let size = r.amax() / x.amax().max(scale);
        residuals.push(size);
        if size <= settings.tolerance {
            return Ok(Orbit::new(t0, period, x, m, impacts, residuals));
        }
        let dim = x.len();
        let j = m - DMatrix::identity(dim, dim);
        let step = j.lu().solve(&(-r)).ok_or("shooting: the monodromy matrix has a multiplier 1 (a fold or a free phase): Newton's matrix is singular")?;
        x += step;
    }
    let shown: Vec<String> = residuals.iter().map(|r| format!("{r:.1e}")).collect();
    Err(format!("shooting: no convergence in {} Newton iterations (residuals {})", settings.max_iterations, shown.join(", ")))
}

/// The orbit over its minimal period. `orbit`, found over `periods`
/// forcing periods of `forcing_period`, may repeat sooner (the guess's
/// period was read off a slow transient): for each divisor `d` of
/// `periods`, smallest first, whose state after `d` forcing periods is
/// back at the start (to Newton's tolerance), the orbit shot over `d`
/// periods from there, with that period's multipliers. Where the start
/// returns only to 1e-6, Newton over `d` periods decides: the orbit it
/// converges to must be the one given (within 1e-6 of its size).
pub fn minimal_period(scene: &Component, orbit: Orbit, forcing_period: f64, settings: Shooting) -> Result<Orbit, String> {
    let periods = (orbit.period / forcing_period).round() as usize;
    let size = orbit.state.amax().max(f64::MIN_POSITIVE);
    for d in (1..periods).filter(|d| periods % d == 0) {
        let span = d as f64 * forcing_period;
        let (end, _, _) = map(scene, orbit.t0, span, &orbit.state)?;
        let returned = (&end - &orbit.state).amax() / size;
        if returned <= 1e-6 {
            if let Ok(shorter) = shoot(scene, orbit.t0, span, &orbit.state, settings) {
                if returned <= settings.tolerance || (&shorter.state - &orbit.state).amax() <= 1e-6 * size {
                    return Ok(shorter);
                }
            }
        }
    }
    Ok(orbit)
}
