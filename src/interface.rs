//! What a scene exposes to the outside world: its parameters (with their
//! allowed ranges and whether they may change during a run), its inputs and
//! its outputs, each with a name, a unit and a description.
//!
//! Only what the scene uses appears. The FMI layer turns this list into
//! scalar variables; nothing here knows about FMI.

use crate::scene::{Load, Range, Scene, StopLaw, Structure};

/// Where a parameter's value lives in the scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ParamKey {
    LoadAmplitude(usize),
    LoadOmega(usize),
    Zeta,
    Restitution(usize),
    ChatterEps(usize),
    StopGap(usize),
    StopPosition(usize),
    ActuatorPosition(usize),
    InitialQ(usize),
    InitialQd(usize),
}

impl ParamKey {
    pub fn get(&self, scene: &Scene) -> f64 {
        match *self {
            ParamKey::LoadAmplitude(i) => match &scene.loads[i] {
                Load::DistributedHarmonic { amplitude, .. } => *amplitude,
            },
            ParamKey::LoadOmega(i) => match &scene.loads[i] {
                Load::DistributedHarmonic { omega, .. } => *omega,
            },
            ParamKey::Zeta => scene.damping.zeta,
            ParamKey::Restitution(i) => match &scene.stops[i].law {
                StopLaw::Restitution { restitution, .. } => *restitution,
            },
            ParamKey::ChatterEps(i) => match &scene.stops[i].law {
                StopLaw::Restitution { eps, .. } => *eps,
            },
            ParamKey::StopGap(i) => scene.stops[i].gap,
            ParamKey::StopPosition(i) => scene.stops[i].x,
            ParamKey::ActuatorPosition(i) => scene.actuators[i].x,
            ParamKey::InitialQ(j) => scene.initial.q.get(j).copied().unwrap_or(0.0),
            ParamKey::InitialQd(j) => scene.initial.qd.get(j).copied().unwrap_or(0.0),
        }
    }

    pub fn set(&self, scene: &mut Scene, value: f64) {
        let n = scene.n_modes();
        match *self {
            ParamKey::LoadAmplitude(i) => match &mut scene.loads[i] {
                Load::DistributedHarmonic { amplitude, .. } => *amplitude = value,
            },
            ParamKey::LoadOmega(i) => match &mut scene.loads[i] {
                Load::DistributedHarmonic { omega, .. } => *omega = value,
            },
            ParamKey::Zeta => scene.damping.zeta = value,
            ParamKey::Restitution(i) => match &mut scene.stops[i].law {
                StopLaw::Restitution { restitution, .. } => *restitution = value,
            },
            ParamKey::ChatterEps(i) => match &mut scene.stops[i].law {
                StopLaw::Restitution { eps, .. } => *eps = value,
            },
            ParamKey::StopGap(i) => scene.stops[i].gap = value,
            ParamKey::StopPosition(i) => scene.stops[i].x = value,
            ParamKey::ActuatorPosition(i) => scene.actuators[i].x = value,
            ParamKey::InitialQ(j) => {
                scene.initial.q.resize(n, 0.0);
                scene.initial.q[j] = value;
            }
            ParamKey::InitialQd(j) => {
                scene.initial.qd.resize(n, 0.0);
                scene.initial.qd[j] = value;
            }
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Parameter {
    pub key: ParamKey,
    pub name: String,
    /// Where the value sits in the scene file, for error messages.
    pub scene_path: String,
    pub description: String,
    pub unit: &'static str,
    pub range: Range,
    /// May change between communication steps; otherwise fixed after
    /// initialisation.
    pub tunable: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum InputKey {
    ActuatorForce(usize),
}

#[derive(Clone, Debug, PartialEq)]
pub struct Input {
    pub key: InputKey,
    pub name: String,
    pub description: String,
    pub unit: &'static str,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum OutputKey {
    StopDisplacement(usize),
    StopVelocity(usize),
    StopImpacts(usize),
    StopLastImpact(usize),
    StopSticking(usize),
    StopReaction(usize),
    Q(usize),
    Qd(usize),
    Energy,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputType {
    Real,
    Integer,
    Boolean,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Output {
    pub key: OutputKey,
    pub name: String,
    pub description: String,
    pub unit: &'static str,
    pub kind: OutputType,
}

/// A variable's name: the element's rename if it has one, else `prefix.key`.
fn named(names: &std::collections::BTreeMap<String, String>, prefix: &str, key: &str) -> String {
    names.get(key).cloned().unwrap_or_else(|| if prefix.is_empty() { key.to_string() } else { format!("{prefix}.{key}") })
}

/// A per-mode name: the pattern's `{j}` replaced by the 1-based mode number.
fn mode_name(names: &std::collections::BTreeMap<String, String>, key: &str, default: &str, j: usize) -> String {
    names.get(key).map(String::as_str).unwrap_or(default).replace("{j}", &(j + 1).to_string())
}

fn span(scene: &Scene) -> Range {
    match scene.structure {
        Structure::Beam { .. } => Range::OPEN_UNIT,
    }
}

fn closed_span(scene: &Scene) -> Range {
    match scene.structure {
        Structure::Beam { .. } => Range::UNIT,
    }
}

/// Every parameter of the scene, in a stable order.
pub fn parameters(scene: &Scene) -> Vec<Parameter> {
    let mut out = Vec::new();
    let unit = "1";
    for (i, load) in scene.loads.iter().enumerate() {
        let Load::DistributedHarmonic { name, names, .. } = load;
        out.push(Parameter {
            key: ParamKey::LoadAmplitude(i),
            name: named(names, name, "amplitude"),
            scene_path: format!("loads[{i}].amplitude"),
            description: format!("Amplitude of the distributed harmonic load '{name}' (per unit length)"),
            unit,
            range: Range::ANY,
            tunable: true,
        });
        out.push(Parameter {
            key: ParamKey::LoadOmega(i),
            name: named(names, name, "omega"),
            scene_path: format!("loads[{i}].omega"),
            description: format!("Circular frequency of the load '{name}'"),
            unit,
            range: Range::NON_NEGATIVE,
            tunable: true,
        });
    }
    out.push(Parameter {
        key: ParamKey::Zeta,
        name: named(&scene.damping.names, "", "zeta"),
        scene_path: "damping.zeta".into(),
        description: "Modal damping ratio of every mode".into(),
        unit,
        range: Range::NON_NEGATIVE,
        tunable: false,
    });
    for (i, stop) in scene.stops.iter().enumerate() {
        let n = &stop.names;
        let s = &stop.name;
        match stop.law {
            StopLaw::Restitution { .. } => {
                out.push(Parameter {
                    key: ParamKey::Restitution(i),
                    name: named(n, s, "R"),
                    scene_path: format!("stops[{i}].law.R"),
                    description: format!("Coefficient of restitution at stop '{s}'"),
                    unit,
                    range: Range::UNIT,
                    tunable: true,
                });
                out.push(Parameter {
                    key: ParamKey::ChatterEps(i),
                    name: named(n, s, "eps"),
                    scene_path: format!("stops[{i}].law.eps"),
                    description: format!(
                        "Chatter threshold at stop '{s}': an impact sooner than eps after the previous one ends the chatter with R = 0 and starts sticking"
                    ),
                    unit,
                    range: Range::NON_NEGATIVE,
                    tunable: true,
                });
            }
        }
        out.push(Parameter {
            key: ParamKey::StopGap(i),
            name: named(n, s, "gap"),
            scene_path: format!("stops[{i}].gap"),
            description: format!("Clearance between the undeformed beam and stop '{s}' (negative: preload)"),
            unit,
            range: Range::ANY,
            tunable: false,
        });
        out.push(Parameter {
            key: ParamKey::StopPosition(i),
            name: named(n, s, "x"),
            scene_path: format!("stops[{i}].x"),
            description: format!("Position of stop '{s}' along the beam"),
            unit,
            range: span(scene),
            tunable: false,
        });
    }
    for (i, a) in scene.actuators.iter().enumerate() {
        out.push(Parameter {
            key: ParamKey::ActuatorPosition(i),
            name: named(&a.names, &a.name, "x"),
            scene_path: format!("actuators[{i}].x"),
            description: format!("Position of the point force '{}' along the beam", a.name),
            unit,
            range: closed_span(scene),
            tunable: false,
        });
    }
    for j in 0..scene.n_modes() {
        out.push(Parameter {
            key: ParamKey::InitialQ(j),
            name: mode_name(&scene.names, "q0", "q0[{j}]", j),
            scene_path: format!("initial.q[{j}]"),
            description: format!("Initial modal displacement of mode {}", j + 1),
            unit,
            range: Range::ANY,
            tunable: false,
        });
    }
    for j in 0..scene.n_modes() {
        out.push(Parameter {
            key: ParamKey::InitialQd(j),
            name: mode_name(&scene.names, "qd0", "qd0[{j}]", j),
            scene_path: format!("initial.qd[{j}]"),
            description: format!("Initial modal velocity of mode {}", j + 1),
            unit,
            range: Range::ANY,
            tunable: false,
        });
    }
    out
}

pub fn inputs(scene: &Scene) -> Vec<Input> {
    scene
        .actuators
        .iter()
        .enumerate()
        .map(|(i, a)| Input {
            key: InputKey::ActuatorForce(i),
            name: named(&a.names, "", &a.name),
            description: format!("Point force '{}' (positive along +w), held constant over each communication step", a.name),
            unit: "1",
        })
        .collect()
}

pub fn outputs(scene: &Scene) -> Vec<Output> {
    let mut out = Vec::new();
    let real = |key, name, description: String| Output { key, name, description, unit: "1", kind: OutputType::Real };
    for (i, stop) in scene.stops.iter().enumerate() {
        let (n, s) = (&stop.names, &stop.name);
        out.push(real(OutputKey::StopDisplacement(i), named(n, s, "w"), format!("Beam displacement at stop '{s}'")));
        out.push(real(OutputKey::StopVelocity(i), named(n, s, "v"), format!("Beam velocity at stop '{s}'")));
        out.push(Output {
            key: OutputKey::StopImpacts(i),
            name: named(n, s, "impacts"),
            description: format!("Number of impacts at stop '{s}' since the start"),
            unit: "",
            kind: OutputType::Integer,
        });
        out.push(real(
            OutputKey::StopLastImpact(i),
            named(n, s, "t_last_impact"),
            format!("Exact time of the latest impact at stop '{s}' (start time before the first)"),
        ));
        out.push(Output {
            key: OutputKey::StopSticking(i),
            name: named(n, s, "sticking"),
            description: format!("Whether the beam is stuck to stop '{s}'"),
            unit: "",
            kind: OutputType::Boolean,
        });
        out.push(real(
            OutputKey::StopReaction(i),
            named(n, s, "lambda"),
            format!("Reaction of stop '{s}' on the beam while sticking (seed eq. 33; pushes along -w for a stop on the +w side), else 0"),
        ));
    }
    for j in 0..scene.n_modes() {
        out.push(real(OutputKey::Q(j), mode_name(&scene.names, "q", "q[{j}]", j), format!("Modal displacement of mode {}", j + 1)));
    }
    for j in 0..scene.n_modes() {
        out.push(real(OutputKey::Qd(j), mode_name(&scene.names, "qd", "qd[{j}]", j), format!("Modal velocity of mode {}", j + 1)));
    }
    out.push(real(OutputKey::Energy, named(&scene.names, "", "energy"), "Kinetic plus strain energy of the beam".into()));
    out
}

/// The value of an output.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Value {
    Real(f64),
    Integer(i64),
    Boolean(bool),
}

impl OutputKey {
    /// Reads the output from a simulation at its current time.
    pub fn evaluate(&self, sim: &crate::sim::Simulation) -> Value {
        let c = sim.current();
        let stops = &sim.model().stops;
        match *self {
            OutputKey::StopDisplacement(i) => Value::Real(stops[i].w.dot(&c.q)),
            OutputKey::StopVelocity(i) => Value::Real(stops[i].w.dot(&c.qd)),
            OutputKey::StopImpacts(i) => Value::Integer(sim.state().stops[i].impacts as i64),
            OutputKey::StopLastImpact(i) => Value::Real(sim.state().stops[i].last_impact),
            OutputKey::StopSticking(i) => Value::Boolean(sim.is_stuck(i)),
            OutputKey::StopReaction(i) => Value::Real(sim.reaction(i)),
            OutputKey::Q(j) => Value::Real(c.q[j]),
            OutputKey::Qd(j) => Value::Real(c.qd[j]),
            OutputKey::Energy => Value::Real(sim.energy()),
        }
    }
}
