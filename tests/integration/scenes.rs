//! Scene files: every shipped scene loads, bad ones are refused with a
//! message naming the field, the value and what is allowed, and the
//! committed modelDescription.xml files (FMI 2.0 and 3.0) are what the
//! generator produces.

use beamstop::package::FmiVersion;
use beamstop::Component;
use beamstop::kinds::modal::scene::Scene;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

fn pinned_text() -> String {
    std::fs::read_to_string(format!("{ROOT}/scenes/pinned_beam.json")).unwrap()
}

fn error_of(text: &str) -> String {
    Scene::from_json(text).expect_err("the scene should be refused").0
}

#[test]
fn committed_model_descriptions_are_current() {
    for entry in std::fs::read_dir(format!("{ROOT}/scenes")).unwrap() {
        let path = entry.unwrap().path();
        let scene = Component::from_json(&std::fs::read_to_string(&path).unwrap()).unwrap();
        for (version, dir) in [(FmiVersion::Fmi2, "modelDescription"), (FmiVersion::Fmi3, "modelDescription/fmi3")] {
            let committed_path = format!("{ROOT}/{dir}/{}.xml", scene.name());
            let committed = std::fs::read_to_string(&committed_path).unwrap_or_default();
            assert!(
                committed == version.model_description(&scene).unwrap(),
                "{committed_path} is not what the generator produces for {}: run `cargo run --release -- model-descriptions`",
                path.display()
            );
        }
    }
}

#[test]
fn a_misspelled_field_is_named_with_the_allowed_ones() {
    let text = pinned_text().replace("\"gap\"", "\"gapp\"");
    let e = error_of(&text);
    assert!(e.contains("unknown field `gapp`") && e.contains("`gap`"), "{e}");
}

#[test]
fn out_of_range_values_name_field_value_and_range() {
    let cases = [
        ("\"R\": 0.7", "\"R\": 1.5", "stops[0].law.R", "1.5", "[0, 1]"),
        ("\"x\": 0.4", "\"x\": 1.2", "stops[0].x", "1.2", "(0, 1)"),
        ("\"zeta\": 0.05", "\"zeta\": -0.1", "damping.zeta", "-0.1", "[0, 1000]"),
        ("\"zeta\": 0.05", "\"zeta\": 1e4", "damping.zeta", "10000", "[0, 1000]"),
        ("\"gap\": 0.0", "\"gap\": 1e150", "stops[0].gap", "1e150", "[-1000, 1000]"),
        ("\"eps\": 1e-6", "\"eps\": -1", "stops[0].law.eps", "-1", "[0, 1787.2"),
        ("\"modes\": 4", "\"modes\": 0", "structure.modes", "0", "[1, 500]"),
    ];
    for (from, to, field, value, range) in cases {
        let text = pinned_text();
        assert!(text.contains(from), "{from}");
        let e = error_of(&text.replace(from, to));
        assert!(e.contains(field) && e.contains(value) && e.contains(range), "{e}");
    }
}

#[test]
fn the_guid_follows_the_scene() {
    let a = Scene::from_json(&pinned_text()).unwrap();
    let b = Scene::from_json(&pinned_text().replace("\"R\": 0.7", "\"R\": 0.71")).unwrap();
    assert_ne!(a.guid(), b.guid());
    // Formatting does not matter, content does.
    let c = Scene::from_json(&pinned_text().replace('\n', " ")).unwrap();
    assert_eq!(a.guid(), c.guid());
}
