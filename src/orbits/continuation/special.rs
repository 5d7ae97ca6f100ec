//! Special points between consecutive points of a branch: detection by
//! the sign changes of test functions, location on the branch by regula
//! falsi in the arclength (module doc of `continuation`).

use nalgebra::{DMatrix, DVector};

use super::corrector::Walker;
use super::grazing::grazing_measure;
use super::{Point, Special, SpecialKind};
use crate::solve::regula_falsi::{End, RegulaFalsi};

/// A special point located, and what happens there.
type Located = (Point, String);

impl Walker {
    /// Special points between consecutive points `a` and `b` (module doc).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn detect(
        &mut self,
        branch: usize,
        periods: usize,
        (a, tangent_a): (&Point, &DVector<f64>),
        (b, tangent_b): (&Point, &DVector<f64>),
        skip_smooth: bool,
        special: &mut Vec<Special>,
        doublings: &mut Vec<Point>,
    ) {
        let n = a.orbit.state.len();
        let mut found: Vec<(SpecialKind, Result<Located, String>)> = Vec::new();
        let sequence_changed = a.profile.impacts != b.profile.impacts || a.profile.sticks != b.profile.sticks;
        if a.profile.impacts != b.profile.impacts {
            let few = a.profile.impacts.min(b.profile.impacts);
            let reference = if a.profile.impacts == few { a } else { b };
            let curvature = reference.profile.closest.map_or(1.0, |c| c.curvature.max(f64::MIN_POSITIVE));
            let psi = move |p: &Point| -> Option<f64> {
                if p.profile.impacts == few {
                    p.profile.closest.map(|c| c.gap)
                } else if p.profile.impacts > few {
                    p.profile.slowest_impact.map(|v| -v * v / (2.0 * curvature))
                } else {
                    None
                }
            };
            let located = self.locate(a, b, tangent_a, periods, &psi, false);
            found.push((
                SpecialKind::Grazing,
                located.map(|p| {
                    let note = format!("impacts per orbit {} -> {}{}; {}", a.profile.impacts, b.profile.impacts, stability_change(a, b), grazing_measure(&p));
                    (p, note)
                }),
            ));
        }
        if a.profile.sticks != b.profile.sticks {
            let sticks_a = a.profile.sticks;
            let psi = move |p: &Point| -> Option<f64> { Some(if p.profile.sticks == sticks_a { 1.0 } else { -1.0 }) };
            let located = self.locate(a, b, tangent_a, periods, &psi, true);
            found.push((
                SpecialKind::Sticking,
                located.map(|p| {
                    let note = format!("sticks per orbit {} -> {}{}", a.profile.sticks, b.profile.sticks, stability_change(a, b));
                    (p, note)
                }),
            ));
        }
        if !sequence_changed && !skip_smooth {
            let det = |p: &Point, shift: f64| -> f64 { (&p.orbit.monodromy + DMatrix::identity(n, n) * shift).determinant() };
            let fold = tangent_a[n].signum() != tangent_b[n].signum();
            if det(a, -1.0).signum() != det(b, -1.0).signum() {
                let kind = if fold { SpecialKind::SaddleNode } else { SpecialKind::BranchPoint };
                let psi = move |p: &Point| Some(det(p, -1.0));
                let located = self.locate(a, b, tangent_a, periods, &psi, false);
                found.push((kind, located.map(|p| (p, format!("a multiplier through +1{}", stability_change(a, b))))));
            }
            if det(a, 1.0).signum() != det(b, 1.0).signum() {
                let psi = move |p: &Point| Some(det(p, 1.0));
                let located = self.locate(a, b, tangent_a, periods, &psi, false);
                if let Ok(p) = &located {
                    doublings.push(p.clone());
                }
                found.push((SpecialKind::PeriodDoubling, located.map(|p| (p, format!("a multiplier through -1{}", stability_change(a, b))))));
            }
            let unstable_pairs = |p: &Point| p.orbit.multipliers.iter().filter(|z| z.im > 1e-9 * z.norm() && z.norm() > 1.0).count();
            if unstable_pairs(a) != unstable_pairs(b) && a.orbit.n_unstable.abs_diff(b.orbit.n_unstable) == 2 {
                let psi = |p: &Point| {
                    p.orbit.multipliers.iter().filter(|z| z.im > 1e-9 * z.norm()).map(|z| z.norm() - 1.0).min_by(|x, y| x.abs().total_cmp(&y.abs()))
                };
                let located = self.locate(a, b, tangent_a, periods, &psi, false);
                found.push((
                    SpecialKind::NeimarkSacker,
                    located.map(|p| {
                        let z = p.orbit.multipliers.iter().filter(|z| z.im > 0.0).min_by(|x, y| (x.norm() - 1.0).abs().total_cmp(&(y.norm() - 1.0).abs()));
                        let note = z.map_or(String::new(), |z| format!("a complex pair through the unit circle at angle {:.6} rad", z.arg()));
                        (p, note + &stability_change(a, b))
                    }),
                ));
            }
        }
        for (kind, located) in found {
            let (point, note) = match located {
                Ok(found) => found,
                // Not located: the nearer of the two points, and why.
                Err(e) => (b.clone(), format!("between {} = {} and {}, not located: {e}", self.name(), a.param, b.param)),
            };
            special.push(Special { kind, branch, point, note });
        }
    }

    /// The zero of `psi` between the consecutive points `a` and `b` of a
    /// branch, by regula falsi (Illinois) on the arclength from `a`, each
    /// trial point corrected onto the branch; `bisect` for a step function.
    pub(super) fn locate(
        &mut self,
        a: &Point,
        b: &Point,
        tangent_a: &DVector<f64>,
        periods: usize,
        psi: &dyn Fn(&Point) -> Option<f64>,
        bisect: bool,
    ) -> Result<Point, String> {
        let ua = self.scaled(&a.orbit.state, a.param);
        let ub = self.scaled(&b.orbit.state, b.param);
        let span = (&ub - &ua).dot(tangent_a);
        let mut bracket = RegulaFalsi::new(
            (0.0, psi(a).ok_or("the test function is not defined at the first point")?),
            (span, psi(b).ok_or("the test function is not defined at the second point")?),
        );
        let (mut best_lo, mut best_hi) = (a.clone(), b.clone());
        let scale = a.param.abs().max(self.range.1 - self.range.0);
        for _ in 0..60 {
            if (best_hi.param - best_lo.param).abs() <= if bisect { 1e-8 } else { 1e-10 } * scale || (bracket.hi - bracket.lo).abs() <= 1e-14 {
                break;
            }
            let s = bracket.next(bisect);
            let u_pred = &ua + tangent_a * s;
            let (point, _, _) = self.correct(&u_pred, tangent_a, periods, Some(a))?;
            match psi(&point).map(|f| bracket.take(s, f)) {
                None => {
                    // Neither side's sequence: shrink towards the first point.
                    bracket.shrink_hi(s);
                    best_hi = point;
                }
                Some(None) => return Ok(point),
                Some(Some(End::Lo)) => best_lo = point,
                Some(Some(End::Hi)) => best_hi = point,
            }
        }
        Ok(if bracket.f_lo.abs() <= bracket.f_hi.abs() { best_lo } else { best_hi })
    }
}

/// ", stability changes: n unstable multipliers a -> b", when it does.
pub(super) fn stability_change(a: &Point, b: &Point) -> String {
    if a.orbit.n_unstable == b.orbit.n_unstable {
        String::new()
    } else {
        format!("; unstable multipliers {} -> {}", a.orbit.n_unstable, b.orbit.n_unstable)
    }
}
