//! `interior = { ... }`: what fills an object, one builder per interior type.
//!
//! * `absorption`, `homogeneous` ([`homogeneous`]): constant coefficients.
//! * `voxel` ([`voxel`]): a density grid from an OpenVDB file.
//! * `fbm` ([`fbm`]): procedural fBm noise, baked, baked lazily or evaluated exactly.
//! * `fabric` ([`fabric`]): a woven patch voxelised at load time or read from a `velour weave`
//!   file ([`fabric_source`]), free-standing or as a shell over a mesh.
//! * `mixture` ([`mixture`]): two to four of `homogeneous`, `voxel` and `fbm` in one object;
//!   `voxel` interiors with albedo or emission grids ([`grids`]) are built as one-component
//!   mixtures.
//!
//! `voxel` and `fbm` share their coefficients, combined homogeneous base medium and
//! estimator choices ([`heterogeneous`], [`tracking`]), and their texturable `albedo`,
//! `attenuation` and `density` ([`field_params`]); `homogeneous`, `voxel` and `fbm` share the
//! scattering keys ([`scattering`]).

mod blend;
mod fabric;
mod fabric_source;
mod fbm;
mod field_params;
mod grids;
mod heterogeneous;
mod homogeneous;
mod mixture;
mod scattering;
mod tracking;
mod voxel;

pub(super) use fabric::fabric_note;

use super::context::Ctx;
use super::desc::{ColorInput, ColorValue, InteriorDesc, ScalarInput};
use super::textures::ParamSite;
use super::validate::{check_range, color};
use super::SceneError;
use crate::geometry::TriangleMesh;
use crate::math::{Aabb, Mat4};
use crate::medium::{Medium, NeeStrategy, WalkInterior};
use crate::spectrum::Rgb;
use crate::texture::{ColorParam, ScalarParam};

/// Where an interior sits: the object transform and its rest shape. (Nothing here depends on
/// the camera or the film size: a fabric's mip level is chosen per ray, from the ray cone.)
pub(super) struct Placement<'a> {
    /// Object to world.
    pub xf: Mat4,
    /// The rest-space box of a mesh, sphere or level-set shape (none for `shape = "bounds"`).
    pub rest_bounds: Option<Aabb>,
    /// The rest-space mesh of a mesh shape.
    pub rest_mesh: Option<&'a TriangleMesh>,
    /// True when the shape has texture coordinates (a mesh with UVs, or a sphere).
    pub has_uvs: bool,
}

/// An interior as built: its medium (for an interior resolved per walk, the one used where
/// no entry point is known: the textures' means, or a blend's first look), its NEE strategy,
/// and how walks resolve it.
pub(super) struct BuiltInterior {
    /// The medium.
    pub medium: Medium,
    /// Where NEE happens inside.
    pub nee: NeeStrategy,
    /// Textured (entry-projected) or blended interiors: resolved per walk.
    pub walk: Option<WalkInterior>,
}

/// The interior of object `name`. `line` is the line of the interior table; `owner` names
/// it in messages (`"<name>: interior"`, or a blend's `"<name>: interior.a"`). Media a blend
/// refers to are added to `media`.
pub(super) fn build_medium(
    ctx: &Ctx,
    line: usize,
    name: &str,
    owner: String,
    interior: &InteriorDesc,
    placement: &Placement<'_>,
    media: &mut Vec<Medium>,
) -> Result<BuiltInterior, SceneError> {
    let at = Site {
        ctx,
        line,
        name,
        owner,
        has_uvs: placement.has_uvs,
        placement,
    };
    Ok(match interior {
        InteriorDesc::Absorption(d) => homogeneous::absorption(&at, d, placement)?,
        InteriorDesc::Homogeneous(d) => homogeneous::homogeneous(&at, d, placement)?,
        InteriorDesc::Voxel(d) => voxel::build(&at, d, placement)?,
        InteriorDesc::Fbm(d) => fbm::build(&at, d, placement)?,
        InteriorDesc::Fabric(d) => fabric::build(&at, d, placement)?,
        InteriorDesc::Blend(d) => blend::build(&at, d, placement, media)?,
        InteriorDesc::Mixture(d) => mixture::build(&at, d, placement, media)?,
    })
}

/// How an interior's textured parameters are read (`projection`, docs/textures.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Projection {
    /// At the entry point, homogeneous along the walk.
    Entry,
    /// At the boundary point closest to every lookup.
    Surface,
}

/// What an interior builder reports errors with: the scene, the interior table's line, the
/// object's name and `"<name>: interior"`.
struct Site<'a> {
    ctx: &'a Ctx<'a>,
    line: usize,
    name: &'a str,
    owner: String,
    has_uvs: bool,
    /// Where the interior sits (for builders that do not take it themselves).
    placement: &'a Placement<'a>,
}

impl Site<'_> {
    /// Where the interior's texturable parameters are read.
    fn params(&self) -> ParamSite<'_> {
        ParamSite {
            ctx: self.ctx,
            line: self.line,
            owner: &self.owner,
            name: self.name,
            has_uvs: self.has_uvs,
        }
    }

    /// How textured parameters are read (`projection`): "entry" (the default) or "surface",
    /// which needs a mesh boundary with texture coordinates.
    fn projection(
        &self,
        p: Option<&str>,
        placement: &Placement<'_>,
    ) -> Result<Projection, SceneError> {
        match p.unwrap_or("entry") {
            "entry" => Ok(Projection::Entry),
            "surface" => match placement.rest_mesh {
                None => Err(self.invalid(format!("{}.projection = \"surface\" needs a mesh boundary to project onto (shape = \"mesh\" with texture coordinates); this object's shape is a sphere or bounds (use \"entry\")", self.owner))),
                Some(m) if m.uvs.is_none() => Err(self.invalid(format!("{}.projection = \"surface\": the mesh has no texture coordinates (per-vertex u, v in the PLY) to read the textures at", self.owner))),
                Some(_) => Ok(Projection::Surface),
            },
            other => Err(self.invalid(format!("{}.projection = \"{other}\" is unknown (expected \"entry\" or \"surface\")", self.owner))),
        }
    }

    /// The object's mesh placed in the world and prepared for closest-point queries: what
    /// `projection = "surface"` projects onto (checked by [`Self::projection`]).
    fn surface_boundary(
        &self,
        placement: &Placement<'_>,
    ) -> Result<crate::geometry::ClosestPointMesh, SceneError> {
        let mesh = placement.rest_mesh.ok_or_else(|| {
            self.invalid(format!(
                "{}.projection = \"surface\" needs a mesh boundary",
                self.owner
            ))
        })?;
        let world = mesh.transformed(placement.xf);
        crate::geometry::ClosestPointMesh::build(&world, &format!("{}.projection", self.owner))
            .map_err(|e| self.failed(&e))
    }

    /// An invalid-value error at the interior's line.
    fn invalid(&self, message: impl Into<String>) -> SceneError {
        self.ctx.invalid(self.line, message)
    }

    /// An error of a loader or constructor, prefixed with the owner.
    fn failed(&self, e: &dyn std::fmt::Display) -> SceneError {
        self.invalid(format!("{}: {e}", self.owner))
    }

    /// `v` when it is finite and in `[min, max]`; `key` is the interior's key.
    fn range(&self, key: &str, v: f32, min: f32, max: f32) -> Result<f32, SceneError> {
        check_range(
            self.ctx,
            self.line,
            &format!("{}.{key}", self.owner),
            v,
            min,
            max,
        )
    }

    /// A colour key in `[0, 1]`, or `default`.
    fn unit_colour(
        &self,
        key: &str,
        v: Option<ColorValue>,
        default: Rgb,
    ) -> Result<Rgb, SceneError> {
        super::validate::check_finite_rgb(
            self.ctx,
            self.line,
            &format!("{}.{key}", self.owner),
            color(v, default),
            0.0,
            1.0,
        )
    }
}

/// The keys every interior type has: `density` (≥ 0, default 1) and `attenuation` (a
/// distance > 0 per channel, default 1), and `nee`. `nee` absent or `"auto"` gives
/// `"exit"` here; the object builder resolves that default once the surface and the lights
/// are known ([`super::nee`]).
fn extinction_and_nee(
    at: &Site,
    density: Option<f32>,
    attenuation: Option<ColorValue>,
    nee: Option<&str>,
) -> Result<(f32, Rgb, NeeStrategy), SceneError> {
    let density = at.range("density", density.unwrap_or(1.0), 0.0, 1e12)?;
    let attenuation = color(attenuation, Rgb::ONE);
    for v in attenuation.0 {
        if v.is_nan() || v <= 0.0 {
            return Err(at.invalid(format!("{}.attenuation = {:?}: every channel must be a distance > 0 (use a large value for no attenuation)", at.owner, attenuation.0)));
        }
    }
    let nee = match nee.unwrap_or(super::nee::AUTO) {
        "exit" | super::nee::AUTO => NeeStrategy::ExitPoint,
        "interior" => NeeStrategy::Interior,
        "exit_guided" => NeeStrategy::ExitGuided,
        "manifold" => NeeStrategy::Manifold,
        other => {
            return Err(at.invalid(format!(
                "{}: interior.nee = \"{other}\" is unknown (expected \"auto\", \"exit\", \"exit_guided\", \"interior\" or \"manifold\")",
                at.name
            )))
        }
    };
    Ok((density, attenuation, nee))
}

/// [`extinction_and_nee`] for interiors whose `density` and `attenuation` may be textures
/// (textured attenuations must be > 0 everywhere, textured densities finite and ≥ 0).
fn textured_extinction_and_nee(
    at: &Site,
    density: Option<&ScalarInput>,
    attenuation: Option<&ColorInput>,
    nee: Option<&str>,
) -> Result<(ScalarParam, ColorParam, NeeStrategy), SceneError> {
    let constant_density = match density {
        Some(ScalarInput::Value(v)) => Some(*v),
        _ => None,
    };
    let constant_attenuation = match attenuation {
        Some(ColorInput::Value(v)) => Some(*v),
        _ => None,
    };
    let (d, a, nee) = extinction_and_nee(at, constant_density, constant_attenuation, nee)?;
    let p = at.params();
    let density = match density {
        Some(ScalarInput::Texture(_)) => p.scalar("density", density, 1.0, 0.0, 1e12)?,
        _ => ScalarParam::Constant(d),
    };
    let attenuation = match attenuation {
        Some(ColorInput::Texture(_)) => {
            p.colour("attenuation", attenuation, Rgb::ONE, 1e-9, f32::INFINITY)?
        }
        _ => ColorParam::Constant(a),
    };
    Ok((density, attenuation, nee))
}
