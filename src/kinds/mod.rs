//! The kinds of simulation this library ships, each in a folder of its
//! own (`modal`, `rotating`), registered here: the one place a kind is
//! added ([`crate::kind::Registration`]). With the
//! default feature `beam` off, a crate that builds an FMU of its own kind
//! links the library without them (its FMU then carries only its kind).

#[cfg(feature = "modal")]
pub mod modal;
#[cfg(feature = "rotating")]
pub mod rotating;

#[cfg(all(feature = "register", feature = "modal"))]
inventory::submit! { crate::kind::Registration(&modal::ModalKind) }
#[cfg(all(feature = "register", feature = "rotating"))]
inventory::submit! { crate::kind::Registration(&rotating::RotatingKind) }

/// Every kind this library ships: its name and the top-level key its scene
/// files are recognized by (to name a kind a binary was built without:
/// [`crate::kind::kind_of`]).
pub const KINDS: [(&str, &str); 2] = [("modal", "structure"), ("rotating", "beam")];
