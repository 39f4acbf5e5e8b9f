//! Procedural fabric: yarns, weaves, velvet pile and fibre scattering.
//!
//! The generator half of the fabric pipeline of the course notes (§3, "Volumetric Skin and
//! Fabric Shading at Framestore"):
//!
//! * [`yarn`]: the procedural yarn model of Zhao, Luan and Bala 2016 ("Fitting Procedural
//!   Yarn Models for Realistic Cloth Rendering"): plies twisted around the yarn axis, fibres
//!   over each ply's cross-section with twist and migration, loop and hair flyaways; named
//!   presets from the published fits; yarns placed on arbitrary centrelines with a
//!   rotation-minimising frame.
//! * [`weave`]: weave patterns as binary matrices (plain, twill, basket, satin, velvet),
//!   warp/weft centrelines with a cosine ease, and [`weave::generate_patch`], which returns a
//!   periodic patch of tagged fibres ([`weave::YarnId`]) ready for voxelisation.
//! * [`fibre_scattering`]: the Chiang et al. 2016 fibre scattering model (R, TT, TRT and the
//!   residual lobe) plus a Lambertian-cylinder diffuse lobe, as a phase function of fibre
//!   volumes, and an SGGX fibre microflake alternative.
//! * [`mod@voxelise`]: coverage-weighted voxelisation of a patch into a [`crate::grid::SparseGrid`]
//!   (density, mean tangent, yarn id), mip levels, OpenVDB export and a single-scattering
//!   preview renderer.
//! * [`shell`]: a voxelised patch tiled over a mesh shell (draped cloth), with the exact
//!   shell map from world points to patch voxels.
//! * [`look`]: how a voxelised patch is shaded and looked up by the renderer: fibre phase
//!   functions per yarn family, fibre tangents in world space, fibre-projected extinction.
//! * [`patch_file`]: the patch files `velour weave` writes (grids plus the generator's
//!   parameters as metadata) read back for rendering.
//! * [`lod`]: the level-of-detail policy of a rendered fabric: the mip level a view needs, the
//!   tiles that give a shell's weave its true size, the normalisation of fibre-projected
//!   extinction.
//!
//! Lengths: the yarn presets are in **centimetres** (the units of the released fits); every
//! length in this module is in the same unit as the yarn parameters it came from. Use
//! [`yarn::YarnParams::scaled`] to convert to scene units.

mod fibre_fast_math;
pub mod fibre_scattering;
mod floor;
pub mod lod;
pub mod look;
pub mod patch_file;
pub mod shell;
pub mod voxelise;
pub mod weave;
pub mod yarn;

pub use fibre_scattering::{
    FibreColour, FibreLobes, FibrePhase, FibrePhaseParams, FibreSample, PreparedFibre,
    SggxFibrePhase, SggxSample,
};
pub use floor::floor_ivec3;
pub use look::{
    projected_width, FabricLook, FibreExtinction, FibreGridLookup, ShellLookup, YarnColours,
};
pub use patch_file::{read_patch_file, PatchFile, PatchFileError, WeaveRecord};
pub use shell::{FabricShell, FibreVoxel, ShellCursor, ShellParams, ShellPoint};
pub use voxelise::{
    render_preview, voxelise, write_patch_vdb, write_patch_vdb_with_metadata, PreviewImage,
    PreviewOptions, VoxelStats, VoxeliseOptions, VoxelisedPatch,
};
pub use weave::{
    generate_patch, FabricPatch, FabricShading, PatchFibre, PileParams, TwillDirection,
    WeaveMatrix, WeaveParams, WeavePattern, YarnId,
};
pub use yarn::{
    generate_yarn, generate_yarn_on_centreline, Centreline, CentrelineFrame, Fibre, FibreKind,
    NormalDist, Twist, Yarn, YarnParams,
};

/// Errors of the fabric generator. Every message names the offending parameter (or
/// preset/pattern name) and the allowed range or values.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FabricError {
    /// A numeric parameter is outside its allowed range.
    #[error("fabric parameter `{name}` = {value} is invalid: allowed {allowed}")]
    InvalidParameter {
        /// Parameter name, as spelt in the Rust struct (e.g. `yarn.ply_count`).
        name: String,
        /// The rejected value, formatted.
        value: String,
        /// The allowed range or values.
        allowed: String,
    },
    /// A yarn preset name is unknown.
    #[error("unknown yarn preset `{name}`: allowed {allowed}")]
    UnknownPreset {
        /// The requested name.
        name: String,
        /// The known names.
        allowed: String,
    },
    /// A weave pattern name is unknown.
    #[error("unknown weave pattern `{name}`: allowed {allowed}")]
    UnknownPattern {
        /// The requested name.
        name: String,
        /// The known names.
        allowed: String,
    },
    /// A weave matrix is not a valid weave (a yarn never interlaces, ragged rows, ...).
    #[error("invalid weave pattern `{pattern}`: {reason}")]
    InvalidPattern {
        /// The pattern (or parameter) concerned.
        pattern: String,
        /// What is wrong.
        reason: String,
    },
    /// The requested geometry would not fit in memory.
    #[error("fabric parameter `{name}` asks for {count} {what}, more than the limit of {limit}")]
    TooLarge {
        /// The parameter that drives the size.
        name: String,
        /// What is being counted (fibres, vertices).
        what: String,
        /// The estimated count.
        count: u64,
        /// The limit.
        limit: u64,
    },
    /// A centreline is unusable (fewer than two distinct points, non-finite values).
    #[error("invalid centreline: {reason}")]
    InvalidCentreline {
        /// What is wrong.
        reason: String,
    },
    /// Writing an export failed.
    #[error("could not write {what}: {reason}")]
    Io {
        /// What was being written.
        what: String,
        /// The I/O error.
        reason: String,
    },
}

/// Builds an [`FabricError::InvalidParameter`].
pub(crate) fn invalid(name: &str, value: impl std::fmt::Display, allowed: &str) -> FabricError {
    FabricError::InvalidParameter {
        name: name.to_string(),
        value: value.to_string(),
        allowed: allowed.to_string(),
    }
}

/// Checks `lo <= x <= hi` (and finiteness); `name` and `allowed` go into the error.
pub(crate) fn check_range(name: &str, x: f32, lo: f32, hi: f32) -> Result<(), FabricError> {
    if x.is_finite() && x >= lo && x <= hi {
        Ok(())
    } else {
        Err(invalid(name, x, &format!("[{lo}, {hi}]")))
    }
}

/// Checks `0 < x <= hi` (and finiteness).
pub(crate) fn check_positive(name: &str, x: f32, hi: f32) -> Result<(), FabricError> {
    if x.is_finite() && x > 0.0 && x <= hi {
        Ok(())
    } else {
        Err(invalid(name, x, &format!("(0, {hi}]")))
    }
}

/// The fibre tangent a lookup at index-space point `p` sees (voxel centres at integers): the
/// nearest voxel's, or, where that voxel holds no fibre (the fringe of a yarn, reached by the
/// trilinear density of its neighbours), the tangent of the trilinear corner with the largest
/// weight that holds one. Zero when no corner does. `fetch` reads a voxel's tangent (and
/// applies any wrapping).
#[inline]
pub fn tangent_near(p: glam::Vec3, mut fetch: impl FnMut(glam::IVec3) -> glam::Vec3) -> glam::Vec3 {
    let nearest = fetch(floor_ivec3(p + glam::Vec3::splat(0.5)));
    if nearest != glam::Vec3::ZERO {
        return nearest;
    }
    let base = floor_ivec3(p);
    let t = p - base.as_vec3();
    let mut best = (0.0f32, glam::Vec3::ZERO);
    for k in 0..8 {
        let d = glam::IVec3::new(k >> 2, (k >> 1) & 1, k & 1);
        let w = (if d.x == 1 { t.x } else { 1.0 - t.x })
            * (if d.y == 1 { t.y } else { 1.0 - t.y })
            * (if d.z == 1 { t.z } else { 1.0 - t.z });
        if w > best.0 {
            let v = fetch(base + d);
            if v != glam::Vec3::ZERO {
                best = (w, v);
            }
        }
    }
    best.1
}
