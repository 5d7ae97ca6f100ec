//! A number in a scene file by its path, `stops[0].law.R` or
//! `initial.q[3]`: how every kind's parameters are read and written, so
//! that a kind declares where each parameter sits and nothing more.
//!
//! Reading an absent number gives 0 (an implied default: an initial modal
//! coordinate not listed, a position not yet given). Writing creates what
//! is missing: an object's field, or an array padded with zeros up to the
//! index.

use serde_json::Value;

/// One step of a path: an object's field or an array's index.
#[derive(Clone, Debug, PartialEq)]
enum Step<'a> {
    Field(&'a str),
    Index(usize),
}

fn steps(path: &str) -> Result<Vec<Step<'_>>, String> {
    let mut out = Vec::new();
    for part in path.split('.') {
        let (field, mut rest) = match part.find('[') {
            Some(i) => (&part[..i], &part[i..]),
            None => (part, ""),
        };
        if field.is_empty() {
            return Err(format!("scene path {path:?}: empty field name"));
        }
        out.push(Step::Field(field));
        while !rest.is_empty() {
            let close = rest.find(']').ok_or_else(|| format!("scene path {path:?}: '[' without ']'"))?;
            let index = rest[1..close].parse::<usize>().map_err(|_| format!("scene path {path:?}: {:?} is not an index", &rest[1..close]))?;
            out.push(Step::Index(index));
            rest = &rest[close + 1..];
            if !(rest.is_empty() || rest.starts_with('[')) {
                return Err(format!("scene path {path:?}: text after ']'"));
            }
        }
    }
    Ok(out)
}

/// The number at `path` (0 where it is absent).
pub fn get(scene: &Value, path: &str) -> Result<f64, String> {
    let mut at = scene;
    for step in steps(path)? {
        let next = match step {
            Step::Field(f) => at.get(f),
            Step::Index(i) => at.get(i),
        };
        match next {
            Some(v) => at = v,
            None => return Ok(0.0),
        }
    }
    match at {
        Value::Number(n) => n.as_f64().ok_or_else(|| format!("scene path {path:?}: {n} is not a number")),
        Value::Null => Ok(0.0),
        other => Err(format!("scene path {path:?}: {other} is not a number")),
    }
}

/// Writes `value` at `path`, creating what is missing.
pub fn set(scene: &mut Value, path: &str, value: f64) -> Result<(), String> {
    let number = serde_json::Number::from_f64(value).map(Value::Number).ok_or_else(|| format!("scene path {path:?}: {value} is not a finite number"))?;
    let mut at = scene;
    for step in steps(path)? {
        at = match step {
            Step::Field(f) => {
                if at.is_null() {
                    *at = Value::Object(Default::default());
                }
                let object = at.as_object_mut().ok_or_else(|| format!("scene path {path:?}: '{f}' of something that is not an object"))?;
                object.entry(f).or_insert(Value::Null)
            }
            Step::Index(i) => {
                if at.is_null() {
                    *at = Value::Array(Vec::new());
                }
                let array = at.as_array_mut().ok_or_else(|| format!("scene path {path:?}: [{i}] of something that is not an array"))?;
                if array.len() <= i {
                    array.resize(i + 1, Value::from(0.0));
                }
                &mut array[i]
            }
        };
    }
    *at = number;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn reads_and_writes_nested_fields_and_indices() {
        let mut scene = json!({"stops": [{"law": {"R": 0.7}}], "initial": {"q": [1.0]}});
        assert_eq!(get(&scene, "stops[0].law.R").unwrap(), 0.7);
        assert_eq!(get(&scene, "initial.q[0]").unwrap(), 1.0);
        // Absent: the implied zero.
        assert_eq!(get(&scene, "initial.q[3]").unwrap(), 0.0);
        assert_eq!(get(&scene, "initial.qd[0]").unwrap(), 0.0);
        set(&mut scene, "stops[0].law.R", 0.25).unwrap();
        set(&mut scene, "initial.q[2]", -3.5).unwrap();
        set(&mut scene, "stops[0].x", 0.4).unwrap();
        assert_eq!(scene, json!({"stops": [{"law": {"R": 0.25}, "x": 0.4}], "initial": {"q": [1.0, 0.0, -3.5]}}));
    }

    #[test]
    fn refuses_bad_paths_and_values() {
        let mut scene = json!({"name": "x", "loads": [1.0]});
        assert!(get(&scene, "name").is_err());
        assert!(set(&mut scene, "loads[0].amplitude", 1.0).is_err());
        assert!(set(&mut scene, "a[", 1.0).is_err());
        assert!(set(&mut scene, "a[x]", 1.0).is_err());
        assert!(set(&mut scene, "a", f64::NAN).is_err());
    }
}
