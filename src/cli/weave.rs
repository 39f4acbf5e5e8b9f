//! `velour weave` (in progress).

use super::CliResult;

/// Arguments of `velour weave`.
#[derive(Debug, clap::Args)]
pub struct WeaveArgs {}

/// Runs `velour weave`.
pub fn run(_args: &WeaveArgs) -> CliResult {
    Err("velour weave is not implemented yet".into())
}
