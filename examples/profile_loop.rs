// Profiling harness (not part of the report): runs S2 or S3 at N modes in a loop.
use std::f64::consts::PI;
use beamstop::interface::ParamKey;
use beamstop::scene::StructureSpec;
use beamstop::{Model, Scene, Simulation};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let which = args[1].clone();
    let n: usize = args[2].parse().unwrap();
    let reps: usize = args[3].parse().unwrap();
    let mut scene = Scene::from_json(&std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/pinned_beam.json")).unwrap()).unwrap();
    if let StructureSpec::Beam { modes, .. } = &mut scene.structure { *modes = n; }
    let t_end = if which == "S2" {
        ParamKey::LoadAmplitude(0).set(&mut scene, 72.0);
        ParamKey::LoadOmega(0).set(&mut scene, 0.7 * PI * PI);
        ParamKey::StopGap(0).set(&mut scene, 1.2);
        ParamKey::Law(0, 1).set(&mut scene, 1e-3);
        60.0 * 2.0 * PI / (0.7 * PI * PI)
    } else { 20.0 };
    scene.solver.max_probes_per_step = Some(u64::MAX / 2);
    let model = Model::build(&scene).unwrap();
    let mut total = 0;
    for _ in 0..reps {
        let mut sim = Simulation::new(model.clone(), 0.0).unwrap();
        sim.set_event_recording(false);
        sim.advance_to(t_end).unwrap();
        total += sim.stats().probes;
    }
    println!("{total}");
}
