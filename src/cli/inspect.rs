//! `velour inspect` (in progress).

use super::CliResult;

/// Arguments of `velour inspect`.
#[derive(Debug, clap::Args)]
pub struct InspectArgs {}

/// Runs `velour inspect`.
pub fn run(_args: &InspectArgs) -> CliResult {
    Err("velour inspect is not implemented yet".into())
}
