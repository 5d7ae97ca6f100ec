//! The integration tests, one module per file, in one test binary (one
//! link instead of one per file): `cargo test --release --test integration`,
//! one file's tests with `cargo test --release --test integration physics::`.

mod common;

mod c_header;
mod compliant;
mod contract;
mod flow;
mod forged_states;
mod hertz;
mod mode_transfer;
mod orbits;
mod physics;
mod range_ends;
mod restores;
mod robustness;
mod rollback;
mod rotating;
mod rotating_flow;
mod scene_physics;
mod scenes;
mod stability;
