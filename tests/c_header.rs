//! The committed C header `include/beamstop_fmi2.h` is the one cbindgen
//! generates from the exported functions (build.rs, into OUT_DIR). Run with
//! `BEAMSTOP_BLESS=1` to rewrite the committed copy after changing the API.

#[test]
fn committed_header_is_current() {
    let generated = std::fs::read_to_string(concat!(env!("OUT_DIR"), "/beamstop_fmi2.h")).expect("build.rs writes the header");
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/include/beamstop_fmi2.h");
    if std::env::var_os("BEAMSTOP_BLESS").is_some() {
        std::fs::write(path, &generated).unwrap();
    }
    let committed = std::fs::read_to_string(path).unwrap_or_default();
    assert!(
        committed == generated,
        "include/beamstop_fmi2.h is out of date: rerun `BEAMSTOP_BLESS=1 cargo test --release --test c_header`"
    );
}
