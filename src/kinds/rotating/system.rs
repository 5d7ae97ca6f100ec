//! The integrated equations of one phase (a contact state, an onset speed,
//! a hub torque) as a first-order system (DOP853's and Radau IIA's).
//!
//! State `y`: torque-driven hub `[theta, B, theta', B', P, E, H]`, prescribed
//! hub `[B, B', P, E, H]` (theta from the profile), with the running totals
//! `P = int F dt` (impulse), `E = int (F - F_spring) gamma' dt` (energy
//! the contact damping dissipated) and `H = int Q_c,theta dt` (angular
//! impulse about the axis, the moment of the contact force). They come out
//! of the integration to its accuracy; their Jacobian rows are left zero
//! (nothing depends on them, so Newton solves them exactly once the rest
//! has converged) and they have no error control of their own.
//!
//! The contact force `F = K gamma^1.5 + damping` (DWZ eqs. 2-4) acts while
//! pressed and `gamma = -gap > 0` and the raw force is positive, along the
//! plane's normal: `Q_c = F d gap / dz`.

use std::sync::Arc;

use nalgebra::{DMatrix, DVector};

use super::model::RotatingModel;
use crate::structure::rotating::{AccelerationScratch, ContactTerms, Plane};
use crate::contact::Contact;
use crate::solve::radau::ImplicitSystem;

/// The contact quantities at one state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ContactPoint {
    /// `gamma = -gap` and `gamma'`.
    pub penetration: f64,
    pub rate: f64,
    /// The unclamped law `K gamma^1.5 + damping` (0 for `gamma <= 0`).
    pub raw: f64,
    /// The force acting (0 unless pressed, penetrating and pushing) and its
    /// derivatives with respect to `gamma` and `gamma'`.
    pub force: f64,
    pub df_dp: f64,
    pub df_dpd: f64,
}

/// One phase's equations.
#[derive(Clone, Debug)]
pub struct Phase {
    pub model: Arc<RotatingModel>,
    pub contact: Contact,
    pub onset_speed: f64,
    pub torque: f64,
}

impl Phase {
    pub fn n(&self) -> usize {
        self.model.n_modes()
    }

    pub fn prescribed(&self) -> bool {
        self.model.prescribed().is_some()
    }

    /// Index of `P` in `y` (`E`, `H` follow).
    pub fn extras(&self) -> usize {
        let n = self.n();
        if self.prescribed() {
            2 * n
        } else {
            2 * n + 2
        }
    }

    pub fn dim(&self) -> usize {
        self.extras() + 3
    }

    /// `(z, z')` at time `t` from `y`.
    pub fn coords(&self, t: f64, y: &DVector<f64>) -> (DVector<f64>, DVector<f64>) {
        let n = self.n();
        match self.model.prescribed() {
            None => {
                let y = y.as_slice();
                (DVector::from_column_slice(&y[..n + 1]), DVector::from_column_slice(&y[n + 1..2 * n + 2]))
            }
            Some(p) => {
                let (th, thd, _) = p.at(t);
                let mut z = DVector::zeros(n + 1);
                let mut zd = DVector::zeros(n + 1);
                z[0] = th;
                zd[0] = thd;
                z.rows_mut(1, n).copy_from(&y.rows(0, n));
                zd.rows_mut(1, n).copy_from(&y.rows(n, n));
                (z, zd)
            }
        }
    }

    /// `z'` along a curve `y(t)` with derivative `dy` (the hub from the profile).
    pub fn coords_rate(&self, t: f64, dy: &DVector<f64>) -> DVector<f64> {
        let n = self.n();
        match self.model.prescribed() {
            None => dy.rows(0, n + 1).into_owned(),
            Some(p) => {
                let mut zd = DVector::zeros(n + 1);
                zd[0] = p.at(t).1;
                zd.rows_mut(1, n).copy_from(&dy.rows(0, n));
                zd
            }
        }
    }

    /// The contact at `(z, z')`; no surface: all zero.
    pub fn contact_point(&self, z: &DVector<f64>, zd: &DVector<f64>) -> ContactPoint {
        self.contact_point_at(z.as_slice(), zd.as_slice())
    }

    /// [`Self::contact_point`] from slices (no allocation).
    pub fn contact_point_at(&self, z: &[f64], zd: &[f64]) -> ContactPoint {
        let Some(s) = &self.model.surface else { return ContactPoint::default() };
        let (gamma, rate) = self.model.beam.plane_penetration(z, zd, &s.plane);
        self.contact_point_from(gamma, rate)
    }

    /// The contact quantities at penetration `gamma` and rate `rate`.
    pub fn contact_point_from(&self, gamma: f64, rate: f64) -> ContactPoint {
        let Some(s) = &self.model.surface else { return ContactPoint::default() };
        let mut c = ContactPoint { penetration: gamma, rate, ..Default::default() };
        if gamma > 0.0 {
            let (f, dp, dpd) = s.law.raw_force(gamma, rate, self.onset_speed);
            c.raw = f;
            if self.contact == Contact::Pressed && f > 0.0 {
                (c.force, c.df_dp, c.df_dpd) = (f, dp, dpd);
            }
        }
        c
    }

    /// Elastic energy stored while pressed (0 otherwise: what is left at
    /// the end of a push counts as dissipated).
    pub fn stored_energy(&self, c: &ContactPoint) -> f64 {
        match &self.model.surface {
            Some(s) => s.law.stored_energy(self.contact, c.penetration),
            None => 0.0,
        }
    }

    /// `z''` (the hub's from the profile when prescribed) and the contact's
    /// generalized force.
    pub fn accelerations(&self, t: f64, z: &DVector<f64>, zd: &DVector<f64>, c: &ContactPoint) -> Result<(DVector<f64>, DVector<f64>), String> {
        let n = self.n();
        let beam = &self.model.beam;
        let qc = match &self.model.surface {
            Some(s) if c.force > 0.0 => beam.contact_generalized_force(z, &s.plane, c.force),
            _ => DVector::zeros(n + 1),
        };
        let mut zdd = DVector::zeros(n + 1);
        match self.model.prescribed() {
            None => beam.accelerations(z, zd, self.torque, Some(&qc), &mut zdd)?,
            Some(p) => {
                let thdd = p.at(t).2;
                let mut bdd = DVector::zeros(n);
                beam.prescribed_accelerations(z, zd, thdd, Some(&qc), &mut bdd);
                zdd[0] = thdd;
                zdd.rows_mut(1, n).copy_from(&bdd);
            }
        }
        Ok((zdd, qc))
    }

    /// The hub torque: the input, or the one a prescribed motion needs.
    pub fn hub_torque(&self, t: f64, z: &DVector<f64>, zd: &DVector<f64>, c: &ContactPoint) -> f64 {
        match self.model.prescribed() {
            None => self.torque,
            Some(_) => match self.accelerations(t, z, zd, c) {
                Ok((zdd, qc)) => {
                    let bdd = zdd.rows(1, self.n()).into_owned();
                    self.model.beam.required_torque(z, zd, zdd[0], &bdd, Some(&qc))
                }
                Err(_) => f64::NAN,
            },
        }
    }

    pub(super) fn fill_rhs(&self, t: f64, y: &DVector<f64>, dy: &mut DVector<f64>) -> Result<(), String> {
        if !self.prescribed() {
            return self.fill_rhs_free_hub(y.as_slice(), dy.as_mut_slice(), &mut AccelerationScratch::default());
        }
        let n = self.n();
        let (z, zd) = self.coords(t, y);
        let c = self.contact_point(&z, &zd);
        let (zdd, qc) = self.accelerations(t, &z, &zd, &c)?;
        let e = self.extras();
        if self.prescribed() {
            dy.rows_mut(0, n).copy_from(&zd.rows(1, n));
            dy.rows_mut(n, n).copy_from(&zdd.rows(1, n));
        } else {
            dy.rows_mut(0, n + 1).copy_from(&zd);
            dy.rows_mut(n + 1, n + 1).copy_from(&zdd);
        }
        dy[e] = c.force;
        dy[e + 1] = match &self.model.surface {
            Some(s) if c.force > 0.0 => (c.force - s.law.spring_force(c.penetration).0) * c.rate,
            _ => 0.0,
        };
        dy[e + 2] = qc[0];
        Ok(())
    }

    /// [`Self::fill_rhs`] for a hub driven by its torque, without
    /// allocation: `y = [z; z'; extras]`.
    pub(super) fn fill_rhs_free_hub(&self, y: &[f64], dy: &mut [f64], scratch: &mut AccelerationScratch) -> Result<(), String> {
        let m = self.n() + 1;
        let (z, rest) = y.split_at(m);
        let zd = &rest[..m];
        let e = self.extras();
        let (head, tail) = dy.split_at_mut(m);
        head.copy_from_slice(zd);
        let terms = self.with_pushing_law(|contact| self.model.beam.accelerations_in_place(z, zd, self.torque, contact, &mut tail[..m], scratch))?;
        self.totals_rates(&terms, &mut dy[e..e + 3]);
        Ok(())
    }

    /// `run` given the contact the beam's equations take: the surface and
    /// the law's force `(penetration, rate)`, when pressed (only a pressed
    /// contact pushes), else `None`.
    pub(super) fn with_pushing_law<T>(&self, run: impl FnOnce(Option<(&Plane, &mut dyn FnMut(f64, f64) -> f64)>) -> T) -> T {
        let onset_speed = self.onset_speed;
        let surface = self.model.surface.as_ref();
        let mut force = |p: f64, rate: f64| match surface {
            Some(s) if p > 0.0 => s.law.raw_force(p, rate, onset_speed).0.max(0.0),
            _ => 0.0,
        };
        run(surface.filter(|_| self.contact == Contact::Pressed).map(|s| (&s.plane, &mut force as &mut dyn FnMut(f64, f64) -> f64)))
    }

    /// The running totals' rates `[P', E', H']` from one evaluation's contact terms.
    pub(super) fn totals_rates(&self, terms: &ContactTerms, out: &mut [f64]) {
        out[0] = terms.force;
        out[1] = match &self.model.surface {
            Some(s) if terms.force > 0.0 => (terms.force - s.law.spring_force(terms.penetration).0) * terms.rate,
            _ => 0.0,
        };
        out[2] = terms.hub_force;
    }

    /// `d Q_c / d(z, z')` ((N+1) x 2(N+1)) for the force acting now.
    fn contact_force_jacobian(&self, z: &DVector<f64>, zd: &DVector<f64>, c: &ContactPoint) -> Option<DMatrix<f64>> {
        let s = self.model.surface.as_ref()?;
        if c.force <= 0.0 {
            return None;
        }
        let m = self.n() + 1;
        let (g, h) = self.model.gap_gradient_hessian(z, &s.plane);
        // gamma = -gap: d gamma/dz = -g, d gamma'/dz = -H z', d gamma'/dz' = -g.
        let hzd = &h * zd;
        let dfdz = -(&g * c.df_dp + &hzd * c.df_dpd);
        let dfdzd = -&g * c.df_dpd;
        let mut out = DMatrix::zeros(m, 2 * m);
        out.view_mut((0, 0), (m, m)).copy_from(&(&h * c.force + &g * dfdz.transpose()));
        out.view_mut((0, m), (m, m)).copy_from(&(&g * dfdzd.transpose()));
        Some(out)
    }

    pub(super) fn fill_jacobian(&self, t: f64, y: &DVector<f64>, jac: &mut DMatrix<f64>) -> Result<(), String> {
        let n = self.n();
        let m = n + 1;
        let model = &self.model;
        let beam = &model.beam;
        let (z, zd) = self.coords(t, y);
        let c = self.contact_point(&z, &zd);
        let dqc = self.contact_force_jacobian(&z, &zd, &c);
        jac.fill(0.0);
        match model.prescribed() {
            None => {
                // d z''/d(z, z') without contact, then the contact's share:
                // J^-1 (dQ_c - dJ/dz (z''_full - z''_free)); only J_00 depends on B.
                let mut a = beam.acceleration_jacobian(&z, &zd, self.torque)?;
                if let Some(dq) = dqc {
                    let qc = beam.contact_generalized_force(&z, &model.surface.as_ref().expect("a surface").plane, c.force);
                    let delta = beam.solve_mass_vector(&z, &qc)?;
                    let mdb = &model.m_minus_d * z.rows(1, n);
                    let mut extra = dq;
                    for k in 0..n {
                        extra[(0, 1 + k)] -= 2.0 * mdb[k] * delta[0];
                    }
                    a += beam.solve_mass(&z, &extra)?;
                }
                for i in 0..m {
                    jac[(i, m + i)] = 1.0;
                }
                jac.view_mut((m, 0), (m, 2 * m)).copy_from(&a);
            }
            Some(_) => {
                // M B'' = theta'^2 (M - D) B - K B + g sin(theta) S B - C B' + (const) + Q_c,B.
                let (sn, thd) = (z[0].sin(), zd[0]);
                let mut db = &model.m_minus_d * (thd * thd) - &beam.k + &model.s_geo * (beam.params.gravity * sn);
                let mut dbd = -&beam.damping;
                if let Some(dq) = dqc {
                    db += dq.view((1, 1), (n, n));
                    dbd += dq.view((1, m + 1), (n, n));
                }
                for i in 0..n {
                    jac[(i, n + i)] = 1.0;
                }
                jac.view_mut((n, 0), (n, n)).copy_from(&model.m_chol.solve(&db));
                jac.view_mut((n, n), (n, n)).copy_from(&model.m_chol.solve(&dbd));
            }
        }
        Ok(())
    }
}

impl ImplicitSystem for Phase {
    fn dim(&self) -> usize {
        Phase::dim(self)
    }

    fn rhs(&mut self, t: f64, y: &DVector<f64>, dy: &mut DVector<f64>) {
        if self.fill_rhs(t, y, dy).is_err() {
            // J(z) lost definiteness: the integrator sees a non-finite value.
            dy.fill(f64::NAN);
        }
    }

    fn jacobian(&mut self, t: f64, y: &DVector<f64>, jac: &mut DMatrix<f64>) -> bool {
        if self.fill_jacobian(t, y, jac).is_err() {
            jac.fill(f64::NAN);
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinds::rotating::spec::RotatingSpec;

    fn model(hub: &str, damping: &str) -> Arc<RotatingModel> {
        let text = format!(
            r#"{{ "name": "t", "beam": {{ "length": 1.0, "mass_per_length": 0.86884, "bending_stiffness": 541.26 }},
            "n_modes": 3, "hub_inertia": 0.05, "hub_radius": 0.05, "gravity": 9.81, "modal_damping": 0.01,
            "surface": {{ "normal": [0.2, -1], "point": [1, 0], "law": {{ "type": "hertz", "K": 1e8, {damping} }} }},
            "hub": {hub} }}"#
        );
        Arc::new(RotatingModel::new(&RotatingSpec::from_json(&text).unwrap()).unwrap())
    }

    #[test]
    fn jacobian_matches_finite_differences_in_contact() {
        let cases = [
            ("\"torque\"", "\"damping\": \"lankarani_nikravesh\", \"e\": 0.7"),
            ("\"torque\"", "\"C\": 40"),
            ("{\"prescribed\": {\"type\": \"spin_up\", \"omega_s\": 6, \"T\": 3}}", "\"damping\": \"hunt_crossley\", \"e\": 0.5"),
        ];
        for (hub, damping) in cases {
            let m = model(hub, damping);
            let mut phase = Phase { model: m.clone(), contact: Contact::Pressed, onset_speed: 0.8, torque: 0.3 };
            let dim = phase.dim();
            let n = phase.n();
            // A state 1e-4 m inside the plane, moving in.
            let mut y = DVector::zeros(dim);
            let (theta, b) = (0.15, [2e-3, -4e-4, 1e-4]);
            let t = 1.3;
            if phase.prescribed() {
                y.rows_mut(0, n).copy_from_slice(&b);
                y.rows_mut(n, n).copy_from_slice(&[0.3, -0.2, 0.1]);
            } else {
                y[0] = theta;
                y.rows_mut(1, n).copy_from_slice(&b);
                y[n + 1] = 2.0;
                y.rows_mut(n + 2, n).copy_from_slice(&[0.3, -0.2, 0.1]);
            }
            // Shift the plane's point so that gamma = 1e-4 here.
            let (z, zd) = phase.coords(t, &y);
            let gap = m.beam.plane_gap(&z, &m.surface.as_ref().unwrap().plane);
            let mut mm = (*m).clone();
            let s = mm.surface.as_mut().unwrap();
            let (nrm, d) = (s.plane.normal, gap + 1e-4);
            s.plane.point = [s.plane.point[0] + nrm[0] * d, s.plane.point[1] + nrm[1] * d];
            phase.model = Arc::new(mm);
            let c = phase.contact_point(&z, &zd);
            assert!((c.penetration - 1e-4).abs() < 1e-12 && c.force > 0.0, "{c:?}");
            let mut jac = DMatrix::zeros(dim, dim);
            assert!(phase.jacobian(t, &y, &mut jac));
            let (mut fp, mut fm) = (DVector::zeros(dim), DVector::zeros(dim));
            let rows = phase.extras();
            for k in 0..rows {
                let h = 1e-7 * y[k].abs().max(1e-3);
                let (mut yp, mut ym) = (y.clone(), y.clone());
                yp[k] += h;
                ym[k] -= h;
                phase.rhs(t, &yp, &mut fp);
                phase.rhs(t, &ym, &mut fm);
                let col = (&fp - &fm).rows(0, rows) / (2.0 * h);
                let err = (&col - jac.view((0, k), (rows, 1))).norm() / col.norm().max(1.0);
                assert!(err < 1e-6, "{hub} {damping} column {k}: {err:e}\n{col}\n{}", jac.view((0, k), (rows, 1)));
            }
        }
    }
}
