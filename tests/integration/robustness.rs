//! Robustness: degenerate states that must start and stay at rest, work
//! that must stay bounded, and restored states that must be ones the model
//! can be in. Each case compares with what the physics says (a structure at
//! rest under no load stays exactly at rest) or checks a promise (a bounded
//! number of search points, a refused corrupted state).

use crate::common;

use beamstop::kinds::modal::interface::ParamKey;
use beamstop::contact::Contact;
use beamstop::kinds::modal::sim::SimState;
use beamstop::SimError;
use beamstop::kinds::modal::{sim::EventKind, model::Model, scene::Scene, sim::Simulation};

fn with(mut scene: Scene, values: &[(ParamKey, f64)]) -> Scene {
    for (k, v) in values {
        k.set(&mut scene, *v);
    }
    scene
}

fn start(scene: &Scene) -> Simulation {
    Simulation::new(Model::build(scene).unwrap(), 0.0).unwrap_or_else(|e| panic!("start: {e}"))
}

/// At rest on the stop (gap 0) under each kind of "no load": the state
/// stays exactly zero, the reaction zero, and the run costs a handful of
/// search points, not a million events.
#[test]
fn at_rest_on_the_stop_stays_at_rest() {
    let pinned = common::scene("pinned_beam");
    let cases = [
        ("F = 0", vec![(ParamKey::LoadAmplitude(0), 0.0)]),
        ("omega = 0 (sin load)", vec![(ParamKey::LoadOmega(0), 0.0)]),
        ("F = 0, zeta = 0", vec![(ParamKey::LoadAmplitude(0), 0.0), (ParamKey::Zeta, 0.0)]),
        ("omega = 0, zeta = 0", vec![(ParamKey::LoadOmega(0), 0.0), (ParamKey::Zeta, 0.0)]),
    ];
    for (label, values) in cases {
        let mut sim = start(&with(pinned.clone(), &values));
        for k in 1..=100 {
            sim.advance_to(k as f64).unwrap_or_else(|e| panic!("{label}: {e}"));
        }
        let c = sim.current();
        assert!(c.q.iter().chain(c.qd.iter()).all(|x| *x == 0.0), "{label}: moved: {c:?}");
        assert_eq!(sim.reaction(0), 0.0, "{label}");
        assert!(sim.stats().probes < 10_000, "{label}: {} search points for 100 time units at rest", sim.stats().probes);
        let events: Vec<_> = sim.drain_events();
        assert!(events.iter().all(|e| !matches!(e.kind, EventKind::Impact { .. })), "{label}: impacts at rest: {events:?}");
    }
}

/// A load a hundred orders of magnitude below the scene's scale (omega =
/// 1e-100) is a static zero load for any horizon: the beam stays on the
/// stop, and stepping costs what it costs at rest.
#[test]
fn a_vanishing_load_frequency_does_not_crawl() {
    for omega in [5e-324, 1e-300, 1e-100, 1e-20] {
        let mut sim = start(&with(common::scene("pinned_beam"), &[(ParamKey::LoadOmega(0), omega)]));
        sim.advance_to(10.0).unwrap_or_else(|e| panic!("omega = {omega}: {e}"));
        assert!(sim.stats().probes < 10_000, "omega = {omega}: {} search points", sim.stats().probes);
        let w = sim.model().stops[0].geometry.w.dot(&sim.current().q);
        assert!(w.abs() < 1e-12, "omega = {omega}: left the stop, w = {w}");
    }
}

/// Grazing from rest: at rest on the stop with the load pulling away, the
/// beam leaves without an impact; pushing into it, it sticks.
#[test]
fn grazing_from_rest() {
    let away = with(common::scene("pinned_beam"), &[(ParamKey::LoadAmplitude(0), -76.8)]);
    let mut sim = start(&away);
    sim.advance_to(3.0).unwrap();
    assert!(sim.state().stops[0].impacts == 0 && !sim.is_stuck(0));
    let w = sim.model().stops[0].geometry.w.dot(&sim.current().q);
    assert!(w < -1e-3, "did not leave: w = {w}");
    let toward = common::scene("pinned_beam");
    let mut sim = start(&toward);
    sim.advance_to(1.0).unwrap();
    assert!(sim.is_stuck(0), "a load pushing into the stop from rest holds the beam on it");
}

/// A compliant stop at zero gap, touched at rest while the load pushes
/// into it (HertzStop's base excitation; RigidAndHertzStops' Hertz stop
/// beside its rigid one): the contact holds and the run goes on. Its
/// error scale was the contact's alone, nothing at zero gap and speed, and
/// the first step stuck at t = 1e-152 with the contact ending and starting
/// again every 1.5e-156 s.
#[test]
fn a_compliant_stop_touched_at_rest_under_a_load_runs_on() {
    for (name, stop, k, until) in [("hertz_stop", 0, 1e16, 2e-4), ("hertz_stop", 0, 1.088e10, 2e-4), ("rigid_and_hertz", 1, 1e8, 0.05)] {
        let scene = common::scene(name);
        assert_eq!(scene.stops[stop].law.parameters()[0].key, "K", "{name}");
        let scene = with(scene, &[(ParamKey::StopGap(stop), 0.0), (ParamKey::Law(stop, 0), k)]);
        let mut sim = start(&scene);
        sim.advance_to(until).unwrap_or_else(|e| panic!("{name}, K = {k}: {e}"));
        let events = sim.drain_events();
        assert!(events.len() < 20, "{name}, K = {k}: {} events by t = {until}: {events:?}", events.len());
        assert!(sim.stats().probes < 1_000_000, "{name}, K = {k}: {} search points", sim.stats().probes);
    }
}

/// A compliant stop pressed while the rigid stop beside it holds the beam,
/// at the least tolerance: RigidAndHertzStops with both stops at zero gap
/// and a power-law stop (n = 1.1) runs its 3 s, as at tolerance 1e-12 to
/// 1e-12 of the motion's scale. The held stop's drift over a step stayed
/// at 12 ulps of its coordinate whatever the step, above the tolerance:
/// the steps fell to 3e-8 s and the run reached the work cap at t = 2.32.
#[test]
fn a_hold_beside_a_pressed_compliant_stop_runs_at_the_least_tolerance() {
    let text = std::fs::read_to_string(format!("{}/scenes/rigid_and_hertz.json", env!("CARGO_MANIFEST_DIR"))).unwrap();
    let mut json: serde_json::Value = serde_json::from_str(&text).unwrap();
    json["stops"][0]["gap"] = 0.0.into();
    json["stops"][1]["gap"] = 0.0.into();
    json["stops"][1]["law"] = serde_json::json!({ "type": "power_law", "n": 1.1, "K": 3e4 });
    let run = |tolerance: f64| {
        let mut scene = json.clone();
        scene["solver"]["integration_tolerance"] = tolerance.into();
        let mut sim = start(&Scene::from_json(&scene.to_string()).unwrap());
        sim.advance_to(3.0).unwrap_or_else(|e| panic!("tolerance {tolerance:e}: {e}"));
        assert!(sim.state().stops[0].sticks > 0, "tolerance {tolerance:e}: the rigid stop held");
        sim.current().clone()
    };
    let (least, loose) = (run(1e-14), run(1e-12));
    let off = (&least.q - &loose.q).amax() / loose.q.amax();
    assert!(off < 1e-9, "q at tolerances 1e-14 and 1e-12: {off:e} of its scale apart");
}

/// A beam at rest on a rigid stop at zero gap, pressed onto it by a
/// spring-dashpot stop it already penetrates (RigidAndHertzStops' stops,
/// the soft one a spring-dashpot at gap -1e-6, both on the + side), sticks
/// at t = 0 with the reaction that balances the spring there: `(w_r . w_s)
/// / (w_r . w_r)` times `k 1e-6` (the load is zero at t = 0), and stays.
/// The gap's rate read 5e-17 against its estimated noise of 3e-17 (its
/// terms cancel through the coupled phase's basis): taken as leaving, the
/// same zero was found again at t = 0 until the event cap.
#[test]
fn a_beam_pressed_onto_a_rigid_stop_at_rest_sticks_there() {
    let text = std::fs::read_to_string(format!("{}/scenes/rigid_and_hertz.json", env!("CARGO_MANIFEST_DIR"))).unwrap();
    let mut json: serde_json::Value = serde_json::from_str(&text).unwrap();
    json["stops"][0]["gap"] = 0.0.into();
    json["stops"][1]["gap"] = (-1e-6).into();
    json["stops"][1]["law"] = serde_json::json!({ "type": "spring_dashpot", "k": 3e4, "c": 10.0 });
    let model = Model::build(&Scene::from_json(&json.to_string()).unwrap()).unwrap();
    let (wr, ws) = (model.stops[0].geometry.w.clone(), model.stops[1].geometry.w.clone());
    let mut sim = Simulation::new(model, 0.0).unwrap();
    sim.advance_to(1.0).unwrap();
    let events = sim.drain_events();
    assert_eq!(events.len(), 1, "{events:?}");
    let EventKind::Stick { stop: 0, reaction } = events[0].kind else { panic!("{events:?}") };
    assert_eq!(events[0].time, 0.0);
    let expected = wr.dot(&ws) / wr.dot(&wr) * 3e4 * 1e-6;
    assert!((reaction - expected).abs() < 1e-12 * expected.abs(), "reaction {reaction} against {expected}");
    assert!(sim.is_stuck(0), "held at t = 1");
}

/// A linear-damped stop touched while a rigid stop holds the beam: its
/// force jumps by `C v0` at the onset, the hold's reaction turns to a pull
/// at that instant, and the hold is released there, at every tolerance
/// (a fuzzed scene: power law n = 3, C = 300, a rigid stop with R = 0).
/// Left to the phase's search, the release came a sample later at 1e-10,
/// and at 1e-12 to 1e-14 the collocation of the pulling hold failed
/// ("force collocation step fell to 3e-16 s").
#[test]
fn a_hold_is_released_where_a_damped_onset_beside_it_pulls() {
    let text = r#"{
  "name": "DampedOnsetBesideHold",
  "structure": { "type": "beam", "support": "pinned-pinned", "modes": 4 },
  "damping": { "zeta": 0.0 },
  "loads": [ { "type": "distributed_harmonic", "name": "ld", "amplitude": 300, "omega": 100, "waveform": "sin" } ],
  "stops": [
    { "name": "h0", "x": 0.25, "gap": 0.1, "side": "negative", "law": { "type": "power_law", "n": 3.0, "K": 1223047090.4464798, "damping": "linear", "C": 300 } },
    { "name": "r", "x": 0.4, "gap": 0.05, "side": "negative", "law": { "type": "restitution", "R": 0.0, "eps": 1e-6 } }
  ],
  "initial": { "qd": [1.9095754869195014, -27.275682609446733, 0.2893911322350551] }
}"#;
    let json: serde_json::Value = serde_json::from_str(text).unwrap();
    let run = |tolerance: f64| {
        let mut scene = json.clone();
        scene["solver"] = serde_json::json!({ "integration_tolerance": tolerance });
        let mut sim = start(&Scene::from_json(&scene.to_string()).unwrap());
        sim.advance_to(1.0).unwrap_or_else(|e| panic!("tolerance {tolerance:e}: {e}"));
        let events = sim.drain_events();
        let onset = events.iter().position(|e| matches!(e.kind, EventKind::Contact { stop: 0, .. }) && e.time > 0.41).expect("the onset beside the hold");
        assert!(matches!(events[onset + 1].kind, EventKind::Release { stop: 1 }) && events[onset + 1].time == events[onset].time, "tolerance {tolerance:e}: {:?}", &events[onset..onset + 2]);
        sim.current().clone()
    };
    let (loose, tight) = (run(1e-10), run(1e-13));
    let off = (&loose.q - &tight.q).amax() / tight.q.amax();
    assert!(off < 1e-8, "q at tolerances 1e-10 and 1e-13: {off:e} of its scale apart");
}

/// Event-free work is capped too: a load 1e3 times faster than the first
/// mode over a step of 1000 time units stops at the cap with the time it
/// reached, consistent and resumable.
#[test]
fn the_work_of_one_step_is_capped() {
    let mut scene = with(common::scene("pinned_beam"), &[(ParamKey::LoadOmega(0), 1e4), (ParamKey::StopGap(0), 0.5)]);
    scene.solver.max_probes_per_step = Some(20_000);
    let mut sim = start(&scene);
    match sim.advance_to(1000.0) {
        Err(SimError::TooMuchWork { time, work: probes, cap }) => {
            assert_eq!(probes, 20_000);
            assert!(SimError::TooMuchWork { time, work: probes, cap }.to_string().contains("max_probes_per_step"));
            assert!(time > 0.0 && time < 1000.0, "{time}");
            assert_eq!(sim.time(), time);
            // The run goes on from there.
            sim.advance_to(time + 0.01).unwrap();
        }
        other => panic!("expected the work cap, got {other:?}"),
    }
}

/// A restored state is checked like a reached one: each corruption is
/// refused with a message naming what is wrong, and the true state passes.
#[test]
fn restored_states_are_validated() {
    let scene = common::scene("pinned_beam");
    let model = Model::build(&scene).unwrap();
    // Stuck from t = 0 until 3.18 in the default scene.
    let mut sim = Simulation::new(model.clone(), 0.0).unwrap();
    sim.advance_to(1.0).unwrap();
    assert!(sim.is_stuck(0));
    let good = sim.state().clone();
    let inputs = sim.inputs().to_vec();
    let restored = Simulation::restore_checked(model.clone(), inputs.clone(), good.clone()).expect("the true state");
    assert_eq!(restored.state(), sim.state());

    let corrupt = |label: &str, change: &dyn Fn(&mut SimState), expect: &str| {
        let mut st = good.clone();
        change(&mut st);
        match Simulation::restore_checked(model.clone(), inputs.clone(), st) {
            Ok(_) => panic!("{label}: accepted"),
            Err(m) => assert!(m.contains(expect), "{label}: message {m:?} does not mention {expect:?}"),
        }
    };
    corrupt("NaN time", &|s| s.time = f64::NAN, "time");
    corrupt("infinite anchor time", &|s| s.anchor_time = f64::NEG_INFINITY, "anchor time");
    corrupt("NaN q", &|s| s.current.q[1] = f64::NAN, "current.q[2]");
    corrupt("NaN qd", &|s| s.anchor.qd[0] = f64::NAN, "anchor.qd[1]");
    corrupt("NaN last impact", &|s| s.stops[0].last_impact = f64::NAN, "last impact");
    corrupt("future impact", &|s| s.stops[0].last_impact = 5.0, "after the time");
    corrupt("NaN time stuck", &|s| s.stops[0].stuck_time = f64::NAN, "time stuck");
    corrupt("negative time stuck", &|s| s.stops[0].stuck_time = -1.0, "time stuck");
    corrupt("a hold starting in the future", &|s| s.stops[0].held_since = s.time + 1.0, "hold start");
    corrupt("times out of order", &|s| s.scan = s.time - 0.5, "out of order");
    corrupt("a rigid stop pressed like a compliant one", &|s| s.stops[0].contact = Contact::Pressed, "a state its law does not have");
    corrupt("departing a function not watched", &|s| s.stops[0].departing[1] = true, "departing flag 2");
    corrupt("stuck flag cleared", &|s| s.stops[0].contact = Contact::Open, "away from the motion");
    corrupt(
        "stuck flag cleared, anchored now, treated as leaving",
        &|s| {
            s.stops[0].contact = Contact::Open;
            s.stops[0].departing = [true, false];
            s.anchor = s.current.clone();
            s.anchor_time = s.time;
            s.scan = s.time;
            s.probed = s.time;
        },
        "pressed into it",
    );
    corrupt("moving along a stop it is stuck to", &|s| s.current.qd[0] += 1e-3, "stuck to stop");
    corrupt(
        "through the stop",
        &|s| {
            s.stops[0].contact = Contact::Open;
            s.current.q[0] += 0.1;
            s.anchor = s.current.clone();
            s.anchor_time = s.time;
            s.scan = s.time;
            s.probed = s.time;
        },
        "penetrated",
    );

    // A free state well below the stop: stuck flag set there is refused.
    let mut free = Simulation::new(Model::build(&with(scene.clone(), &[(ParamKey::StopGap(0), 0.5)])).unwrap(), 0.0).unwrap();
    free.advance_to(0.3).unwrap();
    let mut st = free.state().clone();
    st.stops[0].contact = Contact::Held;
    st.anchor = st.current.clone();
    st.anchor_time = st.time;
    st.scan = st.time;
    st.probed = st.time;
    let m = Simulation::restore_checked(free.model().clone(), free.inputs().to_vec(), st).unwrap_err();
    assert!(m.contains("stuck to stop"), "{m}");
    // A current state off the motion its anchor gives.
    let mut st = free.state().clone();
    st.current.q[0] -= 1e-3;
    let m = Simulation::restore_checked(free.model().clone(), free.inputs().to_vec(), st).unwrap_err();
    assert!(m.contains("away from the motion"), "{m}");
    // A search position pushed past the next impact: the claim that the
    // segment is event-free up to there is refused (it would skip the impact).
    let mut sim = free.clone();
    sim.drain_events();
    let before = sim.state().clone();
    sim.advance_to(3.0).unwrap();
    let first_impact = sim.drain_events().into_iter().find(|e| matches!(e.kind, EventKind::Impact { .. })).expect("an impact by t = 3").time;
    let mut st = before.clone();
    st.scan = first_impact + 1e-3;
    let m = Simulation::restore_checked(free.model().clone(), free.inputs().to_vec(), st).unwrap_err();
    assert!(m.contains("cannot be certified"), "{m}");
    // The true one passes.
    Simulation::restore_checked(free.model().clone(), free.inputs().to_vec(), before).unwrap();
}

/// Energy balance sums must be finite too.
#[test]
fn restored_energy_balance_is_validated() {
    let mut scene = common::scene("pinned_beam");
    scene.outputs.energy_balance = true;
    let model = Model::build(&scene).unwrap();
    let mut sim = Simulation::new(model.clone(), 0.0).unwrap();
    sim.advance_to(4.0).unwrap();
    let mut st = sim.state().clone();
    st.balance.as_mut().unwrap().forcing[2] = f64::INFINITY;
    let m = Simulation::restore_checked(model, sim.inputs().to_vec(), st).unwrap_err();
    assert!(m.contains("FE[3]"), "{m}");
}

/// The energy balance's quadrature counts against the same cap: a chain
/// with WB00's accounting, loaded at the fastest admitted frequency,
/// over a step a thousand times its horizon, stops at the cap promptly.
#[test]
fn the_energy_balance_counts_against_the_cap() {
    let mut scene = common::scene("wagg_bishop_chain");
    assert!(scene.outputs.energy_balance);
    let omega_max = beamstop::kinds::modal::interface::Limits::of(&scene).load_frequency_range().max;
    ParamKey::LoadOmega(0).set(&mut scene, omega_max);
    scene.solver.max_probes_per_step = Some(200_000);
    let mut sim = start(&scene);
    let t0 = std::time::Instant::now();
    match sim.advance_to(1e5) {
        Err(SimError::TooMuchWork { time, work, .. }) => {
            assert!(time > 0.0 && time < 1e5);
            // The work reported is what the cap counts (the search's points
            // reported alone said 23 units of a cap of 400,000).
            assert!(work > 199_000 && work <= 200_000, "{work} units of work reported at a cap of 200,000");
        }
        other => panic!("expected the work cap, got {other:?}"),
    }
    // 200k units of work: well under a second (a generous bound, not a benchmark).
    assert!(t0.elapsed() < std::time::Duration::from_secs(5), "{:?}", t0.elapsed());
}
