//! The branches and special points of a [`Diagram`] as CSV tables
//! (`branch.csv`, `special.csv`); list columns hold JSON arrays.

use super::continuation::{Diagram, Point};

fn list(values: impl Iterator<Item = f64>) -> String {
    let items: Vec<String> = values.map(|v| format!("{v:?}")).collect();
    format!("\"[{}]\"", items.join(","))
}

fn optional(value: Option<f64>) -> String {
    value.map_or(String::new(), |v| format!("{v:?}"))
}

/// The columns every point has, after the parameter's.
fn point_columns(p: &Point) -> String {
    let periods = p.periods();
    format!(
        "{:?},{},{},{},{},{:?},{},{:?},{:?},{:?},{},{},{},{},{}",
        p.param,
        p.orbit.stable(),
        p.orbit.n_unstable,
        p.profile.impacts as f64 / periods as f64,
        p.profile.sticks,
        p.orbit.period,
        periods,
        p.profile.peak,
        p.profile.norm,
        p.orbit.multipliers.iter().map(|z| z.norm()).fold(0.0, f64::max),
        optional(p.profile.closest.map(|c| c.gap)),
        optional(p.profile.slowest_impact),
        list(p.profile.section.iter().copied()),
        list(p.orbit.multipliers.iter().map(|z| z.re)),
        list(p.orbit.multipliers.iter().map(|z| z.im)),
    )
}

const POINT_HEADER: &str =
    "stable,n_unstable,impacts_per_period,sticks,period,periods,peak,norm,largest_multiplier,closest_gap,slowest_impact,section,multipliers_re,multipliers_im";

/// `branch.csv`: one row per continuation point.
pub fn branches_csv(d: &Diagram) -> String {
    let mut out = format!("branch,{},{POINT_HEADER},state\n", d.param);
    for b in &d.branches {
        for p in &b.points {
            out.push_str(&format!("{},{},{}\n", b.index, point_columns(p), list(p.orbit.state.iter().copied())));
        }
    }
    out
}

/// `special.csv`: one row per special point.
pub fn special_csv(d: &Diagram) -> String {
    let mut out = format!("type,branch,{},{POINT_HEADER},note\n", d.param);
    for s in &d.special {
        out.push_str(&format!("{},{},{},\"{}\"\n", s.kind.code(), s.branch, point_columns(&s.point), s.note.replace('"', "'")));
    }
    out
}
