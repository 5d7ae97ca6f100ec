//! The stability suite: stiff and extreme cases, each with its pass
//! criterion. Every case also checks the invariants of `Watch`: no NaN or
//! Inf anywhere, the stops never penetrated beyond rounding, no stop ever
//! pulling, and, where the scene accounts for energy (`balanced`), the
//! energy never above what the loads put in (`E(t) <= E(0) + sum FE_j(t)`:
//! the damping and the impacts only take energy out). The accounting costs
//! a quadrature resolving the fastest mode, so the 200-mode and the very
//! long runs go without it.

use std::f64::consts::{PI, SQRT_2};

use crate::common;

use beamstop::kinds::modal::interface::ParamKey;
use beamstop::kinds::modal::scene::StructureSpec;
use beamstop::kinds::modal::{sim::EventKind, model::Model, scene::Scene, sim::Simulation};

fn pinned() -> Scene {
    common::scene("pinned_beam")
}

/// With WB00's energy accounting switched on.
fn balanced(mut scene: Scene) -> Scene {
    scene.outputs.energy_balance = true;
    scene
}

fn with(mut scene: Scene, values: &[(ParamKey, f64)]) -> Scene {
    for (k, v) in values {
        k.set(&mut scene, *v);
    }
    scene
}

fn modes(mut scene: Scene, n: usize) -> Scene {
    if let StructureSpec::Beam { modes, .. } = &mut scene.structure {
        *modes = n;
    }
    scene
}

/// The Figure 10 regime of VSM12: two impacts per forcing period.
fn figure10() -> Scene {
    with(
        pinned(),
        &[
            (ParamKey::LoadAmplitude(0), 72.0),
            (ParamKey::LoadOmega(0), 0.7 * PI * PI),
            (ParamKey::StopGap(0), 1.2),
            (ParamKey::Law(0, 1), 1e-3),
        ],
    )
}

/// Runs a scene and checks the invariants at every sample.
struct Watch {
    sim: Simulation,
    e0: f64,
    /// The energy scale of the loads, `sum_j |b_j|^2 / (2 omega_j^2)`: the
    /// closed forms are accurate to rounding relative to it.
    load_energy: f64,
    samples: usize,
}

impl Watch {
    fn new(scene: &Scene) -> Watch {
        let model = Model::build(scene).unwrap();
        let load_energy = model
            .oscillators
            .iter()
            .enumerate()
            .map(|(j, o)| model.loads.harmonics.iter().map(|h| h.amplitude[j].norm()).sum::<f64>().powi(2) / (2.0 * o.omega * o.omega))
            .sum();
        let sim = Simulation::new(model, scene.experiment.start).unwrap();
        let e0 = sim.energy();
        Watch { sim, e0, load_energy, samples: 0 }
    }

    fn to(&mut self, t: f64) {
        self.sim.advance_to(t).unwrap_or_else(|e| panic!("advance to {t}: {e}"));
        self.check();
    }

    fn check(&mut self) {
        self.samples += 1;
        let t = self.sim.time();
        let c = self.sim.current();
        assert!(c.q.iter().chain(c.qd.iter()).all(|x| x.is_finite()), "non-finite state at t = {t}");
        let e = self.sim.energy();
        assert!(e.is_finite());
        let mut stored = 0.0;
        for (i, s) in self.sim.model().stops.iter().enumerate() {
            let force = self.sim.stop_force(i);
            assert!(force.is_finite() && force >= -1e-9 * (1.0 + force.abs()), "stop {i} pulls: force {force} at t = {t}");
            if !s.law.rigid() {
                // A compliant stop may be penetrated; it stores energy.
                stored += self.sim.stop_stored_energy(i);
                continue;
            }
            let y = s.geometry.w.dot(&c.q);
            let scale = s.geometry.gap.abs() + s.geometry.w.iter().zip(c.q.iter()).map(|(a, b)| (a * b).abs()).sum::<f64>();
            let penetration = s.geometry.side * (y - s.geometry.target());
            assert!(penetration <= 1e-12 * scale.max(1e-300), "stop {i} penetrated by {penetration:e} at t = {t}");
            let r = self.sim.reaction(i);
            assert!(r.is_finite() && s.geometry.side * r <= 1e-9 * (1.0 + r.abs()), "stop {i} pulls: lambda = {r} at t = {t}");
        }
        if let Some(b) = self.sim.energy_balance() {
            let input: f64 = b.forcing.iter().sum();
            let scale = self.e0 + b.forcing.iter().map(|x| x.abs()).sum::<f64>() + e + self.load_energy;
            assert!(b.damping.iter().all(|d| *d >= -1e-12 * scale), "negative damping energy at t = {t}");
            // Each impact moves the energy by rounding (the position is put
            // exactly on the stop): allow that much per impact. What went
            // into compliant stops is at least what they store now.
            let n: u64 = self.sim.state().stops.iter().map(|s| s.impacts).sum();
            assert!(
                b.impacts - stored >= -64.0 * f64::EPSILON * scale * (1 + n) as f64 - 1e-9 * scale,
                "the stops created energy ({} put in, {stored} stored) by t = {t}",
                b.impacts
            );
            assert!(e + stored <= self.e0 + input + 1e-9 * scale, "energy {e} + {stored} stored above E0 + work {} at t = {t}", self.e0 + input);
        }
    }

    fn sample(&mut self, t_end: f64, n: usize) {
        let t0 = self.sim.time();
        for k in 1..=n {
            self.to(t0 + (t_end - t0) * k as f64 / n as f64);
        }
    }

    fn impacts(&mut self) -> Vec<(f64, f64)> {
        common::impacts(&mut self.sim)
    }
}

#[test]
fn two_hundred_modes() {
    // Pass: the Figure 10 and Figure 4 regimes with 200 modes run through
    // impacts, chatter and sticking with every invariant holding.
    for scene in [modes(figure10(), 200), modes(pinned(), 200)] {
        let mut w = Watch::new(&scene);
        w.sample(7.0, 140);
        let n = w.sim.state().stops[0].impacts;
        assert!(n >= 4, "{n} impacts");
    }
}

#[test]
fn restitution_zero_and_one() {
    // Pass, R = 0: every impact plastic, the beam sticks or leaves with zero
    // velocity; R = 1 without damping or load: energy constant to 1e-11
    // over 1000 impacts.
    let mut w = Watch::new(&balanced(with(figure10(), &[(ParamKey::Law(0, 0), 0.0)])));
    w.sample(20.0, 400);
    assert!(w.sim.state().stops[0].impacts > 5);
    let free = balanced(with(
        pinned(),
        &[(ParamKey::LoadAmplitude(0), 0.0), (ParamKey::Law(0, 0), 1.0), (ParamKey::Zeta, 0.0), (ParamKey::InitialQ(0), -3.0 / SQRT_2)],
    ));
    let mut w = Watch::new(&free);
    let e0 = w.e0;
    let mut t = 0.0;
    while w.sim.state().stops[0].impacts < 1000 {
        t += 1.0;
        w.to(t);
        assert!((w.sim.energy() - e0).abs() < 1e-11 * e0, "drift {:e} after {} impacts", (w.sim.energy() - e0) / e0, w.sim.state().stops[0].impacts);
    }
}

#[test]
fn zero_gap_and_preload() {
    // Pass: with d = 0 (the Figure 4 scene) and a preloaded stop d = -0.05
    // (the beam starts inside its allowed side), every invariant holds.
    let mut w = Watch::new(&balanced(pinned()));
    w.sample(20.0, 400);
    let w1 = SQRT_2 * (0.4 * PI).sin();
    let preload = with(balanced(pinned()), &[(ParamKey::StopGap(0), -0.05), (ParamKey::InitialQ(0), -0.1 / w1)]);
    let mut w = Watch::new(&preload);
    w.sample(20.0, 400);
    assert!(w.sim.state().stops[0].impacts > 10);
}

#[test]
fn grazing() {
    // Mode 1 alone, undamped, swinging up exactly to the stop (amplitude =
    // gap): a tangential touch. Pass: no impact with a non-zero speed, no
    // stall, energy constant; with the amplitude 1e-9 larger, impacts with
    // speeds of the order sqrt(1e-9) relative, and again no stall.
    let w1 = SQRT_2 * (0.4 * PI).sin();
    for (excess, expect_impacts) in [(0.0, false), (1e-9, true)] {
        let amplitude = 0.5 * (1.0 + excess);
        let scene = with(
            balanced(pinned()),
            &[
                (ParamKey::LoadAmplitude(0), 0.0),
                (ParamKey::Zeta, 0.0),
                (ParamKey::StopGap(0), 0.5 * w1),
                (ParamKey::InitialQ(0), -amplitude),
                (ParamKey::Law(0, 0), 1.0),
            ],
        );
        let mut w = Watch::new(&scene);
        w.sample(5.0, 500);
        let speeds: Vec<f64> = w.impacts().iter().map(|i| i.1).collect();
        let vmax = PI * PI * 0.5 * w1;
        println!("grazing, amplitude excess {excess:e}: {} impacts, largest speed {:e} (free-flight speed scale {vmax})", speeds.len(), speeds.iter().cloned().fold(0.0, f64::max));
        if expect_impacts {
            assert!(!speeds.is_empty() && speeds.iter().all(|v| *v < 1e-3 * vmax), "{speeds:?}");
        } else {
            assert!(speeds.iter().all(|v| *v < 1e-6 * vmax), "a graze became an impact: {speeds:?}");
        }
        assert!((w.sim.energy() - w.e0).abs() < 1e-12 * w.e0);
    }
}

#[test]
fn zeno_chatter_as_eps_goes_to_zero() {
    // Pass: with eps = 1e-3 ... 1e-12 and eps = 0 the first chatter sequence
    // ends in sticking; the stick time converges to the accumulation point
    // (differences below 1e-5 for eps <= 1e-6), and eps = 0 ends in a
    // finite number of impacts (the velocity reaches rounding level).
    let mut stick_times = Vec::new();
    for eps in [1e-3, 1e-6, 1e-9, 1e-12, 0.0] {
        let mut w = Watch::new(&with(balanced(pinned()), &[(ParamKey::Law(0, 1), eps)]));
        w.sample(6.6, 66);
        let events = w.sim.drain_events();
        let stick = events.iter().find(|e| e.time > 5.0 && matches!(e.kind, EventKind::Stick { .. })).expect("sticks");
        let n = events.iter().filter(|e| e.time > 5.0 && e.time <= stick.time && matches!(e.kind, EventKind::Impact { .. })).count();
        assert!(n < 200, "eps = {eps}: {n} impacts before sticking");
        stick_times.push((eps, stick.time, n));
    }
    println!("zeno: (eps, stick time, impacts before sticking) = {stick_times:?}");
    let fine: Vec<f64> = stick_times.iter().filter(|s| s.0 <= 1e-6).map(|s| s.1).collect();
    let spread = fine.iter().cloned().fold(f64::MIN, f64::max) - fine.iter().cloned().fold(f64::MAX, f64::min);
    assert!(spread < 1e-5, "stick times {stick_times:?}");
}

#[test]
fn undamped_and_overdamped() {
    // Pass: zeta = 0 with the load and zeta = 2 (every mode over-damped)
    // run with every invariant holding; the over-damped beam still reaches
    // the stop under the load and sticks.
    let mut w = Watch::new(&balanced(with(figure10(), &[(ParamKey::Zeta, 0.0)])));
    w.sample(20.0, 400);
    assert!(w.sim.state().stops[0].impacts > 10);
    let mut w = Watch::new(&balanced(with(pinned(), &[(ParamKey::Zeta, 2.0)])));
    w.sample(20.0, 400);
    assert!(w.sim.is_stuck(0) || w.sim.state().stops[0].impacts > 0);
}

#[test]
fn forcing_at_exact_resonance() {
    // Undamped, loaded exactly at omega_1, stop far away (the largest gap
    // the interface admits, 1000 beam lengths): mode 1 grows
    // linearly, q1 = alpha_1 F (sin(w t) - w t cos(w t)) / (2 w^2). Pass:
    // the closed form to 1e-12 relative at t = 50 (80 periods), where the
    // classical steady-state formula is infinite; then with the stop, the
    // growth is bounded by the impacts.
    let w1 = PI * PI;
    let f = 1.0;
    let scene = with(
        balanced(pinned()),
        &[(ParamKey::LoadAmplitude(0), f), (ParamKey::LoadOmega(0), w1), (ParamKey::Zeta, 0.0), (ParamKey::StopGap(0), 1e3)],
    );
    let mut w = Watch::new(&scene);
    w.to(50.0);
    let alpha = 2.0 * SQRT_2 / PI;
    let t: f64 = 50.0;
    let exact = alpha * f * ((w1 * t).sin() - w1 * t * (w1 * t).cos()) / (2.0 * w1 * w1);
    let q1 = w.sim.current().q[0];
    assert!((q1 - exact).abs() < 1e-12 * exact.abs().max(1.0), "{q1} vs {exact}");
    let mut w = Watch::new(&with(scene, &[(ParamKey::StopGap(0), 0.05), (ParamKey::Law(0, 0), 0.8)]));
    w.sample(50.0, 500);
    assert!(w.sim.state().stops[0].impacts > 50);
}

#[test]
fn communication_steps_from_1e_minus_12_to_1e3_periods() {
    // Pass: a million steps of 1e-12 advance the time exactly and agree
    // with one step to 1e-15; 1000 forcing periods in one step give the
    // same impacts as steps of 0.01 (to 1e-9 for the first 50).
    let scene = figure10();
    let mut tiny = Watch::new(&scene);
    for k in 1..=1_000_000u64 {
        tiny.sim.advance_to(k as f64 * 1e-12).unwrap();
    }
    tiny.check();
    let mut one = Watch::new(&scene);
    one.to(1e-6);
    let d = (&tiny.sim.current().q - &one.sim.current().q).amax();
    println!("1e6 steps of 1e-12 vs one step: max |dq| = {d:e}");
    assert!(d < 1e-15, "{d:e}");
    let period = 2.0 * PI / (0.7 * PI * PI);
    let mut big = Watch::new(&scene);
    big.to(1000.0 * period);
    let mut small = Watch::new(&scene);
    let mut k = 0u64;
    while small.sim.time() < 50.0 * period {
        k += 1;
        small.sim.advance_to(k as f64 * 0.01).unwrap();
    }
    let (a, b) = (big.impacts(), small.impacts());
    assert!(a.len() > 1900, "{} impacts in 1000 periods", a.len());
    for (x, y) in a.iter().zip(&b).take(50) {
        assert!((x.0 - y.0).abs() < 1e-9, "{} vs {}", x.0, y.0);
    }
}

#[test]
fn a_hundred_thousand_forcing_periods() {
    // The Figure 10 regime for 1e5 forcing periods in steps of a tenth of a
    // period. Pass: energy bounded (max over the run below 1.01 x the max
    // over periods 100..200), no drift (the impact speeds and the impact
    // phases Omega t mod 2 pi of the last periods equal those of periods
    // 100..110 to 1e-8: time does not accumulate rounding).
    let scene = figure10();
    let omega = 0.7 * PI * PI;
    let period = 2.0 * PI / omega;
    let mut w = Watch::new(&scene);
    let mut k = 0u64;
    let mut early_max: f64 = 0.0;
    let mut late_max: f64 = 0.0;
    let mut early = Vec::new();
    let mut late = Vec::new();
    while w.sim.time() < 1e5 * period {
        k += 1;
        w.sim.advance_to(k as f64 * 0.1 * period).unwrap();
        let t = w.sim.time() / period;
        let e = w.sim.energy();
        if (100.0..200.0).contains(&t) {
            early_max = early_max.max(e);
        } else if t >= 200.0 {
            late_max = late_max.max(e);
        }
        if k % 100_000 == 0 {
            w.check();
        }
        let impacts = w.impacts();
        if (100.0..110.0).contains(&t) {
            early.extend(impacts);
        } else if t > 1e5 - 10.0 {
            late.extend(impacts);
        }
    }
    w.check();
    println!("1e5 periods: {} and {} impacts in periods 100..110 and the last 10, energy max {early_max} early, {late_max} late", early.len(), late.len());
    assert!(late_max <= 1.01 * early_max, "energy grew: {late_max} vs {early_max}");
    let phase = |t: f64| (omega * t).rem_euclid(2.0 * PI);
    let speeds = |v: &[(f64, f64)]| {
        let mut s: Vec<f64> = v.iter().map(|i| i.1).collect();
        s.sort_by(f64::total_cmp);
        s
    };
    assert_eq!(early.len(), late.len(), "impacts per 10 periods changed");
    let (se, sl) = (speeds(&early), speeds(&late));
    for (a, b) in se.iter().zip(&sl) {
        assert!((a - b).abs() < 1e-8 * a, "impact speed drifted: {a} vs {b}");
    }
    let (mut pe, mut pl): (Vec<f64>, Vec<f64>) = (early.iter().map(|i| phase(i.0)).collect(), late.iter().map(|i| phase(i.0)).collect());
    pe.sort_by(f64::total_cmp);
    pl.sort_by(f64::total_cmp);
    for (a, b) in pe.iter().zip(&pl) {
        assert!((a - b).abs() < 1e-8, "impact phase drifted: {a} vs {b}");
    }
}

#[test]
fn si_steel_beam_and_micro_cantilever_magnitudes() {
    // Pass: the SI steel cantilever (omega_1 = 117 rad/s, gap 2 mm) and an
    // AFM-like silicon micro-cantilever (200 x 30 x 2 um, omega_1 = 4e5
    // rad/s, gap 10 nm, forced at resonance) run with every invariant
    // holding and impact.
    let steel = balanced(common::scene("steel_cantilever"));
    let mut w = Watch::new(&steel);
    w.sample(1.0, 500);
    assert!(w.sim.state().stops[0].impacts > 10);
    let micro = r#"{
      "name": "MicroCantilever", "units": "SI",
      "structure": { "type": "beam", "support": "clamped-free", "modes": 6,
                     "length": 200e-6, "E": 169e9, "I": 2e-23, "rho": 2330, "A": 6e-11 },
      "damping": { "zeta": 0.005 },
      "loads": [ { "type": "base_excitation", "name": "dither", "amplitude": 2000.0, "omega": 4.4e5 } ],
      "stops": [ { "name": "sample", "x": 200e-6, "gap": 1e-8, "side": "negative",
                   "law": { "type": "restitution", "R": 0.8, "eps": 1e-12 } } ],
      "outputs": { "energy_balance": true },
      "experiment": { "stop": 1e-3, "step": 1e-7 }
    }"#;
    let scene = Scene::from_json(micro).unwrap();
    let model = Model::build(&scene).unwrap();
    assert!((model.oscillators[0].omega / 4.4e5 - 1.0).abs() < 0.05, "omega_1 = {}", model.oscillators[0].omega);
    let mut w = Watch::new(&scene);
    w.sample(1e-3, 500);
    assert!(w.sim.state().stops[0].impacts > 10);
}

/// RMTM's hard-impact cantilever (20 modes) with the stop stiffness
/// `kappa` times the static stiffness `3 EI / L^3`.
fn spring_stop(kappa: f64) -> Scene {
    let mut scene = common::scene("spring_stop_hard");
    scene.stops[0].law = beamstop::kinds::modal::scene::StopLaw::SpringDashpot(beamstop::contact::SpringDashpot { k: kappa * 1050.0, c: 0.0, method: Default::default(), transfer_damping: Default::default() });
    scene.solver.max_probes_per_step = Some(u64::MAX);
    scene
}

#[test]
fn compliant_stop_from_soft_to_1e12_times_the_structure() {
    // Pass: kappa = 1e-2 .. 1e12 (c = 0) through 0.3 s of the RMTM
    // hard-impact scene with the energy accounted: every invariant holds,
    // and the search costs a bounded number of points per switch whatever
    // the stiffness (no step collapse: the contact phase is exact, its
    // steps scale with its own period).
    for kappa in [1e-2, 1.0, 1e2, 1e4, 1e8, 1e12] {
        let mut w = Watch::new(&balanced(spring_stop(kappa)));
        w.sample(0.3, 300);
        let stats = w.sim.stats();
        let contacts = w.sim.state().stops[0].impacts;
        assert!(contacts >= 1, "kappa = {kappa}: no contact");
        let per_event = stats.probes as f64 / stats.events.max(1) as f64;
        assert!(per_event < 40.0, "kappa = {kappa}: {per_event} search points per switch ({} events)", stats.events);
    }
}

#[test]
fn compliant_grazing_contact() {
    // Pass: the tip released at rest exactly on the stop's surface, no load
    // and no damping, so it comes back to graze the surface at zero speed
    // every period: at most one contact per period, no storm of zero-length
    // phases, energy constant.
    let mut scene = spring_stop(100.0);
    scene.loads.clear();
    scene.damping = Some(beamstop::kinds::modal::scene::Damping { zeta: Some(0.0), ..Default::default() });
    if let StructureSpec::Beam { modes, .. } = &mut scene.structure {
        *modes = 1;
    }
    // w_tip = W~_1(1) q_1 with unit-mean-square shapes: W~_1(1) = 2 for a cantilever.
    scene.initial.q = vec![scene.stops[0].gap / 2.0];
    scene.initial.qd = vec![0.0];
    let mut w = Watch::new(&balanced(scene));
    let period = 2.0 * PI / w.sim.model().oscillators[0].omega;
    let e0 = w.sim.energy();
    w.sample(50.0 * period, 500);
    let contacts = w.sim.state().stops[0].impacts;
    assert!(contacts <= 51, "{contacts} contacts in 50 periods");
    assert!((w.sim.energy() + w.sim.stop_stored_energy(0) - e0).abs() <= 1e-12 * e0);
}

#[test]
fn compliant_huge_and_tiny_steps() {
    // Pass: one step over 0.4 s and 4000 steps of 1e-4 s end in the same
    // state (the trajectory does not depend on the communication grid), and
    // a thousand steps of 1e-12 s move the state by no more than its
    // velocity says.
    let scene = spring_stop(1e4);
    let mut one = Simulation::new(Model::build(&scene).unwrap(), 0.0).unwrap();
    one.advance_to(0.4).unwrap();
    let mut many = Simulation::new(Model::build(&scene).unwrap(), 0.0).unwrap();
    for k in 1..=4000 {
        many.advance_to(k as f64 * 1e-4).unwrap();
    }
    assert_eq!(one.state().stops[0].impacts, many.state().stops[0].impacts);
    let (a, b) = (one.current(), many.current());
    assert!((&a.q - &b.q).amax() <= 1e-12 * a.q.amax(), "{:e}", (&a.q - &b.q).amax());
    assert!((&a.qd - &b.qd).amax() <= 1e-11 * a.qd.amax());
    let q0 = many.current().clone();
    let t0 = many.time();
    for k in 1..=1000 {
        many.advance_to(t0 + k as f64 * 1e-12).unwrap();
    }
    let moved = (&many.current().q - &q0.q).amax();
    assert!(moved <= 2e-9 * q0.qd.amax() + 1e-18, "moved {moved:e} in 1e-9 s");
}

/// The Hertz-stop cantilever (20 modes) with stiffness `k` N/m^1.5 and the
/// DWZ's undamped law.
fn hertz_stop(k: f64) -> Scene {
    let mut scene = common::scene("hertz_stop");
    scene.stops[0].law = beamstop::kinds::modal::scene::StopLaw::Hertz(beamstop::contact::Hertz {
        stiffness: k,
        damping_coefficient: 0.0,
        damping: beamstop::contact::ContactDamping::Linear,
        restitution: 1.0,
    });
    scene.solver.max_probes_per_step = Some(u64::MAX);
    scene
}

#[test]
fn hertz_stop_from_1e6_to_1e12() {
    // Pass: K = 1e6 .. 1e12 N/m^1.5 through 0.2 s of the base-excited
    // cantilever: every invariant holds, no step collapse (the integrator's
    // steps per contact phase stay bounded whatever K: the contact is
    // resolved on its own time scale), and the work done on the stop over
    // each contact is returned (no damping: nothing dissipated).
    for k in [1e6, 1e8, 1e10, 1e12] {
        let mut w = Watch::new(&hertz_stop(k));
        w.sample(0.2, 200);
        let contacts = w.sim.state().stops[0].impacts;
        assert!(contacts >= 1, "K = {k}: no contact");
        let per_contact = w.sim.stats().probes as f64 / contacts as f64;
        eprintln!("K = {k:e}: {contacts} contacts, {per_contact:.1} steps and search points per contact");
        assert!(per_contact < 400.0, "K = {k}: {per_contact} steps and search points per contact ({contacts} contacts)");
        assert!(w.sim.stop_dissipated_energy(0).abs() <= 1e-12, "K = {k}: dissipated {}", w.sim.stop_dissipated_energy(0));
    }
}

#[test]
fn hertz_grazing_contact() {
    // Pass: the tip released at rest on the surface, no load and no
    // damping, comes back to graze it at zero speed every period: one or
    // two contacts per period, no storm of zero-length phases, energy
    // constant to the integration's accuracy. (A graze whose pushing force
    // is 1e-8 N may split in two contacts at rounding level: at most two.)
    let mut scene = hertz_stop(1e10);
    scene.loads.clear();
    scene.damping = Some(beamstop::kinds::modal::scene::Damping { zeta: Some(0.0), ..Default::default() });
    if let StructureSpec::Beam { modes, .. } = &mut scene.structure {
        *modes = 1;
    }
    // At rest a hair (1e-9 of the gap) inside the surface: the stop pushes
    // it out at a speed that vanishes with the hair, and it returns every
    // period to graze the surface.
    scene.initial.q = vec![0.0];
    let m = Model::build(&scene).unwrap();
    let w_tip = m.stops[0].geometry.w[0] * m.coordinate_scale;
    scene.initial.q = vec![scene.stops[0].gap * (1.0 + 1e-9) / w_tip];
    scene.initial.qd = vec![0.0];
    let mut w = Watch::new(&scene);
    let period = 2.0 * PI / w.sim.model().oscillators[0].omega;
    let e0 = w.sim.energy();
    w.sample(50.0 * period, 500);
    let contacts = w.sim.state().stops[0].impacts;
    let drift = (w.sim.energy() + w.sim.stop_stored_energy(0) - e0).abs() / e0;
    eprintln!("Hertz grazing: {contacts} contacts in 50 periods, energy drift {drift:e}");
    assert!((49..=101).contains(&contacts), "{contacts} contacts in 50 periods");
    assert!(drift <= 1e-9);
}

#[test]
fn hertz_huge_and_tiny_steps() {
    // Pass: one step over 0.2 s and 2000 steps of 1e-4 s end in the same
    // state bit for bit (the integrator's steps never depend on the
    // communication times), and a thousand steps of 1e-12 s inside contact
    // phases move the state by no more than its velocity says.
    let scene = hertz_stop(1.088e10);
    let mut one = Simulation::new(Model::build(&scene).unwrap(), 0.0).unwrap();
    one.advance_to(0.2).unwrap();
    let mut many = Simulation::new(Model::build(&scene).unwrap(), 0.0).unwrap();
    for k in 1..=2000 {
        many.advance_to(k as f64 * 1e-4).unwrap();
    }
    assert!(one.state().stops[0].impacts >= 3);
    assert_eq!(one.state().current, many.state().current);
    // Into the next contact, then tiny steps.
    let mut t = many.time();
    while many.contact(0) != beamstop::contact::Contact::Pressed {
        t += 1e-5;
        many.advance_to(t).unwrap();
    }
    let q0 = many.current().clone();
    for k in 1..=1000 {
        many.advance_to(t + k as f64 * 1e-12).unwrap();
    }
    let moved = (&many.current().q - &q0.q).amax();
    assert!(moved <= 2e-9 * q0.qd.amax() + 1e-18, "moved {moved:e} in 1e-9 s");
}
