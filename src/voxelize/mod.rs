//! Mesh to OpenVDB volume (`velour voxelize`): a narrow-band signed distance level set, or a fog
//! volume made from it, optionally modulated by rest-space fBm noise (docs/voxelize.md).
//!
//! Conventions follow OpenVDB's (docs/references.md §12):
//! - index space: voxel `(i, j, k)` is centred at world `(i V, j V, k V)` (a uniform scale map,
//!   no translation, as OpenVDB's `createLinearTransform(V)`);
//! - **level set**: active voxels where the exact distance to the surface is below `W` voxels,
//!   holding the signed world distance (negative inside); every other voxel is inactive at
//!   `+W V` outside and `−W V` inside (inside bricks far from the surface are inactive tiles);
//!   background `W V`, class `level set`, grid name `surface`;
//! - **fog** (as OpenVDB's `sdfToFogVolume`): 0 and inactive outside; inside, active and equal
//!   to `min(1, d / B)` for a voxel `d` voxels from the surface, so a ramp from 0 at the surface
//!   to 1 at depth `B` voxels and 1 deeper (whole inside bricks are active tiles of 1); with
//!   noise, multiplied by `max(0, 1 + A fbm(F p))` at the voxel's rest-space (mesh) position
//!   `p`; background 0, class `fog volume`, grid name `density`.
//!
//! Distances are exact (closest point on the triangles, [`distance`]); the sign comes from exact
//! ray parity along the three axes with a vote of six half-rays ([`sign`]).

mod assemble;
mod distance;
mod sign;

pub use distance::point_triangle_distance_sq;

use glam::{DAffine3, DVec3, IVec3};
use std::path::Path;

use crate::geometry::{GeometryError, MeshTopology, TriangleMesh};
use crate::grid::{GridError, SparseGrid};
use crate::procedural::{FbmField, FbmParams, ProceduralError};
use crate::vdb::{write_vdb, GridToWrite, MetaEntry, VdbError, WriteOptions};

use sign::{FixedTriangle, ParityTables};

/// Name of the level-set grid written by `voxelize --levelset`.
pub const LEVEL_SET_GRID: &str = "surface";
/// Name of the fog grid written by `voxelize --fog`.
pub const FOG_GRID: &str = "density";
/// Default level-set half width and fog ramp width, in voxels (OpenVDB's
/// `LEVEL_SET_HALF_WIDTH`).
pub const DEFAULT_WIDTH: f64 = 3.0;
/// Largest half width or band, in voxels.
pub const MAX_WIDTH: f64 = 64.0;
/// Largest extent of the voxel domain (mesh bounds plus the band) along any axis, in voxels.
pub const MAX_VOXELS_PER_AXIS: i64 = 8192;
/// Largest number of 8³ bricks in the voxel domain (2²¹, about 10⁹ voxels).
pub const MAX_DOMAIN_BRICKS: i64 = 1 << 21;
/// Largest |index coordinate| of a voxel (the mesh's world position divided by V).
pub const MAX_INDEX_COORDINATE: f64 = (1u64 << 30) as f64;

/// Errors of `voxelize`. Each names the file, flag or value concerned.
#[derive(Debug, thiserror::Error)]
pub enum VoxelizeError {
    /// A parameter outside its allowed range.
    #[error("{flag} {value} is invalid: {allowed}")]
    Parameter {
        /// The flag (`--voxel-size`, `--half-width`, ...).
        flag: &'static str,
        /// The value given.
        value: f64,
        /// What is allowed.
        allowed: String,
    },
    /// The mesh has no triangle of non-zero area.
    #[error("{mesh}: mesh has no faces of non-zero area; nothing to voxelize")]
    NoFaces {
        /// The mesh file.
        mesh: String,
    },
    /// The voxel domain is too large.
    #[error("{mesh}: {what} at --voxel-size {voxel_size} (allowed: {allowed}); use a larger --voxel-size")]
    TooLarge {
        /// The mesh file.
        mesh: String,
        /// What is too large.
        what: String,
        /// The voxel size.
        voxel_size: f64,
        /// The limit.
        allowed: String,
    },
    /// Reading or checking the mesh failed.
    #[error(transparent)]
    Geometry(#[from] GeometryError),
    /// Building the grid failed.
    #[error("building the grid: {0}")]
    Grid(#[from] GridError),
    /// Setting up the noise failed.
    #[error(transparent)]
    Noise(#[from] ProceduralError),
    /// Writing the VDB file failed.
    #[error(transparent)]
    Vdb(#[from] VdbError),
}

/// What to build.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum VolumeKind {
    /// A narrow-band level set with `half_width` voxels on each side of the surface.
    LevelSet {
        /// Half width of the band in voxels (≥ 1).
        half_width: f64,
    },
    /// A fog volume whose density ramps from 0 to 1 across `band` voxels inside the surface.
    Fog {
        /// Width of the ramp in voxels (> 0).
        band: f64,
    },
}

/// Rest-space fBm noise multiplying a fog volume's density by `max(0, 1 + amplitude ·
/// fbm(frequency · p))`, `fbm` ∈ [−1, 1] the sum of `octaves` Perlin octaves (lacunarity 2,
/// gain 0.5; as the procedural interiors, docs/references.md §1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NoiseOptions {
    /// Base frequency, 1 / world unit (> 0).
    pub frequency: f64,
    /// Amplitude (≥ 0; 0 switches the noise off).
    pub amplitude: f64,
    /// Octaves, 1..=16.
    pub octaves: u32,
    /// Noise seed.
    pub seed: u32,
}

/// Options of [`voxelize`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoxelizeOptions {
    /// Voxel edge in world units (> 0).
    pub voxel_size: f64,
    /// Level set or fog.
    pub kind: VolumeKind,
    /// Noise (fog volumes only).
    pub noise: Option<NoiseOptions>,
}

/// Figures of one conversion, for the command's summary and for tests.
#[derive(Clone, Debug, Default)]
pub struct VoxelizeReport {
    /// Triangles used (non-zero area).
    pub triangles: usize,
    /// Edge statistics of the mesh.
    pub topology: MeshTopology,
    /// Voxel domain (inclusive index range).
    pub domain: (IVec3, IVec3),
    /// Bricks reached by the band (exact distances computed).
    pub band_bricks: usize,
    /// Inside bricks away from the surface, stored as constant tiles (or dense with noise).
    pub inside_bricks: usize,
    /// Active voxels, tiles counted voxel by voxel.
    pub active_voxels: u64,
    /// Axis-line crossings found by the sign test.
    pub crossings: usize,
    /// Band voxels whose six half-ray votes disagreed (1 to 5 of 6 inside): 0 for a closed
    /// mesh up to voxels lying exactly on the surface.
    pub split_votes: u64,
    /// Σ value × V³ over active voxels (world units³): for fog the density integral.
    pub integral: f64,
    /// The mesh's enclosed volume by the divergence theorem (world units³; meaningful for
    /// closed meshes).
    pub mesh_volume: f64,
    /// The mesh's surface area (world units²).
    pub mesh_area: f64,
}

/// A converted volume: the grid, its VDB name and class, and the figures.
#[derive(Clone, Debug)]
pub struct Voxelized {
    /// One scalar channel, index-to-world a uniform scale by the voxel size.
    pub grid: SparseGrid,
    /// `surface` or `density`.
    pub name: &'static str,
    /// `level set` or `fog volume`.
    pub class: &'static str,
    /// The figures of the conversion.
    pub report: VoxelizeReport,
}

fn param(flag: &'static str, value: f64, allowed: impl Into<String>) -> VoxelizeError {
    VoxelizeError::Parameter {
        flag,
        value,
        allowed: allowed.into(),
    }
}

impl VoxelizeOptions {
    /// Checks every value, naming the flag of the first bad one.
    ///
    /// # Errors
    /// [`VoxelizeError::Parameter`].
    pub fn validate(&self) -> Result<(), VoxelizeError> {
        let v = self.voxel_size;
        if !(v.is_finite() && v > 0.0) {
            return Err(param(
                "--voxel-size",
                v,
                "must be finite and > 0 (world units)",
            ));
        }
        match self.kind {
            VolumeKind::LevelSet { half_width: w } => {
                if !(w.is_finite() && (1.0..=MAX_WIDTH).contains(&w)) {
                    return Err(param(
                        "--half-width",
                        w,
                        format!("allowed [1, {MAX_WIDTH}] voxels"),
                    ));
                }
            }
            VolumeKind::Fog { band: b } => {
                if !(b.is_finite() && b > 0.0 && b <= MAX_WIDTH) {
                    return Err(param(
                        "--band",
                        b,
                        format!("allowed (0, {MAX_WIDTH}] voxels"),
                    ));
                }
            }
        }
        if let Some(n) = &self.noise {
            if matches!(self.kind, VolumeKind::LevelSet { .. }) {
                return Err(param(
                    "--noise-amplitude",
                    n.amplitude,
                    "noise applies to fog volumes only (--fog), not to level sets",
                ));
            }
            if !(n.frequency.is_finite() && n.frequency > 0.0) {
                return Err(param(
                    "--noise-frequency",
                    n.frequency,
                    "must be finite and > 0 (1 / world unit)",
                ));
            }
            if !(n.amplitude.is_finite() && (0.0..=1e6).contains(&n.amplitude)) {
                return Err(param("--noise-amplitude", n.amplitude, "allowed [0, 1e6]"));
            }
            if !(1..=16).contains(&n.octaves) {
                return Err(param(
                    "--noise-octaves",
                    f64::from(n.octaves),
                    "allowed 1..=16",
                ));
            }
        }
        Ok(())
    }

    /// How far from the surface exact distances are needed, in voxels.
    fn reach(&self) -> f64 {
        match self.kind {
            VolumeKind::LevelSet { half_width } => half_width,
            VolumeKind::Fog { band } => band.max(1.0),
        }
    }
}

/// The mesh's triangles of non-zero area in index space.
fn index_triangles(mesh: &TriangleMesh, voxel_size: f64) -> Vec<[DVec3; 3]> {
    mesh.indices
        .iter()
        .filter_map(|tri| {
            let p = [
                mesh.positions.get(tri[0] as usize)?,
                mesh.positions.get(tri[1] as usize)?,
                mesh.positions.get(tri[2] as usize)?,
            ];
            let p = p.map(|v| v.as_dvec3() / voxel_size);
            let n = (p[1] - p[0]).cross(p[2] - p[0]);
            (n.length_squared() > 0.0).then_some(p)
        })
        .collect()
}

/// The voxel domain: the mesh's bounds plus the reach, checked against the limits.
fn domain(
    tris: &[[DVec3; 3]],
    reach: f64,
    name: &str,
    voxel_size: f64,
) -> Result<(IVec3, IVec3), VoxelizeError> {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for t in tris {
        for p in t {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
    }
    let too_large = |what: String, allowed: String| VoxelizeError::TooLarge {
        mesh: name.to_string(),
        what,
        voxel_size,
        allowed,
    };
    let far = lo.abs().max(hi.abs()).max_element() + reach + 1.0;
    if !(far < MAX_INDEX_COORDINATE) {
        return Err(too_large(
            format!("the mesh reaches {far:.3e} voxels from the origin"),
            format!("at most {MAX_INDEX_COORDINATE:.3e} voxels"),
        ));
    }
    let lo = (lo - DVec3::splat(reach)).floor().as_ivec3() - IVec3::ONE;
    let hi = (hi + DVec3::splat(reach)).ceil().as_ivec3() + IVec3::ONE;
    let size = (hi - lo + IVec3::ONE).as_i64vec3();
    for (axis, n) in ["x", "y", "z"].iter().zip(size.to_array()) {
        if n > MAX_VOXELS_PER_AXIS {
            return Err(too_large(
                format!("the mesh spans {n} voxels along {axis}"),
                format!("at most {MAX_VOXELS_PER_AXIS}"),
            ));
        }
    }
    let bricks = size.to_array().iter().map(|n| n / 8 + 2).product::<i64>();
    if bricks > MAX_DOMAIN_BRICKS {
        return Err(too_large(
            format!("the mesh's bounding box holds about {bricks} bricks of 8³ voxels"),
            format!("at most {MAX_DOMAIN_BRICKS}"),
        ));
    }
    Ok((lo, hi))
}

/// Converts a mesh (world units) into a level set or fog volume. `name` names the mesh in
/// errors. Open or non-manifold meshes are converted (the six-ray vote decides the inside; see
/// the module documentation); the caller warns using [`VoxelizeReport::topology`].
///
/// # Errors
/// Bad options, a mesh without faces of non-zero area or with invalid data, a domain beyond
/// the limits ([`MAX_VOXELS_PER_AXIS`], [`MAX_DOMAIN_BRICKS`]).
pub fn voxelize(
    mesh: &TriangleMesh,
    name: &str,
    opts: &VoxelizeOptions,
) -> Result<Voxelized, VoxelizeError> {
    opts.validate()?;
    if mesh.indices.is_empty() {
        return Err(VoxelizeError::NoFaces {
            mesh: name.to_string(),
        });
    }
    mesh.validate(0)?;
    let v = opts.voxel_size;
    let tris = index_triangles(mesh, v);
    if tris.is_empty() {
        return Err(VoxelizeError::NoFaces {
            mesh: name.to_string(),
        });
    }
    let reach = opts.reach();
    let (lo, hi) = domain(&tris, reach, name, v)?;
    let noise = match opts.noise {
        Some(n) if n.amplitude > 0.0 => {
            let params = FbmParams {
                frequency: n.frequency as f32,
                octaves: n.octaves,
                lacunarity: 2.0,
                gain: 0.5,
                amplitude: n.amplitude as f32,
                offset: 1.0,
                min: 0.0,
                max: (1.0 + n.amplitude) as f32,
                seed: n.seed,
            };
            params.check_extent(lo.abs().max(hi.abs()).max_element() as f64 * v)?;
            Some(FbmField::new(params, DAffine3::IDENTITY)?)
        }
        _ => None,
    };

    let fixed: Vec<FixedTriangle> = tris.iter().map(|t| FixedTriangle::new(*t)).collect();
    let parity = ParityTables::build(&fixed, lo, hi);
    let bands = distance::band_distances(&tris, reach);

    let mut report = VoxelizeReport {
        triangles: tris.len(),
        topology: mesh.topology(),
        domain: (lo, hi),
        band_bricks: bands.len(),
        crossings: parity.crossing_count(),
        mesh_volume: f64::from(mesh.signed_volume()).abs(),
        mesh_area: f64::from(mesh.area()),
        ..VoxelizeReport::default()
    };
    let assembled = match opts.kind {
        VolumeKind::LevelSet { half_width } => {
            assemble::level_set(&bands, &parity, (lo, hi), half_width, v, &mut report)?
        }
        VolumeKind::Fog { band } => assemble::fog(
            &bands,
            &parity,
            (lo, hi),
            band,
            v,
            noise.as_ref(),
            &mut report,
        )?,
    };
    let (grid, name, class) = assembled;
    Ok(Voxelized {
        grid,
        name,
        class,
        report,
    })
}

/// Writes a converted volume as a one-grid OpenVDB file (blosc, OpenVDB's default), with the
/// voxelize parameters as grid metadata (`velour_voxelize_source`, `..._voxel_size`, ...).
///
/// # Errors
/// [`VdbError`] when writing fails.
pub fn write(
    out: &Path,
    vol: &Voxelized,
    source: &str,
    opts: &VoxelizeOptions,
) -> Result<(), VoxelizeError> {
    let mut meta = vec![
        MetaEntry::string("velour_voxelize_source", source),
        MetaEntry::string("velour_voxelize_voxel_size", &opts.voxel_size.to_string()),
    ];
    match opts.kind {
        VolumeKind::LevelSet { half_width } => {
            meta.push(MetaEntry::string(
                "velour_voxelize_half_width",
                &half_width.to_string(),
            ));
        }
        VolumeKind::Fog { band } => {
            meta.push(MetaEntry::string("velour_voxelize_band", &band.to_string()));
        }
    }
    if let Some(n) = opts.noise.filter(|n| n.amplitude > 0.0) {
        meta.push(MetaEntry::string(
            "velour_voxelize_noise",
            &format!(
                "frequency {} amplitude {} octaves {} seed {}",
                n.frequency, n.amplitude, n.octaves, n.seed
            ),
        ));
    }
    let g = GridToWrite {
        class: vol.class,
        metadata: &meta,
        ..GridToWrite::new(vol.name, &vol.grid)
    };
    write_vdb(out, &[g], &WriteOptions::default())?;
    Ok(())
}
