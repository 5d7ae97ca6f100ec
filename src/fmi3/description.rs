//! modelDescription.xml (FMI 3.0) from a scene: the FMI 2.0 variables with
//! the same value references, typed Float64, Int32 and Boolean, after them
//! the independent variable `time`, and the co-simulation capabilities of
//! this shell (event mode, early return, intermediate update).
//!
//! Deterministic (no generation date), so the committed copies under
//! modelDescription/fmi3/ can be checked against the generator.

use std::fmt::Write;

use crate::component::Component;
use crate::fmi::variables::{Causality, VarType, Variability, VariableTable};
use crate::fmi::xml::{escape, log_categories, num, unit_definitions};
use crate::variables::Unit;

/// The name of the independent variable.
pub const TIME: &str = "time";

/// Why a scene cannot be an FMI 3.0 FMU (a variable named like the
/// independent variable).
pub fn check(scene: &Component) -> Result<(), String> {
    if scene.variables().names().any(|n| n == TIME) {
        return Err(format!("{}: a variable is named {TIME:?}, the name of FMI 3.0's independent variable: rename it with \"names\"", scene.name()));
    }
    Ok(())
}

pub fn model_description(scene: &Component) -> String {
    let table = VariableTable::new(scene);
    let mut x = String::new();
    let id = scene.name();
    let _ = writeln!(x, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(
        x,
        r#"<fmiModelDescription fmiVersion="3.0" modelName="{id}" instantiationToken="{}" description="{}" generationTool="beamstop {}" variableNamingConvention="structured">"#,
        scene.guid(),
        escape(&scene.description()),
        env!("CARGO_PKG_VERSION"),
    );
    let _ = writeln!(
        x,
        r#"  <CoSimulation modelIdentifier="{id}" needsExecutionTool="false" canBeInstantiatedOnlyOncePerProcess="false" canGetAndSetFMUState="true" canSerializeFMUState="true" providesDirectionalDerivatives="false" providesAdjointDerivatives="false" providesPerElementDependencies="false" canHandleVariableCommunicationStepSize="true" maxOutputDerivativeOrder="0" providesIntermediateUpdate="true" mightReturnEarlyFromDoStep="true" canReturnEarlyAfterIntermediateUpdate="true" hasEventMode="true" providesEvaluateDiscreteStates="false"/>"#
    );
    // Seconds, unless the scene is in scaled units (every unit "1").
    let scaled = table.variables.iter().all(|v| v.ty != VarType::Real || v.unit == Unit::One);
    let time_unit = if scaled { Unit::One } else { Unit::Second };
    unit_definitions(&mut x, &table, Some(time_unit));
    log_categories(&mut x, "fmi3");
    let e = scene.experiment();
    let _ = writeln!(x, r#"  <DefaultExperiment startTime="{}" stopTime="{}" stepSize="{}"/>"#, num(e.start), num(e.stop), num(e.step));
    let _ = writeln!(x, "  <ModelVariables>");
    for v in &table.variables {
        let causality = match v.causality {
            Causality::Parameter => "parameter",
            Causality::Input => "input",
            Causality::Output => "output",
        };
        let variability = match v.variability {
            Variability::Fixed => "fixed",
            Variability::Tunable => "tunable",
            Variability::Discrete => "discrete",
            Variability::Continuous => "continuous",
        };
        let initial = match v.causality {
            Causality::Parameter => r#" initial="exact""#,
            Causality::Input => "",
            Causality::Output => r#" initial="calculated""#,
        };
        let element = match v.ty {
            VarType::Real => "Float64",
            VarType::Integer => "Int32",
            VarType::Boolean => "Boolean",
        };
        let mut attrs = String::new();
        if v.ty == VarType::Real {
            let _ = write!(attrs, r#" unit="{}""#, escape(&v.unit.name()));
        }
        if let Some(s) = v.start {
            let _ = write!(attrs, r#" start="{}""#, num(s));
        }
        if let Some(m) = v.min {
            let _ = write!(attrs, r#" min="{}""#, num(m));
        }
        if let Some(m) = v.max {
            let _ = write!(attrs, r#" max="{}""#, num(m));
        }
        let _ = writeln!(
            x,
            r#"    <{element} name="{}" valueReference="{}" description="{}" causality="{causality}" variability="{variability}"{initial}{attrs}/>"#,
            escape(&v.name),
            v.vr,
            escape(&v.description),
        );
    }
    let _ = writeln!(
        x,
        r#"    <Float64 name="{TIME}" valueReference="{}" description="Simulation time" causality="independent" variability="continuous" unit="{}"/>"#,
        table.variables.len(),
        escape(&time_unit.name())
    );
    let _ = writeln!(x, "  </ModelVariables>");
    let _ = writeln!(x, "  <ModelStructure>");
    let outputs: Vec<u32> = table.variables.iter().filter(|v| v.causality == Causality::Output).map(|v| v.vr).collect();
    for vr in &outputs {
        let _ = writeln!(x, r#"    <Output valueReference="{vr}"/>"#);
    }
    for vr in &outputs {
        let _ = writeln!(x, r#"    <InitialUnknown valueReference="{vr}"/>"#);
    }
    let _ = writeln!(x, "  </ModelStructure>");
    let _ = writeln!(x, "</fmiModelDescription>");
    x
}
