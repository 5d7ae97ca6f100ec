//! Every parameter and input of every packaged scene at both ends of its
//! declared range: the value is refused with a message naming it, or the
//! run starts, takes one default communication step, a step to the
//! experiment's horizon (scenes with an integrated contact law: a tenth
//! of it, the whole with `scripts/test --full`) and (modal kinds, except
//! the initial state of modes above the first and the integrated laws'
//! scenes but with --full) one to a thousand times it, and
//! stays sane (finite state,
//! no rigid stop penetrated beyond rounding, a step that ends at its
//! target or at a work cap, never an error that ends the run). The
//! FMI-level twin is tests/python/test_robustness.py; this one also
//! prints the longest step it saw.

use std::time::{Duration, Instant};

use beamstop::component::Component;
use beamstop::kind::Run;
use beamstop::kinds::modal::ModalRun;
use beamstop::kinds::rotating::RotatingRun;
use beamstop::kinds::modal::scene::Range;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

fn scenes() -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(format!("{ROOT}/scenes"))
        .unwrap()
        .filter_map(|e| e.ok())
        .filter_map(|e| e.path().file_stem().map(|s| s.to_string_lossy().into_owned()))
        .collect();
    names.sort();
    names
}

/// The scene, its modal steps capped at 1e5 search points: sanity at the
/// range ends needs the long steps to run, not to reach the default cap
/// (which lets a whole horizon through and would make this test 4 times
/// slower).
fn component(name: &str) -> Component {
    let mut json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(format!("{ROOT}/scenes/{name}.json")).unwrap()).unwrap();
    if json.get("structure").is_some() {
        json["solver"]["max_probes_per_step"] = 100_000.into();
    }
    Component::from_json(&json.to_string()).unwrap()
}

fn check_sane(run: &dyn Run, what: &str) {
    match (run.as_any().downcast_ref::<ModalRun>(), run.as_any().downcast_ref::<RotatingRun>()) {
        (Some(ModalRun { sim, .. }), _) => {
            let c = sim.current();
            assert!(c.q.iter().chain(c.qd.iter()).all(|x| x.is_finite()), "{what}: non-finite state");
            assert!(sim.energy().is_finite(), "{what}: energy {}", sim.energy());
            for s in sim.model().stops.iter().filter(|s| s.law.rigid()) {
                let y = s.geometry.w.dot(&c.q);
                let scale = s.geometry.gap.abs() + s.geometry.w.iter().zip(c.q.iter()).map(|(a, b)| (a * b).abs()).sum::<f64>();
                let penetration = s.geometry.side * (y - s.geometry.target());
                assert!(penetration <= 1e-9 * scale.max(1e-300), "{what}: stop '{}' penetrated by {penetration:e}", s.name);
            }
        }
        (_, Some(RotatingRun { sim, .. })) => {
            assert!(sim.y().iter().all(|x| x.is_finite()), "{what}: non-finite state");
            assert!(sim.total_energy().is_finite(), "{what}: energy {}", sim.total_energy());
        }
        _ => panic!("{what}: a run of another kind"),
    }
}

/// The ends of a range, nudged inside where it is open.
fn ends(range: &Range) -> [f64; 2] {
    let lo = if range.min_open { range.min.next_up() } else { range.min };
    let hi = if range.max_open { range.max.next_down() } else { range.max };
    [lo, hi]
}

/// What one value did: refused (with the message), or ran.
enum Outcome {
    Refused,
    Ran(Duration, String),
}

/// One value of one parameter (or input): starts, two steps.
fn try_value(scene: &Component, inputs: &[f64], what: &str, field: &[&str], reach: Reach) -> Result<Outcome, String> {
    let names_field = |m: &str| field.iter().any(|f| m.contains(f));
    if let Err(m) = scene.validate() {
        if !names_field(&m) {
            return Err(format!("{what}: refused by the scene without naming it: {m}"));
        }
        return Ok(Outcome::Refused);
    }
    let experiment = scene.experiment();
    let start = experiment.start;
    let mut run = match scene.start(start, inputs) {
        Ok(run) => run,
        Err(m) => {
            if !names_field(&m) {
                return Err(format!("{what}: refused at the start without naming it: {m}"));
            }
            return Ok(Outcome::Refused);
        }
    };
    let mut longest = (Duration::ZERO, String::new());
    // A default step, the horizon, and for the modal kinds (exact and
    // linear between events at any amplitude) a thousand horizons; the
    // rotating hub spins up without bound under a held torque, so its
    // test ends at the horizon.
    let horizon = experiment.stop - start;
    let mut targets = vec![start + experiment.step, start + horizon];
    match reach {
        Reach::Tenth => targets[1] = start + 0.1 * horizon,
        Reach::Horizon => {}
        Reach::Thousand if run.as_any().is::<ModalRun>() => targets.push(start + 1e3 * horizon),
        Reach::Thousand => {}
    }
    for target in targets {
        let t1 = Instant::now();
        match run.advance_to(target) {
            Ok(()) => assert_eq!(run.time(), target, "{what}"),
            Err(e) if e.recoverable() => assert!(run.time() <= target, "{what}"),
            Err(e) => return Err(format!("{what}, step to {target}: the run ends: {e}")),
        }
        let took = t1.elapsed();
        if took > longest.0 {
            longest = (took, format!("{what}, step to {target}"));
        }
        check_sane(run.as_ref(), what);
    }
    Ok(Outcome::Ran(longest.0, longest.1))
}

/// The initial displacement or velocity of a mode above the first: it
/// shapes only the transient, which the step to the horizon covers (the
/// damped scenes forget it long before a thousand horizons), so of the
/// initial state only the first mode's entries take the long step.
fn is_higher_mode_initial_state(scene_path: &str) -> bool {
    ["initial.q[", "initial.qd["]
        .iter()
        .any(|prefix| scene_path.strip_prefix(prefix).is_some_and(|rest| !rest.starts_with("0]")))
}

/// How far a value's run goes after its first communication step.
#[derive(Clone, Copy)]
enum Reach {
    /// A tenth of the horizon (the first contacts).
    Tenth,
    /// The horizon.
    Horizon,
    /// The horizon, then (modal kinds) a thousand horizons.
    Thousand,
}

/// Whether a scene has a stop whose contact phase is integrated (Hertz,
/// power law) and the test command runs (not `scripts/test --full`,
/// BEAMSTOP_FULL_TESTS=1): its horizon at every range end costs twice
/// what the closed-form scenes' thousand horizons together do (13 of 19
/// s), so it runs to a tenth of its horizon (its first contacts).
fn integrated_and_not_full(name: &str) -> bool {
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(format!("{ROOT}/scenes/{name}.json")).unwrap()).unwrap();
    let integrated = json["stops"].as_array().is_some_and(|stops| stops.iter().any(|s| matches!(s["law"]["type"].as_str(), Some("hertz" | "power_law"))));
    integrated && std::env::var("BEAMSTOP_FULL_TESTS").as_deref() != Ok("1")
}

/// One scene: (ends tried, refused, longest step and where).
fn scene_ends(name: &str) -> (usize, usize, (Duration, String), Vec<String>) {
    let base = component(name);
    let short = integrated_and_not_full(name);
    let n_inputs = base.inputs().len();
    let mut tried = 0;
    let mut refused = 0;
    let mut longest = (Duration::ZERO, String::new());
    let mut failures = Vec::new();
    let mut tally = |outcome: Result<Outcome, String>| {
        tried += 1;
        match outcome {
            Err(m) => failures.push(m),
            Ok(Outcome::Refused) => refused += 1,
            Ok(Outcome::Ran(d, w)) => {
                if d > longest.0 {
                    longest = (d, w);
                }
            }
        }
    };
    for (k, p) in base.parameters().iter().enumerate() {
        for value in ends(&p.range) {
            let what = format!("{name}: {} = {value:e}", p.name);
            if !value.is_finite() {
                tally(Err(format!("{what}: the declared range [{}, {}] is not finite", p.range.min, p.range.max)));
                continue;
            }
            let mut scene = base.clone();
            scene.set(k, value);
            let reach = if short {
                Reach::Tenth
            } else if is_higher_mode_initial_state(&p.scene_path) {
                Reach::Horizon
            } else {
                Reach::Thousand
            };
            tally(try_value(&scene, &vec![0.0; n_inputs], &what, &[&p.name, &p.scene_path], reach));
        }
    }
    for (i, input) in base.inputs().iter().enumerate() {
        for value in ends(&input.range) {
            let what = format!("{name}: input {} = {value:e}", input.name);
            if !value.is_finite() {
                tally(Err(format!("{what}: the declared range is not finite")));
                continue;
            }
            let mut inputs = vec![0.0; n_inputs];
            inputs[i] = value;
            tally(try_value(&base, &inputs, &what, &[&input.name], if short { Reach::Tenth } else { Reach::Thousand }));
        }
    }
    (tried, refused, longest, failures)
}

#[test]
fn every_parameter_and_input_at_both_ends_of_its_range() {
    // Two threads (the CI machine's cores); each step is timed on its own.
    let names = scenes();
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results: Vec<_> = std::thread::scope(|s| {
        let workers: Vec<_> = (0..2)
            .map(|_| {
                s.spawn(|| {
                    let mut mine = Vec::new();
                    while let Some(name) = names.get(next.fetch_add(1, std::sync::atomic::Ordering::Relaxed)) {
                        mine.push(scene_ends(name));
                    }
                    mine
                })
            })
            .collect();
        workers.into_iter().flat_map(|h| h.join().unwrap()).collect()
    });
    let tried: usize = results.iter().map(|r| r.0).sum();
    let refused: usize = results.iter().map(|r| r.1).sum();
    let longest = results.iter().map(|r| r.2.clone()).max_by_key(|l| l.0).unwrap();
    let failures: Vec<&String> = results.iter().flat_map(|r| &r.3).collect();
    for f in &failures {
        println!("FAIL {f}");
    }
    println!("{tried} range ends, {refused} refused at build or start; longest step {:?} ({})", longest.0, longest.1);
    assert!(failures.is_empty(), "{} of {tried} range ends fail", failures.len());
    assert!(longest.0 < Duration::from_secs(10), "longest step {:?}: {}", longest.0, longest.1);
}
