//! One simulation run: the state, the current phase, and the advance to a
//! requested time through every event on the way.
//!
//! The motion between events is a closed-form segment anchored at the last
//! event. The event search walks forward from the anchor in certified
//! steps that depend only on the anchor, never on the times it is asked
//! for, so the trajectory is the same whatever the communication step.

use std::collections::HashMap;
use std::fmt;
use std::sync::Arc;

use nalgebra::DVector;

mod codec;

pub use codec::STATE_VERSION;

use crate::contact::restitution::{apply_impact, energy_loss, ImpactRow};
use crate::model::Model;
use crate::solve::events::{certified_step, tendency_from, Certified, Tendency};
use crate::solve::free::{Increment, ModalBounds, ModalJet};
use crate::solve::functional::NOISE;
use crate::solve::lti::{CoupledSegment, CoupledSystem, LtiError, ProjectedFunctional};
use crate::solve::{DerivativeBounds, FreeDynamics, FreeSegment, Functional, Jet, ModalState};

/// What happened at an event.
#[derive(Clone, Debug, PartialEq)]
pub enum EventKind {
    /// An impact at `stop` with approach speed `speed`; `chatter` marks the
    /// final `R = 0` impact of a chatter sequence.
    Impact { stop: usize, speed: f64, restitution: f64, energy_lost: f64, chatter: bool },
    /// The beam sticks to `stop`; `reaction` is the stop's force then.
    Stick { stop: usize, reaction: f64 },
    /// The reaction of `stop` changed sign: the beam leaves it.
    Release { stop: usize },
    /// The beam touched `stop` with zero velocity and left without impact.
    Graze { stop: usize },
}

#[derive(Clone, Debug, PartialEq)]
pub struct Event {
    pub time: f64,
    pub kind: EventKind,
}

#[derive(Clone, Debug, PartialEq)]
pub enum SimError {
    /// The initial state lies beyond a stop.
    Penetration { stop: String, displacement: f64, limit: f64, side: f64 },
    /// More events than allowed inside one call to `advance_to`.
    TooManyEvents { time: f64, count: u64 },
    /// More event-search points than allowed inside one call to
    /// `advance_to` (events are rare but the search is slow: a very fast
    /// load, an extremely long step).
    TooMuchWork { time: f64, probes: u64 },
    /// A contact phase could not be set up.
    Contact(LtiError),
    /// A requested time lies before the current one.
    Backwards { now: f64, requested: f64 },
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SimError::Penetration { stop, displacement, limit, side } => write!(
                f,
                "the initial state penetrates stop '{stop}': displacement there is {displacement}, allowed {} {limit}; \
                 change the initial modal coordinates or the gap",
                if *side > 0.0 { "<=" } else { ">=" }
            ),
            SimError::TooManyEvents { time, count } => write!(
                f,
                "{count} events within one step near t = {time}: raise solver.max_events_per_step or the chatter threshold eps"
            ),
            SimError::TooMuchWork { time, probes } => write!(
                f,
                "the work cap of one step (event-search points and energy-balance quadrature nodes, \
                 solver.max_probes_per_step) was reached after {probes} event-search points, at t = {time}: \
                 take shorter communication steps or raise solver.max_probes_per_step"
            ),
            SimError::Contact(e) => write!(f, "{e}"),
            SimError::Backwards { now, requested } => {
                write!(f, "requested time {requested} lies before the current time {now}")
            }
        }
    }
}

impl std::error::Error for SimError {}

impl From<LtiError> for SimError {
    fn from(e: LtiError) -> Self {
        SimError::Contact(e)
    }
}

/// Counters of one stop.
#[derive(Clone, Debug, PartialEq)]
pub struct StopState {
    pub impacts: u64,
    /// Time of the latest impact (the start time before the first).
    pub last_impact: f64,
    /// Time of the previous impact of the current chatter sequence, reset
    /// when the stop sticks or releases.
    pub previous_impact: Option<f64>,
}

/// Everything that evolves; with the model and inputs it determines the
/// future exactly (the segment is derived from it).
#[derive(Clone, Debug, PartialEq)]
pub struct SimState {
    pub time: f64,
    pub anchor_time: f64,
    pub anchor: ModalState,
    /// Bit i set: the beam is stuck to stop i.
    pub stuck: u64,
    /// The event search has proven the segment event-free up to here.
    pub scan: f64,
    /// Bit i set: stop i's event function was put on its boundary by the
    /// event handling at `scan` and is leaving it.
    pub departing: u64,
    pub stops: Vec<StopState>,
    /// The state at `time`.
    pub current: ModalState,
    /// Seed 003's energy accounting, when the model asks for it.
    pub balance: Option<EnergyBalance>,
}

/// The work of the loads on each mode `FE_j = int qd_j f_j dt`, the energy
/// its damping dissipates `DE_j = int 2 zeta_j omega_j qd_j^2 dt` (seed 003
/// eq. 8) and the energy lost at impacts, all from the start, so that
/// `E(t) - E(0) = sum_j (FE_j - DE_j) - impacts` (seed 003 eq. 7).
#[derive(Clone, Debug, PartialEq)]
pub struct EnergyBalance {
    pub forcing: Vec<f64>,
    pub damping: Vec<f64>,
    pub impacts: f64,
    /// The sums cover the run up to this time.
    pub time: f64,
}

#[derive(Clone, Debug)]
enum Segment {
    Free {
        segment: FreeSegment,
        /// Each stop's gap at the anchor: exactly 0 for a stop the event
        /// handling just put on its boundary (impact, release), so that the
        /// gap along the segment is that plus an increment accurate relative
        /// to itself.
        anchor_gaps: Vec<f64>,
    },
    Coupled {
        system: Arc<CoupledSystem>,
        segment: CoupledSegment,
        /// Event function of each stop in this segment's coordinates.
        events: Vec<ProjectedFunctional>,
        /// The reaction (seed eq. 33) of each stuck stop.
        reactions: Vec<Option<Functional>>,
    },
}

/// A run of one model.
#[derive(Clone, Debug)]
pub struct Simulation {
    model: Model,
    dynamics: FreeDynamics,
    inputs: Vec<f64>,
    state: SimState,
    segment: Segment,
    gap_functionals: Vec<Functional>,
    coupled_cache: HashMap<u64, Arc<CoupledSystem>>,
    /// Longest interval over which the event search bounds derivatives.
    tau_max: f64,
    record_events: bool,
    events: Vec<Event>,
    stats: Stats,
    /// Work space of the event search, kept between calls (derived from
    /// the dynamics: dropped when they change).
    scratch: Option<ProbeBuffers>,
}

/// Work counters of a run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Points where the event functions were evaluated.
    pub probes: u64,
    /// Events handled (each may hold several simultaneous ones).
    pub events: u64,
}

/// The event search bounds derivatives over at most this many of the
/// model's shortest periods at a time (the bounds hardly grow with it; see
/// `FreeSegment::fill_bounds`).
const TAU_MAX_PERIODS: f64 = 4.0;

fn bit(i: usize) -> u64 {
    1u64 << i
}

impl Simulation {
    /// Starts a run at `start_time` from the model's initial state. A state
    /// at rest on a stop with the load pushing into it starts stuck.
    pub fn new(model: Model, start_time: f64) -> Result<Self, SimError> {
        let initial = model.initial.clone();
        for s in &model.stops {
            let g = s.gap_functional();
            let value = g.offset + g.q.dot(&initial.q);
            let scale = g.offset.abs() + g.q.iter().zip(initial.q.iter()).map(|(a, b)| (a * b).abs()).sum::<f64>();
            if value < -(crate::solve::functional::NOISE * scale).max(model.event_tolerance) {
                return Err(SimError::Penetration {
                    stop: s.name.clone(),
                    displacement: s.w.dot(&initial.q),
                    limit: s.target(),
                    side: s.side,
                });
            }
        }
        let state = SimState {
            time: start_time,
            anchor_time: start_time,
            anchor: initial.clone(),
            stuck: 0,
            scan: start_time,
            departing: 0,
            stops: model.stops.iter().map(|_| StopState { impacts: 0, last_impact: start_time, previous_impact: None }).collect(),
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
        let dynamics = FreeDynamics::new(model.oscillators.clone(), model.forcing_with_inputs(&inputs));
        let gap_functionals = model.stops.iter().map(|s| s.gap_functional()).collect();
        let tau_max = TAU_MAX_PERIODS * model.shortest_period();
        let segment = Segment::Free { segment: FreeSegment::new(&dynamics, state.anchor_time, &state.anchor), anchor_gaps: Vec::new() };
        let mut sim = Simulation {
            model,
            dynamics,
            inputs,
            state,
            segment,
            gap_functionals,
            coupled_cache: HashMap::new(),
            tau_max,
            record_events: true,
            events: Vec::new(),
            stats: Stats::default(),
            scratch: None,
        };
        sim.rebuild_segment()?;
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

    pub fn current(&self) -> &ModalState {
        &self.state.current
    }

    pub fn is_stuck(&self, stop: usize) -> bool {
        self.state.stuck & bit(stop) != 0
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

    pub fn energy(&self) -> f64 {
        self.model.energy(&self.state.current)
    }

    pub fn energy_balance(&self) -> Option<&EnergyBalance> {
        self.state.balance.as_ref()
    }

    /// Adds the loads' work and the damping's dissipation over the part of
    /// the current segment not yet counted, up to `t`, by Gauss-Legendre
    /// quadrature fine enough for the fastest mode: the integrands are
    /// smooth inside a segment, so the sums are exact to rounding.
    fn accumulate_balance(&mut self, t: f64) {
        let Some(from) = self.state.balance.as_ref().map(|b| b.time) else { return };
        if t <= from {
            return;
        }
        let n = self.model.n_modes();
        let fastest = self.fastest_frequency();
        let mut st = ModalState::zeros(n);
        let mut f = DVector::zeros(n);
        let mut forcing = vec![0.0; n];
        let mut damping = vec![0.0; n];
        // qd_j f_j and qd_j^2 oscillate at up to twice the fastest frequency.
        crate::solve::quadrature::for_each_node_band_limited(from, t, 2.0 * fastest, |tau, w| {
            self.state_at(tau, &mut st);
            self.dynamics.forcing.derivative(tau, 0, &mut f);
            for j in 0..n {
                let o = &self.model.oscillators[j];
                forcing[j] += w * st.qd[j] * f[j];
                damping[j] += w * 2.0 * o.a * st.qd[j] * st.qd[j];
            }
        });
        let b = self.state.balance.as_mut().expect("checked above");
        for j in 0..n {
            b.forcing[j] += forcing[j];
            b.damping[j] += damping[j];
        }
        b.time = t;
    }

    /// The fastest frequency in the motion: the highest mode or load.
    fn fastest_frequency(&self) -> f64 {
        let mut fastest = self.model.oscillators.iter().map(|o| o.omega).fold(0.0, f64::max);
        for h in &self.dynamics.forcing.harmonics {
            fastest = fastest.max(h.omega);
        }
        fastest
    }

    /// Quadrature nodes per unit time of the energy balance (0 without
    /// it): each costs about what a point of the event search costs, and
    /// counts against the same cap.
    fn balance_nodes_per_time(&self) -> f64 {
        match self.state.balance {
            // 16-point panels of pi / 2 at twice the fastest frequency.
            Some(_) => 16.0 * 2.0 * self.fastest_frequency() / (0.5 * std::f64::consts::PI),
            None => 0.0,
        }
    }

    /// The reaction of a stop at the current time (0 unless stuck to it).
    pub fn reaction(&self, stop: usize) -> f64 {
        self.reaction_at(stop, self.state.time, &self.state.current)
    }

    fn reaction_at(&self, stop: usize, t: f64, state: &ModalState) -> f64 {
        match &self.segment {
            Segment::Coupled { reactions, .. } => match &reactions[stop] {
                Some(r) => {
                    let mut f = DVector::zeros(self.model.n_modes());
                    self.dynamics.forcing.derivative(t, 0, &mut f);
                    r.value(state, &f)
                }
                None => 0.0,
            },
            Segment::Free { .. } => 0.0,
        }
    }

    /// Sets the held actuator forces; a change starts a new segment now.
    pub fn set_inputs(&mut self, inputs: &[f64]) -> Result<(), SimError> {
        if inputs == self.inputs.as_slice() {
            return Ok(());
        }
        if inputs.len() != self.inputs.len() {
            panic!("{} inputs given, the model has {}", inputs.len(), self.inputs.len());
        }
        self.inputs.copy_from_slice(inputs);
        self.dynamics.set_forcing(self.model.forcing_with_inputs(&self.inputs));
        self.scratch = None;
        self.reanchor_now()
    }

    /// Replaces the model by one with other tunable values (loads,
    /// restitution, chatter threshold); a change starts a new segment now.
    pub fn set_model(&mut self, model: Model) -> Result<(), SimError> {
        if model == self.model {
            return Ok(());
        }
        let same_structure = model.oscillators == self.model.oscillators
            && model.stops.len() == self.model.stops.len()
            && model.stops.iter().zip(&self.model.stops).all(|(a, b)| a.w == b.w && a.target() == b.target());
        if !same_structure {
            self.coupled_cache.clear();
        }
        self.tau_max = TAU_MAX_PERIODS * model.shortest_period();
        self.gap_functionals = model.stops.iter().map(|s| s.gap_functional()).collect();
        self.model = model;
        self.dynamics = FreeDynamics::new(self.model.oscillators.clone(), self.model.forcing_with_inputs(&self.inputs));
        self.scratch = None;
        self.reanchor_now()
    }

    /// Starts a new segment at the current time (the loads changed) and
    /// settles what the change causes there at once (a stuck beam whose
    /// reaction now pulls is released before anyone reads the outputs).
    fn reanchor_now(&mut self) -> Result<(), SimError> {
        if self.state.anchor_time != self.state.time {
            self.state.departing = 0;
        }
        self.state.anchor = self.state.current.clone();
        self.state.anchor_time = self.state.time;
        self.state.scan = self.state.time;
        self.rebuild_segment()?;
        self.advance_to(self.state.time)
    }

    fn coupled_system(&mut self, mask: u64) -> Result<Arc<CoupledSystem>, SimError> {
        if let Some(s) = self.coupled_cache.get(&mask) {
            return Ok(s.clone());
        }
        let n = self.model.n_modes();
        let k = nalgebra::DMatrix::from_diagonal(&DVector::from_iterator(n, self.model.oscillators.iter().map(|o| o.omega * o.omega)));
        let d = nalgebra::DMatrix::from_diagonal(&DVector::from_iterator(n, self.model.oscillators.iter().map(|o| 2.0 * o.a)));
        let cols: Vec<DVector<f64>> =
            self.model.stops.iter().enumerate().filter(|(i, _)| mask & bit(*i) != 0).map(|(_, s)| s.w.clone()).collect();
        let w = nalgebra::DMatrix::from_columns(&cols);
        let sys = Arc::new(CoupledSystem::new(k, d, w)?);
        self.coupled_cache.insert(mask, sys.clone());
        Ok(sys)
    }

    fn stuck_targets(&self, mask: u64) -> DVector<f64> {
        DVector::from_iterator(
            mask.count_ones() as usize,
            self.model.stops.iter().enumerate().filter(|(i, _)| mask & bit(*i) != 0).map(|(_, s)| s.target()),
        )
    }

    /// Derives the segment from the anchor and the phase.
    fn rebuild_segment(&mut self) -> Result<(), SimError> {
        let mask = self.state.stuck;
        if mask == 0 {
            let anchor = &self.state.anchor;
            let anchor_gaps = self
                .gap_functionals
                .iter()
                .enumerate()
                .map(|(i, g)| if self.state.departing & bit(i) != 0 { 0.0 } else { g.offset + g.q.dot(&anchor.q) })
                .collect();
            self.segment = Segment::Free { segment: FreeSegment::new(&self.dynamics, self.state.anchor_time, anchor), anchor_gaps };
            return Ok(());
        }
        let system = self.coupled_system(mask)?;
        let targets = self.stuck_targets(mask);
        let segment = CoupledSegment::new(&system, &self.dynamics.forcing, &targets, self.state.anchor_time, &self.state.anchor);
        let mut reactions_by_column = system.reaction_functionals().into_iter();
        let mut events = Vec::new();
        let mut reactions = Vec::new();
        for (i, stop) in self.model.stops.iter().enumerate() {
            if mask & bit(i) != 0 {
                let r = reactions_by_column.next().expect("one reaction per held stop");
                // Admissible while the stop pushes the beam away: -side lambda >= 0.
                events.push(segment.project_functional(&system, &r.clone().scaled(-stop.side)));
                reactions.push(Some(r));
            } else {
                events.push(segment.project_functional(&system, &self.gap_functionals[i]));
                reactions.push(None);
            }
        }
        self.segment = Segment::Coupled { system, segment, events, reactions };
        Ok(())
    }

    fn state_at(&self, t: f64, out: &mut ModalState) {
        match &self.segment {
            Segment::Free { segment, .. } => segment.state_at(&self.dynamics, t, out),
            Segment::Coupled { system, segment, .. } => segment.state_at(system, t, out),
        }
    }

    /// Jets of every stop's event function at time `t` (state `st`), and the
    /// certified step or the list of functions at zero.
    fn probe(&self, t: f64, st: &mut ModalState, buffers: &mut ProbeBuffers) -> Probe {
        let mut scan = Scan { departing: self.state.departing, ..Scan::default() };
        let tol = self.model.event_tolerance;
        let ProbeBuffers { jet: jet_buf, bounds: bound_buf, increment, .. } = buffers;
        match &self.segment {
            Segment::Free { segment: seg, anchor_gaps } => {
                seg.state_and_increment_at(&self.dynamics, t, st, increment);
                if self.model.stops.is_empty() {
                    return scan.finish();
                }
                jet_buf.fill_free(&self.dynamics, t, st);
                let mut bounds_ready = false;
                for (i, gap) in self.gap_functionals.iter().enumerate() {
                    let mut jet = jet_buf.functional(gap, t);
                    // The gap itself from the anchor's plus the increment.
                    let (dg, noise) = increment.functional(&gap.q);
                    jet.d[0] = anchor_gaps[i] + dg;
                    jet.noise[0] = (noise + NOISE * anchor_gaps[i].abs()).max(tol);
                    scan.consider(i, jet, || {
                        if !bounds_ready {
                            seg.fill_bounds(&self.dynamics, st, increment, self.tau_max, bound_buf);
                            bounds_ready = true;
                        }
                        bound_buf.functional(gap, self.tau_max)
                    });
                }
            }
            Segment::Coupled { system, segment, events, .. } => {
                segment.state_at(system, t, st);
                let sample = segment.sample(system, t);
                let mut coords = None;
                for (i, p) in events.iter().enumerate() {
                    let mut jet = segment.jet(system, &self.dynamics.forcing, p, &sample);
                    if self.state.stuck & bit(i) == 0 {
                        jet.noise[0] = jet.noise[0].max(tol);
                    }
                    scan.consider(i, jet, || {
                        let coords = coords.get_or_insert_with(|| segment.coordinate_bounds(system, &sample, self.tau_max));
                        segment.bounds(&self.dynamics.forcing, p, coords, self.tau_max)
                    });
                }
            }
        }
        scan.finish()
    }

    /// Advances to `t_end`, handling every event on the way (including one
    /// exactly at `t_end`).
    pub fn advance_to(&mut self, t_end: f64) -> Result<(), SimError> {
        if t_end < self.state.time {
            return Err(SimError::Backwards { now: self.state.time, requested: t_end });
        }
        let mut buffers = self.scratch.take().unwrap_or_else(|| ProbeBuffers::new(&self.dynamics));
        let result = self.advance_with(t_end, &mut buffers);
        self.scratch = Some(buffers);
        result
    }

    fn advance_with(&mut self, t_end: f64, buffers: &mut ProbeBuffers) -> Result<(), SimError> {
        let mut st = std::mem::replace(&mut buffers.state, ModalState::zeros(0));
        let result = self.scan_to(t_end, &mut st, buffers);
        buffers.state = st;
        result
    }

    /// Stops consistently at `l`, the last point the search reached.
    fn stop_at(&mut self, l: f64) {
        self.accumulate_balance(l);
        self.state.time = l;
        let mut current = std::mem::replace(&mut self.state.current, ModalState::zeros(0));
        self.state_at(l, &mut current);
        self.state.current = current;
    }

    fn scan_to(&mut self, t_end: f64, st: &mut ModalState, buffers: &mut ProbeBuffers) -> Result<(), SimError> {
        let mut count = 0u64;
        let mut probes = 0u64;
        let (start, balance_rate) = (self.state.time, self.balance_nodes_per_time());
        loop {
            let l = self.state.scan;
            if l > t_end {
                break;
            }
            probes += 1;
            let balance_nodes = balance_rate * (l.min(t_end) - start);
            if probes as f64 + balance_nodes > self.model.max_probes_per_step as f64 {
                self.stop_at(l);
                return Err(SimError::TooMuchWork { time: l, probes: probes - 1 });
            }
            self.stats.probes += 1;
            let at_zero = match self.probe(l, st, buffers) {
                Probe::Events(list) => list,
                Probe::Clear { step, limiting, departing } => {
                    // Clear down to the search's resolution: step on.
                    let next = l + step;
                    if next > l {
                        if l == t_end {
                            break;
                        }
                        // Functions leaving their boundary stop departing once clear of noise.
                        self.state.departing = departing;
                        self.state.scan = next;
                        continue;
                    }
                    // The zero is within one ulp of l.
                    match limiting {
                        Some(lim) => vec![lim],
                        None => break,
                    }
                }
            };
            count += 1;
            self.stats.events += 1;
            if count > self.model.max_events_per_step {
                self.stop_at(l);
                return Err(SimError::TooManyEvents { time: l, count });
            }
            self.handle_events(l, st.clone(), at_zero)?;
        }
        self.accumulate_balance(t_end);
        self.state.time = t_end;
        let mut current = std::mem::replace(&mut self.state.current, ModalState::zeros(0));
        self.state_at(t_end, &mut current);
        self.state.current = current;
        Ok(())
    }

    /// Whether the event search, restarted at the current time with the
    /// current departing flags, proves `[time, scan)` free of events within
    /// `max_probes` points: the check of a restored state's claim that its
    /// segment is event-free up to `scan` (a forged claim would skip a
    /// contact). The state itself is not changed, so a state that passes
    /// continues bit for bit.
    fn certifies_up_to_scan(&self, max_probes: u64) -> bool {
        let target = self.state.scan;
        let mut check = Simulation { record_events: false, scratch: None, ..self.clone() };
        check.state.scan = check.state.time;
        let mut buffers = ProbeBuffers::new(&check.dynamics);
        let mut st = ModalState::zeros(check.model.n_modes());
        for _ in 0..max_probes {
            let l = check.state.scan;
            if l >= target {
                return true;
            }
            match check.probe(l, &mut st, &mut buffers) {
                Probe::Events(_) => return false,
                Probe::Clear { step, departing, .. } => {
                    if !(l + step > l) {
                        return false;
                    }
                    check.state.departing = departing;
                    check.state.scan = l + step;
                }
            }
        }
        false
    }

    fn record(&mut self, time: f64, kind: EventKind) {
        if self.record_events {
            self.events.push(Event { time, kind });
        }
    }

    /// Applies the events found at time `t` (state `st`) and starts a new
    /// segment there if the state or the phase changed.
    fn handle_events(&mut self, t: f64, mut st: ModalState, at_zero: Vec<(usize, Jet)>) -> Result<(), SimError> {
        let mut impacts: Vec<(usize, f64)> = Vec::new();
        let mut sticks: Vec<usize> = Vec::new();
        let mut releases: Vec<usize> = Vec::new();
        let mut departing = self.state.departing;
        for (i, jet) in at_zero {
            if self.state.stuck & bit(i) != 0 {
                // The reaction already pulls (after a change of load), or is
                // about to: release.
                // A reaction resting at zero (no load) keeps the structure held.
                if jet.d[0] < -jet.noise[0] || tendency_from(&jet, 1) == Tendency::Closing {
                    releases.push(i);
                } else {
                    departing |= bit(i);
                }
            } else if jet.d[1] < -jet.noise[1] {
                impacts.push((i, -jet.d[1]));
            } else if jet.d[1] <= jet.noise[1] {
                match tendency_from(&jet, 2) {
                    // At rest on the stop with nothing pushing either way: held
                    // with zero reaction until a load decides.
                    Tendency::Closing | Tendency::Resting => sticks.push(i),
                    Tendency::Opening => {
                        departing |= bit(i);
                        self.record(t, EventKind::Graze { stop: i });
                    }
                }
            } else {
                departing |= bit(i);
            }
        }
        if impacts.is_empty() && sticks.is_empty() && releases.is_empty() {
            self.state.departing = departing;
            return Ok(());
        }
        // The balance up to the event, in the segment ending here.
        self.accumulate_balance(t);
        let energy_before = self.model.energy(&st);
        let mut stuck = self.state.stuck;
        for &i in &releases {
            stuck &= !bit(i);
            departing |= bit(i);
            self.state.stops[i].previous_impact = None;
            self.record(t, EventKind::Release { stop: i });
        }
        // The impact: impacting stops with their restitution, newly pressed
        // and still held stops with R = 0 (seed 000 section 2.2).
        let mut chatter_ends = Vec::new();
        let mut restitution = vec![0.0; self.model.stops.len()];
        for &(i, speed) in &impacts {
            let stop = &self.model.stops[i];
            let counters = &mut self.state.stops[i];
            let since = counters.previous_impact.map(|p| t - p);
            let resolution = 16.0 * f64::EPSILON * t.abs().max(f64::MIN_POSITIVE);
            let chatter = since.is_some_and(|dt| dt < stop.chatter_eps || dt <= resolution)
                || stop.restitution * speed <= 16.0 * f64::EPSILON * st.qd.amax() * stop.w.amax();
            restitution[i] = if chatter { 0.0 } else { stop.restitution };
            counters.impacts += 1;
            counters.last_impact = t;
            counters.previous_impact = Some(t);
            if chatter {
                chatter_ends.push(i);
            }
        }
        let involved: Vec<usize> = (0..self.model.stops.len())
            .filter(|&i| stuck & bit(i) != 0 || sticks.contains(&i) || impacts.iter().any(|&(k, _)| k == i))
            .collect();
        let before = st.qd.clone();
        if !impacts.is_empty() || !sticks.is_empty() {
            let rows: Vec<ImpactRow> = involved
                .iter()
                .map(|&i| ImpactRow { w: &self.model.stops[i].w, restitution: restitution[i], side: self.model.stops[i].side })
                .collect();
            apply_impact(&mut st.qd, &rows);
        }
        for &(i, speed) in &impacts {
            let stop = &self.model.stops[i];
            // Put the contact point exactly on the stop (seed 000 Fig. 3b).
            let miss = stop.target() - stop.w.dot(&st.q);
            st.q.axpy(miss / stop.w.dot(&stop.w), &stop.w, 1.0);
            let lost = energy_loss(&stop.w, &before, restitution[i]);
            self.record(
                t,
                EventKind::Impact { stop: i, speed, restitution: restitution[i], energy_lost: lost, chatter: chatter_ends.contains(&i) },
            );
            departing |= bit(i);
        }
        // After the last impact of a chatter sequence the contact velocity is
        // zero: the beam sticks if the loads press it on (the reaction of seed
        // 000 eq. 32 of the right sign), else it leaves. Zero-velocity
        // contacts found pressed stick.
        let mut jet_buf = ModalJet::new(self.model.n_modes());
        jet_buf.fill_free(&self.dynamics, t, &st);
        for &i in &chatter_ends {
            let jet = jet_buf.functional(&self.gap_functionals[i], t);
            if tendency_from(&jet, 2) != Tendency::Opening {
                stuck |= bit(i);
            }
        }
        for &i in &sticks {
            stuck |= bit(i);
        }
        for i in 0..self.model.stops.len() {
            if stuck & bit(i) != 0 {
                self.state.stops[i].previous_impact = None;
            }
        }
        let newly_stuck = stuck & !self.state.stuck;
        departing |= newly_stuck;
        if stuck != 0 {
            // Exactly on the held stops, moving along them (seed 000 eqs. 29-31:
            // project at entry so no drift accumulates).
            let system = self.coupled_system(stuck)?;
            system.project(&self.stuck_targets(stuck), &mut st);
        }
        self.state.stuck = stuck;
        let lost = energy_before - self.model.energy(&st);
        if let Some(b) = self.state.balance.as_mut() {
            b.impacts += lost;
        }
        self.state.anchor = st;
        self.state.anchor_time = t;
        self.state.scan = t;
        self.state.departing = departing;
        self.rebuild_segment()?;
        // Report the sticks with their initial reaction.
        for i in 0..self.model.stops.len() {
            if newly_stuck & bit(i) != 0 {
                let reaction = self.reaction_at(i, t, &self.state.anchor);
                self.record(t, EventKind::Stick { stop: i, reaction });
            }
        }
        Ok(())
    }
}

/// Work space of the event search.
#[derive(Clone, Debug)]
struct ProbeBuffers {
    state: ModalState,
    jet: ModalJet,
    bounds: ModalBounds,
    increment: Increment,
}

impl ProbeBuffers {
    fn new(dynamics: &FreeDynamics) -> Self {
        let n = dynamics.oscillators.len();
        ProbeBuffers { state: ModalState::zeros(n), jet: ModalJet::new(n), bounds: ModalBounds::new(dynamics), increment: Increment::new(n) }
    }
}

enum Probe {
    /// No zero at this point; `departing` keeps the bits of functions still
    /// within noise of their boundary.
    Clear { step: f64, limiting: Option<(usize, Jet)>, departing: u64 },
    Events(Vec<(usize, Jet)>),
}

/// The event functions' verdicts at one point, gathered.
struct Scan {
    /// Bits of the functions leaving their boundary (input).
    departing: u64,
    at_zero: Vec<(usize, Jet)>,
    step: f64,
    limiting: Option<(usize, Jet)>,
    keep: u64,
}

impl Default for Scan {
    fn default() -> Self {
        Scan { departing: 0, at_zero: Vec::new(), step: f64::INFINITY, limiting: None, keep: 0 }
    }
}

impl Scan {
    /// One function: at its zero (an event), or clear for a certified step;
    /// the derivative bounds are only computed when needed.
    fn consider(&mut self, i: usize, jet: Jet, bounds: impl FnOnce() -> DerivativeBounds) {
        let departing = self.departing & bit(i) != 0;
        if jet.d[0] <= jet.noise[0] {
            if !departing {
                self.at_zero.push((i, jet));
                return;
            }
            self.keep |= bit(i);
        }
        match certified_step(&jet, &bounds(), departing) {
            Certified::Clear(s) => {
                if s < self.step {
                    self.step = s;
                    self.limiting = Some((i, jet));
                }
            }
            Certified::AtZero => self.at_zero.push((i, jet)),
        }
    }

    fn finish(self) -> Probe {
        if self.at_zero.is_empty() {
            Probe::Clear { step: self.step, limiting: self.limiting, departing: self.keep }
        } else {
            Probe::Events(self.at_zero)
        }
    }
}
