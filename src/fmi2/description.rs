//! modelDescription.xml from a scene: only the scene's own variables.
//!
//! Deterministic (no generation date), so the committed copies under
//! modelDescription/ can be checked against the generator.

use std::fmt::Write;

use crate::component::Component;

use crate::fmi::variables::{Causality, VarType, Variability, VariableTable};
use crate::fmi::xml::{escape, log_categories, num, unit_definitions};

pub fn model_description(scene: &Component) -> String {
    let table = VariableTable::new(scene);
    let mut x = String::new();
    let id = scene.name();
    let _ = writeln!(x, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(
        x,
        r#"<fmiModelDescription fmiVersion="2.0" modelName="{id}" guid="{}" description="{}" generationTool="beamstop {}" variableNamingConvention="structured" numberOfEventIndicators="0">"#,
        scene.guid(),
        escape(&scene.description()),
        env!("CARGO_PKG_VERSION"),
    );
    let _ = writeln!(
        x,
        r#"  <CoSimulation modelIdentifier="{id}" needsExecutionTool="false" canHandleVariableCommunicationStepSize="true" canInterpolateInputs="false" maxOutputDerivativeOrder="0" canRunAsynchronuously="false" canBeInstantiatedOnlyOncePerProcess="false" canNotUseMemoryManagementFunctions="true" canGetAndSetFMUstate="true" canSerializeFMUstate="true" providesDirectionalDerivative="false"/>"#
    );
    unit_definitions(&mut x, &table, None);
    log_categories(&mut x, "fmi2");
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
        let _ = writeln!(x, r#"    <!-- index {} -->"#, v.vr + 1);
        let _ = writeln!(
            x,
            r#"    <ScalarVariable name="{}" valueReference="{}" description="{}" causality="{causality}" variability="{variability}"{initial}>"#,
            escape(&v.name),
            v.vr,
            escape(&v.description),
        );
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
        let _ = writeln!(x, "      <{}{attrs}/>", v.ty.name());
        let _ = writeln!(x, "    </ScalarVariable>");
    }
    let _ = writeln!(x, "  </ModelVariables>");
    let _ = writeln!(x, "  <ModelStructure>");
    let outputs: Vec<u32> = table.variables.iter().filter(|v| v.causality == Causality::Output).map(|v| v.vr + 1).collect();
    let _ = writeln!(x, "    <Outputs>");
    for i in &outputs {
        let _ = writeln!(x, r#"      <Unknown index="{i}"/>"#);
    }
    let _ = writeln!(x, "    </Outputs>");
    let _ = writeln!(x, "    <InitialUnknowns>");
    for i in &outputs {
        let _ = writeln!(x, r#"      <Unknown index="{i}"/>"#);
    }
    let _ = writeln!(x, "    </InitialUnknowns>");
    let _ = writeln!(x, "  </ModelStructure>");
    let _ = writeln!(x, "</fmiModelDescription>");
    x
}

