//! `velour convert IN.vdb OUT.vdb [--half] [--compression none|zip|blosc]`: rewrites a VDB
//! file through velour's reader and writer.

use super::CliResult;
use crate::vdb::{write_vdb, Compression, GridToWrite, VdbFile, WriteOptions};
use std::path::PathBuf;

/// Arguments of `velour convert`.
#[derive(Debug, clap::Args)]
pub struct ConvertArgs {
    /// Input OpenVDB file.
    pub input: PathBuf,
    /// Output OpenVDB file.
    pub output: PathBuf,
    /// Save every float and vec3 grid as 16-bit half floats (otherwise each grid keeps its
    /// input precision setting).
    #[arg(long)]
    pub half: bool,
    /// Buffer compression of the output: none, zip or blosc (OpenVDB's default).
    #[arg(long, default_value = "blosc", value_parser = ["none", "zip", "blosc"])]
    pub compression: String,
    /// Store all values of every node instead of only the active ones.
    #[arg(long)]
    pub no_active_mask: bool,
}

/// Runs `velour convert`.
pub fn run(args: &ConvertArgs) -> CliResult {
    let compression = Compression::parse(&args.compression).ok_or_else(|| {
        format!(
            "--compression: unknown codec '{}' (use none, zip or blosc)",
            args.compression
        )
    })?;
    let file = VdbFile::open(&args.input)?;
    let grids = file.read_all()?;
    let to_write: Vec<GridToWrite<'_>> = grids
        .iter()
        .map(|g| GridToWrite {
            name: &g.name,
            class: &g.class,
            grid: &g.grid,
            channel: 0,
            half: args.half || g.saved_as_half,
            map: Some(g.map),
            metadata: &g.metadata,
        })
        .collect();
    let opts = WriteOptions {
        compression,
        active_mask: !args.no_active_mask,
    };
    write_vdb(&args.output, &to_write, &opts)?;
    for g in &grids {
        eprintln!(
            "{}: grid '{}' ({}{}, {}) written",
            args.output.display(),
            g.name,
            g.value_type.name(),
            if args.half || g.saved_as_half {
                ", half"
            } else {
                ""
            },
            g.class
        );
    }
    Ok(())
}
