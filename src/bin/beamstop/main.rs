//! The beamstop command line.
//!
//!   beamstop package [--fmi3] [scene.json ...]
//!                                        build FMUs into target/fmu (FMI 3.0: target/fmu3; default: every scene in scenes/)
//!   beamstop run [scene.json] [--stop T] [--step H] [--out DIR]
//!                                        simulate a scene natively, write CSV results
//!   beamstop describe [--fmi3] scene.json  print the modelDescription.xml of a scene
//!   beamstop describe [--fmi3] --contents scene.json
//!                                        what the scene's FMU binary carries
//!   beamstop variants                    the prebuilt FMU binaries and their Cargo features
//!   beamstop model-descriptions          rewrite modelDescription/<Name>.xml (FMI 3.0: modelDescription/fmi3/) for scenes/
//!   beamstop check scene.json ...        validate scenes
//!   beamstop modes SUPPORT N [X ...]     dimensionless beam modes as JSON
//!   beamstop orbits SCENE.json --param NAME=FROM:TO ... --out DIR
//!                                        periodic orbits continued in a parameter (orbits.rs)

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use beamstop::kind::Run;
use beamstop::package::{variants, write_fmu, FmiVersion};
use beamstop::variables::Value;
use beamstop::Component;

const USAGE: &str = "usage (an option's value as `--name value` or `--name=value`; `beamstop help [COMMAND]`,
`beamstop [COMMAND] --help` print this):
  beamstop package [--fmi3] [scene.json ...]
                                          build FMI 2.0 FMUs into target/fmu, with --fmi3 FMI 3.0 FMUs into
                                          target/fmu3 (default: every scene in scenes/)
  beamstop run [scene.json] [--stop T] [--step H] [--out DIR]
                                          simulate a scene natively (default: scenes/pinned_beam.json)
  beamstop describe [--fmi3] scene.json  print the scene's modelDescription.xml (FMI 2.0, or 3.0)
  beamstop describe [--fmi3] --contents scene.json
                                          what its FMU's binary carries: the smallest prebuilt variant
                                          with its kind and laws (kinds, laws, solvers, standard)
  beamstop variants                      the prebuilt FMU binaries (target/variants/<name>) and the
                                          Cargo features of fmu/ that build them (scripts/build-variants)
  beamstop model-descriptions            rewrite modelDescription/<Name>.xml (FMI 2.0) and
                                          modelDescription/fmi3/<Name>.xml for every scene in scenes/
  beamstop check scene.json ...          validate scene files
  beamstop modes SUPPORT N [X ...]       beta_j and W_j(X), W_j''(X) of the unit-mean-square shapes
                                          (SUPPORT: pinned-pinned, clamped-free, clamped-clamped, clamped-pinned)";

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn load(path: &Path) -> Result<Component, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    Component::from_json(&text).map_err(|e| format!("{}: {e}", path.display()))
}

/// Every scene file in scenes/, sorted.
fn builtin_scenes() -> Result<Vec<PathBuf>, String> {
    let dir = root().join("scenes");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map_err(|e| format!("{}: {e}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .collect();
    files.sort();
    Ok(files)
}

/// The standard `--fmi3` asks for.
fn version(args: &Args) -> FmiVersion {
    if args.flag("fmi3") {
        FmiVersion::Fmi3
    } else {
        FmiVersion::Fmi2
    }
}

fn package(args: &[String]) -> Result<(), String> {
    let args = parse(args, &[], &["fmi3"]).map_err(|e| format!("package: {e}"))?;
    let version = version(&args);
    let files = if args.positional.is_empty() { builtin_scenes()? } else { args.positional.iter().map(PathBuf::from).collect() };
    // Validate everything first: no FMU is written from an invalid scene.
    let scenes: Vec<Component> = files.iter().map(|f| load(f)).collect::<Result<_, _>>()?;
    // Each scene gets the smallest prebuilt binary that carries it.
    let dir = variants::variants_dir()?;
    let binaries: Vec<PathBuf> = scenes.iter().map(|s| variants::binary(&dir, variants::covering(s)?, version)).collect::<Result<_, _>>()?;
    let out = root().join("target").join(match version {
        FmiVersion::Fmi2 => "fmu",
        FmiVersion::Fmi3 => "fmu3",
    });
    for (scene, binary) in scenes.iter().zip(&binaries) {
        let path = write_fmu(scene, binary, &out, version)?;
        println!("{}", path.display());
    }
    Ok(())
}

/// `beamstop variants`: one line per prebuilt FMU binary, its directory
/// name and the Cargo features of fmu/ that build it (for
/// scripts/build-variants).
fn list_variants() {
    for version in [FmiVersion::Fmi2, FmiVersion::Fmi3] {
        for v in &variants::VARIANTS {
            println!("{} {}", v.build_name(version), v.features(version).join(","));
        }
    }
}

/// `beamstop describe --contents scene.json`: the binary an FMU of the
/// scene carries (variant, kinds, laws, solvers, standard).
fn describe_contents(scene: &Component, version: FmiVersion) -> Result<(), String> {
    let variant = variants::covering(scene)?;
    for (part, names) in variant.contents(version) {
        println!("{part}: {}", names.join(", "));
    }
    Ok(())
}

fn run(args: &[String]) -> Result<(), String> {
    let args = parse(args, &["stop", "step", "out"], &[]).map_err(|e| format!("run: {e}"))?;
    if args.positional.len() > 1 {
        return Err(format!("run: one scene file at most (given {})", args.positional.join(", ")));
    }
    let positional = &args.positional;
    let file = positional.first().map(PathBuf::from).unwrap_or_else(|| root().join("scenes").join("pinned_beam.json"));
    let scene = load(&file)?;
    let experiment = scene.experiment();
    let stop = args.number("stop")?.unwrap_or(experiment.stop);
    let step = args.number("step")?.unwrap_or(experiment.step);
    if !(step > 0.0) {
        return Err(format!("--step {step}: must be > 0"));
    }
    let out_dir = args.single("out")?.map(PathBuf::from).unwrap_or_else(|| root().join("target").join("results"));
    std::fs::create_dir_all(&out_dir).map_err(|e| format!("{}: {e}", out_dir.display()))?;
    let start = experiment.start;
    // The model (modes, projections, matrices) is built at the start.
    let building = std::time::Instant::now();
    let mut sim = scene.start(start, &vec![0.0; scene.inputs().len()])?;
    let build = building.elapsed();
    sim.set_event_recording(true);
    let outputs = scene.outputs();
    let mut csv = String::from("time");
    for o in outputs {
        csv.push(',');
        csv.push_str(&o.name);
    }
    csv.push('\n');
    let mut events = String::from("time,event,stop,detail\n");
    let clock = std::time::Instant::now();
    let n = ((stop - start) / step).round() as u64;
    // Every output read at every step; the text is made after the clock
    // stops (formatting the numbers costs as much as a fine grid's run).
    let mut rows: Vec<(f64, Vec<Value>)> = Vec::with_capacity(n as usize + 1);
    for k in 0..=n {
        let t = if k == n { stop } else { start + k as f64 * step };
        sim.advance_to(t).map_err(|e| e.to_string())?;
        rows.push((t, (0..outputs.len()).map(|i| sim.evaluate(i)).collect()));
        event_rows(sim.as_mut(), &mut events);
    }
    let elapsed = clock.elapsed();
    for (t, values) in rows {
        let _ = write!(csv, "{t}");
        for v in values {
            let _ = match v {
                Value::Real(x) => write!(csv, ",{x}"),
                Value::Integer(i) => write!(csv, ",{i}"),
                Value::Boolean(b) => write!(csv, ",{}", b as u8),
            };
        }
        csv.push('\n');
    }
    let results = out_dir.join(format!("{}.csv", scene.name()));
    let event_file = out_dir.join(format!("{}_events.csv", scene.name()));
    std::fs::write(&results, csv).map_err(|e| format!("{}: {e}", results.display()))?;
    std::fs::write(&event_file, events).map_err(|e| format!("{}: {e}", event_file.display()))?;
    let w = sim.work();
    let work = format!("{} events, {} {}", w.events, w.units, w.unit);
    println!("{}: t = {start}..{stop}, step {step}: {work}, {:.3} ms (the model's build before it: {:.3} ms)", scene.name(), elapsed.as_secs_f64() * 1e3, build.as_secs_f64() * 1e3);
    println!("results: {}", results.display());
    println!("events:  {}", event_file.display());
    Ok(())
}

/// Appends the events since the last call as CSV rows `time,event,stop,detail`.
fn event_rows(sim: &mut dyn Run, out: &mut String) {
    for e in sim.drain_events() {
        out.push_str(&format!("{:.17},{},{},{}\n", e.time, e.class.word(), e.at, e.detail));
    }
}

/// The dimensionless modes of a beam as JSON, for independent checks.
fn modes(args: &[String]) -> Result<(), String> {
    use beamstop::structure::beam::DimensionlessMode;
    use beamstop::structure::Support;
    let support = match args.first().map(String::as_str) {
        Some("pinned-pinned") => Support::PinnedPinned,
        Some("clamped-free") => Support::ClampedFree,
        Some("clamped-clamped") => Support::ClampedClamped,
        Some("clamped-pinned") => Support::ClampedPinned,
        other => return Err(format!("modes: unknown support {other:?}\n{USAGE}")),
    };
    let n: usize = args.get(1).and_then(|s| s.parse().ok()).filter(|n| (1..=500).contains(n)).ok_or("modes: N must be in 1..=500")?;
    let xs: Vec<f64> = args[2..].iter().map(|s| s.parse::<f64>().map_err(|_| format!("modes: {s} is not a number"))).collect::<Result<_, _>>()?;
    let list: Vec<serde_json::Value> = (1..=n)
        .map(|j| {
            let m = DimensionlessMode::new(support, j);
            serde_json::json!({
                "j": j,
                "beta": m.beta,
                "shape": xs.iter().map(|&x| m.derivative(0, x)).collect::<Vec<f64>>(),
                "curvature": xs.iter().map(|&x| m.derivative(2, x)).collect::<Vec<f64>>(),
            })
        })
        .collect();
    println!("{}", serde_json::json!({ "x": xs, "modes": list }));
    Ok(())
}

mod args;
mod orbits;

use args::{is_help, parse, Args};

/// `describe [--fmi3] [--contents] scene.json`.
fn describe(args: &[String]) -> Result<(), String> {
    let args = parse(args, &[], &["fmi3", "contents"]).map_err(|e| format!("describe: {e}"))?;
    let [file] = args.positional.as_slice() else {
        return Err(format!("describe: one scene file (given {})\n{USAGE}", args.positional.len()));
    };
    let scene = load(Path::new(file))?;
    if args.flag("contents") {
        describe_contents(&scene, version(&args))
    } else {
        version(&args).model_description(&scene).map(|x| print!("{x}"))
    }
}

/// What `beamstop [COMMAND] --help` prints.
fn help(command: Option<&str>) -> String {
    match command {
        Some("orbits") => format!("usage:\n{}", orbits::USAGE),
        _ => format!("{USAGE}\n{}", orbits::USAGE),
    }
}

fn main() -> ExitCode {
    // Output piped into a reader that stops early (`beamstop variants |
    // head -1`) ends the command quietly, as a Unix tool does, instead of
    // a panic on the closed pipe: Rust ignores SIGPIPE by default.
    // SAFETY: restores the default action of one signal before any thread
    // starts; no handler is installed.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let args: Vec<String> = std::env::args().skip(1).collect();
    // `beamstop help [COMMAND]`, `beamstop [COMMAND] --help` (or -h): the usage, on stdout.
    if args.first().is_some_and(|a| a == "help") {
        println!("{}", help(args.get(1).map(String::as_str)));
        return ExitCode::SUCCESS;
    }
    if args.iter().any(|a| is_help(a)) {
        println!("{}", help(args.first().map(String::as_str).filter(|a| !is_help(a))));
        return ExitCode::SUCCESS;
    }
    let result = match args.first().map(String::as_str) {
        Some("package") => package(&args[1..]),
        Some("run") => run(&args[1..]),
        Some("describe") => describe(&args[1..]),
        Some("variants") => {
            list_variants();
            Ok(())
        }
        Some("model-descriptions") => builtin_scenes().and_then(|files| {
            for (version, dir) in [(FmiVersion::Fmi2, root().join("modelDescription")), (FmiVersion::Fmi3, root().join("modelDescription").join("fmi3"))] {
                std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
                for f in &files {
                    let scene = load(f)?;
                    let path = dir.join(format!("{}.xml", scene.name()));
                    std::fs::write(&path, version.model_description(&scene)?).map_err(|e| format!("{}: {e}", path.display()))?;
                    println!("{}", path.display());
                }
            }
            Ok(())
        }),
        Some("modes") => modes(&args[1..]),
        Some("orbits") => orbits::orbits(&args[1..], load),
        Some("check") if args.len() > 1 => args[1..].iter().try_for_each(|f| {
            load(Path::new(f)).map(|s| println!("{f}: ok ({}, GUID {})", s.name(), s.guid()))
        }),
        _ => Err(format!("{USAGE}\n{}", orbits::USAGE)),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("beamstop: {e}");
            ExitCode::FAILURE
        }
    }
}
