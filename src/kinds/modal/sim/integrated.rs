//! Integrated phases: while a stop whose law's phase is nonlinear (Hertz)
//! is pressed or penetrated, the modal equations are stepped by force
//! collocation ([`crate::solve::collocation`]) instead of propagated in
//! closed form: every engaged stop's force is a polynomial over a step,
//! every mode exact under it, and only the nodal forces are solved for.
//!
//! The stepper starts at the phase's anchor with a step size that depends
//! only on the anchor, and steps on its own grid: communication times
//! never shorten a step, so the trajectory does not depend on them, and a
//! restored state rebuilds the same steps from its anchor (the state needs
//! no integrator history). Each accepted step's dense output (the exact
//! motion under the step's force polynomials) goes to the switch locator
//! ([`crate::solve::switch`]: samples, interior minima of the gaps and
//! penetrations, regula falsi to an ulp), and the state at a switch is
//! recomputed by collocation steps of its own from the step's start (or
//! the one before's),
//! shrinking toward it (the method's full order at step ends, where the
//! dense output has stage order; a separation ends the force in a `p^1.5`
//! corner); Newton on that state then carries the switch past its zero.

use nalgebra::DVector;

use super::nonlinear::{dot, NonlinearContact, NonlinearPhase};
use super::{Channel, SimError, Simulation};
use crate::contact::{Contact, Watch};
use crate::solve::collocation::{CollocationOptions, ForceCollocation, PointContact};
use crate::solve::switch::{first_switch, grid, DenseWatch, Located};
use crate::solve::elementary::unit;
use crate::solve::{Functional, Jet, ModalForcing, ModalState, Oscillator, C64, REANCHOR_AFTER};

/// The collocation tolerance from which a switch's state is made from
/// the start of the step before the one it lies in, where that step
/// ended close to it ([`IntegratedSegment::origin_before`]). HertzStop at
/// 20 modes, error of the gap with and without: 1.4e-7 and 5.2e-7 at
/// 1e-7, 2.8e-9 and 1.8e-8 at 2.2e-9, 3.4e-11 and 7.1e-10 at 1e-12.
/// Looser, the step's start: at 1e-4 and 1e-6 the error is no smaller
/// from the step before (2.2e-5 and 4.2e-7 against 1.5e-5 and 2.9e-7),
/// and at 1e-3 a grazing dip of the dense output (penetration 4e-10 m)
/// became a separation and a re-contact.
const FROM_STEP_BEFORE_BELOW: f64 = 3e-7;

/// A located zero refined on the full-order motion
/// ([`IntegratedSegment::refine_zero`]).
struct Refined {
    te: f64,
    at: DVector<f64>,
    /// The motion does not reach the zero in the step.
    spurious: bool,
    /// Above zero and rising where the steps ended: the dense output's dip.
    passed: bool,
}

enum Refinement {
    Done(Refined),
    /// Stepping on past the zero went beyond the search's end.
    PastEnd,
}

/// How one channel is evaluated in an integrated phase.
#[derive(Clone, Debug)]
pub(super) enum Evaluator {
    /// An engaged stop's watch, on contact `i` of the phase.
    Nonlinear { contact: usize, watch: Watch },
    /// A function affine in the modal state (an open stop's gap), and the
    /// rounding of its terms when it leaves zero at the anchor (else 0):
    /// a stop released from a hold leaves as `t^3`, inside the rounding of
    /// the integrated state for a while, so the function counts as that
    /// much larger until it is clear of it (a closing one then crosses
    /// zero that much later, a rounding-sized shift).
    Affine(Functional, f64),
}

/// The integrated segment: the phase's forces, the stepper, and the last
/// accepted step.
#[derive(Clone, Debug)]
pub(super) struct IntegratedSegment {
    pub phase: NonlinearPhase,
    pub solver: ForceCollocation,
    pub evaluators: Vec<Evaluator>,
    /// The last accepted step `[t0, t1]` and the state at its start.
    pub step: Option<(f64, f64, DVector<f64>)>,
    /// The start of the step before it and the state there (a switch
    /// close after that step's end is made from there:
    /// [`IntegratedSegment::origin_before`]).
    pub previous: Option<(f64, DVector<f64>)>,
    /// The state at a time inside the last step computed by a step of its
    /// own from the step's start (full order, where the dense output has
    /// stage order): what the outputs read.
    pub exact: Option<(f64, DVector<f64>)>,
    pub anchor_time: f64,
    pub anchor: DVector<f64>,
    /// Steps accepted since the anchor (see [`REANCHOR_AFTER`]).
    pub steps: u64,
    /// The fastest mode's angular frequency.
    fastest: f64,
    /// Room for one integrated state (the switch locator's samples, the
    /// states and totals the outputs read).
    buffer: std::cell::RefCell<DVector<f64>>,
    /// Per evaluator, the watched direction it reads inside a step
    /// ([`ForceCollocation::watched_coordinates`]; empty when one of them
    /// needs the whole state: a held stop's reaction), and room for those
    /// coordinates.
    direction_of: Vec<usize>,
    coordinates: std::cell::RefCell<Vec<(f64, f64)>>,
    /// What the acceleration depends on besides the state: a held stop's
    /// reaction, a force's rate. Shared with the phase before where its
    /// dynamics and contact directions are these.
    pub equations: std::sync::Arc<PhaseEquations>,
}

/// The modal loads and coefficients the acceleration is formed from (a
/// held stop's reaction: [`NonlinearPhase::reactions`]; a force's rate:
/// [`NonlinearPhase::acceleration`]).
#[derive(Clone, Debug)]
pub(super) struct PhaseEquations {
    pub forcing: ModalForcing,
    /// `omega_j^2` and `2 a_j`.
    pub stiffness: Vec<f64>,
    pub damping: Vec<f64>,
    /// Per contact, its direction's share of each term of `q''`
    /// ([`Self::penetration_acceleration`]).
    along: Vec<AlongContact>,
}

/// One contact's direction `d = side w` applied to the equations of
/// motion: `d . q'' = d . f(t) - (d o omega^2) . q - (d o 2a) . q' - sum_c
/// (d . d_c) F_c`, each factor formed once per phase.
#[derive(Clone, Debug)]
struct AlongContact {
    constant: f64,
    harmonics: Vec<C64>,
    stiffness: Vec<f64>,
    damping: Vec<f64>,
    couplings: Vec<f64>,
}

impl PhaseEquations {
    pub fn new(forcing: ModalForcing, oscillators: &[Oscillator], phase: &NonlinearPhase) -> PhaseEquations {
        let stiffness: Vec<f64> = oscillators.iter().map(|o| o.omega * o.omega).collect();
        let damping: Vec<f64> = oscillators.iter().map(|o| 2.0 * o.a).collect();
        let direction = |c: &NonlinearContact| &c.geometry.w * c.geometry.side;
        let along = phase
            .contacts
            .iter()
            .map(|c| {
                let d = direction(c);
                AlongContact {
                    constant: d.dot(&forcing.constant),
                    harmonics: forcing.harmonics.iter().map(|h| d.iter().zip(h.amplitude.iter()).map(|(dj, b)| b * *dj).fold(C64::new(0.0, 0.0), |a, b| a + b)).collect(),
                    stiffness: d.iter().zip(&stiffness).map(|(dj, k)| dj * k).collect(),
                    damping: d.iter().zip(&damping).map(|(dj, c)| dj * c).collect(),
                    couplings: phase.contacts.iter().map(|other| d.dot(&direction(other))).collect(),
                }
            })
            .collect();
        PhaseEquations { forcing, stiffness, damping, along }
    }

    /// Whether equations formed for `formed_for` serve `phase` too: its
    /// contacts lie along the same directions (under the same dynamics).
    fn serve(formed_for: &NonlinearPhase, phase: &NonlinearPhase) -> bool {
        formed_for.contacts.len() == phase.contacts.len() && formed_for.contacts.iter().zip(&phase.contacts).all(|(a, b)| a.geometry.w == b.geometry.w && a.geometry.side == b.geometry.side)
    }

    /// Every contact's push at `t` in `y` (zero but for the held ones).
    pub fn pushes(&self, phase: &NonlinearPhase, t: f64, y: &DVector<f64>) -> Vec<f64> {
        let mut f = DVector::zeros(phase.n);
        self.forcing.derivative(t, 0, &mut f);
        phase.reactions(y.as_slice(), &f, &self.stiffness, &self.damping)
    }

    /// [`Self::pushes`] with the contacts entering their surface pushing
    /// ([`NonlinearPhase::reactions_entering`]).
    pub fn pushes_entering(&self, phase: &NonlinearPhase, t: f64, y: &DVector<f64>) -> Vec<f64> {
        let mut f = DVector::zeros(phase.n);
        self.forcing.derivative(t, 0, &mut f);
        phase.reactions_entering(y.as_slice(), &f, &self.stiffness, &self.damping)
    }

    /// `q''` at `t` in `y`.
    pub fn acceleration(&self, phase: &NonlinearPhase, t: f64, y: &DVector<f64>) -> DVector<f64> {
        let mut f = DVector::zeros(phase.n);
        self.forcing.derivative(t, 0, &mut f);
        phase.acceleration(y.as_slice(), &f, &self.stiffness, &self.damping)
    }

    /// `p''` of contact `i` at `t` in `y` (`own`: its penetration and
    /// rate there): through its direction's factors ([`AlongContact`])
    /// where no contact is held, `O(N)` with no modal acceleration formed
    /// (a force's rate at every step's ends); else from
    /// [`Self::acceleration`], which solves for the holds.
    pub fn penetration_acceleration(&self, phase: &NonlinearPhase, i: usize, own: (f64, f64), t: f64, y: &DVector<f64>) -> f64 {
        if phase.contacts.iter().any(|c| c.held) {
            let g = &phase.contacts[i].geometry;
            return g.side * g.w.dot(&self.acceleration(phase, t, y));
        }
        let along = &self.along[i];
        let n = phase.n;
        let (q, qd) = y.as_slice()[..2 * n].split_at(n);
        let mut acceleration = along.constant;
        for (h, b) in self.forcing.harmonics.iter().zip(&along.harmonics) {
            acceleration += (b * unit(h.omega * t)).re;
        }
        acceleration -= dot(&along.stiffness, q) + dot(&along.damping, qd);
        for (c, coupling) in along.couplings.iter().enumerate() {
            let (p, pd) = if c == i { own } else { phase.penetration(c, y.as_slice()) };
            acceleration -= coupling * phase.contacts[c].force(p, pd).0;
        }
        acceleration
    }
}

impl IntegratedSegment {
    /// The integrated state `[q; q'; J; E]` at `t` in the last step (the
    /// anchor before the first).
    pub fn y_at(&self, t: f64, out: &mut DVector<f64>) {
        if let Some((te, y)) = &self.exact {
            if *te == t {
                out.copy_from(y);
                return;
            }
        }
        self.dense_y_at(t, out);
    }

    /// The dense output alone (what the switch locator reads: a search
    /// repeated after a switch's full-order state was kept must see the
    /// same function at that very time, or it brackets another zero).
    fn dense_y_at(&self, t: f64, out: &mut DVector<f64>) {
        match &self.step {
            Some((t0, _, y0)) if t == *t0 => out.copy_from(y0),
            Some(_) => {
                if self.solver.dense(t, out).is_none() {
                    // Outside the last step (never asked): its nearest end.
                    out.copy_from(self.solver.y());
                }
            }
            None => out.copy_from(&self.anchor),
        }
    }

    pub fn state_at(&self, t: f64, out: &mut ModalState) {
        let n = self.phase.n;
        let mut y = self.buffer.borrow_mut();
        self.y_at(t, &mut y);
        out.q.copy_from(&y.rows(0, n));
        out.qd.copy_from(&y.rows(n, n));
    }

    /// The impulse and dissipated energy of the phase's contact `i` from
    /// the anchor to `t`.
    pub fn totals_at(&self, i: usize, t: f64) -> (f64, f64) {
        let mut y = self.buffer.borrow_mut();
        self.y_at(t, &mut y);
        let (n, nc) = (self.phase.n, self.phase.contacts.len());
        (y[2 * n + i], y[2 * n + nc + i])
    }

    fn evaluate(&self, e: &Evaluator, t: f64, y: &DVector<f64>) -> f64 {
        match e {
            Evaluator::Nonlinear { contact, watch: Watch::Reaction } => {
                // A held stop's push, -side lambda.
                self.equations.pushes(&self.phase, t, y)[*contact]
            }
            Evaluator::Nonlinear { contact, watch } => {
                let (p, pd) = self.phase.penetration(*contact, y.as_slice());
                let c = &self.phase.contacts[*contact];
                c.law.watched(*watch, p, pd, c.onset_speed).0
            }
            Evaluator::Affine(h, floor) => {
                let n = self.phase.n;
                h.offset + h.q.iter().zip(&y.as_slice()[..n]).map(|(a, b)| a * b).sum::<f64>() + floor
            }
        }
    }
}

/// Where the last piece toward a switch's first estimate started
/// ([`IntegratedSegment::switch_state`]).
struct Approach {
    t: f64,
    y: DVector<f64>,
    aimed: f64,
}

impl IntegratedSegment {
    /// A held stop's push at `t` in `state`, with the size of the terms it
    /// is formed from (for the level a decoder takes as zero); `None` when
    /// the stop is not held in this phase.
    pub fn held_push(&self, stop: usize, t: f64, state: &ModalState) -> Option<(f64, f64)> {
        self.held_push_with(stop, t, state, false)
    }

    /// [`Self::held_push`] as the phase begins, the contacts entering
    /// their surface pushing ([`NonlinearPhase::reactions_entering`]).
    pub fn held_push_entering(&self, stop: usize, t: f64, state: &ModalState) -> Option<(f64, f64)> {
        self.held_push_with(stop, t, state, true)
    }

    fn held_push_with(&self, stop: usize, t: f64, state: &ModalState, entering: bool) -> Option<(f64, f64)> {
        let model = &self.equations;
        let i = self.phase.contacts.iter().position(|c| c.stop == stop && c.held)?;
        let n = self.phase.n;
        let mut y = DVector::zeros(self.phase.dim());
        y.rows_mut(0, n).copy_from(&state.q);
        y.rows_mut(n, n).copy_from(&state.qd);
        let push = if entering { model.pushes_entering(&self.phase, t, &y)[i] } else { model.pushes(&self.phase, t, &y)[i] };
        let mut f = DVector::zeros(n);
        model.forcing.derivative(t, 0, &mut f);
        let w = &self.phase.contacts[i].geometry.w;
        let terms: f64 = (0..n).map(|j| w[j].abs() * (f[j].abs() + model.stiffness[j] * state.q[j].abs() + model.damping[j] * state.qd[j].abs())).sum();
        let others: f64 = (0..self.phase.contacts.len())
            .filter(|&k| !self.phase.contacts[k].held)
            .map(|k| {
                let (p, pd) = self.phase.penetration(k, y.as_slice());
                self.phase.contacts[k].force(p, pd).0 * self.phase.contacts[k].geometry.w.iter().zip(w.iter()).map(|(a, b)| (a * b).abs()).sum::<f64>()
            })
            .sum();
        Some((push, (terms + others) / w.dot(w)))
    }

    /// The state at a switch at `te` in the step `[t0, t1]`: a step of its
    /// own (the end state at `t1`), by pieces shrinking toward `te` from
    /// `origin` (the step's start, or the one before's:
    /// [`Self::origin_before`]; [`ForceCollocation::approach`]).
    /// `approach`: where the last piece toward an earlier estimate of the
    /// switch started, and that estimate, kept by the first call; a later
    /// estimate past that start and no further beyond the earlier
    /// estimate than the last piece's length lands from there (the pieces
    /// before are states of the motion, whichever estimate they aimed at;
    /// the last piece stays within twice its length).
    fn switch_state(&self, origin: (f64, &DVector<f64>), t0: f64, t1: f64, te: f64, approach: &mut Option<Approach>) -> DVector<f64> {
        let mut at = DVector::zeros(self.phase.dim());
        if te == t1 || te <= t0 {
            self.y_at(te, &mut at);
            return at;
        }
        let start = match approach.as_ref().filter(|a| a.t < te && te - a.aimed <= a.aimed - a.t) {
            Some(a) => Ok((a.t, a.y.clone())),
            None => self.solver.approach(&self.phase, origin.0, origin.1, te),
        };
        let landed = start.and_then(|(ta, ya)| {
            if approach.is_none() {
                *approach = Some(Approach { t: ta, y: ya.clone(), aimed: te });
            }
            self.solver.land(&self.phase, ta, ya, te)
        });
        match landed {
            Ok(y) => y,
            Err(_) => {
                self.y_at(te, &mut at);
                at
            }
        }
    }

    /// Where a switch's state at `te` in the last step is made from at
    /// tight tolerances: the start of the step before, where `te` lies
    /// closer to that step's end than a third of its length (else `None`). A step ending
    /// that close to a separation's `t^a` corner collocated a force whose
    /// Taylor radius is a small part of the step, with an error no defect
    /// estimate sees (HertzStop at 20 modes, collocation tolerance 1e-8: a
    /// 15 us step ending 0.9 us before a separation left the tip's
    /// velocity 1.2e-7 m/s off, 40 times the error before it); the pieces
    /// from the step before take it again toward the corner, each at most
    /// three times as long as its distance to it, as
    /// [`ForceCollocation::approach`] grades them.
    fn origin_before(&self, te: f64) -> Option<(f64, &DVector<f64>)> {
        let (t0, _, _) = self.step.as_ref()?;
        match &self.previous {
            Some((tp, yp)) if 3.0 * (te - t0) < t0 - tp => Some((*tp, yp)),
            _ => None,
        }
    }

    /// The located zero refined on the full-order motion: the state at
    /// the located time (a step of its own toward it from `origin`), then
    /// Newton on that state, each iterate a shift of the last (a step
    /// from `origin` where the shift is too long). The zero is the dense
    /// output's (stage order): Newton moves it to the full-order zero
    /// (within the step, after the bracket's start); that state may then
    /// lie a rounding-sized distance short of it, and Newton steps on from
    /// it carry the switch past the zero, as the locator promises.
    fn refine_zero(&self, located: &Located, origin: (f64, &DVector<f64>), t1: f64, t_end: f64, oscillators: &[Oscillator]) -> Refinement {
        let t0 = self.step.as_ref().expect("a step").0;
        let mut te = located.time;
        let mut approach = None;
        let mut at = self.switch_state(origin, t0, t1, te, &mut approach);
        let mut spurious = false;
        // A geometric function below zero by its rounding from the
        // bracket's start on, and rising: a contact that began a
        // rounding-sized distance short of its surface (where the free
        // flight placed its gap's zero), the penetration below zero as the
        // point arrives. No zero here to refine or to switch at (the chord
        // through rounding-sized values falls, the motion does not); the
        // search moves on past the sample. (Below zero by more, the zero is
        // the law's to decide: a contact whose separation was placed late
        // by a loose tolerance, the point back on its way in, switches
        // there.)
        let rising = |te: f64, at: &DVector<f64>, c: usize| self.rate_in(c, te, at).is_some_and(|r| r > 0.0);
        let mut passed = located
            .at_zero
            .first()
            .is_some_and(|&(c, _)| self.is_geometric(c) && rising(te, &at, c) && self.below_by_rounding(c, located.from, oscillators.iter().map(|o| o.omega)));
        if let Some(&(c, slope)) = located.at_zero.first().filter(|_| !passed) {
            for _ in 0..4 {
                let g = self.evaluate(&self.evaluators[c], te, &at);
                let rate = self.rate_in(c, te, &at).filter(|r| *r < 0.0).unwrap_or(slope);
                let next = te - g / rate;
                if !(next > located.from.max(t0) && next < t1) || (next - te).abs() <= 4.0 * f64::EPSILON * te.abs() {
                    break;
                }
                // A state past a push's end inside the surface, or past a
                // push's resumption there, came from a collocation step
                // across the force's corner, where the dissipated power
                // jumps (between zero and `-F_spring p'`): its energy
                // integral carries that step's first-order error (6.7e-11
                // of a 2.2e-11 s overshoot at 6 W at an end; 5.9e-6 of the
                // energy at a resumption at tolerance 1e-8), which a shift
                // from it keeps. Such a state lands afresh from the origin.
                let across_corner = g < 0.0 && self.is_force(c);
                at = match self.solver.shift(&self.phase, te, &at, next).filter(|_| !across_corner) {
                    Some(y) => y,
                    None => self.switch_state(origin, t0, t1, next, &mut approach),
                };
                te = next;
            }
            for _ in 0..6 {
                let g = self.evaluate(&self.evaluators[c], te, &at);
                if g <= 0.0 {
                    break;
                }
                let rate = self.rate_in(c, te, &at).filter(|r| *r < 0.0).unwrap_or(slope);
                // Within the step: its samples and steps cover no further
                // (a slope near zero would send it far past them).
                let next = (te - g / rate).max(te + 4.0 * f64::EPSILON * te.abs()).min(t1);
                if next <= te {
                    break;
                }
                if next > t_end {
                    return Refinement::PastEnd;
                }
                // A shift or a step on from the switch state.
                let on = self.solver.shift(&self.phase, te, &at, next).map(Ok);
                at = match on.unwrap_or_else(|| self.solver.single_step(&self.phase, te, &at, next, false)) {
                    Ok(y) => y,
                    Err(_) => self.switch_state(origin, t0, t1, next, &mut approach),
                };
                te = next;
            }
            // Carried to the step's end with the function still positive:
            // the full-order motion does not reach the zero the dense output
            // (of stage order: at loose tolerances off by more than the
            // function's size) placed in this step.
            let g = self.evaluate(&self.evaluators[c], te, &at);
            spurious = te == t1 && g > 0.0;
            // Above zero and rising where the steps ended: the dense
            // output's dip is its error, not the motion's. So is a
            // geometric function's dip below zero no deeper than the
            // error the tolerance allows it, where the motion rises from
            // it: a point pressed on from rest into a stop at zero gap
            // (p = c t^3) lies closer to the surface than that error for
            // a while, and a separation there (p -1e-18 m, rising at
            // 1e-13 m/s) re-touched at a speed of 7e-12 m/s, a
            // Hunt-Crossley damping's onset speed that froze the contact.
            passed = (g > 0.0 && rising(te, &at, c)) || self.unresolved_dip(c, te, &at, g);
        }
        Refinement::Done(Refined { te, at, spurious, passed })
    }

    /// Whether geometric function `i` at its zero `te` (state `at`,
    /// value `g <= 0` there) dips below zero by no more than the error the
    /// tolerance allows it (each mode's `tol q_scale` through its
    /// direction), and comes back up: rising, or level within its rate's
    /// error allowance (`tol v_scale`) and curving up (the acceleration
    /// the phase's forces leave). The motion does not resolve such a dip.
    /// A point pressed on from rest into a stop at zero gap (p = c t^3)
    /// lies closer to the surface than that error for a while: at
    /// tolerance 1e-13 a separation at p = -1e-18 m, rising at 1e-13 m/s,
    /// touched again at 7e-12 m/s (an onset speed that froze a
    /// Hunt-Crossley contact); at 1e-14, where the force polynomial's
    /// value at the touch pulled the point out as t^2 before the load took
    /// over, the contact ended and began every 1.6e-151 s until the work
    /// cap.
    fn unresolved_dip(&self, i: usize, te: f64, at: &DVector<f64>, g: f64) -> bool {
        if !self.is_geometric(i) {
            return false;
        }
        let (d, sign) = match &self.evaluators[i] {
            Evaluator::Affine(h, _) => (h.q.as_slice(), 1.0),
            Evaluator::Nonlinear { contact, watch } => {
                let geometry = &self.phase.contacts[*contact].geometry;
                (geometry.w.as_slice(), if *watch == Watch::Gap { -geometry.side } else { geometry.side })
            }
        };
        let options = self.solver.options();
        let reach: f64 = d.iter().map(|x| x.abs()).sum();
        if !(g <= 0.0 && -g <= options.tol * options.q_scale * reach) {
            return false;
        }
        let n = self.phase.n;
        let rate = sign * d.iter().zip(&at.as_slice()[n..2 * n]).map(|(x, v)| x * v).sum::<f64>();
        if rate > 0.0 {
            return true;
        }
        let curvature = sign * d.iter().zip(self.equations.acceleration(&self.phase, te, at).iter()).map(|(x, a)| x * a).sum::<f64>();
        -rate <= options.tol * options.v_scale * reach && curvature > 0.0
    }

    /// Whether geometric function `i` lies below zero at `t` by no more
    /// than the rounding of its terms, each mode's at its amplitude
    /// (`omegas`: the modes' frequencies): the free flight reaches its
    /// states as sums of oscillations that large.
    fn below_by_rounding(&self, i: usize, t: f64, omegas: impl Iterator<Item = f64>) -> bool {
        let value = self.value(i, t);
        let (d, offset) = match &self.evaluators[i] {
            Evaluator::Affine(h, _) => (h.q.as_slice(), h.offset),
            Evaluator::Nonlinear { contact, .. } => {
                let g = &self.phase.contacts[*contact].geometry;
                (g.w.as_slice(), g.gap)
            }
        };
        let mut y = self.buffer.borrow_mut();
        self.dense_y_at(t, &mut y);
        let n = self.phase.n;
        let size = offset.abs() + omegas.enumerate().map(|(j, omega)| d[j].abs() * (y[j].abs() + y[n + j].abs() / omega)).sum::<f64>();
        value < 0.0 && value >= -64.0 * f64::EPSILON * size
    }

    /// The rate of watched function `i` at `t` in the integrated state
    /// `y`: for the geometric ones and the forces ([`Self::force_rate`];
    /// not a held stop's reaction).
    fn rate_in(&self, i: usize, t: f64, y: &DVector<f64>) -> Option<f64> {
        let n = self.phase.n;
        let rates = &y.as_slice()[n..2 * n];
        let dot = |a: &[f64], sign: f64| sign * a.iter().zip(rates).map(|(x, d)| x * d).sum::<f64>();
        match &self.evaluators[i] {
            Evaluator::Affine(h, _) => Some(dot(h.q.as_slice(), 1.0)),
            Evaluator::Nonlinear { contact, watch } => {
                let g = &self.phase.contacts[*contact].geometry;
                match watch {
                    Watch::Penetration => Some(dot(g.w.as_slice(), g.side)),
                    Watch::Gap => Some(dot(g.w.as_slice(), -g.side)),
                    Watch::NegatedForce | Watch::Force => Some(self.force_rate(*contact, *watch, t, y)),
                    Watch::Reaction => None,
                }
            }
        }
    }

    /// The rate of a force watch (`watch`: the law force `F(p, p')` or
    /// its negation) of `contact` along the motion, `F_p p' + F_p' p''`
    /// with `p''` from the equations of motion at `t` in `y` (a zero's
    /// refinement; the switch locator's samples take `p''` from the
    /// watched coordinates, [`Self::watched_read`]). With it the search
    /// between samples sees a push that resumes and ends again inside one
    /// sample interval (with no rate a push as short as 7 ms went unseen
    /// in 40 ms samples: its force acted, clamped by the law, but the
    /// phase was never pressed, and the collocation stepped over the
    /// force's corners), and a push's end that the force dips to and
    /// leaves within one.
    fn force_rate(&self, contact: usize, watch: Watch, t: f64, y: &DVector<f64>) -> f64 {
        let (p, pd) = self.phase.penetration(contact, y.as_slice());
        let c = &self.phase.contacts[contact];
        let (_, dp, dpd) = c.law.watched(watch, p, pd, c.onset_speed);
        self.force_rate_at(contact, (p, pd), (dp, dpd), t, y)
    }

    /// [`Self::force_rate`] given the contact's penetration and rate and
    /// the watch's derivatives by them.
    fn force_rate_at(&self, contact: usize, (p, pd): (f64, f64), (dp, dpd): (f64, f64), t: f64, y: &DVector<f64>) -> f64 {
        if dpd == 0.0 {
            return dp * pd;
        }
        dp * pd + dpd * self.equations.penetration_acceleration(&self.phase, contact, (p, pd), t, y)
    }

    /// Whether evaluator `i` watches a stop's force (its zero: a push's
    /// end or resumption inside the surface).
    fn is_force(&self, i: usize) -> bool {
        matches!(self.evaluators[i], Evaluator::Nonlinear { watch: Watch::Force | Watch::NegatedForce, .. })
    }

    /// Whether evaluator `i` is a geometric function (a gap or a
    /// penetration).
    fn is_geometric(&self, i: usize) -> bool {
        matches!(self.evaluators[i], Evaluator::Affine(..) | Evaluator::Nonlinear { watch: Watch::Gap | Watch::Penetration, .. })
    }
}

/// The watched functions along the last accepted step, for the switch
/// locator: gaps and penetrations give their rate (`w . q'` from the
/// dense output's derivative).
impl DenseWatch for IntegratedSegment {
    fn count(&self) -> usize {
        self.evaluators.len()
    }

    fn values(&self, t: f64, out: &mut [f64]) {
        if let Some(coordinates) = self.watched_at(t) {
            for (i, o) in out.iter_mut().enumerate() {
                *o = self.watched_value(i, &coordinates);
            }
            return;
        }
        let mut y = self.buffer.borrow_mut();
        self.dense_y_at(t, &mut y);
        for (o, e) in out.iter_mut().zip(&self.evaluators) {
            *o = self.evaluate(e, t, &y);
        }
    }

    fn value(&self, i: usize, t: f64) -> f64 {
        if let Some(coordinates) = self.watched_at(t) {
            return self.watched_value(i, &coordinates);
        }
        let mut y = self.buffer.borrow_mut();
        self.dense_y_at(t, &mut y);
        self.evaluate(&self.evaluators[i], t, &y)
    }

    fn rate(&self, i: usize, t: f64) -> Option<f64> {
        if let Some(coordinates) = self.watched_at(t) {
            return self.watched_read(i, t, &coordinates).1;
        }
        let mut y = self.buffer.borrow_mut();
        self.dense_y_at(t, &mut y);
        self.dense_read(i, t, &y).1
    }

    fn values_and_rates(&self, t: f64, values: &mut [f64], rates: &mut [Option<f64>]) {
        if let Some(coordinates) = self.watched_at(t) {
            for (i, (value, rate)) in values.iter_mut().zip(rates.iter_mut()).enumerate() {
                (*value, *rate) = self.watched_read(i, t, &coordinates);
            }
            return;
        }
        let mut y = self.buffer.borrow_mut();
        self.dense_y_at(t, &mut y);
        for (i, (value, rate)) in values.iter_mut().zip(rates.iter_mut()).enumerate() {
            (*value, *rate) = self.dense_read(i, t, &y);
        }
    }
}

impl IntegratedSegment {
    /// The watched coordinates at `t` strictly inside the last step (at
    /// its ends the locator reads the exact states), when every evaluator
    /// reads one.
    fn watched_at(&self, t: f64) -> Option<std::cell::Ref<'_, Vec<(f64, f64)>>> {
        if self.direction_of.is_empty() {
            return None;
        }
        let found = self.solver.watched_coordinates(t, &mut self.coordinates.borrow_mut());
        found.then(|| self.coordinates.borrow())
    }

    /// Evaluator `i` from its direction's coordinate and rate (the
    /// formulas of [`Self::evaluate`] and [`Self::rate_in`]).
    fn watched_value(&self, i: usize, coordinates: &[(f64, f64)]) -> f64 {
        let (x, v) = coordinates[self.direction_of[i]];
        match &self.evaluators[i] {
            Evaluator::Affine(h, floor) => h.offset + x + floor,
            Evaluator::Nonlinear { contact, watch } => {
                let c = &self.phase.contacts[*contact];
                c.law.watched(*watch, x - c.geometry.gap, v, c.onset_speed).0
            }
        }
    }

    /// Whether a force watch whose value is `value`, with `at_p` and
    /// `at_pd` its derivatives by `p` and `p'` times `p` and `p'` (the size
    /// of its terms), may dip to zero before the switch locator's next
    /// sample, so that the locator needs its rate (an `O(N)` acceleration)
    /// there: where the last step is longer than a quarter period of the
    /// fastest mode, whose motion can swing the force anywhere between
    /// samples, or where the force lies within half its terms' size of
    /// zero. Farther, and in steps that short, a dip within one sample
    /// interval (an eighth of a step, an arc of at most 11 degrees of the
    /// fastest mode) needs the force to swing by half its size and back.
    /// A pressed Hertz stop with Lankarani-Nikravesh damping at `e = 0.8`
    /// is never that close: its push would end at `p' = -3.7 v0`.
    fn force_may_dip(&self, value: f64, at_p: f64, at_pd: f64) -> bool {
        let long_step = self.step.as_ref().map_or(true, |(t0, t1, _)| (t1 - t0) * self.fastest > std::f64::consts::FRAC_PI_2);
        long_step || value <= 0.5 * (value.abs() + at_p.abs() + at_pd.abs())
    }

    /// Evaluator `i`'s value and rate at `t` from its direction's
    /// coordinate and rate (the formulas of [`Self::dense_read`]; a
    /// force's `p''` the dense output's,
    /// [`ForceCollocation::watched_acceleration`], in place of the
    /// equations of motion's: they differ by the collocation's defect).
    fn watched_read(&self, i: usize, t: f64, coordinates: &[(f64, f64)]) -> (f64, Option<f64>) {
        let (x, v) = coordinates[self.direction_of[i]];
        match &self.evaluators[i] {
            Evaluator::Affine(h, floor) => (h.offset + x + floor, Some(v)),
            Evaluator::Nonlinear { contact, watch } => {
                let c = &self.phase.contacts[*contact];
                let p = x - c.geometry.gap;
                let (value, dp, dpd) = c.law.watched(*watch, p, v, c.onset_speed);
                let rate = match watch {
                    Watch::Penetration => Some(v),
                    Watch::Gap => Some(-v),
                    Watch::Force | Watch::NegatedForce if self.force_may_dip(value, dp * p, dpd * v) => {
                        let acceleration = if dpd == 0.0 { Some(0.0) } else { self.solver.watched_acceleration(t, self.direction_of[i]) };
                        acceleration.map(|a| dp * v + dpd * a)
                    }
                    _ => None,
                };
                (value, rate)
            }
        }
    }

    /// Evaluator `i`'s value and the rate the switch locator reads at `t`
    /// in `y` (a step's ends): [`Self::evaluate`] and [`Self::rate_in`],
    /// but a force's rate only where it may dip to zero
    /// ([`Self::force_may_dip`]).
    fn dense_read(&self, i: usize, t: f64, y: &DVector<f64>) -> (f64, Option<f64>) {
        if let Evaluator::Nonlinear { contact, watch: watch @ (Watch::Force | Watch::NegatedForce) } = self.evaluators[i] {
            let (p, pd) = self.phase.penetration(contact, y.as_slice());
            let c = &self.phase.contacts[contact];
            let (value, dp, dpd) = c.law.watched(watch, p, pd, c.onset_speed);
            let rate = self.force_may_dip(value, dp * p, dpd * pd).then(|| self.force_rate_at(contact, (p, pd), (dp, dpd), t, y));
            return (value, rate);
        }
        (self.evaluate(&self.evaluators[i], t, y), self.rate_in(i, t, y))
    }

    /// Computes and keeps the state at `t` inside the last step to the
    /// method's full order (see [`Self::exact`]).
    pub fn settle_at(&mut self, t: f64) {
        let Some((t0, t1, y0)) = &self.step else { return };
        if t <= *t0 || t >= *t1 || t > self.solver.t() {
            return;
        }
        if let Ok(y) = self.solver.single_step(&self.phase, *t0, y0, t, self.solver.near_corner(t)) {
            self.exact = Some((t, y));
        }
    }
}

impl Simulation {
    /// The integrated segment of a phase with a nonlinear stop engaged:
    /// every engaged stop of a law with a force is one of its contacts.
    pub(super) fn integrated_segment(&mut self) -> Result<IntegratedSegment, SimError> {
        let n = self.model.n_modes();
        let mut contacts = Vec::new();
        let mut index = vec![usize::MAX; self.model.stops.len()];
        for (i, (m, s)) in self.model.stops.iter().zip(&self.state.stops).enumerate() {
            // Engaged compliant stops push by their law; held rigid stops
            // by the reaction that keeps them on their surface.
            if s.contact != Contact::Open {
                index[i] = contacts.len();
                let held = m.law.rigid();
                contacts.push(NonlinearContact { stop: i, law: m.law.clone(), geometry: self.geometries[i].clone(), contact: s.contact, onset_speed: s.onset_speed, held });
            }
        }
        let evaluators: Vec<Evaluator> = self
            .channels
            .iter()
            .map(|ch: &Channel| match self.state.stops[ch.stop].contact {
                Contact::Open => {
                    let h = self.gap_functionals[ch.stop].clone();
                    let floor = if self.state.stops[ch.stop].anchor_departing[ch.slot] {
                        let q = &self.state.anchor.q;
                        64.0 * f64::EPSILON * (h.offset.abs() + h.q.iter().zip(q.iter()).map(|(a, b)| (a * b).abs()).sum::<f64>())
                    } else {
                        0.0
                    };
                    Evaluator::Affine(h, floor)
                }
                _ => Evaluator::Nonlinear { contact: index[ch.stop], watch: ch.watch },
            })
            .collect();
        // The contact's time scale: a quarter of the fastest linearised
        // contact period at the larger of the current and a
        // millionth-of-the-gap penetration caps the step (the force
        // polynomial must resolve the pulse).
        let mut quarter = f64::INFINITY;
        let slowest = self.model.oscillators.iter().map(|o| o.omega).fold(f64::INFINITY, f64::min);
        let (mut scale_q, mut scale_v) = (0.0f64, 0.0f64);
        for c in contacts.iter().filter(|c| !c.held) {
            let g = &c.geometry;
            let w2 = g.w.dot(&g.w);
            let w_max = g.w.amax().max(f64::MIN_POSITIVE);
            // Effective mass of the point, 1 / |w|^2; the deepest
            // penetration of a mass that size arriving at the onset speed
            // (the law's depth storing its kinetic energy) sets the scale
            // of the contact.
            let v0 = c.onset_speed.max(g.penetration_rate(&self.state.anchor.qd).abs());
            // No deeper than the motion reaches (a vanishing stiffness
            // would give an infinite depth).
            let reach = g.gap.abs() + g.w.dot(&self.state.anchor.q).abs() + v0 / slowest;
            let depth = c.law.depth(v0, w2).min(reach);
            let p = g.penetration(&self.state.anchor.q).max(depth).max(1e-6 * g.gap.abs());
            let k_lin = c.law.raw_force(p, 0.0, c.onset_speed).1;
            let omega_c = (k_lin * w2).sqrt();
            if omega_c > 0.0 {
                quarter = quarter.min(0.25 * std::f64::consts::TAU / omega_c);
            }
            scale_q = scale_q.max(g.gap.abs().max(depth) / w_max);
            scale_v = scale_v.max(v0 / w_max);
        }
        // A contact slower than the slowest mode (a stop of vanishing
        // stiffness) sets no time scale: its force error says nothing of the
        // modes' motion, and steps as long as its quarter period would
        // leave the gaps' samples seconds, or ages, apart. The fastest
        // mode's quarter period then bounds the steps: the switch locator
        // sees every dip of a free motion whose extrema lie more than an
        // eighth of a step apart.
        if !quarter.is_finite() || quarter > 0.25 * std::f64::consts::TAU / slowest {
            let fastest = self.model.oscillators.iter().map(|o| o.omega).fold(0.0, f64::max);
            quarter = 0.25 * std::f64::consts::TAU / fastest.max(slowest);
        }
        let phase = NonlinearPhase::new(n, contacts);
        let dim = phase.dim();
        let mut anchor = DVector::zeros(dim);
        anchor.rows_mut(0, n).copy_from(&self.state.anchor.q);
        anchor.rows_mut(n, n).copy_from(&self.state.anchor.qd);
        // The loads' steady response scales the motion too: a stop at zero
        // gap touched at rest, or at a vanishing speed, sets no scale of
        // its own (an error scale of nothing took steps of 1e-156 s).
        let (load_q, load_v) = self.dynamics.load_scale();
        let (scale_q, scale_v) = (scale_q.max(load_q), scale_v.max(load_v));
        let tol = self.model.integration_tolerance;
        let q_scale = scale_q.max(self.state.anchor.q.amax()).max(f64::MIN_POSITIVE);
        let v_scale = (q_scale * slowest).max(scale_v).max(self.state.anchor.qd.amax()).max(f64::MIN_POSITIVE);
        let points = phase.contacts.iter().map(|c| PointContact { d: &c.geometry.w * c.geometry.side, gap: c.geometry.gap }).collect();
        // An onset's force grows as t^a (the law's corner exponent; Hertz:
        // 1.5): a first step of tol^(1/(a+2)) of the contact's scale
        // carries that corner's error to the tolerance, and so does the
        // last piece of a step onto a separation.
        let corner = phase.contacts.iter().map(|c| c.law.corner_exponent()).fold(f64::INFINITY, f64::min);
        let corner_fraction = tol.powf(1.0 / (corner + 2.0));
        let h_init = quarter * corner_fraction.min(0.25);
        // Two things turn with the fastest mode whatever the contacts'
        // own time scale, and cap the steps at its quarter period:
        // - a penetrated stop's force watch carries the rate p', in which
        //   each mode's share is omega_j times its share of p: its rate
        //   (the switch locator's search between samples) turns with that
        //   mode, and a step of a quarter period puts sixteen samples in
        //   its period, where the search sees every turn (a resumed push
        //   3.5 ms long went unseen in 10 ms samples of an 8-mode beam);
        // - a held rigid stop's reaction follows the constrained motion,
        //   which a step of four periods leaves to a polynomial of the
        //   stages' degree (a weak Hertz stop beside a held rigid one: the
        //   motion 2.6e-4 of its scale off the closed-form hold at
        //   tolerance 1e-4, 1.7e-6 at 1e-8; now 1.2e-10 to 1.9e-10, the
        //   weak force's own effect).
        let mut h_max = 16.0 * quarter;
        if evaluators.iter().any(|e| matches!(e, Evaluator::Nonlinear { watch: Watch::NegatedForce, .. })) || phase.contacts.iter().any(|c| c.held) {
            let fastest = self.model.oscillators.iter().map(|o| o.omega).fold(0.0, f64::max);
            h_max = h_max.min(0.25 * std::f64::consts::TAU / fastest.max(slowest));
        }
        let options = CollocationOptions { tol, q_scale, v_scale, h_init: h_init.min(h_max), h_max, corner_fraction };
        // The previous phase's dynamics where they are these (unchanged
        // inputs): shared, not copied; its equations too where its
        // contacts lie along the same directions (some dozen vectors).
        let previous = match &self.spare {
            Some(super::Segment::Integrated(previous)) if **previous.solver.shared_dynamics() == self.dynamics => Some(previous),
            _ => None,
        };
        let dynamics = previous.map_or_else(|| std::sync::Arc::new(self.dynamics.clone()), |p| p.solver.shared_dynamics().clone());
        let equations = match previous {
            Some(p) if PhaseEquations::serve(&p.phase, &phase) => p.equations.clone(),
            _ => std::sync::Arc::new(PhaseEquations::new(self.dynamics.forcing.clone(), &self.dynamics.oscillators, &phase)),
        };
        let mut solver = ForceCollocation::new(dynamics, points, self.state.anchor_time, anchor.clone(), options);
        // The directions the switch locator reads: each engaged contact's
        // (its penetration, rate and force) and each open stop's gap.
        let mut directions: Vec<DVector<f64>> = Vec::new();
        let mut of_contact = vec![usize::MAX; phase.contacts.len()];
        let mut direction_of = Vec::with_capacity(evaluators.len());
        for e in &evaluators {
            match e {
                Evaluator::Nonlinear { watch: Watch::Reaction, .. } => {
                    direction_of.clear();
                    directions.clear();
                    break;
                }
                Evaluator::Nonlinear { contact, .. } => {
                    if of_contact[*contact] == usize::MAX {
                        of_contact[*contact] = directions.len();
                        let g = &phase.contacts[*contact].geometry;
                        directions.push(&g.w * g.side);
                    }
                    direction_of.push(of_contact[*contact]);
                }
                Evaluator::Affine(h, _) => {
                    direction_of.push(directions.len());
                    directions.push(h.q.clone());
                }
            }
        }
        solver.watch_directions(directions);
        if let Some(super::Segment::Integrated(previous)) = &mut self.spare {
            solver.adopt_kernels(&mut previous.solver);
        }
        let fastest = self.model.oscillators.iter().map(|o| o.omega).fold(0.0, f64::max);
        Ok(IntegratedSegment {
            fastest,
            buffer: DVector::zeros(dim).into(),
            direction_of,
            coordinates: Default::default(),
            phase,
            solver,
            evaluators,
            step: None,
            previous: None,
            exact: None,
            anchor_time: self.state.anchor_time,
            anchor,
            steps: 0,
            equations,
        })
    }

    /// Steps the integrated phase until its steps cover `t` (a restored
    /// state replays its phase from the anchor): at most
    /// [`REANCHOR_AFTER`] steps, after which a run re-anchors; a state
    /// further from its anchor (a corrupted time or search position) is
    /// refused.
    pub(super) fn replay_to(&mut self, t: f64) -> Result<(), SimError> {
        let super::Segment::Integrated(seg) = &mut self.segment else { return Ok(()) };
        while seg.step.as_ref().map_or(seg.anchor_time < t, |s| s.1 < t) {
            if seg.steps >= REANCHOR_AFTER {
                return Err(SimError::Integration {
                    time: seg.solver.t(),
                    message: format!(
                        "simulation state: t = {t} lies more than {REANCHOR_AFTER} integration steps after the phase's anchor {} (a run re-anchors after that many)",
                        seg.anchor_time
                    ),
                });
            }
            take_step(seg)?;
        }
        Ok(())
    }

    /// A new anchor at the end of the integrated phase's last step (after
    /// [`REANCHOR_AFTER`] steps without a switch): the phase's totals are
    /// closed there and its integration restarts from that state, so a
    /// restore replays at most that many steps.
    fn reanchor_integrated(&mut self) -> Result<(), SimError> {
        let super::Segment::Integrated(seg) = &self.segment else { unreachable!("an integrated segment") };
        let t = seg.solver.t();
        let n = seg.phase.n;
        let y = seg.solver.y();
        let mut at = ModalState::zeros(n);
        at.q.copy_from(&y.rows(0, n));
        at.qd.copy_from(&y.rows(n, n));
        self.account(t);
        self.close_segment(t, &at);
        self.state.anchor = at;
        self.state.anchor_time = t;
        self.state.scan = t;
        self.state.probed = t;
        for s in &mut self.state.stops {
            s.departing = [false; 2];
        }
        self.mark_anchor_departing();
        self.rebuild_segment()
    }

    /// The event search of an integrated phase from `scan` up to `t_end`:
    /// the first switch with the state there, the channels at zero and the
    /// sample its bracket started at (a search resumed there finds it
    /// again), or `None` when `[scan, t_end]` is clear (then `scan` stays
    /// at or before `t_end`, inside the last step).
    pub(super) fn integrated_search(&mut self, t_end: f64, probes: &mut u64) -> Result<Option<IntegratedSwitch>, SimError> {
        let max_probes = self.model.max_probes_per_step;
        loop {
            let scan = self.state.scan;
            if scan >= t_end && scan > self.state.anchor_time {
                return Ok(None);
            }
            let super::Segment::Integrated(seg) = &mut self.segment else { unreachable!("an integrated segment") };
            if seg.step.as_ref().map_or(true, |s| s.1 <= scan) && seg.steps >= REANCHOR_AFTER {
                self.reanchor_integrated()?;
                continue;
            }
            let super::Segment::Integrated(seg) = &mut self.segment else { unreachable!("an integrated segment") };
            if seg.step.as_ref().map_or(true, |s| s.1 <= scan) {
                let weight = crate::kinds::modal::model::INTEGRATED_STEP_WEIGHT;
                if *probes + weight > max_probes {
                    return Err(SimError::TooMuchWork { time: scan, work: *probes, cap: "solver.max_probes_per_step" });
                }
                // Every attempt counts (rejected ones too: a far state can
                // take hundreds per accepted step), up to the cap: a step's
                // attempts are not known before it, and the one that
                // reaches the cap ends the advance at the next check.
                let before = seg.solver.attempts();
                take_step(seg)?;
                *probes = (*probes + weight * (seg.solver.attempts() - before).max(1)).min(max_probes);
                self.stats.probes += 1;
                if let (Some(trace), Some(step)) = (&mut self.flow_trace, &seg.step) {
                    trace.push(step.1);
                }
            }
            let (t0, t1) = seg.step.as_ref().map(|s| (s.0, s.1)).expect("a step");
            let Some(located) = first_switch(&**seg, t0, t1, scan) else {
                if t1 > t_end {
                    // Clear to beyond t_end; the sample grid is the
                    // step's, so the next search sees the same samples.
                    self.state.scan = self.state.scan.max(t_end);
                    return Ok(None);
                }
                self.state.scan = t1;
                continue;
            };
            // Every zero in the step is refined before it is compared with
            // t_end: the refinement moves the dense output's zero by its
            // error, at loose tolerances a large part of the step, either
            // way. A zero past t_end whose refined time lies before it is
            // this search's (a search that left it to the next would find
            // it before that one's start: an event in the past), and a run
            // stopped before a switch finds it again by a search to its
            // own time (to make it, to restore the state, to take its
            // guard).
            // The state at the switch: a step of its own from the step's
            // start, refined to the full-order zero. Where the step before
            // ended close to it, that step collocated a force near its
            // corner: at tight tolerances the state is made from the step
            // before's start instead ([`IntegratedSegment::origin_before`],
            // [`FROM_STEP_BEFORE_BELOW`]).
            let attempts_before_switch = seg.solver.attempts();
            let tight = self.model.integration_tolerance <= FROM_STEP_BEFORE_BELOW;
            let origin = match seg.origin_before(located.time).filter(|_| tight) {
                Some(before) => before,
                None => (t0, &seg.step.as_ref().expect("a step").2),
            };
            let refined = seg.refine_zero(&located, origin, t1, t_end, &self.model.oscillators);
            let Refinement::Done(Refined { te, at, spurious, passed }) = refined else {
                self.state.scan = self.state.scan.max(t_end);
                return Ok(None);
            };
            // The switch state's steps count as steps (each up to a
            // thousand attempts).
            *probes = (*probes + crate::kinds::modal::model::INTEGRATED_STEP_WEIGHT * (seg.solver.attempts() - attempts_before_switch)).min(max_probes.max(*probes));
            if spurious {
                self.state.scan = t1;
                continue;
            }
            if passed {
                let scan = self.state.scan;
                self.state.scan = grid(t0, t1).into_iter().find(|&s| s >= te && s > scan).unwrap_or(t1);
                continue;
            }
            if te > t_end {
                self.state.scan = self.state.scan.max(t_end);
                return Ok(None);
            }
            if te != t1 && te > t0 {
                // The totals the switch closes the phase with come from
                // this state too, as they do when the run stopped here first.
                seg.exact = Some((te, at.clone()));
            }
            let n = seg.phase.n;
            let mut st = ModalState::zeros(n);
            st.q.copy_from(&at.rows(0, n));
            st.qd.copy_from(&at.rows(n, n));
            let at_zero = located
                .at_zero
                .iter()
                .map(|&(c, slope)| {
                    let value = seg.evaluate(&seg.evaluators[c], te, &at);
                    // A gap's or penetration's rate where it falls is the
                    // switch state's own (the locator's slope is a chord's:
                    // the approach speed an impact reports); where the
                    // state's rises, the dip the chord crossed lies behind
                    // it, and the chord's slope says so.
                    let slope = seg.rate_in(c, te, &at).filter(|r| *r < 0.0).unwrap_or(slope);
                    (c, Jet { d: [value.min(0.0), slope, 0.0, 0.0], noise: [0.0; 4], slack: 0.0 })
                })
                .collect();
            return Ok(Some(IntegratedSwitch { time: te, state: st, at_zero, from: located.from }));
        }
    }
}

impl Simulation {
    /// The stops whose watched functions are at their zero at the switch a
    /// run stopped just before (an integrated phase whose search position
    /// lies before the time): the switch's own state is a Newton step past
    /// their zero, so their contact state no longer matches it. Found
    /// again from the search position, as a restore does; empty when the
    /// run is not stopped before a switch.
    pub(super) fn stops_at_pending_switch(&self) -> Vec<usize> {
        if self.state.scan >= self.state.time || !matches!(self.segment, super::Segment::Integrated(_)) {
            return Vec::new();
        }
        let mut search = self.clone();
        match search.integrated_search(self.state.time, &mut 0) {
            Ok(Some(found)) if found.time == self.state.time => found.at_zero.iter().map(|&(c, _)| search.channels[c].stop).collect(),
            _ => Vec::new(),
        }
    }
}

/// A switch an integrated phase's search located.
pub(super) struct IntegratedSwitch {
    pub time: f64,
    /// The state there (to the method's full order).
    pub state: ModalState,
    pub at_zero: Vec<(usize, Jet)>,
    /// The sample the switch's bracket started at.
    pub from: f64,
}

fn take_step(seg: &mut IntegratedSegment) -> Result<(), SimError> {
    let t0 = seg.solver.t();
    let (a, b) = seg.solver.step(&seg.phase).map_err(|e| integration(t0, e.to_string()))?;
    if seg.direction_of.is_empty() {
        // The locator reads whole states at its samples.
        seg.solver.prefill(&crate::solve::switch::grid(a, b));
    }
    debug_assert_eq!(a, t0);
    // The step's start, in the storage of the start it displaces from
    // `previous` (no allocation per step).
    let start = seg.solver.last_step().expect("a step").start();
    let y0 = match seg.previous.take() {
        Some((_, mut y)) if y.len() == start.len() => {
            y.copy_from(start);
            y
        }
        _ => start.clone(),
    };
    seg.previous = seg.step.replace((a, b, y0)).map(|(t, _, y)| (t, y));
    seg.steps += 1;
    Ok(())
}

/// An integration failure, with what to change.
fn integration(time: f64, message: String) -> SimError {
    SimError::Integration { time, message: format!("{message}; loosen solver.integration_tolerance or check the contact parameters") }
}
