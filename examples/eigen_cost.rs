//! Cost of one coupled-phase decomposition (a held stop on N modes).
use beamstop::solve::lti::CoupledSystem;
use nalgebra::{DMatrix, DVector};
use std::time::Instant;
fn main() {
    for n in [64usize, 128, 256, 500] {
        let k = DMatrix::from_diagonal(&DVector::from_fn(n, |j, _| ((j + 1) as f64).powi(4) * 97.4));
        let d = DMatrix::from_diagonal(&DVector::from_fn(n, |j, _| 0.1 * ((j + 1) as f64).powi(2) * 9.87));
        let w = DMatrix::from_fn(n, 1, |j, _| ((j + 1) as f64 * 0.37 * std::f64::consts::PI).sin());
        let t0 = Instant::now();
        let sys = CoupledSystem::new(k, d, w).unwrap();
        println!("N={n}: {:.3} s (fastest {:.3e})", t0.elapsed().as_secs_f64(), sys.fastest());
    }
}
