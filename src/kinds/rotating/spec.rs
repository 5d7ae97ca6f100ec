//! The scene of a beam on a rotating hub (SI units): the beam, the hub and
//! its drive, an optional fixed plane the tip may strike, the initial state
//! and the solver's tolerance. [`RotatingSpec::validate`] refuses a scene
//! with a message naming the field, its value and the allowed range.
//!
//! ```json
//! { "name": "RotatingBeam",
//!   "beam": { "length": 1.0, "mass_per_length": 0.86884, "bending_stiffness": 541.26 },
//!   "n_modes": 6, "order": "first", "hub_inertia": 0.05,
//!   "surface": { "normal": [0, -1], "point": [1, 0],
//!                "law": { "type": "hertz", "K": 7.6e9, "damping": "lankarani_nikravesh", "e": 0.8 } },
//!   "initial": { "theta_dot": 2.0 },
//!   "hub": "torque" }
//! ```
//! `beam` takes either `mass_per_length` and `bending_stiffness` or `E`,
//! `I`, `rho`, `A`. `hub` is `"torque"` (a torque input, 0 until set) or
//! `{"prescribed": {"type": "spin_up", "omega_s": .., "T": ..}}` (Kane, Ryan &
//! Banerjee: `theta'(t) = omega_s / T (t - T / (2 pi) sin(2 pi t / T))` for
//! `t < T`, then `omega_s`; `theta(t) = theta_0 + int_0^t theta'`) or
//! `{"prescribed": {"type": "harmonic", "A": .., "Omega": ..}}` (a swing
//! `theta(t) = theta_0 + A sin(Omega t)`, `theta'(0) = A Omega`); `theta_0`
//! is `initial.theta` in both.

use serde::{Deserialize, Serialize};

use crate::contact::Law;
use crate::units::Unit;
use crate::variables::{Experiment, Range};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RotatingSpec {
    pub name: String,
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub description: String,
    pub beam: BeamSpec,
    pub n_modes: usize,
    #[serde(default)]
    pub order: OrderSpec,
    /// `J_h` about the axis, kg m^2.
    pub hub_inertia: f64,
    /// From the axis to the clamp, m.
    #[serde(default)]
    pub hub_radius: f64,
    /// `g` along -Y, in the plane of rotation, m/s^2.
    #[serde(default)]
    pub gravity: f64,
    /// Damping ratio `zeta` of every mode.
    #[serde(default)]
    pub modal_damping: f64,
    /// The fixed plane the tip may strike; none: no contact.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub surface: Option<SurfaceSpec>,
    #[serde(default)]
    pub initial: InitialSpec,
    #[serde(default)]
    pub hub: HubDrive,
    #[serde(default)]
    pub solver: SolverSpec,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub experiment: Option<Experiment>,
}

/// The beam's section: `mass_per_length` and `bending_stiffness`, or `E`, `I`, `rho`, `A`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BeamSpec {
    pub length: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass_per_length: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bending_stiffness: Option<f64>,
    #[serde(default, rename = "E", skip_serializing_if = "Option::is_none")]
    pub youngs_modulus: Option<f64>,
    #[serde(default, rename = "I", skip_serializing_if = "Option::is_none")]
    pub second_moment: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rho: Option<f64>,
    #[serde(default, rename = "A", skip_serializing_if = "Option::is_none")]
    pub area: Option<f64>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum OrderSpec {
    /// Geometric stiffening kept (the default).
    #[default]
    First,
    /// The linear floating-frame model (diverges under fast spin-up).
    Zeroth,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SurfaceSpec {
    /// Normal to the free side (need not be unit).
    pub normal: [f64; 2],
    /// A point of the plane, m.
    pub point: [f64; 2],
    /// Any compliant contact law (the scene's `law` object of a stop).
    pub law: Law,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct InitialSpec {
    #[serde(default)]
    pub theta: f64,
    #[serde(default)]
    pub theta_dot: f64,
    /// Modal coordinates (m); empty: all zero.
    #[serde(default, rename = "B", skip_serializing_if = "Vec::is_empty")]
    pub b: Vec<f64>,
    #[serde(default, rename = "B_dot", skip_serializing_if = "Vec::is_empty")]
    pub b_dot: Vec<f64>,
}

/// What turns the hub.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum HubDrive {
    /// A torque input (N m), held over each communication step; 0 until set.
    #[default]
    Torque,
    /// The hub angle follows a profile whatever the beam does.
    Prescribed(Profile),
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum Profile {
    /// Kane, Ryan & Banerjee's spin-up to `omega_s` (rad/s) over `T` (s).
    SpinUp {
        omega_s: f64,
        #[serde(rename = "T")]
        duration: f64,
    },
    /// A harmonic swing about `initial.theta`: `theta(t) = theta_0 + A
    /// sin(Omega t)` (rad, rad/s).
    Harmonic {
        #[serde(rename = "A")]
        amplitude: f64,
        #[serde(rename = "Omega")]
        omega: f64,
    },
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolverSpec {
    /// Relative local error of the integration.
    #[serde(default = "default_tolerance")]
    pub tolerance: f64,
    /// The integrator: `auto` (the default: `exponential` from 16 modes
    /// on, `dop853` below), `exponential`, `dop853` or `radau`.
    #[serde(default)]
    pub method: super::stepper::Method,
    /// Events allowed within one call to `advance_to`.
    #[serde(default = "default_max_events")]
    pub max_events_per_step: u64,
    /// Integration steps allowed within one call to `advance_to`: a bound
    /// on the time one call takes, against runaway work only. Default
    /// ([`SolverSpec::step_budget`]): about two seconds of steps.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_steps_per_step: Option<u64>,
}

impl Default for SolverSpec {
    fn default() -> Self {
        SolverSpec { tolerance: default_tolerance(), method: Default::default(), max_events_per_step: default_max_events(), max_steps_per_step: None }
    }
}

fn default_tolerance() -> f64 {
    1e-10
}

/// The exponential integrator's rtol over the tolerance asked
/// ([`SolverSpec::integration_rtol`]): 1 from 1e-4 up, 3 from 1e-6 down,
/// log-linear between.
fn exponential_factor(asked: f64) -> f64 {
    let decades_below = (-4.0 - asked.log10()).clamp(0.0, 2.0);
    3f64.powf(decades_below / 2.0)
}

fn default_max_events() -> u64 {
    10_000
}

impl SolverSpec {
    /// The relative tolerance the integrator is given for `solver.tolerance`
    /// The exponential integrator's error (its steps held
    /// short of each push's end, [`super::sim`]) is about a hundredth of
    /// its rtol from 1e-6 down at 6 to 64 modes, and up to its rtol from
    /// 1e-4 up: it is given the tolerance asked from 1e-4 up, three times
    /// it from 1e-6 down (blended between; scripts/rotating-scaling: the
    /// error then within 2 times the tolerance at 6, 24, 32 and 64 modes
    /// from 1e-3 to 1e-10; at 10 modes 15 times at 1e-5, where a grazing
    /// pair of contacts comes and goes with the last digits, 51 to 61
    /// events), no looser than the range's top.
    /// DOP853's and Radau's local-error control lets the error grow to 10
    /// to 300 times their rtol over a run with contacts
    /// (report/shared_peer), so they are given a hundredth of it, no
    /// tighter than the range's floor.
    pub fn integration_rtol(&self) -> f64 {
        match self.method.resolve() {
            super::stepper::Method::Exponential => (exponential_factor(self.tolerance) * self.tolerance).min(TOLERANCE_RANGE.max),
            _ => (0.01 * self.tolerance).max(TOLERANCE_RANGE.min),
        }
    }

    /// The integration steps one call may take: `max_steps_per_step`, or
    /// by default about two seconds of steps at `n_modes`. A DOP853 step
    /// with its event search costs at most about 12 + 0.03 (N+1)^2 us
    /// (DWZ: 4 us at 6 modes, 35 us at 32; contact-heavy random parameters
    /// up to 16 us at 6), a Radau step about ten times that, an
    /// exponential one about 4 + 0.008 (N+1)^2 us (DWZ: 13 us at 32
    /// modes, 39 us at 64): 148 000 DOP853 steps at 6 modes, 44 000 at
    /// 32; 157 000 exponential steps at 32 modes, 53 000 at 64. The DWZ
    /// scene's 0.05 s takes 500 to 2 000 steps at 6 modes, 1 000 to
    /// 25 000 at 32 (tolerance 1e-3 to 1e-13).
    pub fn step_budget(&self, n_modes: usize) -> u64 {
        self.max_steps_per_step.unwrap_or_else(|| {
            let products = ((n_modes + 1) * (n_modes + 1)) as f64;
            let micros = match self.method.resolve() {
                super::stepper::Method::Radau => 10.0 * (12.0 + 0.03 * products),
                super::stepper::Method::Exponential => 4.0 + 0.008 * products,
                _ => 12.0 + 0.03 * products,
            };
            (2e6 / micros) as u64
        })
    }
}

/// Allowed ranges (the messages quote them).
pub const N_MODES_MAX: usize = 100;
/// Hub speeds up to this many times the beam's first bending frequency
/// (the first-order model stays valid far beyond the divergence of the
/// zeroth-order one near 1x; past this, centrifugal stiffening makes the
/// bending modes too stiff to resolve at the rounding of the angle).
pub const SPEED_LIMIT_RATIO: f64 = 100.0;
/// With a surface, hub speeds up to this many times the first bending
/// frequency: a tip striking at `omega_1 (R + L)` bends the beam by about
/// its own length, the end of the first-order model (faster strikes
/// leave it, and its mass matrix loses definiteness).
pub const IMPACT_SPEED_LIMIT_RATIO: f64 = 1.0;
/// Hub angles (initial or prescribed start) within +-this, rad: the tip
/// position keeps a resolution of about 1e-12 of the beam's length.
pub const ANGLE_LIMIT: f64 = 1e4;
/// Hub torques up to this many times `J_b omega_1^2` (`J_b` the beam's
/// inertia about its root): the hub's angular acceleration is then at most
/// `0.1 omega_1^2` whatever `J_h`, which deflects the tip statically by
/// `(11/120) mu alpha L^5 / EI = 1.13 alpha L / omega_1^2`, about a tenth
/// of the beam's length (the first-order model's own scale).
pub const TORQUE_LIMIT_RATIO: f64 = 0.1;
/// Hub inertia, hub radius and gravity up to these multiples of the
/// beam's inertia about its root, its length and 9.81 m/s^2.
pub const HUB_INERTIA_MAX_RATIO: f64 = 1e12;
pub const HUB_RADIUS_MAX_RATIO: f64 = 1e3;
pub const GRAVITY_MAX: f64 = 9.81e3;
/// Spin-up durations from this fraction of the first bending period up to
/// this many periods (beyond, the profile's `(2 pi / T)^2` underflows long
/// before any motion shows).
pub const SPIN_DURATION_MIN_RATIO: f64 = 1e-3;
pub const SPIN_DURATION_MAX_RATIO: f64 = 1e6;
/// Swing frequencies of a harmonic hub up to this many times the first
/// bending frequency (as hub speeds, [`SPEED_LIMIT_RATIO`]): faster, the
/// forcing outruns every mode a run resolves.
pub const SWING_FREQUENCY_MAX_RATIO: f64 = 100.0;
/// Surface damping up to the critical damping of the beam's whole mass on
/// the highest mode's frequency, times this (as the modal stops).
pub const DAMPING_MAX_RATIO: f64 = 1e3;
pub const TOLERANCE_RANGE: Range = Range { min: 1e-13, max: 1e-3, min_open: false, max_open: false };
pub const STIFFNESS_RANGE: Range = Range { min: 0.0, max: 1e16, min_open: true, max_open: false };
const POSITIVE: Range = Range::POSITIVE;
const ANY: Range = Range::ANY;

impl RotatingSpec {
    pub fn from_json(text: &str) -> Result<Self, String> {
        let spec: RotatingSpec = serde_json::from_str(text).map_err(|e| format!("rotating scene: {e}"))?;
        spec.validate()?;
        Ok(spec)
    }

    /// `(mu, EI)` from whichever description the beam has (after `validate`).
    pub fn section(&self) -> (f64, f64) {
        let b = &self.beam;
        match (b.mass_per_length, b.bending_stiffness) {
            (Some(mu), Some(ei)) => (mu, ei),
            _ => (
                b.rho.unwrap_or(f64::NAN) * b.area.unwrap_or(f64::NAN),
                b.youngs_modulus.unwrap_or(f64::NAN) * b.second_moment.unwrap_or(f64::NAN),
            ),
        }
    }

    /// First clamped-free bending frequency of the beam, `1.8751^2
    /// sqrt(EI / (mu L^4))`, rad/s (no spin).
    pub fn first_bending_frequency(&self) -> f64 {
        let (mu, ei) = self.section();
        1.875_104_068_711_961_f64.powi(2) * (ei / (mu * self.beam.length.powi(4))).sqrt()
    }

    /// The rigid beam's inertia about its root, `mu L^3 / 3`, kg m^2.
    pub fn beam_inertia(&self) -> f64 {
        let (mu, _) = self.section();
        mu * self.beam.length.powi(3) / 3.0
    }

    /// Allowed hub inertias: positive for a torque-driven hub (at J_h = 0
    /// the mass matrix is near-singular), any for a prescribed one.
    pub fn hub_inertia_range(&self) -> Range {
        let max = HUB_INERTIA_MAX_RATIO * self.beam_inertia();
        match self.hub {
            HubDrive::Torque => Range { min: 0.0, max, min_open: true, max_open: false },
            HubDrive::Prescribed(_) => Range::closed(0.0, max),
        }
    }

    pub fn hub_radius_range(&self) -> Range {
        Range::closed(0.0, HUB_RADIUS_MAX_RATIO * self.beam.length)
    }

    pub fn gravity_range(&self) -> Range {
        Range::closed(0.0, GRAVITY_MAX)
    }

    /// The suggested run (the scene's `experiment`, or 1 s in steps of 1 ms).
    pub fn experiment(&self) -> Experiment {
        self.experiment.clone().unwrap_or(Experiment { start: 0.0, stop: 1.0, step: 1e-3 })
    }

    /// The allowed range of a surface law's parameter, by its unit:
    /// ratios in [0, 1], damping coefficients, and stiffnesses of any
    /// exponent (and durations) in one wide range.
    pub fn law_range(&self, unit: Unit) -> Range {
        match unit {
            Unit::One => Range::UNIT,
            Unit::NewtonSecondPerMetre => self.damping_range(),
            _ => STIFFNESS_RANGE,
        }
    }

    /// Allowed initial hub speeds and spin-up rates.
    pub fn speed_range(&self) -> Range {
        let ratio = if self.surface.is_some() { IMPACT_SPEED_LIMIT_RATIO } else { SPEED_LIMIT_RATIO };
        let w = ratio * self.first_bending_frequency();
        Range::closed(-w, w)
    }

    /// Allowed linear surface damping `C`: up to `DAMPING_MAX_RATIO` times
    /// the critical damping `2 m omega` of the beam's mass `mu L` on the
    /// frequency `((N + 1) pi)^2 sqrt(EI / (mu L^4))` above its highest mode.
    pub fn damping_range(&self) -> Range {
        let (mu, ei) = self.section();
        let l = self.beam.length;
        let omega_high = ((self.n_modes as f64 + 1.0) * std::f64::consts::PI).powi(2) * (ei / (mu * l.powi(4))).sqrt();
        Range::closed(0.0, 2.0 * DAMPING_MAX_RATIO * mu * l * omega_high)
    }

    pub fn angle_range(&self) -> Range {
        Range::closed(-ANGLE_LIMIT, ANGLE_LIMIT)
    }

    /// Allowed hub torques (the input), from the beam alone (not from a parameter).
    pub fn torque_range(&self) -> Range {
        let t = TORQUE_LIMIT_RATIO * self.beam_inertia() * self.first_bending_frequency().powi(2);
        Range::closed(-t, t)
    }

    /// Allowed spin-up durations.
    pub fn spin_duration_range(&self) -> Range {
        let period = std::f64::consts::TAU / self.first_bending_frequency();
        Range::closed(SPIN_DURATION_MIN_RATIO * period, SPIN_DURATION_MAX_RATIO * period)
    }

    /// Allowed swing amplitudes of a harmonic hub, rad: the angle's range.
    pub fn swing_amplitude_range(&self) -> Range {
        Range::closed(0.0, ANGLE_LIMIT)
    }

    /// Allowed swing frequencies of a harmonic hub, rad/s (the peak speed
    /// `A Omega` is checked against [`Self::speed_range`] besides).
    pub fn swing_frequency_range(&self) -> Range {
        Range { min: 0.0, max: SWING_FREQUENCY_MAX_RATIO * self.first_bending_frequency(), min_open: true, max_open: false }
    }

    /// Checks every field; the message names the field, its value and the allowed range.
    pub fn validate(&self) -> Result<(), String> {
        let check = |range: Range, what: &str, v: f64| range.check(what, v).map_err(|e| format!("rotating scene '{}': {e}", self.name));
        let fail = |m: String| Err(format!("rotating scene '{}': {m}", self.name));
        check(POSITIVE, "beam.length", self.beam.length)?;
        let b = &self.beam;
        let direct = [("beam.mass_per_length", b.mass_per_length), ("beam.bending_stiffness", b.bending_stiffness)];
        let material = [("beam.E", b.youngs_modulus), ("beam.I", b.second_moment), ("beam.rho", b.rho), ("beam.A", b.area)];
        let given = |set: &[(&str, Option<f64>)]| set.iter().filter(|(_, v)| v.is_some()).count();
        match (given(&direct), given(&material)) {
            (2, 0) => direct.iter().try_for_each(|(w, v)| check(POSITIVE, w, v.unwrap_or(f64::NAN)))?,
            (0, 4) => material.iter().try_for_each(|(w, v)| check(POSITIVE, w, v.unwrap_or(f64::NAN)))?,
            _ => {
                return fail(
                    "beam: give either mass_per_length and bending_stiffness, or E, I, rho and A (all four), not a mix".into(),
                )
            }
        }
        if !(1..=N_MODES_MAX).contains(&self.n_modes) {
            return fail(format!("n_modes = {}: allowed range is [1, {N_MODES_MAX}]", self.n_modes));
        }
        match self.hub {
            HubDrive::Torque => {
                if !self.hub_inertia_range().contains(self.hub_inertia) {
                    return fail(format!(
                        "hub_inertia = {:?}: allowed range is {} with a torque-driven hub: at J_h = 0 the clamped-free \
                         modes nearly span the rigid rotation and the mass matrix J(z) is near-singular (it turns \
                         indefinite at millimetre deflections); give the hub's inertia or prescribe its motion",
                        self.hub_inertia,
                        self.hub_inertia_range()
                    ));
                }
            }
            HubDrive::Prescribed(Profile::SpinUp { omega_s, duration }) => {
                check(self.hub_inertia_range(), "hub_inertia", self.hub_inertia)?;
                check(self.speed_range(), "hub.prescribed.omega_s", omega_s)?;
                check(self.spin_duration_range(), "hub.prescribed.T", duration)?;
                if self.initial.theta_dot != 0.0 {
                    return fail(format!(
                        "initial.theta_dot = {:?}: a prescribed hub follows its profile (theta_dot(0) = 0 for spin_up); allowed value 0",
                        self.initial.theta_dot
                    ));
                }
            }
            HubDrive::Prescribed(Profile::Harmonic { amplitude, omega }) => {
                check(self.hub_inertia_range(), "hub_inertia", self.hub_inertia)?;
                check(self.swing_amplitude_range(), "hub.prescribed.A", amplitude)?;
                check(self.swing_frequency_range(), "hub.prescribed.Omega", omega)?;
                let (theta0, speeds) = (self.initial.theta, self.speed_range());
                if (theta0.abs() + amplitude).is_finite() && theta0.abs() + amplitude > ANGLE_LIMIT {
                    return fail(format!(
                        "hub.prescribed.A = {amplitude:?}: the swing reaches |initial.theta| + A = {:?} rad; allowed range of A \
                         with initial.theta = {theta0:?} is [0, {:?}] (angles within +-{ANGLE_LIMIT})",
                        theta0.abs() + amplitude,
                        (ANGLE_LIMIT - theta0.abs()).max(0.0)
                    ));
                }
                if amplitude * omega > speeds.max {
                    return fail(format!(
                        "hub.prescribed.Omega = {omega:?}: the peak hub speed A Omega = {:?} rad/s exceeds the speed limit {:?} rad/s{}; \
                         allowed range of Omega with A = {amplitude:?} is (0, {:?}]",
                        amplitude * omega,
                        speeds.max,
                        if self.surface.is_some() { " (omega_1 with a surface)" } else { "" },
                        speeds.max / amplitude
                    ));
                }
                if self.initial.theta_dot != 0.0 {
                    return fail(format!(
                        "initial.theta_dot = {:?}: a prescribed hub follows its profile (theta_dot(0) = A Omega = {:?} for harmonic); \
                         allowed value 0 (leave it out)",
                        self.initial.theta_dot,
                        amplitude * omega
                    ));
                }
            }
        }
        check(self.hub_radius_range(), "hub_radius", self.hub_radius)?;
        check(self.gravity_range(), "gravity", self.gravity)?;
        check(Range::closed(0.0, 10.0), "modal_damping", self.modal_damping)?;
        if let Some(s) = &self.surface {
            check(ANY, "surface.normal[0]", s.normal[0])?;
            check(ANY, "surface.normal[1]", s.normal[1])?;
            if s.normal[0] == 0.0 && s.normal[1] == 0.0 {
                return fail("surface.normal = [0, 0]: a normal needs a non-zero length".into());
            }
            check(ANY, "surface.point[0]", s.point[0])?;
            check(ANY, "surface.point[1]", s.point[1])?;
            if s.law.rigid() {
                return fail("surface.law: a rigid law cannot be integrated; give a compliant one".into());
            }
            s.law.validate("surface.law").map_err(|m| format!("rotating scene '{}': {m}", self.name))?;
            let values = serde_json::to_value(&s.law).expect("a law always serialises");
            for p in s.law.parameters() {
                let v = crate::fields::get(&values, p.key).unwrap_or(f64::NAN);
                check(self.law_range(p.unit), &format!("surface.law.{}", p.key), v)?;
            }
        }
        check(self.angle_range(), "initial.theta", self.initial.theta)?;
        check(self.speed_range(), "initial.theta_dot", self.initial.theta_dot)?;
        for (what, v) in [("initial.B", &self.initial.b), ("initial.B_dot", &self.initial.b_dot)] {
            if !v.is_empty() && v.len() != self.n_modes {
                return fail(format!("{what} has {} entries: give none (all zero) or n_modes = {}", v.len(), self.n_modes));
            }
            for (i, x) in v.iter().enumerate() {
                check(ANY, &format!("{what}[{i}]"), *x)?;
            }
        }
        check(TOLERANCE_RANGE, "solver.tolerance", self.solver.tolerance)?;
        if self.solver.max_events_per_step == 0 {
            return fail("solver.max_events_per_step = 0: allowed range is [1, inf)".into());
        }
        if self.solver.max_steps_per_step == Some(0) {
            return fail("solver.max_steps_per_step = 0: allowed range is [1, inf)".into());
        }
        if let Some(e) = &self.experiment {
            check(ANY, "experiment.start", e.start)?;
            check(ANY, "experiment.stop", e.stop)?;
            check(POSITIVE, "experiment.step", e.step)?;
            if e.stop < e.start {
                return fail(format!("experiment.stop = {:?}: allowed range is [experiment.start = {:?}, inf)", e.stop, e.start));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DWZ_SCENE: &str = r#"{ "name": "t", "beam": { "length": 1.0, "mass_per_length": 0.86884, "bending_stiffness": 541.26 },
        "n_modes": 6, "hub_inertia": 0.05,
        "surface": { "normal": [0, -1], "point": [1, 0],
                     "law": { "type": "hertz", "K": 7.6e9, "damping": "lankarani_nikravesh", "e": 0.8 } },
        "initial": { "theta_dot": 2.0 } }"#;

    #[test]
    fn parses_and_refuses_with_named_fields() {
        let s = RotatingSpec::from_json(DWZ_SCENE).unwrap();
        assert_eq!(s.hub, HubDrive::Torque);
        assert_eq!(s.order, OrderSpec::First);
        assert!(matches!(&s.surface.as_ref().unwrap().law, Law::Hertz(h) if h.damping == crate::contact::ContactDamping::LankaraniNikravesh));
        let e = RotatingSpec::from_json(&DWZ_SCENE.replace("\"hub_inertia\": 0.05", "\"hub_inertia\": 0.0")).unwrap_err();
        assert!(e.contains("hub_inertia = 0.0") && e.contains("(0, 289613333333.3333]") && e.contains("near-singular"), "{e}");
        let e = RotatingSpec::from_json(&DWZ_SCENE.replace("\"K\": 7.6e9", "\"K\": -1")).unwrap_err();
        assert!(e.contains("surface.law.K = -1.0") && e.contains("(0, 10000000000000000]"), "{e}");
        let e = RotatingSpec::from_json(&DWZ_SCENE.replace("\"e\": 0.8", "\"e\": 1.5")).unwrap_err();
        assert!(e.contains("surface.law.e = 1.5") && e.contains("[0, 1]"), "{e}");
        let e = RotatingSpec::from_json(&DWZ_SCENE.replace("n_modes\": 6", "n_modes\": 0")).unwrap_err();
        assert!(e.contains("n_modes = 0") && e.contains("[1, 100]"), "{e}");
        let e = RotatingSpec::from_json(&DWZ_SCENE.replace("\"theta_dot\"", "\"theta_dott\"")).unwrap_err();
        assert!(e.contains("unknown field `theta_dott`"), "{e}");
        let e = RotatingSpec::from_json(&DWZ_SCENE.replace("\"type\": \"hertz\"", "\"type\": \"hertz\", \"Q\": 1")).unwrap_err();
        assert!(e.contains("unknown field `Q`"), "{e}");
        let e = RotatingSpec::from_json(&DWZ_SCENE.replace("\"mass_per_length\": 0.86884,", "\"rho\": 2700,")).unwrap_err();
        assert!(e.contains("not a mix"), "{e}");
        let spin = DWZ_SCENE.replace("\"hub_inertia\": 0.05", "\"hub_inertia\": 0, \"hub\": {\"prescribed\": {\"type\": \"spin_up\", \"omega_s\": 6, \"T\": 15}}")
            .replace("\"theta_dot\": 2.0", "\"theta\": 0.1");
        let s = RotatingSpec::from_json(&spin).unwrap();
        assert_eq!(s.hub, HubDrive::Prescribed(Profile::SpinUp { omega_s: 6.0, duration: 15.0 }));
        let e = RotatingSpec::from_json(&spin.replace("\"T\": 15", "\"T\": 0")).unwrap_err();
        assert!(e.contains("hub.prescribed.T = 0.0"), "{e}");
    }

    #[test]
    fn a_harmonic_hub_is_checked_field_by_field() {
        let swing = |a: &str, w: &str, initial: &str| {
            DWZ_SCENE.replace("\"hub_inertia\": 0.05", &format!("\"hub_inertia\": 0, \"hub\": {{\"prescribed\": {{\"type\": \"harmonic\", \"A\": {a}, \"Omega\": {w}}}}}"))
                .replace("\"theta_dot\": 2.0", initial)
        };
        let s = RotatingSpec::from_json(&swing("0.3", "12", "\"theta\": -0.3")).unwrap();
        assert_eq!(s.hub, HubDrive::Prescribed(Profile::Harmonic { amplitude: 0.3, omega: 12.0 }));
        // omega_1 = 87.76 rad/s: Omega up to 100 omega_1, A Omega up to omega_1 (a surface).
        let e = RotatingSpec::from_json(&swing("-0.1", "12", "\"theta\": 0")).unwrap_err();
        assert!(e.contains("hub.prescribed.A = -0.1") && e.contains("[0, 10000]"), "{e}");
        let e = RotatingSpec::from_json(&swing("0.3", "0", "\"theta\": 0")).unwrap_err();
        assert!(e.contains("hub.prescribed.Omega = 0.0") && e.contains("(0, 8775.7"), "{e}");
        let e = RotatingSpec::from_json(&swing("0.3", "1e5", "\"theta\": 0")).unwrap_err();
        assert!(e.contains("hub.prescribed.Omega = 100000.0") && e.contains("(0, 8775.7"), "{e}");
        let e = RotatingSpec::from_json(&swing("2", "50", "\"theta\": 0")).unwrap_err();
        assert!(e.contains("hub.prescribed.Omega = 50.0") && e.contains("A Omega = 100.0") && e.contains("(0, 43.87"), "{e}");
        let e = RotatingSpec::from_json(&swing("9999.5", "0.001", "\"theta\": 1")).unwrap_err();
        assert!(e.contains("hub.prescribed.A = 9999.5") && e.contains("[0, 9999.0]"), "{e}");
        let e = RotatingSpec::from_json(&swing("0.3", "12", "\"theta_dot\": 3.6")).unwrap_err();
        assert!(e.contains("initial.theta_dot = 3.6") && e.contains("allowed value 0"), "{e}");
        let e = RotatingSpec::from_json(&swing("0.3", "12", "\"theta\": 0").replace("\"Omega\"", "\"omega\"")).unwrap_err();
        assert!(e.contains("unknown field `omega`"), "{e}");
    }
}
