//! The multi-point impact rule of rigid stops (VSM12 eqs. 25-28; WB00
//! eq. 6): the impulses of every contact point impacting at one time,
//! solved together, whatever law decided each point's restitution.
//!
//! An impulse `P_i` at each point changes the modal velocities by
//! `qd+ = qd- + sum_i w_i P_i` (eq. 25) so that the contact velocity
//! becomes `w_i . qd+ = -R_i w_i . qd-` (eq. 18). With one point this is
//! eq. 28. Points held by sticking take part with `R = 0`.

use nalgebra::{DMatrix, DVector};

/// One contact point taking part in an impact.
#[derive(Clone, Debug)]
pub struct ImpactRow<'a> {
    /// Shape vector `w_j = W_j(x_c)`.
    pub w: &'a DVector<f64>,
    /// Coefficient of restitution for this point (0 for held points).
    pub restitution: f64,
    /// +1 if the stop limits `w . q` from above, -1 from below: the
    /// impulse on the beam must have the sign of `-side`.
    pub side: f64,
}

/// Applies the impact rule in place and writes the impulses, one per row,
/// into `impulses`. Points whose impulse would pull on the beam (only
/// possible for held points) are dropped and the rest solved again; their
/// impulse is 0.
pub fn apply_impact(qd: &mut DVector<f64>, rows: &[ImpactRow], impulses: &mut Vec<f64>) {
    impulses.clear();
    if let [row] = rows {
        // One point: eq. 28 directly, `P = -(1 + R) w . qd- / (w . w)`.
        let p = -(1.0 + row.restitution) * row.w.dot(qd) / row.w.dot(row.w);
        qd.axpy(p, row.w, 1.0);
        impulses.push(p);
        return;
    }
    impulses.resize(rows.len(), 0.0);
    let mut active: Vec<bool> = vec![true; rows.len()];
    let before = qd.clone();
    loop {
        let idx: Vec<usize> = (0..rows.len()).filter(|&i| active[i]).collect();
        let m = idx.len();
        impulses.iter_mut().for_each(|p| *p = 0.0);
        if m == 0 {
            qd.copy_from(&before);
            return;
        }
        let gram = DMatrix::from_fn(m, m, |a, b| rows[idx[a]].w.dot(rows[idx[b]].w));
        let rhs = DVector::from_fn(m, |a, _| {
            let r = &rows[idx[a]];
            -(1.0 + r.restitution) * r.w.dot(&before)
        });
        let p = gram.lu().solve(&rhs).unwrap_or_else(|| DVector::zeros(m));
        let mut after = before.clone();
        for (a, &i) in idx.iter().enumerate() {
            after.axpy(p[a], rows[i].w, 1.0);
            impulses[i] = p[a];
        }
        let pulling: Vec<usize> = idx.iter().copied().filter(|&i| impulses[i] * rows[i].side > 0.0).collect();
        if pulling.is_empty() || m == 1 {
            qd.copy_from(&after);
            return;
        }
        for i in pulling {
            active[i] = false;
        }
    }
}

/// Kinetic energy lost by a single-point impact:
/// `(1 - R^2) (w . qd-)^2 / (2 w . w)` (Kelvin's impact loss with the modal restitution rule, VSM12 eq. 28).
pub fn energy_loss(w: &DVector<f64>, qd_before: &DVector<f64>, restitution: f64) -> f64 {
    let v = w.dot(qd_before);
    (1.0 - restitution * restitution) * v * v / (2.0 * w.dot(w))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::dvector;

    #[test]
    fn single_point_rule_is_eq_28() {
        let w = dvector![1.1, 0.3, -0.8];
        let mut qd = dvector![2.0, -1.0, 0.5];
        let before = qd.clone();
        apply_impact(&mut qd, &[ImpactRow { w: &w, restitution: 0.7, side: 1.0 }], &mut Vec::new());
        assert!((w.dot(&qd) + 0.7 * w.dot(&before)).abs() < 1e-14);
        let expected = &before - &w * ((1.0 + 0.7) * w.dot(&before) / w.dot(&w));
        assert!((qd - expected).norm() < 1e-14);
    }

    #[test]
    fn energy_loss_matches_kinetic_energy_difference() {
        let w = dvector![1.1, 0.3, -0.8];
        let mut qd = dvector![2.0, -1.0, 0.5];
        let before = qd.clone();
        apply_impact(&mut qd, &[ImpactRow { w: &w, restitution: 0.4, side: 1.0 }], &mut Vec::new());
        let lost = 0.5 * (before.norm_squared() - qd.norm_squared());
        assert!((lost - energy_loss(&w, &before, 0.4)).abs() < 1e-14);
    }
}
