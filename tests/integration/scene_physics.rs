//! The scenes beyond the foundation against independent computations:
//! WB00's energy balance and restitution formula on the chain's P(1,1)
//! orbit, beam theory's static deflection for the SI cantilever, energy
//! conservation with two-sided and simultaneous contacts.

use std::f64::consts::PI;

use crate::common;

use beamstop::kinds::modal::interface::ParamKey;
use beamstop::kinds::modal::{sim::EventKind, model::Model, scene::Scene, sim::Simulation};
use common::{impacts, scene as load};

#[test]
fn chain_settles_on_p11_and_satisfies_the_wb00_energy_balance() {
    let scene = load("wagg_bishop_chain");
    let mut sim = Simulation::new(Model::build(&scene).unwrap(), 0.0).unwrap();
    sim.advance_to(1600.0).unwrap();
    let list = impacts(&mut sim);
    let n = list.len();
    let period = 2.0 * PI / 0.9;
    // One impact per forcing period: P(1,1).
    for w in list[n - 6..].windows(2) {
        assert!((w[1].0 - w[0].0 - period).abs() < 1e-9, "inter-impact time {}", w[1].0 - w[0].0);
    }
    let ((ta, _), (tb, vb)) = (list[n - 2], list[n - 1]);
    let mut probe = Simulation::new(Model::build(&scene).unwrap(), 0.0).unwrap();
    probe.advance_to(ta).unwrap();
    let a = probe.energy_balance().unwrap().clone();
    probe.advance_to(tb).unwrap();
    let b = probe.energy_balance().unwrap().clone();
    let residual: f64 = (0..2).map(|j| (b.forcing[j] - a.forcing[j]) - (b.damping[j] - a.damping[j])).sum();
    let lost = b.impacts - a.impacts;
    // Eq. 11: the energy lost at impact equals the residual modal energy.
    assert!((residual - lost).abs() < 1e-9 * lost, "RE {residual} vs IE {lost}");
    // Eq. 10 and 13: IE = m v_N^2 (1 - r^2) / 2, so r = sqrt(1 - RE / KE_i).
    let ke = 0.5 * 1.0 * vb * vb;
    assert!(((1.0 - residual / ke).sqrt() - 0.7).abs() < 1e-9);
}

/// `E(t) - E(0) = sum_j (FE_j - DE_j) - impact losses` (WB00 eq. 7),
/// through impacts, chatter and sticking: the quadrature of the loads'
/// work and the damping against the closed-form energy.
#[test]
fn the_energy_bookkeeping_closes_through_impacts_and_sticking() {
    let mut pinned = load("pinned_beam");
    pinned.outputs.energy_balance = true;
    for scene in [load("wagg_bishop_chain"), load("wagg_bishop_cantilever_4mode"), pinned] {
        let mut sim = Simulation::new(Model::build(&scene).unwrap(), 0.0).unwrap();
        let e0 = sim.energy();
        let mut scale = e0;
        for k in 1..=120 {
            sim.advance_to(k as f64 * 0.5).unwrap();
            let b = sim.energy_balance().unwrap();
            let work: f64 = b.forcing.iter().sum::<f64>() - b.damping.iter().sum::<f64>() - b.impacts;
            scale = scale.max(sim.energy()).max(b.forcing.iter().map(|x| x.abs()).sum());
            assert!(
                (sim.energy() - e0 - work).abs() < 1e-10 * scale,
                "{}: t = {}: E - E0 = {} but the balance says {}",
                scene.name,
                sim.time(),
                sim.energy() - e0,
                work
            );
        }
        assert!(sim.state().stops[0].impacts > 3, "{}", scene.name);
    }
}

/// Beam theory: a cantilever loaded by P at x = a deflects at the tip by
/// `P a^2 (3 L - a) / (6 E I)` and carries `P a` at the clamp.
#[test]
fn si_cantilever_static_deflection_matches_beam_theory() {
    let mut scene = load("steel_cantilever");
    scene.loads.clear();
    ParamKey::StopGap(0).set(&mut scene, 1.0);
    ParamKey::Zeta.set(&mut scene, 2.0);
    let model = Model::build(&scene).unwrap();
    let tip = model.sensors[0].w.clone();
    let clamp = model.sensors[1].moment.clone().unwrap();
    let mut sim = Simulation::new(model, 0.0).unwrap();
    let p = 1.0;
    sim.set_inputs(&[p, 0.0]).unwrap();
    sim.advance_to(30.0).unwrap();
    let (a, l, ei) = (0.15, 0.3, 210e9 * 1.3333333333333333e-11);
    let expected = p * a * a * (3.0 * l - a) / (6.0 * ei);
    let got = tip.dot(&sim.current().q);
    assert!((got / expected - 1.0).abs() < 1e-4, "tip deflection {got} vs {expected}");
    // The modal sum of the moment converges slowly (8 modes): a few percent.
    let moment = clamp.dot(&sim.current().q);
    assert!((moment / (p * a) - 1.0).abs() < 0.05, "clamp moment {moment} vs {}", p * a);
    // A uniform clamp acceleration g is the beam's own weight: tip
    // deflection mu g L^4 / (8 E I), with the load opposing the acceleration.
    let mut sim = Simulation::new(Model::build(&scene).unwrap(), 0.0).unwrap();
    sim.set_inputs(&[0.0, 9.81]).unwrap();
    sim.advance_to(30.0).unwrap();
    let mu = 7850.0 * 4e-5;
    let sag = -mu * 9.81 * l.powi(4) / (8.0 * ei);
    let got = tip.dot(&sim.current().q);
    assert!((got / sag - 1.0).abs() < 1e-4, "self-weight tip deflection {got} vs {sag}");
}

/// A two-sided clearance (two stops at one point, opposite sides) and two
/// stops hit at the same instant: with R = 1 and no damping or load, energy
/// is conserved through every contact and the beam stays inside.
#[test]
fn clearance_and_simultaneous_impacts_conserve_energy_with_r_one() {
    let base = r#"{
      "name": "Contacts", "structure": { "type": "beam", "support": "pinned-pinned", "modes": 6 },
      "damping": { "zeta": 0.0 },
      "stops": [
        { "name": "up", "x": 0.3, "gap": 0.4, "side": "positive", "law": { "type": "restitution", "R": 1.0, "eps": 0.0 } },
        { "name": "down", "x": 0.3, "gap": 0.4, "side": "negative", "law": { "type": "restitution", "R": 1.0, "eps": 0.0 } },
        { "name": "right", "x": 0.7, "gap": 0.4, "side": "positive", "law": { "type": "restitution", "R": 1.0, "eps": 0.0 } }
      ],
      "initial": { "q": [0.0, 0.0, 0.0], "qd": [10.0, 2.0, 0.0, 1.0] }
    }"#;
    let scene = Scene::from_json(base).unwrap();
    let model = Model::build(&scene).unwrap();
    let w = model.stops[0].geometry.w.clone();
    let mut sim = Simulation::new(model, 0.0).unwrap();
    let e0 = sim.energy();
    for k in 1..=1000 {
        sim.advance_to(k as f64 * 0.01).unwrap();
        let y = w.dot(&sim.current().q);
        assert!(y.abs() <= 0.4 + 1e-12, "w(0.3) = {y} outside the clearance");
        assert!((sim.energy() - e0).abs() < 1e-11 * e0, "energy {} vs {e0}", sim.energy());
    }
    let counts: Vec<u64> = sim.state().stops.iter().map(|s| s.impacts).collect();
    assert!(counts.iter().all(|&c| c > 5), "impacts per stop {counts:?}");

    // Mode 1 alone hits two symmetric stops at the same instant.
    let symmetric = base.replace("\"x\": 0.3, \"gap\": 0.4, \"side\": \"negative\"", "\"x\": 0.5, \"gap\": 5.0, \"side\": \"negative\"")
        .replace("\"qd\": [10.0, 2.0, 0.0, 1.0]", "\"qd\": [10.0]");
    let scene = Scene::from_json(&symmetric).unwrap();
    let mut sim = Simulation::new(Model::build(&scene).unwrap(), 0.0).unwrap();
    let e0 = sim.energy();
    sim.advance_to(0.5).unwrap();
    let events = sim.drain_events();
    let first: Vec<_> = events.iter().take(2).collect();
    assert!(matches!(first[0].kind, EventKind::Impact { stop: 0, .. }) && matches!(first[1].kind, EventKind::Impact { stop: 2, .. }));
    assert_eq!(first[0].time, first[1].time, "the symmetric stops are hit together");
    assert!((sim.energy() - e0).abs() < 1e-12 * e0);
    // By symmetry the motion stays in the symmetric modes 1, 3, 5.
    assert!(sim.current().q[1].abs() < 1e-12 && sim.current().q[3].abs() < 1e-12);
}

/// A Hertz stop of vanishing stiffness engaged while the rigid stop beside
/// it holds the beam (RigidAndHertzStops at the admitted minimum `K`, and
/// at `K = 1e-6` at tolerances 1e-4 to 1e-8) moves the beam as the rigid
/// stop alone does, whose held phases are closed-form: at t = 2 (after 1.5
/// of holding) within 1e-9 of the motion's scale, and within 1e-8 at `K =
/// 1e-6` (its force's own effect: 1.2e-10 to 1.9e-10). The held reaction's
/// polynomial went unchecked, and the steps such a stop allows (four
/// periods of the fastest mode) let the held state drift until the
/// reaction changed sign: energies of 1.5 to 4.1 against 1.86. Checked,
/// steps that long still left the reaction's polynomial spanning four
/// periods of the constrained motion: 1.7e-6 off at 1e-8.
#[test]
fn a_vanishing_hertz_stop_beside_a_held_rigid_one_leaves_the_rigid_motion() {
    let text = std::fs::read_to_string(format!("{}/scenes/rigid_and_hertz.json", env!("CARGO_MANIFEST_DIR"))).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(json["stops"][1]["law"]["type"], "hertz");
    let mut rigid_alone = json.clone();
    rigid_alone["stops"].as_array_mut().unwrap().truncate(1);
    let run = |j: &serde_json::Value| {
        let mut sim = Simulation::new(Model::build(&Scene::from_json(&j.to_string()).unwrap()).unwrap(), 0.0).unwrap();
        for k in 1..=200 {
            sim.advance_to(k as f64 * 0.01).unwrap();
        }
        assert!(sim.is_stuck(0), "held at t = 2");
        sim.current().clone()
    };
    let reference = run(&rigid_alone);
    let scale = reference.q.amax();
    for (k, tol, bound) in [(3.908454749658794e-11, 1e-12, 1e-9), (1e-6, 1e-4, 1e-8), (1e-6, 1e-6, 1e-8), (1e-6, 1e-8, 1e-8)] {
        let mut weak = json.clone();
        weak["stops"][1]["law"]["K"] = k.into();
        weak["solver"]["integration_tolerance"] = tol.into();
        let state = run(&weak);
        let off = (&state.q - &reference.q).amax() / scale;
        assert!(off < bound, "K = {k}, tolerance {tol}: q off by {off:e} of its scale");
    }
}
