//! What a rotating-beam scene exposes: its parameters (fixed for a run:
//! each one shapes the model the integration starts from), its input (the
//! hub torque, unless the hub's motion is prescribed) and its outputs, and
//! how each output is read from a run. Only what the scene uses appears: a
//! scene without a surface has no contact outputs, one without gravity no
//! `g`. Nothing here knows about FMI.

use super::spec::{HubDrive, Profile, RotatingSpec};
use super::RotatingSimulation;
use crate::contact::{Contact, LawOutput, StopOutput};
use crate::variables::{Input, Output, OutputType, Parameter, Range, Unit, Value};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RotatingOutput {
    Theta,
    ThetaDot,
    TipDeflection,
    TipX,
    TipY,
    RootMoment,
    Energy,
    HubTorque,
    /// An output the surface's law provides ([`LawOutput::surface`]).
    Law(StopOutput),
    Impulse,
}

/// Every parameter of the scene, in a stable order; all fixed for a run.
pub fn parameters(spec: &RotatingSpec) -> Vec<Parameter> {
    let mut out = Vec::new();
    let mut push = |name: &str, scene_path: &str, description: String, unit, range| {
        out.push(Parameter { name: name.into(), scene_path: scene_path.into(), description, unit, range, tunable: false });
    };
    let prescribed = matches!(spec.hub, HubDrive::Prescribed(_));
    let inertia_note = if prescribed {
        "enters only the torque the prescribed motion needs"
    } else {
        "a torque-driven hub needs J_h > 0: at 0 the mass matrix is near-singular"
    };
    push("J_h", "hub_inertia", format!("Moment of inertia of the hub about its axis ({inertia_note})"), Unit::KilogramMetre2, spec.hub_inertia_range());
    if spec.hub_radius != 0.0 {
        push("R", "hub_radius", "Distance from the axis to the clamped root".into(), Unit::Metre, spec.hub_radius_range());
    }
    if spec.gravity != 0.0 {
        push("g", "gravity", "Gravity along -Y, in the plane of rotation".into(), Unit::MetrePerSecond2, spec.gravity_range());
    }
    if spec.modal_damping != 0.0 {
        push("zeta", "modal_damping", "Damping ratio of every bending mode".into(), Unit::One, Range::closed(0.0, 10.0));
    }
    if let Some(surface) = &spec.surface {
        // The law describes its own parameters.
        for p in surface.law.parameters() {
            push(p.key, &format!("surface.law.{}", p.key), p.description.replace("{stop}", "surface"), p.unit, spec.law_range(p.unit));
        }
    }
    push("theta0", "initial.theta", "Initial hub angle".into(), Unit::Radian, spec.angle_range());
    match spec.hub {
        HubDrive::Torque => push("theta_dot0", "initial.theta_dot", "Initial hub speed".into(), Unit::RadianPerSecond, spec.speed_range()),
        HubDrive::Prescribed(Profile::SpinUp { .. }) => {
            push(
                "omega_s",
                "hub.prescribed.omega_s",
                "Final hub speed of the spin-up theta' = omega_s / T (t - T / (2 pi) sin(2 pi t / T)), t < T".into(),
                Unit::RadianPerSecond,
                spec.speed_range(),
            );
            push("T", "hub.prescribed.T", "Duration of the spin-up".into(), Unit::Second, spec.spin_duration_range());
        }
        HubDrive::Prescribed(Profile::Harmonic { .. }) => {
            push(
                "A",
                "hub.prescribed.A",
                "Amplitude of the hub's swing theta = theta0 + A sin(Omega t) (A Omega within the speed limit)".into(),
                Unit::Radian,
                spec.swing_amplitude_range(),
            );
            push(
                "Omega",
                "hub.prescribed.Omega",
                "Frequency of the hub's swing theta = theta0 + A sin(Omega t); its speed at t = 0 is A Omega".into(),
                Unit::RadianPerSecond,
                spec.swing_frequency_range(),
            );
        }
    }
    push(
        "solver.tolerance",
        "solver.tolerance",
        "Relative tolerance of the integration; smaller is more accurate and slower".into(),
        Unit::One,
        super::spec::TOLERANCE_RANGE,
    );
    out
}

/// The hub torque, unless the hub's motion is prescribed.
pub fn inputs(spec: &RotatingSpec) -> Vec<Input> {
    match spec.hub {
        HubDrive::Torque => vec![Input {
            name: "torque".into(),
            description: "Torque on the hub (positive counter-clockwise), held constant over each communication step".into(),
            unit: Unit::NewtonMetre,
            range: spec.torque_range(),
        }],
        HubDrive::Prescribed(_) => Vec::new(),
    }
}

pub fn outputs(spec: &RotatingSpec) -> Vec<(RotatingOutput, Output)> {
    let mut out = Vec::new();
    let mut push = |key, name: &str, description: &str, unit, kind, discrete| {
        out.push((key, Output { name: name.into(), description: description.into(), unit, kind, discrete }));
    };
    let real = OutputType::Real;
    push(RotatingOutput::Theta, "theta", "Hub angle", Unit::Radian, real, false);
    push(RotatingOutput::ThetaDot, "theta_dot", "Hub speed", Unit::RadianPerSecond, real, false);
    push(RotatingOutput::TipDeflection, "tip.w", "Tip deflection in the rotating frame (transverse to the beam's axis)", Unit::Metre, real, false);
    push(RotatingOutput::TipX, "tip.x", "Tip position in the fixed frame, X", Unit::Metre, real, false);
    push(RotatingOutput::TipY, "tip.y", "Tip position in the fixed frame, Y", Unit::Metre, real, false);
    push(RotatingOutput::RootMoment, "root.M", "Bending moment at the clamped root, EI v''(0) (modal sum)", Unit::NewtonMetre, real, false);
    push(RotatingOutput::Energy, "energy", "Kinetic, strain and gravity energy of hub and beam plus the energy stored in the contact", Unit::Joule, real, false);
    if matches!(spec.hub, HubDrive::Prescribed(_)) {
        push(RotatingOutput::HubTorque, "hub.torque", "Torque the prescribed hub motion needs", Unit::NewtonMetre, real, false);
    }
    if let Some(surface) = &spec.surface {
        // The law's outputs that a surface has, and every contact's
        // impulse (before the dissipated energy: the FMU's order).
        let (force, _) = surface.law.formulas();
        let law_outputs = surface.law.outputs().iter().filter_map(|o: &LawOutput| o.surface.map(|text| (o, text)));
        for (o, text) in law_outputs {
            if o.what == StopOutput::DissipatedEnergy {
                push(RotatingOutput::Impulse, "stop.impulse", "Impulse of the contact force over the last communication step (>= 0)", Unit::NewtonSecond, real, true);
            }
            push(RotatingOutput::Law(o.what), &format!("stop.{}", o.suffix), &text.replace("{force}", force), o.unit, o.kind, o.discrete);
        }
    }
    out
}

/// Reads an output from a run at its current time.
pub fn evaluate(key: RotatingOutput, sim: &RotatingSimulation) -> Value {
    match key {
        RotatingOutput::Theta => Value::Real(sim.theta()),
        RotatingOutput::ThetaDot => Value::Real(sim.theta_dot()),
        RotatingOutput::TipDeflection => Value::Real(sim.tip_deflection()),
        RotatingOutput::TipX => Value::Real(sim.tip_position()[0]),
        RotatingOutput::TipY => Value::Real(sim.tip_position()[1]),
        RotatingOutput::RootMoment => Value::Real(sim.root_moment()),
        RotatingOutput::Energy => Value::Real(sim.total_energy()),
        RotatingOutput::HubTorque => Value::Real(sim.hub_torque()),
        RotatingOutput::Law(StopOutput::Force) => Value::Real(sim.contact_force()),
        RotatingOutput::Law(StopOutput::Penetration) => Value::Real(sim.penetration()),
        RotatingOutput::Law(StopOutput::Contact) => Value::Boolean(sim.contact_state() == Contact::Pressed),
        RotatingOutput::Law(StopOutput::Impacts) => Value::Integer(sim.contacts().min(i64::MAX as u64) as i64),
        RotatingOutput::Law(StopOutput::DissipatedEnergy) => Value::Real(sim.dissipated_energy()),
        RotatingOutput::Law(other) => unreachable!("a surface has no {other:?} output (its law's LawOutput::surface is None)"),
        RotatingOutput::Impulse => Value::Real(sim.last_impulse()),
    }
}
