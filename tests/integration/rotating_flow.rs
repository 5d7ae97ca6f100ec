//! The rotating kind's flow (a prescribed harmonic swing,
//! `src/kinds/rotating/flow.rs`): its Jacobian, replayed steps and the
//! onset's reset of the damping's onset speed, against central
//! differences of the simulation itself at the tightest tolerance (1e-12:
//! runs restarted from the state moved by `+-h`, `h` = 1e-6 of the
//! coordinate's scale), over one period of TappingArm with its strike;
//! and the refusals of the drives without a period.

use beamstop::component::Component;
use nalgebra::{DMatrix, DVector};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

fn scene(tolerance: f64) -> Component {
    scene_with(tolerance, "auto")
}

/// The scene with `solver.method = method`: the Jacobian replays DOP853
/// over the steps of whichever integrator the nominal run uses.
fn scene_with(tolerance: f64, method: &str) -> Component {
    let mut json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(format!("{ROOT}/scenes/tapping_arm.json")).unwrap()).unwrap();
    json["solver"]["tolerance"] = serde_json::json!(tolerance);
    json["solver"]["method"] = serde_json::json!(method);
    Component::from_json(&json.to_string()).unwrap()
}

/// The state `[B; B']` after `t` from the scene's own start.
fn settled(scene: &Component, t: f64) -> DVector<f64> {
    let mut run = scene.start(0.0, &[]).unwrap();
    run.advance_to(t).unwrap();
    run.flow().unwrap().state()
}

fn map(scene: &Component, t0: f64, t1: f64, x: &DVector<f64>) -> (DVector<f64>, usize) {
    let mut run = scene.start_from_state(t0, &[], x.as_slice()).unwrap();
    run.set_event_recording(true);
    run.advance_to(t1).unwrap();
    let onsets = run.drain_events().iter().filter(|e| e.class == beamstop::kind::EventClass::ContactOnset).count();
    (run.flow().unwrap().state(), onsets)
}

/// The Jacobian of `[t0, t1]` from the state there after the scene's own
/// start, against central differences of the simulation (module doc):
/// both scaled by the state's scales (the largest modal coordinate, the
/// largest rate), the largest column's difference relative to the matrix's
/// norm, and the strikes on the way.
fn check(method: &str, t0: f64, t1: f64) -> (f64, usize, f64) {
    let scene = scene_with(1e-12, method);
    let x0 = settled(&scene, t0);
    let clock = std::time::Instant::now();
    let mut run = scene.start_from_state(t0, &[], x0.as_slice()).unwrap();
    let jac = run.flow().unwrap().advance_with_jacobian(t1).unwrap();
    let seconds = clock.elapsed().as_secs_f64();
    let (end, onsets) = map(&scene, t0, t1, &x0);
    let moved = (run.flow().unwrap().state() - &end).amax() / end.amax();
    assert!(moved <= 1e-15, "advance_with_jacobian moves as advance_to does: {moved:e}");
    let n = x0.len() / 2;
    let scales: Vec<f64> = (0..2 * n).map(|k| if k < n { x0.rows(0, n).amax() } else { x0.rows(n, n).amax() }).collect();
    let mut fd = DMatrix::zeros(2 * n, 2 * n);
    for k in 0..2 * n {
        let h = 1e-6 * scales[k];
        let (mut plus, mut minus) = (x0.clone(), x0.clone());
        plus[k] += h;
        minus[k] -= h;
        let column = (map(&scene, t0, t1, &plus).0 - map(&scene, t0, t1, &minus).0) / (plus[k] - minus[k]);
        fd.set_column(k, &column);
    }
    let scaled = |m: &DMatrix<f64>| DMatrix::from_fn(2 * n, 2 * n, |i, j| m[(i, j)] * scales[j] / scales[i]);
    let (j, f) = (scaled(&jac), scaled(&fd));
    let worst = (0..2 * n).map(|k| (j.column(k) - f.column(k)).norm()).fold(0.0, f64::max) / f.norm();
    (worst, onsets, seconds)
}

/// Over the strike (a tenth of a period round it: the onset, the push,
/// the separation): at the tightest tolerance, to 1e-5, whichever
/// integrator the nominal run uses.
#[test]
fn jacobian_through_a_strike_matches_central_differences() {
    let period = std::f64::consts::TAU / 12.0;
    for method in ["auto", "dop853"] {
        let (worst, onsets, seconds) = check(method, 3.2 * period, 3.3 * period);
        println!("tapping arm ({method}), 0.1 period round a strike: Jacobian vs central differences {worst:.2e} ({seconds:.2} s for the Jacobian)");
        assert_eq!(onsets, 1, "{method}: one strike in the window");
        assert!(worst < 1e-5, "{method}: {worst:e}");
    }
}

/// A whole period (`--ignored`: 2 s for the Jacobian, 4 s for the differences).
#[test]
#[ignore]
fn jacobian_over_a_period_matches_central_differences() {
    let period = std::f64::consts::TAU / 12.0;
    let (worst, onsets, seconds) = check("auto", 3.0 * period, 4.0 * period);
    println!("tapping arm, one period: Jacobian vs central differences {worst:.2e} ({seconds:.2} s for the Jacobian)");
    assert_eq!(onsets, 1, "one strike in the period");
    assert!(worst < 1e-5, "{worst:e}");
}

#[test]
fn drives_without_a_period_are_refused_with_the_reason() {
    for (file, words) in [("rotating_beam", "driven by its torque input"), ("spin_up", "spin-up is not periodic")] {
        let scene = Component::from_json(&std::fs::read_to_string(format!("{ROOT}/scenes/{file}.json")).unwrap()).unwrap();
        let mut run = scene.start(0.0, &vec![0.0; scene.inputs().len()]).unwrap();
        assert!(run.flow().is_none(), "{file}");
        let e = beamstop::orbits::check_flow(&scene, 0.0).unwrap_err();
        assert!(e.contains(words) && e.contains("harmonic"), "{file}: {e}");
    }
}

/// Newton on the tapping arm's period-1 orbit at its defaults (Omega =
/// 12) at the tightest tolerance: the residuals fall quadratically to the
/// integration's floor, and the Floquet multipliers agree with the
/// eigenvalues of a monodromy matrix from central differences of the
/// simulation (`h` = 1e-6 of the state's scales) to 1e-5 (`--ignored`:
/// about 10 s; `-- --nocapture` prints both).
#[test]
#[ignore]
fn newton_converges_and_multipliers_match_central_differences() {
    use beamstop::orbits::{shoot, strobe, Shooting};
    let period = std::f64::consts::TAU / 12.0;
    // At the scene's own tolerance (1e-10) Newton stops at its floor.
    let own = scene(1e-10);
    let guess = strobe(&own, 0.0, period, 1).unwrap();
    let orbit = shoot(&own, 0.0, period, &guess, Shooting { tolerance: 1e-11, max_iterations: 8 }).unwrap();
    println!("solver.tolerance = 1e-10: Newton residuals {:?}", orbit.residuals.iter().map(|r| format!("{r:.2e}")).collect::<Vec<_>>());
    let scene = scene(1e-12);
    let guess = strobe(&scene, 0.0, period, 1).unwrap();
    let clock = std::time::Instant::now();
    let orbit = shoot(&scene, 0.0, period, &guess, Shooting { tolerance: 1e-13, max_iterations: 8 }).unwrap();
    println!("Newton residuals |Phi(x) - x| / |x|: {:?} ({:.1} s)", orbit.residuals.iter().map(|r| format!("{r:.2e}")).collect::<Vec<_>>(), clock.elapsed().as_secs_f64());
    let x0 = &orbit.state;
    let n = x0.len() / 2;
    let mut fd = DMatrix::zeros(2 * n, 2 * n);
    for k in 0..2 * n {
        let scale = if k < n { x0.rows(0, n).amax() } else { x0.rows(n, n).amax() };
        let (mut plus, mut minus) = (x0.clone(), x0.clone());
        plus[k] += 1e-6 * scale;
        minus[k] -= 1e-6 * scale;
        let column = (map(&scene, 0.0, period, &plus).0 - map(&scene, 0.0, period, &minus).0) / (plus[k] - minus[k]);
        fd.set_column(k, &column);
    }
    let mut ours: Vec<_> = orbit.multipliers.clone();
    let mut theirs: Vec<_> = fd.complex_eigenvalues().iter().copied().collect();
    let key = |z: &beamstop::solve::complex::C64| (-z.norm(), z.im);
    ours.sort_by(|a, b| key(a).partial_cmp(&key(b)).unwrap());
    theirs.sort_by(|a, b| key(a).partial_cmp(&key(b)).unwrap());
    let worst = ours.iter().zip(&theirs).map(|(a, b)| (*a - *b).norm()).fold(0.0, f64::max);
    for (a, b) in ours.iter().zip(&theirs).take(6) {
        println!("multiplier {:+.9} {:+.9}i  central differences {:+.9} {:+.9}i", a.re, a.im, b.re, b.im);
    }
    println!("largest difference {worst:.2e}; {} contact(s) per period", orbit.impacts_per_period);
    let r = &orbit.residuals;
    assert!(r.last().unwrap() < &1e-11, "{r:?}");
    assert!(worst < 1e-5, "{worst:e}");
}
