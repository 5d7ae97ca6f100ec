//! What the modelDescription.xml of both standards (and the FMU's
//! documentation) write alike: escaped text, numbers in their shortest
//! round-trip form, the unit definitions and the log categories.

use std::fmt::Write;

use super::logging::CATEGORIES;
use super::variables::{VarType, VariableTable};
use crate::variables::Unit;

/// Text as an XML attribute or element holds it.
pub fn escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// Shortest round-trip form of a number, as XML wants it.
pub fn num(x: f64) -> String {
    let s = format!("{x:?}");
    s.strip_suffix(".0").map(str::to_string).unwrap_or(s)
}

/// The LogCategories element, its descriptions in the words of `standard`
/// ("fmi2" or "fmi3": the status names they give).
pub fn log_categories(x: &mut String, standard: &str) {
    let _ = writeln!(*x, "  <LogCategories>");
    for (name, description) in CATEGORIES {
        let _ = writeln!(*x, r#"    <Category name="{name}" description="{}"/>"#, escape(&description.replace("{fmi}", standard)));
    }
    let _ = writeln!(*x, "  </LogCategories>");
}

/// The UnitDefinitions of the table's Real variables and `extra` (the same
/// element in FMI 2.0 and 3.0).
pub fn unit_definitions(x: &mut String, table: &VariableTable, extra: Option<Unit>) {
    let mut units: Vec<Unit> = table.variables.iter().filter(|v| v.ty == VarType::Real).map(|v| v.unit).chain(extra).collect();
    units.sort();
    units.dedup();
    let _ = writeln!(*x, "  <UnitDefinitions>");
    for u in &units {
        let Some(e) = u.si_exponents() else {
            // Fractional exponents (N/m^1.5) have no BaseUnit in FMI 2.0.
            let _ = writeln!(*x, r#"    <Unit name="{}"/>"#, escape(&u.name()));
            continue;
        };
        let mut attrs = String::new();
        for (name, exp) in ["kg", "m", "s", "rad"].iter().zip(e) {
            if exp != 0 {
                let _ = write!(attrs, r#" {name}="{exp}""#);
            }
        }
        let _ = writeln!(*x, r#"    <Unit name="{}"><BaseUnit{attrs}/></Unit>"#, escape(&u.name()));
    }
    let _ = writeln!(*x, "  </UnitDefinitions>");
}
