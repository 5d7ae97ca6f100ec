//! The rotating beam's equations in the coordinates of a frozen linear
//! part, for the exponential integrator's remainder.
//!
//! With `z = [theta; B] = Phi p` (`Phi_0` the hub's row, `Phi_B` the
//! modes') and `Psi = Phi^-1` (`Psi_0` the hub's column, `Psi_B` the
//! modes'), the remainder the integrator collocates is `g = Psi z'' +
//! Omega^2 p + c p'` ([`crate::solve::exponential`]). By the hub's Schur
//! complement (the module doc of [`super`]), `z'' = [theta''; M^-1 Q_B -
//! a theta'']` with `a = M^-1 Gamma`, so
//!
//! `Psi z'' = u theta'' + W Q_B`, `u = Psi_0 - Psi_B a`, `W = Psi_B M^-1`,
//!
//! (a prescribed hub: `z = [theta(t); Phi p]`, `M B'' = Q_B - Gamma
//! theta''`, so `Psi B'' = u theta'' + W Q_B` with `u = -W Gamma`, `W =
//! Psi M^-1`, and no hub equation),
//!
//! and every term of `Q_B` and of the hub's equation is linear or
//! quadratic in `p` and `p'` through products fixed with the frozen part:
//! `b.(M - D) b = p.(G p)` and `b'.(M - D) b = p'.(G p)` with `G =
//! Phi_B^T (M - D) Phi_B`; likewise the damping, gravity's `S` and the
//! tip's shortening `C_L`. Since `Phi^T J0 Phi = I`, `Psi = Phi^T J0`:
//! `Psi_B = Phi_0^T Gamma^T + Phi_B^T M` (`Psi_B = Phi^T M` for a
//! prescribed hub), so `W = Phi_B^T + Phi_0^T a^T` and
//!
//! `W X b = Phi_B^T X Phi_B p + Phi_0^T (a . X b)` for `X = M - D, S,
//! C_L`:
//!
//! `H p = W (M - D) b = G p + Phi_0^T (a . (M - D) b)`, the hub's
//! `a . X b` being terms its equation needs anyway.
//!
//! The frozen part's own terms cancel in closed form. It was frozen at a
//! hub speed `theta0'` and angle `theta0`: `K0 = K - theta0'^2 (M - D) -
//! g sin(theta0) S` with the undeflected `J` (or `M`), so `Omega^2 p = W K0
//! b - u kappa.p - L p`, `kappa.p = a . K0 b / (J_h + J_b - Gamma . a)`
//! (`kappa = 0` for a prescribed hub), with `L` what `diag(Omega^2)` leaves
//! of the frozen part: a clamped negative eigenvalue, and the eigensolver's
//! error. Hence
//!
//! `g = u (theta'' - kappa.p) + (theta'^2 - theta0'^2) H p + L p + g (sin
//! theta - sin theta0) W S b - g cos theta W sigma + (contact, damping)`:
//!
//! what the linear part leaves out and nothing it holds. `L`'s entries
//! are about 1e-16 of the largest `omega^2`, so only the slow modes' rows
//! matter beside its diagonal. Per evaluation that is one `(N + 1)^2`
//! product in free flight (`G p`) and a few rows of `L`, instead of six
//! (`Phi p`, `Phi p'`, `(M - D) b`, `K b`, `M^-1 Q_B`, `Psi z''`); a
//! pressed contact adds one (`Phi_B^T C_L Phi_B p`), gravity one and
//! damping one.

use nalgebra::DMatrix;

use super::{mat_vec, ContactTerms, Plane, RotatingBeam, TipFrame};
use crate::solve::matvec::mat_vecs;

/// How the hub moves: a torque drives it (its angle among the modal
/// coordinates), or its angle, rate and acceleration are given.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Hub {
    Torque(f64),
    Prescribed { theta: f64, theta_dot: f64, theta_ddot: f64 },
}

/// A frozen linear part (the exponential integrator's) as the remainder
/// needs it.
#[derive(Clone, Copy, Debug)]
pub struct FrozenPart<'a> {
    /// `z = Phi p`, `p = Psi z` (`z = [theta; B]` for a torque-driven hub,
    /// `z = B` for a prescribed one).
    pub phi: &'a DMatrix<f64>,
    pub psi: &'a DMatrix<f64>,
    /// Per mode `omega^2` and the damping `c`.
    pub omega2: &'a [f64],
    pub damping: &'a [f64],
    /// The hub speed squared and `sin(theta)` the frozen stiffness `K0 =
    /// K - theta0'^2 (M - D) - g sin(theta0) S` has.
    pub theta_dot_sq: f64,
    pub sin_theta: f64,
    pub prescribed: bool,
}

/// Products of one frozen linear part with the beam's matrices
/// (column-major `m x m`, `m` the modal coordinates: `N + 1` for a
/// torque-driven hub, `N` for a prescribed one).
#[derive(Clone, Debug)]
pub struct ModalEquations {
    products: FrozenProducts,
    scratch: [Vec<f64>; 5],
}

/// What [`ModalEquations`] holds beside its working arrays.
#[derive(Clone, Debug)]
struct FrozenProducts {
    m: usize,
    prescribed: bool,
    /// `Phi_0` (the hub angle's row; empty when prescribed), `Phi_B^T w`, `Phi_B^T sigma`.
    phi_hub: Vec<f64>,
    phi_w: Vec<f64>,
    phi_sigma: Vec<f64>,
    /// `G` (module doc).
    g_md: DMatrix<f64>,
    /// The frozen part: `theta0'^2`, `sin theta0`, `kappa`; `L` (module
    /// doc): the slow modes' rows, every mode's diagonal.
    frozen_w2: f64,
    frozen_sin: f64,
    kappa: Vec<f64>,
    left_slow: DMatrix<f64>,
    left_diagonal: Vec<f64>,
    /// `diag(c) - W C Phi_B` (`None`: no damping).
    e_c: Option<DMatrix<f64>>,
    /// `u`; `Phi_B^T X^T a` for `X = M - D, K, C, S, C_L` (the hub's
    /// `a . Q_B` term by term); `a . sigma`, `a . w`.
    u: Vec<f64>,
    a_md: Vec<f64>,
    a_k: Vec<f64>,
    a_c: Vec<f64>,
    a_s: Vec<f64>,
    a_l: Vec<f64>,
    a_sigma: f64,
    a_w: f64,
    /// Gravity: `Phi_B^T S Phi_B`, `W sigma`.
    gravity: Option<(DMatrix<f64>, Vec<f64>)>,
    /// The tip: `Phi_B^T C_L Phi_B`; `W w`.
    tip: DMatrix<f64>,
    tip_w: Vec<f64>,
    /// `J_h + J_b - Gamma . M^-1 Gamma`: the hub's Schur complement at `B = 0`.
    schur_0: f64,
}

impl RotatingBeam {
    /// The products of the frozen linear part `frozen`.
    pub fn modal_equations(&self, frozen: FrozenPart<'_>) -> ModalEquations {
        let FrozenPart { phi, psi, omega2, damping: c, theta_dot_sq: frozen_w2, sin_theta: frozen_sin, prescribed } = frozen;
        let n = self.n_modes();
        let m = if prescribed { n } else { n + 1 };
        assert!(
            phi.shape() == (m, m) && psi.shape() == (m, m) && omega2.len() == m && c.len() == m,
            "modal_equations: {m} modal coordinates expected"
        );
        let hub = m - n;
        let phi_b = phi.rows(hub, n).into_owned();
        let psi_b = psi.columns(hub, n).into_owned();
        let w = &psi_b * &self.m_inv;
        let a = &self.m_inv_gamma;
        let pt = phi_b.transpose();
        let quad = |x: &DMatrix<f64>| &pt * (x * &phi_b);
        let proj = |x: &DMatrix<f64>| &w * (x * &phi_b);
        let along_a = |x: &DMatrix<f64>| (&pt * (x.transpose() * a)).as_slice().to_vec();
        let mut e_c = (!self.undamped).then(|| -proj(&self.damping));
        for k in 0..m {
            if let Some(e) = e_c.as_mut() {
                e[(k, k)] += c[k];
            }
        }
        let e_c = e_c.or_else(|| c.iter().any(|x| *x != 0.0).then(|| DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(c))));
        let u = if prescribed { -(&w * &self.gamma) } else { psi.column(0) - &psi_b * a };
        let gravity = (self.params.gravity != 0.0).then(|| (quad(&self.s_geo), (&w * &self.sigma).as_slice().to_vec()));
        let (a_md, a_k, a_s) = (along_a(&self.m_minus_d), along_a(&self.k), along_a(&self.s_geo));
        let schur_0 = self.params.hub_inertia + self.j_b - self.gamma_m_inv_gamma;
        let kappa = if prescribed {
            vec![0.0; m]
        } else {
            (0..m).map(|k| (a_k[k] - frozen_w2 * a_md[k] - self.params.gravity * frozen_sin * a_s[k]) / schur_0).collect()
        };
        // `L = diag(Omega^2) - (W K0 Phi_B - u kappa^T)` (module doc). Its
        // entries, about 1e-16 of the largest `omega^2`, are not small
        // beside a slow mode's (1e-10 of the first's at 32 modes: a shift
        // of its frequency and a coupling the run would accumulate), so
        // the slow modes' rows are kept whole, the others' diagonals.
        let k0_phi = (&self.k - &self.m_minus_d * frozen_w2 - &self.s_geo * (self.params.gravity * frozen_sin)) * &phi_b;
        let own = &w * &k0_phi;
        let left = DMatrix::from_fn(m, m, |i, j| if i == j { omega2[i] } else { 0.0 } - (own[(i, j)] - u[i] * kappa[j]));
        let matters = |i: usize| (0..m).any(|j| j != i && left[(i, j)].abs() > LEFT_RELATIVE * omega2[i]);
        let slow_rows = (0..m).rev().find(|&i| matters(i)).map_or(0, |i| i + 1);
        let left_slow = left.rows(0, slow_rows).into_owned();
        let left_diagonal: Vec<f64> = (0..m).map(|k| left[(k, k)]).collect();
        let products = FrozenProducts {
            m,
            prescribed,
            phi_hub: if prescribed { Vec::new() } else { phi.row(0).iter().copied().collect() },
            phi_w: (&pt * &self.w).as_slice().to_vec(),
            phi_sigma: (&pt * &self.sigma).as_slice().to_vec(),
            g_md: quad(&self.m_minus_d),
            frozen_w2,
            frozen_sin,
            kappa,
            left_slow,
            left_diagonal,
            e_c,
            u: u.as_slice().to_vec(),
            a_md,
            a_k,
            a_c: along_a(&self.damping),
            a_s,
            a_l: along_a(&self.c_tip),
            a_sigma: a.dot(&self.sigma),
            a_w: a.dot(&self.w),
            gravity,
            tip: quad(&self.c_tip),
            tip_w: (&w * &self.w).as_slice().to_vec(),
            schur_0,
        };
        ModalEquations { products, scratch: Default::default() }
    }
}

/// A row of `L` (module doc) is kept whole when an entry off its
/// diagonal exceeds this share of the row's `omega^2`.
const LEFT_RELATIVE: f64 = 1e-14;

/// The remainder's dot products: `Phi_0 . p`, `Phi_0 . p'` (0 for a
/// prescribed hub), `a_md . p`, `a_k . p`, `kappa . p`, `p . G p`, `p' .
/// G p`.
struct Sums {
    hub: f64,
    hub_rate: f64,
    a_md: f64,
    a_k: f64,
    kappa: f64,
    p_gp: f64,
    pd_gp: f64,
}

impl Sums {
    /// Seven running sums in one pass, each in the order of `k` (the
    /// bits of seven calls of [`dot`]; the independent sums overlap).
    #[inline(always)]
    fn of(phi_hub: Option<&[f64]>, a_md: &[f64], a_k: &[f64], kappa: &[f64], p: &[f64], pd: &[f64], gp: &[f64]) -> Self {
        let mut s = Sums { hub: 0.0, hub_rate: 0.0, a_md: 0.0, a_k: 0.0, kappa: 0.0, p_gp: 0.0, pd_gp: 0.0 };
        for k in 0..p.len() {
            if let Some(row) = phi_hub {
                s.hub += row[k] * p[k];
                s.hub_rate += row[k] * pd[k];
            }
            s.a_md += a_md[k] * p[k];
            s.a_k += a_k[k] * p[k];
            s.kappa += kappa[k] * p[k];
            s.p_gp += p[k] * gp[k];
            s.pd_gp += gp[k] * pd[k];
        }
        s
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

impl ModalEquations {
    /// The tip in the hub's frame at `(p, p')`, `lp` given room for
    /// `Phi_B^T C_L Phi_B p`.
    fn tip_frame((tip, phi_w): (&DMatrix<f64>, &[f64]), beam: &RotatingBeam, p: &[f64], pd: &[f64], sn: f64, cs: f64, lp: &mut [f64]) -> TipFrame {
        mat_vec(tip.as_slice(), p, lp);
        Self::tip_frame_of((lp, phi_w), beam, p, pd, sn, cs)
    }

    /// The tip in the hub's frame from `lp = Phi_B^T C_L Phi_B p`.
    fn tip_frame_of((lp, phi_w): (&[f64], &[f64]), beam: &RotatingBeam, p: &[f64], pd: &[f64], sn: f64, cs: f64) -> TipFrame {
        TipFrame {
            x: beam.params.hub_radius + beam.params.length - 0.5 * dot(p, lp),
            y: dot(phi_w, p),
            xd: -dot(lp, pd),
            yd: dot(phi_w, pd),
            sn,
            cs,
        }
    }

    /// The penetration of `plane` (`-gap`) and its rate at the modal state
    /// `(p, p')` for the hub's motion `hub`, as
    /// [`RotatingBeam::plane_penetration`] gives them at `z = Phi p`
    /// (one product instead of three); `lp` is room for `m` values.
    pub fn penetration(&self, beam: &RotatingBeam, p: &[f64], pd: &[f64], hub: Hub, plane: &Plane, lp: &mut Vec<f64>) -> (f64, f64) {
        let (theta, thd) = match hub {
            Hub::Torque(_) => (dot(&self.products.phi_hub, p), dot(&self.products.phi_hub, pd)),
            Hub::Prescribed { theta, theta_dot, .. } => (theta, theta_dot),
        };
        let (sn, cs) = theta.sin_cos();
        lp.resize(self.products.m, 0.0);
        Self::tip_frame((&self.products.tip, &self.products.phi_w), beam, p, pd, sn, cs, lp).penetration(thd, plane)
    }

    /// `g = Psi z'' + Omega^2 p + c p'` at `(p, p')` for the hub's
    /// motion `hub` (of the kind the products were made for), with the
    /// normal force on the tip along `plane` (`force(penetration, rate)`,
    /// `None`: no contact), as [`RotatingBeam::accelerations_in_place`]
    /// and [`RotatingBeam::prescribed_accelerations`] give `z''`; an error
    /// when `J` is not positive definite.
    pub fn remainder(
        &mut self,
        beam: &RotatingBeam,
        p: &[f64],
        pd: &[f64],
        hub: Hub,
        contact: Option<(&Plane, &mut dyn FnMut(f64, f64) -> f64)>,
        g: &mut [f64],
    ) -> Result<ContactTerms, String> {
        let m = self.products.m;
        assert!(p.len() == m && pd.len() == m && g.len() == m, "modal remainder: {m} coordinates");
        let ModalEquations { products: this, scratch } = self;
        // The rooms keep the batch's length ([`Self::remainders`]): cut
        // to one point's and grown again, they were zeroed at each batch.
        for v in scratch.iter_mut() {
            if v.len() < m {
                v.resize(m, 0.0);
            }
        }
        let [gp, hp, lp, sp, tmp] = scratch;
        let (gp, hp, lp, sp, tmp) = (&mut gp[..m], &mut hp[..m], &mut lp[..m], &mut sp[..m], &mut tmp[..m]);
        mat_vec(this.g_md.as_slice(), p, gp);
        let slow = this.left_slow.nrows();
        mat_vec(this.left_slow.as_slice(), p, &mut g[..slow]);
        if let Some((s_geo, _)) = &this.gravity {
            mat_vec(s_geo.as_slice(), p, sp);
        }
        if contact.is_some() {
            mat_vec(this.tip.as_slice(), p, lp);
        }
        if let Some(e_c) = &this.e_c {
            mat_vec(e_c.as_slice(), pd, tmp);
        }
        let products = PointProducts { gp, lp, sp, tmp };
        this.finish(beam, &ModalPoint { p, pd, hub }, products, hp, contact, g).ok_or_else(not_positive_definite)
    }

    /// [`Self::remainder`] at several points (a step's nodes), the same
    /// bits point by point: the products with the `m x m` matrices go
    /// through each matrix once for all points
    /// ([`crate::solve::matvec::mat_vecs`]). `terms[i]`: point `i`'s
    /// contact terms, `None` where `J` is not positive definite (its `g`
    /// then unset).
    pub fn remainders(
        &mut self,
        beam: &RotatingBeam,
        points: &[ModalPoint<'_>],
        mut contact: Option<(&Plane, &mut dyn FnMut(f64, f64) -> f64)>,
        gs: &mut [&mut [f64]],
        terms: &mut [Option<ContactTerms>],
    ) {
        let (m, count) = (self.products.m, points.len());
        assert!(
            gs.len() == count && terms.len() == count && points.iter().zip(gs.iter()).all(|(x, g)| x.p.len() == m && x.pd.len() == m && g.len() == m),
            "modal remainder: {m} coordinates at each point"
        );
        for ((points, gs), terms) in points.chunks(POINTS).zip(gs.chunks_mut(POINTS)).zip(terms.chunks_mut(POINTS)) {
            let contact = contact.as_mut().map(|(plane, force)| (*plane, &mut **force as &mut dyn FnMut(f64, f64) -> f64));
            self.remainders_of_chunk(beam, points, contact, gs, terms);
        }
    }

    /// [`Self::remainders`] at up to [`POINTS`] points (no allocation).
    fn remainders_of_chunk(
        &mut self,
        beam: &RotatingBeam,
        points: &[ModalPoint<'_>],
        mut contact: Option<(&Plane, &mut dyn FnMut(f64, f64) -> f64)>,
        gs: &mut [&mut [f64]],
        terms: &mut [Option<ContactTerms>],
    ) {
        let (m, count) = (self.products.m, points.len());
        let ModalEquations { products: this, scratch } = self;
        for v in scratch.iter_mut() {
            v.resize(m * POINTS, 0.0);
        }
        let [gp, hp, lp, sp, tmp] = scratch;
        let ps: [&[f64]; POINTS] = std::array::from_fn(|i| points.get(i).map_or(&[][..], |x| x.p));
        let pds: [&[f64]; POINTS] = std::array::from_fn(|i| points.get(i).map_or(&[][..], |x| x.pd));
        let (ps, pds) = (&ps[..count], &pds[..count]);
        // Room for each point's product, in `v`.
        fn rows_of(v: &mut [f64], m: usize) -> [&mut [f64]; POINTS] {
            let mut rows = v.chunks_exact_mut(m);
            std::array::from_fn(|_| rows.next().unwrap_or_default())
        }
        // The products first, every point's at once.
        mat_vecs(this.g_md.as_slice(), ps, &mut rows_of(gp, m)[..count], -0.0);
        let slow = this.left_slow.nrows();
        {
            let mut g_rows = gs.iter_mut();
            let mut outs: [&mut [f64]; POINTS] = std::array::from_fn(|_| g_rows.next().map_or(Default::default(), |g| &mut g[..slow]));
            mat_vecs(this.left_slow.as_slice(), ps, &mut outs[..count], -0.0);
        }
        if let Some((s_geo, _)) = &this.gravity {
            mat_vecs(s_geo.as_slice(), ps, &mut rows_of(sp, m)[..count], -0.0);
        }
        if contact.is_some() {
            mat_vecs(this.tip.as_slice(), ps, &mut rows_of(lp, m)[..count], -0.0);
        }
        if let Some(e_c) = &this.e_c {
            mat_vecs(e_c.as_slice(), pds, &mut rows_of(tmp, m)[..count], -0.0);
        }
        for (i, ((point, g), terms_i)) in points.iter().zip(gs.iter_mut()).zip(terms.iter_mut()).enumerate() {
            let at = i * m..(i + 1) * m;
            let products = PointProducts { gp: &gp[at.clone()], lp: &lp[at.clone()], sp: &sp[at.clone()], tmp: &tmp[at.clone()] };
            let contact = contact.as_mut().map(|(plane, force)| (*plane, &mut **force as &mut dyn FnMut(f64, f64) -> f64));
            *terms_i = this.finish(beam, point, products, &mut hp[at], contact, g);
        }
    }

}

impl FrozenProducts {
    /// One point's remainder from its products (`g[..slow]` holding `L`'s
    /// slow rows times `p`).
    #[inline(always)]
    fn finish(
        &self,
        beam: &RotatingBeam,
        point: &ModalPoint<'_>,
        products: PointProducts<'_>,
        hp: &mut [f64],
        contact: Option<(&Plane, &mut dyn FnMut(f64, f64) -> f64)>,
        g: &mut [f64],
    ) -> Option<ContactTerms> {
        let m = self.m;
        let ModalPoint { p, pd, hub } = *point;
        let PointProducts { gp, lp, sp, tmp } = products;
        let free_hub = !self.prescribed;
        // The dot products of `p`, `p'` and `G p`, in one pass (each summed
        // in order, as `dot` sums).
        let sums = Sums::of(free_hub.then_some(&self.phi_hub[..]), &self.a_md, &self.a_k, &self.kappa, p, pd, gp);
        let (theta, thd, torque) = match hub {
            Hub::Torque(torque) if free_hub => (sums.hub, sums.hub_rate, torque),
            Hub::Prescribed { theta, theta_dot, .. } if !free_hub => (theta, theta_dot, 0.0),
            _ => panic!("modal remainder: the hub's motion is not of the kind the products were made for"),
        };
        let grav = beam.params.gravity;
        let (sn, cs) = if grav != 0.0 || contact.is_some() { theta.sin_cos() } else { (0.0, 1.0) };
        let a_md_p = sums.a_md;
        // Hub: q0 - a . Q_B over the Schur complement (a torque-driven hub).
        let mut q0 = torque - 2.0 * thd * sums.pd_gp;
        let mut a_qb = thd * thd * a_md_p - sums.a_k;
        if self.e_c.is_some() {
            a_qb -= dot(&self.a_c, pd);
        }
        let mut a_s_p = 0.0;
        if self.gravity.is_some() {
            a_s_p = dot(&self.a_s, p);
            q0 -= grav * (beam.s_1 * cs - sn * dot(&self.phi_sigma, p) - 0.5 * cs * dot(p, sp));
            a_qb += grav * sn * a_s_p - grav * cs * self.a_sigma;
        }
        let mut terms = ContactTerms::default();
        let mut pushing = None;
        if let Some((plane, force)) = contact {
            let tip = ModalEquations::tip_frame_of((lp, &self.phi_w), beam, p, pd, sn, cs);
            (terms.penetration, terms.rate) = tip.penetration(thd, plane);
            terms.force = force(terms.penetration, terms.rate);
            if terms.force != 0.0 {
                let f = terms.force;
                let [nx, ny] = plane.normal;
                let (lx, ly) = (cs * nx + sn * ny, -sn * nx + cs * ny);
                terms.hub_force = f * (-tip.y * lx + tip.x * ly);
                q0 += terms.hub_force;
                let a_l_p = dot(&self.a_l, p);
                a_qb += f * (-lx * a_l_p + ly * self.a_w);
                pushing = Some((f, lx, ly, a_l_p));
            }
        }
        let thdd = match hub {
            Hub::Prescribed { theta_ddot, .. } => theta_ddot,
            Hub::Torque(_) => {
                let schur = self.schur_0 + sums.p_gp;
                if !(schur > 0.0) {
                    return None;
                }
                (q0 - a_qb) / schur
            }
        };
        // The modes (module doc): u (theta'' - kappa.p) + (theta'^2 -
        // theta0'^2) H p (+ E_c p', gravity, contact), with `W X Phi_B p
        // = Phi_B^T X Phi_B p + Phi_0 (a . X b)` (`Psi = Phi^T J0`).
        let hub_row = |k: usize| if free_hub { self.phi_hub[k] } else { 0.0 };
        for k in 0..m {
            hp[k] = gp[k] + hub_row(k) * a_md_p;
        }
        let hub = thdd - sums.kappa;
        let dw2 = thd * thd - self.frozen_w2;
        let slow = self.left_slow.nrows();
        for k in slow..m {
            g[k] = self.left_diagonal[k] * p[k];
        }
        for k in 0..m {
            g[k] += self.u[k] * hub + dw2 * hp[k];
        }
        if self.e_c.is_some() {
            for k in 0..m {
                g[k] += tmp[k];
            }
        }
        if let Some((_, w_sigma)) = &self.gravity {
            for k in 0..m {
                let ws_b = sp[k] + hub_row(k) * a_s_p;
                g[k] += grav * ((sn - self.frozen_sin) * ws_b - cs * w_sigma[k]);
            }
        }
        if let Some((f, lx, ly, a_l_p)) = pushing {
            for k in 0..m {
                let wl_b = lp[k] + hub_row(k) * a_l_p;
                g[k] += f * (-lx * wl_b + ly * self.tip_w[k]);
            }
        }
        Some(terms)
    }
}

/// One point where [`ModalEquations::remainders`] evaluates: the modal
/// coordinates, their rates and the hub's motion.
#[derive(Clone, Copy, Debug)]
pub struct ModalPoint<'a> {
    pub p: &'a [f64],
    pub pd: &'a [f64],
    pub hub: Hub,
}

/// One point's products with the `m x m` matrices: `G p`, `Phi_B^T C_L
/// Phi_B p` (pressed), `Phi_B^T S Phi_B p` (gravity), `E_c p'` (damping).
struct PointProducts<'a> {
    gp: &'a [f64],
    lp: &'a [f64],
    sp: &'a [f64],
    tmp: &'a [f64],
}

/// Points per pass of [`ModalEquations::remainders`] (the exponential
/// integrator's nodes past a step's start, at most).
const POINTS: usize = 8;

fn not_positive_definite() -> String {
    "rotating beam: J(z) is not positive definite (hub inertia too small for this deflection?)".to_string()
}

#[cfg(test)]
mod tests {
    use super::super::{Order, RotatingBeamParams};
    use super::*;
    use nalgebra::{DVector, SymmetricEigen};

    /// The modal remainder against the physical route (`z = Phi p`,
    /// [`RotatingBeam::accelerations_in_place`] or, for a prescribed hub,
    /// [`RotatingBeam::prescribed_accelerations`], then `Psi z'' + Omega^2
    /// p + c p'`), with gravity, damping, a hub radius and a pressed
    /// contact, at states of every scale: within 1e-11 of the terms' size.
    #[test]
    fn modal_remainder_is_the_physical_one() {
        for prescribed in [false, true] {
            for (gravity, zeta, pressed) in [(0.0, 0.0, false), (9.81, 0.02, false), (9.81, 0.0, true), (0.0, 0.01, true)] {
                check(prescribed, gravity, zeta, pressed);
            }
        }
    }

    /// The DWZ beam at `n` modes (a hub radius, damping `zeta`, gravity).
    fn dwz_beam(n: usize, gravity: f64, zeta: f64) -> RotatingBeam {
        let params = RotatingBeamParams {
            length: 1.0,
            mass_per_length: 0.86884,
            bending_stiffness: 541.26,
            hub_inertia: 0.05,
            hub_radius: 0.1,
            gravity,
            n_modes: n,
            order: Order::First,
            modal_damping: vec![zeta],
        };
        RotatingBeam::new(params).unwrap()
    }

    /// A frozen part as the stepper makes it: K - theta0'^2 (M - D) - g
    /// sin(theta0) S, with J(0) and bordered for a torque-driven hub
    /// (frozen at another hub speed and angle than the states'): its
    /// equations, `Phi`, `Psi`, `omega^2` and damping.
    fn frozen_equations(beam: &RotatingBeam, prescribed: bool) -> (ModalEquations, DMatrix<f64>, DMatrix<f64>, Vec<f64>, Vec<f64>) {
        let n = beam.n_modes();
        let m = if prescribed { n } else { n + 1 };
        let gravity = beam.params.gravity;
        let (frozen_theta, frozen_theta_dot) = (0.4, 1.5);
        let stiff = &beam.k - &beam.m_minus_d * (frozen_theta_dot * frozen_theta_dot) - &beam.s_geo * (gravity * f64::sin(frozen_theta));
        let border = |b: &DMatrix<f64>| DMatrix::from_fn(n + 1, n + 1, |i, j| if i == 0 || j == 0 { 0.0 } else { b[(i - 1, j - 1)] });
        let (mass, kb, cb) = if prescribed { (beam.m.clone(), stiff, beam.damping.clone()) } else { (beam.mass_matrix(&DVector::zeros(n + 1)), border(&stiff), border(&beam.damping)) };
        let l = mass.clone().cholesky().unwrap().l();
        let a = l.solve_lower_triangular(&l.solve_lower_triangular(&kb).unwrap().transpose()).unwrap();
        let eig = SymmetricEigen::new(0.5 * (&a + a.transpose()));
        let phi = l.transpose().solve_upper_triangular(&eig.eigenvectors).unwrap();
        let psi = eig.eigenvectors.transpose() * l.transpose();
        let omega2: Vec<f64> = eig.eigenvalues.iter().map(|x| x.max(0.0)).collect();
        let cq = phi.transpose() * &cb * &phi;
        let c: Vec<f64> = (0..m).map(|k| if omega2[k] > 0.0 { cq[(k, k)].max(0.0) } else { 0.0 }).collect();
        let frozen = FrozenPart { phi: &phi, psi: &psi, omega2: &omega2, damping: &c, theta_dot_sq: frozen_theta_dot * frozen_theta_dot, sin_theta: f64::sin(frozen_theta), prescribed };
        (beam.modal_equations(frozen), phi, psi, omega2, c)
    }

    /// The remainder at a step's nodes in one call (the products through
    /// each matrix once) gives each node [`ModalEquations::remainder`]'s
    /// bits and contact terms, at 20 modes (the products' wide path), for
    /// both hubs, with and without gravity, damping and a pressed contact.
    #[test]
    fn remainders_at_several_points_are_the_single_ones_bits() {
        let n = 20;
        for prescribed in [false, true] {
            for (gravity, zeta, pressed) in [(0.0, 0.0, false), (9.81, 0.02, true), (0.0, 0.01, true)] {
                let beam = dwz_beam(n, gravity, zeta);
                let (mut eq, ..) = frozen_equations(&beam, prescribed);
                let m = if prescribed { n } else { n + 1 };
                let plane = Plane::new([0.3, -1.0], [1.1, 0.0]).unwrap();
                let law = |pen: f64, rate: f64| if pen > -1.0 { 1e5 * (pen + 1.0) + 30.0 * rate } else { 0.0 };
                let mut seed = 777u64;
                let mut next = move || {
                    seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                    (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
                };
                // Nine points: a batch of eight and one more.
                let states: Vec<(Vec<f64>, Vec<f64>, Hub)> = (0..9)
                    .map(|i| {
                        let scale = 1e-3 * (1.0 + i as f64);
                        let p: Vec<f64> = (0..m).map(|k| scale * next() / (1 + k) as f64).collect();
                        let pd: Vec<f64> = (0..m).map(|k| 100.0 * scale * next() / (1 + k) as f64).collect();
                        let hub = if prescribed { Hub::Prescribed { theta: 0.7 + 0.1 * i as f64, theta_dot: 2.0, theta_ddot: -3.0 } } else { Hub::Torque(0.3 * i as f64) };
                        (p, pd, hub)
                    })
                    .collect();
                let points: Vec<ModalPoint<'_>> = states.iter().map(|(p, pd, hub)| ModalPoint { p, pd, hub: *hub }).collect();
                let mut batch = vec![vec![f64::NAN; m]; points.len()];
                let mut terms = vec![None; points.len()];
                {
                    let mut f = law;
                    let contact = pressed.then(|| (&plane, &mut f as &mut dyn FnMut(f64, f64) -> f64));
                    let mut outs: Vec<&mut [f64]> = batch.iter_mut().map(|g| &mut g[..]).collect();
                    eq.remainders(&beam, &points, contact, &mut outs, &mut terms);
                }
                for (i, point) in points.iter().enumerate() {
                    let mut f = law;
                    let contact = pressed.then(|| (&plane, &mut f as &mut dyn FnMut(f64, f64) -> f64));
                    let mut single = vec![f64::NAN; m];
                    let t = eq.remainder(&beam, point.p, point.pd, point.hub, contact, &mut single).unwrap();
                    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    let case = format!("prescribed={prescribed} g={gravity} zeta={zeta} pressed={pressed} point {i}");
                    assert_eq!(bits(&batch[i]), bits(&single), "{case}");
                    let batch_terms = terms[i].expect("J positive definite");
                    let terms_bits = |t: ContactTerms| [t.penetration, t.rate, t.force, t.hub_force].map(f64::to_bits);
                    assert_eq!(terms_bits(batch_terms), terms_bits(t), "{case}");
                }
            }
        }
    }

    fn check(prescribed: bool, gravity: f64, zeta: f64, pressed: bool) {
        let n = 7;
        let beam = dwz_beam(n, gravity, zeta);
        let m = if prescribed { n } else { n + 1 };
        let (mut eq, phi, psi, omega2, c) = frozen_equations(&beam, prescribed);
        let plane = Plane::new([0.3, -1.0], [1.1, 0.0]).unwrap();
        let mut seed = 12345u64;
        let mut next = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let (theta, theta_dot, theta_ddot) = (0.7, 2.0, -3.0);
        for scale in [1e-6, 1e-3, 3e-2] {
            let z: Vec<f64> = (0..=n).map(|k| if k == 0 { theta } else { scale * next() / (k * k) as f64 }).collect();
            let zd: Vec<f64> = (0..=n).map(|k| if k == 0 { theta_dot } else { 100.0 * scale * next() / k as f64 }).collect();
            let (zv, zdv) = (DVector::from_column_slice(&z), DVector::from_column_slice(&zd));
            let hub = m - n;
            let (p, pd) = (&psi * zv.rows(1 - hub, m), &psi * zdv.rows(1 - hub, m));
            let law = |pen: f64, rate: f64| if pen > -1.0 { 1e5 * (pen + 1.0) + 30.0 * rate } else { 0.0 };
            // The physical route from Phi p (what the integrator does).
            let (mut zp, mut zdp) = (zv.clone(), zdv.clone());
            zp.rows_mut(1 - hub, m).copy_from(&(&phi * &p));
            zdp.rows_mut(1 - hub, m).copy_from(&(&phi * &pd));
            let mut zdd = DVector::zeros(n + 1);
            let t1 = if prescribed {
                let mut t = ContactTerms::default();
                let mut qc = DVector::zeros(n + 1);
                if pressed {
                    (t.penetration, t.rate) = beam.plane_penetration(zp.as_slice(), zdp.as_slice(), &plane);
                    t.force = law(t.penetration, t.rate);
                    qc = beam.contact_generalized_force(&zp, &plane, t.force);
                    t.hub_force = qc[0];
                }
                let mut bdd = DVector::zeros(n);
                beam.prescribed_accelerations(&zp, &zdp, theta_ddot, Some(&qc), &mut bdd);
                zdd.rows_mut(1, n).copy_from(&bdd);
                t
            } else {
                let mut f1 = law;
                let contact = pressed.then(|| (&plane, &mut f1 as &mut dyn FnMut(f64, f64) -> f64));
                beam.accelerations_in_place(zp.as_slice(), zdp.as_slice(), 0.3, contact, zdd.as_mut_slice(), &mut Default::default()).unwrap()
            };
            let psi_zdd = &psi * zdd.rows(1 - hub, m);
            let mut f2 = law;
            let contact = pressed.then(|| (&plane, &mut f2 as &mut dyn FnMut(f64, f64) -> f64));
            let motion = if prescribed { Hub::Prescribed { theta, theta_dot, theta_ddot } } else { Hub::Torque(0.3) };
            let mut g = vec![0.0; m];
            let t2 = eq.remainder(&beam, p.as_slice(), pd.as_slice(), motion, contact, &mut g).unwrap();
            let case = format!("prescribed={prescribed} g={gravity} zeta={zeta} pressed={pressed} scale={scale}");
            for k in 0..m {
                let reference = psi_zdd[k] + omega2[k] * p[k] + c[k] * pd[k];
                let size = psi_zdd[k].abs() + (omega2[k] * p[k]).abs() + (c[k] * pd[k]).abs() + 1e-300;
                assert!((g[k] - reference).abs() <= 1e-11 * size, "{case} mode {k}: {} against {reference} (size {size})", g[k]);
            }
            for (x, y) in [(t1.penetration, t2.penetration), (t1.rate, t2.rate), (t1.force, t2.force), (t1.hub_force, t2.hub_force)] {
                assert!((x - y).abs() <= 1e-12 * x.abs().max(1.0), "{case}: contact terms {t1:?} against {t2:?}");
            }
            // The penetration alone (the switch locator's), pressed or not.
            let physical = beam.plane_penetration(zp.as_slice(), zdp.as_slice(), &plane);
            let modal = eq.penetration(&beam, p.as_slice(), pd.as_slice(), motion, &plane, &mut Vec::new());
            for (x, y) in [(physical.0, modal.0), (physical.1, modal.1)] {
                assert!((x - y).abs() <= 1e-12 * x.abs().max(1.0), "{case}: penetration {physical:?} against {modal:?}");
            }
        }
    }
}
