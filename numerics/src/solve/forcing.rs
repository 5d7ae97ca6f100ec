//! Loads projected on the modes: `f(t) = c + sum_h Re(b_h e^{i Omega_h t})`.

use nalgebra::DVector;

use super::elementary::unit;
use super::complex::C64;

/// One harmonic component: `Re(amplitude_j e^{i omega t})` on mode j.
#[derive(Clone, Debug, PartialEq)]
pub struct Harmonic {
    pub omega: f64,
    pub amplitude: DVector<C64>,
}

/// The modal load vector as an explicit function of time.
#[derive(Clone, Debug, PartialEq)]
pub struct ModalForcing {
    /// Constant part (held inputs, static loads, preload of compliant stops).
    pub constant: DVector<f64>,
    pub harmonics: Vec<Harmonic>,
}

impl ModalForcing {
    pub fn zero(n: usize) -> Self {
        ModalForcing { constant: DVector::zeros(n), harmonics: Vec::new() }
    }

    pub fn len(&self) -> usize {
        self.constant.len()
    }

    pub fn is_empty(&self) -> bool {
        self.constant.is_empty()
    }

    /// Adds `Re(amplitude e^{i omega t})`, merging equal frequencies.
    pub fn add_harmonic(&mut self, omega: f64, amplitude: DVector<C64>) {
        if let Some(h) = self.harmonics.iter_mut().find(|h| h.omega == omega) {
            h.amplitude += amplitude;
        } else {
            self.harmonics.push(Harmonic { omega, amplitude });
        }
    }

    /// `int_a^b f dt`, exact: `Re(b_h e^{i W a} (b - a) phi1(i W (b - a)))` per harmonic.
    pub fn integral(&self, a: f64, b: f64) -> DVector<f64> {
        let span = b - a;
        let mut out = &self.constant * span;
        for h in &self.harmonics {
            let factor = unit(h.omega * a) * super::oscillator::phi1(C64::new(0.0, h.omega * span)) * span;
            for (o, amp) in out.iter_mut().zip(h.amplitude.iter()) {
                *o += (amp * factor).re;
            }
        }
        out
    }

    /// `d^m f_j / dt^m` at time `t` for every mode, `m <= 3`.
    pub fn derivative(&self, t: f64, m: u32, out: &mut DVector<f64>) {
        if m == 0 {
            out.copy_from(&self.constant);
        } else {
            out.fill(0.0);
        }
        for h in &self.harmonics {
            // (i Omega)^m e^{i Omega t}
            let factor = unit(h.omega * t) * C64::new(0.0, h.omega).powu(m);
            for (o, b) in out.iter_mut().zip(h.amplitude.iter()) {
                *o += (b * factor).re;
            }
        }
    }

    /// `d^m f / dt^m` for m = 0..out.len() at time `t`, sharing the rotations.
    pub fn derivatives(&self, t: f64, out: &mut [DVector<f64>]) {
        let mut buffer = [C64::new(0.0, 0.0); 8];
        if self.harmonics.len() <= buffer.len() {
            for (r, h) in buffer.iter_mut().zip(&self.harmonics) {
                *r = unit(h.omega * t);
            }
            self.derivatives_rotated(&buffer[..self.harmonics.len()], out);
        } else {
            let rotations: Vec<C64> = self.harmonics.iter().map(|h| unit(h.omega * t)).collect();
            self.derivatives_rotated(&rotations, out);
        }
    }

    /// As [`Self::derivatives`] (at most 4 orders), given `e^{i Omega t}` of
    /// every harmonic; mode by mode ([`Self::mode_derivatives_rotated`]).
    pub fn derivatives_rotated(&self, rotations: &[C64], out: &mut [DVector<f64>]) {
        assert!(out.len() <= 4, "{} load derivatives asked for, at most 4", out.len());
        let n = out.iter().map(|o| o.len()).fold(self.constant.len(), usize::min);
        for j in 0..n {
            let values = self.mode_derivatives_rotated::<4>(j, rotations);
            for (o, v) in out.iter_mut().zip(&values) {
                o[j] = *v;
            }
        }
    }

    /// `d^m f_j / dt^m` of mode `j` for m = 0..M: the constant, then
    /// each harmonic's `Re(b (i Omega)^m e^{i Omega t})`, `(i Omega)^m` by
    /// repeated products.
    #[inline]
    pub fn mode_derivatives_rotated<const M: usize>(&self, j: usize, rotations: &[C64]) -> [f64; M] {
        let mut out = [0.0; M];
        // Slices, not nalgebra's indexing: this runs per mode per probe.
        if M > 0 {
            out[0] = self.constant.as_slice()[j];
        }
        for (h, &rotation) in self.harmonics.iter().zip(rotations) {
            let b = h.amplitude.as_slice()[j];
            let mut factor = rotation;
            for o in out.iter_mut() {
                *o += b.re * factor.re - b.im * factor.im;
                // Times i Omega.
                factor = C64::new(-h.omega * factor.im, h.omega * factor.re);
            }
        }
        out
    }

    /// Bounds `B[m][j] >= |d^m f_j / dt^m|` over all time, m = 0..=4.
    pub fn bounds(&self) -> [DVector<f64>; 5] {
        let n = self.len();
        std::array::from_fn(|m| DVector::from_fn(n, |j, _| self.bound(j, m as u32)))
    }

    /// A bound on `|d^m f_j / dt^m|` over all time.
    pub fn bound(&self, j: usize, m: u32) -> f64 {
        let mut b = if m == 0 { self.constant[j].abs() } else { 0.0 };
        for h in &self.harmonics {
            b += h.amplitude[j].norm() * h.omega.powi(m as i32);
        }
        b
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shared_derivatives_match_each_one_alone_and_a_finite_difference() {
        // A constant and three harmonics on three modes.
        let mut f = ModalForcing { constant: DVector::from_vec(vec![0.5, -1.0, 2.0]), harmonics: Vec::new() };
        f.add_harmonic(1.3, DVector::from_vec(vec![C64::new(1.0, 0.2), C64::new(0.0, -2.0), C64::new(0.3, 0.0)]));
        f.add_harmonic(7.0, DVector::from_vec(vec![C64::new(-0.4, 0.1), C64::new(0.5, 0.5), C64::new(0.0, 0.0)]));
        f.add_harmonic(0.2, DVector::from_vec(vec![C64::new(0.0, 3.0), C64::new(1.0, 0.0), C64::new(-2.0, 1.0)]));
        let t = 2.7;
        let mut all: [DVector<f64>; 4] = std::array::from_fn(|_| DVector::zeros(3));
        f.derivatives(t, &mut all);
        let mut one = DVector::zeros(3);
        for m in 0..4 {
            f.derivative(t, m, &mut one);
            assert!((&all[m as usize] - &one).amax() < 1e-12, "m = {m}: {} vs {one}", all[m as usize]);
        }
        // The first derivative against a central difference of the values.
        let (mut ahead, mut behind) = (DVector::zeros(3), DVector::zeros(3));
        let dt = 1e-6;
        f.derivative(t + dt, 0, &mut ahead);
        f.derivative(t - dt, 0, &mut behind);
        assert!(((ahead - behind) / (2.0 * dt) - &all[1]).amax() < 1e-6);
    }
}
