//! `velour render` (in progress).

use super::CliResult;

/// Arguments of `velour render`.
#[derive(Debug, clap::Args)]
pub struct RenderArgs {}

/// Runs `velour render`.
pub fn run(_args: &RenderArgs) -> CliResult {
    Err("velour render is not implemented yet".into())
}
