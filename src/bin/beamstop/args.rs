//! The command line's words: positional arguments, `--name value` and
//! `--name=value` options, value-less flags, and `--help` / `-h`, parsed
//! the same way for every subcommand.

/// One subcommand's arguments.
#[derive(Debug, Default, PartialEq)]
pub struct Args {
    pub positional: Vec<String>,
    /// `(name, value)` in the order given, names without the `--`.
    pub options: Vec<(String, String)>,
    /// The flags given (names without the `--`).
    pub flags: Vec<String>,
    /// `--help` or `-h` was given.
    pub help: bool,
}

impl Args {
    /// The values of a repeatable option, in order.
    pub fn values<'a>(&'a self, name: &'a str) -> impl Iterator<Item = &'a str> + 'a {
        self.options.iter().filter(move |(n, _)| n == name).map(|(_, v)| v.as_str())
    }

    /// The value of an option given at most once.
    pub fn single(&self, name: &str) -> Result<Option<&str>, String> {
        let mut given = self.options.iter().filter(|(n, _)| n == name).map(|(_, v)| v.as_str());
        let first = given.next();
        match given.next() {
            Some(second) => Err(format!("--{name} is given twice ({} and {second}): give it once", first.unwrap_or_default())),
            None => Ok(first),
        }
    }

    /// A number option given at most once.
    pub fn number(&self, name: &str) -> Result<Option<f64>, String> {
        self.single(name)?.map(|s| s.trim().parse::<f64>().map_err(|_| format!("--{name} {s}: not a number"))).transpose()
    }

    pub fn flag(&self, name: &str) -> bool {
        self.flags.iter().any(|f| f == name)
    }
}

/// Whether an argument asks for help.
pub fn is_help(arg: &str) -> bool {
    arg == "--help" || arg == "-h"
}

/// Splits `args` by `valued` (options that take a value, either as the
/// next argument or after `=`) and `flags` (options without one).
pub fn parse(args: &[String], valued: &[&str], flags: &[&str]) -> Result<Args, String> {
    let mut out = Args::default();
    let mut i = 0;
    while i < args.len() {
        let a = &args[i];
        i += 1;
        if is_help(a) {
            out.help = true;
            continue;
        }
        let Some(word) = a.strip_prefix("--") else {
            out.positional.push(a.clone());
            continue;
        };
        let (name, inline) = match word.split_once('=') {
            Some((name, value)) => (name, Some(value.to_string())),
            None => (word, None),
        };
        if flags.contains(&name) {
            if let Some(value) = inline {
                return Err(format!("--{name} takes no value (given '{value}')"));
            }
            out.flags.push(name.to_string());
        } else if valued.contains(&name) {
            let value = match inline {
                Some(value) => value,
                None => {
                    let value = args.get(i).filter(|v| !is_help(v)).ok_or(format!("--{name} needs a value"))?.clone();
                    i += 1;
                    value
                }
            };
            out.options.push((name.to_string(), value));
        } else {
            let known: Vec<String> = valued.iter().chain(flags).map(|n| format!("--{n}")).collect();
            let known = if known.is_empty() { "none".to_string() } else { known.join(", ") };
            return Err(format!("unknown option --{name} (the options here: {known})"));
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn words(s: &str) -> Vec<String> {
        s.split_whitespace().map(String::from).collect()
    }

    #[test]
    fn both_forms_flags_and_help() {
        let a = parse(&words("scene.json --out=d --step 0.1 --fmi3 --from-state=1,-2 -h"), &["out", "step", "from-state"], &["fmi3"]).unwrap();
        assert_eq!(a.positional, ["scene.json"]);
        assert_eq!(a.options, [("out".into(), "d".into()), ("step".into(), "0.1".into()), ("from-state".into(), "1,-2".into())]);
        assert!(a.flag("fmi3") && a.help);
        assert_eq!(a.number("step").unwrap(), Some(0.1));
    }

    #[test]
    fn faults_are_named() {
        assert_eq!(parse(&words("--out"), &["out"], &[]).unwrap_err(), "--out needs a value");
        assert!(parse(&words("--fmi3=1"), &[], &["fmi3"]).unwrap_err().contains("--fmi3 takes no value"));
        assert!(parse(&words("--bogus 1"), &["out"], &[]).unwrap_err().contains("unknown option --bogus"));
        let twice = parse(&words("--out a --out=b"), &["out"], &[]).unwrap();
        assert!(twice.single("out").unwrap_err().contains("--out is given twice (a and b)"));
    }
}
