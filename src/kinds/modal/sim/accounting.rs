//! What the stops do to the structure and where the energy goes: the
//! energy balance of WB00, the dissipation in the stops, the stops'
//! impulses (exact over each segment), forces and reactions.

use nalgebra::DVector;

use super::phases::Segment;
use super::state::EnergyBalance;
use super::Simulation;
use crate::contact::Contact;
use crate::solve::ModalState;

impl Simulation {
    pub fn energy_balance(&self) -> Option<&EnergyBalance> {
        self.state.balance.as_ref()
    }

    /// Adds the loads' work and the damping's dissipation over the part of
    /// the current segment not yet counted, up to `t`, by Gauss-Legendre
    /// quadrature fine enough for the fastest mode: the integrands are
    /// smooth inside a segment, so the sums are exact to rounding.
    fn accumulate_balance(&mut self, t: f64) {
        let Some(from) = self.state.balance.as_ref().map(|b| b.time) else { return };
        if t <= from {
            return;
        }
        let n = self.model.n_modes();
        let fastest = self.fastest_frequency();
        let mut st = ModalState::zeros(n);
        let mut f = DVector::zeros(n);
        let mut forcing = vec![0.0; n];
        let mut damping = vec![0.0; n];
        let mut into_stops = 0.0;
        let pressed: Vec<usize> = (0..self.model.stops.len()).filter(|&i| self.state.stops[i].contact == Contact::Pressed).collect();
        // qd_j f_j and qd_j^2 oscillate at up to twice the fastest frequency.
        crate::solve::quadrature::for_each_node_band_limited(from, t, 2.0 * fastest, |tau, w| {
            self.state_at(tau, &mut st);
            self.dynamics.forcing.derivative(tau, 0, &mut f);
            for j in 0..n {
                let o = &self.model.oscillators[j];
                forcing[j] += w * st.qd[j] * f[j];
                damping[j] += w * 2.0 * o.a * st.qd[j] * st.qd[j];
            }
            // The work the structure does on compliant stops, F p'.
            for &i in &pressed {
                let (s, g) = (&self.model.stops[i], &self.geometries[i]);
                into_stops += w * s.law.force(Contact::Pressed, g.penetration(&st.q), g.penetration_rate(&st.qd), 0.0) * g.penetration_rate(&st.qd);
            }
        });
        let b = self.state.balance.as_mut().expect("checked above");
        for j in 0..n {
            b.forcing[j] += forcing[j];
            b.damping[j] += damping[j];
        }
        b.impacts += into_stops;
        b.time = t;
    }

    /// Brings the balance and the compliant stops' dissipation up to `t`.
    pub(super) fn account(&mut self, t: f64) {
        self.accumulate_balance(t);
        self.accumulate_dissipation(t);
    }

    /// Adds the energy the dashpots of pressed stops dissipate, `c int p'^2`,
    /// over the part of the current segment not yet counted, by quadrature
    /// fine enough for the phase's fastest rate (exact to rounding).
    fn accumulate_dissipation(&mut self, t: f64) {
        let from = self.state.accounted;
        if t <= from {
            return;
        }
        self.state.accounted = t;
        // Only a pressed dashpot dissipates, and only a coupled phase has one.
        let Segment::Coupled { phase, .. } = &self.segment else { return };
        let system = &phase.system;
        let dashpots: Vec<(usize, f64)> = (0..self.model.stops.len())
            .filter(|&i| self.state.stops[i].contact == Contact::Pressed)
            .filter_map(|i| self.model.stops[i].law.dashpot().map(|c| (i, c)))
            .collect();
        if dashpots.is_empty() {
            return;
        }
        let mut fastest = system.fastest();
        for h in &self.dynamics.forcing.harmonics {
            fastest = fastest.max(h.omega);
        }
        let mut st = ModalState::zeros(self.model.n_modes());
        let mut sums = vec![0.0; dashpots.len()];
        crate::solve::quadrature::for_each_node_band_limited(from, t, 2.0 * fastest, |tau, w| {
            self.state_at(tau, &mut st);
            for (k, &(i, c)) in dashpots.iter().enumerate() {
                let v = self.geometries[i].penetration_rate(&st.qd);
                sums[k] += w * c * v * v;
            }
        });
        for (k, &(i, _)) in dashpots.iter().enumerate() {
            self.state.stops[i].dissipated += sums[k];
        }
    }

    /// The impulse stop `i` delivered over the current segment, from the
    /// anchor to `t` (state `at_t`), exact: the force is linear in the
    /// state and the load, so its integral is linear in `int q`
    /// ([`CoupledSegment::integral_q`]), `q(t) - q(t0)` and `int f`.
    fn segment_impulse(&self, i: usize, t: f64, at_t: &ModalState) -> f64 {
        let stop = &self.model.stops[i];
        let g = &self.geometries[i];
        let span = t - self.state.anchor_time;
        if span <= 0.0 {
            return 0.0;
        }
        // The force is a functional `offset + a . q + b . qd`: its integral
        // is `offset span + a . int q + b . [q]`.
        let pressed_spring = |iq: &DVector<f64>| match stop.law.force_functional(g) {
            Some(h) => h.offset * span + h.q.dot(iq) + h.qd.as_ref().map_or(0.0, |b| b.dot(&(&at_t.q - &self.state.anchor.q))),
            None => 0.0,
        };
        match &self.segment {
            // Free oscillators (mode transfer in contact): `omega^2 int q =
            // int f - [q'] - 2 a [q]` mode by mode, exact.
            Segment::Free { .. } if self.state.stops[i].contact == Contact::Pressed => {
                let f = self.dynamics.forcing.integral(self.state.anchor_time, t);
                let iq = DVector::from_fn(f.len(), |j, _| {
                    let o = &self.dynamics.oscillators[j];
                    (f[j] - (at_t.qd[j] - self.state.anchor.qd[j]) - 2.0 * o.a * (at_t.q[j] - self.state.anchor.q[j])) / (o.omega * o.omega)
                });
                pressed_spring(&iq)
            }
            Segment::Free { .. } => 0.0,
            #[cfg(feature = "power-law")]
            Segment::Integrated(seg) => seg.phase.contacts.iter().position(|c| c.stop == i).map_or(0.0, |k| seg.totals_at(k, t).0),
            Segment::Coupled { phase, segment } => match self.state.stops[i].contact {
                Contact::Held => {
                    let r = phase.reactions[i].as_ref().expect("a held stop has a reaction");
                    let iq = segment.integral_q(&phase.system, t);
                    let mut lambda = r.q.dot(&iq) + r.offset * span;
                    if let Some(b) = &r.qd {
                        lambda += b.dot(&(&at_t.q - &self.state.anchor.q));
                    }
                    if let Some(c) = &r.f {
                        lambda += c.dot(&phase.forcing.integral(self.state.anchor_time, t));
                    }
                    -g.side * lambda
                }
                Contact::Pressed => pressed_spring(&segment.integral_q(&phase.system, t)),
                _ => 0.0,
            },
        }
    }

    /// The impulse stop `i` has delivered since the start (0 when the
    /// model does not keep impulses).
    pub fn impulse_total(&self, i: usize) -> f64 {
        if !self.model.impulses {
            return 0.0;
        }
        self.state.stops[i].impulse + self.segment_impulse(i, self.state.time, &self.state.current)
    }

    /// The impulse stop `i` delivered during the last advance that moved
    /// time (>= 0, pushing the structure away from the stop; a difference
    /// of running totals, so clamped at 0 against their rounding).
    pub fn last_impulse(&self, i: usize) -> f64 {
        (self.impulse_total(i) - self.state.stops[i].impulse_mark).max(0.0)
    }

    /// The force stop `i` pushes with now (>= 0): a held stop's reaction, a
    /// pressed compliant stop's `k p + c p'`.
    pub fn stop_force(&self, i: usize) -> f64 {
        let (s, g) = (&self.model.stops[i], &self.geometries[i]);
        match self.state.stops[i].contact {
            Contact::Held => -g.side * self.reaction(i),
            c => s.law.force(c, g.penetration(&self.state.current.q), g.penetration_rate(&self.state.current.qd), self.state.stops[i].onset_speed),
        }
    }

    /// Elastic energy stored in stop `i` now.
    pub fn stop_stored_energy(&self, i: usize) -> f64 {
        self.model.stops[i].law.stored_energy(self.state.stops[i].contact, self.geometries[i].penetration(&self.state.current.q))
    }

    /// Energy dissipated in stop `i` since the start (its dashpot, and the
    /// spring energy left when a dashpot ends contact while penetrated).
    pub fn stop_dissipated_energy(&self, i: usize) -> f64 {
        let mut d = self.state.stops[i].dissipated + self.segment_dissipation(i);
        if self.state.accounted < self.state.time {
            let mut probe = Simulation { record_events: false, scratch: None, ..self.clone() };
            probe.accumulate_dissipation(self.state.time);
            d = probe.state.stops[i].dissipated;
        }
        d
    }

    /// Closes the current segment at `t` (state `at_t`): its impulses join
    /// the stops' totals before a new segment starts.
    pub(super) fn close_segment(&mut self, t: f64, at_t: &ModalState) {
        if self.model.impulses {
            for i in 0..self.model.stops.len() {
                let p = self.segment_impulse(i, t, at_t);
                self.state.stops[i].impulse += p;
            }
        }
        #[cfg(feature = "power-law")]
        if let Segment::Integrated(seg) = &self.segment {
            for (k, c) in seg.phase.contacts.iter().enumerate() {
                self.state.stops[c.stop].dissipated += seg.totals_at(k, t).1.max(0.0);
            }
        }
    }

    /// Energy an integrated phase's contacts dissipated since its anchor.
    fn segment_dissipation(&self, i: usize) -> f64 {
        match &self.segment {
            #[cfg(feature = "power-law")]
            Segment::Integrated(seg) => seg.phase.contacts.iter().position(|c| c.stop == i).map_or(0.0, |k| seg.totals_at(k, self.state.time).1.max(0.0)),
            _ => 0.0,
        }
    }

    /// The fastest frequency in the motion: the highest mode or load.
    fn fastest_frequency(&self) -> f64 {
        let mut fastest = self.model.oscillators.iter().map(|o| o.omega).fold(0.0, f64::max);
        for h in &self.dynamics.forcing.harmonics {
            fastest = fastest.max(h.omega);
        }
        fastest
    }

    /// Quadrature nodes per unit time of the energy accounting in the
    /// current phase (the energy balance, when kept; the dissipation of
    /// pressed dashpots): each costs about what a point of the event
    /// search costs, and counts against the same cap.
    pub(super) fn accounting_nodes_per_time(&self) -> f64 {
        // 16-point panels of pi / 2 at twice the fastest frequency.
        let per_frequency = 16.0 * 2.0 / (0.5 * std::f64::consts::PI);
        let mut rate = match self.state.balance {
            Some(_) => per_frequency * self.fastest_frequency(),
            None => 0.0,
        };
        if let Segment::Coupled { phase, .. } = &self.segment {
            let dashpot = (0..self.model.stops.len()).any(|i| self.state.stops[i].contact == Contact::Pressed && self.model.stops[i].law.dashpot().is_some());
            if dashpot {
                let fastest = self.dynamics.forcing.harmonics.iter().fold(phase.system.fastest(), |m, h| m.max(h.omega));
                rate += per_frequency * fastest;
            }
        }
        rate
    }

    /// The reaction of a stop at the current time (0 unless stuck to it).
    pub fn reaction(&self, stop: usize) -> f64 {
        self.reaction_at(stop, self.state.time, &self.state.current)
    }

    /// The size of the terms of [`Self::reaction_at`] (its rounding level
    /// is relative to it); 0 where the stop holds no reaction.
    pub(super) fn reaction_size_at(&self, stop: usize, t: f64, state: &ModalState) -> f64 {
        match &self.segment {
            Segment::Coupled { phase, .. } => match &phase.reactions[stop] {
                Some(r) => {
                    let mut f = DVector::zeros(self.model.n_modes());
                    phase.forcing.derivative(t, 0, &mut f);
                    r.term_size(state, &f)
                }
                None => 0.0,
            },
            #[cfg(feature = "power-law")]
            Segment::Integrated(seg) => seg.held_push(stop, t, state).map_or(0.0, |(_, size)| size),
            Segment::Free { .. } => 0.0,
        }
    }

    pub(super) fn reaction_at(&self, stop: usize, t: f64, state: &ModalState) -> f64 {
        match &self.segment {
            Segment::Coupled { phase, .. } => match &phase.reactions[stop] {
                Some(r) => {
                    let mut f = DVector::zeros(self.model.n_modes());
                    phase.forcing.derivative(t, 0, &mut f);
                    r.value(state, &f)
                }
                None => 0.0,
            },
            // lambda = -side push (the push is the contact's force).
            #[cfg(feature = "power-law")]
            Segment::Integrated(seg) => seg.held_push(stop, t, state).map_or(0.0, |(push, _)| -self.model.stops[stop].geometry.side * push),
            Segment::Free { .. } => 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::kinds::modal::model::Model;
    use crate::kinds::modal::scene::Scene;
    use crate::kinds::modal::sim::{EventKind, Simulation};

    /// The stop's impulse, exact from the closed forms segment by segment,
    /// against the momentum balance of the one mode of a cantilever thrown
    /// at its tip stop (no loads): `qd(T) - qd(0) + 2 a (q(T) - q(0)) +
    /// omega^2 int q = -side w I`, with `int q` by the trapezoidal rule on
    /// a grid of 1e-4 (`q` is continuous through every event). At least
    /// two of the events met must be `wanted` ones.
    fn impulse_matches_the_momentum_balance(law: &str, wanted: fn(&EventKind) -> bool) {
        let scene = Scene::from_json(&format!(
            r#"{{
                "name": "OneMode",
                "structure": {{ "type": "beam", "support": "clamped-free", "modes": 1 }},
                "damping": {{ "zeta": 0.05 }},
                "stops": [ {{ "name": "tip_stop", "x": 1.0, "gap": 0.1, "side": "positive", "law": {law} }} ],
                "initial": {{ "q": [0.0], "qd": [2.0] }}
            }}"#
        ))
        .unwrap();
        let model = Model::build(&scene).unwrap();
        let (osc, geometry) = (model.oscillators[0].clone(), model.stops[0].geometry.clone());
        let mut sim = Simulation::new(model, 0.0).unwrap();
        let (start, h, steps) = (sim.current().clone(), 1e-4, 50_000);
        let (mut integral, mut previous) = (0.0, start.q[0]);
        let mut events = Vec::new();
        for k in 1..=steps {
            sim.advance_to(k as f64 * h).unwrap();
            let q = sim.current().q[0];
            integral += 0.5 * h * (previous + q);
            previous = q;
            events.extend(sim.drain_events());
        }
        let end = sim.current();
        let momentum = (end.qd[0] - start.qd[0]) + 2.0 * osc.a * (end.q[0] - start.q[0]) + osc.omega * osc.omega * integral;
        let balance = -momentum / (geometry.side * geometry.w[0]);
        let exact = sim.impulse_total(0);
        assert!(events.iter().filter(|e| wanted(&e.kind)).count() >= 2, "{events:?}");
        assert!(exact > 0.5, "an impulse of {exact}");
        assert!((exact - balance).abs() <= 1e-6 * exact, "exact {exact}, from the momentum balance {balance}");
    }

    #[test]
    fn a_spring_dashpot_stop_s_impulse_matches_the_momentum_balance() {
        impulse_matches_the_momentum_balance(r#"{ "type": "spring_dashpot", "k": 20.0, "c": 0.3 }"#, |k| matches!(k, EventKind::Contact { .. }));
    }

    #[test]
    fn a_rigid_stop_s_impulse_matches_the_momentum_balance() {
        impulse_matches_the_momentum_balance(r#"{ "type": "restitution", "R": 0.5, "eps": 1e-6 }"#, |k| matches!(k, EventKind::Impact { .. }));
    }
}
