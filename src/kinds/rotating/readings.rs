//! What the outputs read at the run's present instant, made once per
//! instant: a master reads every output after each communication step,
//! and most of them share the coordinates, the tip's position, the
//! contact point and the energy (the tip one product with an `N x N`
//! modal matrix for both the tip's outputs and the contact point, the
//! energy three). The instant is recognised by what it is
//! made from (time, state, contact state, onset speed), so no change of
//! the run can leave a stale reading behind.

use std::cell::{RefCell, RefMut};

use nalgebra::DVector;

use super::system::{ContactPoint, Phase};
use crate::contact::Contact;
use crate::structure::rotating::TipFrame;

/// The readings of the last instant asked for.
#[derive(Clone, Debug, Default)]
pub(super) struct Readings(RefCell<Option<Reading>>);

/// One instant's coordinates and, once asked for, what is made from them.
#[derive(Clone, Debug)]
pub(super) struct Reading {
    key: Key,
    /// `(z, z') = ([theta, B], [theta', B'])`.
    pub z: DVector<f64>,
    pub zd: DVector<f64>,
    tip: Option<TipFrame>,
    point: Option<ContactPoint>,
    energy: Option<f64>,
}

#[derive(Clone, Debug)]
struct Key {
    time: f64,
    state: DVector<f64>,
    contact: Contact,
    onset_speed: f64,
}

impl Readings {
    /// The instant of `phase` at `time` with integrated state `y`.
    pub(super) fn at(&self, phase: &Phase, time: f64, y: &DVector<f64>) -> RefMut<'_, Reading> {
        let mut cell = self.0.borrow_mut();
        let current = cell.as_ref().is_some_and(|i| {
            let k = &i.key;
            k.time == time && k.contact == phase.contact && k.onset_speed == phase.onset_speed && same_bits(k.state.as_slice(), y.as_slice())
        });
        if !current {
            let (z, zd) = phase.coords(time, y);
            let key = Key { time, state: y.clone(), contact: phase.contact, onset_speed: phase.onset_speed };
            *cell = Some(Reading { key, z, zd, tip: None, point: None, energy: None });
        }
        RefMut::map(cell, |i| i.as_mut().expect("just made"))
    }
}

impl Reading {
    /// The tip in the floating frame (its position and rate: one product
    /// for both the tip's outputs and the contact point).
    fn tip(&mut self, phase: &Phase) -> TipFrame {
        *self.tip.get_or_insert_with(|| phase.model.beam.tip_at(self.z.as_slice(), self.zd.as_slice()))
    }

    /// Tip position in the fixed frame, m.
    pub(super) fn tip_position(&mut self, phase: &Phase) -> [f64; 2] {
        self.tip(phase).position()
    }

    /// The contact point (all zero without a surface).
    pub(super) fn point(&mut self, phase: &Phase) -> ContactPoint {
        if let Some(p) = self.point {
            return p;
        }
        let point = match &phase.model.surface {
            Some(s) => {
                let (gamma, rate) = self.tip(phase).penetration(self.zd[0], &s.plane);
                phase.contact_point_from(gamma, rate)
            }
            None => ContactPoint::default(),
        };
        *self.point.insert(point)
    }

    /// Kinetic, strain and gravity energy of hub and beam, J.
    pub(super) fn energy(&mut self, phase: &Phase) -> f64 {
        *self.energy.get_or_insert_with(|| phase.model.beam.energy(&self.z, &self.zd))
    }
}

/// `a` and `b` hold the same numbers, bit for bit (no early exit: the
/// loop vectorises, and the caller's answer is almost always yes).
fn same_bits(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0, |diff, (x, y)| diff | (x.to_bits() ^ y.to_bits())) == 0
}
