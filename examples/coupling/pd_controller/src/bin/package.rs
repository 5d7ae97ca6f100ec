//! `package-pd-controller [OUT_DIR]`: PDController.fmu from this crate's
//! scene.json and the FMU binary cargo built beside this command (default
//! OUT_DIR: target/coupling under the repository).

use std::path::PathBuf;
use std::process::ExitCode;

use beamstop::component::Component;
use beamstop::package::{library_beside_executable, write_fmu, FmiVersion};
use pd_controller_fmu::PdKind;

fn main() -> ExitCode {
    let crate_dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let out = std::env::args().nth(1).map(PathBuf::from).unwrap_or_else(|| crate_dir.join("../../../target/coupling"));
    let result = std::fs::read_to_string(crate_dir.join("scene.json"))
        .map_err(|e| format!("scene.json: {e}"))
        .and_then(|text| Component::of_kind(&PdKind, &text))
        .and_then(|scene| {
            let binary = library_beside_executable("pd_controller_fmu")?;
            write_fmu(&scene, &binary, &out, FmiVersion::Fmi2)
        });
    match result {
        Ok(path) => {
            println!("{}", path.display());
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("package-pd-controller: {e}");
            ExitCode::FAILURE
        }
    }
}
