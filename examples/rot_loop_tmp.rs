use beamstop::kinds::rotating::{RotatingModel, RotatingSimulation};
use beamstop::kinds::rotating::spec::RotatingSpec;
use std::sync::Arc;
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let text = std::fs::read_to_string(&args[1]).unwrap();
    let spec: RotatingSpec = serde_json::from_str(&text).unwrap();
    let reps: usize = args[2].parse().unwrap();
    let model = Arc::new(RotatingModel::new(&spec).unwrap());
    let t0 = std::time::Instant::now();
    for _ in 0..reps {
        let mut sim = RotatingSimulation::new(model.clone(), 0.0).unwrap();
        sim.advance_to(0.05).unwrap();
    }
    eprintln!("{:.3} ms per run", t0.elapsed().as_secs_f64() * 1e3 / reps as f64);
}
