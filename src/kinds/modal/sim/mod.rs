//! One simulation run: the state, the current phase, and the advance to a
//! requested time through every event on the way.
//!
//! The motion between events is a closed-form segment anchored at the last
//! event. The event search walks forward from the anchor in certified
//! steps that depend only on the anchor, never on the times it is asked
//! for, so the trajectory is the same whatever the communication step.
//!
//! This file holds the run itself ([`Simulation`]: its making, its
//! accessors, the advance and the changes of inputs and model); the rest
//! by job: `state.rs` (the state), `record.rs` (events),
//! `phases.rs` and `coupled.rs` (the current phase and its segment),
//! `search.rs` (the event search), `events.rs` (the event handling),
//! `accounting.rs` (impulses, forces, energy), `transfer.rs` (mode
//! transfer), `integrated.rs` (nonlinear phases) and `codec.rs` (the
//! encoded state).

use std::collections::HashMap;
use std::sync::Arc;

use nalgebra::DVector;

mod accounting;
mod codec;
mod coupled;
mod events;
mod flow;
#[cfg(feature = "power-law")]
mod flow_integrated;
#[cfg(feature = "power-law")]
mod integrated;
#[cfg(feature = "power-law")]
pub mod nonlinear;
mod phases;
mod record;
mod search;
mod state;
mod transfer;

pub use codec::STATE_VERSION;
pub use flow::state_vector;
pub use crate::kind::Reached;
use crate::error::SimError;
pub use record::{Event, EventKind};
pub use state::{EnergyBalance, Frozen, SimState, Stats, StopState};

use coupled::{PhaseEntry, PhaseMemo};
use events::EventWork;
use phases::{Channel, Segment};
use search::ProbeBuffers;
use transfer::{active_geometries, phase_dynamics};

use crate::contact::{Contact, Geometry};
use crate::kinds::modal::model::Model;
use crate::solve::lti::CoupledSystem;
use crate::solve::{FreeDynamics, FreeSegment, Functional, ModalState};

/// A run of one model.
#[derive(Clone, Debug)]
pub struct Simulation {
    model: Model,
    dynamics: FreeDynamics,
    inputs: Vec<f64>,
    state: SimState,
    segment: Segment,
    /// The event functions of the current phase.
    channels: Vec<Channel>,
    /// Each stop's geometry in the current basis (with mode transfer, the
    /// frozen shape's share of the gap taken off).
    geometries: Vec<Geometry>,
    gap_functionals: Vec<Functional>,
    coupled_cache: HashMap<Vec<Contact>, Arc<CoupledSystem>>,
    /// The contact phases entered lately, with their projected loads and
    /// functions (derived data, never part of the state).
    phase_cache: Vec<PhaseEntry>,
    /// The contact phases entered under the current dynamics, most recent
    /// first: a re-entry (every stick of a chatter-and-stick run) starts
    /// its segment without forming the phase's loads and functions again.
    /// Cleared whenever the dynamics or the model change.
    phase_memo: Vec<PhaseMemo>,
    /// The segment a change of phase displaced, kept for its storage: the
    /// next segment of its kind (at the next stick, the next release)
    /// restarts in it instead of allocating its own.
    spare: Option<Segment>,
    /// Longest interval over which the event search bounds derivatives.
    tau_max: f64,
    record_events: bool,
    events: Vec<Event>,
    stats: Stats,
    /// Work space of the event search, kept between calls (derived from
    /// the dynamics: dropped when they change).
    scratch: Option<ProbeBuffers>,
    /// The dynamics changed inside an advance (a change of basis): the
    /// search's work space must be rebuilt.
    basis_changed: bool,
    /// Mode transfer with inherited damping: the contact phase's system.
    transfer_system: Option<Arc<CoupledSystem>>,
    /// Work space of the event handling (no state: any value will do;
    /// `None` until the first event). Boxed: taken out and put back at
    /// every event, a pointer moves instead of the scratch vectors' headers.
    event_work: Option<Box<EventWork>>,
    /// While a flow's Jacobian is formed: the ends of the integrated
    /// steps taken (derived, never part of the state).
    #[cfg(feature = "power-law")]
    flow_trace: Option<Vec<f64>>,
}

/// The event search bounds derivatives over at most this many of the
/// model's shortest periods at a time (the bounds hardly grow with it; see
/// `FreeSegment::fill_bounds`).
const TAU_MAX_PERIODS: f64 = 4.0;

impl Simulation {
    /// Starts a run at `start_time` from the model's initial state. A state
    /// at rest on a stop with the load pushing into it starts stuck.
    pub fn new(model: Model, start_time: f64) -> Result<Self, SimError> {
        let initial = model.initial.clone();
        let mut stops = Vec::new();
        for (i, s) in model.stops.iter().enumerate() {
            let g = s.geometry.gap_functional();
            let value = g.offset + g.q.dot(&initial.q);
            let scale = g.offset.abs() + g.q.iter().zip(initial.q.iter()).map(|(a, b)| (a * b).abs()).sum::<f64>();
            if s.law.rigid() && value < -(crate::solve::functional::NOISE * scale).max(model.event_tolerance) {
                let mut fields = vec![format!("stops[{i}].gap")];
                fields.extend((0..model.n_modes()).filter(|&j| initial.q[j] * s.geometry.w[j] != 0.0).map(|j| format!("initial.q[{j}]")));
                return Err(SimError::Penetration {
                    stop: s.name.clone(),
                    displacement: s.geometry.w.dot(&initial.q),
                    limit: s.geometry.target(),
                    side: s.geometry.side,
                    fields,
                });
            }
            let contact = s.law.initial_contact(s.geometry.penetration(&initial.q), s.geometry.penetration_rate(&initial.qd));
            if s.law.term(Contact::Pressed) == crate::contact::PhaseTerm::Nonlinear && s.geometry.penetration(&initial.q) > 0.0 {
                // No deeper than a point of the stop's effective mass
                // arriving at the speed limit reaches (as the rotating
                // beam's start): beyond, the law's force and damping leave
                // every scale the run can resolve.
                let penetration = s.geometry.penetration(&initial.q);
                let limit = s.law.depth(model.speed_limit, s.geometry.w.dot(&s.geometry.w));
                if penetration > limit {
                    let mut fields = vec![format!("stops[{i}].gap")];
                    fields.extend((0..model.n_modes()).filter(|&j| initial.q[j] * s.geometry.w[j] != 0.0).map(|j| format!("initial.q[{j}]")));
                    return Err(SimError::InitialPenetration { point: format!("the point of stop '{}'", s.name), penetration, limit, fields });
                }
            }
            stops.push(StopState {
                contact,
                departing: [false; 2],
                anchor_departing: [false; 2],
                impacts: if contact == Contact::Pressed { 1 } else { 0 },
                last_impact: start_time,
                previous_impact: None,
                impulse: 0.0,
                impulse_mark: 0.0,
                dissipated: 0.0,
                onset_speed: s.geometry.penetration_rate(&initial.qd).max(0.0),
                sticks: u64::from(contact == Contact::Held),
                stuck_time: 0.0,
                held_since: start_time,
            });
        }
        let state = SimState {
            time: start_time,
            anchor_time: start_time,
            anchor: initial.clone(),
            scan: start_time,
            probed: start_time,
            stops,
            accounted: start_time,
            frozen: model.transfer.as_ref().map(|_| Frozen { c: DVector::zeros(model.n_modes()), d: DVector::zeros(model.n_modes()) }),
            current: initial,
            balance: model.energy_balance.then(|| EnergyBalance {
                forcing: vec![0.0; model.n_modes()],
                damping: vec![0.0; model.n_modes()],
                impacts: 0.0,
                time: start_time,
            }),
        };
        let inputs = vec![0.0; model.inputs.len()];
        let mut sim = Self::restore(model, inputs, state)?;
        // Settle contacts present at the start (impact, sticking).
        sim.advance_to(start_time)?;
        Ok(sim)
    }

    /// Restores a run from a saved state (see [`Self::state`]): everything
    /// else is derived from the model, the inputs and the state.
    pub fn restore(model: Model, inputs: Vec<f64>, state: SimState) -> Result<Self, SimError> {
        let dynamics = phase_dynamics(&model, &inputs, &state);
        let geometries = active_geometries(&model, &state);
        let gap_functionals = geometries.iter().map(|g| g.gap_functional()).collect();
        let tau_max = TAU_MAX_PERIODS * model.shortest_period();
        let segment = Segment::Free { segment: FreeSegment::new(&dynamics, state.anchor_time, &state.anchor), functions: Vec::new() };
        let mut sim = Simulation {
            model,
            dynamics,
            inputs,
            state,
            segment,
            channels: Vec::new(),
            geometries,
            gap_functionals,
            coupled_cache: HashMap::new(),
            phase_cache: Vec::new(),
            phase_memo: Vec::new(),
            spare: None,
            tau_max,
            record_events: true,
            events: Vec::new(),
            stats: Stats::default(),
            scratch: None,
            basis_changed: false,
            transfer_system: None,
            event_work: None,
            #[cfg(feature = "power-law")]
            flow_trace: None,
        };
        sim.rebuild_segment()?;
        // An integrated phase rebuilds its steps from the anchor.
        #[cfg(feature = "power-law")]
        sim.replay_to(sim.state.scan.max(sim.state.time))?;
        let time = sim.state.time;
        #[cfg(feature = "power-law")]
        if sim.segment.is_integrated() && sim.state.scan < time {
            // Stopped just before a switch, in the switch's own state: the
            // search finds it again from the saved position.
            let from = sim.state.scan;
            let found = sim.integrated_search(time, &mut 0)?;
            sim.state.scan = from;
            if found.map(|f| f.time) != Some(time) {
                return Err(SimError::Integration {
                    time,
                    message: format!("simulation state: no switch at this time from the search position {from}, where the state says the run stopped before one"),
                });
            }
        } else if let Segment::Integrated(seg) = &mut sim.segment {
            seg.settle_at(time);
        }
        Ok(sim)
    }

    pub fn stats(&self) -> Stats {
        self.stats
    }

    pub fn model(&self) -> &Model {
        &self.model
    }

    pub fn state(&self) -> &SimState {
        &self.state
    }

    pub fn inputs(&self) -> &[f64] {
        &self.inputs
    }

    pub fn time(&self) -> f64 {
        self.state.time
    }

    /// The anchor's time: the motion now is propagated from there.
    pub fn earliest_time(&self) -> f64 {
        self.state.anchor_time
    }

    pub fn current(&self) -> &ModalState {
        &self.state.current
    }

    pub fn is_stuck(&self, stop: usize) -> bool {
        self.state.stops[stop].contact == Contact::Held
    }

    /// Total time the structure has been stuck to `stop` since the start,
    /// the current hold included.
    pub fn stuck_time(&self, stop: usize) -> f64 {
        let s = &self.state.stops[stop];
        s.stuck_time + if s.contact == Contact::Held { self.state.time - s.held_since } else { 0.0 }
    }

    pub fn contact(&self, stop: usize) -> Contact {
        self.state.stops[stop].contact
    }

    /// Keep (default) or drop the record of events.
    pub fn set_event_recording(&mut self, on: bool) {
        self.record_events = on;
        if !on {
            self.events.clear();
        }
    }

    /// The events since the last call.
    pub fn drain_events(&mut self) -> Vec<Event> {
        std::mem::take(&mut self.events)
    }

    /// Advances to `t_end`, handling every event on the way (including one
    /// exactly at `t_end`).
    pub fn advance_to(&mut self, t_end: f64) -> Result<(), SimError> {
        self.advance(t_end, None).map(|_| ())
    }

    /// The advance of the contract ([`crate::kind::Run::advance`]): to
    /// `t_end`, stopping just before the change of an event that the
    /// record reports where `stop_before(te)` says so (the state just
    /// before it; an advance to the same time makes it). The events are
    /// found again from the state alone, so a saved state keeps them. One
    /// advance: one work cap.
    pub fn advance(&mut self, t_end: f64, stop_before: Option<&mut dyn FnMut(f64) -> bool>) -> Result<Reached, SimError> {
        if t_end < self.state.time {
            return Err(SimError::Backwards { now: self.state.time, requested: t_end });
        }
        if t_end > self.state.time && self.model.impulses {
            for i in 0..self.model.stops.len() {
                // An integrated phase's impulse may dip a rounding below
                // zero at a contact's start: the mark never does.
                self.state.stops[i].impulse_mark = self.impulse_total(i).max(0.0);
            }
        }
        let mut buffers = self.scratch.take().unwrap_or_else(|| ProbeBuffers::new(&self.dynamics));
        let result = self.advance_with(t_end, &mut buffers, stop_before);
        self.scratch = Some(buffers);
        result
    }

    /// Sets the held actuator forces; a change starts a new segment now.
    pub fn set_inputs(&mut self, inputs: &[f64]) -> Result<(), SimError> {
        if inputs == self.inputs.as_slice() {
            return Ok(());
        }
        if inputs.len() != self.inputs.len() {
            panic!("{} inputs given, the model has {}", inputs.len(), self.inputs.len());
        }
        let current = self.state.current.clone();
        self.close_segment(self.state.time, &current);
        self.inputs.copy_from_slice(inputs);
        self.dynamics = phase_dynamics(&self.model, &self.inputs, &self.state);
        self.phase_memo.clear();
        self.scratch = None;
        self.reanchor_now()
    }

    /// Replaces the model by one with other tunable values (loads,
    /// restitution, chatter threshold); a change starts a new segment now.
    pub fn set_model(&mut self, model: Model) -> Result<(), SimError> {
        if model == self.model {
            return Ok(());
        }
        let same_phases = model.oscillators == self.model.oscillators
            && model.stops.len() == self.model.stops.len()
            && model.stops.iter().zip(&self.model.stops).all(|(a, b)| a.geometry == b.geometry && a.law == b.law);
        if !same_phases {
            self.coupled_cache.clear();
            self.phase_cache.clear();
            self.transfer_system = None;
        }
        self.tau_max = TAU_MAX_PERIODS * model.shortest_period();
        let current = self.state.current.clone();
        self.close_segment(self.state.time, &current);
        self.model = model;
        self.refresh_basis();
        self.scratch = None;
        self.reanchor_now()
    }

    /// Starts a new segment at the current time (the loads changed) and
    /// settles what the change causes there at once (a stuck beam whose
    /// reaction now pulls is released before anyone reads the outputs).
    /// The caller has closed the old segment's impulses.
    fn reanchor_now(&mut self) -> Result<(), SimError> {
        if self.state.anchor_time != self.state.time {
            for s in &mut self.state.stops {
                s.departing = [false; 2];
            }
            self.state.probed = self.state.time;
        }
        self.state.anchor = self.state.current.clone();
        self.state.anchor_time = self.state.time;
        self.state.scan = self.state.time;
        self.mark_anchor_departing();
        self.rebuild_segment()?;
        // In an integrated phase (a compliant contact pressed beside the
        // hold) the search takes a reaction pulling from the phase's start
        // for no zero: such holds are released here, as at a phase's start.
        self.release_pulled_holds(self.state.time)?;
        // A stick made at this very time flags its reaction as departing
        // (see `claims`); under the new loads the reaction may pull off
        // the boundary: the flag then no longer holds, and the search
        // releases the stop here, before any output is read.
        if self.drop_broken_reaction_claims() {
            self.rebuild_segment()?;
        }
        self.advance_to(self.state.time)
    }

    /// Drops the departing flags of held stops whose reaction now pulls
    /// beyond the level the decoder takes as on the boundary (see
    /// `codec::check_departing`); whether any was dropped.
    fn drop_broken_reaction_claims(&mut self) -> bool {
        let mut dropped = false;
        for i in 0..self.model.stops.len() {
            if self.state.stops[i].contact != Contact::Held {
                continue;
            }
            let Some(slot) = self.model.stops[i].law.watches(Contact::Held).iter().position(|w| *w == crate::contact::Watch::Reaction) else { continue };
            let flags = self.state.stops[i].departing[slot] || self.state.stops[i].anchor_departing[slot];
            if !flags {
                continue;
            }
            let (t, current) = (self.state.time, &self.state.current);
            let push = -self.geometries[i].side * self.reaction_at(i, t, current);
            if push < -codec::ON_BOUNDARY * (1.0 + push.abs() + self.reaction_size_at(i, t, current)) {
                self.state.stops[i].departing[slot] = false;
                self.state.stops[i].anchor_departing[slot] = false;
                dropped = true;
            }
        }
        dropped
    }

    /// Keeps the departing flags of a new anchor (part of the state: a
    /// restore rebuilds the segment from them, not from the flags the
    /// search has cleared since).
    pub(super) fn mark_anchor_departing(&mut self) {
        for s in &mut self.state.stops {
            s.anchor_departing = s.departing;
        }
    }
}
