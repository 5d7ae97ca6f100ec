//! Generates the C header of the exported FMI functions with cbindgen into
//! include/beamstop_fmi2.h (committed, and compiled by tests/c_header.rs
//! together with the standard fmi2Functions.h).

use std::path::PathBuf;

fn main() {
    println!("cargo:rerun-if-changed=src/fmi2/api.rs");
    println!("cargo:rerun-if-changed=src/fmi2/types.rs");
    println!("cargo:rerun-if-changed=cbindgen.toml");
    let root = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(root.join("cbindgen.toml")).expect("cbindgen.toml is valid");
    let header = match cbindgen::Builder::new().with_crate(&root).with_config(config).generate() {
        Ok(h) => h,
        Err(e) => panic!("cbindgen failed on src/fmi2/api.rs: {e}"),
    };
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR")).join("beamstop_fmi2.h");
    header.write_to_file(&out);
    // Keep the committed copy current (rewritten only when it changes).
    let committed = root.join("include").join("beamstop_fmi2.h");
    let fresh = std::fs::read(&out).expect("header just written");
    if std::fs::read(&committed).ok().as_deref() != Some(&fresh[..]) {
        let _ = std::fs::create_dir_all(committed.parent().expect("has parent"));
        let _ = std::fs::write(&committed, &fresh);
    }
}
