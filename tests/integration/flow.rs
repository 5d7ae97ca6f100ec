//! The exact flow's Jacobian (phase transition matrices and saltation
//! matrices, `src/sim/flow.rs`) against central finite differences of the
//! simulation itself: runs restarted at `t0` from the state there moved by
//! `+-h` in one coordinate. The step is where the differences are most
//! accurate: 1e-7 of the state's largest coordinate where their error
//! falls as h^2 (the free beam, the spring stop: 5e-10 there), 1e-5 where
//! it grows as 1/h, the rounding of some thirty event times (the forced
//! scenes: 5e-9 and 4e-8 there). `cargo test --release --test integration flow:: --
//! --nocapture` prints each.
//! Every event kind of the closed-form laws away from threshold
//! decisions: restitution impacts, a chatter sequence ending in a stick
//! (the eps rule decides the same on both sides), the stuck phase and its
//! release, a spring-dashpot stop's onset and separation with the dashpot's
//! jump in the vector field. Integrated Hertz contacts (issue 44) at the
//! tolerance 1e-12 with the step 1e-6: the one-mass oscillator with LN90
//! damping (1e-7) and with a linear damping, whose force jumps at the
//! onset (4e-8), and HertzStop's 20 modes over a forcing period.

use crate::common;

use beamstop::kinds::modal::interface::ParamKey;
use beamstop::kinds::modal::sim::state_vector;
use beamstop::solve::ModalState;
use beamstop::kinds::modal::{model::Model, scene::Scene, sim::Simulation};
use nalgebra::{DMatrix, DVector};

fn with(mut scene: Scene, values: &[(ParamKey, f64)]) -> Scene {
    for &(k, v) in values {
        k.set(&mut scene, v);
    }
    scene
}

fn modal(x: &DVector<f64>) -> ModalState {
    let n = x.len() / 2;
    ModalState { q: x.rows(0, n).into_owned(), qd: x.rows(n, n).into_owned() }
}

/// A run of `model` started at `t0` in state `x`.
fn start(model: &Model, t0: f64, x: &DVector<f64>) -> Simulation {
    let mut m = model.clone();
    m.initial = modal(x);
    Simulation::new(m, t0).unwrap()
}

/// The Jacobian over `[t0, t1]` (from the model's own state at `t0`), its
/// largest difference from central differences with the step `h_rel` of
/// the state's largest coordinate, relative to its largest entry, and the
/// events it went through.
fn check(model: Model, t0: f64, t1: f64, h_rel: f64) -> (DMatrix<f64>, f64, usize) {
    let mut sim = Simulation::new(model.clone(), 0.0).unwrap();
    sim.advance_to(t0).unwrap();
    let x0 = state_vector(sim.current());
    let mut run = start(&model, t0, &x0);
    run.set_event_recording(true);
    let jac = run.advance_with_jacobian(t1).unwrap();
    let events = run.drain_events().len();
    // The same trajectory as a plain advance, bit for bit.
    let mut plain = start(&model, t0, &x0);
    plain.advance_to(t1).unwrap();
    assert_eq!(state_vector(plain.current()), state_vector(run.current()), "advance_with_jacobian moves as advance_to does");
    let h = h_rel * x0.amax();
    let mut fd = DMatrix::zeros(x0.len(), x0.len());
    for k in 0..x0.len() {
        let end = |s: f64| {
            let mut x = x0.clone();
            x[k] += s * h;
            let mut r = start(&model, t0, &x);
            r.advance_to(t1).unwrap();
            state_vector(r.current())
        };
        fd.set_column(k, &((end(1.0) - end(-1.0)) / (2.0 * h)));
    }
    let err = (&jac - &fd).amax() / jac.amax();
    eprintln!("[{t0}, {t1}]: {events} events, h = {h_rel:e} of the state: relative difference {err:e}");
    (jac, err, events)
}

#[test]
fn restitution_impacts() {
    // The free pinned beam with a light damping, R = 0.7: impacts only.
    let scene = with(
        common::scene("pinned_beam"),
        &[(ParamKey::LoadAmplitude(0), 0.0), (ParamKey::Zeta, 0.01), (ParamKey::InitialQ(0), -3.0 / 2f64.sqrt()), (ParamKey::InitialQ(1), 0.3)],
    );
    let (_, err, events) = check(Model::build(&scene).unwrap(), 0.05, 0.6, 1e-7);
    assert!(events >= 3, "{events} events");
    assert!(err < 1e-7, "relative difference {err:e} over {events} events");
}

#[test]
fn forced_impacts_of_figure_4() {
    // VSM12's Figure 4 scene in free flight after the first release, up to
    // before the chatter: impacts under the load.
    let (_, err, events) = check(Model::build(&common::scene("pinned_beam")).unwrap(), 4.0, 6.45, 1e-5);
    assert!(events >= 2, "{events} events");
    assert!(err < 1e-7, "relative difference {err:e} over {events} events");
}

#[test]
fn chatter_stick_and_release() {
    // From free flight through a chatter sequence that ends stuck (the eps
    // rule decides it), the stuck phase, the release, free flight.
    let (jac, err, events) = check(Model::build(&common::scene("pinned_beam")).unwrap(), 6.52, 9.8, 1e-5);
    assert!(events >= 4, "{events} events");
    assert!(err < 1e-7, "relative difference {err:e} over {events} events");
    assert!(jac.iter().all(|x| x.is_finite()));
}

#[test]
fn spring_dashpot_onset_and_separation() {
    // The soft spring stop with a dashpot: the vector field jumps by the
    // dashpot's force at the onset.
    let scene = with(common::scene("spring_stop_soft"), &[(ParamKey::Law(0, 1), 0.5)]);
    let (_, err, events) = check(Model::build(&scene).unwrap(), 0.05, 0.2, 1e-7);
    assert!(events >= 2, "{events} events");
    assert!(err < 1e-7, "relative difference {err:e} over {events} events");
}

/// The one-mass oscillator of issue 44 with a Hertz stop (LN90 damping)
/// at the gap 1: `c = 0.1`, `omega = 1`, amplitude `a`.
pub fn hertz_oscillator(a: f64) -> Scene {
    hertz_oscillator_with(a, r#""damping": "lankarani_nikravesh", "e": 0.8"#)
}

pub fn hertz_oscillator_with(a: f64, damping: &str) -> Scene {
    Scene::from_json(&format!(
        r#"{{"name": "HertzOscillator", "structure": {{"type": "chain", "masses": 1, "m": 1.0, "k": 1.0, "c": 0.1}},
         "loads": [{{"type": "point_harmonic", "name": "A1", "mass": 1, "amplitude": {a}, "omega": 1.0, "waveform": "cos"}}],
         "stops": [{{"name": "stop", "mass": 1, "gap": 1.0, "side": "positive", "law": {{"type": "hertz", "K": 1e6, {damping}}}}}],
         "solver": {{"integration_tolerance": 1e-12}},
         "experiment": {{"start": 0, "stop": 200, "step": 0.05}}}}"#
    ))
    .unwrap()
}

#[test]
fn hertz_oscillator_contacts() {
    // Integrated Hertz contacts with the onset speed's damping: over three
    // forcing periods of the contacting orbit's transient.
    let model = Model::build(&hertz_oscillator(0.15)).unwrap();
    let t0 = 20.0;
    let (_, err, events) = check(model, t0, t0 + 3.0 * std::f64::consts::TAU, 1e-6);
    assert!(events >= 4, "{events} events");
    assert!(err < 1e-5, "relative difference {err:e} over {events} events");
}

#[test]
fn hertz_stop_beam_contacts() {
    // HertzStop (20 modes) at its forcing, tolerance 1e-12, over one
    // forcing period after a transient.
    let scene = with(common::scene("hertz_stop"), &[(ParamKey::IntegrationTolerance, 1e-12)]);
    let model = Model::build(&scene).unwrap();
    let period = std::f64::consts::TAU / 136.49234534301007;
    let t0 = 20.0 * period;
    let (_, err, events) = check(model, t0, t0 + period, 1e-6);
    assert!(events >= 2, "{events} events");
    assert!(err < 1e-5, "relative difference {err:e} over {events} events");
}



#[test]
fn hertz_linear_damping_jump() {
    // DWZ's linear damping: the force jumps by C v0 at the onset, so the
    // saltation there is not the identity; the push ends inside the stop.
    let model = Model::build(&hertz_oscillator_with(0.15, r#""C": 100.0"#)).unwrap();
    let (_, err, events) = check(model, 20.0, 20.0 + 3.0 * std::f64::consts::TAU, 1e-6);
    assert!(events >= 4, "{events} events");
    assert!(err < 1e-5, "relative difference {err:e} over {events} events");
}

/// A shipped spring-stop scene with its stop's contact method.
fn with_method(name: &str, method: &str) -> Scene {
    let text = std::fs::read_to_string(format!("{}/scenes/{name}.json", env!("CARGO_MANIFEST_DIR"))).unwrap();
    Scene::from_json(&text.replace(r#""type": "spring_dashpot","#, &format!(r#""type": "spring_dashpot", "method": "{method}","#))).unwrap()
}

/// The first time after `from` at which the run is in free flight, on a
/// grid of `step`.
fn free_flight_after(model: &Model, from: f64, step: f64) -> f64 {
    let mut sim = Simulation::new(model.clone(), 0.0).unwrap();
    let mut t = from;
    loop {
        sim.advance_to(t).unwrap();
        if (0..model.stops.len()).all(|i| sim.contact(i) == beamstop::contact::Contact::Open) {
            return t;
        }
        t += step;
    }
}

#[test]
fn mode_transfer_mtm_switches() {
    // MTM on the hard spring stop (20 modes) at its forcing: from free
    // flight over a forcing period with its contacts, each switch a change
    // of basis (the reset's Jacobian with its saltation).
    let model = Model::build(&with_method("spring_stop_hard", "mtm")).unwrap();
    let period = 2.0 * std::f64::consts::PI / model.loads.harmonics[0].omega;
    let t0 = free_flight_after(&model, 10.0 * period, period / 50.0);
    let (_, err, events) = check(model, t0, t0 + period, 1e-7);
    assert!(events >= 2, "{events} events");
    assert!(err < 1e-7, "relative difference {err:e} over {events} events");
}
