//! The FMI 2.0 co-simulation state machine as one table: each function
//! lists the states it may be called in (as the Reference FMUs do), and
//! one check answers for all of them.

use crate::fmi::{Call, ModelState};

/// The FMI 2.0 name of a state.
pub fn state_name(state: ModelState) -> &'static str {
    match state {
        ModelState::Instantiated => "Instantiated",
        ModelState::InitializationMode => "InitializationMode",
        ModelState::StepMode => "StepComplete",
        ModelState::StepDiscarded => "StepFailed",
        ModelState::StepCanceled => "StepCanceled",
        ModelState::Terminated => "Terminated",
        ModelState::Error => "Error",
        ModelState::Fatal => "Fatal",
        ModelState::EventMode => "EventMode (FMI 3.0)",
    }
}

const INSTANTIATED: u32 = ModelState::Instantiated as u32;
const INIT: u32 = ModelState::InitializationMode as u32;
const STEP_COMPLETE: u32 = ModelState::StepMode as u32;
const STEP_FAILED: u32 = ModelState::StepDiscarded as u32;
const STEP_CANCELED: u32 = ModelState::StepCanceled as u32;
const TERMINATED: u32 = ModelState::Terminated as u32;
const ERROR: u32 = ModelState::Error as u32;

/// Every state but Fatal.
const ALIVE: u32 = INSTANTIATED | INIT | STEP_COMPLETE | STEP_FAILED | STEP_CANCELED | TERMINATED | ERROR;
const READABLE: u32 = INIT | STEP_COMPLETE | STEP_FAILED | STEP_CANCELED | TERMINATED | ERROR;
const SETTABLE: u32 = INSTANTIATED | INIT | STEP_COMPLETE;

/// The FMI functions that take an instance.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Function {
    SetDebugLogging,
    SetupExperiment,
    EnterInitializationMode,
    ExitInitializationMode,
    Terminate,
    Reset,
    GetReal,
    GetInteger,
    GetBoolean,
    GetString,
    SetReal,
    SetInteger,
    SetBoolean,
    SetString,
    GetFMUstate,
    SetFMUstate,
    FreeFMUstate,
    SerializedFMUstateSize,
    SerializeFMUstate,
    DeSerializeFMUstate,
    GetDirectionalDerivative,
    SetRealInputDerivatives,
    GetRealOutputDerivatives,
    DoStep,
    CancelStep,
    GetStatus,
    GetRealStatus,
    GetIntegerStatus,
    GetBooleanStatus,
    GetStringStatus,
    /// Any Model Exchange function: never allowed in a co-simulation FMU.
    ModelExchange(&'static str),
}

impl Call for Function {
    fn name(self) -> &'static str {
        Function::name(self)
    }

    fn check(self, state: ModelState) -> Result<(), String> {
        Function::check(self, state)
    }
}

impl Function {
    /// The states this function may be called in.
    pub fn allowed(self) -> u32 {
        use Function::*;
        match self {
            SetDebugLogging | Reset | GetFMUstate | SetFMUstate | FreeFMUstate | SerializedFMUstateSize
            | SerializeFMUstate | DeSerializeFMUstate => ALIVE,
            SetupExperiment | EnterInitializationMode => INSTANTIATED,
            ExitInitializationMode => INIT,
            Terminate => STEP_COMPLETE | STEP_FAILED,
            GetReal | GetInteger | GetBoolean | GetString | GetDirectionalDerivative => READABLE,
            SetReal | SetInteger | SetBoolean | SetString | SetRealInputDerivatives => SETTABLE,
            GetRealOutputDerivatives => STEP_COMPLETE | STEP_FAILED | STEP_CANCELED | TERMINATED | ERROR,
            DoStep => STEP_COMPLETE,
            CancelStep => 0,
            GetStatus | GetRealStatus | GetIntegerStatus | GetBooleanStatus | GetStringStatus => {
                STEP_COMPLETE | STEP_FAILED | STEP_CANCELED | TERMINATED
            }
            ModelExchange(_) => 0,
        }
    }

    pub fn name(self) -> &'static str {
        use Function::*;
        match self {
            SetDebugLogging => "fmi2SetDebugLogging",
            SetupExperiment => "fmi2SetupExperiment",
            EnterInitializationMode => "fmi2EnterInitializationMode",
            ExitInitializationMode => "fmi2ExitInitializationMode",
            Terminate => "fmi2Terminate",
            Reset => "fmi2Reset",
            GetReal => "fmi2GetReal",
            GetInteger => "fmi2GetInteger",
            GetBoolean => "fmi2GetBoolean",
            GetString => "fmi2GetString",
            SetReal => "fmi2SetReal",
            SetInteger => "fmi2SetInteger",
            SetBoolean => "fmi2SetBoolean",
            SetString => "fmi2SetString",
            GetFMUstate => "fmi2GetFMUstate",
            SetFMUstate => "fmi2SetFMUstate",
            FreeFMUstate => "fmi2FreeFMUstate",
            SerializedFMUstateSize => "fmi2SerializedFMUstateSize",
            SerializeFMUstate => "fmi2SerializeFMUstate",
            DeSerializeFMUstate => "fmi2DeSerializeFMUstate",
            GetDirectionalDerivative => "fmi2GetDirectionalDerivative",
            SetRealInputDerivatives => "fmi2SetRealInputDerivatives",
            GetRealOutputDerivatives => "fmi2GetRealOutputDerivatives",
            DoStep => "fmi2DoStep",
            CancelStep => "fmi2CancelStep",
            GetStatus => "fmi2GetStatus",
            GetRealStatus => "fmi2GetRealStatus",
            GetIntegerStatus => "fmi2GetIntegerStatus",
            GetBooleanStatus => "fmi2GetBooleanStatus",
            GetStringStatus => "fmi2GetStringStatus",
            ModelExchange(name) => name,
        }
    }

    /// Whether the function may be called in `state`; if not, why.
    pub fn check(self, state: ModelState) -> Result<(), String> {
        if self.allowed() & state as u32 != 0 {
            return Ok(());
        }
        Err(match self {
            Function::ModelExchange(name) => {
                format!("{name}: this FMU implements Co-Simulation only, not Model Exchange")
            }
            Function::CancelStep => "fmi2CancelStep: no step is ever in progress (fmi2DoStep never returns fmi2Pending)".into(),
            f => {
                let allowed: Vec<&str> =
                    ModelState::ALL.into_iter().filter(|s| f.allowed() & *s as u32 != 0).map(state_name).collect();
                format!(
                    "{}: Illegal call sequence: called in state {}, allowed in {}",
                    f.name(),
                    state_name(state),
                    allowed.join(", ")
                )
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn do_step_only_after_initialization() {
        assert!(Function::DoStep.check(ModelState::StepMode).is_ok());
        let e = Function::DoStep.check(ModelState::Instantiated).unwrap_err();
        assert!(e.contains("Illegal call sequence") && e.contains("StepComplete"), "{e}");
    }

    #[test]
    fn after_error_only_recovery_functions() {
        for f in [Function::Reset, Function::SetFMUstate, Function::GetReal] {
            assert!(f.check(ModelState::Error).is_ok(), "{f:?}");
        }
        for f in [Function::DoStep, Function::SetReal, Function::Terminate] {
            assert!(f.check(ModelState::Error).is_err(), "{f:?}");
        }
        assert!(Function::Reset.check(ModelState::Fatal).is_err());
    }
}
