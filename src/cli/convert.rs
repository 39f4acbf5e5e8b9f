//! `velour convert` (in progress).

use super::CliResult;

/// Arguments of `velour convert`.
#[derive(Debug, clap::Args)]
pub struct ConvertArgs {}

/// Runs `velour convert`.
pub fn run(_args: &ConvertArgs) -> CliResult {
    Err("velour convert is not implemented yet".into())
}
