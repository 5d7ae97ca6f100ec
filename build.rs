//! Generates the C header of the exported FMI functions with cbindgen into
//! `$OUT_DIR/beamstop_fmi2.h`. The committed copy `include/beamstop_fmi2.h`
//! is checked against it by `tests/c_header.rs` (which rewrites it when run
//! with `BEAMSTOP_BLESS=1`); a build never writes outside `OUT_DIR`.

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
}
