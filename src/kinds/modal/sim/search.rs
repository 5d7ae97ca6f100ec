//! The event search: from the anchor, certified steps that depend only
//! on the anchor, until an event function reaches its zero; then the
//! events are handled and the search goes on from the new anchor.

use super::Channel;
#[cfg(feature = "power-law")]
use super::integrated::IntegratedSwitch;
use crate::contact::{Contact, Switch};
use crate::kind::Reached;
use super::phases::Segment;
use super::{SimError, Simulation};
use crate::contact::Watch;
use crate::solve::events::{certified_step, converging_on_zero, Certified};
use crate::solve::free::{Increment, ModalBounds, ModalJet};
use crate::solve::functional::NOISE;
use crate::solve::lti::{CoordinateBounds, CoupledSample};
use crate::solve::{FreeDynamics, Jet, ModalState};

impl Simulation {
    /// The channels' departing flags, into `out`.
    fn departing_flags_into(&self, out: &mut Vec<bool>) {
        // Written in place: every probe does this.
        out.resize(self.channels.len(), false);
        for (flag, ch) in out.iter_mut().zip(&self.channels) {
            *flag = self.state.stops[ch.stop].departing[ch.slot];
        }
    }

    /// Stores the search's departing flags back into the stops.
    fn set_departing(&mut self, flags: &[bool]) {
        for (ch, &f) in self.channels.iter().zip(flags) {
            self.state.stops[ch.stop].departing[ch.slot] = f;
        }
    }

    /// Jets of every watched event function at time `t` (state `st`), and
    /// the certified step or the list of functions at zero.
    pub(super) fn probe(&self, t: f64, st: &mut ModalState, buffers: &mut ProbeBuffers) -> Probe {
        let tol = self.model.event_tolerance;
        let ProbeBuffers { jet: jet_buf, bounds: bound_buf, increment, coupled, coords, departing, keep, at_zero, limiting, .. } = buffers;
        self.departing_flags_into(departing);
        let mut scan = Scan::new(departing, keep, at_zero, limiting);
        match &self.segment {
            Segment::Free { segment: seg, functions } => {
                seg.state_and_increment_at(&self.dynamics, t, st, increment);
                if self.channels.is_empty() {
                    return scan.finish();
                }
                // The modal jet arrays are only filled for functions of the
                // velocity or the load, and for the mode split.
                let mut modal_ready = false;
                let mut bounds_ready = false;
                for (c, (h, at_anchor)) in functions.iter().enumerate() {
                    let mut jet = if h.qd.is_none() && h.f.is_none() {
                        ModalJet::displacement_jet(&self.dynamics, &increment.rotations, st, h, t)
                    } else {
                        if !modal_ready {
                            jet_buf.fill_free_rotated(&self.dynamics, &increment.rotations, st);
                            modal_ready = true;
                        }
                        jet_buf.functional(h, t)
                    };
                    if h.qd.is_none() {
                        // The value itself from the anchor's plus the increment.
                        let (dh, noise) = increment.functional(&h.q);
                        jet.d[0] = at_anchor + dh;
                        jet.noise[0] = (noise + NOISE * at_anchor.abs()).max(tol);
                    } else {
                        jet.noise[0] = jet.noise[0].max(tol);
                    }
                    let tau = self.tau_max;
                    let displacement = h.qd.is_none() && h.f.is_none();
                    scan.consider(c, jet, |departing| {
                        let bounds = if displacement {
                            seg.displacement_bounds(&self.dynamics, st, increment, tau, h)
                        } else {
                            if !bounds_ready {
                                seg.fill_bounds(&self.dynamics, st, increment, tau, bound_buf);
                                bounds_ready = true;
                            }
                            bound_buf.functional(h, tau)
                        };
                        let plain = certified_step(&jet, &bounds, departing);
                        match plain {
                            Certified::Clear(s) if !departing && !converging_on_zero(&jet, s) => {
                                // Split into transients and steady responses
                                // first: it costs O(N) and, where it certifies
                                // more, the mode split's arrays are not formed
                                // (S2: 4 % less time, the same probes).
                                let transient = seg.transient_split_step(&self.dynamics, st, increment, h, &jet, &bounds);
                                if transient > s {
                                    return Certified::Clear(transient);
                                }
                                if !modal_ready {
                                    jet_buf.fill_free_rotated(&self.dynamics, &increment.rotations, st);
                                    modal_ready = true;
                                }
                                if !bounds_ready {
                                    seg.fill_bounds(&self.dynamics, st, increment, tau, bound_buf);
                                    bounds_ready = true;
                                }
                                Certified::Clear(s.max(bound_buf.split_step(jet_buf, h, &jet, tau)))
                            }
                            other => other,
                        }
                    });
                }
            }
            #[cfg(feature = "power-law")]
            Segment::Integrated(_) => unreachable!("integrated phases search on their own steps"),
            Segment::Coupled { phase, segment } => {
                let (system, events) = (&phase.system, &phase.events);
                // The modal state itself is only formed at events (`scan_to`).
                segment.sample_into(system, t, coupled);
                let mut coords_ready = false;
                for (c, p) in events.iter().enumerate() {
                    let mut jet = segment.jet(p, coupled);
                    if self.channels[c].watch != Watch::Reaction {
                        jet.noise[0] = jet.noise[0].max(tol);
                    }
                    scan.consider(c, jet, |departing| {
                        if !coords_ready {
                            segment.coordinate_bounds_into(system, coupled, self.tau_max, coords);
                            coords_ready = true;
                        }
                        let bounds = segment.bounds(p, coords, self.tau_max);
                        match certified_step(&jet, &bounds, departing) {
                            Certified::Clear(s) if !departing && !converging_on_zero(&jet, s) => {
                                Certified::Clear(s.max(segment.split_step(system, p, coupled, coords, &jet, &bounds)))
                            }
                            other => other,
                        }
                    });
                }
            }
        }
        scan.finish()
    }

    pub(super) fn advance_with(&mut self, t_end: f64, buffers: &mut ProbeBuffers, stop_before: Option<&mut dyn FnMut(f64) -> bool>) -> Result<Reached, SimError> {
        let mut st = std::mem::replace(&mut buffers.state, ModalState::zeros(0));
        let result = self.scan_to(t_end, &mut st, buffers, stop_before);
        buffers.state = st;
        result
    }

    /// Whether the functions at their zero (state `st`) make an event the
    /// record reports (an impact, a stick, a release, a contact's onset or
    /// the end of its push), not only touch their boundary: where an
    /// advance may stop before the change.
    fn changes_state(&self, st: &ModalState, at_zero: &[(usize, Jet)]) -> bool {
        at_zero.iter().any(|(c, jet)| {
            let Channel { stop: i, watch, .. } = self.channels[*c];
            let contact = self.state.stops[i].contact;
            match self.model.stops[i].law.on_zero(contact, watch, jet, self.geometries[i].penetration(&st.q)) {
                Switch::Stay | Switch::Graze => false,
                // A compliant stop's switches that the event record leaves
                // out (the point leaving a stop penetrated without force,
                // or pressed again inside it) change the phase, not what
                // an importer sees: no stop there (one per reported event).
                Switch::To(next) if contact != Contact::Held => {
                    matches!((contact, next), (Contact::Open, Contact::Pressed) | (Contact::Pressed, _))
                }
                _ => true,
            }
        })
    }

    /// Moves an event found at `l` onto the zero itself. The search stops
    /// where the function is within its (conservative) rounding noise of
    /// zero, up to some tens of ulp of the time early; Newton steps on the
    /// closed form take it to within an ulp or two (the free pinned beam's
    /// first impact at 1/(2 pi): from 28 ulp to 1), as long as each step
    /// stays inside the other functions' certified clear step and the
    /// advance (up to `t_end`), and the point it reaches still has the
    /// event within rounding on either side. Steps only go forward and
    /// stop where the next one rounds away or the zero is passed, so a
    /// restored run probing at the point returned stays there. Unbiased:
    /// over 1000 impacts of the free beam with R = 1 the struck point sits
    /// at -1.3e-15 on average, against +7.3e-15 without.
    fn polish(&self, mut l: f64, mut clear: f64, t_end: f64, st: &mut ModalState, buffers: &mut ProbeBuffers) -> f64 {
        for _ in 0..8 {
            let Some(delta) = newton_step(&buffers.at_zero) else { break };
            let to = l + delta;
            if !(to > l && to <= t_end && delta <= clear) {
                break;
            }
            match self.probe(to, st, buffers) {
                // At the zero within rounding from either side: a step
                // that overshoots (a slope off at a far time) is not taken.
                Probe::Events { clear: c } if buffers.at_zero.iter().all(|(_, j)| j.d[0] >= -j.noise[0]) => {
                    l = to;
                    clear = c;
                }
                Probe::Events { .. } => {
                    let again = self.probe(l, st, buffers);
                    debug_assert!(matches!(again, Probe::Events { .. }));
                    break;
                }
                Probe::Clear { .. } => {
                    // Not at the zero there after all: the event stays at l.
                    let again = self.probe(l, st, buffers);
                    debug_assert!(matches!(again, Probe::Events { .. }));
                    break;
                }
            }
        }
        l
    }

    /// Stops just before an integrated phase's switch at `te`, in the
    /// switch's own state (the segment's exact state there, which the
    /// switch's handling continues from): the outputs before the change
    /// are those after it wherever the law resets nothing. A restore finds
    /// the switch again for it ([`Simulation::restore`]).
    fn stop_at_switch(&mut self, te: f64) {
        self.account(te);
        self.state.time = te;
        let mut current = std::mem::replace(&mut self.state.current, ModalState::zeros(0));
        self.state_at(te, &mut current);
        self.state.current = current;
    }

    /// Stops consistently at `l`, the last point the search reached.
    fn stop_at(&mut self, l: f64) {
        self.account(l);
        self.state.time = l;
        // The state a restore recomputes (a full-order step), not the
        // collocation polynomial's.
        #[cfg(feature = "power-law")]
        if let Segment::Integrated(seg) = &mut self.segment {
            seg.settle_at(l);
        }
        let mut current = std::mem::replace(&mut self.state.current, ModalState::zeros(0));
        self.state_at(l, &mut current);
        self.state.current = current;
    }

    /// The search up to `t_end` (module doc); with `stop_before`, it stops
    /// just before the change of the first event that changes the state or
    /// the phase and for which `stop_before(te)` says so.
    fn scan_to(&mut self, t_end: f64, st: &mut ModalState, buffers: &mut ProbeBuffers, mut stop_before: Option<&mut dyn FnMut(f64) -> bool>) -> Result<Reached, SimError> {
        let mut count = 0u64;
        let mut probes = 0u64;
        // The accounting's quadrature nodes so far, up to `counted`, at the
        // current phase's rate.
        let (mut nodes, mut counted, mut node_rate) = (0.0, self.state.time, self.accounting_nodes_per_time());
        // The budget in points as a float, converted once: u64 to f64 is a
        // dozen instructions on x86-64 (i64 to f64 one), at every probe.
        let budget = self.model.max_probes_per_step as f64;
        // The work the cap counts, kept in the stats as it grows.
        let base = self.stats.work;
        loop {
            #[cfg(feature = "power-law")]
            if self.segment.is_integrated() {
                // The integrated search counts against the cap with the
                // accounting's nodes so far.
                let mut work = probes + nodes as u64;
                let searched = self.integrated_search(t_end, &mut work);
                probes = work - nodes as u64;
                self.stats.work = base + probes + nodes as u64;
                let Some(found) = searched.inspect_err(|_| self.stop_at(self.state.scan.min(t_end)))? else { break };
                let IntegratedSwitch { time: te, state: at, at_zero, from } = found;
                if stop_before.is_some() && self.changes_state(&at, &at_zero) && stop_before.as_mut().is_some_and(|f| f(te)) {
                    // The search finds the switch again from the sample its
                    // bracket started at (the one search position allowed
                    // before the time: see the codec).
                    self.state.scan = from;
                    self.stop_at_switch(te);
                    return Ok(Reached::Event(te));
                }
                count += 1;
                self.stats.events += 1;
                if count > self.model.max_events_per_step {
                    self.stop_at(te);
                    return Err(SimError::TooManyEvents { time: te, count });
                }
                let anchor = self.state.anchor_time;
                let mut at = at;
                // The integrated search tests signs, not departures: only
                // the functions at zero here get their flags (from the
                // event handling).
                for s in &mut self.state.stops {
                    s.departing = [false; 2];
                }
                self.state.probed = te;
                self.handle_events(te, &mut at, &at_zero)?;
                if self.state.anchor_time == anchor && self.segment.is_integrated() {
                    // Nothing switched: search on past the zero.
                    self.state.scan = self.state.scan.max(te);
                }
                continue;
            }
            let mut l = self.state.scan;
            if l > t_end {
                break;
            }
            probes += 1;
            let more = node_rate * (l - counted);
            if probes as i64 as f64 + nodes + more > budget {
                // Stop where the accounting's nodes exhaust the budget (the
                // search has certified every point up to l).
                let room = (budget - probes as i64 as f64 - nodes).max(0.0);
                let at = if more > room { (counted + room / node_rate).clamp(counted, l) } else { l };
                self.stop_at(at);
                // The work the cap counts: the search points and the
                // accounting's quadrature nodes.
                let work = (probes - 1) + nodes as u64;
                self.stats.work = base + work;
                return Err(SimError::TooMuchWork { time: at, work, cap: "solver.max_probes_per_step" });
            }
            nodes += more;
            counted = l;
            self.stats.work = base + probes + nodes as u64;
            self.stats.probes += 1;
            match self.probe(l, st, buffers) {
                Probe::Events { clear } => {
                    let polished = self.polish(l, clear, t_end, st, buffers);
                    if polished != l {
                        self.state.scan = polished;
                        l = polished;
                    }
                }
                Probe::Clear { step, limiting } => {
                    // Clear down to the search's resolution: step on.
                    let next = l + step;
                    if next > l {
                        if l == t_end {
                            break;
                        }
                        // Functions leaving their boundary stop departing once clear of noise.
                        self.set_departing(&buffers.keep);
                        self.state.probed = l;
                        self.state.scan = next;
                        continue;
                    }
                    // The zero is within one ulp of l.
                    match limiting {
                        Some(i) => buffers.at_zero.push((i, buffers.limiting)),
                        None => break,
                    }
                }
            }
            if let Segment::Coupled { phase, segment } = &self.segment {
                // Coupled probes sample the complex coordinates only; the
                // probe at the event has them at its time.
                segment.state_at_sample(&phase.system, l, &buffers.coupled, st);
            }
            if stop_before.is_some() && self.changes_state(st, &buffers.at_zero) && stop_before.as_mut().is_some_and(|f| f(l)) {
                // Found again by the probe at the search position, l.
                self.stop_at(l);
                return Ok(Reached::Event(l));
            }
            count += 1;
            self.stats.events += 1;
            if count > self.model.max_events_per_step {
                self.stop_at(l);
                return Err(SimError::TooManyEvents { time: l, count });
            }
            // Every flag from this point: the functions at zero get theirs
            // from the event handling, the others keep what the probe found.
            self.set_departing(&buffers.keep);
            self.state.probed = l;
            self.handle_events(l, st, &buffers.at_zero)?;
            node_rate = self.accounting_nodes_per_time();
            if std::mem::take(&mut self.basis_changed) {
                *buffers = ProbeBuffers::new(&self.dynamics);
                *st = ModalState::zeros(self.model.n_modes());
            }
        }
        self.account(t_end);
        self.state.time = t_end;
        #[cfg(feature = "power-law")]
        if let Segment::Integrated(seg) = &mut self.segment {
            seg.settle_at(t_end);
        }
        let mut current = std::mem::replace(&mut self.state.current, ModalState::zeros(0));
        self.state_at(t_end, &mut current);
        self.state.current = current;
        Ok(Reached::Time)
    }

    /// Whether the event search, restarted at the current time with the
    /// current departing flags, proves `[time, scan)` free of events within
    /// `max_probes` points: the check of a restored state's claim that its
    /// segment is event-free up to `scan` (a forged claim would skip a
    /// contact). The state itself is not changed, so a state that passes
    /// continues bit for bit.
    pub(super) fn certifies_up_to_scan(&self, max_probes: u64) -> bool {
        let target = self.state.scan;
        let mut check = Simulation { record_events: false, scratch: None, ..self.clone() };
        #[cfg(feature = "power-law")]
        if check.segment.is_integrated() {
            // Replay the phase and search it from the current time.
            if check.rebuild_segment().is_err() {
                return false;
            }
            check.state.scan = check.state.time;
            let mut probes = 0;
            return matches!(check.integrated_search(target, &mut probes), Ok(None));
        }
        check.state.scan = check.state.time;
        let mut buffers = ProbeBuffers::new(&check.dynamics);
        let mut st = ModalState::zeros(check.model.n_modes());
        for _ in 0..max_probes {
            let l = check.state.scan;
            if l >= target {
                return true;
            }
            match check.probe(l, &mut st, &mut buffers) {
                Probe::Events { .. } => return false,
                Probe::Clear { step, .. } => {
                    if !(l + step > l) {
                        return false;
                    }
                    check.set_departing(&buffers.keep);
                    check.state.scan = l + step;
                }
            }
        }
        false
    }
}

/// Work space of the event search.
#[derive(Clone, Debug)]
pub(super) struct ProbeBuffers {
    state: ModalState,
    jet: ModalJet,
    bounds: ModalBounds,
    increment: Increment,
    coupled: CoupledSample,
    coords: Vec<CoordinateBounds>,
    /// The channels' departing flags before and after a probe.
    departing: Vec<bool>,
    keep: Vec<bool>,
    /// The functions at their zero after a probe that found events.
    pub(super) at_zero: Vec<(usize, Jet)>,
    /// The jet of the function that limited a clear probe's step.
    limiting: Jet,
}

impl ProbeBuffers {
    pub(super) fn new(dynamics: &FreeDynamics) -> Self {
        let n = dynamics.oscillators.len();
        ProbeBuffers {
            state: ModalState::zeros(n),
            jet: ModalJet::new(n),
            bounds: ModalBounds::new(dynamics),
            increment: Increment::new(n),
            coupled: CoupledSample::default(),
            coords: Vec::new(),
            departing: Vec::new(),
            keep: Vec::new(),
            at_zero: Vec::new(),
            limiting: Jet::default(),
        }
    }
}

/// What one probe of the event search found.
pub(super) enum Probe {
    /// No zero at this point; the probe buffers' `keep` holds the
    /// departing flags of functions still within noise of their boundary.
    /// `limiting`: the function that set the step (its jet in the probe
    /// buffers' `limiting`).
    Clear { step: f64, limiting: Option<usize> },
    /// Functions at their zero, listed in the probe buffers' `at_zero`;
    /// the others are clear for `clear`.
    Events { clear: f64 },
}

/// The event functions' verdicts at one point, gathered.
struct Scan<'a> {
    /// Functions leaving their boundary (input).
    departing: &'a [bool],
    at_zero: &'a mut Vec<(usize, Jet)>,
    step: f64,
    limiting: Option<usize>,
    /// The limiting function's jet (output; written in place, not moved
    /// through the probe's result: it is only read at a step below an ulp).
    limiting_jet: &'a mut Jet,
    /// Functions still departing after this point (output).
    keep: &'a mut Vec<bool>,
}

impl<'a> Scan<'a> {
    fn new(departing: &'a [bool], keep: &'a mut Vec<bool>, at_zero: &'a mut Vec<(usize, Jet)>, limiting_jet: &'a mut Jet) -> Self {
        keep.resize(departing.len(), false);
        keep.fill(false);
        at_zero.clear();
        Scan { departing, at_zero, step: f64::INFINITY, limiting: None, limiting_jet, keep }
    }

    /// One function: at its zero (an event), or clear for a certified step;
    /// `step` (given whether the function is departing) certifies it, and
    /// is only called when needed.
    fn consider(&mut self, i: usize, jet: Jet, step: impl FnOnce(bool) -> Certified) {
        let departing = self.departing[i];
        if jet.d[0] <= jet.noise[0] {
            if !departing {
                self.at_zero.push((i, jet));
                return;
            }
            self.keep[i] = true;
        }
        match step(departing) {
            Certified::Clear(s) => {
                if s < self.step {
                    self.step = s;
                    self.limiting = Some(i);
                    *self.limiting_jet = jet;
                }
            }
            Certified::AtZero => self.at_zero.push((i, jet)),
        }
    }

    fn finish(self) -> Probe {
        if self.at_zero.is_empty() {
            Probe::Clear { step: self.step, limiting: self.limiting }
        } else {
            Probe::Events { clear: self.step }
        }
    }
}

/// The Newton step from a point where every function in `at_zero` is at
/// its zero within rounding noise and still decreasing (the search
/// converges on a transversal zero from the admissible side) to the first
/// of their zeros; `None` where one is at or past its zero, or grazing.
fn newton_step(at_zero: &[(usize, Jet)]) -> Option<f64> {
    let mut delta = f64::INFINITY;
    for (_, jet) in at_zero {
        let [h, h1, ..] = jet.d;
        if !(h > 0.0 && h1 < 0.0) {
            return None;
        }
        delta = delta.min(h / -h1);
    }
    delta.is_finite().then_some(delta)
}
