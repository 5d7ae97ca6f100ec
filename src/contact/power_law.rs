//! The power-law stop: a nonlinear spring that pushes and never pulls,
//! `F = max(0, K p^n + damping)` with `p` the penetration and the exponent
//! `n` in [1, 3] fixed by the scene: n = 1.5 is Hertz's sphere (DWZ eqs.
//! 2-4), n = 1 a flat punch, n near 1.1 a line contact. The damping is linear `C p'`, or
//! hysteretic in its power-law form (HC75 as calibrated by MO99, LN90):
//! `K p^n * 3 (1 - e) / 2 * p' / v0` and `K p^n * 3 (1 - e^2) / 4 * p' /
//! v0`, with `v0` the approach speed at the onset and `e` the restitution
//! aimed at. The stored energy is `K p^(n+1) / (n+1)`.
//!
//! The force is not linear in the state (but at n = 1 with linear damping,
//! which is the spring-dashpot stop), so its contact phases are integrated
//! (`PhaseTerm::Nonlinear`); its switches are those of every compliant
//! stop: apart, the gap closes: pressed; pressed, the force reaches zero:
//! apart if `p <= 0`, else penetrated without force; penetrated, the force
//! turns positive: pressed again, or the point leaves the surface: apart.

use serde::{Deserialize, Serialize};

use super::{closing, Contact, ContactDamping, ContactLaw, LawOutput, ParamSpec, PhaseTerm, Switch, Watch, COMPLIANT_OUTPUTS, COMPLIANT_STATES};
use crate::solve::Jet;
use crate::units::Unit;

/// Scene schema: `{"type": "power_law", "n": ..., "K": ..., "C": ...,
/// "damping": "linear" | "hunt_crossley" | "lankarani_nikravesh", "e":
/// ...}` (`C` with linear damping, `e` with the other two). `n` is not an
/// FMU parameter: `K`'s unit, N/m^n, follows it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PowerLaw {
    /// The exponent `n` of `K p^n`, in [1, 3].
    #[serde(rename = "n")]
    pub exponent: f64,
    /// `K` of `K p^n` (N/m^n in SI scenes).
    #[serde(rename = "K")]
    pub stiffness: f64,
    /// `C` of the linear damping `C p'` (N s/m).
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

/// The exponents a scene may give.
const EXPONENTS: std::ops::RangeInclusive<f64> = 1.0..=3.0;

impl PowerLaw {
    /// The unclamped force `K p^n + damping` at penetration `p`, rate `pd`,
    /// and its derivatives with respect to `p` and `pd`.
    pub fn raw_force(&self, p: f64, pd: f64, onset_speed: f64) -> (f64, f64, f64) {
        let pp = p.max(0.0);
        let (spring, stiffness) = self.spring(pp);
        let h = self.damping.hysteresis(self.restitution, onset_speed);
        let c = if self.damping.is_linear() { self.damping_coefficient } else { 0.0 };
        (spring * (1.0 + h * pd) + c * pd, stiffness * (1.0 + h * pd), spring * h + c)
    }

    /// `K p^n` and its derivative `n K p^(n-1)` at `p >= 0`.
    fn spring(&self, p: f64) -> (f64, f64) {
        let below = p.powf(self.exponent - 1.0);
        (self.stiffness * below * p, self.exponent * self.stiffness * below)
    }

    /// Elastic energy stored in the stop, `K p^(n+1) / (n+1)`.
    pub fn stored_energy(&self, p: f64) -> f64 {
        let pp = p.max(0.0);
        self.stiffness * pp.powf(self.exponent + 1.0) / (self.exponent + 1.0)
    }
}

impl ContactLaw for PowerLaw {
    fn parameters(&self) -> Vec<ParamSpec> {
        let stiffness = ParamSpec {
            key: "K",
            description: "Stiffness K of the power-law stop '{stop}' (force K p^n + damping, p the penetration, n fixed by the scene)",
            unit: Unit::power_stiffness(self.exponent),
            tunable: true,
        };
        let damping = if self.damping.is_linear() {
            ParamSpec {
                key: "C",
                description: "Linear damping C of the power-law stop '{stop}' (force K p^n + C p', never pulling)",
                unit: Unit::NewtonSecondPerMetre,
                tunable: true,
            }
        } else {
            ParamSpec { key: "e", description: "Restitution the hysteretic damping of the power-law stop '{stop}' aims at", unit: Unit::One, tunable: true }
        };
        vec![stiffness, damping]
    }

    fn validate(&self, path: &str) -> Result<(), String> {
        if !EXPONENTS.contains(&self.exponent) {
            return Err(format!("{path}.n = {:?}: the exponent of K p^n must be in [{}, {}]", self.exponent, EXPONENTS.start(), EXPONENTS.end()));
        }
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

    fn on_zero(&self, contact: Contact, watch: Watch, jet: &Jet, p: f64) -> Switch {
        match (contact, watch) {
            (Contact::Open, Watch::Gap) if closing(jet, true) => Switch::To(Contact::Pressed),
            (Contact::Pressed, Watch::Force) if closing(jet, false) => Switch::To(if p > 0.0 { Contact::Penetrated } else { Contact::Open }),
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
        PowerLaw::raw_force(self, p, pd, onset_speed)
    }

    fn watched_force(&self, p: f64, pd: f64, onset_speed: f64) -> (f64, f64, f64) {
        let h = self.damping.hysteresis(self.restitution, onset_speed);
        super::push_watch(self.damping, self.damping_coefficient, self.stiffness, h, pd, || PowerLaw::raw_force(self, p, pd, onset_speed))
    }

    /// `K p^n` grows as `t^n` at the onset; a linear damping's push may
    /// end inside the surface in a kink (`t^1`).
    fn corner_exponent(&self) -> f64 {
        if self.damping.is_linear() && self.damping_coefficient != 0.0 {
            self.exponent.min(1.0)
        } else {
            self.exponent
        }
    }

    fn spring_force(&self, p: f64) -> (f64, f64) {
        self.spring(p.max(0.0))
    }

    fn stored_energy(&self, contact: Contact, p: f64) -> f64 {
        match contact {
            Contact::Pressed => PowerLaw::stored_energy(self, p),
            _ => 0.0,
        }
    }

    fn energy_left_at_release(&self, p: f64) -> f64 {
        PowerLaw::stored_energy(self, p)
    }

    /// `((n+1) m v^2 / 2 K)^(1/(n+1))`, from `K p^(n+1) / (n+1) = m v^2 / 2`.
    fn depth(&self, speed: f64, inverse_mass: f64) -> f64 {
        let n1 = self.exponent + 1.0;
        (n1 * speed * speed / (2.0 * self.stiffness * inverse_mass)).powf(1.0 / n1)
    }

    fn outputs(&self) -> &'static [LawOutput] {
        COMPLIANT_OUTPUTS
    }

    fn formulas(&self) -> (&'static str, &'static str) {
        ("K p^n + damping", "K p^(n+1) / (n+1)")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::Hertz;

    fn law(n: f64, damping: ContactDamping) -> PowerLaw {
        PowerLaw { exponent: n, stiffness: 3e9, damping_coefficient: if damping.is_linear() { 40.0 } else { 0.0 }, damping, restitution: 0.6 }
    }

    #[test]
    fn derivatives_match_finite_differences() {
        for n in [1.0, 1.1, 1.5, 2.0, 3.0] {
            for damping in [ContactDamping::Linear, ContactDamping::HuntCrossley, ContactDamping::LankaraniNikravesh] {
                let l = law(n, damping);
                let (p, pd, v0) = (2e-5, -0.3, 0.8);
                let (f, dp, dpd) = l.raw_force(p, pd, v0);
                let h = 1e-6;
                let fd_p = (l.raw_force(p * (1.0 + h), pd, v0).0 - l.raw_force(p * (1.0 - h), pd, v0).0) / (2.0 * p * h);
                // The force is affine in pd: a wide difference is exact but for rounding.
                let fd_pd = (l.raw_force(p, pd + 0.1, v0).0 - l.raw_force(p, pd - 0.1, v0).0) / 0.2;
                // Rounding of f over the difference's width bounds the agreement.
                assert!((dp - fd_p).abs() <= 1e-7 * (dp.abs() + f.abs() / p), "n {n} {damping:?}: {dp} vs {fd_p}");
                assert!((dpd - fd_pd).abs() <= 1e-7 * dpd.abs().max(1e-300), "n {n} {damping:?}: {dpd} vs {fd_pd}");
            }
        }
    }

    #[test]
    fn at_one_and_a_half_it_is_the_hertz_law() {
        for damping in [ContactDamping::Linear, ContactDamping::HuntCrossley, ContactDamping::LankaraniNikravesh] {
            let l = law(1.5, damping);
            let hertz = Hertz { stiffness: l.stiffness, damping_coefficient: l.damping_coefficient, damping, restitution: l.restitution };
            for (p, pd) in [(1e-9, 0.7), (2e-5, -0.3), (3e-3, 1.9)] {
                let (a, b) = (l.raw_force(p, pd, 0.8), hertz.raw_force(p, pd, 0.8));
                for (x, y) in [(a.0, b.0), (a.1, b.1), (a.2, b.2)] {
                    assert!((x - y).abs() <= 4.0 * f64::EPSILON * y.abs(), "{damping:?} p {p}: {x} vs {y}");
                }
                let (x, y) = (l.stored_energy(p), hertz.stored_energy(p));
                assert!((x - y).abs() <= 4.0 * f64::EPSILON * y, "{x} vs {y}");
            }
        }
    }

    #[test]
    fn stored_energy_is_the_springs_work() {
        let l = law(1.1, ContactDamping::Linear);
        let p = 3e-4;
        // Simpson on the spring force from 0 to p.
        let m = 2000;
        let h = p / m as f64;
        let work: f64 = (0..=m).map(|i| l.spring(i as f64 * h).0 * if i == 0 || i == m { 1.0 } else if i % 2 == 1 { 4.0 } else { 2.0 }).sum::<f64>() * h / 3.0;
        assert!((work - l.stored_energy(p)).abs() <= 1e-6 * work, "{work} vs {}", l.stored_energy(p));
    }

    #[test]
    fn exponent_outside_one_to_three_is_refused_naming_it() {
        let e = law(3.5, ContactDamping::Linear).validate("stops[1].law").unwrap_err();
        assert!(e.contains("stops[1].law.n = 3.5") && e.contains("[1, 3]"), "{e}");
        assert!(law(1.0, ContactDamping::Linear).validate("x").is_ok());
    }
}
