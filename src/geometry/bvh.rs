//! One compressed wide BVH (`obvhs`: PLOC build, CWBVH traversal) over every triangle and
//! sphere of a scene, traversed with a conservative node test and our own primitive tests.

use std::time::Duration;

use glam::{UVec2, Vec3A, Vec4};
use obvhs::aabb::Aabb as OAabb;
use obvhs::cwbvh::builder::build_cwbvh;
use obvhs::cwbvh::node::{extract_byte64, CwBvhNode};
use obvhs::cwbvh::CwBvh;
use obvhs::{Boundable, BvhBuildParams};

use crate::math::{Aabb, Ray, Vec2, Vec3};

use super::sphere::{intersect_sphere, SphereHit};
use super::triangle::{ShearedRay, TriangleHit};
use super::{GeometryError, Hit, MeshTopology, Shape};

/// A primitive in BVH order: a triangle `(a, b, c)` or a sphere (`a` = centre, `b.x` = radius).
#[derive(Clone, Copy, Debug)]
struct Prim {
    a: Vec3,
    b: Vec3,
    c: Vec3,
    shape: u32,
    prim: u32,
    sphere: bool,
}

struct PrimBox(OAabb);

impl Boundable for PrimBox {
    fn aabb(&self) -> OAabb {
        self.0
    }
}

/// The scene's surfaces and their acceleration structure (immutable once built).
#[derive(Clone, Debug)]
pub struct SceneGeometry {
    bvh: Option<CwBvh>,
    prims: Vec<Prim>,
    shapes: Vec<Shape>,
    topologies: Vec<Option<MeshTopology>>,
    bounds: Aabb,
}

enum Best {
    Tri(usize, TriangleHit),
    Sphere(usize, SphereHit),
}

/// Reciprocal direction with magnitudes capped at 1e20 (sign kept, `-0` treated as `+0`
/// like the octant test), so that node slab tests never produce `0·∞`.
fn capped_inverse(d: Vec3) -> Vec3A {
    let f = |x: f32| {
        if x.abs() < 1e-20 {
            if x < 0.0 {
                -1e20
            } else {
                1e20
            }
        } else {
            1.0 / x
        }
    };
    Vec3A::new(f(d.x), f(d.y), f(d.z))
}

/// Conservative ray test against the 8 quantised child boxes of a CWBVH node (Ylitie et al.
/// 2017 layout). Each slab distance `t = q·(e/d) + (p − o)/d` carries an absolute rounding
/// error below `4ε(255|e/d| + |(p − o)/d|)`, which is subtracted from entry and added to
/// exit distances; the interval is clipped to `[0, t_max]` (obvhs's stock test clips at
/// `1e-4`, which would cull hits just in front of the origin).
#[inline(always)]
fn node_hits(
    node: &CwBvhNode,
    o: Vec3A,
    inv: Vec3A,
    neg: [bool; 3],
    t_max: f32,
    oct_inv4: u32,
) -> u32 {
    let s = node.compute_extent() * inv;
    let a = (Vec3A::from(node.p) - o) * inv;
    let err = (s.abs() * 255.0 + a.abs()) * (4.0 * f32::EPSILON);
    let (child_bits8, bit_index8) = node.get_child_and_index_bits(oct_inv4);
    let q = |arr: &[u8; 8], h: usize| {
        Vec4::new(
            f32::from(arr[4 * h]),
            f32::from(arr[4 * h + 1]),
            f32::from(arr[4 * h + 2]),
            f32::from(arr[4 * h + 3]),
        )
    };
    let mut hit_mask = 0u32;
    for h in 0..2 {
        let (nx, fx) = if neg[0] {
            (&node.child_max_x, &node.child_min_x)
        } else {
            (&node.child_min_x, &node.child_max_x)
        };
        let (ny, fy) = if neg[1] {
            (&node.child_max_y, &node.child_min_y)
        } else {
            (&node.child_min_y, &node.child_max_y)
        };
        let (nz, fz) = if neg[2] {
            (&node.child_max_z, &node.child_min_z)
        } else {
            (&node.child_min_z, &node.child_max_z)
        };
        let tn_x = q(nx, h) * s.x + Vec4::splat(a.x - err.x);
        let tf_x = q(fx, h) * s.x + Vec4::splat(a.x + err.x);
        let tn_y = q(ny, h) * s.y + Vec4::splat(a.y - err.y);
        let tf_y = q(fy, h) * s.y + Vec4::splat(a.y + err.y);
        let tn_z = q(nz, h) * s.z + Vec4::splat(a.z - err.z);
        let tf_z = q(fz, h) * s.z + Vec4::splat(a.z + err.z);
        let tn = tn_x.max(tn_y).max(tn_z).max(Vec4::ZERO);
        let tf = tf_x.min(tf_y).min(tf_z).min(Vec4::splat(t_max));
        let m = tn.cmple(tf).bitmask();
        for j in 0..4 {
            if m & (1 << j) != 0 {
                let child = 4 * h + j;
                hit_mask |= extract_byte64(child_bits8, child) << extract_byte64(bit_index8, child);
            }
        }
    }
    hit_mask
}

/// Depth (in nodes) of a compressed wide BVH.
fn cwbvh_depth(bvh: &CwBvh) -> usize {
    if bvh.nodes.is_empty() {
        return 0;
    }
    let mut max = 0;
    let mut stack = vec![(0u32, 1usize)];
    while let Some((i, d)) = stack.pop() {
        max = max.max(d);
        let Some(node) = bvh.nodes.get(i as usize) else {
            continue;
        };
        for c in 0..8 {
            if !node.is_leaf(c) && !node.is_child_empty(c) {
                stack.push((node.child_node_index(c), d + 1));
            }
        }
    }
    max
}

impl SceneGeometry {
    /// Validates the shapes, orients every closed mesh outward
    /// ([`super::TriangleMesh::make_outward`]), and builds one BVH over all triangles and
    /// spheres (spheres enter as primitives by their bounds). Errors name the shape index.
    pub fn build(mut shapes: Vec<Shape>) -> Result<SceneGeometry, GeometryError> {
        let mut topologies = Vec::with_capacity(shapes.len());
        for (i, s) in shapes.iter_mut().enumerate() {
            match s {
                Shape::Mesh(m) => {
                    m.validate(i)?;
                    let topo = m.topology();
                    if topo.is_closed() {
                        m.make_outward();
                    }
                    topologies.push(Some(topo));
                }
                Shape::Sphere { center, radius } => {
                    let far = center.abs().max_element() + *radius > super::mesh::MAX_COORDINATE;
                    if !center.is_finite() || !radius.is_finite() || *radius <= 0.0 || far {
                        return Err(GeometryError::InvalidShape {
                            shape: i,
                            message: format!(
                                "sphere needs a finite centre, a radius > 0 and coordinates within ±{:e} (got {center:?}, {radius})",
                                super::mesh::MAX_COORDINATE
                            ),
                        });
                    }
                    topologies.push(None);
                }
            }
        }
        let mut prims = Vec::new();
        let mut bounds = Aabb::EMPTY;
        for (si, s) in shapes.iter().enumerate() {
            bounds = bounds.union(s.bounds());
            match s {
                Shape::Mesh(m) => {
                    for (ti, t) in m.indices.iter().enumerate() {
                        let [a, b, c] = t.map(|i| m.positions[i as usize]);
                        prims.push(Prim {
                            a,
                            b,
                            c,
                            shape: si as u32,
                            prim: ti as u32,
                            sphere: false,
                        });
                    }
                }
                Shape::Sphere { center, radius } => prims.push(Prim {
                    a: *center,
                    b: Vec3::splat(*radius),
                    c: Vec3::ZERO,
                    shape: si as u32,
                    prim: 0,
                    sphere: true,
                }),
            }
        }
        if prims.is_empty() {
            return Ok(SceneGeometry {
                bvh: None,
                prims,
                shapes,
                topologies,
                bounds,
            });
        }
        if prims.len() > (u32::MAX / 2) as usize {
            return Err(GeometryError::InvalidShape {
                shape: 0,
                message: "too many primitives".to_string(),
            });
        }
        // Padding covers the non-conservative rounding of obvhs's box quantisation (below an
        // ulp of the node extent) with a wide margin.
        let mag = bounds
            .min
            .abs()
            .max(bounds.max.abs())
            .max_element()
            .max(bounds.extent().max_element());
        let pad = 16.0 * f32::EPSILON * mag;
        let boxes: Vec<PrimBox> = prims
            .iter()
            .map(|p| {
                let (lo, hi) = if p.sphere {
                    (p.a - p.b, p.a + p.b)
                } else {
                    (p.a.min(p.b).min(p.c), p.a.max(p.b).max(p.c))
                };
                PrimBox(OAabb::new(
                    Vec3A::from(lo - Vec3::splat(pad)),
                    Vec3A::from(hi + Vec3::splat(pad)),
                ))
            })
            .collect();
        let bvh = build_cwbvh(
            &boxes,
            BvhBuildParams::medium_build(),
            &mut Duration::default(),
        );
        let ordered: Vec<Prim> = bvh
            .primitive_indices
            .iter()
            .map(|&i| prims[i as usize])
            .collect();
        Ok(SceneGeometry {
            bvh: Some(bvh),
            prims: ordered,
            shapes,
            topologies,
            bounds,
        })
    }

    /// Closest hit with `0 < t < t_max` along `ray` (unit direction), or `None`. Rays that
    /// leave a surface must start at [`crate::math::offset_ray_origin`]; `t_min` is 0.
    #[must_use]
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<Hit> {
        let bvh = self.bvh.as_ref()?;
        if !ray.o.is_finite()
            || !ray.d.is_finite()
            || ray.d == Vec3::ZERO
            || t_max.is_nan()
            || t_max <= 0.0
        {
            return None;
        }
        let sr = ShearedRay::new(ray);
        let o = Vec3A::from(ray.o);
        let inv = capped_inverse(ray.d);
        let neg = [ray.d.x < 0.0, ray.d.y < 0.0, ray.d.z < 0.0];
        let mut closest = t_max;
        let mut best: Option<Best> = None;
        let mut state = bvh.new_traversal(Vec3A::from(ray.d));
        let mut node;
        obvhs::traverse!(
            bvh,
            node,
            state,
            node_hits(node, o, inv, neg, closest, state.oct_inv4),
            {
                let slot = state.primitive_id as usize;
                let p = &self.prims[slot];
                if p.sphere {
                    if let Some(h) = intersect_sphere(ray, p.a, p.b.x, closest) {
                        closest = h.t;
                        best = Some(Best::Sphere(slot, h));
                    }
                } else if let Some(h) = sr.intersect(p.a, p.b, p.c, closest) {
                    closest = h.t;
                    best = Some(Best::Tri(slot, h));
                }
            }
        );
        best.map(|b| self.make_hit(ray, b))
    }

    /// True when anything is hit with `0 < t < t_max` (shadow rays; stops at the first hit).
    #[must_use]
    pub fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        let Some(bvh) = self.bvh.as_ref() else {
            return false;
        };
        if !ray.o.is_finite()
            || !ray.d.is_finite()
            || ray.d == Vec3::ZERO
            || t_max.is_nan()
            || t_max <= 0.0
        {
            return false;
        }
        let sr = ShearedRay::new(ray);
        let o = Vec3A::from(ray.o);
        let inv = capped_inverse(ray.d);
        let neg = [ray.d.x < 0.0, ray.d.y < 0.0, ray.d.z < 0.0];
        let mut found = false;
        let mut state = bvh.new_traversal(Vec3A::from(ray.d));
        let mut node;
        obvhs::traverse!(
            bvh,
            node,
            state,
            node_hits(node, o, inv, neg, t_max, state.oct_inv4),
            {
                let p = &self.prims[state.primitive_id as usize];
                let hit = if p.sphere {
                    intersect_sphere(ray, p.a, p.b.x, t_max).is_some()
                } else {
                    sr.intersect(p.a, p.b, p.c, t_max).is_some()
                };
                if hit {
                    found = true;
                    break;
                }
            }
        );
        found
    }

    fn make_hit(&self, ray: &Ray, best: Best) -> Hit {
        match best {
            Best::Sphere(slot, h) => {
                let p = &self.prims[slot];
                // p = c + r n: rounding grows with |c| + r, not with |p|.
                let p_error = match self.shapes.get(p.shape as usize) {
                    Some(Shape::Sphere { center, radius }) => {
                        crate::math::gamma(6) * 4.0 * (center.abs().max_element() + radius)
                    }
                    _ => crate::math::gamma(6) * 4.0 * h.p.abs().max_element(),
                };
                Hit {
                    t: h.t,
                    p: h.p,
                    ng: h.n,
                    ns: h.n,
                    uv: h.uv,
                    shape: p.shape,
                    prim: 0,
                    p_error,
                }
            }
            Best::Tri(slot, h) => {
                let p = &self.prims[slot];
                let pos = p.a * h.b0 + p.b * h.b1 + p.c * h.b2;
                let ng = (p.b - p.a).cross(p.c - p.a).normalize_or(-ray.d);
                let mut ns = ng;
                let mut uv = Vec2::new(h.b1, h.b2);
                if let Some(Shape::Mesh(m)) = self.shapes.get(p.shape as usize) {
                    let tri = m.indices[p.prim as usize].map(|i| i as usize);
                    if let Some(n) = &m.normals {
                        let s = (n[tri[0]] * h.b0 + n[tri[1]] * h.b1 + n[tri[2]] * h.b2)
                            .normalize_or(ng);
                        ns = if s.dot(ng) < 0.0 { -s } else { s };
                    }
                    if let Some(t) = &m.uvs {
                        uv = t[tri[0]] * h.b0 + t[tri[1]] * h.b1 + t[tri[2]] * h.b2;
                    }
                }
                // Barycentric interpolation error (pbrt-v4 §6.8.6): γ7 Σ|b_i p_i|.
                let p_error = crate::math::gamma(7)
                    * (p.a.abs() * h.b0.abs() + p.b.abs() * h.b1.abs() + p.c.abs() * h.b2.abs())
                        .max_element();
                Hit {
                    t: h.t,
                    p: pos,
                    ng,
                    ns,
                    uv,
                    shape: p.shape,
                    prim: p.prim,
                    p_error,
                }
            }
        }
    }

    /// Bounds of every shape.
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Number of shapes given to [`SceneGeometry::build`].
    #[must_use]
    pub fn shape_count(&self) -> usize {
        self.shapes.len()
    }

    /// Depth of the BVH in nodes (diagnostics; 0 when empty).
    #[must_use]
    pub fn bvh_depth(&self) -> usize {
        self.bvh.as_ref().map_or(0, cwbvh_depth)
    }

    /// Number of BVH primitives (triangles plus spheres).
    #[must_use]
    pub fn primitive_count(&self) -> usize {
        self.prims.len()
    }

    /// The shape with index `i` as stored (closed meshes already oriented outward).
    #[must_use]
    pub fn shape(&self, i: usize) -> Option<&Shape> {
        self.shapes.get(i)
    }

    /// Whether shape `i` bounds a volume: spheres always, meshes when
    /// [`super::TriangleMesh::is_closed`]. The scene loader warns (naming the mesh) when an
    /// open mesh is used as the boundary of an interior medium.
    #[must_use]
    pub fn is_closed(&self, i: usize) -> bool {
        match self.topologies.get(i) {
            Some(Some(t)) => t.is_closed(),
            Some(None) => true,
            None => false,
        }
    }

    /// Edge statistics of mesh shape `i` (`None` for spheres or out-of-range indices).
    #[must_use]
    pub fn topology(&self, i: usize) -> Option<MeshTopology> {
        self.topologies.get(i).copied().flatten()
    }
}
