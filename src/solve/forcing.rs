//! Loads projected on the modes: `f(t) = c + sum_h Re(b_h e^{i Omega_h t})`.

use nalgebra::DVector;

use super::oscillator::C64;

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
            let factor = C64::from_polar(1.0, h.omega * a) * super::oscillator::phi1(C64::new(0.0, h.omega * span)) * span;
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
            let factor = C64::from_polar(1.0, h.omega * t) * C64::new(0.0, h.omega).powu(m);
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
                *r = C64::from_polar(1.0, h.omega * t);
            }
            self.derivatives_rotated(&buffer[..self.harmonics.len()], out);
        } else {
            let rotations: Vec<C64> = self.harmonics.iter().map(|h| C64::from_polar(1.0, h.omega * t)).collect();
            self.derivatives_rotated(&rotations, out);
        }
    }

    /// As [`Self::derivatives`], given `e^{i Omega t}` of every harmonic.
    pub fn derivatives_rotated(&self, rotations: &[C64], out: &mut [DVector<f64>]) {
        let constant = self.constant.as_slice();
        for (m, o) in out.iter_mut().enumerate() {
            let o = o.as_mut_slice();
            if m == 0 {
                let n = o.len().min(constant.len());
                o[..n].copy_from_slice(&constant[..n]);
            } else {
                o.fill(0.0);
            }
        }
        for (h, &rotation) in self.harmonics.iter().zip(rotations) {
            let mut factor = rotation;
            let amplitude = h.amplitude.as_slice();
            for o in out.iter_mut() {
                let o = o.as_mut_slice();
                let n = o.len().min(amplitude.len());
                for (x, b) in o[..n].iter_mut().zip(&amplitude[..n]) {
                    *x += b.re * factor.re - b.im * factor.im;
                }
                // Times i Omega.
                factor = C64::new(-h.omega * factor.im, h.omega * factor.re);
            }
        }
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
