//! `velour merge`: checks that part files belong together and cover the render exactly once,
//! then adds their exact film states into the whole image.

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::PathBuf;

use super::part::PartInfo;
use super::split::TileSpec;
use crate::film::Film;
use crate::image_io::ExrImage;

/// Why parts cannot be merged; every variant names the part file(s) at fault.
#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    /// No parts were given.
    #[error("no part files to merge")]
    NoParts,
    /// A part lacks its metadata or its exact film state, or they disagree with its size.
    #[error("{path}: not a velour part file: {reason}")]
    NotAPart {
        /// The part.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// A part belongs to another render.
    #[error("{path}: {what} is {got}, but {first} has {want}: the parts are not of one render")]
    Mismatch {
        /// The part.
        path: PathBuf,
        /// The first part, which the others are compared with.
        first: PathBuf,
        /// The attribute that differs.
        what: &'static str,
        /// This part's value.
        got: String,
        /// The first part's value.
        want: String,
    },
    /// Parts overlap or leave a gap.
    #[error("{0}")]
    Coverage(String),
}

/// One part: its file, what it says about itself and its film band.
struct Part {
    path: PathBuf,
    info: PartInfo,
    film: Film,
}

fn read_part(path: PathBuf, img: &ExrImage) -> Result<Part, MergeError> {
    let not = |reason: String| MergeError::NotAPart {
        path: path.clone(),
        reason,
    };
    let info = PartInfo::from_attributes(&img.attributes).map_err(not)?;
    let film = Film::from_exr_image(img).map_err(|e| not(e.to_string()))?;
    if film.width() != info.width || film.height() != info.rows.end - info.rows.start {
        return Err(not(format!(
            "its pixels are {}x{} but it claims rows {}..{} of a {}x{} image",
            film.width(),
            film.height(),
            info.rows.start,
            info.rows.end,
            info.width,
            info.height
        )));
    }
    let tile = info.tile.unwrap_or(TileSpec { index: 0, count: 1 });
    let rows = tile.rows(info.height).map_err(not)?;
    if rows != info.rows {
        return Err(not(format!(
            "tile {tile} of {} rows is rows {}..{}, not {}..{}",
            info.height, rows.start, rows.end, info.rows.start, info.rows.end
        )));
    }
    if info.samples.end > info.spp {
        return Err(not(format!(
            "samples {}..{} exceed the render's {} spp",
            info.samples.start, info.samples.end, info.spp
        )));
    }
    Ok(Part { path, info, film })
}

/// Merges `parts` (file name and decoded image) into the whole film. The result is
/// bit-identical to one process rendering every tile and sample; the returned [`PartInfo`]
/// describes the whole render. Writes nothing: the caller writes the image only on success.
pub fn merge_parts(parts: Vec<(PathBuf, ExrImage)>) -> Result<(Film, PartInfo), MergeError> {
    let mut read = Vec::with_capacity(parts.len());
    for (path, img) in parts {
        read.push(read_part(path, &img)?);
    }
    let first = read.first().ok_or(MergeError::NoParts)?;
    let f = &first.info;
    let tiles_of = |i: &PartInfo| i.tile.map_or(1, |t| t.count);
    for p in &read[1..] {
        let checks: [(&'static str, String, String); 6] = [
            (
                "the velour version",
                p.info.version.clone(),
                f.version.clone(),
            ),
            (
                "the scene hash",
                p.info.scene_hash.clone(),
                f.scene_hash.clone(),
            ),
            ("the seed", p.info.seed.to_string(), f.seed.to_string()),
            (
                "the resolution",
                format!("{}x{}", p.info.width, p.info.height),
                format!("{}x{}", f.width, f.height),
            ),
            ("the spp", p.info.spp.to_string(), f.spp.to_string()),
            (
                "the tile count",
                tiles_of(&p.info).to_string(),
                tiles_of(f).to_string(),
            ),
        ];
        for (what, got, want) in checks {
            if got != want {
                return Err(MergeError::Mismatch {
                    path: p.path.clone(),
                    first: first.path.clone(),
                    what,
                    got,
                    want,
                });
            }
        }
    }
    // Every tile's sample ranges must tile 0..spp exactly once.
    let count = tiles_of(f);
    let mut by_tile: BTreeMap<u32, Vec<(Range<u32>, &PathBuf)>> = BTreeMap::new();
    for p in &read {
        let index = p.info.tile.map_or(0, |t| t.index);
        by_tile
            .entry(index)
            .or_default()
            .push((p.info.samples.clone(), &p.path));
    }
    for index in 0..count {
        let name = if count == 1 {
            "the image".to_string()
        } else {
            format!("tile {index}/{count}")
        };
        let Some(ranges) = by_tile.get_mut(&index) else {
            return Err(MergeError::Coverage(format!(
                "{name} has no part (no file holds it)"
            )));
        };
        ranges.sort_by_key(|(r, _)| (r.start, r.end));
        let mut next = 0u32;
        let mut previous: Option<&PathBuf> = None;
        for (r, path) in ranges.iter() {
            if r.start < next {
                return Err(MergeError::Coverage(format!(
                    "{} and {} both hold samples {}..{} of {name}",
                    previous.map_or_else(String::new, |p| p.display().to_string()),
                    path.display(),
                    r.start,
                    next.min(r.end)
                )));
            }
            if r.start > next {
                return Err(MergeError::Coverage(format!(
                    "samples {next}..{} of {name} are missing (no part holds them)",
                    r.start
                )));
            }
            next = r.end;
            previous = Some(path);
        }
        if next < f.spp {
            return Err(MergeError::Coverage(format!(
                "samples {next}..{} of {name} are missing (no part holds them)",
                f.spp
            )));
        }
    }
    let mut film = Film::with_light_layers(f.width, f.height, first.film.light_layer_names())
        .map_err(|e| MergeError::NotAPart {
            path: first.path.clone(),
            reason: e.to_string(),
        })?;
    for p in &read {
        film.merge_rows(&p.film, p.info.rows.start)
            .map_err(|e| MergeError::NotAPart {
                path: p.path.clone(),
                reason: e.to_string(),
            })?;
    }
    let whole = PartInfo {
        tile: None,
        rows: 0..f.height,
        samples: 0..f.spp,
        ..f.clone()
    };
    Ok((film, whole))
}
