use beamstop::{Model, Scene, Simulation, EventKind};
fn main() {
    let text = std::fs::read_to_string("scenes/pinned_beam.json").unwrap();
    let mut scene = Scene::from_json(&text).unwrap();
    let args: Vec<String> = std::env::args().collect();
    let which = args.get(1).map(String::as_str).unwrap_or("fig4");
    if which == "free" {
        use beamstop::interface::ParamKey;
        ParamKey::LoadAmplitude(0).set(&mut scene, 0.0);
        ParamKey::Restitution(0).set(&mut scene, 1.0);
        ParamKey::Zeta.set(&mut scene, 0.0);
        ParamKey::InitialQ(0).set(&mut scene, -3.0 / 2f64.sqrt());
    }
    if which == "p2" {
        use beamstop::interface::ParamKey;
        ParamKey::LoadAmplitude(0).set(&mut scene, 72.0);
        ParamKey::LoadOmega(0).set(&mut scene, 0.7 * std::f64::consts::PI.powi(2));
        ParamKey::StopGap(0).set(&mut scene, 1.2);
        ParamKey::ChatterEps(0).set(&mut scene, 1e-3);
    }
    let model = Model::build(&scene).unwrap();
    let mut sim = Simulation::new(model, 0.0).unwrap();
    let e0 = sim.energy();
    let t_end: f64 = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(20.0);
    let t0 = std::time::Instant::now();
    if let Err(e) = sim.advance_to(t_end) { let ev = sim.drain_events(); for x in ev.iter().take(12) { println!("{:.17} {:?}", x.time, x.kind); } println!("... {} events; err {e:?}", ev.len()); return; }
    let el = t0.elapsed();
    let evs = sim.drain_events();
    let mut last = f64::NAN;
    for e in &evs {
        match &e.kind {
            EventKind::Impact { speed, restitution, chatter, .. } => { println!("{:.15} impact v={speed:.3e} R={restitution} chatter={chatter} dt={:.3e}", e.time, e.time - last); last = e.time; }
            k => println!("{:.15} {:?}", e.time, k),
        }
    }
    println!("{:?}", sim.stats());
    println!("events {} energy {} -> {} rel {:.3e}; elapsed {:?}", evs.len(), e0, sim.energy(), (sim.energy()-e0)/e0, el);
    println!("first impact - 1/(2pi) = {:.3e}", evs.first().map(|e| e.time).unwrap_or(0.0) - 1.0/(2.0*std::f64::consts::PI));
}
#[allow(dead_code)]
fn unused() {}
