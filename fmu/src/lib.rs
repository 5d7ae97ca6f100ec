//! The FMU binary `libbeamstop_fmu.so`. Built with the default feature
//! `full` it is beamstop with everything (its `fmi2*` and `fmi3*`
//! functions and every kind it registers). Built as a variant (`beamstop
//! variants`, scripts/build-variants) it registers only the kinds and
//! exports only the standard named by its features, over a beamstop built
//! with only the variant's laws: the linker drops every other kind, law,
//! solver and standard, since nothing reaches them. `beamstop package`
//! copies the variant that covers a scene into its FMU as
//! `binaries/<platform>/<modelIdentifier>.so`.

#[cfg(all(feature = "full", any(feature = "modal", feature = "rotating", feature = "fmi2", feature = "fmi3")))]
compile_error!("beamstop_fmu: a variant is built with --no-default-features (`full` has every kind and standard already)");

// The full build: beamstop's exported `#[no_mangle] extern "C"` functions
// and its kinds' registrations come with it.
pub use beamstop;

// A variant: the entry points of its standard, compiled here from
// beamstop's own files (which use `beamstop::` paths for this).
#[cfg(feature = "fmi2")]
mod fmi2;
#[cfg(feature = "fmi3")]
mod fmi3;

#[cfg(feature = "modal")]
inventory::submit! { beamstop::kind::Registration(&beamstop::kinds::modal::ModalKind) }
#[cfg(feature = "rotating")]
inventory::submit! { beamstop::kind::Registration(&beamstop::kinds::rotating::RotatingKind) }
