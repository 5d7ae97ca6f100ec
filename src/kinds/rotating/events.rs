//! The contact law's watched functions along one accepted step, on the
//! integrator's dense output `u(t)`, for the shared switch locator
//! ([`crate::solve::switch`]): the surface's law says which functions its
//! contact state watches ([`crate::contact::ContactLaw::watches`]) and
//! their values; the geometric ones (the gap, the penetration) also give
//! their rate along `u`, so that a tip that dips into the surface and
//! leaves again between two samples is found. Also the largest force of a
//! push inside the step.

use std::cell::{Cell, RefCell};

use nalgebra::DVector;

use super::stepper::Stepper;
use super::system::{ContactPoint, Phase};
use crate::contact::{Contact, Watch};
use crate::solve::extremum::maximize;
use crate::solve::switch::{first_switch, is_inner_sample, DenseWatch, SAMPLES};

/// The last accepted step `[t0, t1]` of `solver`, with the state `y0` at its start.
pub struct StepCurve<'a> {
    pub phase: &'a Phase,
    pub solver: &'a Stepper,
    pub t0: f64,
    pub t1: f64,
    pub y0: &'a DVector<f64>,
    /// Room for `u(t)` and `u'(t)` (the samples' states), and for the
    /// modal route's product ([`Stepper::dense_penetration`]).
    buffers: &'a RefCell<(DVector<f64>, DVector<f64>, Vec<f64>)>,
    /// The last few contact points and gap rates, by time: the locator
    /// asks for a sample's value and rate again as the next bracket's
    /// start.
    points: RefCell<Recent<ContactPoint>>,
    rates: RefCell<Recent<f64>>,
    /// Windows the conservative advancement searched (its work).
    windows: Cell<u64>,
}

/// The room a step's curve works in, kept across steps by the simulation
/// (its contents are written before they are read).
#[derive(Clone, Debug, Default)]
pub struct CurveRoom(RefCell<(DVector<f64>, DVector<f64>, Vec<f64>)>);

/// The last [`RECENT`] values of a function of time.
struct Recent<T> {
    entries: [(f64, T); RECENT],
    next: usize,
}

const RECENT: usize = 4;

impl<T: Copy + Default> Recent<T> {
    fn new() -> Self {
        Recent { entries: [(f64::NAN, T::default()); RECENT], next: 0 }
    }

    fn get(&self, t: f64) -> Option<T> {
        self.entries.iter().find(|e| e.0 == t).map(|e| e.1)
    }

    fn put(&mut self, t: f64, value: T) -> T {
        self.entries[self.next] = (t, value);
        self.next = (self.next + 1) % RECENT;
        value
    }
}

/// `len` entries of room: on the stack up to its length, else on the heap.
fn room<'a>(stack: &'a mut [f64], heap: &'a mut Vec<f64>, len: usize) -> &'a mut [f64] {
    if len <= stack.len() {
        &mut stack[..len]
    } else {
        heap.resize(len, 0.0);
        &mut heap[..]
    }
}

/// A located switch: its time, the watch whose zero it is, and the slope
/// of the chord that bracketed it.
pub type Switch = (f64, Watch, f64);

impl<'a> StepCurve<'a> {
    pub fn new(phase: &'a Phase, solver: &'a Stepper, t0: f64, t1: f64, y0: &'a DVector<f64>, room: &'a CurveRoom) -> Self {
        let dim = y0.len();
        {
            let (y, dy, _) = &mut *room.0.borrow_mut();
            if y.len() != dim {
                *y = DVector::zeros(dim);
                *dy = DVector::zeros(dim);
            }
        }
        StepCurve {
            phase,
            solver,
            t0,
            t1,
            y0,
            buffers: &room.0,
            points: RefCell::new(Recent::new()),
            rates: RefCell::new(Recent::new()),
            windows: Cell::new(0),
        }
    }

    /// `u(t)` into `out`, as [`Self::y`].
    fn y_into(&self, t: f64, out: &mut DVector<f64>) {
        if t <= self.t0 {
            out.copy_from(self.y0);
        } else if t >= self.t1 || !self.solver.dense(t, out) {
            out.copy_from_slice(self.solver.y_slice());
        }
    }

    /// `u(t)`: exactly `y0` and the step's end at the ends.
    pub fn y(&self, t: f64) -> DVector<f64> {
        if t <= self.t0 {
            return self.y0.clone();
        }
        if t >= self.t1 {
            return self.solver.y();
        }
        let mut out = DVector::zeros(self.y0.len());
        if !self.solver.dense(t, &mut out) {
            out = self.solver.y();
        }
        out
    }

    pub fn point(&self, t: f64) -> ContactPoint {
        if let Some(c) = self.points.borrow().get(t) {
            return c;
        }
        let c = self.point_uncached(t);
        self.points.borrow_mut().put(t, c)
    }

    fn point_uncached(&self, t: f64) -> ContactPoint {
        if let Some((penetration, rate)) = self.inside_penetration(t) {
            return self.phase.contact_point_from(penetration, rate);
        }
        if self.phase.prescribed() {
            let y = self.y(t);
            let (z, zd) = self.phase.coords(t, &y);
            return self.phase.contact_point(&z, &zd);
        }
        let y = &mut self.buffers.borrow_mut().0;
        self.y_into(t, y);
        let m = self.phase.n() + 1;
        self.phase.contact_point_at(&y.as_slice()[..m], &y.as_slice()[m..2 * m])
    }

    fn watches(&self) -> &'static [Watch] {
        match &self.phase.model.surface {
            Some(s) => s.law.watches(self.phase.contact),
            None => &[],
        }
    }

    fn watched(&self, watch: Watch, c: &ContactPoint) -> f64 {
        let law = &self.phase.model.surface.as_ref().expect("a surface").law;
        law.watched(watch, c.penetration, c.rate, self.phase.onset_speed).0
    }

    /// `d/dt gap(u(t))`.
    fn gap_rate(&self, t: f64) -> f64 {
        if let Some(r) = self.rates.borrow().get(t) {
            return r;
        }
        let r = self.gap_rate_uncached(t);
        self.rates.borrow_mut().put(t, r)
    }

    /// The contact point for the peak force's search: inside the step
    /// from the exponential integrator's modal state (the search decides
    /// no switch), else [`Self::point`].
    fn peak_point(&self, t: f64) -> ContactPoint {
        if let Some(c) = self.points.borrow().get(t) {
            return c;
        }
        if t > self.t0 && t < self.t1 {
            if let Some((penetration, rate)) = self.solver.dense_penetration(self.phase, t, &mut self.buffers.borrow_mut().2) {
                return self.phase.contact_point_from(penetration, rate);
            }
        }
        self.point(t)
    }

    /// The penetration and its rate at a sample of the step's grid
    /// ([`crate::solve::switch::grid`], inside the step) from the
    /// exponential integrator's modal state. Everywhere else (the step's
    /// ends, the roots' bisection, the peak's search) they come from the
    /// physical state ([`Self::y`]): a switch's time is where the physical
    /// state's function changes sign, so the next phase, which starts
    /// from that state, does not start a rounding past its zero.
    fn inside_penetration(&self, t: f64) -> Option<(f64, f64)> {
        if !(t > self.t0 && t < self.t1 && is_inner_sample(self.t0, self.t1, t)) {
            return None;
        }
        self.solver.dense_penetration(self.phase, t, &mut self.buffers.borrow_mut().2)
    }

    fn gap_rate_uncached(&self, t: f64) -> f64 {
        let Some(s) = &self.phase.model.surface else { return 0.0 };
        if let Some((_, rate)) = self.inside_penetration(t) {
            return -rate;
        }
        if self.solver.velocity_is_rate() {
            // The dense output's velocities are its coordinates' rates.
            let y = &mut self.buffers.borrow_mut().0;
            self.y_into(t, y);
            if !self.phase.prescribed() {
                let m = self.phase.n() + 1;
                return -self.phase.model.beam.plane_penetration(&y.as_slice()[..m], &y.as_slice()[m..2 * m], &s.plane).1;
            }
            let (z, zd) = self.phase.coords(t, y);
            return self.phase.model.beam.contact_generalized_force(&z, &s.plane, 1.0).dot(&zd);
        }
        if !self.phase.prescribed() {
            // The penetration's rate is linear in z': along `u`, with `u'`
            // in its place, it is the rate of the penetration of `u`.
            let (y, dy, _) = &mut *self.buffers.borrow_mut();
            self.y_into(t, y);
            if !self.solver.dense_derivative(t, dy) {
                return 0.0;
            }
            let m = self.phase.n() + 1;
            return -self.phase.model.beam.plane_penetration(&y.as_slice()[..m], &dy.as_slice()[..m], &s.plane).1;
        }
        let y = self.y(t);
        let mut dy = DVector::zeros(y.len());
        if !self.solver.dense_derivative(t, &mut dy) {
            return 0.0;
        }
        let (z, _) = self.phase.coords(t, &y);
        let zdot = self.phase.coords_rate(t, &dy);
        self.phase.model.beam.contact_generalized_force(&z, &s.plane, 1.0).dot(&zdot)
    }

    /// The windows the first switch's search searched one by one (see
    /// [`Self::first_switch_advancing`]).
    pub fn windows(&self) -> u64 {
        self.windows.get()
    }

    /// The first switch in the step, or `None`.
    pub fn first_switch(&self) -> Option<Switch> {
        let located = match self.gap_speed_bound() {
            Some(speed) => self.first_switch_advancing(speed)?,
            None => first_switch(self, self.t0, self.t1, self.t0)?,
        };
        let (i, slope) = located.at_zero[0];
        Some((located.time, self.watches()[i], slope))
    }

    /// For a step of the exponential integrator or DOP853 in free flight: a bound
    /// on `|d gap / dt|` over it (the modes' speeds along the gap's
    /// gradient at the step's start, the hub's for a prescribed one), and
    /// what the gradient's turn with the hub adds: the plane's normal turns
    /// in the beam's frame, so over a step that turns the hub by up to
    /// `dtheta` each entry of the gradient moves by up to `dtheta` times
    /// its amplitude
    /// ([`crate::structure::rotating::RotatingBeam::contact_gradient_and_turn`]), times that
    /// coordinate's largest rate. A step that the gap cannot close in is
    /// not sampled.
    fn gap_speed_bound(&self) -> Option<f64> {
        let surface = self.phase.model.surface.as_ref()?;
        if self.phase.contact != Contact::Open {
            return None;
        }
        let (z, zd) = self.phase.coords(self.t0, self.y0);
        let (gradient, turn) = self.phase.model.beam.contact_gradient_and_turn(&z, &surface.plane);
        let h = self.t1 - self.t0;
        let (mut stack, mut heap) = ([0.0; 72], Vec::new());
        match self.phase.model.prescribed() {
            None => {
                let rates = room(&mut stack, &mut heap, gradient.len());
                let along = self.solver.speed_bounds(gradient.as_slice(), rates)?;
                let dtheta = h * rates[0];
                Some(along + dtheta * turn.iter().zip(rates.iter()).map(|(a, r)| a * r).sum::<f64>())
            }
            Some(p) => {
                let speed = zd[0].abs().max(p.speed_bound(self.t0, self.t1));
                let rates = room(&mut stack, &mut heap, gradient.len() - 1);
                let along = self.solver.speed_bounds(&gradient.as_slice()[1..], rates)? + 1.5 * (gradient[0].abs() * speed);
                let dtheta = h * speed;
                Some(along + dtheta * (turn[0] * speed + turn.iter().skip(1).zip(rates.iter()).map(|(a, r)| a * r).sum::<f64>()))
            }
        }
    }

    /// The first switch by conservative advancement: from each point the
    /// gap cannot close before `gap / speed`; where that is shorter than
    /// a quarter of the shortest modal period, the shared locator searches
    /// the next period's window (samples, interior minima), and the
    /// advancement resumes after it; where the gap cannot move by more
    /// than its rounding before the step's end, the rest of the step is
    /// one window. No zero is passed while `speed` bounds the gap's rate.
    fn first_switch_advancing(&self, speed: f64) -> Option<crate::solve::switch::Located> {
        let window = self.phase.model.shortest_period();
        // The gap's rounding: a few units in the last place of the tip's
        // distance from the axis.
        let still = 4.0 * f64::EPSILON * self.phase.model.tip_radius();
        let mut t = self.t0;
        while t < self.t1 {
            let gap = -self.point(t).penetration;
            if gap > 0.0 && gap > 0.25 * window * speed {
                let next = (t + gap / speed).min(self.t1);
                if next >= self.t1 {
                    // The gap cannot close before the step's end.
                    break;
                }
                // (An advance below the time's resolution there would
                // stand still: the window's search moves on instead.)
                if next > t {
                    t = next;
                    continue;
                }
            }
            // A window below the time's resolution (a state from outside
            // at a late time) would stand still, and where the gap cannot
            // move by more than its rounding before the step's end (a beam
            // at rest on the surface) windows find nothing samples of the
            // whole rest miss: the rest of the step.
            let b = (t + window).min(self.t1);
            let b = if b > t && speed * (self.t1 - t) > still { b } else { self.t1 };
            self.windows.set(self.windows.get() + 1);
            if let Some(located) = first_switch(self, t, b, t) {
                return Some(located);
            }
            t = b;
        }
        None
    }

    /// The largest force on `[t0, end]` along `u` while pressed: its time
    /// (a golden-section search over the sample intervals on either side of
    /// the best sample, also when that is the first or the last: the peak
    /// may lie inside the first or last interval) and value.
    pub fn peak_force(&self, end: f64) -> Option<(f64, f64)> {
        if self.phase.contact != Contact::Pressed || self.phase.model.surface.is_none() {
            return None;
        }
        let end = end.min(self.t1);
        let h = end - self.t0;
        if h <= 0.0 || h.is_nan() {
            return None;
        }
        let f = |t: f64| self.peak_point(t).force;
        let ts: [f64; SAMPLES + 1] = std::array::from_fn(|k| if k == SAMPLES { end } else { self.t0 + h * k as f64 / SAMPLES as f64 });
        let fs: [f64; SAMPLES + 1] = std::array::from_fn(|k| f(ts[k]));
        let k = (0..ts.len()).fold(0, |best, i| if fs[i] > fs[best] { i } else { best });
        let xtol = 1e-8 * h;
        if k == 0 || k == SAMPLES {
            // The best sample an end and the force falling from it into
            // the step: that end is the peak (the search below takes the
            // bracket to hold one peak; it would close in on the end by
            // golden sections, about 38 evaluations).
            let inside = if k == 0 { ts[0] + xtol } else { ts[SAMPLES] - xtol };
            if f(inside) <= fs[k] {
                return Some((ts[k], fs[k]));
            }
        }
        let (lo, hi) = (ts[k.saturating_sub(1)], ts[(k + 1).min(SAMPLES)]);
        // Brent's search from the best sample (its bracket's middle, or
        // a point inside when it is an end: the peak may lie inside the
        // first or last interval); a location to 1e-8 of the step leaves
        // the value's error at ~1e-16 of the force's curvature scale.
        let (x, fx) = if k == 0 || k == SAMPLES { let x = 0.5 * (lo + hi); (x, f(x)) } else { (ts[k], fs[k]) };
        let (t, v) = maximize(f, lo, hi, x, fx, xtol);
        if v >= fs[k] {
            Some((t, v))
        } else {
            Some((ts[k], fs[k]))
        }
    }
}

impl DenseWatch for StepCurve<'_> {
    fn count(&self) -> usize {
        self.watches().len()
    }

    fn values(&self, t: f64, out: &mut [f64]) {
        let c = self.point(t);
        for (o, &w) in out.iter_mut().zip(self.watches()) {
            *o = self.watched(w, &c);
        }
    }

    fn value(&self, i: usize, t: f64) -> f64 {
        self.watched(self.watches()[i], &self.point(t))
    }

    fn rate(&self, i: usize, t: f64) -> Option<f64> {
        match self.watches()[i] {
            Watch::Gap => Some(self.gap_rate(t)),
            Watch::Penetration => Some(-self.gap_rate(t)),
            _ => None,
        }
    }
}
