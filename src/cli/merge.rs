//! `velour merge -o OUT.exr PART.exr…`: puts the parts of a split render back together,
//! bit-identical to one process rendering it all (see [`crate::farm`]).

use std::path::PathBuf;

use super::CliResult;
use crate::farm::merge_parts;
use crate::image_io::read_exr;
use crate::render::{png_path_for, write_film};

/// Arguments of `velour merge`.
#[derive(Debug, clap::Args)]
pub struct MergeArgs {
    /// Part files written by `velour render --tile` / `--samples`.
    #[arg(required = true)]
    pub parts: Vec<PathBuf>,
    /// The merged image (EXR; a PNG preview goes next to it).
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// Exposure of the PNG preview, in stops.
    #[arg(long, default_value_t = 0.0)]
    pub exposure: f32,
}

/// Runs `velour merge`. Writes nothing unless every check passes.
pub fn run(args: &MergeArgs) -> CliResult {
    let mut parts = Vec::with_capacity(args.parts.len());
    for p in &args.parts {
        let img =
            read_exr(p).map_err(|e| format!("{}: corrupt or unreadable part: {e}", p.display()))?;
        parts.push((p.clone(), img));
    }
    // Attributes the parts agree on (the first part's) besides the part identity.
    let mut attributes = parts
        .first()
        .map(|(_, img)| img.attributes.clone())
        .unwrap_or_default();
    let (film, whole) = merge_parts(parts)?;
    attributes.retain(|k, _| {
        !matches!(
            k.as_str(),
            "velour:tile"
                | "velour:rows"
                | "velour:samples"
                | "velour:done"
                | "velour:render_seconds"
        )
    });
    attributes.extend(whole.to_attributes());
    attributes.insert("velour:merged_parts".into(), args.parts.len().to_string());
    write_film(&film, &args.output, args.exposure, &attributes)?;
    println!(
        "merged {} parts into {} and {} ({}x{}, {} spp)",
        args.parts.len(),
        args.output.display(),
        png_path_for(&args.output).display(),
        whole.width,
        whole.height,
        whole.spp
    );
    Ok(())
}
