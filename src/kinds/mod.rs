//! The kinds of simulation this library ships, each in a folder of its
//! own (`modal`, `rotating`), registered here: the one place a kind is
//! added ([`crate::kind::Registration`]). With the
//! default feature `beam` off, a crate that builds an FMU of its own kind
//! links the library without them (its FMU then carries only its kind).

pub mod modal;
pub mod rotating;

#[cfg(feature = "modal")]
inventory::submit! { crate::kind::Registration(&modal::ModalKind) }
#[cfg(feature = "rotating")]
inventory::submit! { crate::kind::Registration(&rotating::RotatingKind) }

/// Every kind this library ships: its name, the top-level key its scene
/// files are recognized by, and whether this build carries it (the
/// features `modal` and `rotating`).
pub const KINDS: [(&str, &str, bool); 2] = [("modal", "structure", cfg!(feature = "modal")), ("rotating", "beam", cfg!(feature = "rotating"))];
