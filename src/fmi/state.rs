//! The states of an instance and the status of a call, shared by both
//! standards (FMI 2.0.4 section 4.2.4, FMI 3.0 section 4.2.1). Each shell
//! has its own table of legal calls ([`Call`]) over these states.

/// An instance's state: the union of both standards' co-simulation states.
/// FMI 2.0 calls `StepMode` "stepComplete" and `StepDiscarded`
/// "stepFailed"; `EventMode` is FMI 3.0's only.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelState {
    Instantiated = 1 << 0,
    InitializationMode = 1 << 1,
    StepMode = 1 << 2,
    StepDiscarded = 1 << 3,
    StepCanceled = 1 << 4,
    Terminated = 1 << 5,
    Error = 1 << 6,
    Fatal = 1 << 7,
    EventMode = 1 << 8,
}

impl ModelState {
    pub const ALL: [ModelState; 9] = [
        ModelState::Instantiated,
        ModelState::InitializationMode,
        ModelState::StepMode,
        ModelState::StepDiscarded,
        ModelState::StepCanceled,
        ModelState::Terminated,
        ModelState::Error,
        ModelState::Fatal,
        ModelState::EventMode,
    ];

    /// The code a serialized state stores.
    pub fn code(self) -> u16 {
        self as u16
    }

    pub fn from_code(code: u16) -> Option<ModelState> {
        Self::ALL.into_iter().find(|s| s.code() == code)
    }

    /// Whether initialisation is over (fixed parameters are then fixed).
    pub fn initialized(self) -> bool {
        !matches!(self, ModelState::Instantiated | ModelState::InitializationMode)
    }
}

/// A C entry point of one standard: its name and the states it may be
/// called in.
pub trait Call: Copy {
    fn name(self) -> &'static str;
    /// Whether the function may be called in `state`; if not, why.
    fn check(self, state: ModelState) -> Result<(), String>;
    /// A variable type's name in this standard.
    fn type_name(self, ty: super::variables::VarType) -> &'static str {
        ty.name()
    }
}

/// The status of a call, ordered by severity (the same codes in
/// `fmi2Status` and `fmi3Status`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Status {
    Ok = 0,
    Warning = 1,
    Discard = 2,
    Error = 3,
    Fatal = 4,
}

impl Status {
    pub fn raw(self) -> libc::c_int {
        self as libc::c_int
    }
}
