//! The one error of every kind of simulation, and whether the run that
//! met it stays usable: a step that hit a cap is discarded with the state
//! valid at the time reached; anything else ends the run.

use std::fmt;

use crate::solve::lti::LtiError;

#[derive(Clone, Debug, PartialEq)]
pub enum SimError {
    /// The scene cannot form a model (the message names the field).
    Scene(String),
    /// The initial state lies beyond a rigid stop; `fields`: the scene
    /// fields that put it there (the stop's gap and the initial modal
    /// displacements that move the point).
    Penetration { stop: String, displacement: f64, limit: f64, side: f64, fields: Vec<String> },
    /// The initial state puts a point deeper into a compliant surface than
    /// a run may start (`limit`: the depth whose stored energy is the
    /// kinetic energy at the speed limit); `fields` name what to change.
    InitialPenetration { point: String, penetration: f64, limit: f64, fields: Vec<String> },
    /// More events than allowed inside one advance.
    TooManyEvents { time: f64, count: u64 },
    /// More work than allowed inside one advance (event-search points,
    /// quadrature nodes, integration steps, in units of `cap`'s setting).
    TooMuchWork { time: f64, work: u64, cap: &'static str },
    /// A contact phase could not be set up.
    Contact(LtiError),
    /// A requested time lies before the current one.
    Backwards { now: f64, requested: f64 },
    /// A time or an input is NaN or infinite.
    NonFinite { what: &'static str, value: f64 },
    /// The value cannot be set in this scene.
    NotAnInput(String),
    /// What this kind of run cannot do (the message says what and why).
    Unsupported(String),
    /// An integrated phase failed (`message` says why and what to change).
    Integration { time: f64, message: String },
}

impl SimError {
    /// The state is valid at the time reached and a shorter or different
    /// step may succeed (too many events, too much work): the step is
    /// discarded, not the run.
    pub fn recoverable(&self) -> bool {
        matches!(self, SimError::TooManyEvents { .. } | SimError::TooMuchWork { .. })
    }
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SimError::Scene(m) => write!(f, "{m}"),
            SimError::Penetration { stop, displacement, limit, side, fields } => write!(
                f,
                "the initial state penetrates stop '{stop}': displacement there is {displacement}, allowed {} {limit}; \
                 change the initial modal coordinates or the gap ({})",
                if *side > 0.0 { "<=" } else { ">=" },
                fields.join(", ")
            ),
            SimError::InitialPenetration { point, penetration, limit, fields } => write!(
                f,
                "the initial state ({}) puts {point} {penetration:e} m into the surface, deeper than a run may \
                 start ({limit:e} m: the depth whose stored energy 2/5 K gamma^2.5 equals the kinetic energy of the \
                 point's effective mass at the speed limit); start with {point} outside the surface, on it, or less deep",
                fields.join(", ")
            ),
            SimError::TooManyEvents { time, count } => write!(
                f,
                "{count} events within one step near t = {time:?}: raise solver.max_events_per_step (or, at a rigid stop, \
                 the chatter threshold eps)"
            ),
            SimError::TooMuchWork { time, work, cap } => write!(
                f,
                "the work cap of one step ({cap}) was reached after {work} units of work, at t = {time:?}: take shorter \
                 communication steps or raise {cap}"
            ),
            SimError::Contact(e) => write!(f, "{e}"),
            SimError::Backwards { now, requested } => write!(f, "requested time {requested:?} lies before the current time {now:?}"),
            SimError::NonFinite { what, value } => write!(f, "{what} = {value}: must be finite"),
            SimError::NotAnInput(m) => write!(f, "cannot set {m}"),
            SimError::Unsupported(m) => write!(f, "{m}"),
            SimError::Integration { time, message } => write!(f, "the integration failed at t = {time:?}: {message}"),
        }
    }
}

impl std::error::Error for SimError {}

impl From<LtiError> for SimError {
    fn from(e: LtiError) -> Self {
        SimError::Contact(e)
    }
}
