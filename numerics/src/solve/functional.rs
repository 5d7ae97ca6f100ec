//! Event functions: scalars linear in the modal state and the load,
//! `h(t) = offset + a . q + b . qd + c . f(t)`.
//!
//! Gaps (`d - w . q`) and contact reactions (VSM12 eq. 33) both have this
//! form, so one event locator serves every switch of every phase.

use nalgebra::DVector;

#[derive(Clone, Debug, PartialEq)]
pub struct Functional {
    pub offset: f64,
    pub q: DVector<f64>,
    pub qd: Option<DVector<f64>>,
    pub f: Option<DVector<f64>>,
}

impl Functional {
    /// `offset + a . q`.
    pub fn of_position(offset: f64, a: DVector<f64>) -> Self {
        Functional { offset, q: a, qd: None, f: None }
    }

    /// The value for a state and a load vector.
    pub fn value(&self, state: &crate::solve::ModalState, f: &DVector<f64>) -> f64 {
        self.offset
            + self.q.dot(&state.q)
            + self.qd.as_ref().map_or(0.0, |b| b.dot(&state.qd))
            + self.f.as_ref().map_or(0.0, |c| c.dot(f))
    }

    /// The size of the terms of [`Self::value`] (the sum of their
    /// magnitudes): what the value's rounding is relative to.
    pub fn term_size(&self, state: &crate::solve::ModalState, f: &DVector<f64>) -> f64 {
        let dot_abs = |a: &DVector<f64>, b: &DVector<f64>| a.iter().zip(b.iter()).map(|(x, y)| (x * y).abs()).sum::<f64>();
        self.offset.abs()
            + dot_abs(&self.q, &state.q)
            + self.qd.as_ref().map_or(0.0, |b| dot_abs(b, &state.qd))
            + self.f.as_ref().map_or(0.0, |c| dot_abs(c, f))
    }

    /// The value for a state with no load (`c . f` left out).
    pub fn value_without_load(&self, state: &crate::solve::ModalState) -> f64 {
        self.offset + self.q.dot(&state.q) + self.qd.as_ref().map_or(0.0, |b| b.dot(&state.qd))
    }

    pub fn scaled(mut self, s: f64) -> Self {
        self.offset *= s;
        self.q *= s;
        if let Some(b) = self.qd.as_mut() {
            *b *= s;
        }
        if let Some(c) = self.f.as_mut() {
            *c *= s;
        }
        self
    }
}

/// `h, h', h'', h'''` at one instant, each with the size of its rounding noise.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Jet {
    pub d: [f64; 4],
    pub noise: [f64; 4],
    /// The rounding level of `h` measured from the absolute state: a dip
    /// below zero no deeper than this is the boundary itself (`noise[0]`
    /// can be far smaller when `h` is computed as an increment).
    pub slack: f64,
}

impl Jet {
    /// Widens the noise of the derivatives by what an error of a few ulps in
    /// the time `t` does to them: event times are only known to that
    /// resolution, so a derivative that small is no evidence of a direction.
    /// (The value itself keeps its rounding noise: the event search
    /// converges on it.)
    pub fn with_time_uncertainty(mut self, t: f64) -> Self {
        let dt = 4.0 * f64::EPSILON * t.abs().max(1.0);
        for m in 1..3 {
            self.noise[m] += self.d[m + 1].abs() * dt;
        }
        self.slack = self.slack.max(self.noise[0]);
        self
    }
}

/// Bounds on `|h''|, |h'''|, |h''''|` over an interval `[t, t + tau]`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DerivativeBounds {
    pub tau: f64,
    pub m: [f64; 3],
    /// The rounding levels of `h, h', h'', h'''` that the bounds themselves
    /// allow for (0 where they are built from the exact state): values below
    /// them are no evidence of a direction.
    pub floor: [f64; 4],
}

/// Relative size of the rounding noise assumed on every evaluated quantity.
pub const NOISE: f64 = 64.0 * f64::EPSILON;
