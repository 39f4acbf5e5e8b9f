//! `velour diff` (in progress).

use super::CliResult;

/// Arguments of `velour diff`.
#[derive(Debug, clap::Args)]
pub struct DiffArgs {}

/// Runs `velour diff`.
pub fn run(_args: &DiffArgs) -> CliResult {
    Err("velour diff is not implemented yet".into())
}
