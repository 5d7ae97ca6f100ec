//! `beamstop orbits`: periodic orbits continued in one parameter
//! (`beamstop::orbits`), written as `branch.csv` and `special.csv`.

use std::path::PathBuf;

use beamstop::orbits::{continue_orbits, table, Continuation};
use beamstop::Component;
use nalgebra::DVector;

pub const USAGE: &str = "  beamstop orbits SCENE.json --param NAME=FROM:TO [--start VALUE ...] [--set NAME=VALUE ...]
                 [--tie NAME=SCALE*PARAM^POWER ...] [--from-state X1,X2,...] [--points N]
                 [--transient PERIODS] [--max-period M]
                 [--max-branches B] [--phase T0] [--forcing NAME] --out DIR
                                          continue the periodic orbits in parameter NAME over FROM..TO (the first
                                          orbits from simulated transients at each START, default FROM; or from the
                                          state [q; q'] given at phase T0), NAME tied to it by --tie as a power
                                          law: DIR/branch.csv, DIR/special.csv";

fn number(text: &str, what: &str) -> Result<f64, String> {
    text.trim().parse::<f64>().map_err(|_| format!("{what}: '{text}' is not a number"))
}

pub fn orbits(args: &[String], load: impl Fn(&std::path::Path) -> Result<Component, String>) -> Result<(), String> {
    let mut file = None;
    let mut range = None;
    let mut out = None;
    let mut sets = Vec::new();
    let mut ties = Vec::new();
    let mut options: Vec<(String, String)> = Vec::new();
    let mut i = 0;
    while i < args.len() {
        let a = &args[i];
        if let Some(name) = a.strip_prefix("--") {
            let value = args.get(i + 1).ok_or(format!("--{name} needs a value"))?.clone();
            match name {
                "param" => range = Some(value),
                "set" => sets.push(value),
                "out" => out = Some(PathBuf::from(value)),
                "tie" => ties.push(value),
                "start" | "from-state" | "points" | "transient" | "max-period" | "max-branches" | "phase" | "forcing" => options.push((name.into(), value)),
                _ => return Err(format!("orbits: unknown option --{name}\n{USAGE}")),
            }
            i += 2;
        } else {
            file = Some(PathBuf::from(a));
            i += 1;
        }
    }
    let file = file.ok_or(format!("orbits: a scene file is needed\n{USAGE}"))?;
    let range = range.ok_or(format!("orbits: --param NAME=FROM:TO is needed\n{USAGE}"))?;
    let out = out.ok_or(format!("orbits: --out DIR is needed\n{USAGE}"))?;
    let (name, ends) = range.split_once('=').ok_or(format!("--param {range}: NAME=FROM:TO"))?;
    let (from, to) = ends.split_once(':').ok_or(format!("--param {range}: NAME=FROM:TO"))?;
    let mut scene = load(&file)?;
    for set in &sets {
        let (n, v) = set.split_once('=').ok_or(format!("--set {set}: NAME=VALUE"))?;
        let index = scene.parameters().iter().position(|p| p.name == n).ok_or_else(|| {
            let names: Vec<&str> = scene.parameters().iter().map(|p| p.name.as_str()).collect();
            format!("--set {set}: the scene has no parameter '{n}' (it has {})", names.join(", "))
        })?;
        scene.set(index, number(v, &format!("--set {n}"))?);
        scene.validate().map_err(|e| format!("--set {set}: {e}"))?;
    }
    let mut settings = Continuation::new(name, number(from, "--param FROM")?, number(to, "--param TO")?);
    for (name, value) in &options {
        let what = format!("--{name}");
        let count = || -> Result<usize, String> { value.parse::<usize>().ok().filter(|&n| n >= 1).ok_or(format!("{what} {value}: a whole number >= 1")) };
        match name.as_str() {
            "start" => settings.starts.push(number(value, &what)?),
            "from-state" => {
                let x: Vec<f64> = value.split(',').map(|v| number(v, &what)).collect::<Result<_, _>>()?;
                settings.start_state = Some(DVector::from_vec(x));
            }
            "points" => settings.points = count()?,
            "transient" => settings.transient = count()?,
            "max-period" => settings.max_period = count()?,
            "max-branches" => settings.max_branches = count()?,
            "phase" => settings.t0 = number(value, &what)?,
            "forcing" => settings.forcing = Some(value.clone()),
            _ => unreachable!("options are checked above"),
        }
    }
    for tie in &ties {
        settings.tied.push(parse_tie(tie, name)?);
    }
    let clock = std::time::Instant::now();
    let diagram = continue_orbits(&scene, &settings)?;
    let seconds = clock.elapsed().as_secs_f64();
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    for (file, text) in [("branch.csv", table::branches_csv(&diagram)), ("special.csv", table::special_csv(&diagram))] {
        let path = out.join(file);
        std::fs::write(&path, text).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    for b in &diagram.branches {
        let (lo, hi) = b.points.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| (l.min(p.param), h.max(p.param)));
        let stable = b.points.iter().filter(|p| p.orbit.stable()).count();
        println!("branch {}: period {} T, {} points ({stable} stable), {name} = {lo} .. {hi}", b.index, b.periods, b.points.len());
    }
    for s in &diagram.special {
        println!("  {} on branch {} at {name} = {}: {}", s.kind.code(), s.branch, s.point.param, s.note);
    }
    for note in &diagram.notes {
        println!("  note: {note}");
    }
    println!("{} map evaluations in {seconds:.3} s; {}", diagram.evaluations, out.display());
    Ok(())
}

/// `NAME=SCALE*PARAM^POWER` (or `PARAM^POWER`, `SCALE*PARAM`, `**` for `^`).
fn parse_tie(text: &str, param: &str) -> Result<(String, f64, f64), String> {
    let bad = || format!("--tie {text}: NAME=SCALE*{param}^POWER");
    let (name, law) = text.split_once('=').ok_or_else(bad)?;
    let law = law.replace("**", "^").replace(' ', "");
    let (scale, rest) = match law.split_once('*') {
        Some((scale, rest)) => (number(scale, "--tie SCALE")?, rest.to_string()),
        None => (1.0, law.clone()),
    };
    let (base, power) = match rest.split_once('^') {
        Some((base, power)) => (base.to_string(), number(power, "--tie POWER")?),
        None => (rest.clone(), 1.0),
    };
    if base != param {
        return Err(format!("{}: the law must be in the continued parameter {param}", bad()));
    }
    Ok((name.to_string(), scale, power))
}
