//! `PDController.fmu`: a sampled PD (PID with anti-windup) controller of a
//! hub angle, the partner of `RotatingBeamImpact.fmu` in the coupling
//! example (examples/coupling/): libcosim couples the two through an OSP
//! system structure.
//!
//! This crate is a kind of simulation of its own ([`beamstop::kind`]),
//! registered here with beamstop's registry of kinds; beamstop's one FMI layer
//! makes the FMU of it. Built without beamstop's default `beam` feature,
//! the FMU carries only this kind. `cargo run --release -p
//! pd_controller_fmu --bin package-pd-controller -- OUT_DIR` builds it.
//!
//! **The law.** At the start `t` of each step `[t, t + h]` the controller
//! samples its inputs `theta`, `theta_dot` and computes
//!
//! ```text
//! e = r(t) - theta
//! v = Kp e + Kd (r'(t) - theta_dot) + Ki I
//! torque = clamp(v, -torque_max, torque_max)
//! ```
//!
//! and then integrates `I += e h` (`h` the difference of the step's end and
//! start times) unless the output saturates with the error pushing it
//! further (clamping anti-windup). The reference `r(t)` slews from
//! `theta_start` to `theta_ref` over `T_slew` seconds along the
//! minimum-jerk quintic `10 s^3 - 15 s^4 + 6 s^5`, `s = (t - t0) / T_slew`
//! (a step at `t0` when `T_slew = 0`). The output `torque` is this sample,
//! held until the next step: a digital controller whose result is applied
//! one sample after its inputs were read. Before the first step the
//! outputs are the law at the start time with the current inputs and
//! `I = 0`, so a master that propagates initial values (libcosim does)
//! hands the plant a torque for its first step.
//!
//! Ordering: stepped after the plant (Jacobi, libcosim's fixed-step
//! algorithm), the plant's torque over `[t_k, t_k+1]` is the law at
//! `t_k-1`; stepped before it with `theta(t_k)` set first (Gauss-Seidel),
//! the law at `t_k`. The Python mirror of this law
//! (`beamstop_tools.coupling.controller`) performs the same floating-point
//! operations in the same order, so the two give the same torques bit for bit.

use std::sync::Arc;

use beamstop::codec::{Reader, Writer};
use beamstop::kind::{EventRecord, Kind, Reached, Registration, Run, Scene, SimError, Work};
use beamstop::variables::{Experiment, Input, Output, OutputType, Parameter, Range, Unit, Value, Variables};
use serde::{Deserialize, Serialize};
use serde_json::Value as Json;

/// The controller's scene file: `{"kind": "pd_controller", "name": ..., "Kp": ..., ...}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PdScene {
    pub kind: String,
    pub name: String,
    #[serde(default)]
    pub description: String,
    #[serde(rename = "Kp")]
    pub kp: f64,
    #[serde(rename = "Kd")]
    pub kd: f64,
    #[serde(rename = "Ki")]
    pub ki: f64,
    pub theta_ref: f64,
    pub theta_start: f64,
    #[serde(rename = "T_slew")]
    pub t_slew: f64,
    pub torque_max: f64,
    #[serde(default = "default_experiment")]
    pub experiment: Experiment,
}

fn default_experiment() -> Experiment {
    Experiment { start: 0.0, stop: 1.3, step: 1e-4 }
}

/// Largest gain, angle and torque (the controller runs at any size; these
/// keep every value finite through the law).
const GAIN: f64 = 1e9;
const ANGLE: f64 = 1e4;
const SPEED: f64 = 1e6;
const TORQUE: f64 = 1e12;

fn parameters() -> Vec<Parameter> {
    let p = |name: &str, description: &str, unit, range| Parameter {
        name: name.into(),
        scene_path: name.into(),
        description: description.into(),
        unit,
        range,
        tunable: false,
    };
    vec![
        p("Kp", "Proportional gain", Unit::NewtonMetrePerRadian, Range::closed(-GAIN, GAIN)),
        p("Kd", "Derivative gain (on r' - theta_dot)", Unit::NewtonMetreSecondPerRadian, Range::closed(-GAIN, GAIN)),
        p("Ki", "Integral gain (0: PD)", Unit::NewtonMetrePerRadianSecond, Range::closed(-GAIN, GAIN)),
        p("theta_ref", "Target hub angle the slew ends at", Unit::Radian, Range::closed(-ANGLE, ANGLE)),
        p("theta_start", "Hub angle the slew starts from", Unit::Radian, Range::closed(-ANGLE, ANGLE)),
        p("T_slew", "Duration of the slew from the start time (0: a step)", Unit::Second, Range::closed(0.0, 1e6)),
        p("torque_max", "Torque limit", Unit::NewtonMetre, Range { min: 0.0, max: TORQUE, min_open: true, max_open: false }),
    ]
}

fn variables() -> Variables {
    let input = |name: &str, description: &str, unit, limit: f64| Input { name: name.into(), description: description.into(), unit, range: Range::closed(-limit, limit) };
    let output = |name: &str, description: &str, unit| Output { name: name.into(), description: description.into(), unit, kind: OutputType::Real, discrete: true };
    Variables {
        parameters: parameters(),
        inputs: vec![input("theta", "Measured hub angle", Unit::Radian, ANGLE), input("theta_dot", "Measured hub speed", Unit::RadianPerSecond, SPEED)],
        outputs: vec![
            output("torque", "Commanded hub torque: the latest sample of the law, held", Unit::NewtonMetre),
            output("theta_r", "Reference angle at the latest sample", Unit::Radian),
            output("integral", "Integral of the error I", Unit::RadianSecond),
        ],
    }
}

/// The kind: scene files with `"kind": "pd_controller"`.
pub struct PdKind;

inventory::submit! { Registration(&PdKind) }

impl Kind for PdKind {
    fn name(&self) -> &'static str {
        "pd_controller"
    }

    fn recognizes(&self, scene: &Json) -> bool {
        scene.get("kind").and_then(Json::as_str) == Some("pd_controller")
    }

    fn load(&self, scene: &Json) -> Result<Box<dyn Scene>, String> {
        let s: PdScene = serde_json::from_value(scene.clone()).map_err(|e| format!("controller scene: {e}"))?;
        let json = serde_json::to_value(&s).map_err(|e| e.to_string())?;
        for p in parameters() {
            let v = beamstop::fields::get(&json, &p.scene_path)?;
            p.range.check(&p.name, v)?;
        }
        Ok(Box::new(PdLoaded(Arc::new(s))))
    }
}

/// A validated controller scene.
#[derive(Debug)]
struct PdLoaded(Arc<PdScene>);

impl Scene for PdLoaded {
    fn name(&self) -> &str {
        &self.0.name
    }

    fn description(&self) -> &str {
        &self.0.description
    }

    fn experiment(&self) -> Experiment {
        self.0.experiment.clone()
    }

    fn canonical(&self) -> String {
        serde_json::to_string_pretty(&*self.0).expect("a controller scene always serialises")
    }

    fn variables(&self) -> Variables {
        variables()
    }

    fn method(&self) -> &'static str {
        "A sampled controller: at the start of each step it reads theta and theta_dot, evaluates the \
         law and holds the torque over the step; the integral of the error advances by e h unless \
         the torque saturates with the error pushing it further."
    }

    fn shortest_period(&self) -> Result<f64, SimError> {
        // Nothing to resolve but the slew (as its runs say).
        Ok(self.0.t_slew.max(1.0))
    }

    fn start(&self, start_time: f64, inputs: &[f64]) -> Result<Box<dyn Run>, SimError> {
        let mut run = Controller { p: self.0.clone(), t_start: start_time, time: start_time, theta: 0.0, theta_dot: 0.0, sampled: false, torque: 0.0, theta_r: 0.0, integral: 0.0 };
        run.set_inputs(inputs)?;
        Ok(Box::new(run))
    }

    fn decode(&self, inputs: &[f64], r: &mut Reader) -> Result<Box<dyn Run>, String> {
        let version = r.u32()?;
        if version != STATE_VERSION {
            return Err(format!("controller state version {version}, this FMU reads {STATE_VERSION}"));
        }
        let sampled = match r.u8()? {
            0 => false,
            1 => true,
            b => return Err(format!("controller state: sampled flag {b} is not a Boolean")),
        };
        let x = r.f64s(7, "controller state")?;
        if let Some(i) = x.iter().position(|v| !v.is_finite()) {
            return Err(format!("controller state: entry {i} = {}: must be finite", x[i]));
        }
        if !(x[0] <= x[1]) {
            return Err(format!("controller state: time {} before the start {}", x[1], x[0]));
        }
        if (x[2], x[3]) != (inputs[0], inputs[1]) {
            return Err("controller state: theta and theta_dot differ from the saved inputs".into());
        }
        let run = Controller { p: self.0.clone(), sampled, t_start: x[0], time: x[1], theta: x[2], theta_dot: x[3], torque: x[4], theta_r: x[5], integral: x[6] };
        Ok(Box::new(run))
    }
}

const STATE_VERSION: u32 = 2;

/// One sample of the law.
struct Sample {
    torque: f64,
    reference: f64,
    error: f64,
    /// The integral holds still (anti-windup).
    frozen: bool,
}

/// A run of the controller.
#[derive(Clone, Debug)]
struct Controller {
    p: Arc<PdScene>,
    /// Start time of the experiment: the slew's t0.
    t_start: f64,
    time: f64,
    theta: f64,
    theta_dot: f64,
    /// Whether a step has sampled the inputs (else the outputs follow them).
    sampled: bool,
    torque: f64,
    theta_r: f64,
    /// Integral of the error up to `time`.
    integral: f64,
}

impl Controller {
    /// The reference and its rate at `t`.
    fn reference(&self, t: f64) -> (f64, f64) {
        let p = &self.p;
        if !(p.t_slew > 0.0) {
            return (p.theta_ref, 0.0);
        }
        let s = ((t - self.t_start) / p.t_slew).clamp(0.0, 1.0);
        if s == 1.0 {
            return (p.theta_ref, 0.0);
        }
        let d = p.theta_ref - p.theta_start;
        let shape = s * s * s * (10.0 + s * (-15.0 + s * 6.0));
        let rate = 30.0 * s * s * (1.0 - s) * (1.0 - s) / p.t_slew;
        (p.theta_start + d * shape, d * rate)
    }

    /// The law at `t` with the current inputs and integral.
    fn law(&self, t: f64) -> Sample {
        let p = &self.p;
        let (r, r_dot) = self.reference(t);
        let e = r - self.theta;
        let v = p.kp * e + p.kd * (r_dot - self.theta_dot) + p.ki * self.integral;
        let torque = v.max(-p.torque_max).min(p.torque_max);
        Sample { torque, reference: r, error: e, frozen: torque != v && e * v > 0.0 }
    }
}

impl Run for Controller {
    fn time(&self) -> f64 {
        self.time
    }

    fn shortest_period(&self) -> f64 {
        // Nothing to resolve but the slew.
        self.p.t_slew.max(1.0)
    }

    /// A sampled controller has no events: every advance reaches `t`.
    fn advance(&mut self, t: f64, _stop_before: Option<&mut dyn FnMut(f64) -> bool>) -> Result<Reached, SimError> {
        if t < self.time {
            return Err(SimError::Backwards { now: self.time, requested: t });
        }
        if t == self.time {
            return Ok(Reached::Time);
        }
        let s = self.law(self.time);
        self.torque = s.torque;
        self.theta_r = s.reference;
        if !s.frozen {
            self.integral += s.error * (t - self.time);
        }
        self.sampled = true;
        self.time = t;
        Ok(Reached::Time)
    }

    fn set_inputs(&mut self, inputs: &[f64]) -> Result<(), SimError> {
        self.theta = inputs[0];
        self.theta_dot = inputs[1];
        Ok(())
    }

    fn set_event_recording(&mut self, _on: bool) {}

    fn drain_events(&mut self) -> Vec<EventRecord> {
        Vec::new()
    }

    fn evaluate(&self, index: usize) -> Value {
        let unsampled = || self.law(self.t_start);
        Value::Real(match (index, self.sampled) {
            (0, true) => self.torque,
            (0, false) => unsampled().torque,
            (1, true) => self.theta_r,
            (1, false) => unsampled().reference,
            _ => self.integral,
        })
    }

    fn encode(&self, w: &mut Writer) {
        w.u32(STATE_VERSION);
        w.u8(self.sampled as u8);
        w.f64s(&[self.t_start, self.time, self.theta, self.theta_dot, self.torque, self.theta_r, self.integral]);
    }

    fn work(&self) -> Work {
        Work { events: 0, units: 0, unit: "samples", cap: u64::MAX }
    }
}
