//! The pinned-pinned beam of VSM12 against independent computations:
//! a fine-step RK4 integration with its own impact handling, closed forms,
//! conservation laws and VSM12's own formulas (eqs. 28 and 33).

use std::f64::consts::{PI, SQRT_2};

use crate::common;

use beamstop::kinds::modal::interface::ParamKey;
use beamstop::SimError;
use beamstop::kinds::modal::{sim::EventKind, model::Model, scene::Scene, sim::Simulation};
use nalgebra::DVector;

fn pinned_scene() -> Scene {
    common::scene("pinned_beam")
}

fn with(mut scene: Scene, values: &[(ParamKey, f64)]) -> Scene {
    for (k, v) in values {
        k.set(&mut scene, *v);
    }
    scene
}

fn sim(scene: &Scene) -> Simulation {
    Simulation::new(Model::build(scene).unwrap(), 0.0).unwrap()
}

/// The free-vibration scene of VSM12 section 3: w(x, 0) = -3 sin(pi x).
fn free_vibration(r: f64) -> Scene {
    with(
        pinned_scene(),
        &[
            (ParamKey::LoadAmplitude(0), 0.0),
            (ParamKey::Law(0, 0), r),
            (ParamKey::Zeta, 0.0),
            (ParamKey::InitialQ(0), -3.0 / SQRT_2),
        ],
    )
}

fn impact_times(s: &mut Simulation) -> Vec<f64> {
    common::impacts(s).into_iter().map(|i| i.0).collect()
}

#[test]
fn first_impact_is_a_quarter_period_of_mode_one() {
    let mut s = sim(&free_vibration(1.0));
    s.advance_to(0.2).unwrap();
    let t = impact_times(&mut s);
    assert!((t[0] - 1.0 / (2.0 * PI)).abs() < 1e-12, "first impact at {}", t[0]);
}

#[test]
fn energy_is_conserved_with_perfectly_elastic_impacts() {
    let mut s = sim(&free_vibration(1.0));
    let e0 = s.energy();
    let mut worst = 0.0f64;
    for k in 1..=2000 {
        s.advance_to(k as f64 * 0.01).unwrap();
        worst = worst.max((s.energy() - e0).abs() / e0);
    }
    // The elastic motion is chaotic: impact times differing by rounding
    // (1e-14 at t = 3) part by 1e-6 at t = 8, so the count by t = 20
    // (96 to 102) is not a property of the code; the drift is.
    let impacts = impact_times(&mut s).len();
    assert!(impacts > 80, "only {impacts} impacts");
    assert!(worst < 1e-12, "energy drift {worst:e} over {impacts} impacts");
}

#[test]
fn energy_lost_per_impact_is_the_restitution_formula() {
    // No load, no damping: energy changes only at impacts, by
    // (1 - R^2)(w . qd-)^2 / (2 w . w) (VSM12 eq. 28 with Kelvin's loss), computed here from the
    // pre-impact state read just before each impact.
    let scene = free_vibration(0.6);
    let model = Model::build(&scene).unwrap();
    let w = model.stops[0].geometry.w.clone();
    let mut s = sim(&scene);
    s.advance_to(3.0).unwrap();
    let times = impact_times(&mut s);
    assert!(times.len() > 5);
    let mut probe = sim(&scene);
    let mut checked = 0;
    for pair in times.windows(2).take(8) {
        let (t0, t1) = (pair[0], pair[1]);
        // Just before t1 (the contact velocity there differs from the
        // pre-impact one by a relative 1e-9 at most).
        probe.advance_to(t1 - 1e-9 * (t1 - t0)).unwrap();
        let before = probe.energy();
        let v = w.dot(&probe.current().qd);
        probe.advance_to(t1).unwrap();
        let after = probe.energy();
        let predicted = (1.0 - 0.36) * v * v / (2.0 * w.dot(&w));
        assert!(((before - after) - predicted).abs() < 1e-6 * predicted.max(1e-12), "{before} {after} {predicted}");
        checked += 1;
    }
    assert!(checked >= 5);
}

#[test]
fn every_impact_puts_the_contact_point_exactly_on_the_stop() {
    let scene = with(pinned_scene(), &[(ParamKey::Law(0, 1), 1e-3)]);
    let mut s = sim(&scene);
    s.advance_to(20.0).unwrap();
    let times = impact_times(&mut s);
    assert!(times.len() > 20);
    let model = Model::build(&scene).unwrap();
    let w = &model.stops[0].geometry.w;
    let mut replay = sim(&scene);
    for &t in &times {
        replay.advance_to(t).unwrap();
        let miss = w.dot(&replay.current().q) - model.stops[0].geometry.target();
        assert!(miss.abs() < 1e-14, "w(x_stop) - d = {miss:e} at the impact at t = {t}");
    }
}

/// The sticking reaction evaluated independently from the state: VSM12
/// eq. 32 solved for lambda. (Eq. 33 as printed carries the opposite sign
/// on the `omega^2 q + 2 zeta omega qd` term; eq. 32 fixes it.)
fn vsm12_reaction(model: &Model, t: f64, q: &DVector<f64>, qd: &DVector<f64>) -> f64 {
    let (f_amp, omega) = (76.8, 0.1 * PI * PI);
    let w = &model.stops[0].geometry.w;
    let mut num_f = 0.0;
    let mut num_state = 0.0;
    for j in 0..model.n_modes() {
        let jj = (j + 1) as f64;
        let omega_j = (jj * PI).powi(2);
        let alpha = SQRT_2 * (1.0 - (jj * PI).cos()) / (jj * PI);
        num_f += w[j] * alpha * f_amp * (omega * t).sin();
        num_state += w[j] * (omega_j * omega_j * q[j] + 2.0 * 0.05 * omega_j * qd[j]);
    }
    (num_state - num_f) / w.dot(w)
}

#[test]
fn sticking_holds_the_constraint_and_a_compressive_reaction_equal_to_eq_33() {
    let scene = pinned_scene();
    let model = Model::build(&scene).unwrap();
    let w = model.stops[0].geometry.w.clone();
    let mut s = sim(&scene);
    let mut stuck_samples = 0;
    for k in 0..=2000 {
        let t = k as f64 * 0.01;
        s.advance_to(t).unwrap();
        if s.is_stuck(0) {
            stuck_samples += 1;
            let c = s.current();
            assert!((w.dot(&c.q) - 0.0).abs() < 1e-13, "w(x_stop) = {:e} while stuck at t = {t}", w.dot(&c.q));
            assert!(w.dot(&c.qd).abs() < 1e-11, "contact velocity {:e} while stuck", w.dot(&c.qd));
            let lambda = s.reaction(0);
            assert!(lambda <= 1e-9, "lambda = {lambda} > 0 while stuck at t = {t}");
            let independent = vsm12_reaction(&model, t, &c.q, &c.qd);
            assert!((lambda - independent).abs() < 1e-9 * (1.0 + independent.abs()), "{lambda} vs eq. 32 {independent}");
        }
    }
    assert!(stuck_samples > 500, "stuck at only {stuck_samples} samples");
}

#[test]
fn release_happens_where_the_reaction_changes_sign() {
    let scene = pinned_scene();
    let model = Model::build(&scene).unwrap();
    let mut s = sim(&scene);
    s.advance_to(10.0).unwrap();
    let releases: Vec<f64> =
        s.drain_events().into_iter().filter(|e| matches!(e.kind, EventKind::Release { .. })).map(|e| e.time).collect();
    assert!(releases.len() >= 2);
    for t in releases {
        // Stuck just before the release, with lambda < 0 heading to zero:
        // the line through lambda(t - 2 delta), lambda(t - delta) crosses zero at t.
        let delta = 1e-6;
        let lambda_at = |tt: f64| {
            let mut before = sim(&scene);
            before.advance_to(tt).unwrap();
            assert!(before.is_stuck(0), "not stuck at {tt}, before the release at {t}");
            let c = before.current().clone();
            vsm12_reaction(&model, tt, &c.q, &c.qd)
        };
        let (l2, l1) = (lambda_at(t - 2.0 * delta), lambda_at(t - delta));
        assert!(l2 < l1 && l1 < 0.0, "lambda {l2}, {l1} before the release at {t}");
        let zero = t - delta - l1 * delta / (l1 - l2);
        assert!((zero - t).abs() < 1e-8, "lambda extrapolates to zero at {zero}, release at {t}");
    }
}

#[test]
fn chatter_ends_in_sticking_with_inter_impact_times_shrinking_by_about_r() {
    let mut s = sim(&pinned_scene());
    s.advance_to(6.6).unwrap();
    let events = s.drain_events();
    let stick = events
        .iter()
        .position(|e| e.time > 5.0 && matches!(e.kind, EventKind::Stick { .. }))
        .expect("sticking after the chatter");
    let chatter: Vec<f64> = events[..stick]
        .iter()
        .filter(|e| e.time > 5.0 && matches!(e.kind, EventKind::Impact { .. }))
        .map(|e| e.time)
        .collect();
    let gaps: Vec<f64> = chatter.windows(2).map(|p| p[1] - p[0]).collect();
    let last_ratios: Vec<f64> = gaps.windows(2).rev().take(8).map(|p| p[1] / p[0]).collect();
    for r in &last_ratios {
        assert!((r - 0.7).abs() < 0.02, "ratio {r}");
    }
    assert!(*gaps.last().unwrap() < 1e-6, "the final impact came {} after the previous one", gaps.last().unwrap());
    match events[stick - 1].kind {
        EventKind::Impact { restitution, chatter, .. } => assert!(restitution == 0.0 && chatter),
        ref k => panic!("sticking not preceded by the final R = 0 impact: {k:?}"),
    }
}

/// Saves `sim` and restores it into `model` with `inputs`: a simulation
/// that forms every phase afresh.
fn restored(sim: &Simulation, model: &Model, inputs: &[f64]) -> Simulation {
    use beamstop::codec::{Reader, Writer};
    let mut w = Writer(Vec::new());
    sim.encode(&mut w);
    Simulation::decode(model.clone(), inputs.to_vec(), &mut Reader::new(&w.0)).unwrap()
}

/// Runs `fresh` to t = 20 in steps of 0.01 from step `first`, saved and
/// restored (into `model` with `inputs`) after every step with a stick,
/// and checks its events and final state against `kept`, run to t = 20 in
/// one call, bit for bit. Returns the number of restores.
fn agrees_with_restores_at_every_stick(kept: &mut Simulation, mut fresh: Simulation, first: usize, model: &Model, inputs: &[f64], what: &str) -> usize {
    kept.advance_to(20.0).unwrap();
    let mut events = Vec::new();
    let mut restores = 0;
    for i in first..=2000 {
        fresh.advance_to(i as f64 * 0.01).unwrap();
        let new = fresh.drain_events();
        if new.iter().any(|e| matches!(e.kind, EventKind::Stick { .. })) {
            fresh = restored(&fresh, model, inputs);
            restores += 1;
        }
        events.extend(new);
    }
    let kept_events = kept.drain_events();
    assert_eq!(kept_events.len(), events.len(), "{what}");
    for (a, b) in kept_events.iter().zip(&events) {
        assert_eq!(a.time, b.time, "{what}: {:?} vs {:?}", a.kind, b.kind);
    }
    assert_eq!(kept.state().current, fresh.state().current, "{what}");
    restores
}

/// Each sticking phase re-entered starts from the loads and functions
/// projected at its first entry (kept by the simulation); a simulation
/// saved and restored at every stick projects them afresh. Both must give
/// the same events and state bit for bit over the Figure 4 scene's seven
/// sticking phases.
#[test]
fn re_entered_phases_match_phases_projected_afresh() {
    let model = Model::build(&pinned_scene()).unwrap();
    let mut kept = Simulation::new(model.clone(), 0.0).unwrap();
    let fresh = Simulation::new(model.clone(), 0.0).unwrap();
    let restores = agrees_with_restores_at_every_stick(&mut kept, fresh, 1, &model, &[], "Figure 4");
    assert!(restores >= 7, "{restores} sticking phases");
}

/// The phases kept for re-entry hold the loads they were projected under:
/// a change of the loads mid-run (an input, the actuator's force; or a
/// parameter, the load's amplitude) must not meet a phase kept from
/// before. The run with the change, keeping its phases, and one saved and
/// restored at every stick after it (projecting afresh) agree bit for bit,
/// and differ from the run without the change.
#[test]
fn phases_re_entered_after_the_loads_change_use_the_new_loads() {
    let model = Model::build(&pinned_scene()).unwrap();
    let stronger = Model::build(&with(pinned_scene(), &[(ParamKey::LoadAmplitude(0), 90.0)])).unwrap();
    let changes: [(&str, Model, Vec<f64>); 2] = [("input", model.clone(), vec![-20.0]), ("parameter", stronger, vec![0.0])];
    for (what, after, inputs) in changes {
        let mut kept = Simulation::new(model.clone(), 0.0).unwrap();
        kept.advance_to(7.0).unwrap();
        let sticks_before = kept.drain_events().iter().filter(|e| matches!(e.kind, EventKind::Stick { .. })).count();
        assert!(sticks_before >= 2, "{what}: {sticks_before} sticks before the change");
        let mut unchanged = kept.clone();
        kept.set_inputs(&inputs).unwrap();
        kept.set_model(after.clone()).unwrap();
        let fresh = restored(&kept, &after, &inputs);
        let restores = agrees_with_restores_at_every_stick(&mut kept, fresh, 701, &after, &inputs, what);
        assert!(restores >= 2, "{what}: {restores} sticking phases after the change");
        unchanged.advance_to(20.0).unwrap();
        assert_ne!(unchanged.state().current, kept.state().current, "{what}");
    }
}

#[test]
fn the_trajectory_does_not_depend_on_the_communication_step() {
    for scene in [pinned_scene(), free_vibration(0.8)] {
        let mut a = sim(&scene);
        for k in 1..=2000 {
            a.advance_to(k as f64 * 0.01).unwrap();
        }
        let mut b = sim(&scene);
        let mut t = 0.0;
        while t < 20.0 {
            t = (t + 0.37f64).min(20.0);
            b.advance_to(t).unwrap();
        }
        let (ca, cb) = (a.current(), b.current());
        let diff = (&ca.q - &cb.q).amax().max((&ca.qd - &cb.qd).amax());
        assert!(diff < 1e-10, "state differs by {diff:e}");
        assert_eq!(a.state().stops[0].impacts, b.state().stops[0].impacts);
    }
}

#[test]
fn an_initial_state_through_the_stop_is_refused() {
    let scene = with(pinned_scene(), &[(ParamKey::InitialQ(0), 0.5)]);
    match Simulation::new(Model::build(&scene).unwrap(), 0.0) {
        Err(SimError::Penetration { stop, .. }) => assert_eq!(stop, "stop"),
        other => panic!("expected a penetration error, got {:?}", other.map(|_| ())),
    }
}

/// An independent reference: RK4 with a small fixed step on the modal
/// equations, the impact located by bisection on re-integrated sub-steps,
/// VSM12 eq. 28 applied. It shares no code with the library.
fn rk4_impacts(n: usize, f_amp: f64, omega: f64, zeta: f64, r: f64, gap: f64, q0: &[f64], t_end: f64) -> Vec<f64> {
    let x_s = 0.4;
    let w: Vec<f64> = (1..=n).map(|j| SQRT_2 * (j as f64 * PI * x_s).sin()).collect();
    let om: Vec<f64> = (1..=n).map(|j| (j as f64 * PI).powi(2)).collect();
    let alpha: Vec<f64> = (1..=n).map(|j| SQRT_2 * (1.0 - (j as f64 * PI).cos()) / (j as f64 * PI)).collect();
    let acc = |t: f64, q: &[f64], v: &[f64], out: &mut [f64]| {
        for j in 0..n {
            out[j] = alpha[j] * f_amp * (omega * t).sin() - 2.0 * zeta * om[j] * v[j] - om[j] * om[j] * q[j];
        }
    };
    let step = |t: f64, q: &mut Vec<f64>, v: &mut Vec<f64>, h: f64| {
        let (mut a1, mut a2, mut a3, mut a4) = (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        acc(t, q, v, &mut a1);
        let q2: Vec<f64> = (0..n).map(|j| q[j] + 0.5 * h * v[j]).collect();
        let v2: Vec<f64> = (0..n).map(|j| v[j] + 0.5 * h * a1[j]).collect();
        acc(t + 0.5 * h, &q2, &v2, &mut a2);
        let q3: Vec<f64> = (0..n).map(|j| q[j] + 0.5 * h * v2[j]).collect();
        let v3: Vec<f64> = (0..n).map(|j| v[j] + 0.5 * h * a2[j]).collect();
        acc(t + 0.5 * h, &q3, &v3, &mut a3);
        let q4: Vec<f64> = (0..n).map(|j| q[j] + h * v3[j]).collect();
        let v4: Vec<f64> = (0..n).map(|j| v[j] + h * a3[j]).collect();
        acc(t + h, &q4, &v4, &mut a4);
        for j in 0..n {
            q[j] += h / 6.0 * (v[j] + 2.0 * v2[j] + 2.0 * v3[j] + v4[j]);
            v[j] += h / 6.0 * (a1[j] + 2.0 * a2[j] + 2.0 * a3[j] + a4[j]);
        }
    };
    let gapf = |q: &[f64]| gap - q.iter().zip(&w).map(|(a, b)| a * b).sum::<f64>();
    let h = 2e-5;
    let (mut t, mut q, mut v) = (0.0, q0.to_vec(), vec![0.0; n]);
    let mut impacts = Vec::new();
    while t < t_end {
        let (mut q1, mut v1) = (q.clone(), v.clone());
        step(t, &mut q1, &mut v1, h);
        if gapf(&q1) < 0.0 {
            // Bisection on the sub-step length.
            let (mut lo, mut hi) = (0.0, h);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                let (mut qm, mut vm) = (q.clone(), v.clone());
                step(t, &mut qm, &mut vm, mid);
                if gapf(&qm) < 0.0 {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            let (mut qi, mut vi) = (q.clone(), v.clone());
            step(t, &mut qi, &mut vi, lo);
            let wv: f64 = vi.iter().zip(&w).map(|(a, b)| a * b).sum();
            let ww: f64 = w.iter().map(|x| x * x).sum();
            for j in 0..n {
                vi[j] -= (1.0 + r) * wv * w[j] / ww; // VSM12 eq. 28
            }
            t += lo;
            q = qi;
            v = vi;
            impacts.push(t);
            continue;
        }
        q = q1;
        v = v1;
        t += h;
    }
    impacts
}

#[test]
fn impact_times_match_an_independent_rk4_integration() {
    // Forced, damped, R = 0.7, gap 1.2: VSM12's Figure 10 regime
    // (two impacts per period), 3 forcing periods.
    let omega = 0.7 * PI * PI;
    let scene = with(
        pinned_scene(),
        &[
            (ParamKey::LoadAmplitude(0), 72.0),
            (ParamKey::LoadOmega(0), omega),
            (ParamKey::StopGap(0), 1.2),
            (ParamKey::Law(0, 1), 1e-3),
        ],
    );
    let t_end = 3.0 * 2.0 * PI / omega;
    let mut s = sim(&scene);
    s.advance_to(t_end).unwrap();
    let ours = impact_times(&mut s);
    let reference = rk4_impacts(4, 72.0, omega, 0.05, 0.7, 1.2, &[0.0; 4], t_end);
    assert_eq!(ours.len(), reference.len(), "{ours:?} vs {reference:?}");
    assert!(ours.len() >= 4);
    for (a, b) in ours.iter().zip(&reference) {
        assert!((a - b).abs() < 1e-8, "impact at {a} vs RK4 {b}");
    }
}

/// The stick counters against the event log: `sticks` counts the Stick
/// events and `stuck_time` sums the Stick-to-Release intervals (the hold
/// still open at the end up to the current time), whatever the
/// communication step; a state saved inside a hold keeps both.
#[test]
fn stick_counters_match_the_event_log() {
    let scene = pinned_scene();
    let mut coarse = sim(&scene);
    coarse.advance_to(20.0).unwrap();
    let events = coarse.drain_events();
    let (mut count, mut total, mut since) = (0u64, 0.0, None);
    for e in &events {
        match e.kind {
            EventKind::Stick { .. } => {
                count += 1;
                since = Some(e.time);
            }
            EventKind::Release { .. } => total += e.time - since.take().expect("a release follows a stick"),
            _ => {}
        }
    }
    if let Some(s) = since {
        total += 20.0 - s;
    }
    assert!(count >= 5, "the Figure 4 scene sticks repeatedly ({count})");
    assert_eq!(coarse.state().stops[0].sticks, count);
    assert!((coarse.stuck_time(0) - total).abs() < 1e-12, "{} vs {total}", coarse.stuck_time(0));
    // Stepped at 0.01, sampled: the same totals, and the sampled flag agrees
    // with the exact time to within one step per hold.
    let mut fine = sim(&scene);
    let (mut sampled, dt) = (0.0, 0.01);
    let mut saved = None;
    for k in 1..=2000 {
        fine.advance_to(k as f64 * dt).unwrap();
        if fine.is_stuck(0) {
            sampled += dt;
            if saved.is_none() && k > 1000 {
                saved = Some(fine.state().clone());
            }
        }
    }
    assert_eq!(fine.state().stops[0].sticks, count);
    assert!((fine.stuck_time(0) - total).abs() < 1e-9, "{} vs {total}", fine.stuck_time(0));
    assert!((sampled - total).abs() <= dt * count as f64, "{sampled} vs {total}");
    let state = saved.expect("stuck at some sample after t = 10");
    let mut restored = Simulation::restore(Model::build(&scene).unwrap(), vec![0.0], state.clone()).unwrap();
    assert!(restored.is_stuck(0) && restored.stuck_time(0) > state.stops[0].stuck_time);
    restored.advance_to(20.0).unwrap();
    assert!((restored.stuck_time(0) - total).abs() < 1e-9 && restored.state().stops[0].sticks == count);
}

#[test]
fn impulses_are_only_integrated_when_the_scene_outputs_them() {
    // The Figure 4 scene (7 sticks, whose held phases need the exact
    // integral of the reaction): the motion does not depend on whether the
    // impulses are kept, and they are only kept when asked for.
    let mut on = pinned_scene();
    on.outputs.impulse = true;
    let mut off = pinned_scene();
    off.outputs.impulse = false;
    let (mut a, mut b) = (sim(&on), sim(&off));
    a.advance_to(20.0).unwrap();
    b.advance_to(20.0).unwrap();
    assert_eq!(impact_times(&mut a), impact_times(&mut b));
    assert_eq!(a.current(), b.current());
    assert!(a.impulse_total(0) > 0.0, "impulse {}", a.impulse_total(0));
    assert_eq!(b.impulse_total(0), 0.0);
}

#[test]
fn simulations_of_one_model_share_its_contact_decompositions_and_agree_bit_for_bit() {
    // The Figure 4 scene starts stuck and sticks 7 times by t = 20: its
    // held phase is decomposed once for the model, whichever simulation
    // (a clone of the model) needs it first; a second run is the same bit
    // for bit. A model changed after it was built (a stiffer first mode)
    // finds no stale decomposition: it adds its own and moves differently.
    let model = Model::build(&pinned_scene()).unwrap();
    assert!(model.phase_systems.is_empty());
    let run = |model: &Model| {
        let mut s = Simulation::new(model.clone(), 0.0).unwrap();
        s.set_event_recording(true);
        s.advance_to(20.0).unwrap();
        let events: Vec<(f64, String)> = s.drain_events().into_iter().map(|e| (e.time, format!("{:?}", e.kind))).collect();
        (events, s.state().current.q.clone())
    };
    let first = run(&model);
    assert!(first.0.iter().any(|e| e.1.starts_with("Stick")), "the scene sticks");
    assert_eq!(model.phase_systems.len(), 1, "one held phase, decomposed once");
    let second = run(&model);
    assert_eq!(model.phase_systems.len(), 1, "the second run found it");
    assert_eq!(first, second);
    let mut changed = model.clone();
    changed.oscillators[0] = beamstop::solve::Oscillator::new(1.01 * model.oscillators[0].omega, model.oscillators[0].zeta);
    let third = run(&changed);
    assert_eq!(model.phase_systems.len(), 2, "the changed model decomposed its own");
    assert_ne!(first.1, third.1);
}
