//! What a scene exposes to the outside world: its parameters (with their
//! allowed ranges and whether they may change during a run), its inputs and
//! its outputs, each with a name, a unit and a description.
//!
//! Only what the scene uses appears. The FMI layer turns this list into
//! scalar variables; nothing here knows about FMI.

use crate::contact::StopOutput;
use crate::kinds::modal::scene::{ActuatorKind, Load, Names, Quantity, Range, Scene, SceneError, Units};
pub use crate::variables::{Input, Output, OutputType, Parameter, Unit};

/// A quantity's unit in the scene's unit system (everything is "1" scaled).
fn unit(scene: &Scene, u: Unit) -> Unit {
    match scene.units {
        Units::Scaled => Unit::One,
        Units::Si => u,
    }
}

/// Where a parameter's value lives in the scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ParamKey {
    LoadAmplitude(usize),
    LoadOmega(usize),
    LoadPosition(usize),
    Zeta,
    ZetaMode(usize),
    Viscous,
    /// Parameter `k` of stop `i`'s law (in the law's own order).
    Law(usize, usize),
    StopGap(usize),
    StopPosition(usize),
    SensorPosition(usize),
    ActuatorPosition(usize),
    InitialQ(usize),
    InitialQd(usize),
    IntegrationTolerance,
}

impl ParamKey {
    /// Where the value sits in the scene file (`stops[0].law.R`); `law` is
    /// the parameter's key in its law ([`crate::contact::ParamSpec::key`]).
    pub fn path(&self, scene: &Scene) -> String {
        match *self {
            ParamKey::LoadAmplitude(i) => format!("loads[{i}].amplitude"),
            ParamKey::LoadOmega(i) => format!("loads[{i}].omega"),
            ParamKey::LoadPosition(i) => format!("loads[{i}].x"),
            ParamKey::Zeta => "damping.zeta".into(),
            ParamKey::ZetaMode(j) => format!("damping.zeta_modes[{j}]"),
            ParamKey::Viscous => "damping.viscous".into(),
            ParamKey::Law(i, k) => format!("stops[{i}].law.{}", scene.stops[i].law.parameters()[k].key),
            ParamKey::StopGap(i) => format!("stops[{i}].gap"),
            ParamKey::StopPosition(i) => format!("stops[{i}].x"),
            ParamKey::SensorPosition(i) => format!("sensors[{i}].x"),
            ParamKey::ActuatorPosition(i) => format!("actuators[{i}].x"),
            ParamKey::InitialQ(j) => format!("initial.q[{j}]"),
            ParamKey::InitialQd(j) => format!("initial.qd[{j}]"),
            ParamKey::IntegrationTolerance => "solver.integration_tolerance".into(),
        }
    }

    /// The value in `scene` (0 where it is implied).
    pub fn get(&self, scene: &Scene) -> f64 {
        let json = serde_json::to_value(scene).expect("a scene always serialises");
        crate::fields::get(&json, &self.path(scene)).expect("a parameter's path holds a number")
    }

    /// Sets the value in `scene` (creating what it implies).
    pub fn set(&self, scene: &mut Scene, value: f64) {
        let path = self.path(scene);
        scene.set_field(&path, value).expect("a number at a parameter's path keeps the scene readable");
    }
}

impl Scene {
    /// Sets the number at a scene path (`stops[0].law.R`), creating what
    /// it implies ([`crate::fields::set`]); not validated.
    pub fn set_field(&mut self, path: &str, value: f64) -> Result<(), String> {
        let mut json = serde_json::to_value(&*self).expect("a scene always serialises");
        crate::fields::set(&mut json, path, value)?;
        *self = serde_json::from_value(json).map_err(|e| format!("{path} = {value}: {e}"))?;
        Ok(())
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum OutputKey {
    StopDisplacement(usize),
    StopVelocity(usize),
    StopImpacts(usize),
    StopLastImpact(usize),
    StopSticking(usize),
    StopSticks(usize),
    StopStuckTime(usize),
    StopReaction(usize),
    StopForce(usize),
    StopPenetration(usize),
    StopContact(usize),
    StopImpulse(usize),
    StopStoredEnergy(usize),
    StopDissipatedEnergy(usize),
    SensorDisplacement(usize),
    SensorVelocity(usize),
    SensorMoment(usize),
    Q(usize),
    Qd(usize),
    Energy,
    ForcingEnergy(usize),
    DampingEnergy(usize),
    ImpactEnergy,
}

/// A variable's name: the element's rename if it has one, else `prefix.key`.
fn named(names: &Names, prefix: &str, key: &str) -> String {
    names.get(key).cloned().unwrap_or_else(|| if prefix.is_empty() { key.to_string() } else { format!("{prefix}.{key}") })
}

/// A per-mode name: the pattern's `{j}` replaced by the 1-based mode number.
fn mode_name(names: &Names, key: &str, default: &str, j: usize) -> String {
    names.get(key).map(String::as_str).unwrap_or(default).replace("{j}", &(j + 1).to_string())
}

/// The allowed positions along a beam: for stops, not at a pinned or
/// clamped end (every mode has a node there, a stop could not act); for
/// the rest, anywhere.
fn span(scene: &Scene, stop: bool) -> Range {
    let length = scene.section().ok().flatten().map_or(1.0, |s| s.length);
    let free_right = matches!(scene.structure, crate::kinds::modal::scene::StructureSpec::Beam { support: crate::kinds::modal::scene::SupportKind::ClampedFree, .. });
    if stop {
        Range { min: 0.0, max: length, min_open: true, max_open: !free_right }
    } else {
        Range::closed(0.0, length)
    }
}

/// The honest ranges of a scene's values, from its structure alone (never
/// from a parameter, so they are fixed when the FMU is packaged). The model
/// is linear and exact at any amplitude, but its rounding is relative to
/// the largest quantity in play: beyond these limits a millimetre gap would
/// drown in the rounding of the deflection (a force of 1e150 N would pass
/// through the stop) or the event search would have to resolve a load far
/// faster than every mode.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// Largest displacement: 1000 times the beam's length (1 in scaled units).
    pub displacement: f64,
    /// Lowest natural frequency, from below (the cantilever's 1.875^2 c for
    /// beams, `2 sqrt(k/m) sin(pi / (4 N + 2))` for the chain).
    pub omega_low: f64,
    /// Highest natural frequency, from above (`((N + 1) pi)^2 c` for beams,
    /// `2 sqrt(k / m)` for the chain).
    pub omega_high: f64,
    /// The mass moved by a point force (the beam's or one mass of the chain).
    pub mass: f64,
    /// Mass per unit length (beams; 1 for chains).
    pub mass_per_length: f64,
}

/// Largest modal damping ratio (heavily over-damped modes stay exact, but
/// beyond this nothing moves within any useful horizon).
pub const MAX_ZETA: f64 = 1e3;
/// The stiffest compliant stop, relative to `m omega_low^2`.
pub const MAX_STOP_STIFFNESS_RATIO: f64 = 1e14;
/// The softest power-law (Hertz) stop, relative to the stiffest: its force
/// 1e-30 of the stiffest one's at the same penetration.
pub const MIN_POWER_STIFFNESS_RATIO: f64 = 1e-30;
/// The fastest load, relative to the highest natural frequency.
pub const MAX_LOAD_FREQUENCY_RATIO: f64 = 1e3;
/// The largest displacement, relative to the structure's length.
pub const MAX_DISPLACEMENT_RATIO: f64 = 1e3;

impl Limits {
    pub fn of(scene: &Scene) -> Limits {
        match (&scene.structure, scene.section().ok().flatten()) {
            (crate::kinds::modal::scene::StructureSpec::Chain { masses, m, k, .. }, _) => {
                let w = 2.0 * (k / m).sqrt();
                Limits {
                    displacement: MAX_DISPLACEMENT_RATIO,
                    omega_low: w * (std::f64::consts::PI / (4.0 * *masses as f64 + 2.0)).sin(),
                    omega_high: w,
                    mass: *m,
                    mass_per_length: 1.0,
                }
            }
            (_, section) => {
                let s = section.unwrap_or(crate::kinds::modal::scene::Section { length: 1.0, mass_per_length: 1.0, bending_stiffness: 1.0 });
                let c = (s.bending_stiffness / (s.mass_per_length * s.length.powi(4))).sqrt();
                let n = scene.n_modes() as f64;
                Limits {
                    displacement: MAX_DISPLACEMENT_RATIO * s.length,
                    omega_low: 1.875f64.powi(2) * c,
                    omega_high: ((n + 1.0) * std::f64::consts::PI).powi(2) * c,
                    mass: s.mass_per_length * s.length,
                    mass_per_length: s.mass_per_length,
                }
            }
        }
    }

    /// Displacements, gaps, initial modal displacements.
    pub fn displacement_range(&self) -> Range {
        Range::closed(-self.displacement, self.displacement)
    }

    /// Initial modal velocities: an amplitude of at most the displacement
    /// limit in the slowest mode.
    pub fn velocity_range(&self) -> Range {
        let v = self.displacement * self.omega_low;
        Range::closed(-v, v)
    }

    /// Accelerations (base excitation): a static deflection of at most the
    /// displacement limit in the slowest mode.
    pub fn acceleration(&self) -> f64 {
        self.displacement * self.omega_low * self.omega_low
    }

    /// Load amplitudes and input forces of each kind.
    pub fn force_range(&self, per_length: bool) -> Range {
        let f = self.acceleration() * if per_length { self.mass_per_length } else { self.mass };
        Range::closed(-f, f)
    }

    pub fn acceleration_range(&self) -> Range {
        Range::closed(-self.acceleration(), self.acceleration())
    }

    pub fn load_frequency_range(&self) -> Range {
        Range::closed(0.0, MAX_LOAD_FREQUENCY_RATIO * self.omega_high)
    }

    /// Durations such as the chatter threshold: up to 1000 periods of the
    /// slowest mode (beyond that every impact after the first ends a chatter).
    pub fn duration_range(&self) -> Range {
        Range::closed(0.0, 1e3 * 2.0 * std::f64::consts::PI / self.omega_low)
    }

    pub fn zeta_range(&self) -> Range {
        Range::closed(0.0, MAX_ZETA)
    }

    /// The range a law parameter may take, by its unit: ratios in [0, 1],
    /// durations, stiffnesses (N/m^n by the exponent), damping.
    pub fn law_range(&self, unit: Unit) -> Range {
        match unit {
            Unit::One => Range::UNIT,
            Unit::Second => self.duration_range(),
            Unit::NewtonPerMetre => self.stop_stiffness_range(),
            Unit::NewtonPerMetrePower(n) => self.power_stiffness_range(n.value()),
            Unit::NewtonSecondPerMetre => self.stop_damping_range(),
            other => unreachable!("no law parameter is in {}", other.name()),
        }
    }

    /// Power-law stiffness: a force `K p^n` no stiffer than the hardest
    /// linear stop at a penetration of 1e-9 of the displacement scale (`K =
    /// k / p^(n - 1)` there), and at least `MIN_POWER_STIFFNESS_RATIO` of
    /// that: a law without force has no force whose end ends a contact
    /// (a linear stop's closed form needs none), and one of a denormal
    /// size has its force and its switches in the underflow.
    pub fn power_stiffness_range(&self, n: f64) -> Range {
        let p = 1e-9 * self.displacement / MAX_DISPLACEMENT_RATIO;
        let max = self.stop_stiffness_range().max / p.powf(n - 1.0);
        Range::closed(MIN_POWER_STIFFNESS_RATIO * max, max)
    }

    /// Stop stiffness: up to `MAX_STOP_STIFFNESS_RATIO` times the stiffness
    /// `m omega_low^2` of the slowest mode (RMTM's hardest case, kappa =
    /// 1e4, is about 1e-10 of it): beyond, the contact phase's frequency
    /// would exceed the slowest mode's by 1e7 and the penetration drown in
    /// the rounding of the deflection.
    pub fn stop_stiffness_range(&self) -> Range {
        Range::closed(0.0, MAX_STOP_STIFFNESS_RATIO * self.mass * self.omega_low * self.omega_low)
    }

    /// Stop damping: up to the critical damping of the whole mass on the
    /// highest mode's frequency, times `MAX_ZETA`.
    pub fn stop_damping_range(&self) -> Range {
        Range::closed(0.0, 2.0 * MAX_ZETA * self.mass * self.omega_high)
    }

    /// Viscous damping per length giving at most `MAX_ZETA` in the slowest mode.
    pub fn viscous_range(&self) -> Range {
        Range::closed(0.0, 2.0 * MAX_ZETA * self.mass_per_length * self.omega_low)
    }
}

/// Every parameter of the scene, in a stable order.
pub fn parameters(scene: &Scene) -> Vec<Parameter> {
    let limits = Limits::of(scene);
    let mut out = Vec::new();
    let mut push = |key: ParamKey, name, scene_path: String, description: String, u, range, tunable| {
        debug_assert_eq!(scene_path, key.path(scene));
        out.push(Parameter { name, scene_path, description, unit: unit(scene, u), range, tunable });
    };
    let beam = scene.is_beam();
    for (i, load) in scene.loads.iter().enumerate() {
        let (name, names, kind, amplitude_unit, amplitude_range) = match load {
            Load::DistributedHarmonic { name, names, .. } => {
                (name, names, "distributed load (per unit length)", Unit::NewtonPerMetre, limits.force_range(true))
            }
            Load::PointHarmonic { name, names, .. } => (name, names, "point force", Unit::Newton, limits.force_range(false)),
            Load::BaseExcitation { name, names, .. } => {
                (name, names, "base acceleration", Unit::MetrePerSecond2, limits.acceleration_range())
            }
        };
        push(
            ParamKey::LoadAmplitude(i),
            named(names, name, "amplitude"),
            format!("loads[{i}].amplitude"),
            format!("Amplitude of the harmonic {kind} '{name}'"),
            amplitude_unit,
            amplitude_range,
            true,
        );
        push(
            ParamKey::LoadOmega(i),
            named(names, name, "omega"),
            format!("loads[{i}].omega"),
            format!("Circular frequency of the load '{name}'"),
            Unit::RadianPerSecond,
            limits.load_frequency_range(),
            true,
        );
        if beam && matches!(load, Load::PointHarmonic { .. }) {
            push(
                ParamKey::LoadPosition(i),
                named(names, name, "x"),
                format!("loads[{i}].x"),
                format!("Position of the point force '{name}' along the beam"),
                Unit::Metre,
                span(scene, false),
                false,
            );
        }
    }
    if let Some(d) = &scene.damping {
        if d.zeta.is_some() {
            push(ParamKey::Zeta, named(&d.names, "", "zeta"), "damping.zeta".into(), "Modal damping ratio of every mode".into(), Unit::One, limits.zeta_range(), false);
        }
        if let Some(z) = &d.zeta_modes {
            for j in 0..z.len() {
                push(
                    ParamKey::ZetaMode(j),
                    mode_name(&d.names, "zeta_modes", "zeta[{j}]", j),
                    format!("damping.zeta_modes[{j}]"),
                    format!("Damping ratio of mode {}", j + 1),
                    Unit::One,
                    limits.zeta_range(),
                    false,
                );
            }
        }
        if d.viscous.is_some() {
            push(
                ParamKey::Viscous,
                named(&d.names, "", "c_viscous"),
                "damping.viscous".into(),
                "Viscous damping per unit length (zeta_j = c / (2 rho A omega_j))".into(),
                Unit::NewtonSecondPerMetre2,
                limits.viscous_range(),
                false,
            );
        }
    }
    for (i, stop) in scene.stops.iter().enumerate() {
        let (n, s) = (&stop.names, &stop.name);
        // Under mode transfer the contact basis is built from the stop's
        // parameters: they are fixed for the run.
        let transfer = stop.law.mode_transfer().is_some();
        for (k, spec) in stop.law.parameters().iter().enumerate() {
            push(
                ParamKey::Law(i, k),
                named(n, s, spec.key),
                format!("stops[{i}].law.{}", spec.key),
                spec.description.replace("{stop}", s),
                spec.unit,
                limits.law_range(spec.unit),
                spec.tunable && !transfer,
            );
        }
        push(
            ParamKey::StopGap(i),
            named(n, s, "gap"),
            format!("stops[{i}].gap"),
            format!("Clearance between the undeformed structure and stop '{s}' (negative: preload)"),
            Unit::Metre,
            limits.displacement_range(),
            false,
        );
        if beam {
            push(ParamKey::StopPosition(i), named(n, s, "x"), format!("stops[{i}].x"), format!("Position of stop '{s}' along the beam"), Unit::Metre, span(scene, true), false);
        }
    }
    if beam {
        for (i, sensor) in scene.sensors.iter().enumerate() {
            let s = &sensor.name;
            push(ParamKey::SensorPosition(i), named(&sensor.names, s, "x"), format!("sensors[{i}].x"), format!("Position of sensor '{s}' along the beam"), Unit::Metre, span(scene, false), false);
        }
        for (i, a) in scene.actuators.iter().enumerate() {
            if a.kind == ActuatorKind::Force {
                push(
                    ParamKey::ActuatorPosition(i),
                    named(&a.names, &a.name, "x"),
                    format!("actuators[{i}].x"),
                    format!("Position of the point force '{}' along the beam", a.name),
                    Unit::Metre,
                    span(scene, false),
                    false,
                );
            }
        }
    }
    for j in 0..scene.n_modes() {
        push(ParamKey::InitialQ(j), mode_name(&scene.names, "q0", "q0[{j}]", j), format!("initial.q[{j}]"), format!("Initial modal displacement of mode {}", j + 1), Unit::Metre, limits.displacement_range(), false);
    }
    for j in 0..scene.n_modes() {
        push(ParamKey::InitialQd(j), mode_name(&scene.names, "qd0", "qd0[{j}]", j), format!("initial.qd[{j}]"), format!("Initial modal velocity of mode {}", j + 1), Unit::MetrePerSecond, limits.velocity_range(), false);
    }
    if scene.has_integrated_phase() {
        push(
            ParamKey::IntegrationTolerance,
            "solver.integration_tolerance".into(),
            "solver.integration_tolerance".into(),
            "Relative tolerance of the integrated contact phases (closed-form phases are exact regardless); smaller is more accurate and slower".into(),
            Unit::One,
            crate::kinds::modal::scene::INTEGRATION_TOLERANCE_RANGE,
            false,
        );
    }
    out
}

pub fn inputs(scene: &Scene) -> Vec<Input> {
    let limits = Limits::of(scene);
    scene
        .actuators
        .iter()
        .map(|a| {
            let (description, u, range) = match a.kind {
                ActuatorKind::Force => (
                    format!("Point force '{}' (positive along +w), held constant over each communication step", a.name),
                    Unit::Newton,
                    limits.force_range(false),
                ),
                ActuatorKind::BaseAcceleration => (
                    format!("Acceleration '{}' of the supports (and stops), held constant over each communication step", a.name),
                    Unit::MetrePerSecond2,
                    limits.acceleration_range(),
                ),
            };
            Input { name: named(&a.names, "", &a.name), description, unit: unit(scene, u), range }
        })
        .collect()
}

/// Every output of the scene, with what it reads.
pub fn outputs(scene: &Scene) -> Vec<(OutputKey, Output)> {
    let mut out = Vec::new();
    let mut push = |key, name, description: String, u, kind, discrete| {
        out.push((key, Output { name, description, unit: unit(scene, u), kind, discrete }));
    };
    let real = OutputType::Real;
    for (i, stop) in scene.stops.iter().enumerate() {
        let (n, s) = (&stop.names, &stop.name);
        push(OutputKey::StopDisplacement(i), named(n, s, "w"), format!("Displacement at stop '{s}'"), Unit::Metre, real, false);
        push(OutputKey::StopVelocity(i), named(n, s, "v"), format!("Velocity at stop '{s}'"), Unit::MetrePerSecond, real, false);
        // What the law provides.
        let (force, stored) = stop.law.formulas();
        for o in stop.law.outputs() {
            let key = match o.what {
                StopOutput::Impacts => OutputKey::StopImpacts(i),
                StopOutput::LastImpact => OutputKey::StopLastImpact(i),
                StopOutput::Sticking => OutputKey::StopSticking(i),
                StopOutput::Sticks => OutputKey::StopSticks(i),
                StopOutput::StuckTime => OutputKey::StopStuckTime(i),
                StopOutput::Reaction => OutputKey::StopReaction(i),
                StopOutput::Force => OutputKey::StopForce(i),
                StopOutput::Penetration => OutputKey::StopPenetration(i),
                StopOutput::Contact => OutputKey::StopContact(i),
                StopOutput::StoredEnergy => OutputKey::StopStoredEnergy(i),
                StopOutput::DissipatedEnergy => OutputKey::StopDissipatedEnergy(i),
            };
            let description = o.description.replace("{stop}", s).replace("{force}", force).replace("{stored}", stored);
            push(key, named(n, s, o.suffix), description, o.unit, o.kind, o.discrete);
        }
        if scene.outputs.impulse {
            push(
            OutputKey::StopImpulse(i),
            named(n, s, "impulse"),
            format!("Impulse stop '{s}' delivered over the last communication step (>= 0, pushing the structure away: -side w direction), exact"),
            Unit::NewtonSecond,
            real,
            true,
        );
        }
    }
    for (i, sensor) in scene.sensors.iter().enumerate() {
        let (n, s) = (&sensor.names, &sensor.name);
        for q in &sensor.quantities {
            match q {
                Quantity::Displacement => push(OutputKey::SensorDisplacement(i), named(n, s, "w"), format!("Displacement at sensor '{s}'"), Unit::Metre, real, false),
                Quantity::Velocity => push(OutputKey::SensorVelocity(i), named(n, s, "v"), format!("Velocity at sensor '{s}'"), Unit::MetrePerSecond, real, false),
                Quantity::BendingMoment => push(
                    OutputKey::SensorMoment(i),
                    named(n, s, "M"),
                    format!("Bending moment EI w'' at sensor '{s}' (modal sum: converges slowly in the number of modes)"),
                    Unit::NewtonMetre,
                    real,
                    false,
                ),
            }
        }
    }
    if scene.outputs.modal {
        for j in 0..scene.n_modes() {
            push(OutputKey::Q(j), mode_name(&scene.names, "q", "q[{j}]", j), format!("Modal displacement of mode {}", j + 1), Unit::Metre, real, false);
        }
        for j in 0..scene.n_modes() {
            push(OutputKey::Qd(j), mode_name(&scene.names, "qd", "qd[{j}]", j), format!("Modal velocity of mode {}", j + 1), Unit::MetrePerSecond, real, false);
        }
    }
    if scene.outputs.energy {
        push(OutputKey::Energy, named(&scene.names, "", "energy"), "Kinetic plus strain energy".into(), Unit::Joule, real, false);
    }
    if scene.outputs.energy_balance {
        for j in 0..scene.n_modes() {
            push(
                OutputKey::ForcingEnergy(j),
                mode_name(&scene.names, "FE", "FE[{j}]", j),
                format!("Work of the loads on mode {} since the start (WB00 eq. 8, FE_j)", j + 1),
                Unit::Joule,
                real,
                false,
            );
        }
        for j in 0..scene.n_modes() {
            push(
                OutputKey::DampingEnergy(j),
                mode_name(&scene.names, "DE", "DE[{j}]", j),
                format!("Energy dissipated by the damping of mode {} since the start (WB00 eq. 8, DE_j)", j + 1),
                Unit::Joule,
                real,
                false,
            );
        }
        push(OutputKey::ImpactEnergy, named(&scene.names, "", "impact_energy"), "Energy lost at impacts since the start".into(), Unit::Joule, real, true);
    }
    out
}

/// Every variable name of a scene (parameters, inputs, outputs).
pub fn variable_names(scene: &Scene) -> Vec<String> {
    let mut v: Vec<String> = parameters(scene).into_iter().map(|p| p.name).collect();
    v.extend(inputs(scene).into_iter().map(|i| i.name));
    v.extend(outputs(scene).into_iter().map(|(_, o)| o.name));
    v
}

impl Scene {
    /// Parses and validates a scene; errors name the field and what is allowed.
    pub fn from_json(text: &str) -> Result<Scene, SceneError> {
        let scene = Scene::parse(text)?;
        scene.validate()?;
        Ok(scene)
    }

    /// Everything that cannot change after packaging: the structure
    /// ([`Scene::validate_structure`]), every value within the range of the
    /// parameter that carries it, and distinct variable names.
    pub fn validate(&self) -> Result<(), SceneError> {
        self.validate_structure()?;
        let json = serde_json::to_value(self).expect("a scene always serialises");
        for p in parameters(self) {
            let value = crate::fields::get(&json, &p.scene_path).map_err(SceneError)?;
            p.range.check(&format!("{} ({})", p.scene_path, p.name), value).map_err(SceneError)?;
        }
        let mut names = std::collections::BTreeSet::new();
        for v in variable_names(self) {
            if !names.insert(v.clone()) {
                return Err(SceneError(format!("two variables would be named {v:?}: rename one with \"names\"")));
            }
        }
        Ok(())
    }
}
