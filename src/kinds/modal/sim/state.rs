//! What a run's state holds: the evolving state that, with the model and
//! the inputs, determines the future ([`SimState`], with each stop's
//! contact state and counters, the frozen shape of mode transfer and the
//! energy balance), and the run's work counters ([`Stats`]).

use nalgebra::DVector;

use crate::contact::Contact;
use crate::solve::ModalState;

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
    /// WB00's energy accounting, when the model asks for it.
    pub balance: Option<EnergyBalance>,
    /// With mode transfer (RMTM's MTM and RMTM methods): the shape the current
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
/// its damping dissipates `DE_j = int 2 zeta_j omega_j qd_j^2 dt` (WB00
/// eq. 8) and the energy lost at impacts, all from the start, so that
/// `E(t) - E(0) = sum_j (FE_j - DE_j) - impacts` (WB00 eq. 7).
#[derive(Clone, Debug, PartialEq)]
pub struct EnergyBalance {
    pub forcing: Vec<f64>,
    pub damping: Vec<f64>,
    pub impacts: f64,
    /// The sums cover the run up to this time.
    pub time: f64,
}

/// Work counters of a run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Points where the event functions were evaluated.
    pub probes: u64,
    /// Events handled (each may hold several simultaneous ones).
    pub events: u64,
    /// The work the cap of one step counts (`solver.max_probes_per_step`):
    /// search points, integrated steps by their weight, and the energy
    /// balance's quadrature nodes.
    pub work: u64,
}
