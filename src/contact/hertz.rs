//! The Hertz stop: a nonlinear spring that pushes and never pulls,
//! `F = max(0, K p^1.5 + damping)` with `p` the penetration (DWZ
//! eqs. 2-4: `F = K gamma^1.5 + C gamma'`), and the damping either
//! DWZ's linear `C p'` or a hysteretic one that vanishes with the
//! penetration and so keeps the force continuous at the onset:
//! - Hunt & Crossley (HC75), as calibrated by Marhefka & Orin (MO99):
//!   `K p^1.5 (1 + 3 (1 - e) / 2 * p' / v0)`;
//! - Lankarani & Nikravesh (LN90): `K p^1.5 (1 + 3 (1 - e^2) / 4 * p' / v0)`,
//!
//! with `v0` the approach speed at the onset and `e` the restitution they
//! aim at. The force is not linear in the state, so its contact phases are
//! integrated (`PhaseTerm::Nonlinear`); the onset is the free flight's gap
//! closing, located exactly like every other law's. Its switches:
//! - apart, the gap closes: pressed;
//! - pressed, the force reaches zero: apart if `p <= 0`, else penetrated
//!   without force (the damping would pull);
//! - penetrated, the force turns positive: pressed again; or the point
//!   leaves the surface: apart.

use serde::{Deserialize, Serialize};

use super::{closing, ContactDamping, COMPLIANT_OUTPUTS, COMPLIANT_STATES, Contact, ContactLaw, LawOutput, ParamSpec, PhaseTerm, Switch, Watch};
use crate::solve::Jet;
use crate::units::{Exponent, Unit};

/// N/m^1.5.
const HERTZ_EXPONENT: Exponent = Exponent::of(1.5);

/// Scene schema: `{"type": "hertz", "K": ..., "C": ..., "damping": "linear"
/// | "hunt_crossley" | "lankarani_nikravesh", "e": ...}` (`C` with linear
/// damping, `e` with the other two).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Hertz {
    /// `K` of `K p^1.5` (N/m^1.5 in SI scenes).
    #[serde(rename = "K")]
    pub stiffness: f64,
    /// `C` of DWZ's linear damping `C p'` (N s/m).
    #[serde(rename = "C", default)]
    pub damping_coefficient: f64,
    #[serde(default, skip_serializing_if = "ContactDamping::is_linear")]
    pub damping: ContactDamping,
    /// The restitution the hysteretic damping aims at.
    #[serde(rename = "e", default = "one")]
    pub restitution: f64,
}

fn one() -> f64 {
    1.0
}

const STIFFNESS: ParamSpec = ParamSpec {
    key: "K",
    description: "Hertz stiffness of stop '{stop}' (force K p^1.5 + damping, p the penetration)",
    unit: Unit::NewtonPerMetrePower(HERTZ_EXPONENT),
    tunable: true,
};

impl Hertz {
    const LINEAR: &'static [ParamSpec] = &[
        STIFFNESS,
        ParamSpec {
            key: "C",
            description: "Linear damping C of the Hertz stop '{stop}' (force K p^1.5 + C p', never pulling)",
            unit: Unit::NewtonSecondPerMetre,
            tunable: true,
        },
    ];
    const HYSTERETIC: &'static [ParamSpec] = &[
        STIFFNESS,
        ParamSpec {
            key: "e",
            description: "Restitution the hysteretic damping of the Hertz stop '{stop}' aims at",
            unit: Unit::One,
            tunable: true,
        },
    ];

    /// The unclamped force `K p^1.5 + damping` at penetration `p > 0`, rate
    /// `pd`, and its derivatives with respect to `p` and `pd`.
    pub fn raw_force(&self, p: f64, pd: f64, onset_speed: f64) -> (f64, f64, f64) {
        let pp = p.max(0.0);
        let root = pp.sqrt();
        let spring = self.stiffness * pp * root;
        let h = self.damping.hysteresis(self.restitution, onset_speed);
        let c = self.damping_coefficient * self.damping.is_linear() as u8 as f64;
        let f = spring * (1.0 + h * pd) + c * pd;
        let df_dp = 1.5 * self.stiffness * root * (1.0 + h * pd);
        let df_dpd = spring * h + c;
        (f, df_dp, df_dpd)
    }

    /// Elastic energy stored in the stop, `2/5 K p^2.5`.
    pub fn stored_energy(&self, p: f64) -> f64 {
        let pp = p.max(0.0);
        0.4 * self.stiffness * pp * pp * pp.sqrt()
    }
}

impl ContactLaw for Hertz {
    fn parameters(&self) -> Vec<ParamSpec> {
        match self.damping {
            ContactDamping::Linear => Self::LINEAR,
            _ => Self::HYSTERETIC,
        }
        .to_vec()
    }

    fn validate(&self, path: &str) -> Result<(), String> {
        self.damping.check_coefficient(path, self.damping_coefficient)
    }

    fn states(&self) -> &'static [Contact] {
        COMPLIANT_STATES
    }

    fn term(&self, contact: Contact) -> PhaseTerm {
        match contact {
            Contact::Pressed | Contact::Penetrated => PhaseTerm::Nonlinear,
            _ => PhaseTerm::None,
        }
    }

    fn watches(&self, contact: Contact) -> &'static [Watch] {
        match contact {
            Contact::Pressed => &[Watch::Force, Watch::Penetration],
            Contact::Penetrated => &[Watch::NegatedForce, Watch::Penetration],
            Contact::Open | Contact::Held => &[Watch::Gap],
        }
    }

    /// The decision at a zero of `watch`; `p` the penetration there.
    fn on_zero(&self, contact: Contact, watch: Watch, jet: &Jet, p: f64) -> Switch {
        match (contact, watch) {
            (Contact::Open, Watch::Gap) if closing(jet, true) => Switch::To(Contact::Pressed),
            (Contact::Pressed, Watch::Force) if closing(jet, false) => {
                if p > 0.0 {
                    Switch::To(Contact::Penetrated)
                } else {
                    Switch::To(Contact::Open)
                }
            }
            (Contact::Pressed | Contact::Penetrated, Watch::Penetration) if closing(jet, false) => Switch::To(Contact::Open),
            (Contact::Penetrated, Watch::NegatedForce) if closing(jet, false) => Switch::To(Contact::Pressed),
            _ => Switch::Stay,
        }
    }

    fn initial_contact(&self, p: f64, pd: f64) -> Contact {
        if p <= 0.0 {
            Contact::Open
        } else if self.watched_force(p, pd, pd.max(0.0)).0 >= 0.0 {
            // The push's sign from the watched function: the force itself
            // rounds to zero at a subnormal penetration (a preload of
            // 1e-300), where a force-free start would be wrong.
            Contact::Pressed
        } else {
            Contact::Penetrated
        }
    }

    fn raw_force(&self, p: f64, pd: f64, onset_speed: f64) -> (f64, f64, f64) {
        Hertz::raw_force(self, p, pd, onset_speed)
    }

    fn watched_force(&self, p: f64, pd: f64, onset_speed: f64) -> (f64, f64, f64) {
        let h = self.damping.hysteresis(self.restitution, onset_speed);
        super::push_watch(self.damping, self.damping_coefficient, self.stiffness, h, pd, || Hertz::raw_force(self, p, pd, onset_speed))
    }

    /// `K p^1.5`'s onset and end (a linear damping's kink at a push ending
    /// inside the surface is taken at the same fraction).
    fn corner_exponent(&self) -> f64 {
        1.5
    }

    fn spring_force(&self, p: f64) -> (f64, f64) {
        let pp = p.max(0.0);
        (self.stiffness * pp * pp.sqrt(), 1.5 * self.stiffness * pp.sqrt())
    }

    fn stored_energy(&self, contact: Contact, p: f64) -> f64 {
        match contact {
            Contact::Pressed => Hertz::stored_energy(self, p),
            _ => 0.0,
        }
    }

    fn energy_left_at_release(&self, p: f64) -> f64 {
        Hertz::stored_energy(self, p)
    }

    /// `(5 m v^2 / 4 K)^(2/5)`, from `2/5 K p^2.5 = m v^2 / 2`.
    fn depth(&self, speed: f64, inverse_mass: f64) -> f64 {
        (1.25 * speed * speed / (self.stiffness * inverse_mass)).powf(0.4)
    }

    fn outputs(&self) -> &'static [LawOutput] {
        COMPLIANT_OUTPUTS
    }

    fn formulas(&self) -> (&'static str, &'static str) {
        ("K p^1.5 + damping", "2/5 K p^2.5")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derivatives_match_finite_differences() {
        for damping in [ContactDamping::Linear, ContactDamping::HuntCrossley, ContactDamping::LankaraniNikravesh] {
            let law = Hertz { stiffness: 3e9, damping_coefficient: 40.0, damping, restitution: 0.6 };
            let (p, pd, v0) = (2e-5, -0.3, 0.8);
            let (_, dp, dpd) = law.raw_force(p, pd, v0);
            let h = 1e-6;
            let fd_p = (law.raw_force(p * (1.0 + h), pd, v0).0 - law.raw_force(p * (1.0 - h), pd, v0).0) / (2.0 * p * h);
            let fd_pd = (law.raw_force(p, pd * (1.0 + h), v0).0 - law.raw_force(p, pd * (1.0 - h), v0).0) / (2.0 * pd * h);
            assert!((dp - fd_p).abs() <= 1e-7 * dp.abs(), "{damping:?}: {dp} vs {fd_p}");
            assert!((dpd - fd_pd).abs() <= 1e-7 * dpd.abs().max(1e-300), "{damping:?}: {dpd} vs {fd_pd}");
        }
    }

    #[test]
    fn hysteretic_force_is_continuous_at_the_onset() {
        for damping in [ContactDamping::HuntCrossley, ContactDamping::LankaraniNikravesh] {
            let law = Hertz { stiffness: 1e9, damping_coefficient: 0.0, damping, restitution: 0.5 };
            assert_eq!(law.raw_force(0.0, 1.0, 1.0).0, 0.0);
        }
        let linear = Hertz { stiffness: 1e9, damping_coefficient: 10.0, damping: ContactDamping::Linear, restitution: 1.0 };
        assert_eq!(linear.raw_force(0.0, 1.0, 1.0).0, 10.0);
    }
}
