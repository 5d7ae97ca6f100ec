//! The modal coefficient-of-restitution impact rule (VSM12 eqs. 25-28;
//! WB00 eq. 6), for one or several simultaneous contact points.
//!
//! An impulse `P_i` at each point changes the modal velocities by
//! `qd+ = qd- + sum_i w_i P_i` (eq. 25) so that the contact velocity
//! becomes `w_i . qd+ = -R_i w_i . qd-` (eq. 18). With one point this is
//! eq. 28. Points held by sticking take part with `R = 0`.

use nalgebra::{DMatrix, DVector};

use serde::{Deserialize, Serialize};

use super::{Contact, ContactLaw, LawOutput, ParamSpec, PhaseTerm, RangeKind, StopOutput, Switch, Watch};
use crate::variables::OutputType;
use crate::units::Unit;
use crate::solve::events::{tendency_from, Tendency};
use crate::solve::Jet;

/// The rigid stop of VSM12: impacts by the restitution rule, chatter
/// ended by the threshold `eps` (VSM12 sec. 2.2), then sticking.
/// Scene schema: `{"type": "restitution", "R": ..., "eps": ...}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Restitution {
    #[serde(rename = "R")]
    pub restitution: f64,
    /// An impact sooner than this after the previous one of a chatter
    /// sequence ends the chatter with `R = 0`.
    #[serde(rename = "eps")]
    pub chatter_eps: f64,
}

impl Restitution {
    pub const PARAMETERS: &'static [ParamSpec] = &[
        ParamSpec { key: "R", description: "Coefficient of restitution at stop '{stop}'", unit: Unit::One, range: RangeKind::Unit, tunable: true },
        ParamSpec {
            key: "eps",
            description: "Chatter threshold at stop '{stop}': an impact sooner than eps after the previous one ends the chatter with R = 0 and starts sticking",
            unit: Unit::Second,
            range: RangeKind::Duration,
            tunable: true,
        },
    ];

    /// The coefficient an impact at time `t` uses: `R`, or 0 when it ends a
    /// chatter sequence (sooner than `eps` after the previous impact, or
    /// too slow for `R` times its speed to be told from rounding,
    /// `negligible`).
    pub fn effective(&self, t: f64, previous_impact: Option<f64>, speed: f64, negligible: f64) -> f64 {
        let since = previous_impact.map(|p| t - p);
        let resolution = 16.0 * f64::EPSILON * t.abs().max(f64::MIN_POSITIVE);
        let chatter = since.is_some_and(|dt| dt < self.chatter_eps || dt <= resolution) || self.restitution * speed <= negligible;
        if chatter {
            0.0
        } else {
            self.restitution
        }
    }
}

const OUTPUTS: &[LawOutput] = &[
    LawOutput { what: StopOutput::Impacts, suffix: "impacts", description: "Number of impacts at stop '{stop}' since the start", unit: Unit::One, kind: OutputType::Integer, discrete: true },
    LawOutput {
        what: StopOutput::LastImpact,
        suffix: "t_last_impact",
        description: "Exact time of the latest impact at stop '{stop}' (the start time before the first)",
        unit: Unit::Second,
        kind: OutputType::Real,
        discrete: true,
    },
    LawOutput { what: StopOutput::Sticking, suffix: "sticking", description: "Whether the structure is stuck to stop '{stop}'", unit: Unit::One, kind: OutputType::Boolean, discrete: true },
    LawOutput {
        what: StopOutput::Sticks,
        suffix: "sticks",
        description: "Number of times the structure stuck to stop '{stop}' since the start",
        unit: Unit::One,
        kind: OutputType::Integer,
        discrete: true,
    },
    LawOutput {
        what: StopOutput::StuckTime,
        suffix: "stuck_time",
        description: "Total time the structure has been stuck to stop '{stop}' since the start (exact, the current hold included)",
        unit: Unit::Second,
        kind: OutputType::Real,
        discrete: false,
    },
    LawOutput {
        what: StopOutput::Reaction,
        suffix: "lambda",
        description: "Reaction of stop '{stop}' while sticking (VSM12 eq. 33; <= 0 for a stop on the +w side), else 0",
        unit: Unit::Newton,
        kind: OutputType::Real,
        discrete: false,
    },
];

impl ContactLaw for Restitution {
    fn parameters(&self) -> &'static [ParamSpec] {
        Self::PARAMETERS
    }

    fn states(&self) -> &'static [Contact] {
        &[Contact::Open, Contact::Held]
    }

    fn term(&self, contact: Contact) -> PhaseTerm {
        match contact {
            Contact::Held => PhaseTerm::Constraint,
            _ => PhaseTerm::None,
        }
    }

    fn watches(&self, contact: Contact) -> &'static [Watch] {
        match contact {
            Contact::Held => &[Watch::Reaction],
            _ => &[Watch::Gap],
        }
    }

    fn on_zero(&self, contact: Contact, watch: Watch, jet: &Jet, _p: f64) -> Switch {
        match (contact, watch) {
            // The reaction already pulls (after a change of load), or is
            // about to: release. A reaction resting at zero (no load) keeps
            // the structure held.
            (Contact::Held, _) => {
                if jet.d[0] < -jet.noise[0] || tendency_from(jet, 1) == Tendency::Closing {
                    Switch::To(Contact::Open)
                } else {
                    Switch::Stay
                }
            }
            (_, _) if jet.d[1] < -jet.noise[1] => Switch::Impact,
            (_, _) if jet.d[1] <= jet.noise[1] => match tendency_from(jet, 2) {
                // At rest on the stop with nothing pushing either way: held
                // with zero reaction until a load decides.
                Tendency::Closing | Tendency::Resting => Switch::Stick,
                Tendency::Opening => Switch::Graze,
            },
            _ => Switch::Stay,
        }
    }

    fn initial_contact(&self, _p: f64, _pd: f64) -> Contact {
        Contact::Open
    }

    fn rigid(&self) -> bool {
        true
    }

    fn restitution(&self, t: f64, previous_impact: Option<f64>, speed: f64, negligible: f64) -> Option<f64> {
        Some(self.effective(t, previous_impact, speed, negligible))
    }

    fn outputs(&self) -> &'static [LawOutput] {
        OUTPUTS
    }
}

/// One contact point taking part in an impact.
#[derive(Clone, Debug)]
pub struct ImpactRow<'a> {
    /// Shape vector `w_j = W_j(x_c)`.
    pub w: &'a DVector<f64>,
    /// Coefficient of restitution for this point (0 for held points).
    pub restitution: f64,
    /// +1 if the stop limits `w . q` from above, -1 from below: the
    /// impulse on the beam must have the sign of `-side`.
    pub side: f64,
}

/// Applies the impact rule in place and writes the impulses, one per row,
/// into `impulses`. Points whose impulse would pull on the beam (only
/// possible for held points) are dropped and the rest solved again; their
/// impulse is 0.
pub fn apply_impact(qd: &mut DVector<f64>, rows: &[ImpactRow], impulses: &mut Vec<f64>) {
    impulses.clear();
    if let [row] = rows {
        // One point: eq. 28 directly, `P = -(1 + R) w . qd- / (w . w)`.
        let p = -(1.0 + row.restitution) * row.w.dot(qd) / row.w.dot(row.w);
        qd.axpy(p, row.w, 1.0);
        impulses.push(p);
        return;
    }
    impulses.resize(rows.len(), 0.0);
    let mut active: Vec<bool> = vec![true; rows.len()];
    let before = qd.clone();
    loop {
        let idx: Vec<usize> = (0..rows.len()).filter(|&i| active[i]).collect();
        let m = idx.len();
        impulses.iter_mut().for_each(|p| *p = 0.0);
        if m == 0 {
            qd.copy_from(&before);
            return;
        }
        let gram = DMatrix::from_fn(m, m, |a, b| rows[idx[a]].w.dot(rows[idx[b]].w));
        let rhs = DVector::from_fn(m, |a, _| {
            let r = &rows[idx[a]];
            -(1.0 + r.restitution) * r.w.dot(&before)
        });
        let p = gram.lu().solve(&rhs).unwrap_or_else(|| DVector::zeros(m));
        let mut after = before.clone();
        for (a, &i) in idx.iter().enumerate() {
            after.axpy(p[a], rows[i].w, 1.0);
            impulses[i] = p[a];
        }
        let pulling: Vec<usize> = idx.iter().copied().filter(|&i| impulses[i] * rows[i].side > 0.0).collect();
        if pulling.is_empty() || m == 1 {
            qd.copy_from(&after);
            return;
        }
        for i in pulling {
            active[i] = false;
        }
    }
}

/// Kinetic energy lost by a single-point impact:
/// `(1 - R^2) (w . qd-)^2 / (2 w . w)` (Kelvin's impact loss with the modal restitution rule, VSM12 eq. 28).
pub fn energy_loss(w: &DVector<f64>, qd_before: &DVector<f64>, restitution: f64) -> f64 {
    let v = w.dot(qd_before);
    (1.0 - restitution * restitution) * v * v / (2.0 * w.dot(w))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::dvector;

    #[test]
    fn single_point_rule_is_eq_28() {
        let w = dvector![1.1, 0.3, -0.8];
        let mut qd = dvector![2.0, -1.0, 0.5];
        let before = qd.clone();
        apply_impact(&mut qd, &[ImpactRow { w: &w, restitution: 0.7, side: 1.0 }], &mut Vec::new());
        assert!((w.dot(&qd) + 0.7 * w.dot(&before)).abs() < 1e-14);
        let expected = &before - &w * ((1.0 + 0.7) * w.dot(&before) / w.dot(&w));
        assert!((qd - expected).norm() < 1e-14);
    }

    #[test]
    fn energy_loss_matches_kinetic_energy_difference() {
        let w = dvector![1.1, 0.3, -0.8];
        let mut qd = dvector![2.0, -1.0, 0.5];
        let before = qd.clone();
        apply_impact(&mut qd, &[ImpactRow { w: &w, restitution: 0.4, side: 1.0 }], &mut Vec::new());
        let lost = 0.5 * (before.norm_squared() - qd.norm_squared());
        assert!((lost - energy_loss(&w, &before, 0.4)).abs() < 1e-14);
    }
}
