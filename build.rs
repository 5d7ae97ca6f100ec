//! Generates the C headers of the exported FMI functions with cbindgen into
//! `$OUT_DIR`: `beamstop_fmi2.h` from src/fmi2/api.rs only (cbindgen.toml)
//! and `beamstop_fmi3.h` from src/fmi3/api.rs and src/fmi3/absent.rs
//! (cbindgen-fmi3.toml).
//! The committed copies `include/beamstop_fmi2.h` and
//! `include/beamstop_fmi3.h` are checked against them by `tests/integration/c_header.rs`
//! (which rewrites them when run with `BEAMSTOP_BLESS=1`); a build never
//! writes outside `OUT_DIR`.

use std::path::{Path, PathBuf};

/// Runs cbindgen over the source files `api` (their `mod` and `use` items
/// are not followed: the types come from the standard headers) with the
/// configuration `config`, into `$OUT_DIR/<out>`.
fn generate(root: &Path, api: &[&str], config: &str, out: &str) {
    let config = match cbindgen::Config::from_file(root.join(config)) {
        Ok(c) => c,
        Err(e) => panic!("{config} is not a valid cbindgen configuration: {e}"),
    };
    let mut builder = cbindgen::Builder::new().with_config(config);
    for file in api {
        builder = builder.with_src(root.join(file));
    }
    let header = match builder.generate() {
        Ok(h) => h,
        Err(e) => panic!("cbindgen failed on {api:?}: {e}"),
    };
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR")).join(out);
    header.write_to_file(&out);
}

fn main() {
    println!("cargo:rerun-if-changed=src/fmi2/api.rs");
    println!("cargo:rerun-if-changed=src/fmi2/types.rs");
    println!("cargo:rerun-if-changed=cbindgen.toml");
    println!("cargo:rerun-if-changed=src/fmi3/api.rs");
    println!("cargo:rerun-if-changed=src/fmi3/absent.rs");
    println!("cargo:rerun-if-changed=src/fmi3/types.rs");
    println!("cargo:rerun-if-changed=cbindgen-fmi3.toml");
    let root = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    generate(&root, &["src/fmi2/api.rs"], "cbindgen.toml", "beamstop_fmi2.h");
    generate(&root, &["src/fmi3/api.rs", "src/fmi3/absent.rs"], "cbindgen-fmi3.toml", "beamstop_fmi3.h");
}
