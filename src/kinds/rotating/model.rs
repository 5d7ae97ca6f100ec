//! A validated scene turned into numbers: the beam's equations
//! ([`RotatingBeam`]), the surface, the hub drive and the initial state.

use std::f64::consts::TAU;

use nalgebra::{Cholesky, DMatrix, DVector, Dyn};

use super::frozen::FrozenMemo;
use super::spec::{HubDrive, OrderSpec, Profile, RotatingSpec};
use crate::contact::Law;
use crate::structure::rotating::{DimensionlessIntegrals, Order, Plane, RotatingBeam, RotatingBeamParams};

/// The plane and its law.
#[derive(Clone, Debug)]
pub struct Surface {
    pub plane: Plane,
    pub law: Law,
}

/// Kane, Ryan & Banerjee's spin-up profile.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpinUp {
    pub theta0: f64,
    pub omega_s: f64,
    pub duration: f64,
}

impl SpinUp {
    /// `(theta, theta', theta'')` at `t` (at rest before 0).
    pub fn at(&self, t: f64) -> (f64, f64, f64) {
        let (ws, tt) = (self.omega_s, self.duration);
        let a = TAU / tt;
        if t <= 0.0 {
            (self.theta0, 0.0, 0.0)
        } else if t < tt {
            let th = ws / tt * (0.5 * t * t + ((a * t).cos() - 1.0) / (a * a));
            (self.theta0 + th, ws / tt * (t - (a * t).sin() / a), ws / tt * (1.0 - (a * t).cos()))
        } else {
            (self.theta0 + 0.5 * ws * tt + ws * (t - tt), ws, 0.0)
        }
    }
}

/// A harmonic swing `theta(t) = theta0 + A sin(Omega t)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Swing {
    pub theta0: f64,
    pub amplitude: f64,
    pub omega: f64,
}

impl Swing {
    /// `(theta, theta', theta'')` at `t`.
    pub fn at(&self, t: f64) -> (f64, f64, f64) {
        let (s, c) = (self.omega * t).sin_cos();
        let (a, w) = (self.amplitude, self.omega);
        (self.theta0 + a * s, a * w * c, -a * w * w * s)
    }
}

/// A prescribed hub motion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HubMotion {
    SpinUp(SpinUp),
    Swing(Swing),
}

impl HubMotion {
    /// `(theta, theta', theta'')` at `t`.
    pub fn at(&self, t: f64) -> (f64, f64, f64) {
        match self {
            HubMotion::SpinUp(p) => p.at(t),
            HubMotion::Swing(p) => p.at(t),
        }
    }

    /// A bound on `|theta'|` over `[t0, t1]` (the spin-up's speed is
    /// monotone, a swing's at most `A Omega`).
    pub fn speed_bound(&self, t0: f64, t1: f64) -> f64 {
        match self {
            HubMotion::SpinUp(p) => p.at(t0).1.abs().max(p.at(t1).1.abs()),
            HubMotion::Swing(p) => (p.amplitude * p.omega).abs(),
        }
    }

    /// The motion's period, if it is periodic (a swing's `2 pi / Omega`).
    pub fn period(&self) -> Option<f64> {
        match self {
            HubMotion::SpinUp(_) => None,
            HubMotion::Swing(p) => Some(TAU / p.omega),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Drive {
    Torque,
    Prescribed(HubMotion),
}

/// What a model computed that holds for other scenes too, found by
/// content: handed from a component's model to the next one when its
/// values change ([`crate::kind::Scene::shared`]).
#[derive(Clone, Debug)]
pub struct Shared {
    /// A function of the number of modes.
    pub integrals: DimensionlessIntegrals,
    /// The frozen linear parts, with the beam's parameters and whether the
    /// hub was prescribed: what they are a function of.
    pub frozen: (RotatingBeamParams, bool, FrozenMemo),
}

#[derive(Clone, Debug)]
pub struct RotatingModel {
    pub spec: RotatingSpec,
    pub beam: RotatingBeam,
    pub surface: Option<Surface>,
    pub drive: Drive,
    /// The order-dependent matrices the equations use: `M - D` (or `M`),
    /// the tip shortening `C_L` (or 0), the gravity stiffness `S` (or 0).
    pub m_minus_d: DMatrix<f64>,
    pub c_tip: DMatrix<f64>,
    pub s_geo: DMatrix<f64>,
    pub m_chol: Cholesky<f64, Dyn>,
    /// `theta, B, theta', B'` at the start.
    pub initial_z: DVector<f64>,
    pub initial_zd: DVector<f64>,
    /// The exponential integrator's frozen linear parts built so far.
    pub frozen: FrozenMemo,
}

impl RotatingModel {
    /// The model of a scene; the error (a scene that cannot form one) names the field.
    pub fn new(spec: &RotatingSpec) -> Result<Self, String> {
        Self::new_with(spec, None)
    }

    /// [`Self::new`] with what a model built before holds for this one
    /// ([`Shared`]): its modal integrals (when they are for as many modes:
    /// a pure function of that number) and its frozen linear parts (when
    /// the beam's parameters and the hub's kind are the same: a pure
    /// function of them and the grid point).
    pub fn new_with(spec: &RotatingSpec, earlier: Option<&Shared>) -> Result<Self, String> {
        spec.validate()?;
        let n = spec.n_modes;
        let (mu, ei) = spec.section();
        let order = match spec.order {
            OrderSpec::First => Order::First,
            OrderSpec::Zeroth => Order::Zeroth,
        };
        let params = RotatingBeamParams {
            length: spec.beam.length,
            mass_per_length: mu,
            bending_stiffness: ei,
            hub_inertia: spec.hub_inertia,
            hub_radius: spec.hub_radius,
            gravity: spec.gravity,
            modal_damping: vec![spec.modal_damping],
            n_modes: n,
            order,
        };
        let beam = RotatingBeam::new_with(params, earlier.map(|e| &e.integrals)).map_err(|e| format!("rotating scene '{}': {e}", spec.name))?;
        let surface = match &spec.surface {
            None => None,
            Some(s) => Some(Surface {
                plane: Plane::new(s.normal, s.point).map_err(|e| format!("rotating scene '{}': surface: {e}", spec.name))?,
                law: s.law.clone(),
            }),
        };
        let drive = match spec.hub {
            HubDrive::Torque => Drive::Torque,
            HubDrive::Prescribed(Profile::SpinUp { omega_s, duration }) => {
                Drive::Prescribed(HubMotion::SpinUp(SpinUp { theta0: spec.initial.theta, omega_s, duration }))
            }
            HubDrive::Prescribed(Profile::Harmonic { amplitude, omega }) => {
                Drive::Prescribed(HubMotion::Swing(Swing { theta0: spec.initial.theta, amplitude, omega }))
            }
        };
        let (m_minus_d, c_tip, s_geo) = match order {
            Order::First => (&beam.m - &beam.d, beam.c_l.clone(), beam.s.clone()),
            Order::Zeroth => (beam.m.clone(), DMatrix::zeros(n, n), DMatrix::zeros(n, n)),
        };
        let m_chol = Cholesky::new(beam.m.clone()).ok_or_else(|| format!("rotating scene '{}': modal mass matrix not positive definite", spec.name))?;
        let vec_or_zero = |v: &Vec<f64>| if v.is_empty() { DVector::zeros(n) } else { DVector::from_column_slice(v) };
        let (b, bd) = (vec_or_zero(&spec.initial.b), vec_or_zero(&spec.initial.b_dot));
        let mut initial_z = DVector::zeros(n + 1);
        let mut initial_zd = DVector::zeros(n + 1);
        initial_z[0] = spec.initial.theta;
        initial_zd[0] = spec.initial.theta_dot;
        initial_z.rows_mut(1, n).copy_from(&b);
        initial_zd.rows_mut(1, n).copy_from(&bd);
        let prescribed = matches!(drive, Drive::Prescribed(_));
        let frozen = match earlier {
            Some(Shared { frozen: (params, was_prescribed, memo), .. }) if *params == beam.params && *was_prescribed == prescribed => memo.clone(),
            _ => FrozenMemo::default(),
        };
        Ok(RotatingModel { spec: spec.clone(), beam, surface, drive, m_minus_d, c_tip, s_geo, m_chol, initial_z, initial_zd, frozen })
    }

    /// What a model built after this one can take over ([`Shared`]).
    pub fn shared(&self) -> Shared {
        Shared { integrals: self.beam.hat.clone(), frozen: (self.beam.params.clone(), self.prescribed().is_some(), self.frozen.clone()) }
    }

    pub fn n_modes(&self) -> usize {
        self.beam.n_modes()
    }

    pub fn prescribed(&self) -> Option<HubMotion> {
        match self.drive {
            Drive::Prescribed(p) => Some(p),
            Drive::Torque => None,
        }
    }

    /// Shortest modal period (non-rotating), s.
    pub fn shortest_period(&self) -> f64 {
        TAU / self.beam.omega(self.n_modes())
    }

    /// Radius of the tip, `R + L`.
    pub fn tip_radius(&self) -> f64 {
        self.beam.params.hub_radius + self.beam.params.length
    }

    /// `d gap / dz` and its Hessian at `z` (see the module doc of
    /// [`crate::structure::rotating`]): with `n' = A^T n = (l_x, l_y)`,
    /// `X = R + L + u_L`, `Y = v_L`, `gap = l_x X + l_y Y - n . p0`.
    pub fn gap_gradient_hessian(&self, z: &DVector<f64>, plane: &Plane) -> (DVector<f64>, DMatrix<f64>) {
        let n = self.n_modes();
        let b = z.rows(1, n);
        let cb = &self.c_tip * b;
        let x = self.tip_radius() - 0.5 * b.dot(&cb);
        let y = self.beam.w.dot(&b);
        let (sn, cs) = z[0].sin_cos();
        let [nx, ny] = plane.normal;
        let (lx, ly) = (cs * nx + sn * ny, -sn * nx + cs * ny);
        let mut g = DVector::zeros(n + 1);
        g[0] = ly * x - lx * y;
        g.rows_mut(1, n).copy_from(&(&cb * (-lx) + &self.beam.w * ly));
        let mut h = DMatrix::zeros(n + 1, n + 1);
        h[(0, 0)] = -lx * x - ly * y;
        let cross = &cb * (-ly) - &self.beam.w * lx;
        h.view_mut((0, 1), (1, n)).copy_from(&cross.transpose());
        h.view_mut((1, 0), (n, 1)).copy_from(&cross);
        h.view_mut((1, 1), (n, n)).copy_from(&(&self.c_tip * (-lx)));
        (g, h)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinds::rotating::spec::RotatingSpec;

    fn spec(order: &str) -> RotatingSpec {
        RotatingSpec::from_json(&format!(
            r#"{{ "name": "t", "beam": {{ "length": 1.2, "mass_per_length": 0.9, "bending_stiffness": 300 }},
            "n_modes": 4, "order": "{order}", "hub_inertia": 0.3, "hub_radius": 0.1,
            "surface": {{ "normal": [0.3, -1], "point": [1, 0.2], "law": {{ "type": "hertz", "K": 1e9 }} }} }}"#
        ))
        .unwrap()
    }

    #[test]
    fn gap_gradient_and_hessian_match_finite_differences() {
        for order in ["first", "zeroth"] {
            let m = RotatingModel::new(&spec(order)).unwrap();
            let plane = m.surface.as_ref().unwrap().plane;
            let z = DVector::from_vec(vec![0.4, 0.02, -0.01, 0.004, 0.001]);
            let (g, h) = m.gap_gradient_hessian(&z, &plane);
            let g_ref = m.beam.contact_generalized_force(&z, &plane, 1.0);
            assert!((&g - &g_ref).norm() < 1e-14, "{order}: {g} {g_ref}");
            let d = 1e-6;
            for k in 0..5 {
                let e = DVector::from_fn(5, |i, _| if i == k { d } else { 0.0 });
                let col = (m.gap_gradient_hessian(&(&z + &e), &plane).0 - m.gap_gradient_hessian(&(&z - &e), &plane).0) / (2.0 * d);
                assert!((&col - h.column(k)).norm() < 1e-8 * (1.0 + col.norm()), "{order} column {k}: {col} vs {}", h.column(k));
            }
        }
    }

    #[test]
    fn spin_up_profile_is_consistent() {
        let p = SpinUp { theta0: 0.3, omega_s: 6.0, duration: 15.0 };
        for t in [0.5, 3.0, 7.5, 14.9, 15.0, 20.0] {
            let h = 1e-5;
            let (a, b) = (p.at(t - h), p.at(t + h));
            let (_, thd, thdd) = p.at(t);
            assert!(((b.0 - a.0) / (2.0 * h) - thd).abs() < 1e-8, "theta' at {t}");
            assert!(((b.1 - a.1) / (2.0 * h) - thdd).abs() < 1e-6, "theta'' at {t}");
        }
        assert_eq!(p.at(0.0), (0.3, 0.0, 0.0));
        assert_eq!(p.at(30.0).1, 6.0);
    }

    #[test]
    fn swing_profile_is_consistent() {
        let p = Swing { theta0: -0.2, amplitude: 0.3, omega: 12.0 };
        for t in [0.0, 0.05, 0.13, 0.4, 1.7] {
            let h = 1e-5;
            let (a, b) = (p.at(t - h), p.at(t + h));
            let (_, thd, thdd) = p.at(t);
            assert!(((b.0 - a.0) / (2.0 * h) - thd).abs() < 1e-8, "theta' at {t}");
            assert!(((b.1 - a.1) / (2.0 * h) - thdd).abs() < 1e-6, "theta'' at {t}");
        }
        assert_eq!(p.at(0.0), (-0.2, 0.3 * 12.0, 0.0));
        assert_eq!(HubMotion::Swing(p).period(), Some(TAU / 12.0));
    }
}
