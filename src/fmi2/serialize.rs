//! fmi2SerializeFMUstate: a versioned, self-describing byte format that
//! restores in another process (never a copy of a struct with pointers).
//!
//! Layout (little endian): magic `BEAMSTOP`, format version (u32), GUID
//! (u32 length + UTF-8), then the snapshot field by field. The solver state
//! is stored as its defining numbers (anchor, phase, search position,
//! counters); everything derived from them is rebuilt on restore, so a
//! restored instance continues bit for bit like the original.

use nalgebra::DVector;

use crate::model::Model;
use crate::sim::{EnergyBalance, SimState, Simulation, StopState};
use crate::solve::ModalState;

use super::instance::{Instance, Snapshot};
use super::state_machine::ModelState;

const MAGIC: &[u8; 8] = b"BEAMSTOP";
pub const FORMAT_VERSION: u32 = 1;

struct Writer(Vec<u8>);

impl Writer {
    fn u8(&mut self, v: u8) {
        self.0.push(v);
    }
    fn u32(&mut self, v: u32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn f64(&mut self, v: f64) {
        self.0.extend_from_slice(&v.to_bits().to_le_bytes());
    }
    fn opt_f64(&mut self, v: Option<f64>) {
        self.u8(v.is_some() as u8);
        self.f64(v.unwrap_or(0.0));
    }
    fn f64s(&mut self, v: &[f64]) {
        self.u32(v.len() as u32);
        v.iter().for_each(|x| self.f64(*x));
    }
    fn str(&mut self, s: &str) {
        self.u32(s.len() as u32);
        self.0.extend_from_slice(s.as_bytes());
    }
    fn modal(&mut self, m: &ModalState) {
        self.f64s(m.q.as_slice());
        self.f64s(m.qd.as_slice());
    }
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len()).ok_or_else(|| {
            format!("serialized state truncated: need {n} bytes at offset {}, have {}", self.at, self.bytes.len())
        })?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn u8(&mut self) -> Result<u8, String> {
        Ok(self.take(1)?[0])
    }
    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().expect("4 bytes")))
    }
    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().expect("8 bytes")))
    }
    fn f64(&mut self) -> Result<f64, String> {
        Ok(f64::from_bits(self.u64()?))
    }
    fn opt_f64(&mut self) -> Result<Option<f64>, String> {
        let flag = self.u8()?;
        let v = self.f64()?;
        Ok(if flag != 0 { Some(v) } else { None })
    }
    fn f64s(&mut self, expected: usize, what: &str) -> Result<Vec<f64>, String> {
        let n = self.u32()? as usize;
        if n != expected {
            return Err(format!("serialized state has {n} {what}, this FMU has {expected}"));
        }
        (0..n).map(|_| self.f64()).collect()
    }
    fn str(&mut self) -> Result<String, String> {
        let n = self.u32()? as usize;
        String::from_utf8(self.take(n)?.to_vec()).map_err(|_| "serialized state: GUID is not UTF-8".to_string())
    }
    fn modal(&mut self, n: usize) -> Result<ModalState, String> {
        Ok(ModalState {
            q: DVector::from_vec(self.f64s(n, "modal displacements")?),
            qd: DVector::from_vec(self.f64s(n, "modal velocities")?),
        })
    }
}

pub fn serialize(guid: &str, s: &Snapshot) -> Vec<u8> {
    let mut w = Writer(Vec::new());
    w.0.extend_from_slice(MAGIC);
    w.u32(FORMAT_VERSION);
    w.str(guid);
    w.u8(s.machine as u8);
    w.f64(s.start_time);
    w.opt_f64(s.stop_time);
    w.f64(s.last_successful_time);
    w.u8(s.terminated as u8);
    w.f64s(&s.parameters);
    w.f64s(&s.inputs);
    match &s.sim {
        None => w.u8(0),
        Some(sim) => {
            w.u8(1);
            let st = sim.state();
            w.u32(st.anchor.q.len() as u32);
            w.u32(st.stops.len() as u32);
            w.f64(st.time);
            w.f64(st.anchor_time);
            w.modal(&st.anchor);
            w.u64(st.stuck);
            w.f64(st.scan);
            w.u64(st.departing);
            for stop in &st.stops {
                w.u64(stop.impacts);
                w.f64(stop.last_impact);
                w.opt_f64(stop.previous_impact);
            }
            w.modal(&st.current);
            match &st.balance {
                None => w.u8(0),
                Some(b) => {
                    w.u8(1);
                    w.f64s(&b.forcing);
                    w.f64s(&b.damping);
                    w.f64(b.impacts);
                    w.f64(b.time);
                }
            }
        }
    }
    w.0
}

pub fn deserialize(instance: &Instance, bytes: &[u8]) -> Result<Snapshot, String> {
    let mut r = Reader { bytes, at: 0 };
    if r.take(MAGIC.len())? != MAGIC {
        return Err("not a beamstop FMU state (bad magic)".into());
    }
    let version = r.u32()?;
    if version != FORMAT_VERSION {
        return Err(format!("serialized state format version {version}; this FMU reads version {FORMAT_VERSION}"));
    }
    let guid = r.str()?;
    if guid != instance.guid() {
        return Err(format!("serialized state belongs to FMU {guid}, not to this one ({})", instance.guid()));
    }
    let machine = ModelState::from_code(r.u8()?).ok_or("serialized state: unknown instance state")?;
    let start_time = r.f64()?;
    let stop_time = r.opt_f64()?;
    let last_successful_time = r.f64()?;
    let terminated = r.u8()? != 0;
    let table = instance.table();
    let parameters = r.f64s(table.parameters.len(), "parameters")?;
    let inputs = r.f64s(table.inputs.len(), "inputs")?;
    let sim = if r.u8()? == 0 {
        None
    } else {
        let scene = instance.scene_with(&parameters);
        let model = Model::build(&scene).map_err(|e| format!("serialized parameters are invalid: {e}"))?;
        let n = r.u32()? as usize;
        let n_stops = r.u32()? as usize;
        if n != model.n_modes() || n_stops != model.stops.len() {
            return Err(format!(
                "serialized state has {n} modes and {n_stops} stops, this FMU {} and {}",
                model.n_modes(),
                model.stops.len()
            ));
        }
        let time = r.f64()?;
        let anchor_time = r.f64()?;
        let anchor = r.modal(n)?;
        let stuck = r.u64()?;
        let scan = r.f64()?;
        let departing = r.u64()?;
        let stops = (0..n_stops)
            .map(|_| Ok(StopState { impacts: r.u64()?, last_impact: r.f64()?, previous_impact: r.opt_f64()? }))
            .collect::<Result<Vec<_>, String>>()?;
        let current = r.modal(n)?;
        let balance = if r.u8()? == 0 {
            None
        } else {
            Some(EnergyBalance {
                forcing: r.f64s(n, "forcing energies")?,
                damping: r.f64s(n, "damping energies")?,
                impacts: r.f64()?,
                time: r.f64()?,
            })
        };
        if balance.is_some() != model.energy_balance {
            return Err("serialized state and this FMU disagree on the energy balance outputs".into());
        }
        let state = SimState { time, anchor_time, anchor, stuck, scan, departing, stops, current, balance };
        Some(Simulation::restore(model, inputs.clone(), state).map_err(|e| e.to_string())?)
    };
    if r.at != bytes.len() {
        return Err(format!("serialized state has {} trailing bytes", bytes.len() - r.at));
    }
    Ok(Snapshot { machine, parameters, inputs, start_time, stop_time, sim, last_successful_time, terminated })
}
