//! The current phase and its segment: the watched event functions
//! (channels) of the stops' contact states, and the segment rebuilt from
//! the anchor when the state or the phase changes (free flight, a coupled
//! contact phase, mode transfer, or an integrated nonlinear phase).

use std::sync::Arc;

use super::coupled::CoupledPhase;
#[cfg(feature = "power-law")]
use super::integrated::IntegratedSegment;
use super::{SimError, Simulation};
use crate::contact::{Contact, PhaseTerm, Watch};
use crate::solve::lti::CoupledSegment;
use crate::solve::{FreeSegment, Functional, ModalState};

/// One watched event function: its stop, its slot among the stop's
/// watches, and what it is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Channel {
    pub(super) stop: usize,
    pub(super) slot: usize,
    pub(super) watch: Watch,
}

/// The motion of the current phase from the anchor.
#[derive(Clone, Debug)]
pub(super) enum Segment {
    Free {
        segment: FreeSegment,
        /// Each channel's function, and its value at the anchor: exactly 0
        /// for a function the event handling just put on its boundary, so
        /// that (for displacement-only functions) the value along the
        /// segment is that plus an increment accurate relative to itself.
        functions: Vec<(Functional, f64)>,
    },
    Coupled { phase: Arc<CoupledPhase>, segment: CoupledSegment },
    /// A nonlinear stop engaged: integrated.
    #[cfg(feature = "power-law")]
    Integrated(Box<IntegratedSegment>),
}

impl Segment {
    /// Whether this is an integrated phase (never in a build without the
    /// integrated laws).
    pub(super) fn is_integrated(&self) -> bool {
        #[cfg(feature = "power-law")]
        if let Segment::Integrated(_) = self {
            return true;
        }
        false
    }
}

impl Simulation {
    /// The event function of one watch of stop `i` (non-negative while the
    /// contact state holds); `None` for a held stop's reaction, which only
    /// the coupled system knows.
    pub(super) fn watched_functional(&self, i: usize, watch: Watch) -> Option<Functional> {
        let stop = &self.model.stops[i];
        let force = || stop.law.force_functional(&self.geometries[i]).expect("a force is watched only for laws that have one");
        Some(match watch {
            Watch::Gap => self.gap_functionals[i].clone(),
            Watch::Penetration => self.gap_functionals[i].clone().scaled(-1.0),
            Watch::Force => force(),
            Watch::NegatedForce => force().scaled(-1.0),
            Watch::Reaction => return None,
        })
    }

    /// Derives the segment from the anchor and the phase.
    pub(super) fn rebuild_segment(&mut self) -> Result<(), SimError> {
        let channels_changed = self.refresh_channels();
        if self.transfer_damped() {
            // Mode transfer in contact with the structure's damping projected
            // on the contact modes: non-proportional, so a coupled phase.
            return self.rebuild_transfer_segment();
        }
        #[cfg(feature = "power-law")]
        if self.model.stops.iter().zip(&self.state.stops).any(|(m, s)| m.law.term(s.contact) == PhaseTerm::Nonlinear) {
            let segment = Segment::Integrated(Box::new(self.integrated_segment()?));
            self.enter(segment);
            return Ok(());
        }
        if self.phase_is_free() {
            self.rebuild_free_segment(channels_changed);
            return Ok(());
        }
        self.rebuild_coupled_segment()
    }

    /// Makes `segment` the current one, keeping the one it displaces as
    /// the spare.
    pub(super) fn enter(&mut self, segment: Segment) {
        let displaced = std::mem::replace(&mut self.segment, segment);
        self.spare = Some(displaced);
    }

    /// Whether free-flight event functions are the current channels' (a
    /// spare's, kept from before a contact phase): gap watches only,
    /// compared by value.
    fn functions_fit(&self, functions: &[(Functional, f64)]) -> bool {
        functions.len() == self.channels.len() && self.channels.iter().zip(functions).all(|(ch, (h, _))| ch.watch == Watch::Gap && *h == self.gap_functionals[ch.stop])
    }

    /// Sets the watched event functions of the current contact states;
    /// whether they changed.
    fn refresh_channels(&mut self) -> bool {
        let wanted = self
            .model
            .stops
            .iter()
            .zip(&self.state.stops)
            .enumerate()
            .flat_map(|(stop, (m, s))| m.law.watches(s.contact).iter().enumerate().map(move |(slot, &watch)| Channel { stop, slot, watch }));
        if wanted.clone().eq(self.channels.iter().copied()) {
            return false;
        }
        self.channels.clear();
        self.channels.extend(wanted);
        true
    }

    /// Whether every stop leaves the current phase's dynamics alone (the
    /// phase key is all open, formed without allocating): the modes fly free.
    fn phase_is_free(&self) -> bool {
        (0..self.model.stops.len()).all(|i| self.phase_contact(i) == Contact::Open)
    }

    /// A free segment from the anchor. A free segment before it is
    /// restarted in place, keeping its event functions when the channels
    /// are the same (an impact on a rigid stop): no allocation per impact.
    pub(super) fn rebuild_free_segment(&mut self, mut channels_changed: bool) {
        // After a contact phase, the free segment it displaced.
        if !matches!(self.segment, Segment::Free { .. }) {
            if let Some(Segment::Free { functions, .. }) = &self.spare {
                if self.functions_fit(functions) {
                    let spare = self.spare.take().expect("a spare");
                    self.enter(spare);
                    channels_changed = false;
                }
            }
        }
        let anchor = &self.state.anchor;
        let value_at_anchor = |ch: &Channel, h: &Functional| if self.state.stops[ch.stop].anchor_departing[ch.slot] { 0.0 } else { h.value_without_load(anchor) };
        if let Segment::Free { segment, functions } = &mut self.segment {
            if !channels_changed && functions.len() == self.channels.len() {
                segment.reset(&self.dynamics, self.state.anchor_time, anchor);
                for (ch, (h, at_anchor)) in self.channels.iter().zip(functions.iter_mut()) {
                    *at_anchor = value_at_anchor(ch, h);
                }
                return;
            }
        }
        let functions = self
            .channels
            .iter()
            .map(|ch| {
                let h = self.watched_functional(ch.stop, ch.watch).expect("free phases watch no reaction");
                let at_anchor = value_at_anchor(ch, &h);
                (h, at_anchor)
            })
            .collect();
        let segment = Segment::Free { segment: FreeSegment::new(&self.dynamics, self.state.anchor_time, anchor), functions };
        self.enter(segment);
    }

    pub(super) fn state_at(&self, t: f64, out: &mut ModalState) {
        match &self.segment {
            Segment::Free { segment, .. } => segment.state_at(&self.dynamics, t, out),
            Segment::Coupled { phase, segment } => segment.state_at(&phase.system, t, out),
            #[cfg(feature = "power-law")]
            Segment::Integrated(seg) => seg.state_at(t, out),
        }
    }
}
