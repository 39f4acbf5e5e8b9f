//! Weave patch files: the OpenVDB files `velour weave` writes (grids `density`, `tangent`,
//! `id`, and `density_mipN`, `tangent_mipN`, `id_mipN` for extra mip levels) with the
//! generator's parameters as file-level metadata ([`WeaveRecord`]), and reading them back
//! into [`VoxelisedPatch`]es for rendering (`interior = { type = "fabric", file = … }`).

use std::path::{Path, PathBuf};

use super::voxelise::{DENSITY, ID, TANGENT};
use super::{VoxelisedPatch, WeaveParams, WeavePattern, YarnParams};
use crate::grid::{ChannelKind, SparseGrid, SparseGridBuilder, Storage, BRICK_VOXELS};
use crate::math::Vec3;
use crate::spectrum::Rgb;
use crate::vdb::{MetaEntry, ValueType, VdbFile, VdbGrid};

/// Prefix of the file-level metadata entries of a weave patch.
pub const META_PREFIX: &str = "velour_weave.";

/// Version of the metadata layout (`velour_weave.version`).
pub const META_VERSION: i64 = 1;

/// The coarsest stored mip level a patch file is searched for.
const MAX_FILE_LEVEL: u32 = 12;

/// The generator parameters of a weave patch, as `velour weave` records them in the file's
/// metadata (entries `velour_weave.<field>`), with what is needed to interpret the grids.
#[derive(Clone, Debug, PartialEq)]
pub struct WeaveRecord {
    /// Weave pattern name as given (`plain`, `twill`, …; [`WeavePattern::from_name`]).
    pub pattern: String,
    /// Yarn preset of the warps ([`YarnParams::preset`]).
    pub warp_yarn: String,
    /// Yarn preset of the wefts.
    pub weft_yarn: String,
    /// Voxels across the tile's largest side at level 0.
    pub resolution: u32,
    /// Pattern repeats along `x` and `y`.
    pub repeats: [u32; 2],
    /// Seed of the fibre generator.
    pub seed: u64,
    /// Flyaway amount (multiplies the fitted hair and loop densities).
    pub flyaways: f32,
    /// Warp, weft and pile albedos the patch was generated with (its default look).
    pub albedos: [Rgb; 3],
    /// The periodic tile, world (patch) units.
    pub tile: [f64; 2],
    /// Voxels across the tile along `x` and `y` at level 0.
    pub dims: [u32; 2],
}

fn key(field: &str) -> String {
    format!("{META_PREFIX}{field}")
}

impl WeaveRecord {
    /// The record of a patch generated from `params` with `seed`, given the names of its
    /// pattern and yarns, voxelised at `resolution` into `level0`.
    #[must_use]
    pub fn new(
        names: [&str; 3],
        params: &WeaveParams,
        seed: u64,
        resolution: u32,
        pile_albedo: Rgb,
        level0: &VoxelisedPatch,
    ) -> WeaveRecord {
        WeaveRecord {
            pattern: names[0].trim().to_ascii_lowercase(),
            warp_yarn: names[1].trim().to_ascii_lowercase(),
            weft_yarn: names[2].trim().to_ascii_lowercase(),
            resolution,
            repeats: params.repeats,
            seed,
            flyaways: params.flyaway_fraction,
            albedos: [params.warp_albedo, params.weft_albedo, pile_albedo],
            tile: level0.tile,
            dims: level0.dims,
        }
    }

    /// The metadata entries.
    #[must_use]
    pub fn to_metadata(&self) -> Vec<MetaEntry> {
        let rgb = |c: Rgb| [c.r(), c.g(), c.b()];
        vec![
            MetaEntry::int64(&key("version"), META_VERSION),
            MetaEntry::string(&key("pattern"), &self.pattern),
            MetaEntry::string(&key("warp_yarn"), &self.warp_yarn),
            MetaEntry::string(&key("weft_yarn"), &self.weft_yarn),
            MetaEntry::int64(&key("resolution"), i64::from(self.resolution)),
            MetaEntry::int64(&key("repeats_x"), i64::from(self.repeats[0])),
            MetaEntry::int64(&key("repeats_y"), i64::from(self.repeats[1])),
            // A string: OpenVDB has no unsigned 64-bit metadata.
            MetaEntry::string(&key("seed"), &self.seed.to_string()),
            MetaEntry::float(&key("flyaways"), self.flyaways),
            MetaEntry::vec3s(&key("warp_albedo"), rgb(self.albedos[0])),
            MetaEntry::vec3s(&key("weft_albedo"), rgb(self.albedos[1])),
            MetaEntry::vec3s(&key("pile_albedo"), rgb(self.albedos[2])),
            MetaEntry::double(&key("tile_x"), self.tile[0]),
            MetaEntry::double(&key("tile_y"), self.tile[1]),
            MetaEntry::int64(&key("dims_x"), i64::from(self.dims[0])),
            MetaEntry::int64(&key("dims_y"), i64::from(self.dims[1])),
        ]
    }

    /// Reads the record from a file's metadata. `Ok(None)` when the file has no
    /// `velour_weave.` entries at all; an error naming the entry when one is missing or has
    /// the wrong type or an invalid value.
    pub fn from_metadata(meta: &[MetaEntry]) -> Result<Option<WeaveRecord>, String> {
        if !meta.iter().any(|e| e.name.starts_with(META_PREFIX)) {
            return Ok(None);
        }
        let get = |f: &str| {
            let k = key(f);
            meta.iter()
                .find(|e| e.name == k)
                .ok_or_else(|| format!("metadata entry `{k}` is missing"))
        };
        let text = |f: &str| -> Result<String, String> {
            get(f)?
                .as_str()
                .map(str::to_string)
                .ok_or_else(|| format!("metadata entry `{}` is not a string", key(f)))
        };
        let int = |f: &str, lo: i64, hi: i64| -> Result<u32, String> {
            let v = get(f)?
                .as_i64()
                .ok_or_else(|| format!("metadata entry `{}` is not an integer", key(f)))?;
            if (lo..=hi).contains(&v) {
                Ok(v as u32)
            } else {
                Err(format!(
                    "metadata entry `{}` = {v} is outside [{lo}, {hi}]",
                    key(f)
                ))
            }
        };
        let real = |f: &str| -> Result<f64, String> {
            let v = get(f)?
                .as_f64()
                .ok_or_else(|| format!("metadata entry `{}` is not a number", key(f)))?;
            if v.is_finite() && v >= 0.0 {
                Ok(v)
            } else {
                Err(format!(
                    "metadata entry `{}` = {v} is not finite and ≥ 0",
                    key(f)
                ))
            }
        };
        let colour = |f: &str| -> Result<Rgb, String> {
            let v = get(f)?
                .as_vec3s()
                .ok_or_else(|| format!("metadata entry `{}` is not a vec3s", key(f)))?;
            if v.iter().all(|x| x.is_finite() && (0.0..=1.0).contains(x)) {
                Ok(Rgb::new(v[0], v[1], v[2]))
            } else {
                Err(format!(
                    "metadata entry `{}` = {v:?} is outside [0, 1]",
                    key(f)
                ))
            }
        };
        let version = get("version")?.as_i64();
        if version != Some(META_VERSION) {
            return Err(format!(
                "metadata entry `{}` = {version:?} is not the supported version {META_VERSION}",
                key("version")
            ));
        }
        let seed = text("seed")?;
        let seed = seed.trim().parse::<u64>().map_err(|_| {
            format!(
                "metadata entry `{}` = \"{seed}\" is not a seed",
                key("seed")
            )
        })?;
        let tile = [real("tile_x")?, real("tile_y")?];
        if tile.iter().any(|t| *t <= 0.0) {
            return Err(format!(
                "the tile {tile:?} recorded in the metadata is empty"
            ));
        }
        Ok(Some(WeaveRecord {
            pattern: text("pattern")?,
            warp_yarn: text("warp_yarn")?,
            weft_yarn: text("weft_yarn")?,
            resolution: int("resolution", 1, 8192)?,
            repeats: [int("repeats_x", 1, 1024)?, int("repeats_y", 1, 1024)?],
            seed,
            flyaways: real("flyaways")? as f32,
            albedos: [
                colour("warp_albedo")?,
                colour("weft_albedo")?,
                colour("pile_albedo")?,
            ],
            tile,
            dims: [int("dims_x", 1, 1 << 20)?, int("dims_y", 1, 1 << 20)?],
        }))
    }

    /// The recorded pattern, parsed.
    pub fn weave_pattern(&self) -> Result<WeavePattern, String> {
        WeavePattern::from_name(&self.pattern).map_err(|e| e.to_string())
    }

    /// The recorded warp and weft yarns, parsed.
    pub fn yarns(&self) -> Result<[YarnParams; 2], String> {
        let p = |n: &str| YarnParams::preset(n).map_err(|e| e.to_string());
        Ok([p(&self.warp_yarn)?, p(&self.weft_yarn)?])
    }
}

/// Why a patch file cannot be used. Every message names the file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PatchFileError {
    /// The file cannot be opened or read, or a grid is corrupt.
    #[error("{path}: {reason}")]
    Read {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        reason: String,
    },
    /// A grid the patch needs is missing.
    #[error("{path}: a weave patch needs the grid `{grid}`, which the file lacks (it has: {available}); write patches with `velour weave -o`")]
    MissingGrid {
        /// The file.
        path: PathBuf,
        /// The missing grid.
        grid: String,
        /// The grids the file has.
        available: String,
    },
    /// The file has no (or broken) weave metadata.
    #[error("{path}: {reason}")]
    Metadata {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// A grid has the wrong type, or the grids of a level disagree.
    #[error("{path}: grid `{grid}`: {reason}")]
    BadGrid {
        /// The file.
        path: PathBuf,
        /// The grid.
        grid: String,
        /// What is wrong.
        reason: String,
    },
}

/// A weave patch file read back: its record and the mip levels it stores (index = level;
/// level 0 is always present).
#[derive(Clone, Debug)]
pub struct PatchFile {
    /// The generator parameters.
    pub record: WeaveRecord,
    /// Stored levels; `levels[l]` is level `l` when the file has it.
    pub levels: Vec<Option<VoxelisedPatch>>,
}

impl PatchFile {
    /// Level `l`: the stored one, or built from level 0 ([`VoxelisedPatch::mip`] over the
    /// accumulators rebuilt by [`VoxelisedPatch::from_channels`]).
    ///
    /// # Errors
    /// [`super::FabricError`] from building the level.
    pub fn level(&self, l: u32) -> Result<VoxelisedPatch, super::FabricError> {
        if let Some(Some(p)) = self.levels.get(l as usize) {
            return Ok(p.clone());
        }
        match self.levels.first() {
            Some(Some(base)) => base.mip(l),
            _ => Err(super::invalid("patch file levels", "none", "level 0")),
        }
    }

    /// Whether the file stores level `l` (otherwise [`Self::level`] builds it).
    #[must_use]
    pub fn stores(&self, l: u32) -> bool {
        matches!(self.levels.get(l as usize), Some(Some(_)))
    }
}

/// The names of the three grids of level `l`.
fn grid_names(l: u32) -> [String; 3] {
    let suffix = if l == 0 {
        String::new()
    } else {
        format!("_mip{l}")
    };
    [
        format!("density{suffix}"),
        format!("tangent{suffix}"),
        format!("id{suffix}"),
    ]
}

/// Reads a weave patch file: its metadata record and every stored level.
///
/// # Errors
/// [`PatchFileError`]: an unreadable file, a missing `density`, `tangent` or `id` grid (of
/// level 0, or of a stored coarser level), missing weave metadata, grids of the wrong type or
/// with different transforms.
pub fn read_patch_file(path: &Path) -> Result<PatchFile, PatchFileError> {
    let read_err = |e: &dyn std::fmt::Display| PatchFileError::Read {
        path: path.to_path_buf(),
        reason: e.to_string(),
    };
    let file = VdbFile::open(path).map_err(|e| read_err(&e))?;
    let names = file.grid_names();
    let has = |n: &str| names.iter().any(|g| g == n);
    let missing = |grid: &str| PatchFileError::MissingGrid {
        path: path.to_path_buf(),
        grid: grid.to_string(),
        available: if names.is_empty() {
            "no grids".into()
        } else {
            names.join(", ")
        },
    };
    // Grids before metadata: a file without the tangent or id grid is not a patch at all.
    for n in grid_names(0) {
        if !has(&n) {
            return Err(missing(&n));
        }
    }
    let record = WeaveRecord::from_metadata(&file.metadata)
        .map_err(|reason| PatchFileError::Metadata {
            path: path.to_path_buf(),
            reason,
        })?
        .ok_or_else(|| PatchFileError::Metadata {
            path: path.to_path_buf(),
            reason: format!(
                "no `{META_PREFIX}*` metadata: the file was not written by `velour weave` (or by one older than the patch round trip); weave it again"
            ),
        })?;
    let mut levels = Vec::new();
    for l in 0..=MAX_FILE_LEVEL {
        let n = grid_names(l);
        if l > 0 && !has(&n[0]) {
            levels.push(None);
            continue;
        }
        for g in &n {
            if !has(g) {
                return Err(missing(g));
            }
        }
        let read = |g: &str| file.read_grid(g).map_err(|e| read_err(&e));
        let grids = [read(&n[0])?, read(&n[1])?, read(&n[2])?];
        let dims = record.dims.map(|d| d.div_ceil(1 << l));
        let grid = merge_channels(path, &grids)?;
        let vp = VoxelisedPatch::from_channels(grid, l, dims, record.tile).map_err(|e| {
            PatchFileError::BadGrid {
                path: path.to_path_buf(),
                grid: n[0].clone(),
                reason: e.to_string(),
            }
        })?;
        levels.push(Some(vp));
    }
    while matches!(levels.last(), Some(None)) {
        levels.pop();
    }
    Ok(PatchFile { record, levels })
}

/// One grid with the three channels of a level, from its `density`, `tangent` and `id` grids
/// (checked: scalar, Vec3, scalar, one transform).
fn merge_channels(path: &Path, grids: &[VdbGrid; 3]) -> Result<SparseGrid, PatchFileError> {
    let bad = |g: &VdbGrid, reason: String| PatchFileError::BadGrid {
        path: path.to_path_buf(),
        grid: g.name.clone(),
        reason,
    };
    let scalar = |t: ValueType| t.components() == 1;
    let [d, t, i] = grids;
    if !scalar(d.value_type) {
        return Err(bad(d, "expected a scalar (float) grid".into()));
    }
    if t.value_type.components() != 3 {
        return Err(bad(t, "expected a vec3 grid".into()));
    }
    if !scalar(i.value_type) {
        return Err(bad(i, "expected a scalar (float) grid".into()));
    }
    for g in [t, i] {
        let (a, b) = (d.grid.index_to_world(), g.grid.index_to_world());
        if !a.abs_diff_eq(b, 1e-9 * a.matrix3.x_axis.length().max(1.0)) {
            return Err(bad(
                g,
                format!(
                    "its transform differs from the grid `{}`'s; the three grids of a level must share one",
                    d.name
                ),
            ));
        }
    }
    let mut gb = SparseGridBuilder::new(Storage::F32);
    gb.add_channel("density", ChannelKind::Scalar, Vec3::ZERO);
    gb.add_channel("tangent", ChannelKind::Vec3, Vec3::ZERO);
    gb.add_channel("id", ChannelKind::Scalar, Vec3::ZERO);
    gb.set_index_to_world(d.grid.index_to_world())
        .map_err(|e| bad(d, e.to_string()))?;
    let mut dens = vec![0.0f32; BRICK_VOXELS];
    let mut tan = vec![0.0f32; BRICK_VOXELS * 3];
    let mut id = vec![0.0f32; BRICK_VOXELS];
    for b in 0..d.grid.brick_count() {
        let origin = d.grid.brick_origin(b);
        let mask = *d.grid.brick_active_mask(b);
        let src = d.grid.brick_data(0, b);
        for (v, x) in dens.iter_mut().enumerate() {
            *x = src.get(v, 1, 0);
        }
        tan.fill(0.0);
        if let Some(tb) = t.grid.brick_at_voxel(origin) {
            let src = t.grid.brick_data(0, tb);
            for (k, x) in tan.iter_mut().enumerate() {
                *x = src.get(k / 3, 3, k % 3);
            }
        }
        id.fill(0.0);
        if let Some(ib) = i.grid.brick_at_voxel(origin) {
            let src = i.grid.brick_data(0, ib);
            for (v, x) in id.iter_mut().enumerate() {
                *x = src.get(v, 1, 0);
            }
        }
        let key = origin >> 3;
        let err = |e: crate::grid::GridError| bad(d, e.to_string());
        gb.fill_brick(DENSITY, key, &dens, mask).map_err(err)?;
        gb.fill_brick(TANGENT, key, &tan, mask).map_err(err)?;
        gb.fill_brick(ID, key, &id, mask).map_err(err)?;
    }
    Ok(gb.build())
}
