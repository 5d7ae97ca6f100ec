//! The kinds of simulation this library ships, each in a folder of its
//! own (`modal`, `rotating`), registered here: the one place a kind is
//! added ([`crate::kind::Registration`]). With the
//! default feature `beam` off, a crate that builds an FMU of its own kind
//! links the library without them (its FMU then carries only its kind).

pub mod modal;
pub mod rotating;

#[cfg(feature = "beam")]
inventory::submit! { crate::kind::Registration(&modal::ModalKind) }
#[cfg(feature = "beam")]
inventory::submit! { crate::kind::Registration(&rotating::RotatingKind) }
