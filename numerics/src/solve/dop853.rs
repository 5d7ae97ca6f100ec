//! DOP853: the explicit Runge-Kutta method of Dormand & Prince of order 8
//! with embedded error estimators of orders 5 and 3 and a continuous
//! extension (dense output) of order 7, step by step.
//!
//! Sources:
//! * HNW93 (docs/references.md): E. Hairer, S. P. Norsett, G. Wanner,
//!   "Solving Ordinary Differential Equations I: Nonstiff Problems", 2nd
//!   ed., Springer 1993, Sec. II.5 (the method, the (5,3) error estimate)
//!   and II.6 (dense output), and Hairer's Fortran code DOP853
//!   (http://www.unige.ch/~hairer/software.html);
//! * scipy.integrate (`_ivp/dop853_coefficients.py`; `_ivp/rk.py`, classes
//!   `RungeKutta`, `DOP853` and `Dop853DenseOutput`; `_ivp/common.py`,
//!   `select_initial_step`), whose coefficients, step-size controller
//!   (SAFETY 0.9, factor in [0.2, 10], no increase right after a rejection),
//!   error norm and dense-output evaluation scheme this file ports.
//!
//! States are slices of any length; every buffer is allocated once in
//! [`Dop853::new`], so [`Dop853::step`], [`Dop853::dense`] and
//! [`Dop853::restart`] do not allocate.
//!
//! The rotating beam's default integrator, and the integrator of the
//! compiled peers the benchmarks compare beamstop with (`examples/`).

/// A right-hand side `dy = f(t, y)`. Every `FnMut(f64, &[f64], &mut [f64])`
/// is one; a struct implementing it can carry switchable state (a phase).
pub trait Rhs {
    fn eval(&mut self, t: f64, y: &[f64], dy: &mut [f64]);
}

impl<F: FnMut(f64, &[f64], &mut [f64])> Rhs for F {
    fn eval(&mut self, t: f64, y: &[f64], dy: &mut [f64]) {
        self(t, y, dy)
    }
}

const N_STAGES: usize = 12;
const N_STAGES_EXTENDED: usize = 16;
const SAFETY: f64 = 0.9;
const MIN_FACTOR: f64 = 0.2;
const MAX_FACTOR: f64 = 10.0;
/// `-1 / (error estimator order + 1)`, the estimator being of order 7.
const ERROR_EXPONENT: f64 = -1.0 / 8.0;

/// Nodes `c_i` (scipy `dop853_coefficients.C`; note c_12 = c_13 = 1).
const C: [f64; N_STAGES_EXTENDED] = [
    0.0,
    0.526001519587677318785587544488e-01,
    0.789002279381515978178381316732e-01,
    0.118350341907227396726757197510,
    0.281649658092772603273242802490,
    0.333333333333333333333333333333,
    0.25,
    0.307692307692307692307692307692,
    0.651282051282051282051282051282,
    0.6,
    0.857142857142857142857142857142,
    1.0,
    1.0,
    0.1,
    0.2,
    0.777777777777777777777777777778,
];

/// The non-zero entries `a_ij` of rows 1..=15 (row 12 is the weights `b`),
/// as `(j, a_ij)` (scipy `dop853_coefficients.A`).
const A1: &[(usize, f64)] = &[(0, 5.26001519587677318785587544488e-2)];
const A2: &[(usize, f64)] = &[(0, 1.97250569845378994544595329183e-2), (1, 5.91751709536136983633785987549e-2)];
const A3: &[(usize, f64)] = &[(0, 2.95875854768068491816892993775e-2), (2, 8.87627564304205475450678981324e-2)];
const A4: &[(usize, f64)] = &[
    (0, 2.41365134159266685502369798665e-1),
    (2, -8.84549479328286085344864962717e-1),
    (3, 9.24834003261792003115737966543e-1),
];
const A5: &[(usize, f64)] = &[
    (0, 3.7037037037037037037037037037e-2),
    (3, 1.70828608729473871279604482173e-1),
    (4, 1.25467687566822425016691814123e-1),
];
const A6: &[(usize, f64)] = &[
    (0, 3.7109375e-2),
    (3, 1.70252211019544039314978060272e-1),
    (4, 6.02165389804559606850219397283e-2),
    (5, -1.7578125e-2),
];
const A7: &[(usize, f64)] = &[
    (0, 3.70920001185047927108779319836e-2),
    (3, 1.70383925712239993810214054705e-1),
    (4, 1.07262030446373284651809199168e-1),
    (5, -1.53194377486244017527936158236e-2),
    (6, 8.27378916381402288758473766002e-3),
];
const A8: &[(usize, f64)] = &[
    (0, 6.24110958716075717114429577812e-1),
    (3, -3.36089262944694129406857109825),
    (4, -8.68219346841726006818189891453e-1),
    (5, 2.75920996994467083049415600797e1),
    (6, 2.01540675504778934086186788979e1),
    (7, -4.34898841810699588477366255144e1),
];
const A9: &[(usize, f64)] = &[
    (0, 4.77662536438264365890433908527e-1),
    (3, -2.48811461997166764192642586468),
    (4, -5.90290826836842996371446475743e-1),
    (5, 2.12300514481811942347288949897e1),
    (6, 1.52792336328824235832596922938e1),
    (7, -3.32882109689848629194453265587e1),
    (8, -2.03312017085086261358222928593e-2),
];
const A10: &[(usize, f64)] = &[
    (0, -9.3714243008598732571704021658e-1),
    (3, 5.18637242884406370830023853209),
    (4, 1.09143734899672957818500254654),
    (5, -8.14978701074692612513997267357),
    (6, -1.85200656599969598641566180701e1),
    (7, 2.27394870993505042818970056734e1),
    (8, 2.49360555267965238987089396762),
    (9, -3.0467644718982195003823669022),
];
const A11: &[(usize, f64)] = &[
    (0, 2.27331014751653820792359768449),
    (3, -1.05344954667372501984066689879e1),
    (4, -2.00087205822486249909675718444),
    (5, -1.79589318631187989172765950534e1),
    (6, 2.79488845294199600508499808837e1),
    (7, -2.85899827713502369474065508674),
    (8, -8.87285693353062954433549289258),
    (9, 1.23605671757943030647266201528e1),
    (10, 6.43392746015763530355970484046e-1),
];
/// Row 12: the weights `b` of the order-8 solution (stages 0..12).
const B: &[(usize, f64)] = &[
    (0, 5.42937341165687622380535766363e-2),
    (5, 4.45031289275240888144113950566),
    (6, 1.89151789931450038304281599044),
    (7, -5.8012039600105847814672114227),
    (8, 3.1116436695781989440891606237e-1),
    (9, -1.52160949662516078556178806805e-1),
    (10, 2.01365400804030348374776537501e-1),
    (11, 4.47106157277725905176885569043e-2),
];
/// Rows 13..=15: the three extra stages of the dense output.
const A13: &[(usize, f64)] = &[
    (0, 5.61675022830479523392909219681e-2),
    (6, 2.53500210216624811088794765333e-1),
    (7, -2.46239037470802489917441475441e-1),
    (8, -1.24191423263816360469010140626e-1),
    (9, 1.5329179827876569731206322685e-1),
    (10, 8.20105229563468988491666602057e-3),
    (11, 7.56789766054569976138603589584e-3),
    (12, -8.298e-3),
];
const A14: &[(usize, f64)] = &[
    (0, 3.18346481635021405060768473261e-2),
    (5, 2.83009096723667755288322961402e-2),
    (6, 5.35419883074385676223797384372e-2),
    (7, -5.49237485713909884646569340306e-2),
    (10, -1.08347328697249322858509316994e-4),
    (11, 3.82571090835658412954920192323e-4),
    (12, -3.40465008687404560802977114492e-4),
    (13, 1.41312443674632500278074618366e-1),
];
const A15: &[(usize, f64)] = &[
    (0, -4.28896301583791923408573538692e-1),
    (5, -4.69762141536116384314449447206),
    (6, 7.68342119606259904184240953878),
    (7, 4.06898981839711007970213554331),
    (8, 3.56727187455281109270669543021e-1),
    (12, -1.39902416515901462129418009734e-3),
    (13, 2.9475147891527723389556272149),
    (14, -9.15095847217987001081870187138),
];
const ROWS: [&[(usize, f64)]; N_STAGES] = [&[], A1, A2, A3, A4, A5, A6, A7, A8, A9, A10, A11];
const EXTRA_ROWS: [&[(usize, f64)]; 3] = [A13, A14, A15];

/// The order-5 error estimator `E5` (scipy), stages 0..12.
const E5: &[(usize, f64)] = &[
    (0, 0.1312004499419488073250102996e-1),
    (5, -0.1225156446376204440720569753e1),
    (6, -0.4957589496572501915214079952),
    (7, 0.1664377182454986536961530415e1),
    (8, -0.3503288487499736816886487290),
    (9, 0.3341791187130174790297318841),
    (10, 0.8192320648511571246570742613e-1),
    (11, -0.2235530786388629525884427845e-1),
];
/// The order-3 estimator `E3 = b - bhat3` (scipy: B with three corrections).
const E3: &[(usize, f64)] = &[
    (0, 5.42937341165687622380535766363e-2 - 0.244094488188976377952755905512),
    (5, 4.45031289275240888144113950566),
    (6, 1.89151789931450038304281599044),
    (7, -5.8012039600105847814672114227),
    (8, 3.1116436695781989440891606237e-1 - 0.733846688281611857341361741547),
    (9, -1.52160949662516078556178806805e-1),
    (10, 2.01365400804030348374776537501e-1),
    (11, 4.47106157277725905176885569043e-2 - 0.220588235294117647058823529412e-1),
];

/// Dense-output rows 3..=6 (scipy `dop853_coefficients.D`), stages 0..16.
const D: [&[(usize, f64)]; 4] = [
    &[
        (0, -0.84289382761090128651353491142e1),
        (5, 0.56671495351937776962531783590),
        (6, -0.30689499459498916912797304727e1),
        (7, 0.23846676565120698287728149680e1),
        (8, 0.21170345824450282767155149946e1),
        (9, -0.87139158377797299206789907490),
        (10, 0.22404374302607882758541771650e1),
        (11, 0.63157877876946881815570249290),
        (12, -0.88990336451333310820698117400e-1),
        (13, 0.18148505520854727256656404962e2),
        (14, -0.91946323924783554000451984436e1),
        (15, -0.44360363875948939664310572000e1),
    ],
    &[
        (0, 0.10427508642579134603413151009e2),
        (5, 0.24228349177525818288430175319e3),
        (6, 0.16520045171727028198505394887e3),
        (7, -0.37454675472269020279518312152e3),
        (8, -0.22113666853125306036270938578e2),
        (9, 0.77334326684722638389603898808e1),
        (10, -0.30674084731089398182061213626e2),
        (11, -0.93321305264302278729567221706e1),
        (12, 0.15697238121770843886131091075e2),
        (13, -0.31139403219565177677282850411e2),
        (14, -0.93529243588444783865713862664e1),
        (15, 0.35816841486394083752465898540e2),
    ],
    &[
        (0, 0.19985053242002433820987653617e2),
        (5, -0.38703730874935176555105901742e3),
        (6, -0.18917813819516756882830838328e3),
        (7, 0.52780815920542364900561016686e3),
        (8, -0.11573902539959630126141871134e2),
        (9, 0.68812326946963000169666922661e1),
        (10, -0.10006050966910838403183860980e1),
        (11, 0.77771377980534432092869265740),
        (12, -0.27782057523535084065932004339e1),
        (13, -0.60196695231264120758267380846e2),
        (14, 0.84320405506677161018159903784e2),
        (15, 0.11992291136182789328035130030e2),
    ],
    &[
        (0, -0.25693933462703749003312586129e2),
        (5, -0.15418974869023643374053993627e3),
        (6, -0.23152937917604549567536039109e3),
        (7, 0.35763911791061412378285349910e3),
        (8, 0.93405324183624310003907691704e2),
        (9, -0.37458323136451633156875139351e2),
        (10, 0.10409964950896230045147246184e3),
        (11, 0.29840293426660503123344363579e2),
        (12, -0.43533456590011143754432175058e2),
        (13, 0.96324553959188282948394950600e2),
        (14, -0.39177261675615439165231486172e2),
        (15, -0.14972683625798562581422125276e3),
    ],
];

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepError {
    /// The step size fell below 10 ulp of t (scipy's `TOO_SMALL_STEP`).
    TooSmallStep,
    /// `t` already is `t_bound`.
    Finished,
}

/// A DOP853 integration from `t` towards `t_bound`.
#[derive(Clone, Debug)]
pub struct Dop853<F: Rhs> {
    pub rhs: F,
    n: usize,
    pub t: f64,
    pub t_old: f64,
    pub t_bound: f64,
    /// The state at `t`, and at `t_old` (start of the last accepted step).
    y: Vec<f64>,
    y_old: Vec<f64>,
    /// `f(t, y)` (first same as last).
    f: Vec<f64>,
    rtol: f64,
    /// One absolute tolerance per component.
    atol: Vec<f64>,
    pub max_step: f64,
    /// The size of the next step to try.
    h_abs: f64,
    /// The last accepted step `t - t_old`.
    h_previous: f64,
    /// Stages `K[s]`, `s` in 0..16, each `n` long (row 12 holds `f(t, y)`).
    k: Vec<f64>,
    ytmp: Vec<f64>,
    scratch: Vec<f64>,
    /// The dense-output coefficients `F[0..7]` of the last accepted step.
    dense_f: Vec<f64>,
    dense_ready: bool,
    pub n_fev: usize,
    pub n_accepted: usize,
    pub n_rejected: usize,
}

fn combine(k: &[f64], n: usize, row: &[(usize, f64)], scale: f64, base: &[f64], out: &mut [f64]) {
    out.copy_from_slice(base);
    for &(j, a) in row {
        let a = a * scale;
        for (o, kj) in out.iter_mut().zip(&k[j * n..(j + 1) * n]) {
            *o += a * kj;
        }
    }
}

/// `sum_j row_j K[j]` into `out`.
fn lincomb(k: &[f64], n: usize, row: &[(usize, f64)], out: &mut [f64]) {
    out.fill(0.0);
    for &(j, a) in row {
        for (o, kj) in out.iter_mut().zip(&k[j * n..(j + 1) * n]) {
            *o += a * kj;
        }
    }
}

impl<F: Rhs> Dop853<F> {
    /// A solver at `(t0, y0)` towards `t_bound`, tolerances `rtol` and
    /// `atol` (one value, or one per component); `first_step: None` selects
    /// it as scipy does.
    pub fn new(rhs: F, t0: f64, y0: &[f64], t_bound: f64, rtol: f64, atol: &[f64], first_step: Option<f64>) -> Self {
        let n = y0.len();
        assert!(atol.len() == 1 || atol.len() == n, "atol: one value or one per component");
        assert!(t_bound >= t0, "forward integration only");
        let atol = if atol.len() == n { atol.to_vec() } else { vec![atol[0]; n] };
        let mut s = Dop853 {
            rhs,
            n,
            t: t0,
            t_old: t0,
            t_bound,
            y: y0.to_vec(),
            y_old: y0.to_vec(),
            f: vec![0.0; n],
            rtol,
            atol,
            max_step: f64::INFINITY,
            h_abs: 0.0,
            h_previous: 0.0,
            k: vec![0.0; N_STAGES_EXTENDED * n],
            ytmp: vec![0.0; n],
            scratch: vec![0.0; n],
            dense_f: vec![0.0; 7 * n],
            dense_ready: false,
            n_fev: 0,
            n_accepted: 0,
            n_rejected: 0,
        };
        s.restart(t0, y0, first_step);
        s
    }

    pub fn y(&self) -> &[f64] {
        &self.y
    }

    /// The last accepted step `[t_old, t]`.
    pub fn last_step(&self) -> (f64, f64) {
        (self.t_old, self.t)
    }

    /// The size of the next step to try.
    pub fn next_step_size(&self) -> f64 {
        self.h_abs
    }

    /// Starts afresh at `(t0, y0)` (the right-hand side may have changed):
    /// evaluates `f(t0, y0)` and sets the first step (`None`: scipy's
    /// `select_initial_step`). No allocation.
    pub fn restart(&mut self, t0: f64, y0: &[f64], first_step: Option<f64>) {
        assert_eq!(y0.len(), self.n);
        self.t = t0;
        self.t_old = t0;
        self.y.copy_from_slice(y0);
        self.y_old.copy_from_slice(y0);
        self.rhs.eval(t0, &self.y, &mut self.f);
        self.n_fev += 1;
        self.dense_ready = false;
        self.h_previous = 0.0;
        self.h_abs = match first_step {
            Some(h) => h.min(self.t_bound - t0).min(self.max_step),
            None => self.select_initial_step(),
        };
    }

    /// scipy `select_initial_step` (Hairer, Norsett & Wanner, Sec. II.4,
    /// "automatic selection of the initial step size"), error estimator
    /// order 7.
    fn select_initial_step(&mut self) -> f64 {
        let n = self.n;
        if n == 0 {
            return f64::INFINITY;
        }
        let interval = self.t_bound - self.t;
        if interval == 0.0 {
            return 0.0;
        }
        let mut d0 = 0.0;
        let mut d1 = 0.0;
        for i in 0..n {
            let scale = self.atol[i] + self.y[i].abs() * self.rtol;
            d0 += (self.y[i] / scale).powi(2);
            d1 += (self.f[i] / scale).powi(2);
        }
        let d0 = (d0 / n as f64).sqrt();
        let d1 = (d1 / n as f64).sqrt();
        let h0 = if d0 < 1e-5 || d1 < 1e-5 { 1e-6 } else { 0.01 * d0 / d1 };
        let h0 = h0.min(interval);
        for i in 0..n {
            self.ytmp[i] = self.y[i] + h0 * self.f[i];
        }
        self.rhs.eval(self.t + h0, &self.ytmp, &mut self.scratch);
        self.n_fev += 1;
        let mut d2 = 0.0;
        for i in 0..n {
            let scale = self.atol[i] + self.y[i].abs() * self.rtol;
            d2 += ((self.scratch[i] - self.f[i]) / scale).powi(2);
        }
        let d2 = (d2 / n as f64).sqrt() / h0;
        let h1 = if d1 <= 1e-15 && d2 <= 1e-15 { (1e-6f64).max(h0 * 1e-3) } else { (0.01 / d1.max(d2)).powf(1.0 / 8.0) };
        (100.0 * h0).min(h1).min(interval).min(self.max_step)
    }

    /// The stages of a step of size `h` from `(t, y)`: the new state in
    /// `ytmp`, `f` there in `K[12]`; returns the error norm.
    fn attempt(&mut self, h: f64) -> f64 {
        let n = self.n;
        let t = self.t;
        // The 12 stages; K[12] = f(t + h, y_new).
        self.k[..n].copy_from_slice(&self.f);
        for s in 1..N_STAGES {
            combine(&self.k, n, ROWS[s], h, &self.y, &mut self.ytmp);
            let (_, ks) = self.k.split_at_mut(s * n);
            self.rhs.eval(t + C[s] * h, &self.ytmp, &mut ks[..n]);
        }
        combine(&self.k, n, B, h, &self.y, &mut self.ytmp);
        {
            let (_, k12) = self.k.split_at_mut(N_STAGES * n);
            self.rhs.eval(t + h, &self.ytmp, &mut k12[..n]);
        }
        self.n_fev += N_STAGES;

        // Error norm: the (5, 3) combination of Hairer's DOP853 as in scipy.
        let mut e5 = 0.0;
        let mut e3 = 0.0;
        for i in 0..n {
            let scale = self.atol[i] + self.y[i].abs().max(self.ytmp[i].abs()) * self.rtol;
            let mut a5 = 0.0;
            for &(j, c) in E5 {
                a5 += c * self.k[j * n + i];
            }
            let mut a3 = 0.0;
            for &(j, c) in E3 {
                a3 += c * self.k[j * n + i];
            }
            e5 += (a5 / scale).powi(2);
            e3 += (a3 / scale).powi(2);
        }
        if e5 == 0.0 && e3 == 0.0 {
            0.0
        } else {
            h * e5 / ((e5 + 0.01 * e3) * n as f64).sqrt()
        }
    }

    /// Takes the attempted step of size `h` to `t_new`, proposing `h_next`.
    fn accept(&mut self, h: f64, t_new: f64, h_next: f64) {
        let n = self.n;
        self.h_previous = h;
        self.t_old = self.t;
        std::mem::swap(&mut self.y_old, &mut self.y);
        self.y.copy_from_slice(&self.ytmp);
        self.t = t_new;
        self.h_abs = h_next;
        self.f.copy_from_slice(&self.k[N_STAGES * n..(N_STAGES + 1) * n]);
        self.dense_ready = false;
        self.n_accepted += 1;
    }

    /// One accepted step (rejected attempts included): returns `[t_old, t_new]`.
    pub fn step(&mut self) -> Result<(f64, f64), StepError> {
        let t = self.t;
        if t >= self.t_bound {
            return Err(StepError::Finished);
        }
        let min_step = 10.0 * (next_up(t) - t).abs();
        let mut h_abs = self.h_abs.min(self.max_step).max(min_step);
        let mut rejected = false;
        loop {
            if h_abs < min_step {
                return Err(StepError::TooSmallStep);
            }
            let mut t_new = t + h_abs;
            if t_new > self.t_bound {
                t_new = self.t_bound;
            }
            let h = t_new - t;
            h_abs = h;
            let error_norm = self.attempt(h);
            if error_norm < 1.0 {
                let mut factor = if error_norm == 0.0 { MAX_FACTOR } else { MAX_FACTOR.min(SAFETY * error_norm.powf(ERROR_EXPONENT)) };
                if rejected {
                    factor = factor.min(1.0);
                }
                self.accept(h, t_new, h_abs * factor);
                return Ok((t, t_new));
            }
            // A non-finite error (a right-hand side that failed) shrinks
            // the step as much as a rejection may.
            h_abs *= if error_norm.is_finite() { MIN_FACTOR.max(SAFETY * error_norm.powf(ERROR_EXPONENT)) } else { MIN_FACTOR };
            rejected = true;
            self.n_rejected += 1;
        }
    }

    /// One step to `t_new` without error control (the state inside the
    /// last step to the method's full order: a step of its own from the
    /// step's start).
    pub fn step_to(&mut self, t_new: f64) {
        let h = t_new - self.t;
        self.attempt(h);
        let h_next = self.h_abs;
        self.accept(h, t_new, h_next);
    }

    /// The three extra stages and the coefficients `F[0..7]` of the
    /// continuous extension of the last accepted step (scipy
    /// `DOP853._dense_output_impl`).
    pub fn prepare_dense(&mut self) {
        let n = self.n;
        let h = self.h_previous;
        for (r, row) in EXTRA_ROWS.iter().enumerate() {
            let s = N_STAGES + 1 + r;
            combine(&self.k, n, row, h, &self.y_old, &mut self.ytmp);
            let (_, ks) = self.k.split_at_mut(s * n);
            self.rhs.eval(self.t_old + C[s] * h, &self.ytmp, &mut ks[..n]);
        }
        self.n_fev += 3;
        let (f0, rest) = self.dense_f.split_at_mut(n);
        let (f1, rest) = rest.split_at_mut(n);
        let (f2, rest) = rest.split_at_mut(n);
        for i in 0..n {
            let dy = self.y[i] - self.y_old[i];
            let f_old = self.k[i];
            f0[i] = dy;
            f1[i] = h * f_old - dy;
            f2[i] = 2.0 * dy - h * (self.f[i] + f_old);
        }
        for (r, row) in D.iter().enumerate() {
            let out = &mut rest[r * n..(r + 1) * n];
            lincomb(&self.k, n, row, out);
            for o in out.iter_mut() {
                *o *= h;
            }
        }
        self.dense_ready = true;
    }

    /// The dense output (order 7) of the last accepted step at `t` in
    /// `[t_old, t]` (extrapolates outside), into `out`; the first call after
    /// a step costs 3 evaluations of the right-hand side.
    pub fn dense(&mut self, t: f64, out: &mut [f64]) {
        if !self.dense_ready {
            self.prepare_dense();
        }
        let n = self.n;
        let x = (t - self.t_old) / self.h_previous;
        let x1 = 1.0 - x;
        let fd = &self.dense_f;
        // Horner-like scheme of scipy's Dop853DenseOutput: F[6] .. F[0],
        // alternately multiplied by x and (1 - x).
        for i in 0..n {
            let mut y = 0.0;
            for (m, r) in (0..7).rev().enumerate() {
                y += fd[r * n + i];
                y *= if m % 2 == 0 { x } else { x1 };
            }
            out[i] = y + self.y_old[i];
        }
    }

    /// The dense output at `t` (as [`Self::dense`]) once
    /// [`Self::prepare_dense`] ran after the last step; `false` before.
    pub fn dense_at(&self, t: f64, out: &mut [f64]) -> bool {
        if !self.dense_ready || self.h_previous == 0.0 {
            return false;
        }
        let n = self.n;
        let x = (t - self.t_old) / self.h_previous;
        let x1 = 1.0 - x;
        let fd = &self.dense_f;
        for i in 0..n {
            let mut y = 0.0;
            for (m, r) in (0..7).rev().enumerate() {
                y += fd[r * n + i];
                y *= if m % 2 == 0 { x } else { x1 };
            }
            out[i] = y + self.y_old[i];
        }
        true
    }

    /// The time derivative of the dense output at `t` (the polynomial's
    /// own, differentiated through the same scheme); `false` before
    /// [`Self::prepare_dense`].
    pub fn dense_derivative_at(&self, t: f64, out: &mut [f64]) -> bool {
        if !self.dense_ready || self.h_previous == 0.0 {
            return false;
        }
        let n = self.n;
        let x = (t - self.t_old) / self.h_previous;
        let x1 = 1.0 - x;
        let fd = &self.dense_f;
        for i in 0..n {
            let (mut y, mut dy) = (0.0, 0.0);
            for (m, r) in (0..7).rev().enumerate() {
                y += fd[r * n + i];
                let (factor, dfactor) = if m % 2 == 0 { (x, 1.0) } else { (x1, -1.0) };
                dy = dy * factor + y * dfactor;
                y *= factor;
            }
            out[i] = dy / self.h_previous;
        }
        true
    }

    /// A bound on `|sum_j w_j y_(offset + j)(t)|` over the last step: the
    /// dense output `y_old + x (F0 + (1 - x) (F1 + x (F2 + ...)))` (`x` the
    /// step's fraction) weighed by `w` is a polynomial of degree 7 in
    /// `x`, no larger on `[0, 1]` than its largest coefficient in the
    /// Bernstein basis (their convex hull holds it); `None` before
    /// [`Self::prepare_dense`].
    pub fn dense_dot_bound(&self, w: &[f64], offset: usize) -> Option<f64> {
        if !self.dense_ready || self.h_previous == 0.0 {
            return None;
        }
        let n = self.n;
        let dot = |v: &[f64]| w.iter().zip(&v[offset..offset + w.len()]).map(|(a, b)| a * b).sum::<f64>();
        // Monomial coefficients, from the innermost factor out.
        const DEG: usize = 7;
        let mut p = [0.0; DEG + 1];
        for r in (0..7).rev() {
            p[0] += dot(&self.dense_f[r * n..(r + 1) * n]);
            let mut next = [0.0; DEG + 1];
            for i in 0..DEG {
                if r % 2 == 0 {
                    // times x
                    next[i + 1] += p[i];
                } else {
                    // times (1 - x)
                    next[i] += p[i];
                    next[i + 1] -= p[i];
                }
            }
            p = next;
        }
        p[0] += dot(&self.y_old);
        // Bernstein coefficients b_i = sum_(j <= i) C(i, j) / C(DEG, j) a_j.
        let binom = |a: usize, b: usize| (0..b).fold(1.0, |acc, k| acc * (a - k) as f64 / (k + 1) as f64);
        let bound = (0..=DEG).map(|i| (0..=i).map(|j| binom(i, j) / binom(DEG, j) * p[j]).sum::<f64>().abs()).fold(0.0, f64::max);
        Some(bound)
    }

    /// A bound on `|y_(offset + j)(t)|` over the last step for each `j` in
    /// `0..out.len()`, into `out` ([`Self::dense_dot_bound`] with a unit
    /// row each, formed component by component); `false` before the dense
    /// output is ready.
    pub fn dense_component_bounds(&self, offset: usize, out: &mut [f64]) -> bool {
        if !self.dense_ready || self.h_previous == 0.0 {
            return false;
        }
        let n = self.n;
        const DEG: usize = 7;
        let binom = |a: usize, b: usize| (0..b).fold(1.0, |acc, k| acc * (a - k) as f64 / (k + 1) as f64);
        // The Bernstein coefficients' weights, `C(i, j) / C(DEG, j)`.
        let weights: [[f64; DEG + 1]; DEG + 1] = std::array::from_fn(|i| std::array::from_fn(|j| if j <= i { binom(i, j) / binom(DEG, j) } else { 0.0 }));
        for (j, o) in out.iter_mut().enumerate() {
            let c = offset + j;
            let mut p = [0.0; DEG + 1];
            for r in (0..7).rev() {
                p[0] += self.dense_f[r * n + c];
                let mut next = [0.0; DEG + 1];
                for i in 0..DEG {
                    if r % 2 == 0 {
                        next[i + 1] += p[i];
                    } else {
                        next[i] += p[i];
                        next[i + 1] -= p[i];
                    }
                }
                p = next;
            }
            p[0] += self.y_old[c];
            *o = (0..=DEG).map(|i| (0..=i).map(|k| weights[i][k] * p[k]).sum::<f64>().abs()).fold(0.0, f64::max);
        }
        true
    }

    /// `sum_i w_i y_i(t)` from the dense output, over the first `w.len()`
    /// components (a scalar event function without the full state).
    pub fn dense_dot(&mut self, t: f64, w: &[f64]) -> f64 {
        if !self.dense_ready {
            self.prepare_dense();
        }
        let n = self.n;
        let x = (t - self.t_old) / self.h_previous;
        let x1 = 1.0 - x;
        let fd = &self.dense_f;
        let mut acc = 0.0;
        for (i, wi) in w.iter().enumerate() {
            let mut y = 0.0;
            for (m, r) in (0..7).rev().enumerate() {
                y += fd[r * n + i];
                y *= if m % 2 == 0 { x } else { x1 };
            }
            acc += wi * (y + self.y_old[i]);
        }
        acc
    }
}

/// The next representable f64 above `x` (finite `x`).
fn next_up(x: f64) -> f64 {
    if x.is_nan() || x == f64::INFINITY {
        return x;
    }
    if x == 0.0 {
        return f64::from_bits(1);
    }
    let b = x.to_bits();
    f64::from_bits(if x > 0.0 { b + 1 } else { b - 1 })
}

/// A self-check (run by the example, since example tests are not run by
/// `cargo test`): the damped harmonic oscillator `y'' + 2 a y' + w^2 y =
/// cos(W t)` against its closed form at rtol 1e-12, end point and dense
/// output at mid-steps. Returns `(end error, dense error, steps)`.
pub fn self_check() -> (f64, f64, usize) {
    // Undamped, unforced first: y = cos(w t), exact everywhere.
    let w = 3.0;
    let exact = |t: f64| [(w * t).cos(), -w * (w * t).sin()];
    let rhs = move |_t: f64, y: &[f64], dy: &mut [f64]| {
        dy[0] = y[1];
        dy[1] = -w * w * y[0];
    };
    let t_end = 10.0;
    let mut s = Dop853::new(rhs, 0.0, &[1.0, 0.0], t_end, 1e-12, &[1e-12], None);
    let mut dense_err: f64 = 0.0;
    let mut out = [0.0; 2];
    while s.t < t_end {
        let (a, b) = s.step().expect("step");
        for frac in [0.25, 0.5, 0.75] {
            let tm = a + frac * (b - a);
            s.dense(tm, &mut out);
            let e = exact(tm);
            dense_err = dense_err.max((out[0] - e[0]).abs()).max((out[1] - e[1]).abs() / w);
        }
    }
    let e = exact(t_end);
    let end_err = (s.y()[0] - e[0]).abs().max((s.y()[1] - e[1]).abs() / w);
    let steps = s.n_accepted;

    // Non-autonomous: y'' + w^2 y = cos(W t), y(0) = y'(0) = 0
    // (checks the nodes c_i, which an autonomous test cannot see):
    // y = (cos(W t) - cos(w t)) / (w^2 - W^2).
    let big_w = 1.7;
    let forced = move |t: f64| ((big_w * t).cos() - (w * t).cos()) / (w * w - big_w * big_w);
    let rhs2 = move |t: f64, y: &[f64], dy: &mut [f64]| {
        dy[0] = y[1];
        dy[1] = (big_w * t).cos() - w * w * y[0];
    };
    let mut s2 = Dop853::new(rhs2, 0.0, &[0.0, 0.0], t_end, 1e-12, &[1e-12], None);
    let mut forced_err: f64 = 0.0;
    while s2.t < t_end {
        let (a, b) = s2.step().expect("step");
        let tm = 0.5 * (a + b);
        s2.dense(tm, &mut out);
        forced_err = forced_err.max((out[0] - forced(tm)).abs()).max((s2.y()[0] - forced(b)).abs());
    }
    (end_err.max(forced_err), dense_err.max(forced_err), steps)
}

#[cfg(test)]
mod tests {
    /// The method against closed forms (undamped and forced oscillators),
    /// and the dense output's derivative against a central difference.
    #[test]
    fn matches_closed_forms() {
        let (end_err, dense_err, steps) = super::self_check();
        assert!(end_err < 1e-10 && dense_err < 1e-9, "end {end_err:e}, dense {dense_err:e}");
        assert!(steps > 10);
        let w = 3.0;
        let rhs = move |_t: f64, y: &[f64], dy: &mut [f64]| {
            dy[0] = y[1];
            dy[1] = -w * w * y[0];
        };
        let mut s = super::Dop853::new(rhs, 0.0, &[1.0, 0.0], 10.0, 1e-12, &[1e-12], None);
        s.step().unwrap();
        s.prepare_dense();
        let (a, b) = s.last_step();
        let (mut d, mut p, mut m) = ([0.0; 2], [0.0; 2], [0.0; 2]);
        let tm = a + 0.3 * (b - a);
        let eps = 1e-6 * (b - a);
        assert!(s.dense_derivative_at(tm, &mut d));
        s.dense_at(tm + eps, &mut p);
        s.dense_at(tm - eps, &mut m);
        for i in 0..2 {
            let fd = (p[i] - m[i]) / (2.0 * eps);
            assert!((d[i] - fd).abs() < 1e-7 * (1.0 + fd.abs()), "component {i}: {} against {fd}", d[i]);
        }
        // And against the equation: y' = v.
        let mut y = [0.0; 2];
        s.dense_at(tm, &mut y);
        assert!((d[0] - y[1]).abs() < 1e-9, "{} against {}", d[0], y[1]);
    }

    /// The dense output's bound on a weighted velocity holds at every
    /// point of a step long enough for the velocity to change sign, and
    /// is within 1.5 times the largest value there.
    #[test]
    fn dense_dot_bound_covers_the_step() {
        let w = 3.0;
        let rhs = move |_t: f64, y: &[f64], dy: &mut [f64]| {
            dy[0] = y[1];
            dy[1] = -w * w * y[0];
        };
        let mut s = super::Dop853::new(rhs, 0.0, &[1.0, 0.0], 10.0, 1e-3, &[1e-3], None);
        for _ in 0..3 {
            s.step().unwrap();
        }
        s.prepare_dense();
        let (a, b) = s.last_step();
        assert!(w * (b - a) > 0.5, "a long step: {}", b - a);
        let bound = s.dense_dot_bound(&[2.0], 1).unwrap();
        let mut y = [0.0; 2];
        let largest = (0..=1000).fold(0.0f64, |m, i| {
            s.dense_at(a + (b - a) * i as f64 / 1000.0, &mut y);
            m.max((2.0 * y[1]).abs())
        });
        assert!(largest <= bound && bound < 1.5 * largest, "largest {largest}, bound {bound}");
        // Component by component: the unit rows' bounds, bit for bit.
        let mut each = [0.0; 2];
        assert!(s.dense_component_bounds(0, &mut each));
        for (j, unit) in [[1.0, 0.0], [0.0, 1.0]].iter().enumerate() {
            assert_eq!(each[j], s.dense_dot_bound(unit, 0).unwrap(), "component {j}");
        }
    }
}
