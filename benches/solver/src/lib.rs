//! beamstop's criterion benchmarks live in `benches/solver.rs` (`cargo bench -p beamstop_bench`).
