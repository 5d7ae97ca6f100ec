//! Every parameter of every packaged scene at both ends of its declared
//! range: the model either refuses the value with a message naming it, or
//! starts, takes one default communication step and one step a thousand
//! times the default horizon, and stays sane (finite state, no stop
//! penetrated beyond rounding, a step that ends at its target or at the
//! work cap). The FMI-level twin is tests/python/test_range_ends.py; this
//! one also prints the longest step it saw.

use std::time::{Duration, Instant};

use beamstop::interface::parameters;
use beamstop::{Model, Scene, SimError, Simulation};

const SCENES: [&str; 5] = ["pinned_beam", "steel_cantilever", "wagg_bishop_chain", "wagg_bishop_cantilever_1mode", "wagg_bishop_cantilever_4mode"];

fn scene(name: &str) -> Scene {
    let path = format!("{}/scenes/{name}.json", env!("CARGO_MANIFEST_DIR"));
    Scene::from_json(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn check_sane(sim: &Simulation, what: &str) {
    let c = sim.current();
    assert!(c.q.iter().chain(c.qd.iter()).all(|x| x.is_finite()), "{what}: non-finite state");
    assert!(sim.energy().is_finite(), "{what}: energy {}", sim.energy());
    for s in &sim.model().stops {
        let y = s.geometry.w.dot(&c.q);
        let scale = s.geometry.gap.abs() + s.geometry.w.iter().zip(c.q.iter()).map(|(a, b)| (a * b).abs()).sum::<f64>();
        let penetration = s.geometry.side * (y - s.geometry.target());
        assert!(penetration <= 1e-9 * scale.max(1e-300), "{what}: stop '{}' penetrated by {penetration:e}", s.name);
    }
}

/// One scene: (ends tried, refused, longest step and where).
fn scene_ends(name: &str) -> (usize, usize, (Duration, String)) {
    let mut longest = (Duration::ZERO, String::new());
    let mut tried = 0;
    let mut refused = 0;
    let base = scene(name);
    for p in parameters(&base) {
        for value in [p.range.min, p.range.max] {
            let value = if p.range.min_open && value == p.range.min {
                value.next_up()
            } else if p.range.max_open && value == p.range.max {
                value.next_down()
            } else {
                value
            };
            let what = format!("{name}: {} = {value:e}", p.name);
            assert!(value.is_finite(), "{what}: the declared range is not finite");
            let mut s = base.clone();
            p.key.set(&mut s, value);
            tried += 1;
            let model = match Model::build(&s) {
                Ok(m) => m,
                Err(e) => {
                    // A value that cannot form a model is refused with its name.
                    assert!(e.0.contains(&p.scene_path) || e.0.contains("cannot act"), "{what}: {}", e.0);
                    refused += 1;
                    continue;
                }
            };
            let start = s.experiment.start;
            let mut sim = match Simulation::new(model, start) {
                Ok(sim) => sim,
                Err(SimError::Penetration { .. }) => {
                    refused += 1;
                    continue;
                }
                Err(e) => panic!("{what}: start: {e}"),
            };
            for target in [start + s.experiment.step, start + 1e3 * (s.experiment.stop - start)] {
                let t1 = Instant::now();
                match sim.advance_to(target) {
                    Ok(()) => assert_eq!(sim.time(), target),
                    Err(SimError::TooMuchWork { time, .. } | SimError::TooManyEvents { time, .. }) => {
                        assert!(time <= target && time == sim.time(), "{what}");
                    }
                    Err(e) => panic!("{what}: {e}"),
                }
                let took = t1.elapsed();
                if took > longest.0 {
                    longest = (took, format!("{what}, step to {target}"));
                }
                check_sane(&sim, &what);
            }
        }
    }
    (tried, refused, longest)
}

#[test]
fn every_parameter_at_both_ends_of_its_range() {
    // Two threads (the CI machine's cores); each step is timed on its own.
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results: Vec<_> = std::thread::scope(|s| {
        let workers: Vec<_> = (0..2)
            .map(|_| {
                s.spawn(|| {
                    let mut mine = Vec::new();
                    while let Some(name) = SCENES.get(next.fetch_add(1, std::sync::atomic::Ordering::Relaxed)) {
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
    println!("{tried} range ends, {refused} refused at build or start; longest step {:?} ({})", longest.0, longest.1);
    assert!(longest.0 < Duration::from_secs(10), "longest step {:?}: {}", longest.0, longest.1);
}
