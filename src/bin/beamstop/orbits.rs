//! `beamstop orbits`: periodic orbits continued in one parameter
//! (`beamstop::orbits`), written as `branch.csv` and `special.csv`.

use std::path::PathBuf;

use super::args::parse;
use std::fs::File;
use std::io::Write;
use std::path::Path;
use std::time::Instant;

use beamstop::orbits::{continue_orbits_observed, table, Branch, Continuation, Observer, Point, Special};
use beamstop::Component;
use nalgebra::DVector;

pub const USAGE: &str = "  beamstop orbits SCENE.json --param NAME=FROM:TO [--start VALUE ...] [--set NAME=VALUE ...]
                 [--tie NAME=SCALE*PARAM^POWER ...] [--from-state X1,X2,...] [--points N]
                 [--transient PERIODS] [--max-period M]
                 [--max-branches B] [--phase T0] [--forcing NAME] [--progress SECONDS] --out DIR
                                          continue the periodic orbits in parameter NAME over FROM..TO (the first
                                          orbits from simulated transients at each START, default FROM, then TO
                                          and the middles of stretches no branch reached; or from the
                                          state [q; q'] given at phase T0), NAME tied to it by --tie as a power
                                          law: DIR/branch.csv, DIR/special.csv, each branch's rows written as it
                                          ends; progress on stderr (each branch, and every SECONDS, default 10).
                                          A parameter is held (--set) or tied (--tie) once, and never the continued one";

fn number(text: &str, what: &str) -> Result<f64, String> {
    text.trim().parse::<f64>().map_err(|_| format!("{what}: '{text}' is not a number"))
}

/// Options that take a value.
const VALUED: [&str; 13] =
    ["param", "set", "tie", "out", "start", "from-state", "points", "transient", "max-period", "max-branches", "phase", "forcing", "progress"];

pub fn orbits(args: &[String], load: impl Fn(&std::path::Path) -> Result<Component, String>) -> Result<(), String> {
    let args = parse(args, &VALUED, &[]).map_err(|e| format!("orbits: {e}\n{USAGE}"))?;
    let file = match args.positional.as_slice() {
        [file] => PathBuf::from(file),
        [] => return Err(format!("orbits: a scene file is needed\n{USAGE}")),
        more => return Err(format!("orbits: one scene file (given {})", more.join(", "))),
    };
    let range = args.single("param")?.ok_or(format!("orbits: --param NAME=FROM:TO is needed\n{USAGE}"))?;
    let out = PathBuf::from(args.single("out")?.ok_or(format!("orbits: --out DIR is needed\n{USAGE}"))?);
    let (name, ends) = range.split_once('=').ok_or(format!("--param {range}: NAME=FROM:TO"))?;
    let (from, to) = ends.split_once(':').ok_or(format!("--param {range}: NAME=FROM:TO"))?;
    let values = |option| args.values(option);
    held_once(name, values("set"), values("tie"))?;
    let mut scene = load(&file)?;
    for set in values("set") {
        let (n, v) = set.split_once('=').ok_or(format!("--set {set}: NAME=VALUE"))?;
        let index = scene.parameters().iter().position(|p| p.name == n).ok_or_else(|| {
            let names: Vec<&str> = scene.parameters().iter().map(|p| p.name.as_str()).collect();
            format!("--set {set}: the scene has no parameter '{n}' (it has {})", names.join(", "))
        })?;
        scene.set(index, number(v, &format!("--set {n}"))?);
        scene.validate().map_err(|e| format!("--set {set}: {e}"))?;
    }
    for once in ["from-state", "points", "transient", "max-period", "max-branches", "phase", "forcing", "progress"] {
        args.single(once)?;
    }
    let mut progress_every = 10.0;
    let mut settings = Continuation::new(name, number(from, "--param FROM")?, number(to, "--param TO")?);
    for (name, value) in args.options.iter().filter(|(n, _)| !["param", "out", "set", "tie"].contains(&n.as_str())) {
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
            "progress" => progress_every = number(value, &what).and_then(|s| if s > 0.0 { Ok(s) } else { Err(format!("{what} {value}: seconds > 0")) })?,
            _ => {}
        }
    }
    for tie in values("tie") {
        settings.tied.push(parse_tie(tie, name)?);
    }
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    let mut tables = Tables::create(&out, name, progress_every)?;
    let clock = std::time::Instant::now();
    let diagram = continue_orbits_observed(&scene, &settings, &mut tables)?;
    let seconds = clock.elapsed().as_secs_f64();
    if let Some(e) = tables.error {
        return Err(e);
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

/// Checks that `--set` and `--tie` name each parameter once and none the
/// continued one `param`: a parameter given twice (or both held and tied)
/// would leave one of the two silently unused.
fn held_once<'a>(param: &str, sets: impl Iterator<Item = &'a str>, ties: impl Iterator<Item = &'a str>) -> Result<(), String> {
    let mut seen: Vec<(String, String)> = Vec::new();
    for (option, text) in sets.map(|s| ("--set", s)).chain(ties.map(|t| ("--tie", t))) {
        let given = format!("{option} {text}");
        let (name, _) = text.split_once('=').ok_or(format!("{given}: NAME={}", if option == "--set" { "VALUE" } else { "SCALE*PARAM^POWER" }))?;
        let name = name.trim();
        if name == param {
            let what = if option == "--set" { "held at a value" } else { "tied to itself" };
            return Err(format!("{given}: '{name}' is the continued parameter (--param {param}=FROM:TO): it cannot be {what}"));
        }
        if let Some((_, before)) = seen.iter().find(|(n, _)| n == name) {
            return Err(format!("{given}: the parameter '{name}' is already given by {before}: a parameter is held (--set) or tied (--tie) once"));
        }
        seen.push((name.to_string(), given));
    }
    Ok(())
}

/// `branch.csv` and `special.csv` written as each branch ends (a run
/// stopped early leaves the branches it finished), and the progress on
/// stderr: each branch's start and end, and every `every` seconds the
/// branch, the parameter and the points so far.
struct Tables {
    branch: (PathBuf, File),
    special: (PathBuf, File),
    param: String,
    clock: Instant,
    every: f64,
    last: f64,
    points: usize,
    /// The first write that failed.
    error: Option<String>,
}

impl Tables {
    fn create(dir: &Path, param: &str, every: f64) -> Result<Tables, String> {
        let open = |file: &str, header: String| -> Result<(PathBuf, File), String> {
            let path = dir.join(file);
            let mut f = File::create(&path).map_err(|e| format!("{}: {e}", path.display()))?;
            f.write_all(header.as_bytes()).map_err(|e| format!("{}: {e}", path.display()))?;
            Ok((path, f))
        };
        Ok(Tables {
            branch: open("branch.csv", table::branch_header(param))?,
            special: open("special.csv", table::special_header(param))?,
            param: param.to_string(),
            clock: Instant::now(),
            every,
            last: 0.0,
            points: 0,
            error: None,
        })
    }

    fn append(target: &mut (PathBuf, File), text: &str, error: &mut Option<String>) {
        let (path, file) = target;
        if let Err(e) = file.write_all(text.as_bytes()).and_then(|_| file.flush()) {
            error.get_or_insert(format!("{}: {e}", path.display()));
        }
    }
}

impl Observer for Tables {
    fn branch_started(&mut self, index: usize, periods: usize, first: &Point) {
        self.points = 0;
        eprintln!("orbits: branch {index} (period {periods} T) starts at {} = {} ({:.1} s)", self.param, first.param, self.clock.elapsed().as_secs_f64());
    }

    fn point(&mut self, branch: usize, point: &Point) {
        self.points += 1;
        let now = self.clock.elapsed().as_secs_f64();
        if now - self.last >= self.every {
            self.last = now;
            eprintln!("orbits: branch {branch}: {} points, {} = {} ({now:.1} s)", self.points, self.param, point.param);
        }
    }

    fn branch_ended(&mut self, branch: &Branch, special: &[Special]) {
        Tables::append(&mut self.branch, &table::branch_rows(branch), &mut self.error);
        Tables::append(&mut self.special, &table::special_rows(special), &mut self.error);
        let (lo, hi) = branch.points.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| (l.min(p.param), h.max(p.param)));
        eprintln!(
            "orbits: branch {} ends: {} points, {} = {lo} .. {hi} ({:.1} s)",
            branch.index,
            branch.points.len(),
            self.param,
            self.clock.elapsed().as_secs_f64()
        );
    }
}
