//! Restores continue bit for bit: a master that saves the state before
//! every communication step, restores it into a fresh run (through the
//! versioned encoding, as fmi2DeSerializeFMUstate does) and steps both
//! with the same h must see the same bits in every output, for every
//! scene, at three step sizes, and after a tunable parameter or an input
//! changed mid-run. The FMI-level twin (fmi2GetFMUstate into a second
//! instance, serialization) is tests/python/test_restores.py.

use std::collections::BTreeSet;

use beamstop::codec::{Reader, Writer};
use beamstop::component::Component;
use beamstop::contact::Contact;
use beamstop::kind::Run;
use beamstop::kinds::modal::ModalRun;
use beamstop::kinds::rotating::RotatingRun;
use beamstop::variables::Value;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

fn component(name: &str) -> Component {
    Component::from_json(&std::fs::read_to_string(format!("{ROOT}/scenes/{name}.json")).unwrap()).unwrap()
}

/// Every output's bits.
fn outputs(scene: &Component, run: &dyn Run) -> Vec<(String, u64)> {
    scene
        .outputs()
        .iter()
        .enumerate()
        .map(|(i, o)| {
            let bits = match run.evaluate(i) {
                Value::Real(x) => x.to_bits(),
                Value::Integer(i) => i as u64,
                Value::Boolean(b) => b as u64,
            };
            (o.name.clone(), bits)
        })
        .collect()
}

fn encode(run: &dyn Run) -> Vec<u8> {
    let mut w = Writer(Vec::new());
    run.encode(&mut w);
    w.0
}

/// The kind of phase a run is in: free, or which contact states its stops
/// are in ("held", "pressed", "penetrated"), and "chatter" inside a rigid
/// stop's chatter sequence (an impact that may be followed by a stick).
fn phases(run: &dyn Run) -> Vec<&'static str> {
    if let Some(ModalRun { sim, .. }) = run.as_any().downcast_ref::<ModalRun>() {
        let mut out = Vec::new();
        for (i, s) in sim.state().stops.iter().enumerate() {
            out.push(match sim.contact(i) {
                Contact::Open => "free",
                Contact::Held => "held",
                Contact::Pressed => "pressed",
                Contact::Penetrated => "penetrated",
            });
            if s.previous_impact.is_some() {
                out.push("chatter");
            }
        }
        if out.is_empty() {
            out.push("free");
        }
        out
    } else {
        let sim = &run.as_any().downcast_ref::<RotatingRun>().expect("a modal or rotating run").sim;
        vec![match sim.contact_state() {
            Contact::Pressed => "pressed",
            Contact::Penetrated => "penetrated",
            _ => "free",
        }]
    }
}

/// What changes mid-run: a tunable parameter (to `value`) or an input.
#[derive(Clone, Copy, Debug)]
enum Change {
    None,
    Parameter(&'static str, f64),
    Input(usize, f64),
}

/// Runs `steps` steps of `h` from the experiment's start, restoring a copy
/// from the encoding before each and comparing the outputs after it.
/// Returns (steps compared, steps that differ, first difference, the
/// phases the saves were taken in).
fn check(name: &str, packaged: &Component, h: f64, steps: usize, warmup: f64, change: Change) -> (usize, usize, String, BTreeSet<&'static str>) {
    let mut scene = packaged.clone();
    let start = scene.experiment().start;
    let n_inputs = scene.inputs().len();
    let mut inputs = vec![0.0; n_inputs];
    let mut run = scene.start(start, &inputs).unwrap();
    if warmup > 0.0 {
        run.advance_to(start + warmup).unwrap();
    }
    let mut compared = 0;
    let mut differing = 0;
    let mut first = String::new();
    let mut seen = BTreeSet::new();
    for k in 0..steps {
        if k == steps / 3 {
            match change {
                Change::None => {}
                Change::Parameter(p, value) => {
                    let k = scene.parameters().iter().position(|q| q.name == p).unwrap_or_else(|| panic!("{name}: no parameter {p}"));
                    assert!(scene.parameters()[k].tunable, "{name}: {p} is not tunable");
                    scene.set(k, value);
                    scene.retune(run.as_mut()).unwrap();
                }
                Change::Input(i, value) => {
                    inputs[i] = value;
                    run.set_inputs(&inputs).unwrap();
                }
            }
        }
        seen.extend(phases(run.as_ref()));
        let saved = encode(run.as_ref());
        let mut restored = scene.decode(&inputs, &mut Reader::new(&saved)).unwrap_or_else(|e| panic!("{name}: restore at step {k}: {e}"));
        let t = run.time() + h;
        let a = run.advance_to(t);
        let b = restored.advance_to(t);
        compared += 1;
        let (oa, ob) = (outputs(&scene, run.as_ref()), outputs(&scene, restored.as_ref()));
        let same_state = encode(run.as_ref()) == encode(restored.as_ref());
        if a != b || oa != ob || !same_state {
            differing += 1;
            if first.is_empty() {
                let which: Vec<String> = oa
                    .iter()
                    .zip(&ob)
                    .filter(|(x, y)| x != y)
                    .map(|(x, y)| format!("{} {:e} vs {:e}", x.0, f64::from_bits(x.1), f64::from_bits(y.1)))
                    .take(3)
                    .collect();
                first = format!("{name} h = {h:e}, step {k} to t = {t}: {:?} vs {:?}; state same: {same_state}; {}", a.as_ref().err(), b.as_ref().err(), which.join(", "));
            }
        }
        if let Err(e) = &a {
            println!("{name} h = {h:e}: step {k} ends: {e}");
            break;
        }
    }
    (compared, differing, first, seen)
}

/// One scene: runs of `(h, steps, warmup)`; every save restores bit for
/// bit, and the saves cover the `phases` the scene goes through.
fn report(name: &str, runs: &[(f64, usize, f64)], change: Change, expected: &[&str]) {
    report_on(name, &component(name), runs, change, expected)
}

fn report_on(name: &str, scene: &Component, runs: &[(f64, usize, f64)], change: Change, expected: &[&str]) {
    let mut failures = Vec::new();
    let mut seen = BTreeSet::new();
    for &(h, steps, warmup) in runs {
        let (n, bad, first, phases) = check(name, scene, h, steps, warmup, change);
        println!("{name} h = {h:e}: {bad} of {n} differ; saved in {phases:?}");
        assert!(n == steps, "{name} h = {h:e}: stopped after {n} of {steps} steps");
        if bad > 0 {
            failures.push(first);
        }
        seen.extend(phases);
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    for p in expected {
        assert!(seen.contains(p), "{name}: no save in a {p} phase (saved in {seen:?})");
    }
}

/// The experiment's step `h0` and ten and a hundred times it.
fn three(h0: f64, steps: usize, warmup: f64) -> [(f64, usize, f64); 3] {
    [(h0, steps, warmup), (10.0 * h0, steps, warmup), (100.0 * h0, steps, warmup)]
}

#[test]
fn pinned_beam() {
    report("pinned_beam", &three(0.01, 100, 0.0), Change::Parameter("omega", 9.0), &["free", "held", "chatter"]);
}

#[test]
fn pinned_beam_input() {
    report("pinned_beam", &three(0.01, 100, 0.0), Change::Input(0, 30.0), &["free", "held", "chatter"]);
}

#[test]
fn steel_cantilever() {
    report("steel_cantilever", &three(0.001, 100, 0.0), Change::Input(0, 5.0), &["free", "chatter"]);
}

#[test]
fn wagg_bishop_chain() {
    report("wagg_bishop_chain", &three(0.05, 100, 0.0), Change::Parameter("A1.omega", 1.2), &["free"]);
}

#[test]
fn wagg_bishop_cantilever_1mode() {
    report("wagg_bishop_cantilever_1mode", &three(0.01, 100, 0.0), Change::Parameter("base.amplitude", 0.05), &["free"]);
}

#[test]
fn wagg_bishop_cantilever_4mode() {
    report("wagg_bishop_cantilever_4mode", &three(0.01, 100, 0.0), Change::Parameter("base.amplitude", 0.05), &["free"]);
}

#[test]
fn spring_stop_soft() {
    report("spring_stop_soft", &three(1e-4, 100, 0.0), Change::Parameter("shaker.omega", 90.0), &["free", "pressed"]);
}

#[test]
fn spring_stop_hard() {
    report("spring_stop_hard", &three(1e-4, 100, 0.0), Change::None, &["free", "pressed"]);
}

#[test]
fn spring_stop_very_hard() {
    report("spring_stop_very_hard", &three(1e-4, 100, 0.0), Change::None, &["free", "pressed"]);
}

#[test]
fn hertz_stop() {
    report("hertz_stop", &[(1e-4, 100, 0.07), (2e-4, 400, 0.0), (1e-3, 200, 0.0)], Change::None, &["free", "pressed"]);
}

/// Linear damping (F = K p^1.5 + C p') ends pushes inside the surface:
/// the penetrated phase (the scene's own Lankarani-Nikravesh law never does).
#[test]
fn hertz_stop_penetrated() {
    let mut json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(format!("{ROOT}/scenes/hertz_stop.json")).unwrap()).unwrap();
    json["stops"][0]["law"] = serde_json::json!({"type": "hertz", "K": 1.088e10, "C": 2e4, "damping": "linear"});
    let scene = Component::from_json(&json.to_string()).unwrap();
    report_on("hertz_stop (linear damping)", &scene, &[(2e-4, 400, 0.0), (5e-4, 200, 0.0)], Change::None, &["free", "pressed", "penetrated"]);
}

#[test]
fn rotating_beam() {
    report("rotating_beam", &three(1e-5, 100, 0.0), Change::Input(0, 1.0), &["free", "pressed"]);
}

#[test]
fn spin_up() {
    report("spin_up", &three(0.01, 100, 0.0), Change::None, &["free"]);
}

/// The swinging hub through its strike (onset at 0.113 s, separation at
/// 0.125 s) and on into the next swing.
#[test]
fn tapping_arm() {
    report("tapping_arm", &[(2e-3, 65, 0.0), (1e-4, 60, 0.112), (0.02, 10, 0.0)], Change::None, &["free", "pressed"]);
}
