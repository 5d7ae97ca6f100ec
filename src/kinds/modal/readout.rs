//! The outputs' values: a scene's outputs (`crate::kinds::modal::interface`) read from a
//! simulation.

use crate::kinds::modal::interface::OutputKey;
use crate::kinds::modal::sim::Simulation;
pub use crate::variables::Value;

/// Reads an output from a simulation at its current time.
pub fn evaluate(key: OutputKey, sim: &Simulation) -> Value {
    let model = sim.model();
    let scale = model.coordinate_scale;
    let modal = || sim.field();
    match key {
        OutputKey::StopDisplacement(i) => Value::Real(sim.stop_motion(i).0),
        OutputKey::StopVelocity(i) => Value::Real(sim.stop_motion(i).1),
        OutputKey::StopImpacts(i) => Value::Integer(sim.state().stops[i].impacts.min(i64::MAX as u64) as i64),
        OutputKey::StopLastImpact(i) => Value::Real(sim.state().stops[i].last_impact),
        OutputKey::StopSticking(i) => Value::Boolean(sim.is_stuck(i)),
        OutputKey::StopSticks(i) => Value::Integer(sim.state().stops[i].sticks.min(i64::MAX as u64) as i64),
        OutputKey::StopStuckTime(i) => Value::Real(sim.stuck_time(i)),
        OutputKey::StopReaction(i) => Value::Real(sim.reaction(i)),
        OutputKey::StopForce(i) => Value::Real(sim.stop_force(i)),
        OutputKey::StopPenetration(i) => {
            let g = &model.stops[i].geometry;
            Value::Real(g.side * sim.stop_motion(i).0 - g.gap)
        }
        OutputKey::StopContact(i) => {
            Value::Boolean(sim.contact(i) == crate::contact::Contact::Pressed)
        }
        OutputKey::StopImpulse(i) => Value::Real(sim.last_impulse(i)),
        OutputKey::StopStoredEnergy(i) => Value::Real(sim.stop_stored_energy(i)),
        OutputKey::StopDissipatedEnergy(i) => Value::Real(sim.stop_dissipated_energy(i)),
        OutputKey::SensorDisplacement(i) => Value::Real(sim.sensor_motion(i).0),
        OutputKey::SensorVelocity(i) => Value::Real(sim.sensor_motion(i).1),
        OutputKey::SensorMoment(i) => Value::Real(sim.sensor_motion(i).2),
        OutputKey::Q(j) => Value::Real(modal().q[j] / scale),
        OutputKey::Qd(j) => Value::Real(modal().qd[j] / scale),
        OutputKey::Energy => Value::Real(sim.energy()),
        OutputKey::ForcingEnergy(j) => {
            Value::Real(sim.energy_balance().map_or(0.0, |b| b.forcing[j]))
        }
        OutputKey::DampingEnergy(j) => {
            Value::Real(sim.energy_balance().map_or(0.0, |b| b.damping[j]))
        }
        OutputKey::ImpactEnergy => Value::Real(sim.energy_balance().map_or(0.0, |b| b.impacts)),
    }
}
