//! The FMI 3.0 co-simulation state machine as one table (FMI 3.0.1,
//! section 4.2.1): each function lists the states it may be called in, as
//! the Reference FMUs do, and one check answers for all of them. The
//! functions of Model Exchange and Scheduled Execution, clocks and
//! configuration mode are allowed in no state: this FMU has none of them.

use crate::fmi::variables::VarType;
use crate::fmi::{Call, ModelState};

/// The FMI 3.0 name of a state.
pub fn state_name(state: ModelState) -> &'static str {
    match state {
        ModelState::Instantiated => "Instantiated",
        ModelState::InitializationMode => "InitializationMode",
        ModelState::EventMode => "EventMode",
        ModelState::StepMode => "StepMode",
        ModelState::StepDiscarded => "StepDiscarded",
        ModelState::StepCanceled => "StepCanceled",
        ModelState::Terminated => "Terminated",
        ModelState::Error => "Error",
        ModelState::Fatal => "Fatal",
    }
}

const INSTANTIATED: u32 = ModelState::Instantiated as u32;
const INIT: u32 = ModelState::InitializationMode as u32;
const EVENT: u32 = ModelState::EventMode as u32;
const STEP: u32 = ModelState::StepMode as u32;
const DISCARDED: u32 = ModelState::StepDiscarded as u32;
const TERMINATED: u32 = ModelState::Terminated as u32;
const ERROR: u32 = ModelState::Error as u32;

/// Every state but Fatal.
const ALIVE: u32 = INSTANTIATED | INIT | EVENT | STEP | DISCARDED | TERMINATED | ERROR;
const READABLE: u32 = INIT | EVENT | STEP | DISCARDED | TERMINATED | ERROR;
const SETTABLE: u32 = INSTANTIATED | INIT | EVENT | STEP;

/// The FMI 3.0 functions that take an instance.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Function {
    SetDebugLogging,
    EnterInitializationMode,
    ExitInitializationMode,
    EnterEventMode,
    Terminate,
    Reset,
    /// fmi3Get<Type>: the name.
    Get(&'static str),
    /// fmi3Set<Type>: the name.
    Set(&'static str),
    GetNumberOfVariableDependencies,
    GetVariableDependencies,
    GetFMUState,
    SetFMUState,
    FreeFMUState,
    SerializedFMUStateSize,
    SerializeFMUState,
    DeserializeFMUState,
    GetDirectionalDerivative,
    GetAdjointDerivative,
    EvaluateDiscreteStates,
    UpdateDiscreteStates,
    EnterStepMode,
    GetOutputDerivatives,
    DoStep,
    /// A function of something this FMU does not have (clocks,
    /// configuration mode, Model Exchange, Scheduled Execution), with why.
    Absent(&'static str, &'static str),
}

impl Function {
    /// The states this function may be called in.
    pub fn allowed(self) -> u32 {
        use Function::*;
        match self {
            SetDebugLogging | Reset | GetFMUState | SetFMUState | FreeFMUState | SerializedFMUStateSize | SerializeFMUState
            | DeserializeFMUState => ALIVE,
            EnterInitializationMode => INSTANTIATED,
            ExitInitializationMode => INIT,
            EnterEventMode => STEP,
            Terminate => EVENT | STEP | DISCARDED,
            Get(_) => READABLE,
            Set(_) => SETTABLE,
            // Not provided: refused with the reason in every live state.
            GetNumberOfVariableDependencies | GetVariableDependencies | GetDirectionalDerivative | GetAdjointDerivative
            | EvaluateDiscreteStates | GetOutputDerivatives => ALIVE,
            UpdateDiscreteStates => EVENT,
            EnterStepMode => EVENT,
            DoStep => STEP,
            Absent(..) => 0,
        }
    }

    pub fn name(self) -> &'static str {
        use Function::*;
        match self {
            SetDebugLogging => "fmi3SetDebugLogging",
            EnterInitializationMode => "fmi3EnterInitializationMode",
            ExitInitializationMode => "fmi3ExitInitializationMode",
            EnterEventMode => "fmi3EnterEventMode",
            Terminate => "fmi3Terminate",
            Reset => "fmi3Reset",
            Get(name) | Set(name) => name,
            GetNumberOfVariableDependencies => "fmi3GetNumberOfVariableDependencies",
            GetVariableDependencies => "fmi3GetVariableDependencies",
            GetFMUState => "fmi3GetFMUState",
            SetFMUState => "fmi3SetFMUState",
            FreeFMUState => "fmi3FreeFMUState",
            SerializedFMUStateSize => "fmi3SerializedFMUStateSize",
            SerializeFMUState => "fmi3SerializeFMUState",
            DeserializeFMUState => "fmi3DeserializeFMUState",
            GetDirectionalDerivative => "fmi3GetDirectionalDerivative",
            GetAdjointDerivative => "fmi3GetAdjointDerivative",
            EvaluateDiscreteStates => "fmi3EvaluateDiscreteStates",
            UpdateDiscreteStates => "fmi3UpdateDiscreteStates",
            EnterStepMode => "fmi3EnterStepMode",
            GetOutputDerivatives => "fmi3GetOutputDerivatives",
            DoStep => "fmi3DoStep",
            Absent(name, _) => name,
        }
    }
}

impl Call for Function {
    fn name(self) -> &'static str {
        Function::name(self)
    }

    fn type_name(self, ty: VarType) -> &'static str {
        match ty {
            VarType::Real => "Float64",
            VarType::Integer => "Int32",
            VarType::Boolean => "Boolean",
        }
    }

    fn check(self, state: ModelState) -> Result<(), String> {
        if self.allowed() & state as u32 != 0 {
            return Ok(());
        }
        Err(match self {
            Function::Absent(name, why) => format!("{name}: {why}"),
            f => {
                let allowed: Vec<&str> = ModelState::ALL.into_iter().filter(|s| f.allowed() & *s as u32 != 0).map(state_name).collect();
                format!("{}: Illegal call sequence: called in state {}, allowed in {}", f.name(), state_name(state), allowed.join(", "))
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn event_mode_and_step_mode() {
        assert!(Function::UpdateDiscreteStates.check(ModelState::EventMode).is_ok());
        let e = Function::DoStep.check(ModelState::EventMode).unwrap_err();
        assert!(e.contains("Illegal call sequence") && e.contains("EventMode") && e.contains("StepMode"), "{e}");
        assert!(Function::Get("fmi3GetFloat64").check(ModelState::EventMode).is_ok());
        let e = Function::Absent("fmi3GetClock", "this FMU has no clocks").check(ModelState::StepMode).unwrap_err();
        assert_eq!(e, "fmi3GetClock: this FMU has no clocks");
    }
}
