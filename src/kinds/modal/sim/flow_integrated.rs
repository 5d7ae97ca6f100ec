//! The flow's Jacobian through an integrated (Hertz, power-law) contact
//! phase, and what the switches into and out of it need: the phase's
//! vector field and the guard of a switch it locates (issue 44).
//!
//! **The phase.** The collocation's own map over the nominal run's steps
//! is differentiated ([`crate::solve::collocation::Replay`]): the
//! sensitivities of each step solve the linear system Newton factors, so
//! the derivative is exact for the discrete map and as accurate as the
//! map is to the flow (the integration tolerance). The alternative, a
//! difference quotient of replays from moved start states, costs two
//! replays per coordinate (80 for a 20-mode beam) and needs Newton
//! converged to rounding for a smooth quotient; the sensitivities cost one
//! solve with the state's width of right-hand sides per step. The steps
//! are the nominal ones (their ends recorded as the run takes them), the
//! last cut into pieces shrinking toward a switch at its end as the run
//! reaches a switch's state, so the replay's error is the run's.
//!
//! **The onset speed.** A hysteretic damping (Hunt-Crossley, LN90) scales
//! with the approach speed at the onset `v0 = side w . q'` there: the
//! phase depends on it as on a parameter set at the onset, so the flow's
//! Jacobian carries `dv0/dx` from the onset (the guard's time shift
//! included: `dv0 = Dv dx + (Dv F-) dt`, `dt = -Dg dx / g'`) and the
//! phase adds `dy/dv0 dv0/dx`. A section inside such a contact holds its
//! `v0` fixed (a parameter of the map there, not a coordinate).
//!
//! **The saltation** at a switch is `S = I + (F+ - F-) Dg / g'` (no reset),
//! computed from the two vector fields as for every switch. For Hertz and
//! the power law the force is `K p^n` at `p = 0`, so it is zero on both
//! sides of an onset and a separation whatever the damping: with the
//! hysteretic ones (`K p^n (1 + alpha p' / v0)`) the damping term carries
//! `p^n` too, and a push that ends inside the stop (the force reaching
//! zero, `1 + alpha p' / v0 = 0`) ends at zero force: `F+ = F-`, `S = I`.
//! A linear damping (`K p^n + C p'`, DWZ) jumps by `C p'` at the onset and
//! the saltation has that term.

use nalgebra::{DMatrix, DVector};

use super::integrated::Evaluator;
use super::phases::Segment;
use super::{SimError, Simulation};
use crate::contact::Watch;
use crate::solve::free::ModalJet;
use crate::solve::{Functional, ModalState};

/// The Jacobian of an integrated phase.
pub(super) struct PhaseJacobian {
    /// `d[q; q'](t1) / d[q; q'](t0)`.
    pub state: DMatrix<f64>,
    /// Per engaged contact: its stop and `d[q; q'](t1) / d v0` of that stop.
    pub onset: Vec<(usize, DVector<f64>)>,
}

impl Simulation {
    /// The end of the integrated phase's step under way at the current
    /// time, if one covers it (the first step end of the phase after now).
    pub(super) fn integrated_step_end(&self) -> Option<f64> {
        match &self.segment {
            Segment::Integrated(seg) => seg.step.as_ref().map(|s| s.1).filter(|&b| b > self.state.time),
            _ => None,
        }
    }

    /// The Jacobian of the integrated phase of this run (stopped at `t0` in
    /// `x0`) up to `t1`, over the step ends `trace` the run took (module
    /// doc); `switches`: the phase starts at a switch at `t0`, ends at one
    /// at `t1` (the force's corners there).
    pub(super) fn integrated_transition(&self, t0: f64, x0: &ModalState, t1: f64, trace: &[f64], switches: (bool, bool)) -> Result<PhaseJacobian, SimError> {
        let Segment::Integrated(seg) = &self.segment else { unreachable!("an integrated phase") };
        let n = self.model.n_modes();
        let mut times = vec![t0];
        times.extend(trace.iter().copied().filter(|&t| t > t0 && t < t1));
        times.push(t1);
        let mut y0 = DVector::zeros(seg.phase.dim());
        y0.rows_mut(0, n).copy_from(&x0.q);
        y0.rows_mut(n, n).copy_from(&x0.qd);
        let replay = seg.solver.replay_with_jacobian(&seg.phase, &times, &y0, switches).map_err(|_| SimError::Integration {
            time: t0,
            message: format!("the flow's Jacobian: a replayed collocation step of the phase from t = {t0} to {t1} did not converge"),
        })?;
        let onset = seg.phase.contacts.iter().enumerate().map(|(c, contact)| (contact.stop, replay.parameter.column(c).into_owned())).collect();
        Ok(PhaseJacobian { state: replay.jacobian, onset })
    }

    /// `[q'; q'']` of the integrated phase now: the free acceleration less
    /// every engaged stop's `side w F` (held ones: their reaction).
    pub(super) fn integrated_vector_field(&self) -> DVector<f64> {
        let Segment::Integrated(seg) = &self.segment else { unreachable!("an integrated phase") };
        let (t, st) = (self.state.time, &self.state.current);
        let n = self.model.n_modes();
        let mut jet = ModalJet::new(n);
        jet.fill_free(&self.dynamics, t, st);
        let mut a = jet.q[2].clone();
        let mut y = DVector::zeros(seg.phase.dim());
        y.rows_mut(0, n).copy_from(&st.q);
        y.rows_mut(n, n).copy_from(&st.qd);
        let pushes = seg.equations.pushes(&seg.phase, t, &y);
        for (i, c) in seg.phase.contacts.iter().enumerate() {
            let force = if c.held {
                pushes[i]
            } else {
                // The law's force inside the stop, its limit at the
                // surface (a linear damping's `C p'` at an onset).
                let (p, pd) = seg.phase.penetration(i, y.as_slice());
                c.law.raw_force(p.max(0.0), pd, c.onset_speed).0.max(0.0)
            };
            a.axpy(-c.geometry.side * force, &c.geometry.w, 1.0);
        }
        DVector::from_iterator(2 * n, st.qd.iter().chain(a.iter()).copied())
    }

    /// The guard of the switch an integrated phase stopped just before:
    /// its gradient in `[q; q']` (as a functional without load terms), or
    /// `None` for a held stop's reaction (whose gradient the phase does not
    /// form).
    pub(super) fn integrated_guard(&self) -> Result<Option<Functional>, SimError> {
        let t = self.state.time;
        let mut search = self.clone();
        search.state.scan = search.state.scan.min(t);
        let found = search.integrated_search(t, &mut 0)?;
        let Some(found) = found.filter(|f| f.time == t) else {
            return Err(SimError::Unsupported(format!("the exact flow: no switch found again at t = {t} where the integrated phase stopped")));
        };
        let Some(&(c, _)) = found.at_zero.first() else {
            return Err(SimError::Unsupported(format!("the exact flow: no event function at zero at t = {t} where the run stopped")));
        };
        let Segment::Integrated(seg) = &search.segment else { unreachable!("an integrated phase") };
        let n = self.model.n_modes();
        Ok(match &seg.evaluators[c] {
            Evaluator::Affine(h, _) => Some(Functional { offset: h.offset, q: h.q.clone(), qd: None, f: None }),
            Evaluator::Nonlinear { watch: Watch::Reaction, .. } => None,
            Evaluator::Nonlinear { contact, watch } => {
                let st = &self.state.current;
                let mut y = DVector::zeros(seg.phase.dim());
                y.rows_mut(0, n).copy_from(&st.q);
                y.rows_mut(n, n).copy_from(&st.qd);
                let (p, pd) = seg.phase.penetration(*contact, y.as_slice());
                let k = &seg.phase.contacts[*contact];
                let (_, dp, dpd) = k.law.watched(*watch, p, pd, k.onset_speed);
                let d = &k.geometry.w * k.geometry.side;
                Some(Functional { offset: 0.0, q: &d * dp, qd: Some(&d * dpd), f: None })
            }
        })
    }
}
