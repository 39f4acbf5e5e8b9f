//! The `velour` binary: a thin clap front end over [`velour::cli`].

use clap::{Parser, Subcommand};
use velour::cli;

#[derive(Parser)]
#[command(
    name = "velour",
    version,
    about = "Monte-Carlo volumetric path tracer for translucent creatures, fabric and OpenVDB volumes"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene file (or the built-in default scene) to EXR + PNG.
    Render(cli::render::RenderArgs),
    /// SHA-256 of an EXR image's pixels, ignoring its header (render time, command line).
    Checksum(cli::checksum::ChecksumArgs),
    /// Merge the part files of a split render (tiles, sample ranges) into one image.
    Merge(cli::merge::MergeArgs),
    /// Print the grids of an OpenVDB file with their statistics.
    Inspect(cli::inspect::InspectArgs),
    /// Rewrite an OpenVDB file through velour's reader and writer.
    Convert(cli::convert::ConvertArgs),
    /// Generate a woven fabric patch and write it as OpenVDB grids.
    Weave(cli::weave::WeaveArgs),
    /// Convert a PLY mesh into an OpenVDB level set or fog volume (with optional noise).
    Voxelize(cli::voxelize::VoxelizeArgs),
    /// Report majorant-bound tightness and violations per pyramid level (VDB file or scene).
    Majorants(cli::majorants::MajorantsArgs),
    /// Print paths/s and rays/s rendering a scene (default: the built-in creature).
    Bench(cli::bench::BenchArgs),
    /// Compare two EXR images (RMSE, relative MSE, bias, per-pixel z-test).
    Diff(cli::diff::DiffArgs),
    /// Render a high-sample reference image with per-pixel variance (--spp N or --time S).
    Reference(cli::reference::ReferenceArgs),
    /// Measure error against time for each estimator configuration of a scene (CSV + SVG).
    Tradeoff(cli::tradeoff::TradeoffArgs),
}

/// Restores the default SIGPIPE action so that `velour inspect f.vdb | head` ends quietly
/// instead of panicking on a closed pipe (Rust ignores SIGPIPE by default).
fn reset_sigpipe() {
    #[cfg(unix)]
    // SAFETY: `signal` with SIG_DFL only changes this process's signal disposition; it is
    // called once at start-up, before any thread exists.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

fn main() {
    cli::cpu::exit_unless_supported();
    reset_sigpipe();
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Render(a) => cli::render::run(a),
        Command::Merge(a) => cli::merge::run(a),
        Command::Checksum(a) => cli::checksum::run(a),
        Command::Inspect(a) => cli::inspect::run(a),
        Command::Convert(a) => cli::convert::run(a),
        Command::Weave(a) => cli::weave::run(a),
        Command::Voxelize(a) => cli::voxelize::run(a),
        Command::Diff(a) => cli::diff::run(a),
        Command::Bench(a) => cli::bench::run(a),
        Command::Reference(a) => cli::reference::run(a),
        Command::Tradeoff(a) => cli::tradeoff::run(a),
        Command::Majorants(a) => cli::majorants::run(a),
    };
    if let Err(e) = result {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
