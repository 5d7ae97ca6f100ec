//! Contact phases with linear coupling (sticking, compliant stops
//! pressed): their coupled system, loads and origin, the held stops'
//! reactions, and the caches that let a phase entered again skip forming
//! them.

use std::sync::Arc;

use nalgebra::DVector;

use super::phases::Segment;
use super::state::StopState;
use super::{Channel, SimError, Simulation};
use crate::contact::{Contact, PhaseTerm};
use crate::solve::lti::{CoupledSegment, CoupledSystem, PhaseLoads, ProjectedFunctional};
use crate::solve::{Functional, ModalForcing};

/// What every segment of one contact phase shares: built at the phase's
/// first entry, shared by the later ones (each stick of a run).
#[derive(Debug)]
pub(super) struct CoupledPhase {
    pub(super) system: Arc<CoupledSystem>,
    /// The loads of the phase (compliant stops' preload included).
    pub(super) forcing: ModalForcing,
    pub(super) loads: Arc<PhaseLoads>,
    /// Each channel's function in the phase's coordinates.
    pub(super) events: Vec<ProjectedFunctional>,
    /// The reaction (VSM12 eq. 33) of each held stop.
    pub(super) reactions: Vec<Option<Functional>>,
}

/// A contact phase entered before under the current dynamics and model,
/// found by every stop's contact state and the watched channels (which
/// fix everything [`CoupledPhase`] holds while the dynamics stay).
#[derive(Clone, Debug)]
pub(super) struct PhaseMemo {
    contacts: Vec<Contact>,
    channels: Vec<Channel>,
    pub(super) phase: Arc<CoupledPhase>,
}

impl PhaseMemo {
    /// Whether the stops are in this phase's contact states.
    pub(super) fn holds_for(&self, stops: &[StopState]) -> bool {
        self.contacts.iter().eq(stops.iter().map(|s| &s.contact))
    }
}

/// A contact phase's loads and event functions in its coordinates, for
/// the next entry into the same phase: found by the system (the same
/// decomposition), the loads and the origin, compared in full.
#[derive(Clone, Debug)]
pub(super) struct PhaseEntry {
    system: Arc<CoupledSystem>,
    forcing: ModalForcing,
    origin: DVector<f64>,
    origin_force: DVector<f64>,
    loads: Arc<PhaseLoads>,
    projected: Vec<(Functional, ProjectedFunctional)>,
}

/// At most this many phases are kept (a chatter sequence alternates
/// between two or three; every active set of several stops is one).
const PHASE_CACHE_CAPACITY: usize = 8;

impl Simulation {
    /// The contact states that shape the phase (the key of its system). A
    /// pressed mode-transfer stop is part of the basis, not of the phase.
    pub(super) fn phase_key(&self) -> Vec<Contact> {
        (0..self.model.stops.len()).map(|i| self.phase_contact(i)).collect()
    }

    /// Stop `i`'s entry in the phase key: its contact state where that
    /// shapes the phase, else open.
    pub(super) fn phase_contact(&self, i: usize) -> Contact {
        let contact = self.state.stops[i].contact;
        let transfer = self.model.transfer.as_ref().is_some_and(|tr| tr.stop == i);
        if transfer || self.model.stops[i].law.term(contact) == PhaseTerm::None {
            Contact::Open
        } else {
            contact
        }
    }

    /// The coupled system of a phase: `K = diag(omega^2) + sum k w w^T`,
    /// `D = diag(2 zeta omega) + sum c w w^T` over pressed compliant stops,
    /// constrained by the held rigid ones.
    pub(super) fn coupled_system(&mut self, key: &[Contact]) -> Result<Arc<CoupledSystem>, SimError> {
        if let Some(s) = self.coupled_cache.get(key) {
            return Ok(s.clone());
        }
        let sys = self.model.phase_system(key)?;
        self.coupled_cache.insert(key.to_vec(), sys.clone());
        Ok(sys)
    }

    /// The held stops' positions `w . q = target`, in column order.
    pub(super) fn held_targets(&self) -> DVector<f64> {
        let targets: Vec<f64> = self
            .model
            .stops
            .iter()
            .zip(&self.state.stops)
            .filter(|(m, s)| m.law.term(s.contact) == PhaseTerm::Constraint)
            .map(|(m, _)| m.geometry.target())
            .collect();
        DVector::from_vec(targets)
    }

    /// The loads of the current phase, the origin its motion is measured
    /// from and the elastic force at that origin: the origin lies on every
    /// held stop and on the surface of every pressed compliant stop
    /// (minimum norm), so the springs' preload `k target w` and their force
    /// at the origin `k w (w . origin)` cancel analytically, leaving
    /// `k w (w . origin - target)`, formed from the tiny residual; the
    /// springs then act on the small deviation only and keep their accuracy
    /// at any stiffness. Should the surfaces not be independent, the origin
    /// only satisfies the held stops and the preload joins the loads.
    /// The last value is the preload left out of the loads.
    fn phase_loads(&self, system: &CoupledSystem) -> (ModalForcing, DVector<f64>, DVector<f64>, DVector<f64>) {
        let n = self.model.n_modes();
        let held = self.held_targets();
        let base_k = DVector::from_iterator(n, self.model.oscillators.iter().map(|o| o.omega * o.omega));
        let mut cols: Vec<DVector<f64>> = Vec::new();
        let mut targets: Vec<f64> = held.iter().copied().collect();
        let mut springs: Vec<(f64, usize)> = Vec::new();
        for (i, (m, s)) in self.model.stops.iter().zip(&self.state.stops).enumerate() {
            if m.law.term(s.contact) == PhaseTerm::Constraint {
                cols.push(m.geometry.w.clone());
            }
            if let PhaseTerm::Linear { stiffness: k, .. } = m.law.term(s.contact) {
                springs.push((k, i));
            }
        }
        for &(_, i) in &springs {
            cols.push(self.model.stops[i].geometry.w.clone());
            targets.push(self.model.stops[i].geometry.target());
        }
        let mut preload = DVector::zeros(n);
        for &(k, i) in &springs {
            let g = &self.model.stops[i].geometry;
            preload.axpy(k * g.target(), &g.w, 1.0);
        }
        let forcing = self.dynamics.forcing.clone();
        if !springs.is_empty() {
            let a = nalgebra::DMatrix::from_columns(&cols);
            let gram = a.transpose() * &a;
            let (scale, lower) = (gram.diagonal().amax(), gram.diagonal().min());
            let solved = (lower > 1e-12 * scale).then(|| gram.cholesky().map(|c| &a * c.solve(&DVector::from_vec(targets)))).flatten();
            if let Some(origin) = solved.filter(|o| o.iter().all(|v| v.is_finite())) {
                let mut force = origin.component_mul(&base_k);
                for &(k, i) in &springs {
                    let g = &self.model.stops[i].geometry;
                    force.axpy(k * (g.w.dot(&origin) - g.target()), &g.w, 1.0);
                }
                return (forcing, origin, force, preload);
            }
        }
        let origin = system.q_c(&held);
        let mut force = origin.component_mul(&base_k);
        for &(k, i) in &springs {
            let g = &self.model.stops[i].geometry;
            force.axpy(k * g.w.dot(&origin), &g.w, 1.0);
        }
        let mut with_preload = forcing;
        with_preload.constant += &preload;
        (with_preload, origin, force, DVector::zeros(n))
    }

    /// A contact phase's motion from the anchor, in the spare's storage
    /// when the spare is one.
    fn start_coupled(&mut self, system: &CoupledSystem, loads: Arc<PhaseLoads>) -> CoupledSegment {
        match self.spare.take() {
            Some(Segment::Coupled { mut segment, .. }) => {
                segment.restart(system, loads, self.state.anchor_time, &self.state.anchor);
                segment
            }
            other => {
                self.spare = other;
                CoupledSegment::start(system, loads, self.state.anchor_time, &self.state.anchor)
            }
        }
    }

    /// The cached entry of a contact phase, moved to the front (most
    /// recent first), or a new one with the loads projected now.
    fn phase_entry(&mut self, system: &Arc<CoupledSystem>, forcing: ModalForcing, origin: DVector<f64>, origin_force: DVector<f64>) -> &PhaseEntry {
        let found = self.phase_cache.iter().position(|e| {
            Arc::ptr_eq(&e.system, system) && e.forcing == forcing && e.origin == origin && e.origin_force == origin_force
        });
        let entry = match found {
            Some(i) => self.phase_cache.remove(i),
            None => {
                let loads = Arc::new(PhaseLoads::new(system, &forcing, &origin, &origin_force));
                PhaseEntry { system: system.clone(), forcing, origin, origin_force, loads, projected: Vec::new() }
            }
        };
        self.phase_cache.truncate(PHASE_CACHE_CAPACITY - 1);
        self.phase_cache.insert(0, entry);
        &self.phase_cache[0]
    }

    /// A coupled contact phase's segment from the anchor: the phase from
    /// the memo when it was entered before under the current dynamics,
    /// else formed (its system, loads, reactions and event functions) and
    /// remembered.
    pub(super) fn rebuild_coupled_segment(&mut self) -> Result<(), SimError> {
        let memo = self.phase_memo.iter().position(|m| m.channels == self.channels && m.holds_for(&self.state.stops));
        if let Some(i) = memo {
            let memo = self.phase_memo.remove(i);
            let segment = self.start_coupled(&memo.phase.system, memo.phase.loads.clone());
            self.enter(Segment::Coupled { phase: memo.phase.clone(), segment });
            self.phase_memo.insert(0, memo);
            return Ok(());
        }
        let key = self.phase_key();
        let system = self.coupled_system(&key)?;
        let (forcing, origin, origin_force, preload) = self.phase_loads(&system);
        let entry = self.phase_entry(&system, forcing, origin, origin_force);
        let loads = entry.loads.clone();
        let segment = self.start_coupled(&system, loads.clone());
        let mut reactions_by_column = system.reaction_functionals().into_iter();
        let reactions: Vec<Option<Functional>> = key
            .iter()
            .map(|c| {
                (*c == Contact::Held).then(|| {
                    let mut r = reactions_by_column.next().expect("one reaction per held stop");
                    // The springs' preload, kept out of the loads, still loads the constraint.
                    r.offset += r.f.as_ref().map_or(0.0, |f| f.dot(&preload));
                    r
                })
            })
            .collect();
        let functionals: Vec<Functional> = self
            .channels
            .iter()
            .map(|ch| match self.watched_functional(ch.stop, ch.watch) {
                Some(h) => h,
                // Admissible while the stop pushes the beam away: -side lambda >= 0.
                None => reactions[ch.stop].clone().expect("held").scaled(-self.model.stops[ch.stop].geometry.side),
            })
            .collect();
        let entry = &mut self.phase_cache[0];
        let mut events = Vec::with_capacity(functionals.len());
        for h in functionals {
            let projected = match entry.projected.iter().find(|(g, _)| *g == h) {
                Some((_, p)) => p.clone(),
                None => {
                    let p = entry.loads.project_functional(&system, &entry.forcing, &h);
                    entry.projected.push((h, p.clone()));
                    p
                }
            };
            events.push(projected);
        }
        let forcing = entry.forcing.clone();
        let phase = Arc::new(CoupledPhase { system, forcing, loads, events, reactions });
        self.phase_memo.truncate(PHASE_CACHE_CAPACITY - 1);
        let contacts = self.state.stops.iter().map(|s| s.contact).collect();
        self.phase_memo.insert(0, PhaseMemo { contacts, channels: self.channels.clone(), phase: phase.clone() });
        self.enter(Segment::Coupled { phase, segment });
        Ok(())
    }
}
