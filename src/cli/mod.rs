//! The `velour` command-line subcommands. Each submodule owns one subcommand: its clap
//! argument struct and its `run` function.

pub mod bench;
pub mod checksum;
pub mod convert;
pub mod cpu;
pub mod diff;
pub mod inspect;
pub mod majorants;
pub mod merge;
pub mod metadata;
pub mod reference;
pub mod render;
pub mod tradeoff;
pub mod voxelize;
pub mod weave;

/// The result of a subcommand: any error is printed by `main` and the process exits non-zero.
pub type CliResult = Result<(), Box<dyn std::error::Error + Send + Sync>>;
