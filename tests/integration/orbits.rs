//! Periodic orbits by Newton shooting with the exact monodromy matrix
//! (`beamstop::orbits`), against what is known in closed form: the single
//! impact oscillator `x'' + c x' + k x = A cos(w t)` with a rigid stop at
//! `x = d` (a one-mass chain; c = 0.1, k = 1, w = 1, d = 1, R = 0.8).

use std::f64::consts::PI;

use beamstop::component::Component;
use beamstop::orbits::{continue_orbits, shoot, start_from, strobe, Continuation, Shooting, SpecialKind};
use beamstop::solve::complex::C64;
use nalgebra::DVector;

fn oscillator(amplitude: f64) -> Component {
    let text = format!(
        r#"{{
        "name": "ImpactOscillator",
        "structure": {{ "type": "chain", "masses": 1, "m": 1.0, "k": 1.0, "c": 0.1 }},
        "loads": [ {{ "type": "point_harmonic", "name": "A", "mass": 1, "amplitude": {amplitude}, "omega": 1.0, "waveform": "cos" }} ],
        "stops": [ {{ "name": "stop", "mass": 1, "gap": 1.0, "side": "positive", "law": {{ "type": "restitution", "R": 0.8, "eps": 1e-6 }} }} ],
        "experiment": {{ "start": 0, "stop": 100, "step": 0.1 }}
    }}"#
    );
    Component::from_json(&text).unwrap()
}

const C: f64 = 0.1;
const T: f64 = 2.0 * PI;

#[test]
fn non_impacting_orbit_and_its_floquet_multipliers() {
    // Below grazing (A < d sqrt((k - w^2)^2 + (c w)^2) = 0.1): the linear
    // response x = (A / c) sin t, amplitude 0.5 < d.
    let scene = oscillator(0.05);
    let orbit = shoot(&scene, 0.0, T, &DVector::zeros(2), Shooting::default()).unwrap();
    // An affine map: one Newton step.
    assert!(orbit.residuals.len() <= 3 && *orbit.residuals.last().unwrap() < 1e-12, "{:?}", orbit.residuals);
    assert_eq!(orbit.impacts_per_period, 0);
    assert!(orbit.state[0].abs() < 1e-12 && (orbit.state[1].abs() - 0.5).abs() < 1e-12, "{}", orbit.state);
    // exp((-c/2 +- i sqrt(k - c^2/4)) 2 pi / w)
    let exact = (C64::new(-C / 2.0, (1.0 - C * C / 4.0).sqrt()) * T).exp();
    assert_eq!(orbit.multipliers.len(), 2);
    assert!(orbit.multipliers[0].im * orbit.multipliers[1].im < 0.0, "a conjugate pair: {:?}", orbit.multipliers);
    for z in &orbit.multipliers {
        let e = if z.im * exact.im > 0.0 { exact } else { exact.conj() };
        assert!((z - e).norm() < 1e-12, "multiplier {z} against {e}");
    }
    assert!(orbit.stable());
}

#[test]
fn impacting_orbit_converges_quadratically() {
    // Above grazing: a period-1 orbit with one impact per period, from a
    // guess 10 periods into the transient.
    let scene = oscillator(0.15);
    let guess = strobe(&scene, 0.0, T, 10).unwrap();
    let orbit = shoot(&scene, 0.0, T, &guess, Shooting::default()).unwrap();
    let r = &orbit.residuals;
    eprintln!("residuals {r:?}, multipliers {:?}", orbit.multipliers);
    assert!(*r.last().unwrap() < 1e-12);
    assert_eq!(orbit.impacts_per_period, 1);
    // Quadratic: each residual below ten times the square of the one before
    // (while above rounding).
    for w in r.windows(2) {
        if w[1] > 1e-13 {
            assert!(w[1] < 10.0 * w[0] * w[0], "residuals {r:?}");
        }
    }
    // The orbit is a fixed point of the simulation itself.
    let again = strobe_from(&scene, &orbit.state);
    assert!((again - &orbit.state).amax() < 1e-11);
}

fn strobe_from(scene: &Component, x: &DVector<f64>) -> DVector<f64> {
    strobe_over(scene, x, T)
}

fn strobe_over(scene: &Component, x: &DVector<f64>, span: f64) -> DVector<f64> {
    let mut run = start_from(scene, 0.0, x).unwrap();
    run.advance_to(span).unwrap();
    run.flow().unwrap().state()
}

/// Impacts per forcing period after `settle` periods from `x` at `t = 0`,
/// counted over `count` periods: brute-force simulation.
fn impacts_per_period(scene: &Component, x: &DVector<f64>, period: f64, settle: usize, count: usize) -> f64 {
    let mut run = start_from(scene, 0.0, x).unwrap();
    run.set_event_recording(true);
    run.advance_to(settle as f64 * period).unwrap();
    run.drain_events();
    run.advance_to((settle + count) as f64 * period).unwrap();
    let impacts = run.drain_events().iter().filter(|e| e.speed.is_some()).count();
    impacts as f64 / count as f64
}

#[test]
fn grazing_located_and_the_impacting_branch_continued() {
    // Continuation in A from the linear orbit: grazing where the amplitude
    // A / sqrt((k - w^2)^2 + (c w)^2) = 10 A reaches the gap d = 1.
    let scene = oscillator(0.05);
    let mut settings = Continuation::new("A.amplitude", 0.05, 0.2);
    settings.points = 40;
    let diagram = continue_orbits(&scene, &settings).unwrap();
    let grazing: Vec<_> = diagram.special.iter().filter(|s| s.kind == SpecialKind::Grazing).collect();
    assert_eq!(grazing.len(), 1, "{:#?}", diagram.special.iter().map(|s| (s.kind, s.point.param, &s.note)).collect::<Vec<_>>());
    let a = grazing[0].point.param;
    eprintln!("grazing at A = {a:.15} (error {:.1e}), {} points, {} map evaluations", a - 0.1, diagram.branches[0].points.len(), diagram.evaluations);
    assert!((a - 0.1).abs() < 1e-8, "grazing at A = {a}");
    let branch = &diagram.branches[0];
    assert!(branch.points.first().unwrap().param == 0.05 && branch.points.last().unwrap().param == 0.2);
    for p in &branch.points {
        let expected = if p.param < a { 0 } else { 1 };
        assert!(p.profile.impacts == expected || (p.param - a).abs() < 1e-9, "A = {}: {} impacts", p.param, p.profile.impacts);
        // Every point is a periodic orbit of the simulation itself.
        let again = strobe_over(&scene_at(p.param), &p.orbit.state, T);
        assert!((again - &p.orbit.state).amax() < 1e-9 * p.orbit.state.amax(), "A = {}", p.param);
    }
    // Beyond the grazing, the branch is the attractor a transient settles on.
    let p = branch.points.iter().min_by(|x, y| (x.param - 0.15).abs().total_cmp(&(y.param - 0.15).abs())).unwrap();
    let scene = scene_at(p.param);
    let from_transient = shoot(&scene, 0.0, T, &strobe(&scene, 0.0, T, 60).unwrap(), Shooting::default()).unwrap();
    assert!((&from_transient.state - &p.orbit.state).amax() < 1e-9, "{} against {}", from_transient.state, p.orbit.state);
    assert!(p.orbit.stable() && from_transient.stable());
}

fn scene_at(amplitude: f64) -> Component {
    let mut scene = oscillator(0.05);
    scene.set(0, amplitude);
    scene.validate().unwrap();
    scene
}

#[test]
fn pinned_beam_double_impact_branch_and_its_ends() {
    // VSM12 Figure 9's regime (F = 72, omega = 0.7 omega_1, eps = 1e-3):
    // the period-1 double-impact orbit found at d = 1.2, continued in d.
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/pinned_beam.json")).unwrap();
    let mut scene = Component::from_json(&text).unwrap();
    for (name, value) in [("F", 72.0), ("omega", 0.7 * PI * PI), ("eps", 1e-3)] {
        let i = scene.parameters().iter().position(|p| p.name == name).unwrap();
        scene.set(i, value);
    }
    scene.validate().unwrap();
    let period = 2.0 * PI / (0.7 * PI * PI);
    let mut settings = Continuation::new("d", 0.8, 1.66);
    settings.starts = vec![1.2];
    settings.points = 40;
    settings.max_branches = 4;
    let diagram = continue_orbits(&scene, &settings).unwrap();
    let find = |kind: SpecialKind, branch: usize| diagram.special.iter().find(|s| s.kind == kind && s.branch == branch).unwrap_or_else(|| panic!("no {kind:?}: {:#?}", diagram.special));
    let pd = find(SpecialKind::PeriodDoubling, 0);
    // The lower end: a third impact appears (grazing from the smooth side).
    let gr = diagram.special.iter().find(|s| s.kind == SpecialKind::Grazing && s.branch == 0 && s.point.param < 1.0).expect("the lower grazing");
    eprintln!("PD at d = {}, GR at d = {}; {} map evaluations", pd.point.param, gr.point.param, diagram.evaluations);
    assert!(pd.point.param > 1.6 && gr.point.param < 0.86, "PD at {}, GR at {}", pd.point.param, gr.point.param);
    let d = scene.parameters().iter().position(|p| p.name == "d").unwrap();
    let at = |value: f64| {
        let mut s = scene.clone();
        s.set(d, value);
        s.validate().unwrap();
        s
    };
    // The period doubling: shooting on either side (an independent Newton
    // in the state alone) puts a real multiplier on either side of -1.
    let lowest = |value: f64| {
        let orbit = shoot(&at(value), 0.0, period, &pd.point.orbit.state, Shooting::default()).unwrap();
        orbit.multipliers.iter().filter(|z| z.im.abs() < 1e-9).map(|z| z.re).fold(f64::INFINITY, f64::min)
    };
    let (below, above) = (lowest(pd.point.param - 1e-4), lowest(pd.point.param + 1e-4));
    assert!(below > -1.0 && above < -1.0, "multipliers {below} and {above} about d = {}", pd.point.param);
    // The grazing: brute-force simulation from the orbit settles on 2
    // impacts per period just above it and 3 just below.
    let x = &gr.point.orbit.state;
    assert_eq!(impacts_per_period(&at(gr.point.param + 1e-5), x, period, 100, 20), 2.0);
    assert_eq!(impacts_per_period(&at(gr.point.param - 1e-5), x, period, 100, 20), 3.0);
    // The doubled branch: period 2, and not period 1.
    let doubled = diagram.branches.iter().find(|b| b.periods == 2).expect("the doubled branch");
    let p = &doubled.points[doubled.points.len() / 2];
    let s = at(p.param);
    assert!((strobe_over(&s, &p.orbit.state, 2.0 * period) - &p.orbit.state).amax() < 1e-8);
    assert!((strobe_over(&s, &p.orbit.state, period) - &p.orbit.state).amax() > 1e-4);
}

#[test]
fn figure_4_orbit_with_chatter_and_sticking() {
    // VSM12's Figure 4 scene settles on a period-1 orbit that chatters
    // into a stick once per period; shooting from t0 = 4 (free flight).
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/pinned_beam.json")).unwrap();
    let scene = Component::from_json(&text).unwrap();
    let period = 2.0 * PI / (0.1 * PI * PI);
    let t0 = 4.0;
    let mut run = scene.start(0.0, &[0.0]).unwrap();
    run.advance_to(t0 + 2.0 * period).unwrap();
    let guess = run.flow().unwrap().state();
    let orbit = shoot(&scene, t0, period, &guess, Shooting::default()).unwrap();
    eprintln!("residuals {:?}, impacts {}, multipliers {:?}", orbit.residuals, orbit.impacts_per_period, orbit.multipliers);
    assert!(*orbit.residuals.last().unwrap() < 1e-12);
    assert!(orbit.impacts_per_period > 5);
    assert!(orbit.stable());
}

/// WB00's chain (scenes/wagg_bishop_chain.json: two masses m = 1, springs
/// k = 1 and dampers c = 0.1 from the ground and between them, the stop at
/// mass 2 at x_s = 0.1 with r = 0.7, forcing (0.5, 0) cos(0.9 t)): its
/// P(1,1) orbit in closed form, in physical coordinates. With `y = (x, v)`,
/// `Phi = exp(A T)`, the periodic particular solution `p(t)` and the impact
/// map `J = diag(1, 1, 1, -r)`, the state just before the impact at `t_i`
/// solves `(I - Phi J) y = (I - Phi) p(t_i)`, and `x_2 = x_s` fixes `t_i`.
/// Its multipliers are the eigenvalues of `Phi S`, with the saltation
/// matrix `S = J + (F+ - J F-) e_2^T / v_2` of the impact.
#[test]
fn wagg_bishop_p11_orbit_against_its_closed_form() {
    use nalgebra::{DMatrix, DVector as V};
    let (k, c, xs, r, omega) = (1.0, 0.1, 0.1, 0.7, 0.9);
    let period = 2.0 * PI / omega;
    let e = DMatrix::from_row_slice(2, 2, &[2.0, -1.0, -1.0, 1.0]);
    let mut a = DMatrix::zeros(4, 4);
    a.view_mut((0, 2), (2, 2)).copy_from(&DMatrix::identity(2, 2));
    a.view_mut((2, 0), (2, 2)).copy_from(&(&e * -k));
    a.view_mut((2, 2), (2, 2)).copy_from(&(&e * -c));
    let force = V::from_vec(vec![0.5, 0.0]);
    // (K - W^2 M + i W C) X = f: real form [[K - W^2, -W C], [W C, K - W^2]].
    let mut lhs = DMatrix::zeros(4, 4);
    let stiff = &e * k - DMatrix::identity(2, 2) * (omega * omega);
    lhs.view_mut((0, 0), (2, 2)).copy_from(&stiff);
    lhs.view_mut((2, 2), (2, 2)).copy_from(&stiff);
    lhs.view_mut((0, 2), (2, 2)).copy_from(&(&e * (-omega * c)));
    lhs.view_mut((2, 0), (2, 2)).copy_from(&(&e * (omega * c)));
    let mut rhs = V::zeros(4);
    rhs.rows_mut(0, 2).copy_from(&force);
    let xc = lhs.lu().solve(&rhs).unwrap();
    let (re, im) = (xc.rows(0, 2).into_owned(), xc.rows(2, 2).into_owned());
    // x_p = Re((re + i im) e^{i W t}) = re cos - im sin; v_p its derivative.
    let particular = |t: f64| {
        let (s, co) = (omega * t).sin_cos();
        let x = &re * co - &im * s;
        let v = (&re * -s - &im * co) * omega;
        V::from_iterator(4, x.iter().chain(v.iter()).copied())
    };
    let phi = (&a * period).exp();
    let j = DMatrix::from_diagonal(&V::from_vec(vec![1.0, 1.0, 1.0, -r]));
    let solve = (DMatrix::identity(4, 4) - &phi * &j).lu();
    let before = |t: f64| solve.solve(&((DMatrix::identity(4, 4) - &phi) * particular(t))).unwrap();
    // The impact phase: x_2 = x_s approached from below (v_2 > 0), by
    // bisection from a fine scan over one period.
    let g = |t: f64| before(t)[1] - xs;
    let steps = 2000;
    let mut roots = Vec::new();
    for i in 0..steps {
        let (mut lo, mut hi) = (period * i as f64 / steps as f64, period * (i + 1) as f64 / steps as f64);
        if g(lo).signum() == g(hi).signum() {
            continue;
        }
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if g(mid).signum() == g(lo).signum() { lo = mid } else { hi = mid }
        }
        if before(lo)[3] > 0.0 {
            roots.push(lo);
        }
    }
    // The admissible one: beamstop's orbit hits at that phase.
    let scene = Component::from_json(&std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/wagg_bishop_chain.json")).unwrap()).unwrap();
    let orbit = shoot(&scene, 0.0, period, &strobe(&scene, 0.0, period, 200).unwrap(), Shooting::default()).unwrap();
    assert_eq!(orbit.impacts_per_period, 1);
    let mut run = start_from(&scene, 0.0, &orbit.state).unwrap();
    run.set_event_recording(true);
    run.advance_to(period).unwrap();
    let events = run.drain_events();
    let impact = events.iter().find(|e| e.speed.is_some()).unwrap();
    let t_i = *roots.iter().min_by(|x, y| (*x - impact.time).abs().total_cmp(&(*y - impact.time).abs())).unwrap();
    let y = before(t_i);
    eprintln!("closed form: impact at t = {t_i:.15}, v_2 = {:.15}; beamstop: t = {:.15}, speed {:.15}", y[3], impact.time, impact.speed.unwrap());
    assert!((t_i - impact.time).abs() < 1e-10, "impact phase {t_i} against {}", impact.time);
    assert!((y[3] - impact.speed.unwrap()).abs() < 1e-10 * y[3], "impact speed {} against {:?}", y[3], impact.speed);
    // The multipliers: eig(Phi S).
    let b = |t: f64| V::from_vec(vec![0.0, 0.0, 0.5 * (omega * t).cos(), 0.0]);
    let f_minus = &a * &y + b(t_i);
    let f_plus = &a * (&j * &y) + b(t_i);
    let mut e2 = V::zeros(4);
    e2[1] = 1.0;
    let s = &j + (&f_plus - &j * &f_minus) * e2.transpose() / y[3];
    let mut exact: Vec<C64> = (&phi * &s).complex_eigenvalues().iter().copied().collect();
    let mut found = orbit.multipliers.clone();
    let key = |z: &C64| (z.norm(), z.im);
    exact.sort_by(|p, q| key(p).partial_cmp(&key(q)).unwrap());
    found.sort_by(|p, q| key(p).partial_cmp(&key(q)).unwrap());
    eprintln!("multipliers: closed form {exact:?}\n             beamstop    {found:?}");
    for (z, w) in exact.iter().zip(&found) {
        assert!((z - w).norm() < 1e-9, "multiplier {w} against {z}");
    }
}

#[test]
fn a_run_from_a_state_refuses_what_it_cannot_start_from() {
    let scene = oscillator(0.05);
    let short = start_from(&scene, 0.0, &DVector::from_vec(vec![1.0])).unwrap_err();
    assert!(short.contains("a state of 1 coordinates for a structure of 1 modes"), "{short}");
    let nan = start_from(&scene, 0.0, &DVector::from_vec(vec![f64::NAN, 0.0])).unwrap_err();
    assert!(nan.contains("NaN") && nan.contains("finite"), "{nan}");
    // Inside the stop: refused as the scene's own initial state would be.
    let inside = start_from(&scene, 0.0, &DVector::from_vec(vec![1.5, 0.0])).unwrap_err();
    assert!(inside.contains("penetrates"), "{inside}");
    // The torque-driven rotating beam has no periodic drive: no flow to shoot with.
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/rotating_beam.json")).unwrap();
    let rotating = Component::from_json(&text).unwrap();
    let refused = start_from(&rotating, 0.0, &DVector::zeros(4)).unwrap_err();
    assert!(refused.contains("needs an exact flow"), "{refused}");
    let mut settings = Continuation::new("nonexistent", 0.0, 1.0);
    settings.points = 10;
    let e = continue_orbits(&scene, &settings).unwrap_err();
    assert!(e.contains("no parameter 'nonexistent'") && e.contains("A.amplitude"), "{e}");
}

/// Residuals falling quadratically once near the orbit (below 1e-4: the
/// event sequence settled) and while above rounding: each below a hundred
/// times the square of the one before.
fn quadratic(r: &[f64]) -> bool {
    r.windows(2).all(|w| w[0] > 1e-4 || w[1] < 1e-12 || w[1] < 100.0 * w[0] * w[0])
}

#[test]
fn newton_converges_quadratically_on_spring_stops_and_a_period_two_response() {
    let load = |name: &str| Component::from_json(&std::fs::read_to_string(format!("{}/scenes/{name}.json", env!("CARGO_MANIFEST_DIR"))).unwrap()).unwrap();
    let cases: [(&str, &[(&str, f64)], usize, usize); 3] = [
        // RMTM's soft and hard impacts at the scenes' own forcing (soft: at
        // omega_1, in contact; hard: at 1.3 omega_1), and VSM12 Fig. 9's
        // period-2 response at d = 1.64 (between the double-impact orbit's
        // period doubling at 1.6382 and the doubled orbit's own at 1.6413).
        // From a guess a few periods into the transient.
        ("spring_stop_soft", &[], 1, 6),
        ("spring_stop_hard", &[], 1, 12),
        ("pinned_beam", &[("F", 72.0), ("omega", 0.7 * PI * PI), ("eps", 1e-3), ("d", 1.64)], 2, 4),
    ];
    for (name, sets, periods, transient) in cases {
        let mut scene = load(name);
        for (p, v) in sets {
            let i = scene.parameters().iter().position(|q| q.name == *p).unwrap();
            scene.set(i, *v);
        }
        scene.validate().unwrap();
        let omega = scene.get(scene.parameters().iter().position(|q| q.scene_path.ends_with(".omega")).unwrap());
        let period = 2.0 * PI / omega;
        let guess = strobe(&scene, 0.0, period, transient).unwrap();
        let orbit = shoot(&scene, 0.0, periods as f64 * period, &guess, Shooting::default()).unwrap();
        eprintln!("{name}: {} impacts per orbit, residuals {:?}, largest multiplier {:.3}", orbit.impacts_per_period, orbit.residuals, orbit.multipliers.iter().map(|z| z.norm()).fold(0.0, f64::max));
        assert!(*orbit.residuals.last().unwrap() < 1e-12 && quadratic(&orbit.residuals), "{name}: {:?}", orbit.residuals);
        assert!(orbit.impacts_per_period > 0 && orbit.stable(), "{name}");
        if periods == 2 {
            assert!((strobe_over(&scene, &orbit.state, period) - &orbit.state).amax() > 1e-3 * orbit.state.amax(), "period 2, not 1");
        }
    }
}

#[test]
fn scenes_without_an_exact_flow_are_refused_before_any_transient() {
    // Mode transfer changes the basis at contact (not yet a map of one
    // state vector), the rotating beam has no flow: refused up front with
    // the reason, not by a transient that runs into its work cap.
    for (file, said) in [("spring_stop_soft", "uses mode transfer"), ("rotating_beam", "(kind 'rotating') has none")] {
        let mut text = std::fs::read_to_string(format!("{}/scenes/{file}.json", env!("CARGO_MANIFEST_DIR"))).unwrap();
        if file == "spring_stop_soft" {
            text = text.replace(r#""type": "spring_dashpot","#, r#""type": "spring_dashpot", "method": "rmtm","#);
        }
        let scene = Component::from_json(&text).unwrap();
        let first = scene.parameters()[0].name.clone();
        let value = scene.get(0);
        let mut settings = Continuation::new(&first, value, value + 1.0);
        settings.forcing = Some(first.clone());
        let clock = std::time::Instant::now();
        let e = continue_orbits(&scene, &settings).unwrap_err();
        assert!(e.contains("periodic orbits need the exact flow") && e.contains(said), "{file}: {e}");
        assert!(clock.elapsed().as_secs_f64() < 0.5, "{file}: refused after {:?}", clock.elapsed());
    }
}

/// The three-mass chain of issue 44 (c = 0.05, stop on mass 3 at 0.5).
fn chain3() -> Component {
    let text = r#"{"name": "Chain3Stop", "structure": {"type": "chain", "masses": 3, "m": 1.0, "k": 1.0, "c": 0.05},
        "loads": [{"type": "point_harmonic", "name": "A1", "mass": 1, "amplitude": 0.3, "omega": 0.5, "waveform": "cos"}],
        "stops": [{"name": "stop", "mass": 3, "gap": 0.5, "side": "positive", "law": {"type": "restitution", "R": 0.8, "eps": 1e-6}}]}"#;
    Component::from_json(text).unwrap()
}

#[test]
fn an_orbit_is_reported_over_its_minimal_period() {
    // At omega = 0.8 the transient's sections repeat best after 7 forcing
    // periods, but the orbit found there is of period 1.
    let mut settings = Continuation::new("A1.omega", 0.3, 2.0);
    settings.starts = vec![0.8];
    settings.points = 20;
    settings.max_branches = 1;
    let scene = chain3();
    let d = continue_orbits(&scene, &settings).unwrap();
    let b = &d.branches[0];
    assert_eq!(b.periods, 1);
    let at = b.points.iter().find(|p| p.param == 0.8).expect("the start is a point");
    let period = 2.0 * PI / 0.8;
    assert!((at.orbit.period - period).abs() < 1e-12 * period, "{}", at.orbit.period);
    // Its multipliers are those of one period (Phi, not Phi^7: the largest
    // is 0.962 here, 0.762 over seven).
    let mut s = scene.clone();
    let omega = s.parameters().iter().position(|p| p.name == "A1.omega").unwrap();
    s.set(omega, 0.8);
    let one = shoot(&s, 0.0, period, &at.orbit.state, Shooting::default()).unwrap();
    assert_eq!(one.multipliers.len(), at.orbit.multipliers.len());
    let mut a: Vec<f64> = one.multipliers.iter().map(|z| z.norm()).collect();
    let mut b: Vec<f64> = at.orbit.multipliers.iter().map(|z| z.norm()).collect();
    a.sort_by(f64::total_cmp);
    b.sort_by(f64::total_cmp);
    for (x, y) in a.iter().zip(&b) {
        assert!((x - y).abs() < 1e-9, "{a:?} against {b:?}");
    }
}

/// Where the chain's linear response at mass 3 has the gap's amplitude:
/// `|X3(omega)| * A = 0.5`, `X = (K - omega^2 M + i omega C)^-1 e1`
/// (fixed-free chain, unit masses and springs, C = 0.05 K), by bisection.
fn chain3_grazing(lo: f64, hi: f64) -> f64 {
    use nalgebra::{Complex, Matrix3, Vector3};
    let excess = |w: f64| {
        let k = Matrix3::new(2.0, -1.0, 0.0, -1.0, 2.0, -1.0, 0.0, -1.0, 1.0);
        let a: Matrix3<Complex<f64>> = k.map(|v| Complex::new(v - 0.0, 0.05 * w * v)) - Matrix3::identity().map(|v: f64| Complex::new(w * w * v, 0.0));
        let x = a.lu().solve(&Vector3::new(Complex::new(0.3, 0.0), Complex::new(0.0, 0.0), Complex::new(0.0, 0.0))).unwrap();
        x[2].norm() - 0.5
    };
    let (mut a, mut b) = (lo, hi);
    assert!(excess(a) * excess(b) < 0.0);
    for _ in 0..200 {
        let m = 0.5 * (a + b);
        if excess(m) * excess(a) > 0.0 {
            a = m;
        } else {
            b = m;
        }
    }
    0.5 * (a + b)
}

#[test]
fn the_chain_reports_both_grazings_and_follows_the_smooth_orbits_between() {
    // From the impacting branch below omega = 0.6123, whose slow impact
    // vanishes where the linear orbit grazes, on along the linear orbits
    // (upwards: the branch turns back at the grazing) to the next grazing.
    let mut settings = Continuation::new("A1.omega", 0.58, 1.2);
    // The one branch from 0.58 passes both (the far end's cascade above
    // 1.1352 is the next test's).
    settings.max_branches = 1;
    let d = continue_orbits(&chain3(), &settings).unwrap();
    let grazings: Vec<f64> = d.special.iter().filter(|s| s.kind == SpecialKind::Grazing).map(|s| s.point.param).collect();
    for exact in [chain3_grazing(0.6, 0.62), chain3_grazing(1.1, 1.2)] {
        let found = grazings.iter().copied().min_by(|a, b| (a - exact).abs().total_cmp(&(b - exact).abs())).unwrap();
        assert!((found - exact).abs() < 1e-8 * exact, "grazing at {exact}: nearest reported {found} ({grazings:?})");
    }
    // Between them the smooth orbits: no impact, period 1.
    let smooth = d.branches.iter().flat_map(|b| &b.points).filter(|p| p.param > 0.62 && p.param < 1.13).collect::<Vec<_>>();
    assert!(smooth.len() >= 10 && smooth.iter().all(|p| p.profile.impacts == 0), "{} points", smooth.len());
}

#[test]
fn the_chain_between_its_grazings_is_covered_from_the_middle() {
    // Between the grazings at omega = 1.1352 and 1.3379 the linear orbit
    // passes the stop, and Newton finds no impacting orbit beyond either
    // grazing (past the first, a period-adding cascade accumulates on it).
    // Without starts, after FROM and TO, a transient in the middle of
    // that stretch starts the orbits with one impact every two periods.
    let mut settings = Continuation::new("A1.omega", 1.0, 1.6);
    settings.max_branches = 3;
    let d = continue_orbits(&chain3(), &settings).unwrap();
    let spans: Vec<(usize, f64, f64)> = d
        .branches
        .iter()
        .map(|b| (b.periods, b.points.iter().map(|p| p.param).fold(f64::INFINITY, f64::min), b.points.iter().map(|p| p.param).fold(f64::NEG_INFINITY, f64::max)))
        .collect();
    let grazings = [chain3_grazing(1.1, 1.2), chain3_grazing(1.3, 1.4)];
    assert!(spans.iter().any(|&(m, a, z)| m == 1 && a == 1.0 && (z - grazings[0]).abs() < 1e-8), "{spans:?}");
    assert!(spans.iter().any(|&(m, a, z)| m == 1 && z == 1.6 && (a - grazings[1]).abs() < 1e-8), "{spans:?}");
    let middle = d.branches.iter().find(|b| b.periods == 2).expect("a branch of period 2");
    let at = |w: f64| middle.points.iter().min_by(|a, b| (a.param - w).abs().total_cmp(&(b.param - w).abs())).unwrap();
    for w in [1.2, 1.25, 1.3, 1.34] {
        let p = at(w);
        assert!((p.param - w).abs() < 0.01 && p.profile.impacts == 1, "near {w}: {} with {} impacts", p.param, p.profile.impacts);
    }
    assert!(middle.points.iter().any(|p| p.orbit.stable()) && middle.points.iter().any(|p| !p.orbit.stable()));
}

#[test]
fn steps_follow_the_orbits_size_to_the_grazing() {
    // A clamped-clamped beam against a spring stop: its orbit grows eleven
    // times from omega = 10 to the grazing at 20.83. Scaled by the first
    // orbit's size the steps shrank to 8e-4 and the default run stopped at
    // its 2,050-point limit at omega = 20.77.
    let text = r#"{"name": "CCBeamSpring", "structure": {"type": "beam", "support": "clamped-clamped", "modes": 3}, "damping": {"zeta": 0.02},
        "loads": [{"type": "point_harmonic", "name": "P", "x": 0.5, "amplitude": 2.0, "omega": 15.0, "waveform": "sin"}],
        "stops": [{"name": "stop", "x": 0.3, "gap": 0.05, "side": "positive", "law": {"type": "spring_dashpot", "k": 500.0, "c": 0.0}}]}"#;
    let scene = Component::from_json(text).unwrap();
    let mut settings = Continuation::new("P.omega", 10.0, 35.0);
    settings.max_branches = 1;
    let d = continue_orbits(&scene, &settings).unwrap();
    let grazing = d.special.iter().find(|s| s.kind == SpecialKind::Grazing).expect("a grazing");
    assert!((grazing.point.param - 20.825943703).abs() < 1e-6, "{}: {}", grazing.point.param, grazing.note);
    assert!(grazing.point.profile.closest.is_some_and(|c| c.gap.abs() < 1e-10), "{}", grazing.note);
    // And on, round its folds, to the end of the range.
    assert!(d.special.iter().any(|s| s.kind == SpecialKind::End && s.point.param == 35.0), "{:?}", d.special.iter().map(|s| &s.note).collect::<Vec<_>>());
}

/// The impact oscillator of issue 44: c = 0.2, omega = 0.8, gap 0.5, R = 0.8.
fn oscillator_44() -> Component {
    let text = r#"{"name": "ImpactOscillator", "structure": {"type": "chain", "masses": 1, "m": 1.0, "k": 1.0, "c": 0.2},
        "loads": [{"type": "point_harmonic", "name": "A1", "mass": 1, "amplitude": 0.0985, "omega": 0.8, "waveform": "cos"}],
        "stops": [{"name": "stop", "mass": 1, "gap": 0.5, "side": "positive", "law": {"type": "restitution", "R": 0.8, "eps": 1e-9}}],
        "experiment": {"start": 0, "stop": 200, "step": 0.05}}"#;
    Component::from_json(text).unwrap()
}

#[test]
fn a_map_state_on_a_stop_to_rounding_is_on_it() {
    let scene = oscillator(0.15);
    // Beyond the stop (d = 1) by 2.4e-10, approaching: started on the stop,
    // where its impact comes at once.
    let x = DVector::from_vec(vec![1.0 + 2.4e-10, 0.3]);
    let mut run = start_from(&scene, 0.0, &x).unwrap();
    let c = run.flow().unwrap().clearances()[0];
    assert!(c.gap == 0.0 && c.displacement == 1.0, "{c:?}");
    // The stop's law acts at t0: the impact, R = 0.8.
    assert!((run.flow().unwrap().state()[1] + 0.8 * 0.3).abs() < 1e-15, "{}", run.flow().unwrap().state());
    run.advance_to(0.1).unwrap();
    let after = run.flow().unwrap().state();
    assert!(after[0] < 1.0 && after[1] < 0.0, "bounced off the stop: {after}");
    // Deeper than 1e-8 of the stop's scale: refused, as an initial state is.
    let deep = start_from(&scene, 0.0, &DVector::from_vec(vec![1.0 + 1e-7, 0.3])).unwrap_err();
    assert!(deep.contains("penetrates"), "{deep}");
}

fn diagram_44(from: f64) -> beamstop::orbits::Diagram {
    let settings = Continuation::new("A1.amplitude", from, 0.3939543120718441);
    continue_orbits(&oscillator_44(), &settings).unwrap()
}

#[test]
fn rounding_does_not_end_branches_or_move_special_points() {
    // FROM and one ulp less: before, the period-1 branch ended at A =
    // 0.3545 on an iterate 2.4e-10 inside the stop (its impact passes
    // through the section there), and the period-2 branch had 30 points
    // or 199.
    let (a, b) = (diagram_44(0.09848857801796104), diagram_44(0.09848857801796103));
    for d in [&a, &b] {
        assert!(d.special.iter().all(|s| !s.note.contains("penetrates")), "{:?}", d.special.iter().map(|s| &s.note).collect::<Vec<_>>());
        let ends: Vec<f64> = d.special.iter().filter(|s| s.branch == 0 && s.kind == SpecialKind::End).map(|s| s.point.param).collect();
        assert!(ends.contains(&0.3939543120718441), "branch 0 ends at {ends:?}");
    }
    assert_eq!(a.branches.len(), b.branches.len());
    let key = |d: &beamstop::orbits::Diagram| {
        let mut v: Vec<(usize, &'static str, f64)> = d.special.iter().map(|s| (s.branch, s.kind.code(), s.point.param)).collect();
        v.sort_by(|x, y| (x.0, x.1).cmp(&(y.0, y.1)).then(x.2.total_cmp(&y.2)));
        v
    };
    let (ka, kb) = (key(&a), key(&b));
    assert_eq!(ka.len(), kb.len(), "{ka:?}\n{kb:?}");
    for (x, y) in ka.iter().zip(&kb) {
        assert!(x.0 == y.0 && x.1 == y.1 && (x.2 - y.2).abs() <= 1e-9 * x.2.abs(), "{x:?} against {y:?}\n{ka:?}\n{kb:?}");
    }
    // The period-2 branch ends where it meets the period-1 orbit's grazing.
    let grazing = ka.iter().find(|s| s.0 == 0 && s.1 == "GR").unwrap().2;
    let end = ka.iter().filter(|s| s.0 == 1 && s.1 == "EP").map(|s| s.2).fold(f64::INFINITY, f64::min);
    assert!((end - grazing).abs() <= 1e-9 * grazing, "{end} against {grazing}");
}

/// A scene with its integration tolerance set.
fn with_tolerance(mut scene: Component, tol: f64) -> Component {
    let i = scene.parameters().iter().position(|q| q.name == "solver.integration_tolerance").unwrap();
    scene.set(i, tol);
    scene.validate().unwrap();
    scene
}

/// The monodromy matrix over `period` at `x` by central differences of
/// the simulation (step `h` of the state's largest coordinate).
fn monodromy_by_differences(scene: &Component, x: &DVector<f64>, period: f64, h: f64) -> nalgebra::DMatrix<f64> {
    let h = h * x.amax();
    let mut m = nalgebra::DMatrix::zeros(x.len(), x.len());
    for k in 0..x.len() {
        let end = |s: f64| {
            let mut y = x.clone();
            y[k] += s * h;
            strobe_over(scene, &y, period)
        };
        m.set_column(k, &((end(1.0) - end(-1.0)) / (2.0 * h)));
    }
    m
}

/// The largest distance from each multiplier to the nearest eigenvalue of `m`.
fn multipliers_against(multipliers: &[C64], m: &nalgebra::DMatrix<f64>) -> f64 {
    let other: Vec<C64> = m.complex_eigenvalues().iter().copied().collect();
    multipliers.iter().map(|z| other.iter().map(|w| (z - w).norm()).fold(f64::INFINITY, f64::min)).fold(0.0, f64::max)
}

/// Newton from the orbit `x` moved by `fraction` of its size in every
/// coordinate: the residuals, which fall quadratically to the integration
/// tolerance.
fn residuals_from_moved(scene: &Component, x: &DVector<f64>, period: f64, fraction: f64, tolerance: f64) -> Vec<f64> {
    let size = x.amax();
    let moved = DVector::from_fn(x.len(), |k, _| x[k] + fraction * size * if k % 2 == 0 { 1.0 } else { -1.0 });
    let orbit = shoot(scene, 0.0, period, &moved, Shooting { tolerance, ..Shooting::default() }).unwrap();
    assert!((&orbit.state - x).amax() < 1e-8 * size, "Newton from the moved state found another orbit");
    orbit.residuals
}

#[test]
fn hertz_stop_orbit_newton_and_multipliers() {
    // 2.1 s: with BEAMSTOP_FULL_TESTS only (scripts/test --full).
    if std::env::var_os("BEAMSTOP_FULL_TESTS").is_none() {
        eprintln!("skipped: set BEAMSTOP_FULL_TESTS=1");
        return;
    }
    // HertzStop at its own forcing, tolerance 1e-12: the period-1 orbit
    // with seven contacts per period from a transient, Newton again from
    // it moved by 1e-3, and its multipliers against the eigenvalues of a
    // monodromy matrix from central differences of the simulation.
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/hertz_stop.json")).unwrap();
    let scene = with_tolerance(Component::from_json(&text).unwrap(), 1e-12);
    let period = 2.0 * PI / 136.49234534301007;
    let guess = strobe(&scene, 0.0, period, 60).unwrap();
    let orbit = shoot(&scene, 0.0, period, &guess, Shooting { tolerance: 1e-10, ..Shooting::default() }).unwrap();
    let again = residuals_from_moved(&scene, &orbit.state, period, 1e-3, 1e-11);
    let cd = monodromy_by_differences(&scene, &orbit.state, period, 1e-6);
    let diff = multipliers_against(&orbit.multipliers, &cd);
    let largest = orbit.multipliers.iter().map(|z| z.norm()).fold(0.0, f64::max);
    eprintln!("HertzStop: {} contacts per period, residuals {:?}, from 1e-3 away {again:?}, largest multiplier {largest:.6}, multipliers against differences {diff:e}", orbit.impacts_per_period, orbit.residuals);
    assert!(orbit.impacts_per_period >= 2 && orbit.stable());
    assert!(quadratic(&again) && *again.last().unwrap() < 1e-11, "{again:?}");
    assert!(diff < 1e-5, "multipliers {diff:e} from the differences'");
}

#[test]
fn hertz_oscillator_orbit_newton_and_multipliers() {
    // The one-mass oscillator with a Hertz stop (LN90) at A = 0.15, tolerance 1e-12.
    let scene = Component::from_json(&hertz_oscillator_text(0.15)).unwrap();
    let guess = strobe(&scene, 0.0, T, 10).unwrap();
    let orbit = shoot(&scene, 0.0, T, &guess, Shooting { tolerance: 1e-11, ..Shooting::default() }).unwrap();
    let cd = monodromy_by_differences(&scene, &orbit.state, T, 1e-6);
    let diff = multipliers_against(&orbit.multipliers, &cd);
    eprintln!("Hertz oscillator: {} contacts per period, residuals {:?}, multipliers {:?} against differences {diff:e}", orbit.impacts_per_period, orbit.residuals, orbit.multipliers);
    assert_eq!(orbit.impacts_per_period, 1);
    assert!(quadratic(&orbit.residuals) && *orbit.residuals.last().unwrap() < 1e-11, "{:?}", orbit.residuals);
    assert!(diff < 1e-5, "multipliers {diff:e} from the differences'");
}

/// The one-mass oscillator of issue 44 with a Hertz stop (K = 1e6, LN90, e = 0.8).
fn hertz_oscillator_text(amplitude: f64) -> String {
    hertz_oscillator_at(amplitude, r#", "solver": {"integration_tolerance": 1e-12}"#)
}

/// The same at the scene's default tolerance (`solver`: `""`), or with the given solver member.
fn hertz_oscillator_at(amplitude: f64, solver: &str) -> String {
    format!(
        r#"{{"name": "HertzOscillator", "structure": {{"type": "chain", "masses": 1, "m": 1.0, "k": 1.0, "c": 0.1}},
        "loads": [{{"type": "point_harmonic", "name": "A1", "mass": 1, "amplitude": {amplitude}, "omega": 1.0, "waveform": "cos"}}],
        "stops": [{{"name": "stop", "mass": 1, "gap": 1.0, "side": "positive", "law": {{"type": "hertz", "K": 1e6, "damping": "lankarani_nikravesh", "e": 0.8}}}}]{solver},
        "experiment": {{"start": 0, "stop": 200, "step": 0.05}}}}"#
    )
}

#[test]
fn hertz_oscillator_grazing_and_both_branches() {
    // Continued in A from 0.05 to 0.2: the linear orbit, grazing where its
    // amplitude 10 A reaches the gap (A = d sqrt((k - w^2)^2 + (c w)^2) =
    // 0.1; the compliant stop adds no impact speed: its closest approach
    // reaches zero), and the contacting branch beyond, one contact per
    // period, its peak inside the stop.
    let scene = Component::from_json(&hertz_oscillator_at(0.05, "")).unwrap();
    let mut settings = Continuation::new("A1.amplitude", 0.05, 0.2);
    settings.points = 20;
    let diagram = continue_orbits(&scene, &settings).unwrap();
    let grazing: Vec<_> = diagram.special.iter().filter(|s| s.kind == SpecialKind::Grazing).collect();
    assert_eq!(grazing.len(), 1, "{:#?}", diagram.special.iter().map(|s| (s.kind, s.point.param, &s.note)).collect::<Vec<_>>());
    let a = grazing[0].point.param;
    let points: usize = diagram.branches.iter().map(|b| b.points.len()).sum();
    eprintln!("Hertz oscillator: grazing at A = {a:.15} (relative error {:.1e}), {} branches, {points} points, {} map evaluations", (a - 0.1) / 0.1, diagram.branches.len(), diagram.evaluations);
    assert!((a - 0.1).abs() < 1e-8 * 0.1, "grazing at A = {a}");
    let all: Vec<_> = diagram.branches.iter().flat_map(|b| b.points.iter()).collect();
    assert!(all.iter().any(|p| p.param <= 0.05 + 1e-12) && all.iter().any(|p| p.param >= 0.2 - 1e-12));
    for p in &all {
        if p.param < a - 1e-9 {
            assert_eq!(p.profile.impacts, 0, "A = {}", p.param);
            assert!((p.profile.peak - 10.0 * p.param).abs() < 1e-9, "A = {}: peak {}", p.param, p.profile.peak);
        } else if p.param > a + 1e-6 {
            assert_eq!(p.profile.impacts, 1, "A = {}", p.param);
            assert!(p.profile.peak > 1.0, "A = {}: peak {} not inside the stop", p.param, p.profile.peak);
        }
    }
}

#[test]
fn mtm_spring_stop_orbit_newton_and_multipliers() {
    // The hard spring stop (20 modes) with mode transfer by MTM at its
    // forcing (1.3 omega_1): Newton from a transient, multipliers against
    // central differences (step 1e-6).
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/spring_stop_hard.json")).unwrap();
    let scene = Component::from_json(&text.replace(r#""type": "spring_dashpot","#, r#""type": "spring_dashpot", "method": "mtm","#)).unwrap();
    let period = 2.0 * PI / 136.49234534301007;
    let guess = strobe(&scene, 0.0, period, 12).unwrap();
    let orbit = shoot(&scene, 0.0, period, &guess, Shooting::default()).unwrap();
    let cd = monodromy_by_differences(&scene, &orbit.state, period, 1e-6);
    let diff = multipliers_against(&orbit.multipliers, &cd);
    let largest = orbit.multipliers.iter().map(|z| z.norm()).fold(0.0, f64::max);
    eprintln!("SpringStopHard, MTM: {} contacts per period, residuals {:?}, largest multiplier {largest:.6}, multipliers against differences {diff:e}", orbit.impacts_per_period, orbit.residuals);
    assert!(orbit.impacts_per_period >= 1);
    assert!(quadratic(&orbit.residuals) && *orbit.residuals.last().unwrap() < 1e-12, "{:?}", orbit.residuals);
    assert!(diff < 1e-5, "multipliers {diff:e} from the differences'");
}
