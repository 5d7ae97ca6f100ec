//! Mode transfer (RMTM, docs/mode_transfer.md): the basis the motion
//! is in (the structure's modes, or the tip-spring modes while the
//! transfer stop is pressed), the switch between them, and the motion read
//! back in the structure's own modes.

use std::sync::Arc;

use nalgebra::DVector;

use super::coupled::CoupledPhase;
use super::phases::Segment;
use super::state::SimState;
use super::{SimError, Simulation};
use crate::contact::{Contact, Geometry};
use crate::kinds::modal::model::Model;
use crate::kinds::modal::scene::ContactMethod;
use crate::solve::lti::{CoupledSegment, CoupledSystem};
use crate::solve::{FreeDynamics, ModalState};

impl Simulation {
    /// Kinetic plus strain energy of the structure (with mode transfer, of
    /// its projection on the structure's modes).
    pub fn energy(&self) -> f64 {
        match &self.state.frozen {
            None => self.model.energy(&self.state.current),
            Some(_) => self.model.energy(&self.field()),
        }
    }

    /// The motion in the structure's own modal coordinates: the state
    /// itself, or with mode transfer the frozen shape plus the increment,
    /// projected (`c + T^T (d + p)` in contact, `c + T^T d + q` apart).
    pub fn field(&self) -> ModalState {
        let (Some(f), Some(tr)) = (&self.state.frozen, &self.model.transfer) else { return self.state.current.clone() };
        let cur = &self.state.current;
        let t = &tr.overlap;
        if self.in_transfer() {
            ModalState { q: &f.c + t.tr_mul(&(&f.d + &cur.q)), qd: t.tr_mul(&cur.qd) }
        } else {
            ModalState { q: &f.c + t.tr_mul(&f.d) + &cur.q, qd: cur.qd.clone() }
        }
    }

    /// Whether the state is in the tip-spring basis (mode transfer, pressed).
    fn in_transfer(&self) -> bool {
        self.model.transfer.as_ref().is_some_and(|tr| self.state.stops[tr.stop].contact == Contact::Pressed)
    }

    /// Displacement and velocity of the structure at a point given by its
    /// shape in the structure's modes (`w`) and, with mode transfer, in
    /// the tip-spring modes (`phi`).
    pub fn point_motion(&self, w: &DVector<f64>, phi: Option<&DVector<f64>>) -> (f64, f64) {
        let cur = &self.state.current;
        match (&self.state.frozen, phi) {
            (Some(f), Some(phi)) => {
                let frozen = w.dot(&f.c) + phi.dot(&f.d);
                let active = if self.in_transfer() { phi } else { w };
                (frozen + active.dot(&cur.q), active.dot(&cur.qd))
            }
            _ => (w.dot(&cur.q), w.dot(&cur.qd)),
        }
    }

    /// Displacement and velocity at stop `i`.
    pub fn stop_motion(&self, i: usize) -> (f64, f64) {
        let phi = self.model.transfer.as_ref().filter(|tr| tr.stop == i).map(|tr| &tr.stop_w);
        self.point_motion(&self.model.stops[i].geometry.w, phi)
    }

    /// Displacement, velocity and (if measured) bending moment at sensor `i`.
    pub fn sensor_motion(&self, i: usize) -> (f64, f64, f64) {
        let s = &self.model.sensors[i];
        let phi = self.model.transfer.as_ref().map(|tr| &tr.sensors[i]);
        let (w, v) = self.point_motion(&s.w, phi.map(|p| &p.0));
        let m = match &s.moment {
            Some(m) => self.point_motion(m, phi.and_then(|p| p.1.as_ref())).0,
            None => 0.0,
        };
        (w, v, m)
    }

    /// Derives the dynamics and the stops' geometry from the model, the
    /// inputs and the state (after a change of basis or of the model).
    pub(super) fn refresh_basis(&mut self) {
        self.dynamics = phase_dynamics(&self.model, &self.inputs, &self.state);
        self.phase_memo.clear();
        self.geometries = active_geometries(&self.model, &self.state);
        self.gap_functionals = self.geometries.iter().map(|g| g.gap_functional()).collect();
        self.scratch = None;
        // The segment's event functions were made from the old geometry.
        if let Segment::Free { functions, .. } = &mut self.segment {
            functions.clear();
        }
    }

    /// Whether the state is in the tip-spring basis with the structure's
    /// damping projected on the contact modes (a coupled phase).
    pub(super) fn transfer_damped(&self) -> bool {
        self.model.transfer.as_ref().and_then(|tr| tr.damping.as_ref()).filter(|_| self.in_transfer()).is_some()
    }

    /// The segment of mode transfer in contact with inherited damping: a
    /// coupled phase of the tip-spring modes, its system formed once.
    pub(super) fn rebuild_transfer_segment(&mut self) -> Result<(), SimError> {
        let system = match &self.transfer_system {
            Some(s) => s.clone(),
            None => {
                let tr = self.model.transfer.as_ref().expect("in transfer");
                let damping = tr.damping.as_ref().expect("inherited damping");
                let k = nalgebra::DMatrix::from_diagonal(&DVector::from_iterator(tr.oscillators.len(), tr.oscillators.iter().map(|o| o.omega * o.omega)));
                let n = k.nrows();
                let s = Arc::new(CoupledSystem::new(k, damping.clone(), nalgebra::DMatrix::zeros(n, 0))?);
                self.transfer_system = Some(s.clone());
                s
            }
        };
        let n = self.model.n_modes();
        let forcing = self.dynamics.forcing.clone();
        let segment = CoupledSegment::new(&system, &forcing, &DVector::zeros(n), &DVector::zeros(n), self.state.anchor_time, &self.state.anchor);
        let events = self
            .channels
            .iter()
            .map(|ch| {
                let h = self.watched_functional(ch.stop, ch.watch).expect("no held stop with mode transfer");
                segment.project_functional(&system, &forcing, &h)
            })
            .collect();
        let reactions = vec![None; self.model.stops.len()];
        let loads = segment.loads().clone();
        let phase = Arc::new(CoupledPhase { system, forcing, loads, events, reactions });
        self.enter(Segment::Coupled { phase, segment });
        Ok(())
    }

    /// Mode transfer (RMTM): entering or leaving contact changes the
    /// basis; MTM projects both fields on the new modes, RMTM freezes the
    /// displacement and projects the velocity (docs/mode_transfer.md).
    /// Whether the basis changed; `st` is then in the new one.
    pub(super) fn switch_basis(&mut self, st: &mut ModalState, was: &[Contact], contact: &[Contact]) -> bool {
        if let Some(tr) = &self.model.transfer {
            let i = tr.stop;
            let into = was[i] != Contact::Pressed && contact[i] == Contact::Pressed;
            let out = was[i] == Contact::Pressed && contact[i] != Contact::Pressed;
            if into || out {
                let f = self.state.frozen.as_mut().expect("a mode-transfer model keeps a frozen shape");
                let t = &tr.overlap;
                let project = |v: &DVector<f64>| if into { t * v } else { t.tr_mul(v) };
                match tr.method {
                    ContactMethod::Rmtm => {
                        if into {
                            f.c += &st.q;
                        } else {
                            f.d += &st.q;
                        }
                        st.q.fill(0.0);
                    }
                    _ => {
                        st.q = project(&st.q);
                        // Truncation moves the projected tip off the stop
                        // (0.94 of the gap at kappa = 1e4, 20 modes): put it
                        // back on the surface along the new basis's tip
                        // shape, as an impact puts a rigid stop's point on
                        // it, so the phase starts where the switch happened.
                        let g = &self.model.stops[i].geometry;
                        let shape = if into { &tr.stop_w } else { &g.w };
                        let miss = g.target() - shape.dot(&st.q);
                        st.q.axpy(miss / shape.dot(shape), shape, 1.0);
                    }
                }
                st.qd = project(&st.qd);
                return true;
            }
        }
        false
    }
}

/// The free dynamics of the current basis: the structure's modes, or with
/// mode transfer in contact the tip-spring modes (RMTM), each with the
/// constant load its frozen shape and the spring's preload exert
/// (docs/mode_transfer.md: `-omega^2 r` apart, `k target Phi(L) -
/// omega~^2 s` in contact, `r = c + T^T d`, `s = T c + d`).
pub(super) fn phase_dynamics(model: &Model, inputs: &[f64], state: &SimState) -> FreeDynamics {
    let (Some(tr), Some(f)) = (&model.transfer, &state.frozen) else {
        return FreeDynamics::new(model.oscillators.clone(), model.forcing_with_inputs(inputs));
    };
    if state.stops[tr.stop].contact == Contact::Pressed {
        let mut forcing = tr.loads.clone();
        for (a, u) in tr.inputs.iter().zip(inputs) {
            forcing.constant.axpy(*u, a, 1.0);
        }
        let k = model.stops[tr.stop].law.mode_transfer().expect("mode transfer needs a spring stop").stiffness;
        forcing.constant.axpy(k * model.stops[tr.stop].geometry.target(), &tr.stop_w, 1.0);
        let s = &tr.overlap * &f.c + &f.d;
        for (j, o) in tr.oscillators.iter().enumerate() {
            forcing.constant[j] -= o.omega * o.omega * s[j];
        }
        FreeDynamics::new(tr.oscillators.clone(), forcing)
    } else {
        let mut forcing = model.forcing_with_inputs(inputs);
        let r = &f.c + tr.overlap.tr_mul(&f.d);
        for (j, o) in model.oscillators.iter().enumerate() {
            forcing.constant[j] -= o.omega * o.omega * r[j];
        }
        FreeDynamics::new(model.oscillators.clone(), forcing)
    }
}

/// Each stop's geometry in the current basis: with mode transfer, the
/// transfer stop's shape is `Phi(L)` while pressed, and the frozen shape's
/// displacement there is taken off its gap.
pub(super) fn active_geometries(model: &Model, state: &SimState) -> Vec<Geometry> {
    let mut out: Vec<Geometry> = model.stops.iter().map(|s| s.geometry.clone()).collect();
    if let (Some(tr), Some(f)) = (&model.transfer, &state.frozen) {
        let g = &mut out[tr.stop];
        let frozen = g.w.dot(&f.c) + tr.stop_w.dot(&f.d);
        g.gap -= g.side * frozen;
        if state.stops[tr.stop].contact == Contact::Pressed {
            g.w = tr.stop_w.clone();
        }
    }
    out
}
