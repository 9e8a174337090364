//! Benchmarks of loam (see `benches/`).
