//! Periodic orbits by Newton shooting with the exact monodromy matrix
//! (`beamstop::orbits`), against what is known in closed form: the single
//! impact oscillator `x'' + c x' + k x = A cos(w t)` with a rigid stop at
//! `x = d` (a one-mass chain; c = 0.1, k = 1, w = 1, d = 1, R = 0.8).

use std::f64::consts::PI;

use beamstop::component::Component;
use beamstop::orbits::{shoot, strobe, Shooting};
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
    let mut run = beamstop::orbits::start_from(scene, 0.0, x).unwrap();
    run.advance_to(T).unwrap();
    run.flow().unwrap().state()
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
