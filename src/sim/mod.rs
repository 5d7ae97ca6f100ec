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
mod integrated;
pub mod nonlinear;

pub use codec::STATE_VERSION;

use crate::contact::restitution::{apply_impact, energy_loss, ImpactRow};
use crate::contact::{Contact, Geometry, Law, PhaseTerm, Switch, Watch};
use crate::scene::ContactMethod;
use crate::model::Model;
use crate::solve::events::{certified_step, converging_on_zero, tendency_from, Certified, Tendency};
use crate::solve::free::{Increment, ModalBounds, ModalJet};
use crate::solve::functional::NOISE;
use crate::solve::lti::{CoordinateBounds, CoupledSample, CoupledSegment, CoupledSystem, LtiError, PhaseLoads, ProjectedFunctional};
use crate::solve::{FreeDynamics, FreeSegment, Functional, Jet, ModalForcing, ModalState};

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
    /// A compliant stop starts pushing (`speed`: the approach speed).
    Contact { stop: usize, speed: f64 },
    /// A compliant stop's force reached zero; `penetration` is left over
    /// (non-zero only with a dashpot).
    Separation { stop: usize, penetration: f64 },
}

#[derive(Clone, Debug, PartialEq)]
pub struct Event {
    pub time: f64,
    pub kind: EventKind,
}

impl Event {
    /// The stop the event happened at.
    pub fn stop(&self) -> usize {
        match self.kind {
            EventKind::Impact { stop, .. }
            | EventKind::Stick { stop, .. }
            | EventKind::Release { stop }
            | EventKind::Graze { stop }
            | EventKind::Contact { stop, .. }
            | EventKind::Separation { stop, .. } => stop,
        }
    }

    /// One line for a log, naming the stop as the model does.
    pub fn describe(&self, model: &Model) -> String {
        let t = self.time;
        let name = model.stops[self.stop()].name.as_str();
        match &self.kind {
            EventKind::Impact { speed, restitution, energy_lost, chatter, .. } => format!(
                "t = {t:.17}: impact at stop '{name}', approach speed {speed:.6e}, R = {restitution}, energy lost {energy_lost:.6e}{}",
                if *chatter { " (chatter detected: final R = 0 impact)" } else { "" }
            ),
            EventKind::Stick { reaction, .. } => format!("t = {t:.17}: sticking starts at stop '{name}', reaction {reaction:.6e}"),
            EventKind::Release { .. } => format!("t = {t:.17}: release from stop '{name}' (reaction changed sign)"),
            EventKind::Graze { .. } => format!("t = {t:.17}: grazing contact at stop '{name}' (zero velocity, no impact)"),
            EventKind::Contact { speed, .. } => format!("t = {t:.17}: contact starts at stop '{name}', approach speed {speed:.6e}"),
            EventKind::Separation { penetration, .. } => {
                format!("t = {t:.17}: contact ends at stop '{name}' (force zero), penetration left {penetration:.6e}")
            }
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub enum SimError {
    /// The initial state lies beyond a rigid stop.
    /// `fields`: the scene fields that put it there (the stop's gap and
    /// the initial modal displacements that move the point).
    Penetration { stop: String, displacement: f64, limit: f64, side: f64, fields: Vec<String> },
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
    /// The integration of a nonlinear contact phase failed.
    Integration { time: f64, message: String },
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SimError::Penetration { stop, displacement, limit, side, fields } => write!(
                f,
                "the initial state penetrates stop '{stop}': displacement there is {displacement}, allowed {} {limit}; \
                 change the initial modal coordinates or the gap ({})",
                if *side > 0.0 { "<=" } else { ">=" },
                fields.join(", ")
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
            SimError::Integration { time, message } => write!(
                f,
                "the integration of a nonlinear contact phase failed at t = {time}: {message}; \
                 loosen solver.integration_tolerance or check the contact parameters"
            ),
        }
    }
}

impl std::error::Error for SimError {}

impl From<LtiError> for SimError {
    fn from(e: LtiError) -> Self {
        SimError::Contact(e)
    }
}

/// The contact state and counters of one stop.
#[derive(Clone, Debug, PartialEq)]
pub struct StopState {
    pub contact: Contact,
    /// Per watched function of the contact state: put on its boundary by
    /// the event handling at `scan` and leaving it.
    pub departing: [bool; 2],
    /// The departing flags when the anchor was set: those functions count
    /// as exactly 0 at the anchor (the free segment's values there).
    pub anchor_departing: [bool; 2],
    /// Impacts (rigid) or contact onsets (compliant) since the start.
    pub impacts: u64,
    /// Time of the latest impact or onset (the start time before the first).
    pub last_impact: f64,
    /// Time of the previous impact of the current chatter sequence, reset
    /// when the stop sticks or releases.
    pub previous_impact: Option<f64>,
    /// Impulse the stop delivered up to the anchor (pushing away from it).
    pub impulse: f64,
    /// The impulse total when the last advance began.
    pub impulse_mark: f64,
    /// Energy dissipated in the stop up to `SimState::accounted`.
    pub dissipated: f64,
    /// Approach speed at the latest contact onset (the hysteretic Hertz
    /// damping scales with it).
    pub onset_speed: f64,
    /// Stick onsets (rigid stops) since the start.
    pub sticks: u64,
    /// Time spent stuck in the holds that have ended.
    pub stuck_time: f64,
    /// Start of the current hold (meaningful while `Held`).
    pub held_since: f64,
}

/// Everything that evolves; with the model and inputs it determines the
/// future exactly (the segment is derived from it).
#[derive(Clone, Debug, PartialEq)]
pub struct SimState {
    pub time: f64,
    pub anchor_time: f64,
    pub anchor: ModalState,
    /// The event search has proven the segment event-free up to here.
    pub scan: f64,
    /// The last point the search evaluated or handled events at: where
    /// every departing flag's function was on its boundary.
    pub probed: f64,
    /// Contact state and counters of each stop.
    pub stops: Vec<StopState>,
    /// The stops' dissipation covers the run up to here.
    pub accounted: f64,
    /// The state at `time`.
    pub current: ModalState,
    /// Seed 003's energy accounting, when the model asks for it.
    pub balance: Option<EnergyBalance>,
    /// With mode transfer (seed 001's MTM, RMTM): the shape the current
    /// motion is an increment over, in both bases; `current` and `anchor`
    /// are then in the basis of the phase (spring modes while the transfer
    /// stop is pressed).
    pub frozen: Option<Frozen>,
}

/// A frozen displacement field `sum_j W_j c_j + sum_n Phi_n d_n`
/// (cantilever and tip-spring modes; zero for MTM, which projects instead).
#[derive(Clone, Debug, PartialEq)]
pub struct Frozen {
    pub c: DVector<f64>,
    pub d: DVector<f64>,
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

/// One watched event function: its stop, its slot among the stop's
/// watches, and what it is.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Channel {
    stop: usize,
    slot: usize,
    watch: Watch,
}

#[derive(Clone, Debug)]
enum Segment {
    Free {
        segment: FreeSegment,
        /// Each channel's function, and its value at the anchor: exactly 0
        /// for a function the event handling just put on its boundary, so
        /// that (for displacement-only functions) the value along the
        /// segment is that plus an increment accurate relative to itself.
        functions: Vec<(Functional, f64)>,
    },
    Coupled { phase: Arc<CoupledPhase>, segment: CoupledSegment },
    /// A nonlinear stop engaged: integrated.
    Integrated(Box<integrated::IntegratedSegment>),
}

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
}

/// What every segment of one contact phase shares: built at the phase's
/// first entry, shared by the later ones (each stick of a run).
#[derive(Debug)]
struct CoupledPhase {
    system: Arc<CoupledSystem>,
    /// The loads of the phase (compliant stops' preload included).
    forcing: ModalForcing,
    loads: Arc<PhaseLoads>,
    /// Each channel's function in the phase's coordinates.
    events: Vec<ProjectedFunctional>,
    /// The reaction (seed eq. 33) of each held stop.
    reactions: Vec<Option<Functional>>,
}

/// A contact phase entered before under the current dynamics and model,
/// found by every stop's contact state and the watched channels (which
/// fix everything [`CoupledPhase`] holds while the dynamics stay).
#[derive(Clone, Debug)]
struct PhaseMemo {
    contacts: Vec<Contact>,
    channels: Vec<Channel>,
    phase: Arc<CoupledPhase>,
}

impl PhaseMemo {
    /// Whether the stops are in this phase's contact states.
    fn holds_for(&self, stops: &[StopState]) -> bool {
        self.contacts.iter().eq(stops.iter().map(|s| &s.contact))
    }
}

/// A contact phase's loads and event functions in its coordinates, for
/// the next entry into the same phase: found by the system (the same
/// decomposition), the loads and the origin, compared in full.
#[derive(Clone, Debug)]
struct PhaseEntry {
    system: Arc<CoupledSystem>,
    forcing: ModalForcing,
    origin: DVector<f64>,
    origin_force: DVector<f64>,
    loads: Arc<PhaseLoads>,
    projected: Vec<(Functional, ProjectedFunctional)>,
}

/// At most this many phases are kept (a chatter sequence alternates
/// between two or three; every active set of several stops is one).
const PHASE_CACHE_CAPACITY: usize = 8;

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
            if s.law.is_rigid() && value < -(crate::solve::functional::NOISE * scale).max(model.event_tolerance) {
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
            let contact = s.law.initial_contact(&s.geometry, &initial).unwrap_or(Contact::Open);
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
        };
        sim.rebuild_segment()?;
        // An integrated phase rebuilds its steps from the anchor.
        let reach = sim.state.scan.max(sim.state.time);
        sim.replay_to(reach)?;
        if let Segment::Integrated(seg) = &mut sim.segment {
            seg.settle_at(sim.state.time);
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

    /// Kinetic plus strain energy of the structure (with mode transfer, of
    /// its projection on the structure's modes).
    pub fn energy(&self) -> f64 {
        match &self.state.frozen {
            None => self.model.energy(&self.state.current),
            Some(_) => self.model.energy(&self.field()),
        }
    }

    /// The motion in the structure's own modal coordinates: the state
    /// itself, or with mode transfer the frozen shape plus the increment,
    /// projected (`c + T^T (d + p)` in contact, `c + T^T d + q` apart).
    pub fn field(&self) -> ModalState {
        let (Some(f), Some(tr)) = (&self.state.frozen, &self.model.transfer) else { return self.state.current.clone() };
        let cur = &self.state.current;
        let t = &tr.overlap;
        if self.in_transfer() {
            ModalState { q: &f.c + t.tr_mul(&(&f.d + &cur.q)), qd: t.tr_mul(&cur.qd) }
        } else {
            ModalState { q: &f.c + t.tr_mul(&f.d) + &cur.q, qd: cur.qd.clone() }
        }
    }

    /// Whether the state is in the tip-spring basis (mode transfer, pressed).
    fn in_transfer(&self) -> bool {
        self.model.transfer.as_ref().is_some_and(|tr| self.state.stops[tr.stop].contact == Contact::Pressed)
    }

    /// Displacement and velocity of the structure at a point given by its
    /// shape in the structure's modes (`w`) and, with mode transfer, in
    /// the tip-spring modes (`phi`).
    pub fn point_motion(&self, w: &DVector<f64>, phi: Option<&DVector<f64>>) -> (f64, f64) {
        let cur = &self.state.current;
        match (&self.state.frozen, phi) {
            (Some(f), Some(phi)) => {
                let frozen = w.dot(&f.c) + phi.dot(&f.d);
                let active = if self.in_transfer() { phi } else { w };
                (frozen + active.dot(&cur.q), active.dot(&cur.qd))
            }
            _ => (w.dot(&cur.q), w.dot(&cur.qd)),
        }
    }

    /// Displacement and velocity at stop `i`.
    pub fn stop_motion(&self, i: usize) -> (f64, f64) {
        let phi = self.model.transfer.as_ref().filter(|tr| tr.stop == i).map(|tr| &tr.stop_w);
        self.point_motion(&self.model.stops[i].geometry.w, phi)
    }

    /// Displacement, velocity and (if measured) bending moment at sensor `i`.
    pub fn sensor_motion(&self, i: usize) -> (f64, f64, f64) {
        let s = &self.model.sensors[i];
        let phi = self.model.transfer.as_ref().map(|tr| &tr.sensors[i]);
        let (w, v) = self.point_motion(&s.w, phi.map(|p| &p.0));
        let m = match &s.moment {
            Some(m) => self.point_motion(m, phi.and_then(|p| p.1.as_ref())).0,
            None => 0.0,
        };
        (w, v, m)
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
        let mut into_stops = 0.0;
        let pressed: Vec<usize> = (0..self.model.stops.len()).filter(|&i| self.state.stops[i].contact == Contact::Pressed).collect();
        // qd_j f_j and qd_j^2 oscillate at up to twice the fastest frequency.
        crate::solve::quadrature::for_each_node_band_limited(from, t, 2.0 * fastest, |tau, w| {
            self.state_at(tau, &mut st);
            self.dynamics.forcing.derivative(tau, 0, &mut f);
            for j in 0..n {
                let o = &self.model.oscillators[j];
                forcing[j] += w * st.qd[j] * f[j];
                damping[j] += w * 2.0 * o.a * st.qd[j] * st.qd[j];
            }
            // The work the structure does on compliant stops, F p'.
            for &i in &pressed {
                let (s, g) = (&self.model.stops[i], &self.geometries[i]);
                into_stops += w * s.law.force(Contact::Pressed, g, &st, 0.0) * g.penetration_rate(&st.qd);
            }
        });
        let b = self.state.balance.as_mut().expect("checked above");
        for j in 0..n {
            b.forcing[j] += forcing[j];
            b.damping[j] += damping[j];
        }
        b.impacts += into_stops;
        b.time = t;
    }

    /// Brings the balance and the compliant stops' dissipation up to `t`.
    fn account(&mut self, t: f64) {
        self.accumulate_balance(t);
        self.accumulate_dissipation(t);
    }

    /// Adds the energy the dashpots of pressed stops dissipate, `c int p'^2`,
    /// over the part of the current segment not yet counted, by quadrature
    /// fine enough for the phase's fastest rate (exact to rounding).
    fn accumulate_dissipation(&mut self, t: f64) {
        let from = self.state.accounted;
        if t <= from {
            return;
        }
        self.state.accounted = t;
        // Only a pressed dashpot dissipates, and only a coupled phase has one.
        let Segment::Coupled { phase, .. } = &self.segment else { return };
        let system = &phase.system;
        let dashpots: Vec<(usize, f64)> = (0..self.model.stops.len())
            .filter(|&i| self.state.stops[i].contact == Contact::Pressed)
            .filter_map(|i| self.model.stops[i].law.dashpot().map(|c| (i, c)))
            .collect();
        if dashpots.is_empty() {
            return;
        }
        let mut fastest = system.fastest();
        for h in &self.dynamics.forcing.harmonics {
            fastest = fastest.max(h.omega);
        }
        let mut st = ModalState::zeros(self.model.n_modes());
        let mut sums = vec![0.0; dashpots.len()];
        crate::solve::quadrature::for_each_node_band_limited(from, t, 2.0 * fastest, |tau, w| {
            self.state_at(tau, &mut st);
            for (k, &(i, c)) in dashpots.iter().enumerate() {
                let v = self.geometries[i].penetration_rate(&st.qd);
                sums[k] += w * c * v * v;
            }
        });
        for (k, &(i, _)) in dashpots.iter().enumerate() {
            self.state.stops[i].dissipated += sums[k];
        }
    }

    /// The impulse stop `i` delivered over the current segment, from the
    /// anchor to `t` (state `at_t`), exact: the force is linear in the
    /// state and the load, so its integral is linear in `int q`
    /// ([`CoupledSegment::integral_q`]), `q(t) - q(t0)` and `int f`.
    fn segment_impulse(&self, i: usize, t: f64, at_t: &ModalState) -> f64 {
        let stop = &self.model.stops[i];
        let g = &self.geometries[i];
        let span = t - self.state.anchor_time;
        if span <= 0.0 {
            return 0.0;
        }
        // The force is a functional `offset + a . q + b . qd`: its integral
        // is `offset span + a . int q + b . [q]`.
        let pressed_spring = |iq: &DVector<f64>| match stop.law.force_functional(g) {
            Some(h) => h.offset * span + h.q.dot(iq) + h.qd.as_ref().map_or(0.0, |b| b.dot(&(&at_t.q - &self.state.anchor.q))),
            None => 0.0,
        };
        match &self.segment {
            // Free oscillators (mode transfer in contact): `omega^2 int q =
            // int f - [q'] - 2 a [q]` mode by mode, exact.
            Segment::Free { .. } if self.state.stops[i].contact == Contact::Pressed => {
                let f = self.dynamics.forcing.integral(self.state.anchor_time, t);
                let iq = DVector::from_fn(f.len(), |j, _| {
                    let o = &self.dynamics.oscillators[j];
                    (f[j] - (at_t.qd[j] - self.state.anchor.qd[j]) - 2.0 * o.a * (at_t.q[j] - self.state.anchor.q[j])) / (o.omega * o.omega)
                });
                pressed_spring(&iq)
            }
            Segment::Free { .. } => 0.0,
            Segment::Integrated(seg) => seg.phase.contacts.iter().position(|c| c.stop == i).map_or(0.0, |k| seg.totals_at(k, t).0),
            Segment::Coupled { phase, segment } => match self.state.stops[i].contact {
                Contact::Held => {
                    let r = phase.reactions[i].as_ref().expect("a held stop has a reaction");
                    let iq = segment.integral_q(&phase.system, t);
                    let mut lambda = r.q.dot(&iq) + r.offset * span;
                    if let Some(b) = &r.qd {
                        lambda += b.dot(&(&at_t.q - &self.state.anchor.q));
                    }
                    if let Some(c) = &r.f {
                        lambda += c.dot(&phase.forcing.integral(self.state.anchor_time, t));
                    }
                    -g.side * lambda
                }
                Contact::Pressed => pressed_spring(&segment.integral_q(&phase.system, t)),
                _ => 0.0,
            },
        }
    }

    /// The impulse stop `i` has delivered since the start (0 when the
    /// model does not keep impulses).
    pub fn impulse_total(&self, i: usize) -> f64 {
        if !self.model.impulses {
            return 0.0;
        }
        self.state.stops[i].impulse + self.segment_impulse(i, self.state.time, &self.state.current)
    }

    /// The impulse stop `i` delivered during the last advance that moved
    /// time (>= 0, pushing the structure away from the stop; a difference
    /// of running totals, so clamped at 0 against their rounding).
    pub fn last_impulse(&self, i: usize) -> f64 {
        (self.impulse_total(i) - self.state.stops[i].impulse_mark).max(0.0)
    }

    /// The force stop `i` pushes with now (>= 0): a held stop's reaction, a
    /// pressed compliant stop's `k p + c p'`.
    pub fn stop_force(&self, i: usize) -> f64 {
        let (s, g) = (&self.model.stops[i], &self.geometries[i]);
        match self.state.stops[i].contact {
            Contact::Held => -g.side * self.reaction(i),
            c => s.law.force(c, g, &self.state.current, self.state.stops[i].onset_speed),
        }
    }

    /// Elastic energy stored in stop `i` now.
    pub fn stop_stored_energy(&self, i: usize) -> f64 {
        self.model.stops[i].law.stored_energy(self.state.stops[i].contact, &self.geometries[i], &self.state.current)
    }

    /// Energy dissipated in stop `i` since the start (its dashpot, and the
    /// spring energy left when a dashpot ends contact while penetrated).
    pub fn stop_dissipated_energy(&self, i: usize) -> f64 {
        let mut d = self.state.stops[i].dissipated + self.segment_dissipation(i);
        if self.state.accounted < self.state.time {
            let mut probe = Simulation { record_events: false, scratch: None, ..self.clone() };
            probe.accumulate_dissipation(self.state.time);
            d = probe.state.stops[i].dissipated;
        }
        d
    }

    /// Closes the current segment at `t` (state `at_t`): its impulses join
    /// the stops' totals before a new segment starts.
    fn close_segment(&mut self, t: f64, at_t: &ModalState) {
        if self.model.impulses {
            for i in 0..self.model.stops.len() {
                let p = self.segment_impulse(i, t, at_t);
                self.state.stops[i].impulse += p;
            }
        }
        if let Segment::Integrated(seg) = &self.segment {
            for (k, c) in seg.phase.contacts.iter().enumerate() {
                self.state.stops[c.stop].dissipated += seg.totals_at(k, t).1.max(0.0);
            }
        }
    }

    /// Energy an integrated phase's contacts dissipated since its anchor.
    fn segment_dissipation(&self, i: usize) -> f64 {
        match &self.segment {
            Segment::Integrated(seg) => seg.phase.contacts.iter().position(|c| c.stop == i).map_or(0.0, |k| seg.totals_at(k, self.state.time).1.max(0.0)),
            _ => 0.0,
        }
    }

    /// The fastest frequency in the motion: the highest mode or load.
    fn fastest_frequency(&self) -> f64 {
        let mut fastest = self.model.oscillators.iter().map(|o| o.omega).fold(0.0, f64::max);
        for h in &self.dynamics.forcing.harmonics {
            fastest = fastest.max(h.omega);
        }
        fastest
    }

    /// Quadrature nodes per unit time of the energy accounting in the
    /// current phase (the energy balance, when kept; the dissipation of
    /// pressed dashpots): each costs about what a point of the event
    /// search costs, and counts against the same cap.
    fn accounting_nodes_per_time(&self) -> f64 {
        // 16-point panels of pi / 2 at twice the fastest frequency.
        let per_frequency = 16.0 * 2.0 / (0.5 * std::f64::consts::PI);
        let mut rate = match self.state.balance {
            Some(_) => per_frequency * self.fastest_frequency(),
            None => 0.0,
        };
        if let Segment::Coupled { phase, .. } = &self.segment {
            let dashpot = (0..self.model.stops.len()).any(|i| self.state.stops[i].contact == Contact::Pressed && self.model.stops[i].law.dashpot().is_some());
            if dashpot {
                let fastest = self.dynamics.forcing.harmonics.iter().fold(phase.system.fastest(), |m, h| m.max(h.omega));
                rate += per_frequency * fastest;
            }
        }
        rate
    }

    /// The reaction of a stop at the current time (0 unless stuck to it).
    pub fn reaction(&self, stop: usize) -> f64 {
        self.reaction_at(stop, self.state.time, &self.state.current)
    }

    fn reaction_at(&self, stop: usize, t: f64, state: &ModalState) -> f64 {
        match &self.segment {
            Segment::Coupled { phase, .. } => match &phase.reactions[stop] {
                Some(r) => {
                    let mut f = DVector::zeros(self.model.n_modes());
                    phase.forcing.derivative(t, 0, &mut f);
                    r.value(state, &f)
                }
                None => 0.0,
            },
            Segment::Free { .. } | Segment::Integrated(_) => 0.0,
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
        self.advance_to(self.state.time)
    }

    /// Keeps the departing flags of a new anchor (part of the state: a
    /// restore rebuilds the segment from them, not from the flags the
    /// search has cleared since).
    fn mark_anchor_departing(&mut self) {
        for s in &mut self.state.stops {
            s.anchor_departing = s.departing;
        }
    }

    /// Derives the dynamics and the stops' geometry from the model, the
    /// inputs and the state (after a change of basis or of the model).
    fn refresh_basis(&mut self) {
        self.dynamics = phase_dynamics(&self.model, &self.inputs, &self.state);
        self.phase_memo.clear();
        self.geometries = active_geometries(&self.model, &self.state);
        self.gap_functionals = self.geometries.iter().map(|g| g.gap_functional()).collect();
        self.scratch = None;
        // The segment's event functions were made from the old geometry.
        if let Segment::Free { functions, .. } = &mut self.segment {
            functions.clear();
        }
    }

    /// The contact states that shape the phase (the key of its system). A
    /// pressed mode-transfer stop is part of the basis, not of the phase.
    fn phase_key(&self) -> Vec<Contact> {
        (0..self.model.stops.len()).map(|i| self.phase_contact(i)).collect()
    }

    /// Stop `i`'s entry in the phase key: its contact state where that
    /// shapes the phase, else open.
    fn phase_contact(&self, i: usize) -> Contact {
        let contact = self.state.stops[i].contact;
        let transfer = self.model.transfer.as_ref().is_some_and(|tr| tr.stop == i);
        if transfer || self.model.stops[i].law.term(contact) == PhaseTerm::None {
            Contact::Open
        } else {
            contact
        }
    }

    /// The coupled system of a phase: `K = diag(omega^2) + sum k w w^T`,
    /// `D = diag(2 zeta omega) + sum c w w^T` over pressed compliant stops,
    /// constrained by the held rigid ones.
    fn coupled_system(&mut self, key: &[Contact]) -> Result<Arc<CoupledSystem>, SimError> {
        if let Some(s) = self.coupled_cache.get(key) {
            return Ok(s.clone());
        }
        let n = self.model.n_modes();
        let mut k = nalgebra::DMatrix::from_diagonal(&DVector::from_iterator(n, self.model.oscillators.iter().map(|o| o.omega * o.omega)));
        let mut d = nalgebra::DMatrix::from_diagonal(&DVector::from_iterator(n, self.model.oscillators.iter().map(|o| 2.0 * o.a)));
        let mut cols: Vec<DVector<f64>> = Vec::new();
        for (stop, &contact) in self.model.stops.iter().zip(key) {
            let w = &stop.geometry.w;
            match stop.law.term(contact) {
                PhaseTerm::None => {}
                PhaseTerm::Constraint => cols.push(w.clone()),
                PhaseTerm::SpringDashpot { k: ks, c } => {
                    k.ger(ks, w, w, 1.0);
                    d.ger(c, w, w, 1.0);
                }
                PhaseTerm::Nonlinear => unreachable!("nonlinear phases are integrated, not coupled"),
            }
        }
        let w = if cols.is_empty() { nalgebra::DMatrix::zeros(n, 0) } else { nalgebra::DMatrix::from_columns(&cols) };
        let sys = self.model.phase_systems.get_or_build(k, d, w)?;
        self.coupled_cache.insert(key.to_vec(), sys.clone());
        Ok(sys)
    }

    /// The held stops' positions `w . q = target`, in column order.
    fn held_targets(&self) -> DVector<f64> {
        let targets: Vec<f64> = self
            .model
            .stops
            .iter()
            .zip(&self.state.stops)
            .filter(|(m, s)| m.law.term(s.contact) == PhaseTerm::Constraint)
            .map(|(m, _)| m.geometry.target())
            .collect();
        DVector::from_vec(targets)
    }

    /// The loads of the current phase, the origin its motion is measured
    /// from and the elastic force at that origin: the origin lies on every
    /// held stop and on the surface of every pressed compliant stop
    /// (minimum norm), so the springs' preload `k target w` and their force
    /// at the origin `k w (w . origin)` cancel analytically, leaving
    /// `k w (w . origin - target)`, formed from the tiny residual; the
    /// springs then act on the small deviation only and keep their accuracy
    /// at any stiffness. Should the surfaces not be independent, the origin
    /// only satisfies the held stops and the preload joins the loads.
    /// The last value is the preload left out of the loads.
    fn phase_loads(&self, system: &CoupledSystem) -> (ModalForcing, DVector<f64>, DVector<f64>, DVector<f64>) {
        let n = self.model.n_modes();
        let held = self.held_targets();
        let base_k = DVector::from_iterator(n, self.model.oscillators.iter().map(|o| o.omega * o.omega));
        let mut cols: Vec<DVector<f64>> = Vec::new();
        let mut targets: Vec<f64> = held.iter().copied().collect();
        let mut springs: Vec<(f64, usize)> = Vec::new();
        for (i, (m, s)) in self.model.stops.iter().zip(&self.state.stops).enumerate() {
            if m.law.term(s.contact) == PhaseTerm::Constraint {
                cols.push(m.geometry.w.clone());
            }
            if let PhaseTerm::SpringDashpot { k, .. } = m.law.term(s.contact) {
                springs.push((k, i));
            }
        }
        for &(_, i) in &springs {
            cols.push(self.model.stops[i].geometry.w.clone());
            targets.push(self.model.stops[i].geometry.target());
        }
        let mut preload = DVector::zeros(n);
        for &(k, i) in &springs {
            let g = &self.model.stops[i].geometry;
            preload.axpy(k * g.target(), &g.w, 1.0);
        }
        let forcing = self.dynamics.forcing.clone();
        if !springs.is_empty() {
            let a = nalgebra::DMatrix::from_columns(&cols);
            let gram = a.transpose() * &a;
            let (scale, lower) = (gram.diagonal().amax(), gram.diagonal().min());
            let solved = (lower > 1e-12 * scale).then(|| gram.cholesky().map(|c| &a * c.solve(&DVector::from_vec(targets)))).flatten();
            if let Some(origin) = solved.filter(|o| o.iter().all(|v| v.is_finite())) {
                let mut force = origin.component_mul(&base_k);
                for &(k, i) in &springs {
                    let g = &self.model.stops[i].geometry;
                    force.axpy(k * (g.w.dot(&origin) - g.target()), &g.w, 1.0);
                }
                return (forcing, origin, force, preload);
            }
        }
        let origin = system.q_c(&held);
        let mut force = origin.component_mul(&base_k);
        for &(k, i) in &springs {
            let g = &self.model.stops[i].geometry;
            force.axpy(k * g.w.dot(&origin), &g.w, 1.0);
        }
        let mut with_preload = forcing;
        with_preload.constant += &preload;
        (with_preload, origin, force, DVector::zeros(n))
    }

    /// The event function of one watch of stop `i` (non-negative while the
    /// contact state holds); `None` for a held stop's reaction, which only
    /// the coupled system knows.
    fn watched_functional(&self, i: usize, watch: Watch) -> Option<Functional> {
        let stop = &self.model.stops[i];
        let force = || stop.law.force_functional(&self.geometries[i]).expect("a force is watched only for laws that have one");
        Some(match watch {
            Watch::Gap => self.gap_functionals[i].clone(),
            Watch::Penetration => self.gap_functionals[i].clone().scaled(-1.0),
            Watch::Force => force(),
            Watch::NegatedForce => force().scaled(-1.0),
            Watch::Reaction => return None,
        })
    }

    /// Derives the segment from the anchor and the phase.
    fn rebuild_segment(&mut self) -> Result<(), SimError> {
        let channels_changed = self.refresh_channels();
        if let Some(damping) = self.model.transfer.as_ref().and_then(|tr| tr.damping.as_ref()).filter(|_| self.in_transfer()) {
            // Mode transfer in contact with the structure's damping projected
            // on the contact modes: non-proportional, so a coupled phase.
            let system = match &self.transfer_system {
                Some(s) => s.clone(),
                None => {
                    let tr = self.model.transfer.as_ref().expect("in transfer");
                    let k = nalgebra::DMatrix::from_diagonal(&DVector::from_iterator(tr.oscillators.len(), tr.oscillators.iter().map(|o| o.omega * o.omega)));
                    let n = k.nrows();
                    let s = Arc::new(CoupledSystem::new(k, damping.clone(), nalgebra::DMatrix::zeros(n, 0))?);
                    self.transfer_system = Some(s.clone());
                    s
                }
            };
            let n = self.model.n_modes();
            let forcing = self.dynamics.forcing.clone();
            let segment = CoupledSegment::new(&system, &forcing, &DVector::zeros(n), &DVector::zeros(n), self.state.anchor_time, &self.state.anchor);
            let events = self
                .channels
                .iter()
                .map(|ch| {
                    let h = self.watched_functional(ch.stop, ch.watch).expect("no held stop with mode transfer");
                    segment.project_functional(&system, &forcing, &h)
                })
                .collect();
            let reactions = vec![None; self.model.stops.len()];
            let loads = segment.loads().clone();
            let phase = Arc::new(CoupledPhase { system, forcing, loads, events, reactions });
            self.enter(Segment::Coupled { phase, segment });
            return Ok(());
        }
        let nonlinear = self.model.stops.iter().zip(&self.state.stops).any(|(m, s)| m.law.term(s.contact) == PhaseTerm::Nonlinear);
        if nonlinear {
            let segment = Segment::Integrated(Box::new(self.integrated_segment()?));
            self.enter(segment);
            return Ok(());
        }
        if self.phase_is_free() {
            self.rebuild_free_segment(channels_changed);
            return Ok(());
        }
        let memo = self.phase_memo.iter().position(|m| m.channels == self.channels && m.holds_for(&self.state.stops));
        if let Some(i) = memo {
            let memo = self.phase_memo.remove(i);
            let segment = self.start_coupled(&memo.phase.system, memo.phase.loads.clone());
            self.enter(Segment::Coupled { phase: memo.phase.clone(), segment });
            self.phase_memo.insert(0, memo);
            return Ok(());
        }
        let key = self.phase_key();
        let system = self.coupled_system(&key)?;
        let (forcing, origin, origin_force, preload) = self.phase_loads(&system);
        let entry = self.phase_entry(&system, forcing, origin, origin_force);
        let loads = entry.loads.clone();
        let segment = self.start_coupled(&system, loads.clone());
        let mut reactions_by_column = system.reaction_functionals().into_iter();
        let reactions: Vec<Option<Functional>> = key
            .iter()
            .map(|c| {
                (*c == Contact::Held).then(|| {
                    let mut r = reactions_by_column.next().expect("one reaction per held stop");
                    // The springs' preload, kept out of the loads, still loads the constraint.
                    r.offset += r.f.as_ref().map_or(0.0, |f| f.dot(&preload));
                    r
                })
            })
            .collect();
        let functionals: Vec<Functional> = self
            .channels
            .iter()
            .map(|ch| match self.watched_functional(ch.stop, ch.watch) {
                Some(h) => h,
                // Admissible while the stop pushes the beam away: -side lambda >= 0.
                None => reactions[ch.stop].clone().expect("held").scaled(-self.model.stops[ch.stop].geometry.side),
            })
            .collect();
        let entry = &mut self.phase_cache[0];
        let mut events = Vec::with_capacity(functionals.len());
        for h in functionals {
            let projected = match entry.projected.iter().find(|(g, _)| *g == h) {
                Some((_, p)) => p.clone(),
                None => {
                    let p = entry.loads.project_functional(&system, &entry.forcing, &h);
                    entry.projected.push((h, p.clone()));
                    p
                }
            };
            events.push(projected);
        }
        let forcing = entry.forcing.clone();
        let phase = Arc::new(CoupledPhase { system, forcing, loads, events, reactions });
        self.phase_memo.truncate(PHASE_CACHE_CAPACITY - 1);
        let contacts = self.state.stops.iter().map(|s| s.contact).collect();
        self.phase_memo.insert(0, PhaseMemo { contacts, channels: self.channels.clone(), phase: phase.clone() });
        self.enter(Segment::Coupled { phase, segment });
        Ok(())
    }

    /// Makes `segment` the current one, keeping the one it displaces as
    /// the spare.
    fn enter(&mut self, segment: Segment) {
        let displaced = std::mem::replace(&mut self.segment, segment);
        self.spare = Some(displaced);
    }

    /// A contact phase's motion from the anchor, in the spare's storage
    /// when the spare is one.
    fn start_coupled(&mut self, system: &CoupledSystem, loads: Arc<PhaseLoads>) -> CoupledSegment {
        match self.spare.take() {
            Some(Segment::Coupled { mut segment, .. }) => {
                segment.restart(system, loads, self.state.anchor_time, &self.state.anchor);
                segment
            }
            other => {
                self.spare = other;
                CoupledSegment::start(system, loads, self.state.anchor_time, &self.state.anchor)
            }
        }
    }

    /// Whether free-flight event functions are the current channels' (a
    /// spare's, kept from before a contact phase): gap watches only,
    /// compared by value.
    fn functions_fit(&self, functions: &[(Functional, f64)]) -> bool {
        functions.len() == self.channels.len() && self.channels.iter().zip(functions).all(|(ch, (h, _))| ch.watch == Watch::Gap && *h == self.gap_functionals[ch.stop])
    }

    /// The cached entry of a contact phase, moved to the front (most
    /// recent first), or a new one with the loads projected now.
    fn phase_entry(&mut self, system: &Arc<CoupledSystem>, forcing: ModalForcing, origin: DVector<f64>, origin_force: DVector<f64>) -> &PhaseEntry {
        let found = self.phase_cache.iter().position(|e| {
            Arc::ptr_eq(&e.system, system) && e.forcing == forcing && e.origin == origin && e.origin_force == origin_force
        });
        let entry = match found {
            Some(i) => self.phase_cache.remove(i),
            None => {
                let loads = Arc::new(PhaseLoads::new(system, &forcing, &origin, &origin_force));
                PhaseEntry { system: system.clone(), forcing, origin, origin_force, loads, projected: Vec::new() }
            }
        };
        self.phase_cache.truncate(PHASE_CACHE_CAPACITY - 1);
        self.phase_cache.insert(0, entry);
        &self.phase_cache[0]
    }

    /// Sets the watched event functions of the current contact states;
    /// whether they changed.
    fn refresh_channels(&mut self) -> bool {
        let wanted = self
            .model
            .stops
            .iter()
            .zip(&self.state.stops)
            .enumerate()
            .flat_map(|(stop, (m, s))| m.law.watches(s.contact).iter().enumerate().map(move |(slot, &watch)| Channel { stop, slot, watch }));
        if wanted.clone().eq(self.channels.iter().copied()) {
            return false;
        }
        self.channels.clear();
        self.channels.extend(wanted);
        true
    }

    /// Whether every stop leaves the current phase's dynamics alone (the
    /// phase key is all open, formed without allocating): the modes fly free.
    fn phase_is_free(&self) -> bool {
        (0..self.model.stops.len()).all(|i| self.phase_contact(i) == Contact::Open)
    }

    /// A free segment from the anchor. A free segment before it is
    /// restarted in place, keeping its event functions when the channels
    /// are the same (an impact on a rigid stop): no allocation per impact.
    fn rebuild_free_segment(&mut self, mut channels_changed: bool) {
        // After a contact phase, the free segment it displaced.
        if !matches!(self.segment, Segment::Free { .. }) {
            if let Some(Segment::Free { functions, .. }) = &self.spare {
                if self.functions_fit(functions) {
                    let spare = self.spare.take().expect("a spare");
                    self.enter(spare);
                    channels_changed = false;
                }
            }
        }
        let anchor = &self.state.anchor;
        let value_at_anchor = |ch: &Channel, h: &Functional| if self.state.stops[ch.stop].anchor_departing[ch.slot] { 0.0 } else { h.value_without_load(anchor) };
        if let Segment::Free { segment, functions } = &mut self.segment {
            if !channels_changed && functions.len() == self.channels.len() {
                segment.reset(&self.dynamics, self.state.anchor_time, anchor);
                for (ch, (h, at_anchor)) in self.channels.iter().zip(functions.iter_mut()) {
                    *at_anchor = value_at_anchor(ch, h);
                }
                return;
            }
        }
        let functions = self
            .channels
            .iter()
            .map(|ch| {
                let h = self.watched_functional(ch.stop, ch.watch).expect("free phases watch no reaction");
                let at_anchor = value_at_anchor(ch, &h);
                (h, at_anchor)
            })
            .collect();
        let segment = Segment::Free { segment: FreeSegment::new(&self.dynamics, self.state.anchor_time, anchor), functions };
        self.enter(segment);
    }

    fn state_at(&self, t: f64, out: &mut ModalState) {
        match &self.segment {
            Segment::Free { segment, .. } => segment.state_at(&self.dynamics, t, out),
            Segment::Coupled { phase, segment } => segment.state_at(&phase.system, t, out),
            Segment::Integrated(seg) => seg.state_at(t, out),
        }
    }

    /// The channels' departing flags, into `out`.
    fn departing_flags_into(&self, out: &mut Vec<bool>) {
        // Written in place: every probe does this.
        out.resize(self.channels.len(), false);
        for (flag, ch) in out.iter_mut().zip(&self.channels) {
            *flag = self.state.stops[ch.stop].departing[ch.slot];
        }
    }

    /// Stores the search's departing flags back into the stops.
    fn set_departing(&mut self, flags: &[bool]) {
        for (ch, &f) in self.channels.iter().zip(flags) {
            self.state.stops[ch.stop].departing[ch.slot] = f;
        }
    }

    /// Jets of every watched event function at time `t` (state `st`), and
    /// the certified step or the list of functions at zero.
    fn probe(&self, t: f64, st: &mut ModalState, buffers: &mut ProbeBuffers) -> Probe {
        let tol = self.model.event_tolerance;
        let ProbeBuffers { jet: jet_buf, bounds: bound_buf, increment, coupled, coords, departing, keep, at_zero, limiting, .. } = buffers;
        self.departing_flags_into(departing);
        let mut scan = Scan::new(departing, keep, at_zero, limiting);
        match &self.segment {
            Segment::Free { segment: seg, functions } => {
                seg.state_and_increment_at(&self.dynamics, t, st, increment);
                if self.channels.is_empty() {
                    return scan.finish();
                }
                // The modal jet arrays are only filled for functions of the
                // velocity or the load, and for the mode split.
                let mut modal_ready = false;
                let mut bounds_ready = false;
                for (c, (h, at_anchor)) in functions.iter().enumerate() {
                    let mut jet = if h.qd.is_none() && h.f.is_none() {
                        ModalJet::displacement_jet(&self.dynamics, &increment.rotations, st, h, t)
                    } else {
                        if !modal_ready {
                            jet_buf.fill_free_rotated(&self.dynamics, &increment.rotations, st);
                            modal_ready = true;
                        }
                        jet_buf.functional(h, t)
                    };
                    if h.qd.is_none() {
                        // The value itself from the anchor's plus the increment.
                        let (dh, noise) = increment.functional(&h.q);
                        jet.d[0] = at_anchor + dh;
                        jet.noise[0] = (noise + NOISE * at_anchor.abs()).max(tol);
                    } else {
                        jet.noise[0] = jet.noise[0].max(tol);
                    }
                    let tau = self.tau_max;
                    let displacement = h.qd.is_none() && h.f.is_none();
                    scan.consider(c, jet, |departing| {
                        let bounds = if displacement {
                            seg.displacement_bounds(&self.dynamics, st, increment, tau, h)
                        } else {
                            if !bounds_ready {
                                seg.fill_bounds(&self.dynamics, st, increment, tau, bound_buf);
                                bounds_ready = true;
                            }
                            bound_buf.functional(h, tau)
                        };
                        let plain = certified_step(&jet, &bounds, departing);
                        match plain {
                            Certified::Clear(s) if !departing && !converging_on_zero(&jet, s) => {
                                // Split into transients and steady responses
                                // first: it costs O(N) and, where it certifies
                                // more, the mode split's arrays are not formed
                                // (S2: 4 % less time, the same probes).
                                let transient = seg.transient_split_step(&self.dynamics, st, increment, h, &jet, &bounds);
                                if transient > s {
                                    return Certified::Clear(transient);
                                }
                                if !modal_ready {
                                    jet_buf.fill_free_rotated(&self.dynamics, &increment.rotations, st);
                                    modal_ready = true;
                                }
                                if !bounds_ready {
                                    seg.fill_bounds(&self.dynamics, st, increment, tau, bound_buf);
                                    bounds_ready = true;
                                }
                                Certified::Clear(s.max(bound_buf.split_step(jet_buf, h, &jet, tau)))
                            }
                            other => other,
                        }
                    });
                }
            }
            Segment::Integrated(_) => unreachable!("integrated phases search on their own steps"),
            Segment::Coupled { phase, segment } => {
                let (system, events) = (&phase.system, &phase.events);
                // The modal state itself is only formed at events (`scan_to`).
                segment.sample_into(system, t, coupled);
                let mut coords_ready = false;
                for (c, p) in events.iter().enumerate() {
                    let mut jet = segment.jet(p, coupled);
                    if self.channels[c].watch != Watch::Reaction {
                        jet.noise[0] = jet.noise[0].max(tol);
                    }
                    scan.consider(c, jet, |departing| {
                        if !coords_ready {
                            segment.coordinate_bounds_into(system, coupled, self.tau_max, coords);
                            coords_ready = true;
                        }
                        let bounds = segment.bounds(p, coords, self.tau_max);
                        match certified_step(&jet, &bounds, departing) {
                            Certified::Clear(s) if !departing && !converging_on_zero(&jet, s) => {
                                Certified::Clear(s.max(segment.split_step(system, p, coupled, coords, &jet, &bounds)))
                            }
                            other => other,
                        }
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
        if t_end > self.state.time && self.model.impulses {
            for i in 0..self.model.stops.len() {
                self.state.stops[i].impulse_mark = self.impulse_total(i);
            }
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
        self.account(l);
        self.state.time = l;
        // The state a restore recomputes (a full-order step), not the
        // collocation polynomial's.
        if let Segment::Integrated(seg) = &mut self.segment {
            seg.settle_at(l);
        }
        let mut current = std::mem::replace(&mut self.state.current, ModalState::zeros(0));
        self.state_at(l, &mut current);
        self.state.current = current;
    }

    fn scan_to(&mut self, t_end: f64, st: &mut ModalState, buffers: &mut ProbeBuffers) -> Result<(), SimError> {
        let mut count = 0u64;
        let mut probes = 0u64;
        // The accounting's quadrature nodes so far, up to `counted`, at the
        // current phase's rate.
        let (mut nodes, mut counted, mut node_rate) = (0.0, self.state.time, self.accounting_nodes_per_time());
        // The budget in points as a float, converted once: u64 to f64 is a
        // dozen instructions on x86-64 (i64 to f64 one), at every probe.
        let budget = self.model.max_probes_per_step as f64;
        loop {
            if matches!(self.segment, Segment::Integrated(_)) {
                let Some((te, at, at_zero)) = self.integrated_search(t_end, &mut probes).inspect_err(|_| self.stop_at(self.state.scan.min(t_end)))? else { break };
                count += 1;
                self.stats.events += 1;
                if count > self.model.max_events_per_step {
                    self.stop_at(te);
                    return Err(SimError::TooManyEvents { time: te, count });
                }
                let anchor = self.state.anchor_time;
                let mut at = at;
                // The integrated search tests signs, not departures: only
                // the functions at zero here get their flags (from the
                // event handling).
                for s in &mut self.state.stops {
                    s.departing = [false; 2];
                }
                self.state.probed = te;
                self.handle_events(te, &mut at, &at_zero)?;
                if self.state.anchor_time == anchor && matches!(self.segment, Segment::Integrated(_)) {
                    // Nothing switched: search on past the zero.
                    self.state.scan = self.state.scan.max(te);
                }
                continue;
            }
            let l = self.state.scan;
            if l > t_end {
                break;
            }
            probes += 1;
            let more = node_rate * (l - counted);
            if probes as i64 as f64 + nodes + more > budget {
                // Stop where the accounting's nodes exhaust the budget (the
                // search has certified every point up to l).
                let room = (budget - probes as i64 as f64 - nodes).max(0.0);
                let at = if more > room { (counted + room / node_rate).clamp(counted, l) } else { l };
                self.stop_at(at);
                return Err(SimError::TooMuchWork { time: at, probes: probes - 1 });
            }
            nodes += more;
            counted = l;
            self.stats.probes += 1;
            match self.probe(l, st, buffers) {
                Probe::Events => {}
                Probe::Clear { step, limiting } => {
                    // Clear down to the search's resolution: step on.
                    let next = l + step;
                    if next > l {
                        if l == t_end {
                            break;
                        }
                        // Functions leaving their boundary stop departing once clear of noise.
                        self.set_departing(&buffers.keep);
                        self.state.probed = l;
                        self.state.scan = next;
                        continue;
                    }
                    // The zero is within one ulp of l.
                    match limiting {
                        Some(i) => buffers.at_zero.push((i, buffers.limiting)),
                        None => break,
                    }
                }
            }
            count += 1;
            self.stats.events += 1;
            if count > self.model.max_events_per_step {
                self.stop_at(l);
                return Err(SimError::TooManyEvents { time: l, count });
            }
            if let Segment::Coupled { phase, segment } = &self.segment {
                // Coupled probes sample the complex coordinates only; the
                // probe at the event has them at its time.
                segment.state_at_sample(&phase.system, l, &buffers.coupled, st);
            }
            // Every flag from this point: the functions at zero get theirs
            // from the event handling, the others keep what the probe found.
            self.set_departing(&buffers.keep);
            self.state.probed = l;
            self.handle_events(l, st, &buffers.at_zero)?;
            node_rate = self.accounting_nodes_per_time();
            if std::mem::take(&mut self.basis_changed) {
                *buffers = ProbeBuffers::new(&self.dynamics);
                *st = ModalState::zeros(self.model.n_modes());
            }
        }
        self.account(t_end);
        self.state.time = t_end;
        if let Segment::Integrated(seg) = &mut self.segment {
            seg.settle_at(t_end);
        }
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
        if matches!(check.segment, Segment::Integrated(_)) {
            // Replay the phase and search it from the current time.
            if check.rebuild_segment().is_err() {
                return false;
            }
            check.state.scan = check.state.time;
            let mut probes = 0;
            return matches!(check.integrated_search(target, &mut probes), Ok(None));
        }
        check.state.scan = check.state.time;
        let mut buffers = ProbeBuffers::new(&check.dynamics);
        let mut st = ModalState::zeros(check.model.n_modes());
        for _ in 0..max_probes {
            let l = check.state.scan;
            if l >= target {
                return true;
            }
            match check.probe(l, &mut st, &mut buffers) {
                Probe::Events => return false,
                Probe::Clear { step, .. } => {
                    if !(l + step > l) {
                        return false;
                    }
                    check.set_departing(&buffers.keep);
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

    /// Applies the events found at time `t` (state `st`, taken: it becomes
    /// the new anchor, and `st` receives the old one's storage) and starts
    /// a new segment there if the state or the phase changed. `at_zero`
    /// lists the channels at their zero with their jets.
    fn handle_events(&mut self, t: f64, st: &mut ModalState, at_zero: &[(usize, Jet)]) -> Result<(), SimError> {
        let mut work = self.event_work.take().unwrap_or_default();
        work.clear();
        let result = self.apply_events(t, st, at_zero, &mut work);
        self.event_work = Some(work);
        result
    }

    fn apply_events(&mut self, t: f64, st: &mut ModalState, at_zero: &[(usize, Jet)], work: &mut EventWork) -> Result<(), SimError> {
        let n_stops = self.model.stops.len();
        let EventWork { impacts, sticks, releases, switches, was, contact, restitution, chatter_ends, involved, newly_held, before, impulses, jet } = work;
        for &(c, jet) in at_zero {
            let Channel { stop: i, slot, watch } = self.channels[c];
            let m = &self.model.stops[i];
            let contact = self.state.stops[i].contact;
            match m.law.on_zero(contact, watch, &jet, &self.geometries[i], st) {
                Switch::Stay => self.state.stops[i].departing[slot] = true,
                Switch::Graze => {
                    self.state.stops[i].departing[slot] = true;
                    self.record(t, EventKind::Graze { stop: i });
                }
                Switch::Impact => impacts.push((i, -jet.d[1])),
                Switch::Stick => sticks.push(i),
                Switch::To(Contact::Open) if contact == Contact::Held => releases.push(i),
                Switch::To(next) => {
                    if !switches.iter().any(|s| s.0 == i) {
                        switches.push((i, next, -jet.d[1]));
                    }
                }
            }
        }
        if impacts.is_empty() && sticks.is_empty() && releases.is_empty() && switches.is_empty() {
            return Ok(());
        }
        // The balance and the impulses up to the event, in the segment ending here.
        self.account(t);
        self.close_segment(t, st);
        // The energy the events take, for the balance (when kept).
        let energy_before = self.state.balance.as_ref().map(|_| self.model.energy(st));
        was.extend(self.state.stops.iter().map(|s| s.contact));
        contact.extend_from_slice(was);
        for &i in releases.iter() {
            let counters = &mut self.state.stops[i];
            counters.stuck_time += t - counters.held_since;
            contact[i] = Contact::Open;
            counters.departing = [true, false];
            counters.previous_impact = None;
            self.record(t, EventKind::Release { stop: i });
        }
        // Compliant stops: the phase changes, the state does not.
        for &(i, next, rate) in switches.iter() {
            let m = &self.model.stops[i];
            contact[i] = next;
            let counters = &mut self.state.stops[i];
            counters.departing = [true, false];
            match next {
                Contact::Pressed if was[i] == Contact::Open => {
                    counters.impacts += 1;
                    counters.last_impact = t;
                    counters.onset_speed = rate.max(0.0);
                    self.record(t, EventKind::Contact { stop: i, speed: rate });
                }
                Contact::Open | Contact::Penetrated if was[i] == Contact::Pressed => {
                    let penetration = self.geometries[i].penetration(&st.q).max(0.0);
                    // The spring's energy left in the stop is its own.
                    counters.dissipated += m.law.energy_left_at_release(penetration);
                    self.record(t, EventKind::Separation { stop: i, penetration });
                }
                _ => {}
            }
        }
        // Mode transfer (seed 001): entering or leaving contact changes the
        // basis; MTM projects both fields on the new modes, RMTM freezes the
        // displacement and projects the velocity (docs/mode_transfer.md).
        let mut basis_changed = false;
        if let Some(tr) = &self.model.transfer {
            let i = tr.stop;
            let into = was[i] != Contact::Pressed && contact[i] == Contact::Pressed;
            let out = was[i] == Contact::Pressed && contact[i] != Contact::Pressed;
            if into || out {
                let f = self.state.frozen.as_mut().expect("a mode-transfer model keeps a frozen shape");
                let t = &tr.overlap;
                let project = |v: &DVector<f64>| if into { t * v } else { t.tr_mul(v) };
                match tr.method {
                    ContactMethod::Rmtm => {
                        if into {
                            f.c += &st.q;
                        } else {
                            f.d += &st.q;
                        }
                        st.q.fill(0.0);
                    }
                    _ => {
                        st.q = project(&st.q);
                        // Truncation moves the projected tip off the stop
                        // (0.94 of the gap at kappa = 1e4, 20 modes): put it
                        // back on the surface along the new basis's tip
                        // shape, as an impact puts a rigid stop's point on
                        // it, so the phase starts where the switch happened.
                        let g = &self.model.stops[i].geometry;
                        let shape = if into { &tr.stop_w } else { &g.w };
                        let miss = g.target() - shape.dot(&st.q);
                        st.q.axpy(miss / shape.dot(shape), shape, 1.0);
                    }
                }
                st.qd = project(&st.qd);
                basis_changed = true;
            }
        }
        // The impact: impacting stops with their restitution, newly pressed
        // and still held stops with R = 0 (seed 000 section 2.2).
        restitution.resize(n_stops, 0.0);
        for &(i, speed) in impacts.iter() {
            let Law::Restitution(law) = &self.model.stops[i].law else { unreachable!("only rigid stops impact") };
            // Largest magnitudes by plain folds (nalgebra's `amax` goes
            // through its generic SIMD comparisons: dearer for a few modes).
            let largest = |v: &DVector<f64>| v.as_slice().iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let negligible = 16.0 * f64::EPSILON * largest(&st.qd) * largest(&self.model.stops[i].geometry.w);
            let counters = &mut self.state.stops[i];
            restitution[i] = law.effective(t, counters.previous_impact, speed, negligible);
            counters.impacts += 1;
            counters.last_impact = t;
            counters.previous_impact = Some(t);
            // R = 0 ends a chatter sequence (with R = 0 given, every impact does).
            if restitution[i] == 0.0 {
                chatter_ends.push(i);
            }
        }
        involved.extend((0..n_stops).filter(|&i| contact[i] == Contact::Held || sticks.contains(&i) || impacts.iter().any(|&(k, _)| k == i)));
        if before.len() == st.qd.len() {
            before.as_mut_slice().copy_from_slice(st.qd.as_slice());
        } else {
            *before = st.qd.clone();
        }
        if !impacts.is_empty() || !sticks.is_empty() {
            let row = |i: usize| {
                let g = &self.model.stops[i].geometry;
                ImpactRow { w: &g.w, restitution: restitution[i], side: g.side }
            };
            match involved.as_slice() {
                &[i] => apply_impact(&mut st.qd, &[row(i)], impulses),
                many => apply_impact(&mut st.qd, &many.iter().map(|&i| row(i)).collect::<Vec<_>>(), impulses),
            }
            if self.model.impulses {
                for (&i, p) in involved.iter().zip(impulses.iter()) {
                    self.state.stops[i].impulse += -self.model.stops[i].geometry.side * p;
                }
            }
        }
        for &(i, speed) in impacts.iter() {
            let g = &self.model.stops[i].geometry;
            // Put the contact point exactly on the stop (seed 000 Fig. 3b).
            let miss = g.target() - g.w.dot(&st.q);
            st.q.axpy(miss / g.w.dot(&g.w), &g.w, 1.0);
            let lost = energy_loss(&g.w, before, restitution[i]);
            self.record(
                t,
                EventKind::Impact { stop: i, speed, restitution: restitution[i], energy_lost: lost, chatter: chatter_ends.contains(&i) },
            );
            self.state.stops[i].departing = [true, false];
        }
        // After the last impact of a chatter sequence the contact velocity is
        // zero: the beam sticks if the loads press it on (the reaction of seed
        // 000 eq. 32 of the right sign), else it leaves. Zero-velocity
        // contacts found pressed stick.
        if !chatter_ends.is_empty() {
            let n = self.dynamics.oscillators.len();
            let jet = jet.get_or_insert_with(|| ModalJet::new(n));
            if jet.q[0].len() != n {
                *jet = ModalJet::new(n);
            }
            jet.fill_free(&self.dynamics, t, st);
            for &i in chatter_ends.iter() {
                let h = jet.functional(&self.gap_functionals[i], t);
                if tendency_from(&h, 2) != Tendency::Opening {
                    contact[i] = Contact::Held;
                }
            }
        }
        for &i in sticks.iter() {
            contact[i] = Contact::Held;
        }
        for i in 0..n_stops {
            if contact[i] == Contact::Held {
                let counters = &mut self.state.stops[i];
                counters.previous_impact = None;
                if was[i] != Contact::Held {
                    counters.sticks += 1;
                    counters.held_since = t;
                    counters.departing = [true, false];
                    newly_held.push(i);
                }
            }
        }
        for (s, c) in self.state.stops.iter_mut().zip(contact.iter()) {
            s.contact = *c;
        }
        if contact.iter().any(|c| *c == Contact::Held) {
            // Exactly on the held stops, moving along them (seed 000 eqs. 29-31:
            // project at entry so no drift accumulates). A phase entered
            // before has its system at hand.
            let system = match self.phase_memo.iter().find(|m| m.holds_for(&self.state.stops)) {
                Some(memo) => memo.phase.system.clone(),
                None => {
                    let key = self.phase_key();
                    self.coupled_system(&key)?
                }
            };
            system.project(&self.held_targets(), st);
        }
        if let (Some(before), Some(b)) = (energy_before, self.state.balance.as_mut()) {
            b.impacts += before - self.model.energy(st);
        }
        std::mem::swap(&mut self.state.anchor, st);
        self.state.anchor_time = t;
        self.state.scan = t;
        self.mark_anchor_departing();
        if basis_changed {
            self.refresh_basis();
            self.basis_changed = true;
        }
        if !basis_changed && was == contact && matches!(self.segment, Segment::Free { .. }) {
            // An impact in free flight: the same free phase and event
            // functions from the new anchor.
            self.rebuild_free_segment(false);
        } else {
            self.rebuild_segment()?;
        }
        // Report the sticks with their initial reaction.
        for &i in newly_held.iter() {
            let reaction = self.reaction_at(i, t, &self.state.anchor);
            self.record(t, EventKind::Stick { stop: i, reaction });
        }
        Ok(())
    }
}

/// Work space of the event handling, kept between events.
#[derive(Clone, Debug)]
struct EventWork {
    impacts: Vec<(usize, f64)>,
    sticks: Vec<usize>,
    releases: Vec<usize>,
    switches: Vec<(usize, Contact, f64)>,
    /// Each stop's contact state before the events, and after.
    was: Vec<Contact>,
    contact: Vec<Contact>,
    restitution: Vec<f64>,
    chatter_ends: Vec<usize>,
    /// Stops taking part in the impact (impacting, sticking or held).
    involved: Vec<usize>,
    newly_held: Vec<usize>,
    /// The modal velocities before the impact.
    before: DVector<f64>,
    impulses: Vec<f64>,
    /// The free jet after the impact, made when a chatter sequence ends.
    jet: Option<ModalJet>,
}

impl Default for EventWork {
    fn default() -> Self {
        EventWork {
            impacts: Vec::new(),
            sticks: Vec::new(),
            releases: Vec::new(),
            switches: Vec::new(),
            was: Vec::new(),
            contact: Vec::new(),
            restitution: Vec::new(),
            chatter_ends: Vec::new(),
            involved: Vec::new(),
            newly_held: Vec::new(),
            before: DVector::zeros(0),
            impulses: Vec::new(),
            jet: None,
        }
    }
}

impl EventWork {
    fn clear(&mut self) {
        self.impacts.clear();
        self.sticks.clear();
        self.releases.clear();
        self.switches.clear();
        self.was.clear();
        self.contact.clear();
        self.restitution.clear();
        self.chatter_ends.clear();
        self.involved.clear();
        self.newly_held.clear();
        self.impulses.clear();
    }
}

/// Work space of the event search.
#[derive(Clone, Debug)]
struct ProbeBuffers {
    state: ModalState,
    jet: ModalJet,
    bounds: ModalBounds,
    increment: Increment,
    coupled: CoupledSample,
    coords: Vec<CoordinateBounds>,
    /// The channels' departing flags before and after a probe.
    departing: Vec<bool>,
    keep: Vec<bool>,
    /// The functions at their zero after a probe that found events.
    at_zero: Vec<(usize, Jet)>,
    /// The jet of the function that limited a clear probe's step.
    limiting: Jet,
}

impl ProbeBuffers {
    fn new(dynamics: &FreeDynamics) -> Self {
        let n = dynamics.oscillators.len();
        ProbeBuffers {
            state: ModalState::zeros(n),
            jet: ModalJet::new(n),
            bounds: ModalBounds::new(dynamics),
            increment: Increment::new(n),
            coupled: CoupledSample::default(),
            coords: Vec::new(),
            departing: Vec::new(),
            keep: Vec::new(),
            at_zero: Vec::new(),
            limiting: Jet::default(),
        }
    }
}

enum Probe {
    /// No zero at this point; the probe buffers' `keep` holds the
    /// departing flags of functions still within noise of their boundary.
    /// `limiting`: the function that set the step (its jet in the probe
    /// buffers' `limiting`).
    Clear { step: f64, limiting: Option<usize> },
    /// Functions at their zero, listed in the probe buffers' `at_zero`.
    Events,
}

/// The event functions' verdicts at one point, gathered.
struct Scan<'a> {
    /// Functions leaving their boundary (input).
    departing: &'a [bool],
    at_zero: &'a mut Vec<(usize, Jet)>,
    step: f64,
    limiting: Option<usize>,
    /// The limiting function's jet (output; written in place, not moved
    /// through the probe's result: it is only read at a step below an ulp).
    limiting_jet: &'a mut Jet,
    /// Functions still departing after this point (output).
    keep: &'a mut Vec<bool>,
}

impl<'a> Scan<'a> {
    fn new(departing: &'a [bool], keep: &'a mut Vec<bool>, at_zero: &'a mut Vec<(usize, Jet)>, limiting_jet: &'a mut Jet) -> Self {
        keep.resize(departing.len(), false);
        keep.fill(false);
        at_zero.clear();
        Scan { departing, at_zero, step: f64::INFINITY, limiting: None, limiting_jet, keep }
    }

    /// One function: at its zero (an event), or clear for a certified step;
    /// `step` (given whether the function is departing) certifies it, and
    /// is only called when needed.
    fn consider(&mut self, i: usize, jet: Jet, step: impl FnOnce(bool) -> Certified) {
        let departing = self.departing[i];
        if jet.d[0] <= jet.noise[0] {
            if !departing {
                self.at_zero.push((i, jet));
                return;
            }
            self.keep[i] = true;
        }
        match step(departing) {
            Certified::Clear(s) => {
                if s < self.step {
                    self.step = s;
                    self.limiting = Some(i);
                    *self.limiting_jet = jet;
                }
            }
            Certified::AtZero => self.at_zero.push((i, jet)),
        }
    }

    fn finish(self) -> Probe {
        if self.at_zero.is_empty() {
            Probe::Clear { step: self.step, limiting: self.limiting }
        } else {
            Probe::Events
        }
    }
}

/// The free dynamics of the current basis: the structure's modes, or with
/// mode transfer in contact the tip-spring modes (seed 001), each with the
/// constant load its frozen shape and the spring's preload exert
/// (docs/mode_transfer.md: `-omega^2 r` apart, `k target Phi(L) -
/// omega~^2 s` in contact, `r = c + T^T d`, `s = T c + d`).
fn phase_dynamics(model: &Model, inputs: &[f64], state: &SimState) -> FreeDynamics {
    let (Some(tr), Some(f)) = (&model.transfer, &state.frozen) else {
        return FreeDynamics::new(model.oscillators.clone(), model.forcing_with_inputs(inputs));
    };
    if state.stops[tr.stop].contact == Contact::Pressed {
        let mut forcing = tr.loads.clone();
        for (a, u) in tr.inputs.iter().zip(inputs) {
            forcing.constant.axpy(*u, a, 1.0);
        }
        let Law::SpringDashpot(law) = &model.stops[tr.stop].law else { unreachable!("mode transfer needs a spring stop") };
        forcing.constant.axpy(law.k * model.stops[tr.stop].geometry.target(), &tr.stop_w, 1.0);
        let s = &tr.overlap * &f.c + &f.d;
        for (j, o) in tr.oscillators.iter().enumerate() {
            forcing.constant[j] -= o.omega * o.omega * s[j];
        }
        FreeDynamics::new(tr.oscillators.clone(), forcing)
    } else {
        let mut forcing = model.forcing_with_inputs(inputs);
        let r = &f.c + tr.overlap.tr_mul(&f.d);
        for (j, o) in model.oscillators.iter().enumerate() {
            forcing.constant[j] -= o.omega * o.omega * r[j];
        }
        FreeDynamics::new(model.oscillators.clone(), forcing)
    }
}

/// Each stop's geometry in the current basis: with mode transfer, the
/// transfer stop's shape is `Phi(L)` while pressed, and the frozen shape's
/// displacement there is taken off its gap.
fn active_geometries(model: &Model, state: &SimState) -> Vec<Geometry> {
    let mut out: Vec<Geometry> = model.stops.iter().map(|s| s.geometry.clone()).collect();
    if let (Some(tr), Some(f)) = (&model.transfer, &state.frozen) {
        let g = &mut out[tr.stop];
        let frozen = g.w.dot(&f.c) + tr.stop_w.dot(&f.d);
        g.gap -= g.side * frozen;
        if state.stops[tr.stop].contact == Contact::Pressed {
            g.w = tr.stop_w.clone();
        }
    }
    out
}
