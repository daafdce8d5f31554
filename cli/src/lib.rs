//! srug-cli: the `srug` command line and the benchmarks behind `srug bench`.
//!
//! The renderer is the `srug` library; this crate only parses arguments
//! ([`args`]: the shared groups and typed values), runs one subcommand per
//! file (`cmd/`), and measures (`bench/`). Nothing here is needed to embed srug.

pub mod args;
pub mod bench;
mod cmd;

pub use cmd::Cli;
