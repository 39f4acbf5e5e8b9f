//! The scene's boundary of one object as an [`Interface`] for the manifold walk: a ray cast
//! (`f32`, through the BVH) finds the crossed primitive, then the crossing and its local
//! geometry are recomputed in `f64` on that primitive, analytically for spheres, on the
//! triangle's plane with barycentric interpolation of the vertex normals for meshes (their
//! derivatives along the tangent plane give the curvature the constraint needs), and on the
//! face's plane for boxes.

use glam::DVec3;

use super::super::interiors::{
    current_medium, enter, is_false_intersection, InteriorStack, MAX_NESTING,
};
use super::solve::{tangents, Interface, InterfacePoint};
use crate::geometry::{Hit, Shape};
use crate::math::{Ray, Vec3};
use crate::medium::Medium;
use crate::scene::{DielectricParams, Object, ObjectSurface, Scene, ShapeOwner};
use crate::spectrum::Rgb;

/// True when `obj`'s boundary can be the manifold walk's interface for a path whose medium on
/// the far side has IOR `outside_ior`: a smooth dielectric (the BSDF's delta lobe), without a
/// coat, that refracts (relative IOR ≠ 1), or a blend of two such (of one IOR, so both looks
/// refract alike). The integrator's no-double-counting rule (`ManifoldLeg`) uses the same
/// test.
#[must_use]
pub(in crate::integrator) fn is_manifold_interface(obj: &Object, outside_ior: f32) -> bool {
    let smooth = |s: &ObjectSurface| match s {
        ObjectSurface::Dielectric(d) => {
            d.coat.is_none()
                && d.roughness.max() * d.roughness.max() < crate::bsdf::microfacet::SMOOTH_ALPHA
                && d.ior / outside_ior.max(1e-6) != 1.0
        }
        ObjectSurface::Fixed(_)
        | ObjectSurface::Textured(_)
        | ObjectSurface::Blend(_)
        | ObjectSurface::Null => false,
    };
    match &obj.surface {
        ObjectSurface::Blend(b) => smooth(&b.a) && smooth(&b.b),
        s => smooth(s),
    }
}

/// The transmission tint of a manifold interface at texture coordinates `uv`: a
/// dielectric's tint, or a blend's looks' tints weighted by the mask there (the expectation
/// of the walk's per-hit choice: both looks refract alike, so only the tint depends on it).
/// `None` for other surfaces.
pub(super) fn interface_tint(surface: &ObjectSurface, uv: crate::math::Vec2) -> Option<Rgb> {
    match surface {
        ObjectSurface::Dielectric(d) => Some(d.tint.eval(uv, 0.0)),
        ObjectSurface::Blend(b) => {
            let m = b.mask.eval(uv, 0.0);
            let (ta, tb) = (interface_tint(&b.a, uv)?, interface_tint(&b.b, uv)?);
            Some(ta * m + tb * (1.0 - m))
        }
        ObjectSurface::Fixed(_) | ObjectSurface::Textured(_) | ObjectSurface::Null => None,
    }
}

/// True when a dielectric boundary is a pass-through for the medium outside it (IOR
/// `outside_ior`): relative IOR exactly 1 (the BSDF's delta pass-through; its tint is part of
/// the shadow rays' transmittance).
#[must_use]
pub(in crate::integrator) fn is_index_matched(d: &DielectricParams, outside_ior: f32) -> bool {
    d.ior / outside_ior.max(1e-6) == 1.0
}

/// The first refracting boundary seen from inside: the ray from the vertex passes null, false
/// and index-matched boundaries (updating a copy of the interior stack, as a unidirectional path does)
/// and stops at the first real boundary, which must be a smooth refractive dielectric that the
/// ray leaves ([`is_manifold_interface`]). The first projection (the seed) fixes which object
/// that is; later ones must reach the same object.
pub(super) struct SceneInterface<'a> {
    pub scene: &'a Scene,
    /// The vertex's interior stack.
    pub stack: InteriorStack,
    /// The interface object, once the seed has found it.
    pub object: Option<u32>,
    /// The interior stack just inside the interface at the last successful projection.
    pub inside: InteriorStack,
    /// Rays cast so far.
    pub rays: u64,
    /// Length of the seed line's first segment, in the vertex's own medium (for the
    /// roulette).
    pub seed_first_segment: f32,
    /// Texture coordinates of the last interface hit (for a textured tint).
    pub uv: crate::math::Vec2,
    /// The set-up of the last mesh triangle projected onto, with its shape and triangle
    /// numbers: the Newton steps of one solve mostly land on the same triangle.
    last_triangle: Option<(u32, u32, TriangleFrame)>,
}

/// The most boundaries a walk crosses.
pub(super) const SEED_SEGMENTS: usize = 4 * MAX_NESTING;

impl<'a> SceneInterface<'a> {
    pub fn new(scene: &'a Scene, stack: &InteriorStack) -> Self {
        SceneInterface {
            scene,
            stack: *stack,
            object: None,
            inside: *stack,
            rays: 0,
            seed_first_segment: 0.0,
            uv: crate::math::Vec2::ZERO,
            last_triangle: None,
        }
    }

    /// IORs inside and outside the interface at the last projection: (the interface object's
    /// IOR, the IOR of the medium around it).
    pub fn iors(&self) -> Option<(f32, f32)> {
        let oi = self.object?;
        let obj = self.scene.objects.get(oi as usize)?;
        Some((obj.ior, self.inside.ior(&self.scene.objects, Some(oi))))
    }

    /// The crossing of the ray `x0 + t d` with the shape of `hit` (the walk's interface hit),
    /// recomputed in `f64`; a triangle's set-up is kept for the next projection.
    fn project_on_shape(&mut self, x0: DVec3, d: DVec3, hit: &Hit) -> Option<InterfacePoint> {
        match self.scene.geometry.shape(hit.shape as usize)? {
            Shape::Sphere { center, radius } => on_sphere(x0, d, v64(*center), f64::from(*radius)),
            Shape::Mesh(mesh) => {
                let frame = TriangleFrame::new(mesh, hit.prim)?;
                self.last_triangle = Some((hit.shape, hit.prim, frame));
                frame.project(x0, d)
            }
            // A level set: its tangent plane at the hit (curvature left out of the walk).
            Shape::Box { .. } | Shape::LevelSet(_) => on_plane(x0, d, v64(hit.p), v64(hit.ng)),
        }
    }

    /// The first real boundary along the ray from `x0` (through null and false boundaries),
    /// if it is a manifold interface the ray leaves: the hit and the stack before it.
    fn first_interface(&mut self, ray: &Ray) -> Option<(Hit, InteriorStack)> {
        let seed = self.object.is_none();
        let mut first = None;
        // Projections only test passability; the interiors picked on entering do not matter.
        let mut picks = || 0.5;
        let found = self.walk::<false>(ray, &mut picks, |_, _, length| {
            first.get_or_insert(length);
        });
        if seed {
            self.seed_first_segment = first.unwrap_or(0.0);
        }
        if let Some((hit, _, _)) = &found {
            self.uv = hit.uv();
        }
        found.map(|(hit, stack, _)| (hit, stack))
    }

    /// The transmittance from `x0` along `dir` to the interface (the media on the way, and the
    /// tints of index-matched dielectrics crossed), by the media's transmittance estimators;
    /// zero if the ray does not reach the interface object through passable boundaries. The
    /// walk ends on the interface itself, not at a distance, so the ray offsets at the
    /// boundaries crossed cannot make it stop short or run into the interface.
    pub fn transmittance(
        &mut self,
        x0: Vec3,
        dir: Vec3,
        u: &mut impl FnMut() -> f32,
        tracking: &mut crate::tracking::TrackingStats,
    ) -> crate::spectrum::Rgb {
        let mut tr = crate::spectrum::Rgb::ONE;
        let mut picks = || 0.5;
        let found = self.walk::<true>(&Ray::new(x0, dir), &mut picks, |medium, origin, length| {
            if let Some(m) = medium {
                tr *= m.transmittance(&Ray::new(origin, dir), length, &mut *u, tracking);
            }
        });
        match found {
            Some((_, _, tint)) => tr * tint,
            None => crate::spectrum::Rgb::ZERO,
        }
    }

    /// Follows the ray from its origin through null, false and index-matched boundaries
    /// (updating a copy of the vertex's stack, as a unidirectional path does) to the first
    /// other boundary, which must be a manifold interface the ray leaves (the object of the
    /// seed, once known). Calls `segment(medium, origin, length)` for every segment (the
    /// governing medium, if any, when `MEDIA`; without it the medium is not looked up and
    /// `segment` gets `None`). Returns the interface hit, the stack just inside it and the
    /// product of the index-matched dielectrics' tints.
    fn walk<const MEDIA: bool>(
        &mut self,
        ray: &Ray,
        u: &mut impl FnMut() -> f32,
        mut segment: impl FnMut(Option<&Medium>, Vec3, f32),
    ) -> Option<(Hit, InteriorStack, crate::spectrum::Rgb)> {
        let scene = self.scene;
        let mut stack = self.stack;
        let mut origin = ray.o;
        let mut tint = crate::spectrum::Rgb::ONE;
        for _ in 0..SEED_SEGMENTS {
            self.rays += 1;
            let hit = scene
                .geometry
                .intersect(&Ray::new(origin, ray.d), f32::INFINITY)?;
            let mut scratch = None;
            let medium = if MEDIA {
                current_medium(scene, &stack, &mut scratch).map(|(m, _)| m)
            } else {
                None
            };
            segment(medium, origin, hit.t);
            let ShapeOwner::Object(oi) = *scene.shape_owner.get(hit.shape as usize)? else {
                return None;
            };
            let obj = scene.objects.get(oi as usize)?;
            let entering = ray.d.dot(hit.ng) < 0.0;
            // The IOR outside the object, looked up only where it is read (not at null
            // boundaries, most of a walk's).
            let outside = |stack: &InteriorStack| stack.ior(&scene.objects, Some(oi));
            // A null boundary passes whether or not it is a false intersection (both tests
            // below answer yes), so the priorities are not looked up for it.
            let passes = matches!(obj.surface, ObjectSurface::Null)
                || (obj.surface.transmits()
                    && (is_false_intersection(scene, &stack, oi, entering)
                        || match &obj.surface {
                            ObjectSurface::Null => true,
                            // Index-matched: the smooth lobe passes straight through, tinted.
                            ObjectSurface::Dielectric(d)
                                if is_index_matched(d, outside(&stack)) =>
                            {
                                tint *= d.tint.eval(hit.uv(), 0.0);
                                true
                            }
                            // Blends are not walked through (nor counted as pass-through by the
                            // integrator's `ManifoldLeg`).
                            ObjectSurface::Dielectric(_)
                            | ObjectSurface::Fixed(_)
                            | ObjectSurface::Textured(_)
                            | ObjectSurface::Blend(_) => false,
                        }));
            if !passes {
                let ok = !entering
                    && self.object.is_none_or(|o| o == oi)
                    && is_manifold_interface(obj, outside(&stack));
                return ok.then_some((hit, stack, tint));
            }
            if entering {
                enter(scene, &mut stack, oi, hit.uv(), 0.0, &mut *u);
            } else {
                stack.remove(oi);
            }
            origin = hit.spawn_origin(ray.d);
        }
        None
    }
}

fn v64(v: Vec3) -> DVec3 {
    DVec3::new(f64::from(v.x), f64::from(v.y), f64::from(v.z))
}

fn v32(v: DVec3) -> Vec3 {
    Vec3::new(v.x as f32, v.y as f32, v.z as f32)
}

impl Interface for SceneInterface<'_> {
    fn project(&mut self, x0: DVec3, target: DVec3) -> Option<InterfacePoint> {
        let d = (target - x0).try_normalize()?;
        let ray = Ray::new(v32(x0), v32(d));
        let (hit, stack) = self.first_interface(&ray)?;
        let point = match &self.last_triangle {
            Some((shape, prim, frame)) if *shape == hit.shape && *prim == hit.prim => {
                frame.project(x0, d)
            }
            _ => self.project_on_shape(x0, d, &hit),
        }?;
        // The ray left through the crossing: the refined point must agree.
        if !(d.dot(point.ng) > 0.0) {
            return None;
        }
        if let ShapeOwner::Object(oi) = self.scene.shape_owner.get(hit.shape as usize)? {
            self.object = Some(*oi);
        }
        self.inside = stack;
        Some(point)
    }
}

/// The far crossing of the ray `x0 + t d` (from inside) with a sphere.
fn on_sphere(x0: DVec3, d: DVec3, c: DVec3, r: f64) -> Option<InterfacePoint> {
    let oc = x0 - c;
    let b = oc.dot(d);
    // |oc − b d|² is the squared distance of the line from the centre (stable form).
    let perp = oc - d * b;
    let disc = r * r - perp.length_squared();
    if !(disc >= 0.0) {
        return None;
    }
    let t = -b + disc.sqrt();
    if !(t > 0.0) {
        return None;
    }
    let n = ((x0 + d * t) - c) / r;
    let n = n.try_normalize()?;
    let p = c + n * r;
    let (s, tt) = tangents(n);
    Some(InterfacePoint {
        p,
        ng: n,
        ns: n,
        dpdu: [s, tt],
        dndu: [s / r, tt / r],
    })
}

/// The crossing of the ray with the plane through `p` with unit normal `n` (flat: no normal
/// derivative).
fn on_plane(x0: DVec3, d: DVec3, p: DVec3, n: DVec3) -> Option<InterfacePoint> {
    let n = n.try_normalize()?;
    let dn = d.dot(n);
    if dn.abs() < 1e-12 {
        return None;
    }
    let t = (p - x0).dot(n) / dn;
    let (s, tt) = tangents(n);
    Some(InterfacePoint {
        p: x0 + d * t,
        ng: n,
        ns: n,
        dpdu: [s, tt],
        dndu: [DVec3::ZERO; 2],
    })
}

/// A mesh triangle's part of [`on_triangle`] that does not depend on the ray, computed once
/// for the projections that land on the same triangle (the operations and their order are
/// [`on_triangle`]'s, so a projection through the frame is bit for bit the same).
#[derive(Clone, Copy, Debug)]
struct TriangleFrame {
    /// The first corner.
    p0: DVec3,
    /// The edges from `p0`.
    e1: DVec3,
    e2: DVec3,
    /// The unit geometric normal (`e1 × e2` normalised).
    ng: DVec3,
    /// `ng` normalised again and its tangents: [`on_plane`]'s plane.
    n: DVec3,
    dpdu: [DVec3; 2],
    /// The Gram system of the edges and its determinant (nonzero).
    g11: f64,
    g12: f64,
    g22: f64,
    det: f64,
    /// The corners' vertex normals, when the mesh has them.
    normals: Option<[DVec3; 3]>,
}

impl TriangleFrame {
    /// The frame of triangle `prim` of `mesh`; `None` where [`on_triangle`] is `None` for every
    /// ray (a missing triangle, vertex or normal, a degenerate triangle).
    fn new(mesh: &crate::geometry::TriangleMesh, prim: u32) -> Option<TriangleFrame> {
        let tri = mesh.indices.get(prim as usize)?;
        let pos = |k: usize| -> Option<DVec3> {
            mesh.positions.get(*tri.get(k)? as usize).map(|v| v64(*v))
        };
        let (p0, p1, p2) = (pos(0)?, pos(1)?, pos(2)?);
        let (e1, e2) = (p1 - p0, p2 - p0);
        let ng = e1.cross(e2).try_normalize()?;
        let n = ng.try_normalize()?;
        let (s, tt) = tangents(n);
        let (g11, g12, g22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
        let det = g11 * g22 - g12 * g12;
        if !(det.abs() > 0.0) {
            return None;
        }
        let normals = match &mesh.normals {
            Some(normals) => {
                let nrm = |k: usize| -> Option<DVec3> {
                    normals.get(*tri.get(k)? as usize).map(|v| v64(*v))
                };
                Some([nrm(0)?, nrm(1)?, nrm(2)?])
            }
            None => None,
        };
        Some(TriangleFrame {
            p0,
            e1,
            e2,
            ng,
            n,
            dpdu: [s, tt],
            g11,
            g12,
            g22,
            det,
            normals,
        })
    }

    /// Barycentrics `(b1, b2)` of the offset `v` from `p0` in the plane.
    #[inline(always)]
    fn coords(&self, v: DVec3) -> (f64, f64) {
        let (r1, r2) = (self.e1.dot(v), self.e2.dot(v));
        (
            (self.g22 * r1 - self.g12 * r2) / self.det,
            (self.g11 * r2 - self.g12 * r1) / self.det,
        )
    }

    /// [`on_triangle`] for the ray `x0 + t d`.
    fn project(&self, x0: DVec3, d: DVec3) -> Option<InterfacePoint> {
        // `on_plane(x0, d, p0, ng)` with its normalised normal and tangents precomputed.
        let dn = d.dot(self.n);
        if dn.abs() < 1e-12 {
            return None;
        }
        let t = (self.p0 - x0).dot(self.n) / dn;
        let flat = InterfacePoint {
            p: x0 + d * t,
            ng: self.n,
            ns: self.n,
            dpdu: self.dpdu,
            dndu: [DVec3::ZERO; 2],
        };
        let Some([n0, n1, n2]) = self.normals else {
            return Some(flat);
        };
        let p = flat.p;
        let (b1, b2) = self.coords(p - self.p0);
        let raw = n0 * (1.0 - b1 - b2) + n1 * b1 + n2 * b2;
        let len = raw.length();
        if !(len > 1e-12) {
            return Some(flat);
        }
        // Flipped into the geometric hemisphere, as the renderer's hits are.
        let sign = if raw.dot(self.ng) < 0.0 { -1.0 } else { 1.0 };
        let ns = raw * (sign / len);
        let mut dndu = [DVec3::ZERO; 2];
        for (k, t) in flat.dpdu.iter().enumerate() {
            let (a, b) = self.coords(*t);
            let draw = (n1 - n0) * a + (n2 - n0) * b;
            dndu[k] = (draw * sign - ns * ns.dot(draw * sign)) / len;
        }
        Some(InterfacePoint {
            p,
            ng: self.ng,
            ns,
            dpdu: flat.dpdu,
            dndu,
        })
    }
}

/// The crossing of the ray with the hit triangle's plane, with the interpolated shading normal
/// and its derivatives along the plane, computed whole for each ray ([`TriangleFrame`] keeps
/// the ray's own part; the tests compare the two bit for bit).
#[cfg(test)]
fn on_triangle(
    x0: DVec3,
    d: DVec3,
    mesh: &crate::geometry::TriangleMesh,
    hit: &Hit,
) -> Option<InterfacePoint> {
    let tri = mesh.indices.get(hit.prim as usize)?;
    let pos =
        |k: usize| -> Option<DVec3> { mesh.positions.get(*tri.get(k)? as usize).map(|v| v64(*v)) };
    let (p0, p1, p2) = (pos(0)?, pos(1)?, pos(2)?);
    let (e1, e2) = (p1 - p0, p2 - p0);
    let ng = e1.cross(e2).try_normalize()?;
    let flat = on_plane(x0, d, p0, ng)?;
    let p = flat.p;
    // Barycentrics (b1, b2) of p from the Gram system of the edges.
    let (g11, g12, g22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let det = g11 * g22 - g12 * g12;
    if !(det.abs() > 0.0) {
        return None;
    }
    let coords = |v: DVec3| -> (f64, f64) {
        let (r1, r2) = (e1.dot(v), e2.dot(v));
        ((g22 * r1 - g12 * r2) / det, (g11 * r2 - g12 * r1) / det)
    };
    let Some(normals) = &mesh.normals else {
        return Some(flat);
    };
    let nrm = |k: usize| -> Option<DVec3> { normals.get(*tri.get(k)? as usize).map(|v| v64(*v)) };
    let (n0, n1, n2) = (nrm(0)?, nrm(1)?, nrm(2)?);
    let (b1, b2) = coords(p - p0);
    let raw = n0 * (1.0 - b1 - b2) + n1 * b1 + n2 * b2;
    let len = raw.length();
    if !(len > 1e-12) {
        return Some(flat);
    }
    // Flipped into the geometric hemisphere, as the renderer's hits are.
    let sign = if raw.dot(ng) < 0.0 { -1.0 } else { 1.0 };
    let ns = raw * (sign / len);
    let mut dndu = [DVec3::ZERO; 2];
    for (k, t) in flat.dpdu.iter().enumerate() {
        let (a, b) = coords(*t);
        let draw = (n1 - n0) * a + (n2 - n0) * b;
        dndu[k] = (draw * sign - ns * ns.dot(draw * sign)) / len;
    }
    Some(InterfacePoint {
        p,
        ng,
        ns,
        dpdu: flat.dpdu,
        dndu,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::TriangleMesh;
    use crate::math::Vec2;

    /// A hit on triangle 0 of shape 0 (`on_triangle` reads the hit's triangle number).
    fn first_triangle_hit() -> Hit {
        Hit {
            t: 1.0,
            p: Vec3::ZERO,
            ng: Vec3::Z,
            ns: Vec3::Z,
            uv: crate::geometry::HitUv::At(Vec2::ZERO),
            shape: 0,
            prim: 0,
            p_error: 0.0,
        }
    }

    /// The walk and projection as they were before the triangle frames, the lazy medium and
    /// IOR look-ups and the null boundaries' shortcut (the medium is not part of a
    /// projection's answer): the reference for `projections_match_the_written_out_walk`.
    fn reference_project(
        scene: &Scene,
        vertex: &InteriorStack,
        object: Option<u32>,
        x0: DVec3,
        target: DVec3,
    ) -> Option<(
        InterfacePoint,
        InteriorStack,
        u32,
        crate::math::Vec2,
        f32,
        u64,
    )> {
        let d = (target - x0).try_normalize()?;
        let ray = Ray::new(v32(x0), v32(d));
        let mut stack = *vertex;
        let mut origin = ray.o;
        let (mut first, mut rays) = (None, 0u64);
        let mut found = None;
        for _ in 0..SEED_SEGMENTS {
            rays += 1;
            let hit = scene
                .geometry
                .intersect(&Ray::new(origin, ray.d), f32::INFINITY)?;
            first.get_or_insert(hit.t);
            let ShapeOwner::Object(oi) = *scene.shape_owner.get(hit.shape as usize)? else {
                return None;
            };
            let obj = scene.objects.get(oi as usize)?;
            let entering = ray.d.dot(hit.ng) < 0.0;
            let outside = stack.ior(&scene.objects, Some(oi));
            let passes = obj.surface.transmits()
                && (is_false_intersection(scene, &stack, oi, entering)
                    || match &obj.surface {
                        ObjectSurface::Null => true,
                        ObjectSurface::Dielectric(d) => is_index_matched(d, outside),
                        _ => false,
                    });
            if !passes {
                let ok = !entering
                    && object.is_none_or(|o| o == oi)
                    && is_manifold_interface(obj, outside);
                if ok {
                    found = Some((hit, stack, oi));
                }
                break;
            }
            if entering {
                enter(scene, &mut stack, oi, hit.uv(), 0.0, || 0.5);
            } else {
                stack.remove(oi);
            }
            origin = hit.spawn_origin(ray.d);
        }
        let (hit, stack, oi) = found?;
        let point = match scene.geometry.shape(hit.shape as usize)? {
            Shape::Sphere { center, radius } => on_sphere(x0, d, v64(*center), f64::from(*radius)),
            Shape::Mesh(mesh) => on_triangle(x0, d, mesh, &hit),
            Shape::Box { .. } | Shape::LevelSet(_) => on_plane(x0, d, v64(hit.p), v64(hit.ng)),
        }?;
        (d.dot(point.ng) > 0.0).then(|| (point, stack, oi, hit.uv(), first.unwrap_or(0.0), rays))
    }

    /// `SceneInterface::project` on the shipped eye (a meshed globe over null spheres with
    /// priorities, so false intersections, and an iris mesh) against [`reference_project`],
    /// bit for bit: the point, the stack inside, the object, the uv, the seed's first segment
    /// and the rays cast, over solves of several projections from one vertex (the kept
    /// triangle frames are reused) from the sclera, the uvea and the chamber.
    #[test]
    fn projections_match_the_written_out_walk() {
        let scene = Scene::load(std::path::Path::new("scenes/eye.toml")).expect("the eye");
        let named = |name: &str| {
            scene
                .objects
                .iter()
                .position(|o| o.name == name)
                .expect("object") as u32
        };
        let (globe, sclera, uvea, chamber) = (
            named("globe"),
            named("sclera"),
            named("uvea"),
            named("chamber"),
        );
        let mut rng = crate::sampling::Rng::new(20, 3);
        let (mut solved, mut tried) = (0, 0);
        for v in 0..3_000 {
            let dir = crate::sampling::sample_uniform_sphere(rng.next_2d());
            // A vertex in the sclera shell, in the uvea, or in the chamber in front.
            let (x0, inside) = match v % 3 {
                0 => (dir * (0.94 + 0.05 * rng.next_f32()), vec![globe, sclera]),
                1 => (
                    dir * (0.3 + 0.5 * rng.next_f32()),
                    vec![globe, sclera, uvea],
                ),
                _ => (
                    Vec3::new(0.0, 0.0, 0.95) + dir * (0.15 * rng.next_f32()),
                    vec![globe, sclera, uvea, chamber],
                ),
            };
            let mut stack = InteriorStack::default();
            for oi in inside {
                enter(&scene, &mut stack, oi, crate::math::Vec2::ZERO, 0.0, || 0.5);
            }
            let x0 = v64(x0);
            let mut interface = SceneInterface::new(&scene, &stack);
            let light = v64(Vec3::new(-3.2, 1.6, 2.4));
            let mut target = light;
            for step in 0..6 {
                tried += 1;
                let object = interface.object;
                let rays = interface.rays;
                let want = reference_project(&scene, &stack, object, x0, target);
                let got = interface.project(x0, target);
                assert_eq!(
                    got.as_ref().map(point_bits),
                    want.as_ref().map(|w| point_bits(&w.0)),
                    "vertex {v}, step {step}"
                );
                if let (Some(p), Some(w)) = (got, want) {
                    solved += 1;
                    let debug = |s: &InteriorStack| format!("{s:?}");
                    assert_eq!(
                        debug(&interface.inside),
                        debug(&w.1),
                        "vertex {v}, step {step}"
                    );
                    assert_eq!(interface.object, Some(w.2));
                    let bits = |uv: crate::math::Vec2| uv.to_array().map(f32::to_bits);
                    assert_eq!(bits(interface.uv), bits(w.3));
                    assert_eq!(interface.rays - rays, w.5);
                    if step == 0 {
                        assert_eq!(interface.seed_first_segment.to_bits(), w.4.to_bits());
                    }
                    // The next target: a small step in the tangent plane, as Newton's.
                    let k = 0.02 * f64::from(rng.next_f32() - 0.5);
                    target = p.p + p.dpdu[0] * k + p.dpdu[1] * (0.5 * k);
                } else {
                    target = light + v64(dir) * 0.5;
                }
            }
        }
        assert!(
            solved > 5_000 && tried - solved > 1_000,
            "{solved} of {tried}"
        );
    }

    fn point_bits(p: &InterfacePoint) -> Vec<u64> {
        [p.p, p.ng, p.ns, p.dpdu[0], p.dpdu[1], p.dndu[0], p.dndu[1]]
            .iter()
            .flat_map(|v| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()])
            .collect()
    }

    /// A projection through a triangle's kept [`TriangleFrame`] is [`on_triangle`]'s bit for
    /// bit, or `None` where it is: random triangles with and without vertex normals, degenerate
    /// triangles (a repeated corner, collinear corners), normals that cancel at a point
    /// (the flat fallback), rays nearly in the plane, and the same frame reused for many rays.
    #[test]
    fn triangle_frame_projections_are_on_triangle_bit_for_bit() {
        let mut rng = crate::sampling::Rng::new(20, 11);
        let v = |rng: &mut crate::sampling::Rng, s: f32| {
            Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * (2.0 * s) - Vec3::splat(s)
        };
        let (mut some, mut none, mut curved, mut flat) = (0, 0, 0, 0);
        for m in 0..400 {
            let mut positions = vec![v(&mut rng, 1.0), v(&mut rng, 1.0), v(&mut rng, 1.0)];
            match m % 10 {
                0 => positions[2] = positions[1],
                1 => positions[2] = positions[0] + (positions[1] - positions[0]) * 0.25,
                _ => {}
            }
            let normals = match m % 4 {
                0 => None,
                // Opposite normals: their interpolation vanishes between them.
                1 => {
                    let n = v(&mut rng, 1.0).normalize();
                    Some(vec![n, -n, n])
                }
                _ => Some(
                    (0..3)
                        .map(|_| v(&mut rng, 1.0).normalize_or(Vec3::Z))
                        .collect(),
                ),
            };
            let mesh = TriangleMesh {
                positions,
                normals,
                uvs: None,
                indices: vec![[0, 1, 2]],
            };
            let hit = first_triangle_hit();
            let frame = TriangleFrame::new(&mesh, 0);
            let x0 = v64(v(&mut rng, 3.0));
            for k in 0..50 {
                let target = match k % 5 {
                    // Towards a point of the triangle's plane: nearly in it from a corner.
                    0 => v64(mesh.positions[1]) + (v64(mesh.positions[2]) - x0) * 1e-3,
                    // Through the edge between the opposite normals' corners.
                    1 => (v64(mesh.positions[0]) + v64(mesh.positions[1])) * 0.5,
                    _ => v64(v(&mut rng, 1.5)),
                };
                let Some(d) = (target - x0).try_normalize() else {
                    continue;
                };
                let want = on_triangle(x0, d, &mesh, &hit);
                let got = frame.as_ref().and_then(|f| f.project(x0, d));
                assert_eq!(
                    got.as_ref().map(point_bits),
                    want.as_ref().map(point_bits),
                    "mesh {m}, ray {k}: {x0} {d}"
                );
                match want {
                    Some(p) if p.dndu != [DVec3::ZERO; 2] => curved += 1,
                    Some(_) => flat += 1,
                    None => none += 1,
                }
                some += usize::from(want.is_some());
            }
        }
        assert!(
            some > 10_000 && none > 1_000 && curved > 8_000 && flat > 3_000,
            "{some} {none} {curved} {flat}"
        );
    }

    /// The derivative of the interpolated shading normal along the tangent plane against
    /// central differences of the normal at points moved along the tangents.
    #[test]
    fn triangle_normal_derivative_matches_finite_differences() {
        let mesh = TriangleMesh {
            positions: vec![
                Vec3::new(0.0, 0.0, 1.0),
                Vec3::new(1.0, 0.1, 0.9),
                Vec3::new(0.2, 1.0, 0.8),
            ],
            normals: Some(vec![
                Vec3::new(0.1, -0.2, 1.0).normalize(),
                Vec3::new(0.5, 0.1, 0.9).normalize(),
                Vec3::new(-0.2, 0.6, 0.8).normalize(),
            ]),
            uvs: None,
            indices: vec![[0, 1, 2]],
        };
        let hit = first_triangle_hit();
        let x0 = DVec3::new(0.3, 0.3, -1.0);
        let at = |target: DVec3| {
            let d = (target - x0).normalize();
            on_triangle(x0, d, &mesh, &hit).expect("crosses the triangle")
        };
        let p = at(DVec3::new(0.35, 0.3, 0.9));
        let h = 1e-6;
        for k in 0..2 {
            let t = p.dpdu[k];
            let fd = (at(p.p + t * h).ns - at(p.p - t * h).ns) / (2.0 * h);
            assert!(
                (fd - p.dndu[k]).length() < 1e-6,
                "tangent {k}: {} vs finite differences {fd}",
                p.dndu[k]
            );
        }
        // The point is on the triangle's plane and the normals are unit and outward.
        assert!((p.ns.length() - 1.0).abs() < 1e-12 && p.ns.dot(p.ng) > 0.0);
    }
}
