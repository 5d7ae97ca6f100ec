//! RMTM's three methods on its hard-impact cantilever: mode transfer
//! (MTM, RMTM: the contact phase in the modes of the cantilever with the
//! tip spring) converges to force integration (FIM: the spring on the
//! cantilever's own modes) as the number of modes grows, once all three
//! damp the same continuum; RMTM needs far fewer modes (RMTM's finding).
//! The tip-spring modes themselves are checked against a Rayleigh-Ritz
//! computation in `numerics/src/structure/tip_spring.rs`.

use crate::common;

use beamstop::codec::{Reader, Writer};
use beamstop::kinds::modal::scene::{ContactMethod, StopLaw, StructureSpec, TransferDamping};
use beamstop::kinds::modal::{model::Model, scene::Scene, sim::Simulation};

fn hard(method: ContactMethod, modes: usize, damping: TransferDamping) -> Scene {
    let mut scene = common::scene("spring_stop_hard");
    if let StructureSpec::Beam { modes: m, .. } = &mut scene.structure {
        *m = modes;
    }
    let StopLaw::SpringDashpot(law) = &mut scene.stops[0].law else { panic!("spring stop") };
    law.method = method;
    law.transfer_damping = damping;
    scene.solver.max_probes_per_step = Some(u64::MAX);
    scene
}

/// The tip deflection every 0.1 ms over 0.3 s from rest.
fn tip_history(scene: &Scene) -> (Vec<f64>, u64) {
    let mut sim = Simulation::new(Model::build(scene).unwrap(), 0.0).unwrap();
    let tip = scene.sensors.iter().position(|s| s.name == "tip").unwrap();
    let mut out = Vec::new();
    for k in 1..=3000 {
        sim.advance_to(k as f64 * 1e-4).unwrap();
        out.push(sim.sensor_motion(tip).0);
    }
    (out, sim.state().stops[0].impacts)
}

fn distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

#[test]
fn mode_transfer_converges_to_force_integration() {
    let gap = 1e-3;
    let inherited = TransferDamping::Inherited;
    let (reference, contacts) = tip_history(&hard(ContactMethod::Fim, 60, inherited));
    assert!(contacts >= 10, "{contacts} contacts");
    let error = |method, n| distance(&tip_history(&hard(method, n, inherited)).0, &reference) / gap;
    let fim: Vec<f64> = [5, 20].iter().map(|&n| error(ContactMethod::Fim, n)).collect();
    let mtm: Vec<f64> = [5, 20, 40].iter().map(|&n| error(ContactMethod::Mtm, n)).collect();
    let rmtm: Vec<f64> = [5, 20].iter().map(|&n| error(ContactMethod::Rmtm, n)).collect();
    // Converging, and RMTM at 5 modes beats FIM and MTM at 5 by an order of magnitude.
    assert!(mtm[0] > mtm[1] && mtm[2] < 2e-3, "MTM {mtm:?}");
    assert!(rmtm[0] < 1e-2 && rmtm[1] < 2e-3, "RMTM {rmtm:?}");
    assert!(rmtm[0] * 10.0 < fim[0] && rmtm[0] * 10.0 < mtm[0], "RMTM {rmtm:?} FIM {fim:?} MTM {mtm:?}");
}

#[test]
fn modal_damping_in_each_basis_is_a_different_continuum() {
    // RMTM damps each basis modally: in contact the tip-spring modes
    // carry zeta, not the cantilever's. Both converge in N, to limits
    // apart by more than either's truncation error.
    let gap = 1e-3;
    let (modal_20, _) = tip_history(&hard(ContactMethod::Rmtm, 20, TransferDamping::Modal));
    let (modal_40, _) = tip_history(&hard(ContactMethod::Rmtm, 40, TransferDamping::Modal));
    let (inherited_40, _) = tip_history(&hard(ContactMethod::Rmtm, 40, TransferDamping::Inherited));
    let converged = distance(&modal_20, &modal_40) / gap;
    let apart = distance(&modal_40, &inherited_40) / gap;
    assert!(converged < 1e-3 && apart > 10.0 * converged, "converged to {converged:e}, apart by {apart:e}");
}

#[test]
fn mode_transfer_states_restore_and_steps_do_not_matter() {
    // Mid-contact (tip-spring basis, frozen shape set), a saved state
    // continues bit for bit; one long step equals many short ones.
    for method in [ContactMethod::Mtm, ContactMethod::Rmtm] {
        let scene = hard(method, 12, TransferDamping::Inherited);
        let mut sim = Simulation::new(Model::build(&scene).unwrap(), 0.0).unwrap();
        let mut t = 0.0;
        while sim.contact(0) != beamstop::contact::Contact::Pressed {
            t += 1e-4;
            sim.advance_to(t).unwrap();
        }
        let mut w = Writer(Vec::new());
        sim.encode(&mut w);
        let bytes = w.0;
        let mut restored = Simulation::decode(sim.model().clone(), sim.inputs().to_vec(), &mut Reader::new(&bytes)).unwrap();
        sim.advance_to(0.3).unwrap();
        restored.advance_to(0.3).unwrap();
        assert_eq!(sim.state(), restored.state(), "{method:?}");
        let mut one = Simulation::new(Model::build(&scene).unwrap(), 0.0).unwrap();
        one.advance_to(0.3).unwrap();
        let (a, b) = (one.sensor_motion(0).0, sim.sensor_motion(0).0);
        assert!((a - b).abs() < 1e-12 * 1e-3, "{method:?}: {a} vs {b}");
    }
}

/// The structure's motion in its own modes (`[q; q']`, `field()`) at
/// forcing periods `first .. first + 2` of a run from rest.
fn strobe(scene: &Scene, first: usize) -> Vec<nalgebra::DVector<f64>> {
    // The scene's shaker: 1.3 omega_1.
    let period = 2.0 * std::f64::consts::PI / 136.49234534301007;
    let mut sim = Simulation::new(Model::build(scene).unwrap(), 0.0).unwrap();
    (first..first + 3)
        .map(|k| {
            sim.advance_to(k as f64 * period).unwrap();
            let f = sim.field();
            nalgebra::DVector::from_iterator(2 * f.q.len(), f.q.iter().chain(f.qd.iter()).copied())
        })
        .collect()
}

#[test]
fn rmtm_drifts_where_fim_and_mtm_settle_on_a_periodic_orbit() {
    // RMTM keeps the displacement at each switch as a frozen shape: the
    // free phase's increment `q` in the structure's modes (c += q), the
    // contact phase's `p` in the tip-spring modes (d += p). The free
    // dynamics see `c + T^T d`, the contact dynamics `T c + d`; with
    // truncated bases `T T^T != I`, so when the first is periodic the
    // second moves by `(T - T^-T) q` every period: RMTM has no periodic
    // orbit, and `beamstop orbits` refuses it. FIM and MTM repeat.
    let modal = TransferDamping::Modal;
    let change = |method, n, first| {
        let s = strobe(&hard(method, n, modal), first);
        ((&s[1] - &s[0]).amax() / s[0].amax(), (&s[2] - &s[1]).amax() / s[0].amax())
    };
    for method in [ContactMethod::Fim, ContactMethod::Mtm] {
        let (a, b) = change(method, 20, 300);
        assert!(a < 1e-12 && b < 1e-12, "{method:?}: {a:e} {b:e}");
    }
    // The same change in every period, shrinking with the bases' truncation.
    let mut drift = Vec::new();
    for n in [10, 20] {
        let (a, b) = change(ContactMethod::Rmtm, n, 300);
        let (c, _) = change(ContactMethod::Rmtm, n, 200);
        assert!((a - b).abs() < 0.02 * a && (a - c).abs() < 0.05 * a, "RMTM, {n} modes: {c:e} at 200, {a:e} {b:e} at 300");
        drift.push(a);
    }
    eprintln!("RMTM's change per period, 10 and 20 modes: {drift:?}");
    assert!(drift[1] > 1e-9 && drift[1] < drift[0] / 10.0, "{drift:?}");
}
