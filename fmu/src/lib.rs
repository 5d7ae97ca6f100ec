//! The FMU binary `libbeamstop_fmu.so`: beamstop's `fmi2*` functions
//! (`beamstop::fmi2::api`) and the kinds beamstop registers, nothing else.
//! `beamstop package` copies it into every FMU as
//! `binaries/<platform>/<modelIdentifier>.so`.

// Links beamstop: its exported `#[no_mangle] extern "C"` functions and its
// kinds' registrations come with it.
pub use beamstop;
