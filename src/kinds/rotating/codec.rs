//! The run's versioned byte encoding. The state is the last restart (its
//! time, state vector and contact law), the time, the counters and the
//! input; the decoder checks every number, the ordering of the times and
//! the contact state against the geometry, then rebuilds the integrator at
//! the anchor and replays its steps up to the time (the step grid depends
//! only on the anchor), so a restored run continues bit for bit. The
//! replayed state must reproduce the encoded one.

use std::sync::Arc;

use super::model::RotatingModel;
use super::sim::{RotatingSimulation, RotatingStats, REANCHOR_AFTER};
use super::system::Phase;
use crate::codec::{Reader, Writer};
use crate::contact::Contact;
use crate::solve::radau::RadauOptions;
use super::stepper::Stepper;

/// Version of the encoding below; bump on any change.
/// 2: the shared contact-state codes (open 0, pressed 2, penetrated 3).
pub const ROTATING_STATE_VERSION: u32 = 2;

fn bad(m: String) -> String {
    m
}

fn num(r: &mut Reader, what: &str) -> Result<f64, String> {
    let v = r.f64().map_err(|m| bad(format!("rotating state: {m}")))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(bad(format!("rotating state: {what} = {v}: must be finite")))
    }
}

impl RotatingSimulation {
    /// Appends the state (see [`Self::decode`]).
    pub fn encode(&self, w: &mut Writer) {
        w.u32(ROTATING_STATE_VERSION);
        w.u32(self.model.n_modes() as u32);
        w.u8(self.model.prescribed().is_some() as u8);
        w.u8(self.phase.contact.code());
        w.f64(self.time);
        w.f64(self.anchor_time);
        w.f64(self.phase.torque);
        w.f64(self.phase.onset_speed);
        w.u64(self.onsets);
        w.f64(self.impulse_mark);
        w.f64(self.peak_before_anchor);
        w.f64(self.contact_start);
        w.f64(self.impulse_at_start);
        w.f64s(self.anchor.as_slice());
        w.f64s(self.current.as_slice());
    }

    /// A run of `model` restored from [`Self::encode`]'s bytes; refused,
    /// with a message naming the field, unless the model can be in it.
    pub fn decode(model: Arc<RotatingModel>, r: &mut Reader) -> Result<Self, String> {
        let e = |m: String| bad(format!("rotating state: {m}"));
        let version = r.u32().map_err(e)?;
        if version != ROTATING_STATE_VERSION {
            return Err(bad(format!("rotating state version {version}; this build reads version {ROTATING_STATE_VERSION}")));
        }
        let n = r.u32().map_err(e)? as usize;
        let prescribed = r.u8().map_err(e)?;
        if n != model.n_modes() || (prescribed != 0) != model.prescribed().is_some() || prescribed > 1 {
            return Err(bad(format!(
                "rotating state has {n} modes and drive code {prescribed}, the model {} modes and a {} hub",
                model.n_modes(),
                if model.prescribed().is_some() { "prescribed (code 1)" } else { "torque-driven (code 0)" }
            )));
        }
        let code = r.u8().map_err(e)?;
        let contact = Contact::from_code(code)
            .filter(|c| *c != Contact::Held)
            .ok_or_else(|| bad(format!("rotating state: contact code {code} is not one of 0 (open), 2 (pressed), 3 (penetrated)")))?;
        let time = num(r, "time")?;
        let anchor_time = num(r, "anchor time")?;
        let torque = num(r, "torque")?;
        let onset_speed = num(r, "onset speed")?;
        let onsets = r.u64().map_err(e)?;
        let impulse_mark = num(r, "impulse mark")?;
        let peak_before_anchor = num(r, "peak force")?;
        let contact_start = num(r, "contact start")?;
        let impulse_at_start = num(r, "impulse at the contact's start")?;
        let phase = Phase { model: model.clone(), contact, onset_speed, torque };
        let dim = phase.dim();
        let anchor = nalgebra::DVector::from_vec(r.f64s(dim, "anchor state entries").map_err(e)?);
        let current = nalgebra::DVector::from_vec(r.f64s(dim, "current state entries").map_err(e)?);
        for (what, v) in [("anchor", &anchor), ("current", &current)] {
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return Err(bad(format!("rotating state: {what}[{i}] = {}: must be finite", v[i])));
            }
        }
        if anchor_time > time {
            return Err(bad(format!("rotating state: anchor time {anchor_time} <= time {time} must hold")));
        }
        if onsets > 0 && contact_start > anchor_time {
            return Err(bad(format!("rotating state: contact start {contact_start} <= anchor time {anchor_time} must hold")));
        }
        if onset_speed < 0.0 || peak_before_anchor < 0.0 {
            return Err(bad(format!("rotating state: onset speed {onset_speed} and peak force {peak_before_anchor} must be >= 0")));
        }
        if model.prescribed().is_some() && torque != 0.0 {
            return Err(bad(format!("rotating state: torque = {torque} on a prescribed hub: allowed value 0")));
        }
        if model.surface.is_none() && (contact != Contact::Open || onsets > 0) {
            return Err(bad("rotating state: in contact, but the model has no surface".into()));
        }
        let x = phase.extras();
        let impulse = anchor[x];
        // Zero's rounding below the normal range (a force of a subnormal
        // stiffness integrated) is zero.
        if impulse < -f64::MIN_POSITIVE || impulse_at_start > impulse * (1.0 + 1e-12) + f64::MIN_POSITIVE {
            return Err(bad(format!(
                "rotating state: impulse {impulse:e} must be >= 0 and >= the impulse at the contact's start, {impulse_at_start:e}"
            )));
        }
        if onsets == 0 && contact != Contact::Open {
            return Err(bad(format!("rotating state: {contact:?} with no contact onset counted")));
        }
        // The contact state agrees with the penetration at the anchor and now.
        for (what, t, y) in [("anchor", anchor_time, &anchor), ("current state", time, &current)] {
            let (z, zd) = phase.coords(t, y);
            let level = penetration_level(&model, &z);
            let point = phase.contact_point(&z, &zd);
            let gamma = point.penetration;
            let agrees = match contact {
                Contact::Open | Contact::Held => gamma <= level,
                Contact::Pressed | Contact::Penetrated => gamma >= -level,
            };
            if !agrees {
                return Err(bad(format!("rotating state: {contact:?} with penetration {gamma:e} at the {what} (allowed level {level:e})")));
            }
            // In contact, the law's force agrees with the state: pressed
            // while it pushes, penetrated while it would pull.
            if let (Some(s), true) = (&model.surface, contact != Contact::Open) {
                let (raw, dp, dpd) = s.law.raw_force(gamma.max(0.0), point.rate, onset_speed);
                let force_level = dp.abs() * level + dpd.abs() * 1e-9 * point.rate.abs().max(f64::MIN_POSITIVE) + 1e-12 * raw.abs();
                let pushes = match contact {
                    Contact::Pressed => raw >= -force_level,
                    _ => raw <= force_level,
                };
                if !pushes {
                    return Err(bad(format!(
                        "rotating state: {contact:?} at the {what}, but the contact law's force there is {raw:e} N \
                         (penetration {gamma:e} m, rate {:e} m/s): {}",
                        point.rate,
                        if contact == Contact::Pressed { "a pressed contact pushes" } else { "a penetrated contact's law would push" }
                    )));
                }
            }
        }
        let solver = Stepper::new(model.spec.solver.method, &phase, anchor_time, &anchor, &RadauOptions::default())
            .map_err(|er| bad(format!("rotating state: the anchor cannot be integrated: {er}")))?;
        let mut sim = RotatingSimulation {
            model,
            phase,
            solver,
            options: RadauOptions::default(),
            release_floor: None,
            anchor_time,
            anchor: anchor.clone(),
            step: None,
            time: anchor_time,
            current: anchor,
            readings: Default::default(),
            curve_room: Default::default(),
            spare_y0: nalgebra::DVector::zeros(0),
            onsets,
            impulse_mark,
            peak_before_anchor,
            peak: peak_before_anchor,
            contact_start,
            impulse_at_start,
            events: Vec::new(),
            stats: RotatingStats::default(),
            steps_since_anchor: 0,
            trace: None,
        };
        sim.start_phase().map_err(|e| format!("rotating state: {e}"))?;
        // Replay: the steps the run took from its anchor up to its time.
        while sim.step.as_ref().map_or(sim.anchor_time < time, |s| s.t1 < time) {
            if sim.steps_since_anchor >= REANCHOR_AFTER {
                return Err(bad(format!(
                    "rotating state: the time {time} lies more than {REANCHOR_AFTER} integration steps after the anchor {anchor_time}"
                )));
            }
            sim.take_step().map_err(|e| format!("rotating state: {e}"))?;
            if let Some((te, _, _)) = sim.step.as_ref().and_then(|s| s.switch) {
                // At the time: a switch the run stopped before (pending).
                if te < time {
                    return Err(bad(format!("rotating state: a contact switch at t = {te} lies before the time {time} but after the anchor")));
                }
            }
            let t1 = sim.step.as_ref().expect("a step").t1;
            sim.pass_to(t1.min(time));
        }
        sim.pass_to(time);
        sim.current = sim.state_at(time);
        let scale = current.amax().max(f64::MIN_POSITIVE);
        let off = (&sim.current - &current).amax();
        if off > 1e-9 * scale {
            return Err(bad(format!(
                "rotating state: the current state is {off:e} away from the motion its anchor gives at t = {time} (scale {scale:e})"
            )));
        }
        if !(impulse_mark <= sim.impulse_total().max(0.0) * (1.0 + 1e-9) + f64::MIN_POSITIVE && impulse_mark >= 0.0) {
            return Err(bad(format!("rotating state: impulse mark {impulse_mark} outside [0, impulse so far {}]", sim.impulse_total())));
        }
        Ok(sim)
    }
}

/// How far past the surface a state the run wrote may lie on the wrong
/// side of its contact state: a switch is located on the integrator's
/// dense output and the state there is a full-order step of its own, two
/// approximations that agree to the error the tolerance controls. That
/// error, for the tip's penetration, is the tolerance times the size of
/// what makes it up: the hub angle's share `(R + L) |theta|` (integrated
/// with a relative tolerance, unless the hub is prescribed), each mode's
/// `|w_j| |b_j|`, and the floor of the modal amplitudes the integrator
/// scales its absolute tolerance by (see `RotatingSimulation::phase_options`);
/// 16 times that, and never below 1e-9 of the tip radius.
fn penetration_level(model: &RotatingModel, z: &nalgebra::DVector<f64>) -> f64 {
    let n = model.n_modes();
    let radius = model.tip_radius();
    let floor = 1e-4 * model.beam.params.length;
    let hub = if model.prescribed().is_some() { 0.0 } else { radius * z[0].abs() + floor };
    let modes: f64 = (0..n).map(|j| model.beam.w[j].abs() * (z[1 + j].abs() + floor)).sum();
    (16.0 * model.spec.solver.integration_rtol() * (hub + modes)).max(1e-9 * radius)
}
