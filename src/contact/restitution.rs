//! The rigid stop with a coefficient of restitution (VSM12 eqs. 18, 25-28;
//! WB00 eq. 6): impacts, chatter ended by a threshold, sticking. The
//! impulses of simultaneous impacts are solved together in
//! [`super::impact`].

use serde::{Deserialize, Serialize};

use super::{Contact, ContactLaw, LawOutput, ParamSpec, PhaseTerm, StopOutput, Switch, Watch};
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
        ParamSpec { key: "R", description: "Coefficient of restitution at stop '{stop}'", unit: Unit::One, tunable: true },
        ParamSpec {
            key: "eps",
            description: "Chatter threshold at stop '{stop}': an impact sooner than eps after the previous one ends the chatter with R = 0 and starts sticking",
            unit: Unit::Second,
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
    LawOutput { what: StopOutput::Impacts, suffix: "impacts", description: "Number of impacts at stop '{stop}' since the start", unit: Unit::One, kind: OutputType::Integer, discrete: true, surface: None },
    LawOutput {
        what: StopOutput::LastImpact,
        suffix: "t_last_impact",
        description: "Exact time of the latest impact at stop '{stop}' (the start time before the first)",
        unit: Unit::Second,
        kind: OutputType::Real,
        discrete: true,
        surface: None,
    },
    LawOutput { what: StopOutput::Sticking, suffix: "sticking", description: "Whether the structure is stuck to stop '{stop}'", unit: Unit::One, kind: OutputType::Boolean, discrete: true, surface: None },
    LawOutput {
        what: StopOutput::Sticks,
        suffix: "sticks",
        description: "Number of times the structure stuck to stop '{stop}' since the start",
        unit: Unit::One,
        kind: OutputType::Integer,
        discrete: true,
        surface: None,
    },
    LawOutput {
        what: StopOutput::StuckTime,
        suffix: "stuck_time",
        description: "Total time the structure has been stuck to stop '{stop}' since the start (exact, the current hold included)",
        unit: Unit::Second,
        kind: OutputType::Real,
        discrete: false,
        surface: None,
    },
    LawOutput {
        what: StopOutput::Reaction,
        suffix: "lambda",
        description: "Reaction of stop '{stop}' while sticking (VSM12 eq. 33; <= 0 for a stop on the +w side), else 0",
        unit: Unit::Newton,
        kind: OutputType::Real,
        discrete: false,
        surface: None,
    },
];

impl ContactLaw for Restitution {
    fn parameters(&self) -> Vec<ParamSpec> {
        Self::PARAMETERS.to_vec()
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
            (_, _) if jet.d[1] <= jet.noise[1] || opens_within_noise(jet) => match tendency_from(jet, 2) {
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

/// Whether a gap at its zero, opening at `h'` but pressed shut at
/// `h'' < 0`, opens by less than its own rounding: the most it rises,
/// `h'^2 / (2 |h''|)`, stays within the value's noise, so the opening is
/// the rate's rounding, not a motion. A beam at rest on the stop, pressed
/// onto it by a preloaded spring-dashpot stop, read `h' = 5e-17` against
/// a noise of 3e-17 (its terms cancel through the coupled phase's basis):
/// taken as leaving, its zero was found again at the same instant until
/// `solver.max_events_per_step`.
fn opens_within_noise(jet: &Jet) -> bool {
    let (rate, curvature) = (jet.d[1], jet.d[2]);
    curvature < -jet.noise[2] && rate * rate <= 2.0 * jet.noise[0] * -curvature
}
