//! Forged states for every law and kind are refused with a message naming
//! what is wrong: a departing flag far from the stop, contact flags on a
//! free beam, a compliant stop penetrated without force while its law
//! pushes (or pressed while it pulls), a rotating hub state that puts the
//! tip through the surface. Each forgery changes one thing of a true state,
//! which itself restores (tests/integration/restores.rs: bit for bit).

use crate::common;

use beamstop::codec::{Reader, Writer};
use beamstop::component::Component;
use beamstop::kind::Run;
use beamstop::kinds::rotating::RotatingRun;
use beamstop::contact::Contact;
use beamstop::kinds::modal::sim::SimState;
use beamstop::kinds::modal::{model::Model, sim::Simulation};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// A run of a modal scene up to the first time `until` holds (stepping 1e-5
/// of the first mode's period from `t0`).
fn run_until(name: &str, t0: f64, until: impl Fn(&Simulation) -> bool) -> Simulation {
    let model = Model::build(&common::scene(name)).unwrap();
    let dt = 1e-3 * model.shortest_period();
    let mut sim = Simulation::new(model, 0.0).unwrap();
    sim.advance_to(t0).unwrap();
    let mut t = t0;
    while !until(&sim) {
        t += dt;
        sim.advance_to(t).unwrap();
        assert!(t < t0 + 1e5 * dt, "{name}: the state looked for never came");
    }
    sim
}

/// The state anchored at its own time (so that a changed contact state
/// forms its phase from there, and nothing but the change is wrong).
fn anchored_now(st: &SimState) -> SimState {
    let mut st = st.clone();
    st.anchor = st.current.clone();
    st.anchor_time = st.time;
    st.scan = st.time;
    st.probed = st.time;
    st.accounted = st.time;
    for s in &mut st.stops {
        s.departing = [false; 2];
        s.anchor_departing = [false; 2];
    }
    st
}

/// Refused with a message containing `expect`; the true state restores.
fn refused(sim: &Simulation, label: &str, forge: impl Fn(&mut SimState), expect: &str) {
    Simulation::restore_checked(sim.model().clone(), sim.inputs().to_vec(), sim.state().clone()).unwrap_or_else(|m| panic!("{label}: the true state is refused: {m}"));
    let mut st = sim.state().clone();
    forge(&mut st);
    match Simulation::restore_checked(sim.model().clone(), sim.inputs().to_vec(), st) {
        Ok(_) => panic!("{label}: accepted"),
        Err(m) => assert!(m.contains(expect), "{label}: message {m:?} does not mention {expect:?}"),
    }
}

fn gap_at(sim: &Simulation) -> f64 {
    -sim.model().stops[0].geometry.penetration(&sim.current().q)
}

#[test]
fn departing_flags_far_from_the_stop_are_refused_for_every_law() {
    for name in ["pinned_beam", "spring_stop_soft", "spring_stop_hard", "hertz_stop"] {
        // Apart from the stop, not departing (a search point since).
        let sim = run_until(name, 0.0, |s| s.contact(0) == Contact::Open && gap_at(s) > 1e-4 && s.state().stops[0].departing == [false; 2]);
        refused(&sim, &format!("{name}: departing"), |st| st.stops[0].departing[0] = true, "departing flag 1 set");
        refused(&sim, &format!("{name}: departing at the anchor"), |st| {
            *st = anchored_now(st);
            st.stops[0].anchor_departing[0] = true;
        }, "anchor departing flag 1 set");
    }
}

#[test]
fn contact_flags_on_a_free_beam_are_refused_for_every_law() {
    for (name, flag) in [("pinned_beam", Contact::Held), ("spring_stop_hard", Contact::Pressed), ("spring_stop_hard", Contact::Penetrated), ("hertz_stop", Contact::Pressed), ("hertz_stop", Contact::Penetrated)] {
        let sim = run_until(name, 0.0, |s| s.contact(0) == Contact::Open && gap_at(s) > 1e-4);
        refused(&sim, &format!("{name}: {flag:?} apart"), |st| {
            *st = anchored_now(st);
            st.stops[0].contact = flag;
        }, "stop");
    }
}

#[test]
fn compliant_contact_states_must_agree_with_the_law_s_force() {
    for name in ["spring_stop_hard", "hertz_stop"] {
        // Pressed, the law pushing: marking it penetrated without force is refused.
        let sim = run_until(name, 0.0, |s| s.contact(0) == Contact::Pressed && s.stop_force(0) > 1.0);
        refused(&sim, &format!("{name}: penetrated while the law pushes with {} N", sim.stop_force(0)), |st| {
            *st = anchored_now(st);
            st.stops[0].contact = Contact::Penetrated;
        }, "NegatedForce function");
        // And open while inside.
        refused(&sim, &format!("{name}: open while inside"), |st| {
            *st = anchored_now(st);
            st.stops[0].contact = Contact::Open;
        }, "penetrated by");
    }
}

/// A Hertz stop with linear damping ends pushes inside the surface: a
/// state penetrated without force marked pressed is refused (its law pulls).
#[test]
fn a_hertz_stop_pressed_while_its_law_pulls_is_refused() {
    let mut scene = common::scene("hertz_stop");
    scene.stops[0].law = serde_json::from_value(serde_json::json!({"type": "hertz", "K": 1.088e10, "C": 2e4, "damping": "linear"})).unwrap();
    let model = Model::build(&scene).unwrap();
    let mut sim = Simulation::new(model, 0.0).unwrap();
    let mut t = 0.0;
    while sim.contact(0) != Contact::Penetrated {
        t += 1e-5;
        sim.advance_to(t).unwrap();
        assert!(t < 0.5, "never penetrated without force");
    }
    refused(&sim, "hertz: pressed while the law pulls", |st| {
        *st = anchored_now(st);
        st.stops[0].contact = Contact::Pressed;
    }, "Force function");
}

/// The rotating beam's encoding: contact code at byte 9, then nine numbers
/// and two vectors (length-prefixed) of the state `y`.
mod rotating {
    use super::*;

    fn component() -> Component {
        Component::from_json(&std::fs::read_to_string(format!("{ROOT}/scenes/rotating_beam.json")).unwrap()).unwrap()
    }

    fn bytes(run: &dyn Run) -> Vec<u8> {
        let mut w = Writer(Vec::new());
        run.encode(&mut w);
        w.0
    }

    fn decode(scene: &Component, bytes: &[u8]) -> Result<Box<dyn Run>, String> {
        scene.decode(&[0.0], &mut Reader::new(bytes))
    }

    /// The offsets of the contact code and of the anchor's and the current
    /// state's entries.
    const CONTACT: usize = 9;
    const NUMBERS: usize = CONTACT + 1 + 7 * 8 + 8 + 8;

    fn rotating(run: &dyn Run) -> &beamstop::kinds::rotating::RotatingSimulation {
        &run.as_any().downcast_ref::<RotatingRun>().expect("a rotating run").sim
    }

    fn vector_offsets(bytes: &[u8]) -> (usize, usize, usize) {
        let dim = u32::from_le_bytes(bytes[NUMBERS..NUMBERS + 4].try_into().unwrap()) as usize;
        let anchor = NUMBERS + 4;
        let current = anchor + 8 * dim + 4;
        (dim, anchor, current)
    }

    fn f64_at(bytes: &[u8], at: usize) -> f64 {
        f64::from_le_bytes(bytes[at..at + 8].try_into().unwrap())
    }

    fn set_f64(bytes: &mut [u8], at: usize, v: f64) {
        bytes[at..at + 8].copy_from_slice(&v.to_le_bytes());
    }

    #[test]
    fn forged_rotating_states_are_refused() {
        let scene = component();
        // The tip starts on the surface, pressed; a little later it is
        // inside: marked open there, it is refused.
        let mut inside = scene.start(0.0, &[0.0]).unwrap();
        inside.advance_to(1e-5).unwrap();
        let sim = rotating(inside.as_ref());
        assert!(sim.contact_state() == Contact::Pressed && sim.penetration() > 0.0);
        let mut forged = bytes(inside.as_ref());
        decode(&scene, &forged).expect("the true state");
        forged[CONTACT] = 0;
        let m = decode(&scene, &forged).err().expect("open while inside: accepted");
        assert!(m.contains("Open with penetration"), "{m}");

        // Later, apart from the surface: a hub angle that puts the tip through it.
        let mut run = scene.start(0.0, &[0.0]).unwrap();
        let mut t = 0.0;
        loop {
            t += 1e-4;
            run.advance_to(t).unwrap();
            let s = rotating(run.as_ref());
            if s.contact_state() == Contact::Open && s.gap() > 1e-4 {
                break;
            }
            assert!(t < 0.05, "the tip never left the surface");
        }
        let apart = bytes(run.as_ref());
        decode(&scene, &apart).expect("the true state");
        let (_, anchor, current) = vector_offsets(&apart);
        let mut through = apart.clone();
        for at in [anchor, current] {
            // theta, the hub angle, is y[0]: turn it far into the surface.
            let theta = f64_at(&through, at);
            set_f64(&mut through, at, theta + 0.2);
        }
        let m = decode(&scene, &through).err().expect("tip through the surface: accepted");
        assert!(m.contains("penetration"), "{m}");
        // Pressed (and penetrated) on a free beam.
        for code in [2u8, 3] {
            let mut flagged = apart.clone();
            flagged[CONTACT] = code;
            let m = decode(&scene, &flagged).err().unwrap_or_else(|| panic!("contact code {code} apart: accepted"));
            assert!(m.contains("penetration"), "{m}");
        }

        // In contact, pushing: marked penetrated (force-free) is refused.
        let mut run = scene.start(0.0, &[0.0]).unwrap();
        run.advance_to(1e-5).unwrap();
        let s = rotating(run.as_ref());
        assert!(s.contact_state() == Contact::Pressed && s.contact_force() > 0.0);
        let pressed = bytes(run.as_ref());
        decode(&scene, &pressed).expect("the true state");
        let mut penetrated = pressed.clone();
        penetrated[CONTACT] = 3;
        let m = decode(&scene, &penetrated).err().expect("penetrated while pushing: accepted");
        assert!(m.contains("law would push"), "{m}");
    }
}
