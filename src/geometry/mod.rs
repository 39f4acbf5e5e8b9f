//! Surface geometry: triangle meshes (PLY reading of our own, writing through `ply-rs-bw`),
//! analytic spheres, level-set boundaries (zero crossings of a grid, [`LevelSet`]), and one BVH over every triangle of a scene (a full-sweep SAH
//! binary build with `obvhs`'s reinsertion, collapsed into our own 8-wide BVH and traversal) with our own robust primitive tests.
//!
//! Robustness contract (what the integrator relies on):
//! - Ray–triangle hits use the watertight test of Woop, Benthin & Wald 2013 ("Watertight
//!   Ray/Triangle Intersection", JCGT 2(1)), extended with a consistent tie-breaking rule
//!   (symbolic perturbation of the ray origin) so that a ray through a shared edge or vertex
//!   of a mesh hits exactly one of the triangles that meet there.
//! - BVH node tests are conservative: primitive boxes are padded by a rounding-error bound
//!   and the ray–box slab test subtracts/adds its own error bound, so no primitive a ray hits
//!   is ever culled (`obvhs`'s stock node test rejects boxes closer than `t = 1e-4`).
//! - Rays spawned with [`crate::math::offset_ray_origin`] and `t_min = 0` neither re-hit the
//!   surface they leave nor skip a nearby one.
//! - Ray–sphere hits follow Haines et al. 2019 ("Precision Improvements for Ray/Sphere
//!   Intersection", Ray Tracing Gems ch. 7) and re-project the hit point onto the sphere.
//! - [`Hit::ng`] always points to the outside of the shape (spheres: radially; meshes: along
//!   the winding, which [`TriangleMesh::make_outward`] makes outward for closed meshes).

mod aabox;
mod bvh;
mod closest;
mod empty_cells;
mod free_shells;
mod icosphere;
mod levelset;
mod mesh;
mod ply;
pub mod ray_log;
mod sphere;
mod sphere_lanes;
mod sweep_sah;
mod triangle;
mod wide_bvh;

use std::path::PathBuf;
use std::sync::Arc;

use crate::math::{Mat3, Mat4, Vec2, Vec3};

pub use aabox::{intersect_box, BoxHit};
pub use bvh::SceneGeometry;
pub use closest::{closest_on_triangle, ClosestPointMesh, NearestPoint};
pub use icosphere::icosphere;
pub use levelset::{LevelSet, LevelSetError, LevelSetHit};
pub use mesh::{MeshTopology, TriangleMesh};
pub use ply::{load_ply, parse_ply, write_ply};
pub use sphere::{intersect_sphere, sphere_candidate, sphere_uv, SphereCandidate, SphereHit};
pub use triangle::{intersect_triangle, TriangleHit};

/// Errors of the geometry layer. Every variant names the file or shape and the problem.
#[derive(Debug, thiserror::Error)]
pub enum GeometryError {
    /// The file could not be opened, read or written.
    #[error("{path}: {source}")]
    Io {
        /// File concerned.
        path: PathBuf,
        /// Underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The PLY header or payload is malformed (includes files truncated before the element
    /// counts declared in the header are reached).
    #[error("{path}: malformed PLY: {message}")]
    Parse {
        /// File concerned.
        path: PathBuf,
        /// What the parser reported.
        message: String,
    },
    /// A required element (`vertex`, `face`) is absent.
    #[error("{path}: PLY has no `{element}` element")]
    MissingElement {
        /// File concerned.
        path: PathBuf,
        /// Element name.
        element: String,
    },
    /// A required property is absent or has the wrong type.
    #[error("{path}: element `{element}` has no usable property `{property}`")]
    MissingProperty {
        /// File concerned.
        path: PathBuf,
        /// Element name.
        element: String,
        /// Property name (or the accepted alternatives).
        property: String,
    },
    /// A vertex attribute is NaN or infinite.
    #[error("{path}: vertex {vertex} has a non-finite {what}")]
    NonFinite {
        /// File (or shape) concerned.
        path: PathBuf,
        /// Vertex index.
        vertex: usize,
        /// `position`, `normal` or `uv`.
        what: &'static str,
    },
    /// A face refers to a vertex that does not exist.
    #[error(
        "{path}: face {face} refers to vertex {index} but there are only {vertex_count} vertices"
    )]
    IndexOutOfRange {
        /// File concerned.
        path: PathBuf,
        /// Face index (as in the file).
        face: usize,
        /// The offending vertex index (negative values as found in the file).
        index: i64,
        /// Number of vertices declared.
        vertex_count: usize,
    },
    /// A face with fewer than three vertices.
    #[error("{path}: face {face} has {count} vertices (at least 3 needed)")]
    BadFace {
        /// File concerned.
        path: PathBuf,
        /// Face index.
        face: usize,
        /// Number of indices found.
        count: usize,
    },
    /// Bytes left after every element declared in the header was read (the counts in the
    /// header are smaller than the data).
    #[error("{path}: {bytes} bytes of data after the last element declared in the header (wrong element counts?)")]
    TrailingData {
        /// File concerned.
        path: PathBuf,
        /// Number of unread bytes (whitespace excepted for ASCII files).
        bytes: usize,
    },
    /// The mesh has no triangles.
    #[error("{path}: mesh has no faces")]
    Empty {
        /// File concerned.
        path: PathBuf,
    },
    /// A shape handed to [`SceneGeometry::build`] (or written by [`write_ply`]) is invalid.
    #[error("shape {shape}: {message}")]
    InvalidShape {
        /// Index of the shape in the list given to `build` (0 for single meshes).
        shape: usize,
        /// The problem.
        message: String,
    },
    /// A transform that cannot be applied (singular, non-finite, or non-uniform on a sphere).
    #[error("invalid transform: {message}")]
    InvalidTransform {
        /// The problem.
        message: String,
    },
}

/// A world-space shape.
#[derive(Clone, Debug)]
pub enum Shape {
    /// A triangle mesh.
    Mesh(TriangleMesh),
    /// An analytic sphere (world units).
    Sphere {
        /// Centre.
        center: Vec3,
        /// Radius (> 0).
        radius: f32,
    },
    /// An analytic axis-aligned box (world units), closed.
    Box {
        /// Smallest corner.
        min: Vec3,
        /// Largest corner (every component > `min`'s).
        max: Vec3,
    },
    /// The zero crossing of a level-set grid (negative inside), placed by its grid's
    /// index-to-world map; shared, as the grid can be large.
    LevelSet(Arc<LevelSet>),
}

impl Shape {
    /// Applies the affine transform `m` (object to world). Meshes accept any invertible
    /// transform (see [`TriangleMesh::transform`]), and so do level sets (their grid's map is
    /// composed with `m`); spheres accept only similarity transforms
    /// (rotation, uniform scale, translation, reflection) and return
    /// [`GeometryError::InvalidTransform`] otherwise.
    pub fn transform(&mut self, m: Mat4) -> Result<(), GeometryError> {
        check_affine(m)?;
        match self {
            Shape::Mesh(mesh) => {
                mesh.transform(m);
                Ok(())
            }
            Shape::Sphere { center, radius } => {
                let l = Mat3::from_mat4(m);
                let s = l.transpose() * l;
                let k = (s.x_axis.x + s.y_axis.y + s.z_axis.z) / 3.0;
                let tol = 1e-4 * k;
                let off = [s.x_axis.y, s.x_axis.z, s.y_axis.z];
                let diag = [s.x_axis.x, s.y_axis.y, s.z_axis.z];
                if off.iter().any(|v| v.abs() > tol) || diag.iter().any(|v| (v - k).abs() > tol) {
                    return Err(GeometryError::InvalidTransform {
                        message: "a sphere can only be rotated, uniformly scaled and translated"
                            .to_string(),
                    });
                }
                *center = m.transform_point3(*center);
                *radius *= k.sqrt();
                Ok(())
            }
            Shape::Box { min, max } => {
                let l = Mat3::from_mat4(m);
                let diagonal = l.x_axis.y == 0.0
                    && l.x_axis.z == 0.0
                    && l.y_axis.x == 0.0
                    && l.y_axis.z == 0.0
                    && l.z_axis.x == 0.0
                    && l.z_axis.y == 0.0;
                if !diagonal {
                    return Err(GeometryError::InvalidTransform {
                        message: "an axis-aligned box can only be scaled and translated"
                            .to_string(),
                    });
                }
                let (a, b) = (m.transform_point3(*min), m.transform_point3(*max));
                *min = a.min(b);
                *max = a.max(b);
                Ok(())
            }
            Shape::LevelSet(ls) => {
                Arc::make_mut(ls)
                    .transform(m)
                    .map_err(|e| GeometryError::InvalidTransform {
                        message: format!("level set: {e}"),
                    })
            }
        }
    }

    /// World-space bounding box.
    #[must_use]
    pub fn bounds(&self) -> crate::math::Aabb {
        match self {
            Shape::Mesh(m) => m.bounds(),
            Shape::Sphere { center, radius } => crate::math::Aabb {
                min: *center - Vec3::splat(*radius),
                max: *center + Vec3::splat(*radius),
            },
            Shape::Box { min, max } => crate::math::Aabb {
                min: *min,
                max: *max,
            },
            Shape::LevelSet(ls) => ls.bounds(),
        }
    }
}

/// Checks that `m` is a finite, invertible affine transform.
pub(crate) fn check_affine(m: Mat4) -> Result<(), GeometryError> {
    if !m.is_finite() {
        return Err(GeometryError::InvalidTransform {
            message: "non-finite matrix".to_string(),
        });
    }
    let row3 = m.row(3);
    if row3 != glam::Vec4::new(0.0, 0.0, 0.0, 1.0) {
        return Err(GeometryError::InvalidTransform {
            message: format!("not affine (last row {row3:?})"),
        });
    }
    let det = Mat3::from_mat4(m).determinant();
    if det == 0.0 || !det.is_finite() {
        return Err(GeometryError::InvalidTransform {
            message: "singular matrix".to_string(),
        });
    }
    Ok(())
}

/// A ray–surface intersection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the (unit-direction) ray.
    pub t: f32,
    /// Hit point (interpolated on the primitive, not `o + t d`, for accuracy).
    pub p: Vec3,
    /// Unit geometric normal pointing to the outside of the shape. The integrator tells
    /// entering from leaving by the sign of `dot(ray.d, ng)`.
    pub ng: Vec3,
    /// Unit shading normal (interpolated vertex normals), flipped into `ng`'s hemisphere;
    /// equals `ng` when the mesh has no normals.
    pub ns: Vec3,
    /// Surface parameterisation, read with [`Hit::uv`]: interpolated vertex UVs, else the
    /// barycentrics `(b1, b2)` for triangles; `(φ/2π, θ/π)` with θ measured from +y for
    /// spheres, computed from `ng` only when read.
    pub uv: HitUv,
    /// Index of the shape in the `Vec` given to [`SceneGeometry::build`].
    pub shape: u32,
    /// Triangle index within the mesh (0 for spheres).
    pub prim: u32,
    /// Conservative bound on the absolute rounding error of `p` (world units): spawned rays
    /// start this far off the surface (plus a few ULPs), see [`Hit::spawn_origin`].
    pub p_error: f32,
}

/// Where a [`Hit`]'s texture coordinates come from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HitUv {
    /// Known when the hit was recorded.
    At(Vec2),
    /// A sphere's: [`sphere_uv`] of the hit's radial normal `ng`, computed when read (two
    /// inverse trigonometric functions that most sphere hits, on untextured spheres, never
    /// need).
    Sphere,
}

impl Hit {
    /// Surface parameterisation at the hit, as the field `uv` describes it: for spheres
    /// [`sphere_uv`] of `ng`, the same bits as [`intersect_sphere`]'s record.
    #[must_use]
    #[inline]
    pub fn uv(&self) -> Vec2 {
        match self.uv {
            HitUv::At(uv) => uv,
            HitUv::Sphere => sphere_uv(self.ng),
        }
    }

    /// Origin for a ray leaving the surface in direction `dir`: moved off the surface along
    /// the geometric normal by the hit point's error bound, to the side `dir` points to, then
    /// by a few ULPs (Wächter & Binder 2019), so that neither the surface left nor a nearby
    /// one can be re-hit or skipped (large spheres have errors far above one ULP of `p`).
    #[must_use]
    pub fn spawn_origin(&self, dir: Vec3) -> Vec3 {
        let n = if self.ng.dot(dir) < 0.0 {
            -self.ng
        } else {
            self.ng
        };
        crate::math::offset_ray_origin(self.p + n * self.p_error, self.ng, dir)
    }
}
