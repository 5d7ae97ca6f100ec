//! SerializeFMUstate of both standards: a versioned, self-describing byte
//! format that restores in another process (never a copy of a struct with
//! pointers).
//!
//! Layout (little endian): magic `BEAMSTOP`, format version (u32), GUID
//! (u32 length + UTF-8; FMI 3.0's instantiation token is the same string),
//! then the snapshot field by field. The solver state
//! is stored as its defining numbers (anchor, phase, search position,
//! counters); everything derived from them is rebuilt on restore, so a
//! restored instance continues bit for bit like the original.

use crate::codec::{Reader, Writer};

use super::instance::{Instance, Modes, Snapshot};
use super::state::ModelState;

const MAGIC: &[u8; 8] = b"BEAMSTOP";
/// Version 2: the simulation writes its own state (with its own version)
/// and every restored state is validated. Version 3: the instance state
/// as a u32 (FMI 3.0's event mode), and whether an event's discrete
/// change is pending. Version 4: the choices of the instance that saved
/// it (event mode, early return).
pub const FORMAT_VERSION: u32 = 4;

/// The bytes of a state, under the GUID of the FMU that saved it.
pub fn serialize(s: &Snapshot) -> Vec<u8> {
    let mut w = Writer(Vec::new());
    w.0.extend_from_slice(MAGIC);
    w.u32(FORMAT_VERSION);
    w.str(&s.guid);
    w.u32(s.machine.code() as u32);
    w.f64(s.start_time);
    w.opt_f64(s.stop_time);
    w.f64(s.last_successful_time);
    w.u8(s.terminated as u8);
    w.u8(s.pending as u8);
    w.u8(s.made_with.event_mode_used as u8 | (s.made_with.early_return_allowed as u8) << 1);
    w.f64s(&s.parameters);
    w.f64s(&s.inputs);
    match &s.sim {
        None => w.u8(0),
        Some(sim) => {
            w.u8(1);
            sim.encode(&mut w);
        }
    }
    w.0
}

/// Reads a state written by [`serialize`] for this instance and checks it
/// as strictly as a state reached by set calls: a machine state that may
/// be restored (event mode only where the instance has event mode:
/// [`Instance::admits`]), finite times, parameters and
/// inputs within their ranges, and a simulation state the model can be in.
pub fn deserialize(instance: &Instance, bytes: &[u8]) -> Result<Snapshot, String> {
    let mut r = Reader::new(bytes);
    if r.take(MAGIC.len())? != MAGIC {
        return Err("not a beamstop FMU state (bad magic)".into());
    }
    let version = r.u32()?;
    if version != FORMAT_VERSION {
        return Err(format!(
            "serialized state format version {version}; this FMU reads version {FORMAT_VERSION} (states saved by an older build are not read: save them again with this one)"
        ));
    }
    let guid = r.str()?;
    if guid != instance.guid() {
        return Err(format!("serialized state belongs to FMU {guid}, not to this one ({})", instance.guid()));
    }
    let code = r.u32()?;
    let machine = u16::try_from(code)
        .ok()
        .and_then(ModelState::from_code)
        .ok_or_else(|| format!("serialized state: unknown instance state {code}"))?;
    let start_time = r.f64()?;
    let stop_time = r.opt_f64()?;
    let last_successful_time = r.f64()?;
    let terminated = r.u8()? != 0;
    let pending = match r.u8()? {
        0 => false,
        1 => true,
        b => return Err(format!("serialized state: pending-event flag {b}: must be 0 or 1")),
    };
    let modes = r.u8()?;
    if modes > 3 {
        return Err(format!("serialized state: instance choices {modes:#x}: must be within 0..=3 (event mode 1, early return 2)"));
    }
    let made_with = Modes { event_mode_used: modes & 1 != 0, early_return_allowed: modes & 2 != 0 };
    let table = instance.table();
    let parameters = r.f64s(table.interface.parameters.len(), "parameters")?;
    let inputs = r.f64s(table.interface.inputs.len(), "inputs")?;
    let has_sim = r.u8()? != 0;
    // The instance state first: an Error state is refused as such, whatever
    // else it holds.
    if matches!(machine, ModelState::Error | ModelState::Fatal) {
        return Err(format!("serialized state: instance state {machine:?} cannot be restored"));
    }
    if machine == ModelState::EventMode && !made_with.event_mode_used {
        return Err("serialized state: in event mode, saved by an instance without event mode".into());
    }
    if pending && !matches!(machine, ModelState::StepMode | ModelState::EventMode) {
        return Err(format!("serialized state: an event pending in instance state {machine:?}"));
    }
    match machine {
        ModelState::Instantiated | ModelState::InitializationMode if has_sim => {
            return Err(format!("serialized state: instance state {machine:?} with a running simulation"));
        }
        ModelState::StepMode | ModelState::EventMode | ModelState::StepDiscarded | ModelState::StepCanceled | ModelState::Terminated if !has_sim => {
            return Err(format!("serialized state: instance state {machine:?} without a simulation"));
        }
        _ => {}
    }
    if !start_time.is_finite() {
        return Err(format!("serialized state: start time = {start_time}: must be finite"));
    }
    if let Some(stop) = stop_time {
        if !stop.is_finite() || stop < start_time {
            return Err(format!("serialized state: stop time = {stop}: must be finite and >= the start time {start_time}"));
        }
    }
    if !last_successful_time.is_finite() || last_successful_time < start_time {
        return Err(format!(
            "serialized state: last successful time = {last_successful_time}: must be finite and >= the start time {start_time}"
        ));
    }
    for (input, value) in table.interface.inputs.iter().zip(&inputs) {
        input.range.check(&format!("serialized state: input '{}'", input.name), *value)?;
    }
    // The parameters are checked as fmi2SetReal checks them in the same
    // state: the scene's rules before a simulation exists, a whole model
    // once one does.
    let scene = instance.scene_with(&parameters);
    scene.validate().map_err(|e| format!("serialized state: parameters: {e}"))?;
    let sim = if has_sim {
        let sim = scene.decode(&inputs, &mut r)?;
        if sim.time() < start_time {
            return Err(format!("serialized state: simulation time {} before the start time {start_time}", sim.time()));
        }
        // What a run of the instance keeps: its last successful step ends
        // at the simulation's time or before, and no step goes past the
        // stop time (within [`Instance::check_step`]'s rounding).
        if last_successful_time > sim.time() {
            return Err(format!(
                "serialized state: last successful time = {last_successful_time}: must be <= the simulation time {}",
                sim.time()
            ));
        }
        if let Some(stop) = stop_time {
            if sim.time() > stop + 1e-9 * stop.abs().max(1.0) {
                return Err(format!("serialized state: simulation time {} past the stop time {stop}", sim.time()));
            }
        }
        if sim.earliest_time() < start_time {
            return Err(format!(
                "serialized state: the simulation refers to time {} (its anchor), before the start time {start_time}",
                sim.earliest_time()
            ));
        }
        Some(sim)
    } else {
        None
    };
    if r.remaining() != 0 {
        return Err(format!("serialized state has {} trailing bytes", r.remaining()));
    }
    let snapshot = Snapshot { guid: guid.to_string(), machine, parameters, inputs, start_time, stop_time, sim, last_successful_time, terminated, pending, made_with };
    instance.admits(&snapshot).map_err(|m| format!("serialized state: {m}"))?;
    Ok(snapshot)
}
