//! The branches and special points of a [`Diagram`] as CSV tables
//! (`branch.csv`, `special.csv`); list columns hold JSON arrays.

use super::continuation::{Branch, Diagram, Point, Special};

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

/// `branch.csv`'s header line.
pub fn branch_header(param: &str) -> String {
    format!("branch,{param},{POINT_HEADER},state\n")
}

/// `branch.csv`'s rows of one branch.
pub fn branch_rows(b: &Branch) -> String {
    b.points.iter().map(|p| format!("{},{},{}\n", b.index, point_columns(p), state(p))).collect()
}

/// `special.csv`'s header line.
pub fn special_header(param: &str) -> String {
    format!("type,branch,{param},{POINT_HEADER},state,note\n")
}

/// `special.csv`'s rows of some special points.
pub fn special_rows(special: &[Special]) -> String {
    special.iter().map(|s| format!("{},{},{},{},\"{}\"\n", s.kind.code(), s.branch, point_columns(&s.point), state(&s.point), s.note.replace('"', "'"))).collect()
}

/// The orbit's state `[q; q']` at the section, as a list.
fn state(p: &Point) -> String {
    list(p.orbit.state.iter().copied())
}

/// `branch.csv`: one row per continuation point.
pub fn branches_csv(d: &Diagram) -> String {
    d.branches.iter().fold(branch_header(&d.param), |out, b| out + &branch_rows(b))
}

/// `special.csv`: one row per special point.
pub fn special_csv(d: &Diagram) -> String {
    special_header(&d.param) + &special_rows(&d.special)
}
