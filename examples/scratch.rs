use beamstop::interface::ParamKey;
use beamstop::{Model, Scene, Simulation};
use std::time::Instant;
fn main() {
    let mut s = Scene::from_json(&std::fs::read_to_string("scenes/wagg_bishop_cantilever_4mode.json").unwrap()).unwrap();
    ParamKey::LoadOmega(0).set(&mut s, 246740.11002723395);
    ParamKey::InitialQ(1).set(&mut s, -1000.0);
    let m = Model::build(&s).unwrap();
    println!("balance {} cap {}", m.energy_balance, m.max_probes_per_step);
    let mut sim = Simulation::new(m, 0.0).unwrap();
    for k in 1..=5 {
        let t0 = Instant::now();
        let r = sim.advance_to(k as f64 * 1.0);
        println!("{:?} t={} {:?} {:?}", r.err(), sim.time(), t0.elapsed(), sim.stats());
    }
}
