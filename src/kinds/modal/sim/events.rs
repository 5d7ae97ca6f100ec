//! The event handling: at an event, the stops' new contact states
//! (releases, compliant switches, mode transfer, impacts, sticks, the ends
//! of chatter sequences), the state after the impact, projected onto the
//! held stops, and the new segment from there.

use nalgebra::DVector;

use super::phases::Segment;
use super::record::{Event, EventKind};
use super::{Channel, SimError, Simulation};
use crate::contact::impact::{apply_impact, energy_loss, ImpactRow};
use crate::contact::{Contact, Switch};
use crate::solve::events::{tendency_from, Tendency};
use crate::solve::free::ModalJet;
use crate::solve::{Jet, ModalState};

impl Simulation {
    pub(super) fn record(&mut self, time: f64, kind: EventKind) {
        if self.record_events {
            self.events.push(Event { time, kind });
        }
    }

    /// Applies the events found at time `t` (state `st`, taken: it becomes
    /// the new anchor, and `st` receives the old one's storage) and starts
    /// a new segment there if the state or the phase changed. `at_zero`
    /// lists the channels at their zero with their jets.
    pub(super) fn handle_events(&mut self, t: f64, st: &mut ModalState, at_zero: &[(usize, Jet)]) -> Result<(), SimError> {
        let mut work = self.event_work.take().unwrap_or_default();
        work.clear();
        let result = self.apply_events(t, st, at_zero, &mut work);
        self.event_work = Some(work);
        result
    }

    /// [`Self::handle_events`] in the event work space, kind by kind in a
    /// fixed order: releases, compliant switches, the change of basis of
    /// mode transfer, impacts, sticks and the ends of chatter sequences,
    /// the projection onto the held stops; then the new anchor and segment.
    fn apply_events(&mut self, t: f64, st: &mut ModalState, at_zero: &[(usize, Jet)], work: &mut EventWork) -> Result<(), SimError> {
        self.sort_zeros(t, st, at_zero, work);
        if work.impacts.is_empty() && work.sticks.is_empty() && work.releases.is_empty() && work.switches.is_empty() {
            return Ok(());
        }
        // The balance and the impulses up to the event, in the segment ending here.
        self.account(t);
        self.close_segment(t, st);
        // The energy the events take, for the balance (when kept).
        let energy_before = self.state.balance.as_ref().map(|_| self.model.energy(st));
        let EventWork { was, contact, .. } = work;
        was.extend(self.state.stops.iter().map(|s| s.contact));
        contact.extend_from_slice(was);
        self.apply_releases(t, work);
        self.apply_switches(t, st, work);
        let basis_changed = self.switch_basis(st, &work.was, &work.contact);
        self.apply_impacts(t, st, work);
        self.switch_after_jump(t, st, work);
        self.settle_holds(t, st, work);
        self.project_on_held(st, &work.contact)?;
        if let (Some(before), Some(b)) = (energy_before, self.state.balance.as_mut()) {
            b.impacts += before - self.model.energy(st);
        }
        std::mem::swap(&mut self.state.anchor, st);
        self.state.anchor_time = t;
        self.state.scan = t;
        self.mark_anchor_departing();
        if basis_changed {
            self.refresh_basis();
            self.basis_changed = true;
        }
        if !basis_changed && work.was == work.contact && matches!(self.segment, Segment::Free { .. }) {
            // An impact in free flight: the same free phase and event
            // functions from the new anchor.
            self.rebuild_free_segment(false);
        } else {
            self.rebuild_segment()?;
            self.release_pulled_holds(t)?;
        }
        // Report the sticks with their initial reaction.
        for &i in work.newly_held.iter() {
            let reaction = self.reaction_at(i, t, &self.state.anchor);
            self.record(t, EventKind::Stick { stop: i, reaction });
        }
        Ok(())
    }

    /// Sorts the functions at their zero by what their stop does there:
    /// stays in its state (the function departs), grazes, impacts, sticks,
    /// is released, or switches (compliant stops).
    fn sort_zeros(&mut self, t: f64, st: &ModalState, at_zero: &[(usize, Jet)], work: &mut EventWork) {
        let EventWork { impacts, sticks, releases, switches, .. } = work;
        for &(c, jet) in at_zero {
            let Channel { stop: i, slot, watch } = self.channels[c];
            let m = &self.model.stops[i];
            let contact = self.state.stops[i].contact;
            match m.law.on_zero(contact, watch, &jet, self.geometries[i].penetration(&st.q)) {
                Switch::Stay => self.state.stops[i].departing[slot] = true,
                Switch::Graze => {
                    self.state.stops[i].departing[slot] = true;
                    self.record(t, EventKind::Graze { stop: i });
                }
                Switch::Impact => impacts.push((i, -jet.d[1])),
                Switch::Stick => sticks.push(i),
                Switch::To(Contact::Open) if contact == Contact::Held => releases.push(i),
                Switch::To(next) => {
                    if !switches.iter().any(|s| s.0 == i) {
                        switches.push((i, next, -jet.d[1]));
                    }
                }
            }
        }
    }

    /// The stops whose reaction changed sign leave their hold.
    fn apply_releases(&mut self, t: f64, work: &mut EventWork) {
        let EventWork { releases, contact, .. } = work;
        for &i in releases.iter() {
            let counters = &mut self.state.stops[i];
            counters.stuck_time += t - counters.held_since;
            contact[i] = Contact::Open;
            counters.departing = [true, false];
            counters.previous_impact = None;
            self.record(t, EventKind::Release { stop: i });
        }
    }

    /// Held stops whose reaction pulls as the new integrated phase begins
    /// are released at once: a linear-damped stop's force jumps by `C v0`
    /// at its onset, and a hold beside it can pull from that instant. Left
    /// to the phase's search, the hold was released one sample later at
    /// loose tolerances, and at 1e-12 to 1e-14 the collocation of a
    /// pulling hold failed ("step fell to 3e-16 s").
    pub(super) fn release_pulled_holds(&mut self, t: f64) -> Result<(), SimError> {
        #[cfg(feature = "power-law")]
        {
            let Segment::Integrated(seg) = &self.segment else { return Ok(()) };
            let anchor = &self.state.anchor;
            let pulled: Vec<usize> = (0..self.model.stops.len())
                .filter(|&i| self.state.stops[i].contact == Contact::Held)
                .filter(|&i| seg.held_push_entering(i, t, anchor).is_some_and(|(push, size)| push < -crate::solve::functional::NOISE * size))
                .collect();
            if pulled.is_empty() {
                return Ok(());
            }
            for i in pulled {
                let counters = &mut self.state.stops[i];
                counters.stuck_time += t - counters.held_since;
                counters.contact = Contact::Open;
                counters.departing = [true, false];
                counters.previous_impact = None;
                self.record(t, EventKind::Release { stop: i });
            }
            self.mark_anchor_departing();
            self.rebuild_segment()?;
        }
        let _ = t;
        Ok(())
    }

    /// Compliant stops: the phase changes, the state does not.
    fn apply_switches(&mut self, t: f64, st: &ModalState, work: &mut EventWork) {
        let EventWork { switches, was, contact, .. } = work;
        for &(i, next, rate) in switches.iter() {
            let m = &self.model.stops[i];
            contact[i] = next;
            // The new phase's first function leaves its boundary here, when
            // the switch state lies on it: a switch an integrated phase
            // placed late at a loose tolerance (a separation 1e-6 of the
            // gap outside the surface) leaves it off, and a free segment
            // taking it as zero there would put the surface where the
            // point left it (and a restore would refuse the flag).
            let leaves = super::codec::on_boundary(self, i, m.law.watches(next)[0], st);
            let counters = &mut self.state.stops[i];
            counters.departing = [leaves, false];
            match next {
                Contact::Pressed if was[i] == Contact::Open => {
                    counters.impacts += 1;
                    counters.last_impact = t;
                    counters.onset_speed = rate.max(0.0);
                    self.record(t, EventKind::Contact { stop: i, speed: rate });
                }
                Contact::Open | Contact::Penetrated if was[i] == Contact::Pressed => {
                    let penetration = self.geometries[i].penetration(&st.q).max(0.0);
                    // The spring's energy left in the stop is its own.
                    counters.dissipated += m.law.energy_left_at_release(penetration);
                    self.record(t, EventKind::Separation { stop: i, penetration });
                }
                Contact::Pressed if was[i] == Contact::Penetrated => {
                    // A push resumed inside the surface: the spring holds
                    // its energy at this penetration again (counted as
                    // left in the stop since the push ended), as the
                    // rotating kind counts it.
                    let penetration = self.geometries[i].penetration(&st.q).max(0.0);
                    counters.dissipated -= m.law.energy_left_at_release(penetration);
                }
                _ => {}
            }
        }
    }

    /// An impact's jump of the speeds can step an engaged compliant stop
    /// over a zero of its watched functions (a Pressed stop whose damping
    /// now pulls, a Penetrated one whose force now pushes, a contact point
    /// moved off its surface): it switches there, as at that zero.
    fn switch_after_jump(&mut self, t: f64, st: &ModalState, work: &mut EventWork) {
        if work.impacts.is_empty() && work.sticks.is_empty() {
            return;
        }
        let mut jumped = Vec::new();
        for (i, m) in self.model.stops.iter().enumerate() {
            let contact = work.contact[i];
            if m.law.rigid() || !matches!(contact, Contact::Pressed | Contact::Penetrated) {
                continue;
            }
            let g = &self.geometries[i];
            let (p, pd) = (g.penetration(&st.q), g.penetration_rate(&st.qd));
            for &watch in m.law.watches(contact) {
                let value = m.law.watched(watch, p, pd, self.state.stops[i].onset_speed).0;
                if value < 0.0 {
                    let crossed = Jet { d: [value, -1.0, 0.0, 0.0], noise: [0.0; 4], slack: 0.0 };
                    if let Switch::To(next) = m.law.on_zero(contact, watch, &crossed, p) {
                        jumped.push((i, next, pd));
                        break;
                    }
                }
            }
        }
        if !jumped.is_empty() {
            let located = std::mem::replace(&mut work.switches, jumped);
            self.apply_switches(t, st, work);
            work.switches = located;
        }
    }

    /// The impact: impacting stops with their restitution, newly pressed
    /// and still held stops with R = 0 (VSM12 sec. 2.2); each
    /// impacting stop's contact point is put on the stop.
    fn apply_impacts(&mut self, t: f64, st: &mut ModalState, work: &mut EventWork) {
        let n_stops = self.model.stops.len();
        let EventWork { impacts, sticks, contact, restitution, chatter_ends, involved, before, impulses, .. } = work;
        restitution.resize(n_stops, 0.0);
        for &(i, speed) in impacts.iter() {
            let law = &self.model.stops[i].law;
            // Largest magnitudes by plain folds (nalgebra's `amax` goes
            // through its generic SIMD comparisons: dearer for a few modes).
            let largest = |v: &DVector<f64>| v.as_slice().iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let negligible = 16.0 * f64::EPSILON * largest(&st.qd) * largest(&self.model.stops[i].geometry.w);
            let counters = &mut self.state.stops[i];
            restitution[i] = law.restitution(t, counters.previous_impact, speed, negligible).expect("only rigid stops impact");
            counters.impacts += 1;
            counters.last_impact = t;
            counters.previous_impact = Some(t);
            // R = 0 ends a chatter sequence (with R = 0 given, every impact does).
            if restitution[i] == 0.0 {
                chatter_ends.push(i);
            }
        }
        involved.extend((0..n_stops).filter(|&i| contact[i] == Contact::Held || sticks.contains(&i) || impacts.iter().any(|&(k, _)| k == i)));
        if before.len() == st.qd.len() {
            before.as_mut_slice().copy_from_slice(st.qd.as_slice());
        } else {
            *before = st.qd.clone();
        }
        if !impacts.is_empty() || !sticks.is_empty() {
            let row = |i: usize| {
                let g = &self.model.stops[i].geometry;
                ImpactRow { w: &g.w, restitution: restitution[i], side: g.side }
            };
            match involved.as_slice() {
                &[i] => apply_impact(&mut st.qd, &[row(i)], impulses),
                many => apply_impact(&mut st.qd, &many.iter().map(|&i| row(i)).collect::<Vec<_>>(), impulses),
            }
            if self.model.impulses {
                for (&i, p) in involved.iter().zip(impulses.iter()) {
                    self.state.stops[i].impulse += -self.model.stops[i].geometry.side * p;
                }
            }
        }
        for &(i, speed) in impacts.iter() {
            let g = &self.model.stops[i].geometry;
            // Put the contact point exactly on the stop (VSM12 Fig. 3b).
            let miss = g.target() - g.w.dot(&st.q);
            st.q.axpy(miss / g.w.dot(&g.w), &g.w, 1.0);
            let lost = energy_loss(&g.w, before, restitution[i]);
            self.record(
                t,
                EventKind::Impact { stop: i, speed, restitution: restitution[i], energy_lost: lost, chatter: chatter_ends.contains(&i) },
            );
            self.state.stops[i].departing = [true, false];
        }
    }

    /// Sets every stop's new contact state, with the held stops' counters.
    /// After the last impact of a chatter sequence the contact velocity is
    /// zero: the beam sticks if the loads press it on (the reaction of
    /// VSM12 eq. 32 of the right sign), else it leaves. Zero-velocity
    /// contacts found pressed stick.
    fn settle_holds(&mut self, t: f64, st: &ModalState, work: &mut EventWork) {
        let n_stops = self.model.stops.len();
        let EventWork { sticks, was, contact, chatter_ends, newly_held, jet, .. } = work;
        if !chatter_ends.is_empty() {
            let n = self.dynamics.oscillators.len();
            let jet = jet.get_or_insert_with(|| ModalJet::new(n));
            if jet.q[0].len() != n {
                *jet = ModalJet::new(n);
            }
            jet.fill_free(&self.dynamics, t, st);
            // The compliant stops pushing now press on the structure too
            // (the free jet knows only the loads).
            let mut pushed = DVector::zeros(n);
            for (k, m) in self.model.stops.iter().enumerate() {
                if !m.law.rigid() {
                    let g = &self.geometries[k];
                    let force = m.law.force(contact[k], g.penetration(&st.q), g.penetration_rate(&st.qd), self.state.stops[k].onset_speed);
                    if force != 0.0 {
                        pushed.axpy(-g.side * force, &g.w, 1.0);
                    }
                }
            }
            for &i in chatter_ends.iter() {
                let mut h = jet.functional(&self.gap_functionals[i], t);
                h.d[2] += self.gap_functionals[i].q.dot(&pushed);
                if tendency_from(&h, 2) != Tendency::Opening {
                    contact[i] = Contact::Held;
                }
            }
        }
        for &i in sticks.iter() {
            contact[i] = Contact::Held;
        }
        for i in 0..n_stops {
            if contact[i] == Contact::Held {
                let counters = &mut self.state.stops[i];
                counters.previous_impact = None;
                if was[i] != Contact::Held {
                    counters.sticks += 1;
                    counters.held_since = t;
                    counters.departing = [true, false];
                    newly_held.push(i);
                }
            }
        }
        for (s, c) in self.state.stops.iter_mut().zip(contact.iter()) {
            s.contact = *c;
        }
    }

    /// Puts the state exactly on the held stops (`contact`: every stop's
    /// contact state), moving along them.
    fn project_on_held(&mut self, st: &mut ModalState, contact: &[Contact]) -> Result<(), SimError> {
        let nonlinear = self.model.stops.iter().zip(contact).any(|(m, c)| m.law.term(*c) == crate::contact::PhaseTerm::Nonlinear);
        if nonlinear && contact.iter().any(|c| *c == Contact::Held) {
            // An integrated phase: the same projection (identity modal
            // mass) without the coupled system it has none of.
            let held: Vec<usize> = (0..contact.len()).filter(|&i| contact[i] == Contact::Held).collect();
            let w = nalgebra::DMatrix::from_columns(&held.iter().map(|&i| self.geometries[i].w.clone()).collect::<Vec<_>>());
            let gram = w.transpose() * &w;
            let targets = DVector::from_iterator(held.len(), held.iter().map(|&i| self.geometries[i].target()));
            let lu = gram.lu();
            if let (Some(dq), Some(dv)) = (lu.solve(&(targets - w.transpose() * &st.q)), lu.solve(&(w.transpose() * &st.qd))) {
                st.q += &w * dq;
                st.qd -= &w * dv;
            }
            return Ok(());
        }
        if contact.iter().any(|c| *c == Contact::Held) {
            // Exactly on the held stops, moving along them (VSM12 eqs. 29-31:
            // project at entry so no drift accumulates). A phase entered
            // before has its system at hand.
            let system = match self.phase_memo.iter().find(|m| m.holds_for(&self.state.stops)) {
                Some(memo) => memo.phase.system.clone(),
                None => {
                    let key = self.phase_key();
                    self.coupled_system(&key)?
                }
            };
            system.project(&self.held_targets(), st);
        }
        Ok(())
    }
}

/// Work space of the event handling, kept between events.
#[derive(Clone, Debug)]
pub(super) struct EventWork {
    impacts: Vec<(usize, f64)>,
    sticks: Vec<usize>,
    releases: Vec<usize>,
    switches: Vec<(usize, Contact, f64)>,
    /// Each stop's contact state before the events, and after.
    was: Vec<Contact>,
    contact: Vec<Contact>,
    restitution: Vec<f64>,
    chatter_ends: Vec<usize>,
    /// Stops taking part in the impact (impacting, sticking or held).
    involved: Vec<usize>,
    newly_held: Vec<usize>,
    /// The modal velocities before the impact.
    before: DVector<f64>,
    impulses: Vec<f64>,
    /// The free jet after the impact, made when a chatter sequence ends.
    jet: Option<ModalJet>,
}

impl EventWork {
    /// The stops the last impact involved (impacting, sticking or held),
    /// each with the restitution it applied (0 for the sticking and held).
    pub(super) fn impact_rows(&self) -> Vec<(usize, f64)> {
        self.involved.iter().map(|&i| (i, self.restitution.get(i).copied().unwrap_or(0.0))).collect()
    }
}

impl Default for EventWork {
    fn default() -> Self {
        EventWork {
            impacts: Vec::new(),
            sticks: Vec::new(),
            releases: Vec::new(),
            switches: Vec::new(),
            was: Vec::new(),
            contact: Vec::new(),
            restitution: Vec::new(),
            chatter_ends: Vec::new(),
            involved: Vec::new(),
            newly_held: Vec::new(),
            before: DVector::zeros(0),
            impulses: Vec::new(),
            jet: None,
        }
    }
}

impl EventWork {
    fn clear(&mut self) {
        self.impacts.clear();
        self.sticks.clear();
        self.releases.clear();
        self.switches.clear();
        self.was.clear();
        self.contact.clear();
        self.restitution.clear();
        self.chatter_ends.clear();
        self.involved.clear();
        self.newly_held.clear();
        self.impulses.clear();
    }
}
