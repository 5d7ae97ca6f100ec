//! The loads of a coupled phase in its complex coordinates (with their
//! steady responses and the bound terms the event search uses), and
//! functionals expressed in those coordinates: what every segment of one
//! phase shares, whatever its anchor.

use nalgebra::DVector;

use super::CoupledSystem;
use crate::solve::complex::C64;
use crate::solve::forcing::ModalForcing;
use crate::solve::functional::Functional;

/// One harmonic load component in the complex modal coordinates, with the
/// steady response `p_k e^{i W t}` of the coordinates far from resonance
/// (`None` near it).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct ProjectedHarmonic {
    pub(super) omega: f64,
    pub(super) g: DVector<C64>,
    pub(super) steady: Vec<Option<C64>>,
    /// `1 / (L - i W)` where `L` is far from `i W` ([`direct_factor`]).
    pub(super) factor: Vec<Option<C64>>,
}

/// The steady response `g / (i W - L)` of `z' = L z + g e^{i W t}`, unless
/// the denominator is small (resonance), where it would amplify rounding.
fn steady_amplitude(g: C64, eig: C64, omega: f64) -> Option<C64> {
    let den = C64::new(0.0, omega) - eig;
    if modulus(den) > 1e-3 * (modulus(eig) + omega.abs()) {
        Some(g / den)
    } else {
        None
    }
}

/// `1 / (L - i W)` where the difference `expm1(L s) - expm1(i W s)` keeps
/// its relative accuracy to within a factor 8 (`|L - i W| > (|L| + |W|) / 8`).
fn direct_factor(eig: C64, omega: f64) -> Option<C64> {
    let den = eig - C64::new(0.0, omega);
    (modulus(den) > 0.125 * (modulus(eig) + omega.abs())).then(|| C64::new(1.0, 0.0) / den)
}

/// `|z|` without `hypot`'s guard against overflow (the coordinates and
/// eigenvalues here are far from it).
fn modulus(z: C64) -> f64 {
    (z.re * z.re + z.im * z.im).sqrt()
}

/// Per coordinate, the parts of its derivative bounds that do not change
/// along a segment: `sum |P| W^m` over the steady responses (m = 0..=4),
/// `sum |g| W^m` over the near-resonant loads (m = 0..=3), `sum |P|` over
/// every steady response (`size`, the constant load's included) and the
/// constant load's `|P|` alone (`constant`).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct BoundTerms {
    pub(super) steady: [f64; 5],
    pub(super) resonant: [f64; 4],
    pub(super) size: f64,
    pub(super) constant: f64,
}

/// What every segment of one contact phase shares, whatever its anchor:
/// the loads in the system's complex coordinates, their steady responses
/// and the coordinates' bound terms, for one system, load and origin. A
/// phase entered again (each sticking phase of a chatter sequence, each
/// contact of a spring stop) starts its segment from these in O(N^2)
/// without projecting the loads again.
#[derive(Clone, Debug)]
pub struct PhaseLoads {
    pub(super) q_c: DVector<f64>,
    pub(super) g_const: DVector<C64>,
    pub(super) const_steady: Vec<Option<C64>>,
    pub(super) harmonics: Vec<ProjectedHarmonic>,
    pub(super) bound_terms: Vec<BoundTerms>,
}

impl PhaseLoads {
    /// `origin` is the point the motion is measured from: it must satisfy
    /// the constraints `W^T q = targets` (the held stops' positions; for
    /// instance [`CoupledSystem::q_c`]). Choosing it on the surfaces of
    /// pressed compliant stops too keeps their large preload `k target w`
    /// out of the loads: the spring then acts on the small deviation only.
    /// `origin_force` is what the phase's stiffness exerts at the origin
    /// net of any preload the loads leave out (`K origin` when there is none;
    /// the caller forms it without the cancellation `k w (w . origin) - k
    /// w target` would cost).
    pub fn new(sys: &CoupledSystem, forcing: &ModalForcing, origin: &DVector<f64>, origin_force: &DVector<f64>) -> Self {
        let n = sys.n_free();
        let q_c = origin.clone();
        // Loads on y: Z^T (f(t) - K q_c), entering the velocity half.
        // (only the velocity half of the state is loaded: the right half of V^-1)
        let v_inv_loads = sys.v_inv.columns(n, n);
        let lift = |fy: DVector<C64>| -> DVector<C64> { &v_inv_loads * fy };
        let c = sys.z.tr_mul(&(&forcing.constant - origin_force));
        let g_const = lift(c.map(|x| C64::new(x, 0.0)));
        let mut harmonics = Vec::new();
        let mut push = |omega: f64, g: DVector<C64>| {
            let steady = g.iter().zip(sys.eig.iter()).map(|(g, l)| steady_amplitude(*g, *l, omega)).collect();
            let factor = sys.eig.iter().map(|l| direct_factor(*l, omega)).collect();
            harmonics.push(ProjectedHarmonic { omega, g, steady, factor });
        };
        for h in &forcing.harmonics {
            // Re(b e^{i W t}) = (b e^{i W t} + conj(b) e^{-i W t}) / 2.
            let by = DVector::from_fn(n, |i, _| sys.z.column(i).iter().zip(h.amplitude.iter()).map(|(z, b)| b * *z).sum::<C64>());
            let half = C64::new(0.5, 0.0);
            push(h.omega, lift(by.map(|b| b * half)));
            push(-h.omega, lift(by.map(|b| b.conj() * half)));
        }
        let const_steady: Vec<Option<C64>> = g_const.iter().zip(sys.eig.iter()).map(|(g, l)| steady_amplitude(*g, *l, 0.0)).collect();
        let bound_terms = (0..2 * n)
            .map(|k| {
                let mut terms = BoundTerms::default();
                match const_steady[k] {
                    Some(p) => {
                        terms.constant = p.norm();
                        terms.size += terms.constant;
                    }
                    None => terms.resonant[0] += g_const[k].norm(),
                }
                for h in &harmonics {
                    let (mut a, target): (f64, &mut [f64]) = match h.steady[k] {
                        Some(p) => {
                            terms.size += p.norm();
                            (p.norm(), &mut terms.steady)
                        }
                        None => (h.g[k].norm(), &mut terms.resonant),
                    };
                    for m in target.iter_mut() {
                        *m += a;
                        a *= h.omega.abs();
                    }
                }
                terms
            })
            .collect();
        PhaseLoads { q_c, g_const, const_steady, harmonics, bound_terms }
    }

    /// A functional in the complex coordinates: `h = offset + Re(c . z) + f-part`,
    /// with the sizes its bounds use (constant along the phase).
    pub fn project_functional(&self, sys: &CoupledSystem, forcing: &ModalForcing, h: &Functional) -> ProjectedFunctional {
        let n = sys.n_free();
        let aq = sys.z.tr_mul(&h.q);
        let bq = h.qd.as_ref().map(|b| sys.z.tr_mul(b));
        // c_k = V[.., k] . [aq; bq], a column of V at a time; the second of a
        // mirrored pair is the first's conjugate.
        let mut c = DVector::from_element(2 * n, C64::new(0.0, 0.0));
        for (k, column) in sys.v.column_iter().enumerate() {
            if sys.mirrors_previous[k] {
                c[k] = c[k - 1].conj();
                continue;
            }
            let column = column.as_slice();
            let mut s = C64::new(0.0, 0.0);
            for (v, a) in column[..n].iter().zip(aq.iter()) {
                s += v * *a;
            }
            if let Some(b) = &bq {
                for (v, b) in column[n..].iter().zip(b.iter()) {
                    s += v * *b;
                }
            }
            c[k] = s;
        }
        let c_abs = c.iter().map(|c| c.norm()).collect();
        // sum_j |c_j| max |f_j^(m)|, m = 0..=4.
        let load_bounds = std::array::from_fn(|m| {
            h.f.as_ref().map_or(0.0, |cf| cf.iter().enumerate().map(|(j, c)| c.abs() * forcing.bound(j, m as u32)).sum())
        });
        let f_const = h.f.as_ref().map_or(0.0, |cf| cf.dot(&forcing.constant));
        let f_harmonics = match &h.f {
            Some(cf) => forcing.harmonics.iter().map(|hm| hm.amplitude.iter().zip(cf.iter()).map(|(b, c)| b * *c).sum()).collect(),
            None => Vec::new(),
        };
        ProjectedFunctional { offset: h.offset + h.q.dot(&self.q_c), c, c_abs, f: h.f.clone(), f_const, f_harmonics, load_bounds }
    }
}

/// A functional expressed in a coupled segment's complex coordinates.
#[derive(Clone, Debug)]
pub struct ProjectedFunctional {
    pub(super) offset: f64,
    pub(super) c: DVector<C64>,
    /// `|c_k|`.
    pub(super) c_abs: Vec<f64>,
    pub(super) f: Option<DVector<f64>>,
    /// `c . f_const` and `c . b_h` per harmonic: the load part in O(1) per probe.
    pub(super) f_const: f64,
    pub(super) f_harmonics: Vec<C64>,
    /// `sum_j |f_j| max |d^m f_j / dt^m|`, m = 0..=4: the load part's bounds.
    pub(super) load_bounds: [f64; 5],
}
