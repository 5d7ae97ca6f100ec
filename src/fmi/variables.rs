//! The scene's parameters, inputs and outputs as FMI scalar variables:
//! value references, causality, variability, start values. One table
//! serves the instance (get/set) and the modelDescription.xml.

use crate::component::Component;
use crate::variables::{OutputType, Unit, Variables};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VarType {
    Real,
    Integer,
    Boolean,
}

impl VarType {
    pub fn name(self) -> &'static str {
        match self {
            VarType::Real => "Real",
            VarType::Integer => "Integer",
            VarType::Boolean => "Boolean",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Causality {
    Parameter,
    Input,
    Output,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variability {
    Fixed,
    Tunable,
    Discrete,
    Continuous,
}

/// What a variable reads or writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Binding {
    Parameter(usize),
    Input(usize),
    Output(usize),
}

#[derive(Clone, Debug, PartialEq)]
pub struct Variable {
    pub vr: u32,
    pub name: String,
    pub description: String,
    pub unit: Unit,
    pub ty: VarType,
    pub causality: Causality,
    pub variability: Variability,
    /// Start value (parameters and inputs); outputs are calculated.
    pub start: Option<f64>,
    pub min: Option<f64>,
    pub max: Option<f64>,
    pub binding: Binding,
}

/// The interface of a scene, with its variables numbered by value reference.
#[derive(Clone, Debug)]
pub struct VariableTable {
    pub interface: Variables,
    /// Indexed by value reference.
    pub variables: Vec<Variable>,
}

impl VariableTable {
    pub fn new(scene: &Component) -> Self {
        let interface = scene.variables().clone();
        let Variables { parameters, inputs, outputs } = &interface;
        let mut variables = Vec::new();
        let finite = |x: f64| if x.is_finite() { Some(x) } else { None };
        for (i, p) in parameters.iter().enumerate() {
            variables.push(Variable {
                vr: variables.len() as u32,
                name: p.name.clone(),
                description: format!("{} (allowed {})", p.description, p.range),
                unit: p.unit,
                ty: VarType::Real,
                causality: Causality::Parameter,
                variability: if p.tunable { Variability::Tunable } else { Variability::Fixed },
                start: Some(scene.get(i)),
                // FMI bounds are inclusive: an open end becomes the next double inside.
                min: finite(p.range.min).map(|m| if p.range.min_open { m.next_up() } else { m }),
                max: finite(p.range.max).map(|m| if p.range.max_open { m.next_down() } else { m }),
                binding: Binding::Parameter(i),
            });
        }
        for (i, input) in inputs.iter().enumerate() {
            variables.push(Variable {
                vr: variables.len() as u32,
                name: input.name.clone(),
                description: format!("{} (allowed {})", input.description, input.range),
                unit: input.unit,
                ty: VarType::Real,
                causality: Causality::Input,
                variability: Variability::Continuous,
                start: Some(0.0),
                min: finite(input.range.min),
                max: finite(input.range.max),
                binding: Binding::Input(i),
            });
        }
        for (i, o) in outputs.iter().enumerate() {
            let ty = match o.kind {
                OutputType::Real => VarType::Real,
                OutputType::Integer => VarType::Integer,
                OutputType::Boolean => VarType::Boolean,
            };
            let variability = if o.discrete { Variability::Discrete } else { Variability::Continuous };
            variables.push(Variable {
                vr: variables.len() as u32,
                name: o.name.clone(),
                description: o.description.clone(),
                unit: o.unit,
                ty,
                causality: Causality::Output,
                variability,
                start: None,
                min: None,
                max: None,
                binding: Binding::Output(i),
            });
        }
        VariableTable { interface, variables }
    }

    pub fn get(&self, vr: u32) -> Option<&Variable> {
        self.variables.get(vr as usize)
    }

}
