//! Shared set-up for srug benchmarks (see `benches/`).
