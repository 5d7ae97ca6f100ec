//! The exact flow of a closed-form run as a map of its state `x = [q; q']`
//! and its Jacobian, the state-transition matrix, through every event: the
//! product of each phase's transition matrix and each event's saltation
//! matrix (issue 33; the monodromy matrix of a periodic orbit is this over
//! one period).
//!
//! - **A phase.** Between events the motion is affine in the state at the
//!   phase's start (free flight, sticking, a spring-dashpot contact), so
//!   its transition matrix is exact column by column: the phase's own
//!   closed-form segment started from the state plus a unit-sized change
//!   of one coordinate, minus the one started from the state, at the
//!   phase's end (no truncation, only rounding).
//! - **An event.** For a reset `x+ = R(x-)` at a guard `g(x, t) = 0`
//!   between the vector fields `F-` and `F+`: `S = DR + (F+ - DR F-) Dg /
//!   g'`, with `g' = dg/dt + Dg F-` the guard's rate along the motion. A
//!   restitution impact resets the velocities by the linear map the impact
//!   law applies (`P = I - (1 + R) w w^T / w^T w` for one stop), which
//!   gives `S = [[P, 0], [(a+ - P a-) w^T / v-, P]]`; the start of sticking
//!   projects onto the constraint; a release and a compliant stop's switch
//!   reset nothing but change the vector field (the dashpot's term jumps).
//!   `F+-` are the phases' exact accelerations at the event, `Dg` the
//!   guard functional's coefficients.
//!
//! Integrated (Hertz, power-law) phases: `flow_integrated.rs`. Mode
//! transfer by MTM: the switch's reset is the change of basis (the state
//! is in the basis of the current phase: a section in free flight has
//! the structure's modes at both ends). Not covered (refused with the
//! reason): RMTM, which has no periodic orbit (its frozen shape drifts by
//! the same amount every period: docs/mode_transfer.md). Several
//! guards at zero at one instant (two stops struck at once) take the
//! first one's saltation.

use nalgebra::{DMatrix, DVector};

use super::phases::Segment;
use super::search::{Probe, ProbeBuffers};
use super::{Reached, SimError, Simulation};
use crate::contact::impact::{apply_impact, ImpactRow};
use crate::contact::{Contact, Watch};
use crate::solve::free::ModalJet;
use crate::solve::lti::CoupledSample;
use crate::solve::{Functional, ModalState};

/// The state vector `[q; q']` of a modal state.
pub fn state_vector(st: &ModalState) -> DVector<f64> {
    let n = st.q.len();
    DVector::from_iterator(2 * n, st.q.iter().chain(st.qd.iter()).copied())
}

fn modal_state(x: &DVector<f64>) -> ModalState {
    let n = x.len() / 2;
    ModalState { q: x.rows(0, n).into_owned(), qd: x.rows(n, n).into_owned() }
}

impl Simulation {
    /// Why this run has no exact flow, if it has none.
    pub fn flow_unsupported(&self) -> Option<String> {
        self.model.flow_unsupported()
    }

    /// Each stop's clearance now.
    pub fn clearances(&self) -> Vec<crate::kind::Clearance> {
        let st = &self.state.current;
        self.model
            .stops
            .iter()
            .map(|s| crate::kind::Clearance {
                gap: -s.geometry.penetration(&st.q),
                rate: -s.geometry.penetration_rate(&st.qd),
                displacement: s.geometry.w.dot(&st.q),
                velocity: s.geometry.w.dot(&st.qd),
            })
            .collect()
    }

    /// The state `[q; q']` now.
    pub fn flow_state(&self) -> DVector<f64> {
        state_vector(&self.state.current)
    }

    /// Advances to `t_end` through every event as [`Self::advance_to`]
    /// does (the same trajectory, bit for bit) and returns the Jacobian of
    /// the state reached with respect to the state now.
    pub fn advance_with_jacobian(&mut self, t_end: f64) -> Result<DMatrix<f64>, SimError> {
        if let Some(why) = self.flow_unsupported() {
            return Err(SimError::Unsupported(format!("the exact flow and its Jacobian: {why}")));
        }
        let dim = 2 * self.model.n_modes();
        let mut m = DMatrix::identity(dim, dim);
        // Each stop's onset speed's derivative with respect to the state
        // started from (an integrated phase's hysteretic damping scales
        // with it; see flow_integrated.rs): zero until an onset sets it.
        let mut onset = DMatrix::zeros(self.model.stops.len(), dim);
        // Whether a phase starts at an event (an integrated replay grades
        // its first piece then).
        #[cfg(feature = "power-law")]
        let mut after_event = false;
        loop {
            let (t0, x0) = (self.state.time, self.state.current.clone());
            let before = self.clone();
            // An integrated phase's step ends, for its replay.
            #[cfg(feature = "power-law")]
            {
                self.flow_trace = self.integrated_step_end().map(|t| vec![t]).or(Some(Vec::new()));
            }
            let reached = self.advance(t_end, Some(&mut |_| true));
            #[cfg(feature = "power-law")]
            let trace = self.flow_trace.take().unwrap_or_default();
            let reached = reached?;
            let t1 = self.state.time;
            if t1 > t0 {
                #[cfg(feature = "power-law")]
                if before.segment.is_integrated() {
                    let phase = before.integrated_transition(t0, &x0, t1, &trace, (after_event, matches!(reached, Reached::Event(_))))?;
                    let mut next = &phase.state * &m;
                    for (stop, column) in &phase.onset {
                        next += column * onset.row(*stop);
                    }
                    m = next;
                } else {
                    m = before.phase_transition(t0, &x0, t1)? * m;
                }
                #[cfg(not(feature = "power-law"))]
                {
                    m = before.phase_transition(t0, &x0, t1)? * m;
                }
            }
            match reached {
                Reached::Time => return Ok(m),
                Reached::Event(_) => {
                    #[cfg(feature = "power-law")]
                    {
                        after_event = true;
                    }
                    let contacts: Vec<_> = self.state.stops.iter().map(|s| s.contact).collect();
                    let (s, onsets) = self.apply_events_with_saltation()?;
                    let stuck = |sim: &Self| sim.state.stops.iter().map(|s| s.contact).eq(contacts.iter().copied()) && sim.state.anchor_time < t1;
                    if self.state.time == t1 && stuck(self) {
                        // The switch the advance stopped before is not made
                        // by the advance to its time: its search, resumed
                        // where it stopped, finds it again a few roundings
                        // later. A plain advance that far makes it (its
                        // saltation is the one just formed; the flow over
                        // those roundings is the identity to rounding).
                        let mut step = 64.0 * f64::EPSILON * t1.abs().max(f64::MIN_POSITIVE);
                        while stuck(self) && step <= 1e-9 * (t_end - t1).abs().max(t1.abs()) {
                            self.advance((t1 + step).min(t_end), None)?;
                            step *= 4.0;
                        }
                        if stuck(self) {
                            return Err(SimError::Unsupported(format!(
                                "the exact flow: the switch at t = {t1} is not made where the run stopped before it, nor within 1e-9 of the time after it"
                            )));
                        }
                    }
                    for (stop, row) in onsets {
                        onset.set_row(stop, &(row.transpose() * &m));
                    }
                    m = s * m;
                }
            }
        }
    }

    /// The transition matrix of the current phase (this run, stopped at
    /// `t0` in state `x0`) from `t0` to `t1` (module doc).
    fn phase_transition(&self, t0: f64, x0: &ModalState, t1: f64) -> Result<DMatrix<f64>, SimError> {
        let n = self.model.n_modes();
        // One copy whose segment is rebuilt from each start state.
        let mut sim = self.clone();
        let mut out = ModalState::zeros(n);
        let mut from = |start: &ModalState| -> Result<DVector<f64>, SimError> {
            sim.state.anchor.clone_from(start);
            sim.state.anchor_time = t0;
            sim.rebuild_segment()?;
            sim.state_at(t1, &mut out);
            Ok(state_vector(&out))
        };
        let base = from(x0)?;
        let x = state_vector(x0);
        let mut m = DMatrix::zeros(2 * n, 2 * n);
        for k in 0..2 * n {
            // A unit-sized change (affine: exact at any size; the state's
            // own size keeps the difference free of cancellation).
            let h = x[k].abs().max(x.amax()).max(1e-300);
            let mut moved = x.clone();
            moved[k] += h;
            let h = moved[k] - x[k];
            let column = (from(&modal_state(&moved))? - &base) / h;
            m.set_column(k, &column);
        }
        Ok(m)
    }

    /// `F = [q'; q'']` of the current segment at the current time.
    fn vector_field(&self) -> DVector<f64> {
        let t = self.state.time;
        let st = &self.state.current;
        let n = self.model.n_modes();
        let mut a = DVector::zeros(n);
        match &self.segment {
            Segment::Free { .. } => {
                let mut jet = ModalJet::new(n);
                jet.fill_free(&self.dynamics, t, st);
                a.copy_from(&jet.q[2]);
            }
            Segment::Coupled { phase, segment } => {
                let mut sample = CoupledSample::default();
                segment.sample_into(&phase.system, t, &mut sample);
                for j in 0..n {
                    let mut e = DVector::zeros(n);
                    e[j] = 1.0;
                    let h = Functional { offset: 0.0, q: DVector::zeros(n), qd: Some(e), f: None };
                    let p = phase.loads.project_functional(&phase.system, &phase.forcing, &h);
                    a[j] = segment.jet(&p, &sample).d[1];
                }
            }
            #[cfg(feature = "power-law")]
            Segment::Integrated(_) => return self.integrated_vector_field(),
        }
        DVector::from_iterator(2 * n, st.qd.iter().chain(a.iter()).copied())
    }

    /// The guard of the event pending now: its functional (with the load
    /// vector's part) and the load's rate, from the functions at zero.
    fn pending_guard(&mut self) -> Result<(Functional, DVector<f64>), SimError> {
        let t = self.state.time;
        let n = self.model.n_modes();
        #[cfg(feature = "power-law")]
        if self.segment.is_integrated() {
            // No load term: an integrated phase's functions are of the state.
            // Not found again (or a held stop's reaction): no gradient,
            // which only a switch with a jump in the vector field needs.
            let guard = self.integrated_guard().ok().flatten();
            return Ok((guard.unwrap_or(Functional { offset: 0.0, q: DVector::zeros(n), qd: None, f: None }), DVector::zeros(n)));
        }
        let mut buffers = ProbeBuffers::new(&self.dynamics);
        let mut st = ModalState::zeros(n);
        // At zero within its noise, or (the search's last resort) the
        // function whose zero lies within an ulp of the time.
        let found = match self.probe(t, &mut st, &mut buffers) {
            Probe::Events { .. } => buffers.at_zero.first().map(|&(c, _)| c),
            Probe::Clear { limiting, .. } => limiting,
        };
        let Some(c) = found else {
            return Err(SimError::Unsupported(format!("the exact flow: no event function at zero at t = {t} where the run stopped")));
        };
        let ch = self.channels[c];
        let h = match self.watched_functional(ch.stop, ch.watch) {
            Some(h) => h,
            None => match &self.segment {
                Segment::Coupled { phase, .. } => phase.reactions[ch.stop].clone().expect("a held stop's reaction"),
                _ => unreachable!("a reaction is watched in coupled phases"),
            },
        };
        debug_assert!(ch.watch != Watch::Reaction || h.f.is_some() || h.qd.is_some() || h.q.len() == n);
        let mut rate = DVector::zeros(n);
        let forcing = match &self.segment {
            Segment::Coupled { phase, .. } => &phase.forcing,
            _ => &self.dynamics.forcing,
        };
        forcing.derivative(t, 1, &mut rate);
        Ok((h, rate))
    }

    /// Makes the pending event's change (an advance to the same time)
    /// and returns its saltation matrix (module doc), with the derivative
    /// of each compliant onset's speed by the state just before it.
    fn apply_events_with_saltation(&mut self) -> Result<(DMatrix<f64>, Vec<(usize, DVector<f64>)>), SimError> {
        let n = self.model.n_modes();
        let dim = 2 * n;
        let (guard, load_rate) = self.pending_guard()?;
        let f_minus = self.vector_field();
        let transfer_before = self.model.transfer.as_ref().map(|tr| self.state.stops[tr.stop].contact);
        let (recording, recorded) = (self.record_events, self.events.len());
        self.record_events = true;
        self.advance(self.state.time, None)?;
        let impacted = self.events[recorded..].iter().any(|e| matches!(e.kind, super::EventKind::Impact { .. } | super::EventKind::Stick { .. }));
        let onsets: Vec<usize> = self.events[recorded..].iter().filter_map(|e| if let super::EventKind::Contact { stop, .. } = e.kind { Some(stop) } else { None }).collect();
        if !recording {
            self.events.truncate(recorded);
        }
        self.record_events = recording;
        let f_plus = self.vector_field();
        // The reset's Jacobian: the velocities' linear map (the impact law
        // on the stops involved, then the projection onto the held stops).
        let mut dr = DMatrix::identity(dim, dim);
        let involved = self.event_work.as_ref().map(|w| w.impact_rows()).unwrap_or_default();
        if impacted {
            let rows: Vec<ImpactRow> = involved
                .iter()
                .map(|&(i, restitution)| {
                    let g = &self.model.stops[i].geometry;
                    ImpactRow { w: &g.w, restitution, side: g.side }
                })
                .collect();
            let mut impulses = Vec::new();
            for k in 0..n {
                let mut v = DVector::zeros(n);
                v[k] = 1.0;
                apply_impact(&mut v, &rows, &mut impulses);
                if let Segment::Coupled { phase, .. } = &self.segment {
                    let mut st = ModalState { q: DVector::zeros(n), qd: v };
                    phase.system.project(&self.held_targets(), &mut st);
                    v = st.qd;
                }
                dr.view_mut((n, n), (n, n)).set_column(k, &v);
            }
        }
        // Mode transfer (MTM): entering or leaving contact changes the basis,
        // `q+ = P T q` and `q'+ = T q'` (`T^T` leaving), `P` putting the
        // stop's point back on its surface along the new basis's shape
        // (transfer.rs): `DR = diag((I - s s^T / s^T s) T, T)`.
        if let (Some(tr), Some(was)) = (&self.model.transfer, transfer_before) {
            let now = self.state.stops[tr.stop].contact;
            let into = was != Contact::Pressed && now == Contact::Pressed;
            let out = was == Contact::Pressed && now != Contact::Pressed;
            if into || out {
                let t = if into { tr.overlap.clone() } else { tr.overlap.transpose() };
                let shape = if into { tr.stop_w.clone() } else { self.model.stops[tr.stop].geometry.w.clone() };
                let p = DMatrix::identity(n, n) - &shape * shape.transpose() / shape.dot(&shape);
                dr = DMatrix::zeros(dim, dim);
                dr.view_mut((0, 0), (n, n)).copy_from(&(p * &t));
                dr.view_mut((n, n), (n, n)).copy_from(&t);
            }
        }
        // Dg and the guard's rate along the motion before the event.
        let mut dg = DVector::zeros(dim);
        dg.rows_mut(0, n).copy_from(&guard.q);
        if let Some(c) = &guard.qd {
            dg.rows_mut(n, n).copy_from(c);
        }
        let explicit = guard.f.as_ref().map_or(0.0, |c| c.dot(&load_rate));
        let rate = dg.dot(&f_minus) + explicit;
        let jump = &f_plus - &dr * &f_minus;
        if dg.amax() == 0.0 {
            // A guard whose gradient the phase does not form (a held
            // stop's reaction in an integrated phase, or a switch its
            // search does not find again): fine where the vector field is
            // continuous (a Hertz force is zero at the surface), refused
            // where it jumps.
            // (The two fields are formed from states a rounding apart, the
            // one the run stopped in and the one the switch leaves.)
            if jump.amax() <= 1e-9 * f_minus.amax().max(f_plus.amax()) {
                return Ok((dr, Vec::new()));
            }
            return Err(SimError::Unsupported(format!(
                "the exact flow: the switch at t = {} changes the vector field by {:e}, and its guard's gradient is not known there",
                self.state.time,
                jump.amax()
            )));
        }
        if rate == 0.0 || !rate.is_finite() {
            return Err(SimError::Unsupported(format!(
                "the exact flow: the event at t = {} is tangential (guard rate {rate:e}): its saltation matrix does not exist (grazing)",
                self.state.time
            )));
        }
        // The onset speed `v0 = side w . q'` where the guard is reached:
        // `dv0 = Dv dx + (Dv F-) dt`, `dt = -Dg dx / g'`.
        let onsets = onsets
            .into_iter()
            .map(|i| {
                let g = &self.geometries[i];
                let mut dv = DVector::zeros(dim);
                dv.rows_mut(n, n).copy_from(&(&g.w * g.side));
                let shift = dv.dot(&f_minus) / rate;
                (i, &dv - &dg * shift)
            })
            .collect();
        Ok((dr + jump * dg.transpose() / rate, onsets))
    }
}
