//! What a rotating-beam scene exposes: its parameters (fixed for a run:
//! each one shapes the model the integration starts from), its input (the
//! hub torque, unless the hub's motion is prescribed) and its outputs, and
//! how each output is read from a run. Only what the scene uses appears: a
//! scene without a surface has no contact outputs, one without gravity no
//! `g`. Nothing here knows about FMI.

use super::spec::{HubDrive, Profile, RotatingSpec, SurfaceLaw, STIFFNESS_RANGE};
use super::RotatingSimulation;
use crate::contact::HertzDamping;
use crate::interface::{Input, Output, OutputType, Parameter};
use crate::readout::Value;
use crate::scene::Range;
use crate::units::Unit;

/// Where a parameter's value lives in the scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RotatingParam {
    HubInertia,
    HubRadius,
    Gravity,
    ModalDamping,
    SurfaceStiffness,
    /// `C` (linear damping) or `e` (hysteretic damping), by the law's damping.
    SurfaceDamping,
    Theta0,
    ThetaDot0,
    SpinRate,
    SpinDuration,
}

impl RotatingParam {
    pub fn get(self, spec: &RotatingSpec) -> f64 {
        let hertz = || spec.surface.as_ref().map(|s| s.law.hertz()).expect("a surface parameter needs a surface");
        let spin = || match spec.hub {
            HubDrive::Prescribed(Profile::SpinUp { omega_s, duration }) => (omega_s, duration),
            HubDrive::Torque => panic!("a spin-up parameter needs a prescribed hub"),
        };
        match self {
            RotatingParam::HubInertia => spec.hub_inertia,
            RotatingParam::HubRadius => spec.hub_radius,
            RotatingParam::Gravity => spec.gravity,
            RotatingParam::ModalDamping => spec.modal_damping,
            RotatingParam::SurfaceStiffness => hertz().stiffness,
            RotatingParam::SurfaceDamping => match hertz().damping {
                HertzDamping::Linear => hertz().damping_coefficient,
                _ => hertz().restitution,
            },
            RotatingParam::Theta0 => spec.initial.theta,
            RotatingParam::ThetaDot0 => spec.initial.theta_dot,
            RotatingParam::SpinRate => spin().0,
            RotatingParam::SpinDuration => spin().1,
        }
    }

    pub fn set(self, spec: &mut RotatingSpec, value: f64) {
        *self.slot(spec) = value;
    }

    fn slot(self, spec: &mut RotatingSpec) -> &mut f64 {
        match self {
            RotatingParam::HubInertia => &mut spec.hub_inertia,
            RotatingParam::HubRadius => &mut spec.hub_radius,
            RotatingParam::Gravity => &mut spec.gravity,
            RotatingParam::ModalDamping => &mut spec.modal_damping,
            RotatingParam::SurfaceStiffness | RotatingParam::SurfaceDamping => {
                let SurfaceLaw::Hertz(h) = &mut spec.surface.as_mut().expect("a surface parameter needs a surface").law;
                match (self, h.damping) {
                    (RotatingParam::SurfaceStiffness, _) => &mut h.stiffness,
                    (_, HertzDamping::Linear) => &mut h.damping_coefficient,
                    _ => &mut h.restitution,
                }
            }
            RotatingParam::Theta0 => &mut spec.initial.theta,
            RotatingParam::ThetaDot0 => &mut spec.initial.theta_dot,
            RotatingParam::SpinRate | RotatingParam::SpinDuration => match &mut spec.hub {
                HubDrive::Prescribed(Profile::SpinUp { omega_s, duration }) => {
                    if self == RotatingParam::SpinRate {
                        omega_s
                    } else {
                        duration
                    }
                }
                HubDrive::Torque => panic!("a spin-up parameter needs a prescribed hub"),
            },
        }
    }
}

/// The hub torque is the only input.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct HubTorque;

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
    Force,
    Penetration,
    Contact,
    Contacts,
    Impulse,
    DissipatedEnergy,
}

/// Every parameter of the scene, in a stable order; all fixed for a run.
pub fn parameters(spec: &RotatingSpec) -> Vec<Parameter<RotatingParam>> {
    let mut out = Vec::new();
    let mut push = |key, name: &str, scene_path: &str, description: String, unit, range| {
        out.push(Parameter { key, name: name.into(), scene_path: scene_path.into(), description, unit, range, tunable: false });
    };
    let prescribed = matches!(spec.hub, HubDrive::Prescribed(_));
    let inertia_note = if prescribed {
        "enters only the torque the prescribed motion needs"
    } else {
        "a torque-driven hub needs J_h > 0: at 0 the mass matrix is near-singular"
    };
    push(
        RotatingParam::HubInertia,
        "J_h",
        "hub_inertia",
        format!("Moment of inertia of the hub about its axis ({inertia_note})"),
        Unit::KilogramMetre2,
        spec.hub_inertia_range(),
    );
    if spec.hub_radius != 0.0 {
        push(RotatingParam::HubRadius, "R", "hub_radius", "Distance from the axis to the clamped root".into(), Unit::Metre, spec.hub_radius_range());
    }
    if spec.gravity != 0.0 {
        push(RotatingParam::Gravity, "g", "gravity", "Gravity along -Y, in the plane of rotation".into(), Unit::MetrePerSecond2, spec.gravity_range());
    }
    if spec.modal_damping != 0.0 {
        push(RotatingParam::ModalDamping, "zeta", "modal_damping", "Damping ratio of every bending mode".into(), Unit::One, Range::closed(0.0, 10.0));
    }
    if let Some(surface) = &spec.surface {
        let h = surface.law.hertz();
        push(
            RotatingParam::SurfaceStiffness,
            "K",
            "surface.law.K",
            "Hertz stiffness of the surface: force K gamma^1.5 + damping, gamma the tip's penetration (seed 004 eq. 2)".into(),
            Unit::NewtonPerMetre1_5,
            STIFFNESS_RANGE,
        );
        match h.damping {
            HertzDamping::Linear => push(
                RotatingParam::SurfaceDamping,
                "C",
                "surface.law.C",
                "Linear contact damping C: force K gamma^1.5 + C gamma', never pulling (seed 004 eq. 2)".into(),
                Unit::NewtonSecondPerMetre,
                spec.damping_range(),
            ),
            damping => push(
                RotatingParam::SurfaceDamping,
                "e",
                "surface.law.e",
                format!(
                    "Restitution the {} hysteretic damping aims at",
                    if damping == HertzDamping::HuntCrossley { "Hunt-Crossley" } else { "Lankarani-Nikravesh" }
                ),
                Unit::One,
                Range::UNIT,
            ),
        }
    }
    push(RotatingParam::Theta0, "theta0", "initial.theta", "Initial hub angle".into(), Unit::Radian, spec.angle_range());
    match spec.hub {
        HubDrive::Torque => push(RotatingParam::ThetaDot0, "theta_dot0", "initial.theta_dot", "Initial hub speed".into(), Unit::RadianPerSecond, spec.speed_range()),
        HubDrive::Prescribed(Profile::SpinUp { .. }) => {
            push(
                RotatingParam::SpinRate,
                "omega_s",
                "hub.prescribed.omega_s",
                "Final hub speed of the spin-up theta' = omega_s / T (t - T / (2 pi) sin(2 pi t / T)), t < T".into(),
                Unit::RadianPerSecond,
                spec.speed_range(),
            );
            push(RotatingParam::SpinDuration, "T", "hub.prescribed.T", "Duration of the spin-up".into(), Unit::Second, spec.spin_duration_range());
        }
    }
    out
}

pub fn inputs(spec: &RotatingSpec) -> Vec<Input<HubTorque>> {
    match spec.hub {
        HubDrive::Torque => vec![Input {
            key: HubTorque,
            name: "torque".into(),
            description: "Torque on the hub (positive counter-clockwise), held constant over each communication step".into(),
            unit: Unit::NewtonMetre,
            range: spec.torque_range(),
        }],
        HubDrive::Prescribed(_) => Vec::new(),
    }
}

pub fn outputs(spec: &RotatingSpec) -> Vec<Output<RotatingOutput>> {
    let mut out = Vec::new();
    let mut push = |key, name: &str, description: &str, unit, kind, discrete| {
        out.push(Output { key, name: name.into(), description: description.into(), unit, kind, discrete });
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
    if spec.surface.is_some() {
        push(RotatingOutput::Force, "stop.force", "Force the surface pushes the tip with, max(0, K gamma^1.5 + damping)", Unit::Newton, real, false);
        push(RotatingOutput::Penetration, "stop.penetration", "Penetration gamma of the tip into the surface (0 outside)", Unit::Metre, real, false);
        push(RotatingOutput::Contact, "stop.contact", "Whether the surface pushes the tip", Unit::One, OutputType::Boolean, true);
        push(RotatingOutput::Contacts, "stop.contacts", "Number of contact onsets since the start", Unit::One, OutputType::Integer, true);
        push(RotatingOutput::Impulse, "stop.impulse", "Impulse of the contact force over the last communication step (>= 0)", Unit::NewtonSecond, real, true);
        push(
            RotatingOutput::DissipatedEnergy,
            "stop.E_dissipated",
            "Energy the contact dissipated since the start (its damping, and the spring energy left when a push ends inside the surface)",
            Unit::Joule,
            real,
            false,
        );
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
        RotatingOutput::Force => Value::Real(sim.contact_force()),
        RotatingOutput::Penetration => Value::Real(sim.penetration()),
        RotatingOutput::Contact => Value::Boolean(sim.contact_state() == super::ContactState::Pressed),
        RotatingOutput::Contacts => Value::Integer(sim.contacts().min(i64::MAX as u64) as i64),
        RotatingOutput::Impulse => Value::Real(sim.last_impulse()),
        RotatingOutput::DissipatedEnergy => Value::Real(sim.dissipated_energy()),
    }
}
