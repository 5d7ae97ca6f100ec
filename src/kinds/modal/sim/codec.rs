//! The simulation's own versioned encoding of its state, and the decoder
//! that accepts only states the model can be in: finite numbers, times in
//! order, contact flags that name existing stops and agree with the
//! geometry (stuck means on the stop, at rest along it, with a reaction
//! that pushes; a stop the search treats as "departing" must not be
//! pressed into), and a current state that lies on the restored segment.
//! A state that fails any check is refused with a message naming the field.

use crate::codec::{Reader, Writer};
use crate::kinds::modal::model::Model;
use crate::solve::events::{tendency_from, Tendency};
use crate::solve::free::ModalJet;
use crate::solve::functional::NOISE;
use crate::solve::ModalState;

use super::{EnergyBalance, Frozen, SimState, Simulation, StopState};
use crate::contact::{Contact, Watch};

/// Version of the encoding below; bump on any change.
/// 2: per-stop contact states (compliant stops), impulses, dissipation.
/// 3: per-stop approach speed at the latest onset (Hertz damping).
/// 4: per-stop stick onsets, time stuck and the current hold's start.
/// 5: per-stop departing flags at the anchor, the search's last point.
pub const STATE_VERSION: u32 = 5;

impl Simulation {
    /// Appends the state (not the model or the inputs: the caller stores
    /// what they are built from).
    pub fn encode(&self, w: &mut Writer) {
        let st = &self.state;
        w.u32(STATE_VERSION);
        w.u32(st.anchor.q.len() as u32);
        w.u32(st.stops.len() as u32);
        w.f64(st.time);
        w.f64(st.anchor_time);
        w.modal(&st.anchor);
        w.f64(st.scan);
        w.f64(st.probed);
        w.f64(st.accounted);
        for stop in &st.stops {
            w.u8(stop.contact.code());
            w.u8(stop.departing[0] as u8 | (stop.departing[1] as u8) << 1 | (stop.anchor_departing[0] as u8) << 2 | (stop.anchor_departing[1] as u8) << 3);
            w.u64(stop.impacts);
            w.f64(stop.last_impact);
            w.opt_f64(stop.previous_impact);
            w.f64(stop.impulse);
            w.f64(stop.impulse_mark);
            w.f64(stop.dissipated);
            w.f64(stop.onset_speed);
            w.u64(stop.sticks);
            w.f64(stop.stuck_time);
            w.f64(stop.held_since);
        }
        w.modal(&st.current);
        match &st.frozen {
            None => w.u8(0),
            Some(f) => {
                w.u8(1);
                w.f64s(f.c.as_slice());
                w.f64s(f.d.as_slice());
            }
        }
        match &st.balance {
            None => w.u8(0),
            Some(b) => {
                w.u8(1);
                w.f64s(&b.forcing);
                w.f64s(&b.damping);
                w.f64(b.impacts);
                w.f64(b.time);
            }
        }
    }

    /// Reads a state written by [`Self::encode`] for `model` and validates it.
    pub fn decode(model: Model, inputs: Vec<f64>, r: &mut Reader) -> Result<Simulation, String> {
        let version = r.u32()?;
        if version != STATE_VERSION {
            return Err(format!("simulation state version {version}; this build reads version {STATE_VERSION}"));
        }
        let n = r.u32()? as usize;
        let n_stops = r.u32()? as usize;
        if n != model.n_modes() || n_stops != model.stops.len() {
            return Err(format!(
                "simulation state has {n} modes and {n_stops} stops, the model {} and {}",
                model.n_modes(),
                model.stops.len()
            ));
        }
        let time = r.f64()?;
        let anchor_time = r.f64()?;
        let anchor = r.modal(n)?;
        let scan = r.f64()?;
        let probed = r.f64()?;
        let accounted = r.f64()?;
        let stops = (0..n_stops)
            .map(|i| {
                let code = r.u8()?;
                let contact = Contact::from_code(code).ok_or_else(|| format!("simulation state: stops[{i}] contact state code {code} is not one of 0..=3"))?;
                let flags = r.u8()?;
                if flags > 15 {
                    return Err(format!("simulation state: stops[{i}] departing flags {flags:#x} are not within 0..=15"));
                }
                Ok(StopState {
                    contact,
                    departing: [flags & 1 != 0, flags & 2 != 0],
                    anchor_departing: [flags & 4 != 0, flags & 8 != 0],
                    impacts: r.u64()?,
                    last_impact: r.f64()?,
                    previous_impact: r.opt_f64()?,
                    impulse: r.f64()?,
                    impulse_mark: r.f64()?,
                    dissipated: r.f64()?,
                    onset_speed: r.f64()?,
                    sticks: r.u64()?,
                    stuck_time: r.f64()?,
                    held_since: r.f64()?,
                })
            })
            .collect::<Result<Vec<_>, String>>()?;
        let current = r.modal(n)?;
        let frozen = if r.u8()? == 0 {
            None
        } else {
            Some(Frozen {
                c: nalgebra::DVector::from_vec(r.f64s(n, "frozen shape (structure modes)")?),
                d: nalgebra::DVector::from_vec(r.f64s(n, "frozen shape (tip-spring modes)")?),
            })
        };
        if frozen.is_some() != model.transfer.is_some() {
            return Err("simulation state and model disagree on mode transfer (a frozen shape)".into());
        }
        let balance = if r.u8()? == 0 {
            None
        } else {
            Some(EnergyBalance {
                forcing: r.f64s(n, "forcing energies")?,
                damping: r.f64s(n, "damping energies")?,
                impacts: r.f64()?,
                time: r.f64()?,
            })
        };
        if balance.is_some() != model.energy_balance {
            return Err("simulation state and model disagree on the energy balance".into());
        }
        let state = SimState { time, anchor_time, anchor, scan, probed, stops, accounted, current, balance, frozen };
        Simulation::restore_checked(model, inputs, state)
    }

    /// [`Simulation::restore`] for a state from outside (a file, another
    /// process): refused, with a message naming the field, unless the model
    /// can be in it.
    pub fn restore_checked(model: Model, inputs: Vec<f64>, state: SimState) -> Result<Simulation, String> {
        if state.anchor.q.len() != model.n_modes() || state.stops.len() != model.stops.len() {
            return Err("simulation state does not match the model's modes and stops".into());
        }
        if state.balance.as_ref().is_some_and(|b| b.forcing.len() != model.n_modes() || b.damping.len() != model.n_modes()) {
            return Err("simulation state: energy balance does not match the model's modes".into());
        }
        check_numbers(&state)?;
        check_contacts(&state, &model)?;
        let sim = Simulation::restore(model, inputs, state).map_err(|e| e.to_string())?;
        if sim.state.scan < sim.state.time && !sim.segment.is_integrated() {
            return Err(format!(
                "simulation state: times out of order: search position {} before the time {} (only an integrated phase stopped at a switch keeps one)",
                sim.state.scan, sim.state.time
            ));
        }
        check_geometry(&sim)?;
        // An integrated phase's impulse is accurate to its tolerance of the
        // motion's scale (a switch's state, a Newton step from the step's
        // start, may give a little less than the dense output did before
        // it): the impulse that changes the modal speeds by their size,
        // `|q'| / |w|`, is that scale (a stop of tiny stiffness delivers an
        // impulse far below it).
        let integrated = has_integrated_phase(&sim.model);
        let slack = if integrated { (16.0 * sim.model.integration_tolerance).max(1e-9) } else { 1e-9 };
        let speed = sim.state.anchor.qd.norm().max(sim.state.current.qd.norm());
        for i in 0..sim.model.stops.len() {
            let (total, mark) = (sim.impulse_total(i), sim.state.stops[i].impulse_mark);
            let motion = if integrated { slack * speed / sim.geometries[i].w.norm().max(f64::MIN_POSITIVE) } else { 0.0 };
            if mark > total.max(0.0) * (1.0 + slack) + motion + f64::MIN_POSITIVE {
                return Err(format!("simulation state: stops[{i}].impulse mark {mark} exceeds the impulse delivered so far, {total}"));
            }
        }
        if !sim.certifies_up_to_scan(1000) {
            return Err(format!(
                "simulation state: the claim that no event lies between t = {} and the search position {} cannot be certified",
                sim.state.time, sim.state.scan
            ));
        }
        Ok(sim)
    }
}

fn finite(field: &str, v: f64) -> Result<(), String> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(format!("simulation state: {field} = {v}: must be finite"))
    }
}

fn finite_modal(field: &str, m: &ModalState) -> Result<(), String> {
    for (j, (q, qd)) in m.q.iter().zip(m.qd.iter()).enumerate() {
        finite(&format!("{field}.q[{}]", j + 1), *q)?;
        finite(&format!("{field}.qd[{}]", j + 1), *qd)?;
    }
    Ok(())
}

/// Contact states the stops' laws can be in, departing flags naming
/// watched functions.
fn check_contacts(st: &SimState, model: &Model) -> Result<(), String> {
    for (s, m) in st.stops.iter().zip(&model.stops) {
        if !m.law.states().contains(&s.contact) {
            return Err(format!("simulation state: stop '{}' is {:?}, a state its law does not have", m.name, s.contact));
        }
        for (what, flags) in [("departing", s.departing), ("anchor departing", s.anchor_departing)] {
            if flags[1] && m.law.watches(s.contact).len() < 2 {
                return Err(format!("simulation state: stop '{}' {what} flag 2 set, but it watches one function when {:?}", m.name, s.contact));
            }
        }
    }
    Ok(())
}

/// Finite numbers, times in order.
fn check_numbers(st: &SimState) -> Result<(), String> {
    finite("time", st.time)?;
    finite("anchor time", st.anchor_time)?;
    finite("search position", st.scan)?;
    finite("last search point", st.probed)?;
    finite_modal("anchor", &st.anchor)?;
    finite_modal("current", &st.current)?;
    // An integrated phase stopped just before a switch keeps its search
    // position at the sample the switch's bracket starts from (it finds
    // the switch again there): that one position may lie before the time.
    if !(st.anchor_time <= st.time && (st.time <= st.scan || st.anchor_time <= st.scan)) {
        return Err(format!(
            "simulation state: times out of order: anchor {} <= time {} <= search position {} must hold",
            st.anchor_time, st.time, st.scan
        ));
    }
    if !(st.anchor_time <= st.probed && st.probed <= st.time) {
        return Err(format!(
            "simulation state: last search point {} outside [anchor {}, time {}]",
            st.probed, st.anchor_time, st.time
        ));
    }
    finite("accounted time", st.accounted)?;
    if let Some(f) = &st.frozen {
        for (j, (c, d)) in f.c.iter().zip(f.d.iter()).enumerate() {
            finite(&format!("frozen c[{}]", j + 1), *c)?;
            finite(&format!("frozen d[{}]", j + 1), *d)?;
        }
    }
    if !(st.anchor_time <= st.accounted && st.accounted <= st.time) {
        return Err(format!("simulation state: accounted time {} outside [anchor {}, time {}]", st.accounted, st.anchor_time, st.time));
    }
    for (i, s) in st.stops.iter().enumerate() {
        finite(&format!("stops[{i}].impulse"), s.impulse)?;
        finite(&format!("stops[{i}].impulse mark"), s.impulse_mark)?;
        finite(&format!("stops[{i}].dissipated"), s.dissipated)?;
        finite(&format!("stops[{i}].onset speed"), s.onset_speed)?;
        if s.onset_speed < 0.0 {
            return Err(format!("simulation state: stops[{i}].onset speed = {}: must be >= 0", s.onset_speed));
        }
        for (what, v) in [("impulse", s.impulse), ("impulse mark", s.impulse_mark), ("dissipated", s.dissipated)] {
            if v < 0.0 {
                return Err(format!("simulation state: stops[{i}].{what} = {v}: must be >= 0 (stops push, never pull)"));
            }
        }
        finite(&format!("stops[{i}].time stuck"), s.stuck_time)?;
        finite(&format!("stops[{i}].hold start"), s.held_since)?;
        if s.stuck_time < 0.0 {
            return Err(format!("simulation state: stops[{i}].time stuck = {}: must be >= 0", s.stuck_time));
        }
        if s.contact == Contact::Held && s.held_since > st.anchor_time {
            return Err(format!(
                "simulation state: stops[{i}].hold start = {} lies after the anchor {}: a hold starts at or before it",
                s.held_since, st.anchor_time
            ));
        }
        finite(&format!("stops[{i}].last impact"), s.last_impact)?;
        if s.last_impact > st.time {
            return Err(format!("simulation state: stops[{i}].last impact = {} lies after the time {}", s.last_impact, st.time));
        }
        if let Some(p) = s.previous_impact {
            finite(&format!("stops[{i}].previous impact"), p)?;
            if p > st.time {
                return Err(format!("simulation state: stops[{i}].previous impact = {p} lies after the time {}", st.time));
            }
        }
    }
    if let Some(b) = &st.balance {
        for (j, (f, d)) in b.forcing.iter().zip(&b.damping).enumerate() {
            finite(&format!("FE[{}]", j + 1), *f)?;
            finite(&format!("DE[{}]", j + 1), *d)?;
        }
        finite("impact energy", b.impacts)?;
        finite("energy balance time", b.time)?;
        if !(st.anchor_time <= b.time && b.time <= st.time) {
            return Err(format!(
                "simulation state: energy balance time {} outside [anchor {}, time {}]",
                b.time, st.anchor_time, st.time
            ));
        }
    }
    Ok(())
}

/// Whether some stop's law has an integrated (nonlinear) contact phase.
fn has_integrated_phase(model: &Model) -> bool {
    model.stops.iter().any(|s| s.law.states().iter().any(|c| s.law.term(*c) == crate::contact::PhaseTerm::Nonlinear))
}

/// The state agrees with the stops and with its own segment: every stop
/// is where its contact state says (apart: not inside; in contact:
/// inside), every function its contact state watches is non-negative (the
/// state would have switched at its zero), a held stop is on the stop at
/// rest with a pushing reaction, and every departing flag's function was
/// on its boundary where the flags were set.
fn check_geometry(sim: &Simulation) -> Result<(), String> {
    let st = &sim.state;
    let model = &sim.model;
    // Stopped just before an integrated phase's switch (which the restore
    // found again at this very time): the stops it switches are already
    // past their functions' zero.
    #[cfg(feature = "power-law")]
    let switching = sim.stops_at_pending_switch();
    #[cfg(not(feature = "power-law"))]
    let switching: Vec<usize> = Vec::new();
    let integrated = has_integrated_phase(model);
    for (i, stop) in model.stops.iter().enumerate() {
        let name = &stop.name;
        let counters = &st.stops[i];
        let contact = counters.contact;
        let mut at = WatchValues::new(sim, i, &st.current);
        // On the stop to rounding (before the integrated phases' widening
        // below): where a departing flag still means what it says.
        let rounding_p = at.level_p;
        if integrated && !stop.law.rigid() {
            // A compliant stop in a scene with an integrated phase (a rigid
            // stop's impacts and holds put the point exactly on it): its
            // switches are located on
            // the collocation polynomial and their states are full-order
            // steps (a Newton step past the zero), so the state a switch
            // leaves, and the anchor of the phase after it, lie on either
            // side of the surface by up to a few times the integration's
            // accuracy.
            let tolerance = 16.0 * model.integration_tolerance;
            at.level_p = at.level_p.max(tolerance * at.size_p);
            at.level_v = at.level_v.max(tolerance * at.size_v);
        }
        if contact == Contact::Held {
            if at.p.abs() > at.level_p || at.pd.abs() > 1e3 * at.level_v {
                return Err(format!(
                    "simulation state: stuck to stop '{name}' but {:e} away from it moving at {:e} along it",
                    -at.p, -at.pd
                ));
            }
            // A stop saved at its release (the run stopped before the
            // change) has its reaction at zero to the rounding of its terms.
            let pushes = -sim.geometries[i].side * sim.reaction(i);
            if pushes < -ON_BOUNDARY * (1.0 + pushes.abs() + sim.reaction_size_at(i, st.time, &st.current)) {
                return Err(format!("simulation state: stuck to stop '{name}' with a pulling reaction {}", sim.reaction(i)));
            }
        } else if !switching.contains(&i) {
            let outside = match contact {
                Contact::Open => at.p <= at.level_p,
                // A law that pushes while its force does (a dashpot keeps
                // pushing just outside the surface, up to the force's zero
                // at p = -c p' / k) is checked by that force below.
                _ => at.p >= -at.level_p || stop.law.watches(contact).contains(&Watch::Force),
            };
            if !outside {
                let place = if contact == Contact::Open { "apart from it but penetrated by" } else { "in contact but away from it by" };
                return Err(format!("simulation state: stop '{name}' is {contact:?}, {place} {:e} (rounding level {:e})", at.p.abs(), at.level_p));
            }
            for &watch in stop.law.watches(contact) {
                let (value, level) = at.watched(watch, 1.0);
                if value < -level {
                    return Err(format!(
                        "simulation state: stop '{name}' is {contact:?}, but its {watch:?} function is {value:e} (rounding level {level:e}): \
                         the contact state would have switched at its zero"
                    ));
                }
            }
        }
        // An integrated phase's flags are its events' own, read only at its
        // anchor (the search tests signs from there).
        let flag_read = !sim.segment.is_integrated() || st.time == st.anchor_time;
        if contact == Contact::Open && counters.departing[0] && flag_read && at.p.abs() <= rounding_p {
            // On the stop and treated as leaving it: it must not be pressed
            // in. (Off it by more than rounding, within an integrated
            // phase's accuracy, the flag is the last separation's, and the
            // motion may already be closing again: HertzStop at tolerance
            // 1e-4, 64 nm apart 17 us after a separation.)
            let geo = &sim.geometries[i];
            let mut jets = ModalJet::new(model.n_modes());
            jets.fill_free(&sim.dynamics, st.time, &st.current);
            let jet = jets.functional(&sim.gap_functionals[i], st.time);
            let vsize = geo.w.iter().zip(st.current.qd.iter()).map(|(a, b)| (a * b).abs()).sum::<f64>();
            let closing = jet.d[1] < -jet.noise[1].max(NOISE * vsize) || (jet.d[1] <= jet.noise[1] && tendency_from(&jet, 2) == Tendency::Closing);
            // Unless the run stopped just before this stop's impact (FMI
            // 3.0's event mode): the search finds it here. (A state at rest
            // on the stop, pressed on, flagged as leaving it, is refused:
            // an advance would stick it again, a history the run never had.)
            if closing && !sim.impacts_now(i) {
                return Err(format!(
                    "simulation state: on stop '{name}', pressed into it (velocity {:e}, acceleration {:e}) but neither stuck nor impacting",
                    jet.d[1], jet.d[2]
                ));
            }
        }
    }
    check_departing(sim)?;
    // The current state lies on the segment from the anchor.
    let mut on_segment = ModalState::zeros(model.n_modes());
    sim.state_at(st.time, &mut on_segment);
    let scale = st.current.q.amax().max(on_segment.q.amax()) + st.current.qd.amax().max(on_segment.qd.amax());
    let off = (&st.current.q - &on_segment.q).amax().max((&st.current.qd - &on_segment.qd).amax());
    if off > 1e-9 * scale.max(f64::MIN_POSITIVE) {
        return Err(format!(
            "simulation state: the current state is {off:e} away from the motion its anchor gives at t = {} (scale {scale:e})",
            st.time
        ));
    }
    Ok(())
}

impl Simulation {
    /// Whether an advance to the current time makes an impact at `stop`
    /// now: the state is one stopped just before that impact.
    fn impacts_now(&self, stop: usize) -> bool {
        let mut check = Simulation { record_events: true, events: Vec::new(), scratch: None, ..self.clone() };
        let now = check.state.time;
        check.advance(now, None).is_ok()
            && check.events.iter().any(|e| e.time == now && e.stop() == stop && matches!(e.kind, super::EventKind::Impact { .. }))
    }
}

/// A relative level far above rounding and far below any real distance
/// from a boundary: a departing flag's function lies within it.
pub(super) const ON_BOUNDARY: f64 = 1e-9;

/// Whether stop `i`'s watched function `watch` lies on its boundary in
/// `state`: within the level [`check_departing`] allows a departing flag.
pub(super) fn on_boundary(sim: &Simulation, i: usize, watch: Watch, state: &ModalState) -> bool {
    if watch == Watch::Reaction {
        return true;
    }
    let (value, level) = WatchValues::new(sim, i, state).watched(watch, ON_BOUNDARY / NOISE);
    value.abs() <= level
}

/// Departing flags are claims that a function was on its boundary: at the
/// last search point (`departing`) or at the anchor (`anchor_departing`,
/// which the free segment takes as exactly zero there). The search's
/// functions are checked where they claim it; an integrated phase tests
/// signs and never reads the flags.
fn check_departing(sim: &Simulation) -> Result<(), String> {
    let st = &sim.state;
    if sim.segment.is_integrated() {
        return Ok(());
    }
    let free = matches!(sim.segment, super::Segment::Free { .. });
    let mut at_probe = ModalState::zeros(sim.model.n_modes());
    sim.state_at(st.probed, &mut at_probe);
    for (i, stop) in sim.model.stops.iter().enumerate() {
        let counters = &st.stops[i];
        let watches = stop.law.watches(counters.contact);
        for (slot, &watch) in watches.iter().enumerate() {
            let claims = [
                (counters.departing[slot], "departing", "last search point", st.probed, &at_probe),
                (counters.anchor_departing[slot] && free, "anchor departing", "anchor", st.anchor_time, &st.anchor),
            ];
            for (claimed, what, point, t, state) in claims {
                if !claimed {
                    continue;
                }
                let (value, level) = if watch == Watch::Reaction {
                    let r = -sim.geometries[i].side * sim.reaction_at(i, t, state);
                    (r, ON_BOUNDARY * (1.0 + r.abs() + sim.reaction_size_at(i, t, state)))
                } else {
                    WatchValues::new(sim, i, state).watched(watch, ON_BOUNDARY / NOISE)
                };
                // An event sets the flags of the functions it leaves on
                // their boundary, and some leave it at once: a stick's
                // reaction pushes, a dashpot's force jumps to c p' at an
                // onset. The search's first point clears them; a run
                // stopped before it (FMI 3.0's early return) keeps them,
                // on the positive side, where the search would not read
                // them. Such a flag is the event's own (set at the anchor
                // too, and the search has not moved from it), not a claim
                // that the function is on its boundary. The free segment takes an anchor flag's
                // function as exactly zero: that claim must hold (but for
                // the reaction, which a free segment does not watch).
                let from_the_event =
                    what == "departing" && counters.anchor_departing[slot] && st.probed == st.anchor_time && st.scan == st.anchor_time;
                let inert = value > 0.0 && (watch == Watch::Reaction || from_the_event);
                if value.abs() > level && !inert {
                    return Err(format!(
                        "simulation state: stop '{}' {what} flag {} set, but its {watch:?} function is {value:e} at the {point} t = {t}, \
                         not on its boundary (allowed {level:e})",
                        stop.name,
                        slot + 1
                    ));
                }
            }
        }
    }
    Ok(())
}

/// A stop's penetration and rate in a state, with the rounding levels of
/// each (the terms' sizes).
struct WatchValues<'a> {
    law: &'a crate::contact::Law,
    onset_speed: f64,
    p: f64,
    pd: f64,
    level_p: f64,
    level_v: f64,
    /// The sizes of the terms of `p` and `pd`.
    size_p: f64,
    size_v: f64,
}

impl<'a> WatchValues<'a> {
    fn new(sim: &'a Simulation, i: usize, state: &ModalState) -> Self {
        let geo = &sim.geometries[i];
        // With mode transfer the active gap is what the frozen shape
        // leaves of the stop's own: both sizes count.
        let gaps = geo.gap.abs() + sim.model.stops[i].geometry.gap.abs();
        let size = gaps + geo.w.iter().zip(state.q.iter()).map(|(a, b)| (a * b).abs()).sum::<f64>();
        let vsize = geo.w.iter().zip(state.qd.iter()).map(|(a, b)| (a * b).abs()).sum::<f64>();
        // An event's time is a double: the point moves up to an ulp of the
        // time times its speed between two of them, and the search places
        // an event where its function is within the search's noise, up to
        // some tens of ulps of the time early, which Newton steps cannot
        // always take back (HertzStop from a random start: an onset at
        // 2.6e6 m/s left 1.7e-11 short of the surface, 7 ulps of time).
        let time_resolution = 32.0 * sim.state.time.abs() * f64::EPSILON * vsize;
        WatchValues {
            law: &sim.model.stops[i].law,
            onset_speed: sim.state.stops[i].onset_speed,
            p: geo.penetration(&state.q),
            pd: geo.penetration_rate(&state.qd),
            // The states an event leaves carry the rounding of the phase
            // they come from (a contact phase's coordinates, the search's
            // noise, which the next free phase takes as an exact zero):
            // far above this state's own rounding, far below any real
            // distance from the stop (ON_BOUNDARY).
            level_p: (NOISE * size + time_resolution).max(ON_BOUNDARY * size).max(sim.model.event_tolerance).max(f64::MIN_POSITIVE),
            level_v: (NOISE * vsize).max(ON_BOUNDARY * vsize).max(f64::MIN_POSITIVE),
            size_p: size,
            size_v: vsize,
        }
    }

    /// A watched function's value and its rounding level (times `widen`).
    fn watched(&self, watch: Watch, widen: f64) -> (f64, f64) {
        let (value, dp, dpd) = self.law.watched(watch, self.p, self.pd, self.onset_speed);
        let level = widen * (dp.abs() * self.level_p + dpd.abs() * self.level_v + NOISE * value.abs());
        (value, level)
    }
}
