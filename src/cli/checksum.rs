//! `velour checksum IMAGE.exr…`: a SHA-256 of an image's pixels (every channel's name and
//! sample bits, float and integer), ignoring its header attributes (render time, command line),
//! so that two renders that agree bit for bit print the same sum.

use std::path::PathBuf;

use sha2::{Digest, Sha256};

use super::CliResult;
use crate::image_io::{read_exr, ExrImage};

/// Arguments of `velour checksum`.
#[derive(Debug, clap::Args)]
pub struct ChecksumArgs {
    /// EXR images.
    #[arg(required = true)]
    pub images: Vec<PathBuf>,
}

/// SHA-256 (hex) of the image's size and channels in name order: name, then the samples'
/// little-endian bits.
#[must_use]
pub fn pixel_checksum(img: &ExrImage) -> String {
    let mut h = Sha256::new();
    h.update(img.width.to_le_bytes());
    h.update(img.height.to_le_bytes());
    for (name, samples) in &img.channels {
        h.update((name.len() as u64).to_le_bytes());
        h.update(name.as_bytes());
        for v in samples {
            h.update(v.to_bits().to_le_bytes());
        }
    }
    for (name, samples) in &img.uint_channels {
        h.update((name.len() as u64).to_le_bytes());
        h.update(name.as_bytes());
        for v in samples {
            h.update(v.to_le_bytes());
        }
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

/// Runs `velour checksum`: one line per image, `SUM  PATH`.
pub fn run(args: &ChecksumArgs) -> CliResult {
    for path in &args.images {
        let img = read_exr(path)?;
        println!("{}  {}", pixel_checksum(&img), path.display());
    }
    Ok(())
}
