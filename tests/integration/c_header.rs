//! The committed C headers `include/beamstop_fmi2.h` and
//! `include/beamstop_fmi3.h` are the ones cbindgen generates from the
//! exported functions of src/fmi2/api.rs and src/fmi3/api.rs (build.rs,
//! into OUT_DIR). Run with `BEAMSTOP_BLESS=1` to rewrite the committed
//! copies after changing the API.

/// Compares (or, blessing, rewrites) one committed header with its generated copy.
fn check(generated: &str, committed_path: &str, name: &str) {
    if std::env::var_os("BEAMSTOP_BLESS").is_some() {
        std::fs::write(committed_path, generated).unwrap();
    }
    let committed = std::fs::read_to_string(committed_path).unwrap_or_default();
    assert!(
        committed == generated,
        "include/{name} is out of date: rerun `BEAMSTOP_BLESS=1 cargo test --release --test integration c_header::`"
    );
}

#[test]
fn committed_header_is_current() {
    let generated = std::fs::read_to_string(concat!(env!("OUT_DIR"), "/beamstop_fmi2.h")).expect("build.rs writes the header");
    check(&generated, concat!(env!("CARGO_MANIFEST_DIR"), "/include/beamstop_fmi2.h"), "beamstop_fmi2.h");
}

#[test]
fn committed_fmi3_header_is_current() {
    let generated = std::fs::read_to_string(concat!(env!("OUT_DIR"), "/beamstop_fmi3.h")).expect("build.rs writes the FMI 3.0 header");
    check(&generated, concat!(env!("CARGO_MANIFEST_DIR"), "/include/beamstop_fmi3.h"), "beamstop_fmi3.h");
}

#[test]
fn each_header_declares_only_its_own_version() {
    let fmi2 = std::fs::read_to_string(concat!(env!("OUT_DIR"), "/beamstop_fmi2.h")).unwrap();
    let fmi3 = std::fs::read_to_string(concat!(env!("OUT_DIR"), "/beamstop_fmi3.h")).unwrap();
    assert!(fmi2.contains("fmi2DoStep(") && !fmi2.contains("fmi3"), "beamstop_fmi2.h must declare the fmi2 functions only");
    assert!(fmi3.contains("fmi3DoStep(") && !fmi3.contains("fmi2"), "beamstop_fmi3.h must declare the fmi3 functions only");
}
