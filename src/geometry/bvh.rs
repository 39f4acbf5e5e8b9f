//! The scene's surfaces: one wide BVH over every triangle ([`super::wide_bvh`], conservative
//! node test, our watertight triangle test), and the analytic shapes (spheres, boxes) and
//! level sets tested directly, outside the triangle hierarchy.

use glam::{Vec3A, Vec4};

use crate::math::{Aabb, Ray, Vec2, Vec3};

use super::aabox::{intersect_box, intersect_box_lanes, BoxHit};
use super::empty_cells::EmptyCells;
use super::free_shells::FreeShells;
use super::levelset::LevelSetHit;
use super::sphere::{sphere_candidate, SphereCandidate};
use super::sphere_lanes::SphereBlock;
use super::triangle::{ShearedRay, TriangleBlock, TriangleHit, TriangleSoa};
use super::wide_bvh::{Leaf, LeafVisitor, WideBvh, LEAF_BLOCK, MAX_PRIMITIVES};
use super::{GeometryError, Hit, HitUv, MeshTopology, Shape};

mod beyond;

/// Which shape and which of its triangles a BVH position is, with the triangle's geometric
/// normal: what the hit record needs beyond the vertices (read once per closest hit, never
/// by the traversal; 24 bytes a triangle).
#[derive(Clone, Copy, Debug)]
struct Prim {
    /// [`geometric_normal`] of the triangle: NaN components when it has none.
    ng: Vec3,
    shape: u32,
    prim: u32,
    /// Whether the mesh has vertex normals or UVs (the hit record then reads the mesh).
    attributes: bool,
}

/// The scene's surfaces and their acceleration structure (immutable once built).
#[derive(Clone, Debug)]
pub struct SceneGeometry {
    bvh: WideBvh,
    /// The shape and triangle of each BVH position.
    prims: Vec<Prim>,
    /// The vertices of each triangle (BVH order): indices into `verts`.
    tris: Vec<[u32; 3]>,
    /// Every triangle vertex once, as `(x, y, z, 0)`, numbered in the order the BVH's
    /// positions first use them. With `tris` this is the compact layout (16 bytes per vertex
    /// and 12 per triangle instead of 48 per transposed triangle), so that the 20k-triangle
    /// icosphere's hierarchy, nodes and triangles, takes about 0.8 MB instead of 1.4 MB. The
    /// traversal reads the leaves' `blocks` instead; these serve the exact path of a block
    /// with an edge function exactly zero, and the hit records of queries that do not test
    /// blocks ([`BlockLane::NONE`]).
    verts: Vec<Vec4>,
    /// Each leaf's triangles in blocks of four, transposed for the four-lane test, numbered
    /// by `Leaf::block` (144 bytes a block). The traversal reads these, and the closest
    /// hit's record reads its corners back from them ([`SceneGeometry::corners`]): the
    /// test has just loaded the block's lines, where `tris` then `verts` are two dependent
    /// loads, often from outside the first-level cache.
    blocks: Vec<TriangleBlock>,
    /// The cells no triangle touches: short segments inside them skip the traversal.
    empty: Option<EmptyCells>,
    /// The shells about the spheres' centres that no triangle touches: segments inside one
    /// (a ray ending on a sphere nested in a mesh) skip the traversal.
    free: Option<FreeShells>,
    /// Analytic shapes, tested directly.
    analytic: Vec<Analytic>,
    /// When every analytic shape is a sphere: the spheres of `analytic`, in its order, four
    /// to a block, tested in lanes ([`SphereBlock::candidates`]); lane `i` of block `k` is
    /// `analytic[4k + i]`. Empty otherwise.
    sphere_blocks: Vec<SphereBlock>,
    shapes: Vec<Shape>,
    topologies: Vec<Option<MeshTopology>>,
    bounds: Aabb,
    /// `(min, max, shape)` when the scene's only shape is an analytic box (the grid peer
    /// scenes' `bounds`): rays that move away from it ([`moves_away_from_box`]) are answered
    /// without the query (the escape ray after a path leaves the box), the others by the slab
    /// test alone ([`intersect_box_lanes`]), without the loop over shapes.
    sole_box: Option<(Vec3A, Vec3A, u32)>,
}

/// An analytic shape and the index of the shape it is.
#[derive(Clone, Copy, Debug)]
enum Analytic {
    Sphere {
        center: Vec3,
        radius: f32,
        shape: u32,
    },
    Box {
        min: Vec3,
        max: Vec3,
        shape: u32,
    },
    /// A level set: `shapes[shape]` holds it.
    LevelSet {
        shape: u32,
    },
}

enum Best {
    /// A triangle: its BVH position, where its corners are read back ([`BlockLane`]) and
    /// the hit.
    Tri(usize, BlockLane, TriangleHit),
    /// A sphere's candidate with the sphere's centre and radius: its record is made only
    /// for the nearest hit ([`SceneGeometry::make_hit`]).
    Sphere(u32, SphereCandidate, Vec3, f32),
    Box(u32, BoxHit),
    LevelSet(u32, LevelSetHit),
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
                Shape::Box { min, max } => {
                    let far = min.abs().max(max.abs()).max_element() > super::mesh::MAX_COORDINATE;
                    if !min.is_finite() || !max.is_finite() || !min.cmplt(*max).all() || far {
                        return Err(GeometryError::InvalidShape {
                            shape: i,
                            message: format!(
                                "box needs finite corners with min < max on every axis, within ±{:e} (got {min:?}, {max:?})",
                                super::mesh::MAX_COORDINATE
                            ),
                        });
                    }
                    topologies.push(None);
                }
                Shape::LevelSet(ls) => {
                    let b = ls.bounds();
                    let far =
                        b.min.abs().max(b.max.abs()).max_element() > super::mesh::MAX_COORDINATE;
                    if far || !b.is_valid() {
                        return Err(GeometryError::InvalidShape {
                            shape: i,
                            message: format!(
                                "level set lies beyond ±{:e} (bounds {:?} to {:?})",
                                super::mesh::MAX_COORDINATE,
                                b.min,
                                b.max
                            ),
                        });
                    }
                    topologies.push(None);
                }
            }
        }
        // Triangles (shape order) with their vertices as indices into `positions`, the
        // vertices of every mesh one after the other.
        let mut prims = Vec::new();
        let mut corners: Vec<[u32; 3]> = Vec::new();
        let mut positions: Vec<Vec3> = Vec::new();
        let mut analytic = Vec::new();
        let mut bounds = Aabb::EMPTY;
        for (si, s) in shapes.iter().enumerate() {
            bounds = bounds.union(s.bounds());
            match s {
                Shape::Mesh(m) => {
                    let base = positions.len();
                    if base + m.positions.len() > u32::MAX as usize {
                        return Err(GeometryError::InvalidShape {
                            shape: si,
                            message: "too many vertices".to_string(),
                        });
                    }
                    positions.extend_from_slice(&m.positions);
                    for (ti, t) in m.indices.iter().enumerate() {
                        corners.push(t.map(|i| (base + i as usize) as u32));
                        let [a, b, c] = t.map(|i| m.positions[i as usize]);
                        prims.push(Prim {
                            ng: geometric_normal(a, b, c),
                            shape: si as u32,
                            prim: ti as u32,
                            attributes: m.normals.is_some() || m.uvs.is_some(),
                        });
                    }
                }
                Shape::Sphere { center, radius } => analytic.push(Analytic::Sphere {
                    center: *center,
                    radius: *radius,
                    shape: si as u32,
                }),
                Shape::Box { min, max } => analytic.push(Analytic::Box {
                    min: *min,
                    max: *max,
                    shape: si as u32,
                }),
                Shape::LevelSet(_) => analytic.push(Analytic::LevelSet { shape: si as u32 }),
            }
        }
        if prims.len() > MAX_PRIMITIVES as usize {
            return Err(GeometryError::InvalidShape {
                shape: 0,
                message: "too many primitives".to_string(),
            });
        }
        // Padding covers the rounding of the slab test's box planes with a wide margin.
        let mag = bounds
            .min
            .abs()
            .max(bounds.max.abs())
            .max_element()
            .max(bounds.extent().max_element());
        let pad = Vec3::splat(16.0 * f32::EPSILON * mag);
        let boxes: Vec<(Vec3, Vec3)> = corners
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| positions[i as usize]);
                (a.min(b).min(c) - pad, a.max(b).max(c) + pad)
            })
            .collect();
        let bvh = WideBvh::build(&boxes);
        let empty = EmptyCells::build(&boxes, pad.x);
        let ordered: Vec<Prim> = bvh.order().iter().map(|&i| prims[i as usize]).collect();
        // Vertices renumbered by first use in BVH order, so that a leaf's vertices lie
        // together; vertices no triangle uses are dropped.
        let mut renumber = vec![u32::MAX; positions.len()];
        let mut verts = Vec::new();
        let tris = bvh
            .order()
            .iter()
            .map(|&i| {
                corners[i as usize].map(|v| {
                    let slot = &mut renumber[v as usize];
                    if *slot == u32::MAX {
                        *slot = verts.len() as u32;
                        verts.push(positions[v as usize].extend(0.0));
                    }
                    *slot
                })
            })
            .collect();
        let spheres: Vec<(Vec3, f32)> = analytic
            .iter()
            .filter_map(|a| match *a {
                Analytic::Sphere { center, radius, .. } => Some((center, radius)),
                Analytic::Box { .. } | Analytic::LevelSet { .. } => None,
            })
            .collect();
        let centres: Vec<Vec3> = spheres.iter().map(|&(center, _)| center).collect();
        let free = if centres.is_empty() {
            None
        } else {
            let corners: Vec<[Vec3; 3]> = corners
                .iter()
                .map(|t| t.map(|i| positions[i as usize]))
                .collect();
            FreeShells::build(&centres, &corners)
        };
        let mut blocks = Vec::new();
        for leaf in bvh.leaves() {
            debug_assert_eq!(leaf.block as usize, blocks.len());
            let order = &bvh.order()[leaf.first as usize..(leaf.first + leaf.count) as usize];
            for chunk in order.chunks(LEAF_BLOCK as usize) {
                let tris: Vec<[Vec3; 3]> = chunk
                    .iter()
                    .map(|&i| corners[i as usize].map(|v| positions[v as usize]))
                    .collect();
                blocks.push(TriangleBlock::new(&tris));
            }
        }
        let sole_box = match analytic.as_slice() {
            [Analytic::Box { min, max, shape }] if ordered.is_empty() => {
                Some(((*min).into(), (*max).into(), *shape))
            }
            _ => None,
        };
        let sphere_blocks = if spheres.len() == analytic.len() {
            SphereBlock::blocks(&spheres)
        } else {
            Vec::new()
        };
        Ok(SceneGeometry {
            sole_box,
            sphere_blocks,
            free,
            bvh,
            prims: ordered,
            tris,
            verts,
            blocks,
            empty,
            analytic,
            shapes,
            topologies,
            bounds,
        })
    }

    /// Closest hit with `0 < t < t_max` along `ray` (unit direction), or `None`. Rays that
    /// leave a surface must start at [`crate::math::offset_ray_origin`]; `t_min` is 0.
    #[must_use]
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<Hit> {
        let hit = self.closest(ray, t_max);
        #[cfg(feature = "ray-log")]
        super::ray_log::closest(ray, t_max, hit.as_ref());
        hit
    }

    /// [`Self::intersect`]'s search (the ray log's hook is in `intersect`): the dispatch by
    /// the kind of scene, inlined where the ray is cast, so that each kind makes one call
    /// into a function of its own (the sole box's is small enough to need no saved registers
    /// and no stack frame).
    #[inline(always)]
    fn closest(&self, ray: &Ray, t_max: f32) -> Option<Hit> {
        if let Some(sole) = &self.sole_box {
            return closest_on_sole_box(sole, ray, t_max);
        }
        if self.analytic.is_empty() {
            return self.closest_triangle(ray, t_max);
        }
        self.closest_any(ray, t_max)
    }

    /// [`Self::closest`] in a scene of triangles only (no analytic shape): the general
    /// search below with nothing found before the triangles (`closest = t_max`, no free
    /// shell), without the set-up of the analytic shapes' loops.
    #[inline(never)]
    fn closest_triangle(&self, ray: &Ray, t_max: f32) -> Option<Hit> {
        if self.prims.is_empty() || !valid_query(ray, t_max) {
            return None;
        }
        if self.segment_misses_triangles(ray, t_max) {
            return None;
        }
        let mut best = None;
        self.bvh.traverse(
            ray,
            t_max,
            NearestTriangle {
                geometry: self,
                sr: &ShearedRay::new(ray),
                best: &mut best,
            },
        );
        best.map(|(slot, lane, h)| self.make_hit(ray, Best::Tri(slot as usize, lane, h)))
    }

    /// [`Self::closest`] in a scene with analytic shapes (a sole box excepted: see
    /// [`closest_on_sole_box`]).
    #[inline(never)]
    fn closest_any(&self, ray: &Ray, t_max: f32) -> Option<Hit> {
        if !valid_query(ray, t_max) {
            return None;
        }
        let mut closest = t_max;
        let mut best: Option<Best> = None;
        if !self.sphere_blocks.is_empty() {
            // Only spheres: four at a time. A lane tested against a larger bound than the
            // loop's shrinking `closest` finds the same candidate whenever the loop's is
            // nearer than `closest`, and the strict `<` in order keeps the first of equal
            // distances, as the loop does.
            for (k, block) in self.sphere_blocks.iter().enumerate() {
                let lanes = block.candidates(ray, closest);
                let mut hits = lanes.hits;
                while hits != 0 {
                    let i = hits.trailing_zeros() as usize;
                    hits &= hits - 1;
                    if lanes.t(i) < closest {
                        if let Some(&Analytic::Sphere {
                            center,
                            radius,
                            shape,
                        }) = self.analytic.get(4 * k + i)
                        {
                            closest = lanes.t(i);
                            best = Some(Best::Sphere(shape, lanes.candidate(i), center, radius));
                        }
                    }
                }
            }
        }
        for a in self.loose_analytic() {
            match *a {
                Analytic::Sphere {
                    center,
                    radius,
                    shape,
                } => {
                    if let Some(h) = sphere_candidate(ray, center, radius, closest) {
                        closest = h.t;
                        best = Some(Best::Sphere(shape, h, center, radius));
                    }
                }
                Analytic::Box { min, max, shape } => {
                    if let Some(h) = intersect_box(ray, min, max, closest) {
                        closest = h.t;
                        best = Some(Best::Box(shape, h));
                    }
                }
                Analytic::LevelSet { shape } => {
                    if let Some(Shape::LevelSet(ls)) = self.shapes.get(shape as usize) {
                        if let Some(h) = ls.intersect(ray, closest) {
                            closest = h.t;
                            best = Some(Best::LevelSet(shape, h));
                        }
                    }
                }
            }
        }
        let free = match best {
            Some(Best::Sphere(_, _, center, _)) => self.segment_in_free_shell(ray, center, closest),
            _ => false,
        };
        if !self.prims.is_empty() && !free && !self.segment_misses_triangles(ray, closest) {
            // A triangle replaces the analytic shapes' best only when it is nearer.
            let mut tri = None;
            self.bvh.traverse(
                ray,
                closest,
                NearestTriangle {
                    geometry: self,
                    sr: &ShearedRay::new(ray),
                    best: &mut tri,
                },
            );
            if let Some((slot, lane, h)) = tri {
                best = Some(Best::Tri(slot as usize, lane, h));
            }
        }
        best.map(|b| self.make_hit(ray, b))
    }

    /// True when anything is hit with `0 < t < t_max` (shadow rays; stops at the first hit).
    #[must_use]
    #[inline]
    pub fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        let found = self.any_hit(ray, t_max);
        #[cfg(feature = "ray-log")]
        super::ray_log::occluded(ray, t_max, found);
        found
    }

    /// [`Self::occluded`]'s search (the ray log's hook is in `occluded`).
    fn any_hit(&self, ray: &Ray, t_max: f32) -> bool {
        if !valid_query(ray, t_max) {
            return false;
        }
        if self
            .sphere_blocks
            .iter()
            .any(|block| block.candidates(ray, t_max).hits != 0)
        {
            return true;
        }
        if self.loose_analytic().iter().any(|a| match *a {
            Analytic::Sphere { center, radius, .. } => {
                sphere_candidate(ray, center, radius, t_max).is_some()
            }
            Analytic::Box { min, max, .. } => intersect_box(ray, min, max, t_max).is_some(),
            Analytic::LevelSet { shape } => matches!(
                self.shapes.get(shape as usize),
                Some(Shape::LevelSet(ls)) if ls.occluded(ray, t_max)
            ),
        }) {
            return true;
        }
        let mut found = false;
        if !self.prims.is_empty() && !self.segment_misses_triangles(ray, t_max) {
            self.bvh.traverse(
                ray,
                t_max,
                AnyTriangle {
                    geometry: self,
                    sr: &ShearedRay::new(ray),
                    found: &mut found,
                },
            );
        }
        found
    }

    /// The analytic shapes tested one by one: all of them, or none when they are all spheres
    /// (tested in `sphere_blocks`).
    #[inline(always)]
    fn loose_analytic(&self) -> &[Analytic] {
        if self.sphere_blocks.is_empty() {
            &self.analytic
        } else {
            &[]
        }
    }

    /// Block `index` of the leaves' triangles (`Leaf::block`).
    #[inline(always)]
    fn block(&self, index: u32) -> &TriangleBlock {
        debug_assert!((index as usize) < self.blocks.len());
        // SAFETY: the traversal reports leaves of `bvh`, whose blocks `build` stored, all
        // below `blocks.len()`.
        unsafe { self.blocks.get_unchecked(index as usize) }
    }

    /// The triangle at BVH position `slot`, transposed for the triangle test.
    #[inline(always)]
    fn triangle(&self, slot: usize) -> TriangleSoa {
        debug_assert!(slot < self.tris.len());
        // SAFETY: the traversal reports positions below `bvh.order().len() == tris.len()`,
        // and `build` numbers every vertex a triangle names below `verts.len()`.
        unsafe {
            let [a, b, c] = *self.tris.get_unchecked(slot);
            TriangleSoa::from_vertices(
                *self.verts.get_unchecked(a as usize),
                *self.verts.get_unchecked(b as usize),
                *self.verts.get_unchecked(c as usize),
            )
        }
    }

    /// The corners of the triangle at BVH position `slot` as stored (`w` = 0): from block lane
    /// `lane` of the leaves' blocks, whose lines the four-lane test has just read, or through
    /// `tris` and `verts` when `lane` is [`BlockLane::NONE`]. Both hold the same floats
    /// (`build` fills both from the mesh's positions).
    #[inline(always)]
    fn corners(&self, slot: usize, lane: BlockLane) -> [Vec4; 3] {
        if lane == BlockLane::NONE {
            debug_assert!(slot < self.tris.len());
            // SAFETY: as in `triangle`.
            unsafe {
                let [a, b, c] = *self.tris.get_unchecked(slot);
                [a, b, c].map(|v| *self.verts.get_unchecked(v as usize))
            }
        } else {
            self.block(lane.0 >> 2).corners(lane.0 as usize)
        }
    }

    /// Asks the CPU to bring triangle `slot`'s record (`prims`) towards the core: a hint
    /// issued when the traversal finds a nearer triangle, so that [`SceneGeometry::make_hit`]
    /// does not wait for it (no fault and no visible effect, whatever `slot`).
    #[inline(always)]
    fn prefetch_prim(&self, slot: usize) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            let p = self.prims.as_ptr().wrapping_add(slot).cast::<i8>();
            // SAFETY: a prefetch is a hint that never faults, whatever the address.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(p) };
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = slot;
    }

    /// True when the segment `(0, t_max)` of `ray` provably hits no triangle: it is short
    /// and lies in cells no triangle touches ([`EmptyCells`]; the traversal would find nothing).
    #[inline(always)]
    fn segment_misses_triangles(&self, ray: &Ray, t_max: f32) -> bool {
        t_max.is_finite()
            && self
                .empty
                .as_ref()
                .is_some_and(|e| e.clear(ray.o, ray.at(t_max)))
    }

    /// True when the segment `(0, t_max)` of `ray`, which ends on a sphere centred at
    /// `center`, lies in a shell about that centre that no triangle touches ([`FreeShells`];
    /// the traversal would find nothing).
    #[inline(always)]
    fn segment_in_free_shell(&self, ray: &Ray, center: Vec3, t_max: f32) -> bool {
        self.free
            .as_ref()
            .is_some_and(|f| f.clear_about(center, ray.o, ray.d, t_max))
    }

    /// Drops the triangle-free shells (tests compare with and without them).
    #[cfg(test)]
    fn without_free_shells(mut self) -> Self {
        self.free = None;
        self
    }

    /// Drops the empty-cell grid (tests compare with and without it).
    #[cfg(test)]
    fn without_empty_cells(mut self) -> Self {
        self.empty = None;
        self
    }

    fn make_hit(&self, ray: &Ray, best: Best) -> Hit {
        match best {
            Best::Sphere(shape, candidate, center, radius) => {
                // The record without its uv, read from `ng` when needed (`HitUv::Sphere`).
                let (p, n) = candidate.point_and_normal(center, radius);
                // p = c + r n: rounding grows with |c| + r, not with |p| (`center` and
                // `radius` are the shape's own, copied into `analytic` by `build`).
                let p_error = crate::math::gamma(6) * 4.0 * (center.abs().max_element() + radius);
                Hit {
                    t: candidate.t,
                    p,
                    ng: n,
                    ns: n,
                    uv: HitUv::Sphere,
                    shape,
                    prim: 0,
                    p_error,
                }
            }
            Best::Box(shape, h) => box_record(ray, shape, h),
            Best::LevelSet(shape, h) => Hit {
                t: h.t,
                p: h.p,
                ng: h.n,
                ns: h.ns,
                uv: HitUv::At(Vec2::ZERO),
                shape,
                prim: 0,
                p_error: h.p_error,
            },
            Best::Tri(slot, lane, h) => {
                debug_assert!(slot < self.prims.len());
                // SAFETY: `slot` is a BVH position the traversal reported, below
                // `bvh.order().len() == prims.len()`.
                let p = unsafe { self.prims.get_unchecked(slot) };
                let [a4, b4, c4] = self.corners(slot, lane);
                // The corners as stored (`w` = 0), combined in SIMD lanes: the same
                // per-coordinate IEEE operations as on `Vec3`s.
                let pos = (a4 * h.b0 + b4 * h.b1 + c4 * h.b2).truncate();
                // A triangle without a normal faces the ray.
                let ng = if p.ng.x.is_nan() { -ray.d } else { p.ng };
                let mut ns = ng;
                let mut uv = Vec2::new(h.b1, h.b2);
                // (The mesh is read only when it has normals or UVs.)
                if p.attributes {
                    if let Some(Shape::Mesh(m)) = self.shapes.get(p.shape as usize) {
                        let tri = || m.indices[p.prim as usize].map(|i| i as usize);
                        if let Some(n) = &m.normals {
                            let tri = tri();
                            let s = (n[tri[0]] * h.b0 + n[tri[1]] * h.b1 + n[tri[2]] * h.b2)
                                .normalize_or(ng);
                            ns = if s.dot(ng) < 0.0 { -s } else { s };
                        }
                        if let Some(t) = &m.uvs {
                            let tri = tri();
                            uv = t[tri[0]] * h.b0 + t[tri[1]] * h.b1 + t[tri[2]] * h.b2;
                        }
                    }
                }
                // Barycentric interpolation error (pbrt-v4 §6.8.6): γ7 Σ|b_i p_i|.
                let p_error = crate::math::gamma(7)
                    * (a4.abs() * h.b0.abs() + b4.abs() * h.b1.abs() + c4.abs() * h.b2.abs())
                        .truncate()
                        .max_element();
                Hit {
                    t: h.t,
                    p: pos,
                    ng,
                    ns,
                    uv: HitUv::At(uv),
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
        self.bvh.depth()
    }

    /// Number of primitives (triangles plus analytic shapes).
    #[must_use]
    pub fn primitive_count(&self) -> usize {
        self.prims.len() + self.analytic.len()
    }

    /// The shape with index `i` as stored (closed meshes already oriented outward).
    #[must_use]
    pub fn shape(&self, i: usize) -> Option<&Shape> {
        self.shapes.get(i)
    }

    /// Whether shape `i` bounds a volume: spheres and boxes always, meshes when
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

/// The triangle at traversal position `slot` (a leaf's entry, as [`WideBvh::traverse`]
/// reports it) against the sheared ray up to `t_max`: both visitors' test.
#[inline(always)]
fn test_slot(g: &SceneGeometry, sr: &ShearedRay, slot: u32, t_max: f32) -> Option<TriangleHit> {
    debug_assert!((slot as usize) < g.tris.len());
    // SAFETY: the traversal reports positions below `bvh.order().len() == tris.len()`,
    // and `build` numbers every corner a triangle names below `verts.len()`.
    unsafe { sr.intersect_corners(&g.verts, *g.tris.get_unchecked(slot as usize), t_max) }
}

/// The closest-hit query's triangle test as the traversal's [`LeafVisitor`]: keeps the
/// nearest hit so far in `best` (position and hit), and asks for its record's line.
struct NearestTriangle<'g, 'b> {
    geometry: &'g SceneGeometry,
    /// The ray's shear constants, by reference: the traversal reads them from the caller's
    /// frame instead of copying them into its own.
    sr: &'b ShearedRay,
    best: &'b mut Option<(u32, BlockLane, TriangleHit)>,
}

impl LeafVisitor for NearestTriangle<'_, '_> {
    #[inline(always)]
    fn visit(&mut self, slot: u32, t_max: f32) -> f32 {
        match test_slot(self.geometry, self.sr, slot, t_max) {
            Some(h) => {
                self.geometry.prefetch_prim(slot as usize);
                *self.best = Some((slot, BlockLane::NONE, h));
                h.t
            }
            None => t_max,
        }
    }

    /// The leaf's triangles four at a time ([`ShearedRay::intersect4`]): the nearest lane's
    /// hit, as the one-by-one visit in position order keeps; a block with an edge function
    /// exactly zero one triangle at a time ([`Self::visit`], which takes the exact path).
    ///
    /// Every lane of a block is tested: lanes past the leaf's count repeat the block's first
    /// triangle ([`TriangleBlock::new`]), so they hit, or are unsure, exactly when lane 0 is,
    /// at its distance, and [`Hits4::nearest`](super::triangle::Hits4::nearest) keeps the lowest of equally near lanes. The
    /// answer is the masked test's, without the mask and the block's count in the loop.
    #[inline(always)]
    fn visit_leaf(&mut self, leaf: Leaf, mut t_max: f32) -> f32 {
        let end = leaf.first + leaf.count;
        let (mut block, mut first) = (leaf.block, leaf.first);
        while first < end {
            let h = self.sr.intersect4(self.geometry.block(block), 15, t_max);
            if h.unsure != 0 {
                let n = (end - first).min(LEAF_BLOCK);
                for lane in 0..n {
                    let slot = first + lane;
                    if let Some(hit) = test_slot(self.geometry, self.sr, slot, t_max) {
                        self.geometry.prefetch_prim(slot as usize);
                        *self.best = Some((slot, BlockLane::new(block, lane), hit));
                        t_max = hit.t;
                    }
                }
            } else if h.hit != 0 {
                let (lane, hit) = h.nearest();
                let slot = first + lane as u32;
                self.geometry.prefetch_prim(slot as usize);
                *self.best = Some((slot, BlockLane::new(block, lane as u32), hit));
                t_max = hit.t;
            }
            block += 1;
            first += LEAF_BLOCK;
        }
        t_max
    }
}

/// Where a hit triangle's corners are read back for its record: the low two bits are the
/// lane and the rest the index of a leaf block ([`TriangleBlock::corners`]), or
/// [`BlockLane::NONE`] (through `tris` and `verts`). Blocks number at most [`MAX_PRIMITIVES`] < 2³⁰, so the
/// product fits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct BlockLane(u32);

impl BlockLane {
    /// No block: the corners come from `tris` and `verts`.
    const NONE: BlockLane = BlockLane(u32::MAX);

    /// Lane `lane` (below 4) of block `block`.
    #[inline(always)]
    fn new(block: u32, lane: u32) -> Self {
        debug_assert!(lane < 4 && block < u32::MAX >> 2);
        BlockLane(block << 2 | (lane & 3))
    }
}

/// The occlusion query's triangle test as the traversal's [`LeafVisitor`]: ends the
/// traversal (returns 0) at the first hit, noting it in `found`.
struct AnyTriangle<'g, 'f> {
    geometry: &'g SceneGeometry,
    /// As in [`NearestTriangle`].
    sr: &'f ShearedRay,
    found: &'f mut bool,
}

impl LeafVisitor for AnyTriangle<'_, '_> {
    #[inline(always)]
    fn visit(&mut self, slot: u32, t_max: f32) -> f32 {
        if test_slot(self.geometry, self.sr, slot, t_max).is_some() {
            *self.found = true;
            0.0
        } else {
            t_max
        }
    }

    /// The leaf's triangles eight at a time, two blocks at once ([`ShearedRay::intersect8`];
    /// a leaf's last block alone in both halves, its lanes twice); a pair with an edge
    /// function exactly zero one triangle at a time ([`Self::visit`], the exact path). Every
    /// lane of a block is tested, as in [`NearestTriangle::visit_leaf`]; any hit ends the
    /// query, so which lane hits does not matter. (The closest-hit query keeps the four-lane
    /// test: in eight lanes it was slower on the recorded rays, docs/BENCHMARKS.md.)
    #[inline(always)]
    fn visit_leaf(&mut self, leaf: Leaf, t_max: f32) -> f32 {
        let end = leaf.first + leaf.count;
        let (mut block, mut first) = (leaf.block, leaf.first);
        loop {
            let left = end - first;
            let second = block + u32::from(left > LEAF_BLOCK);
            let g = self.geometry;
            let h = self.sr.intersect8(g.block(block), g.block(second), t_max);
            let found = h.hit != 0
                || (h.unsure != 0
                    && (first..first + left.min(2 * LEAF_BLOCK))
                        .any(|slot| test_slot(g, self.sr, slot, t_max).is_some()));
            if found {
                *self.found = true;
                return 0.0;
            }
            if left <= 2 * LEAF_BLOCK {
                return t_max;
            }
            block += 2;
            first += 2 * LEAF_BLOCK;
        }
    }
}

/// A query the hierarchy answers: finite origin and direction, a nonzero direction, and
/// `t_max > 0` (other queries hit nothing).
///
/// The same predicate as `o.is_finite() && d.is_finite() && d != Vec3::ZERO && t_max > 0`,
/// evaluated with two 4-lane compares and no branch per component (a component is finite
/// when its magnitude is below ∞, which NaN is not; `−0` equals `0`).
#[inline(always)]
fn valid_query(ray: &Ray, t_max: f32) -> bool {
    let o = Vec4::from((ray.o, 0.0));
    let d = Vec4::from((ray.d, 0.0));
    let inf = Vec4::splat(f32::INFINITY);
    let finite = o.abs().cmplt(inf).bitmask() & d.abs().cmplt(inf).bitmask();
    let nonzero = d.cmpne(Vec4::ZERO).bitmask();
    (finite & 7 == 7) & (nonzero != 0) & (t_max > 0.0)
}

/// [`SceneGeometry::closest`] when the scene's only shape is the analytic box `sole`
/// (`(min, max, shape)`, [`SceneGeometry::sole_box`]): what the general search does with one
/// box and no triangles. Rays moving away from the box miss it ([`moves_away_from_box`]);
/// the others are tested by the slab test in lanes. Of [`valid_query`]'s conditions only the
/// ray's finiteness is checked: a zero direction (every slab parallel, the entry at −∞ and
/// the exit at +∞, neither strictly between 0 and `t_max`) and a `t_max` that is not
/// positive (no distance lies strictly between 0 and it) or NaN already give no hit there.
#[inline(never)]
fn closest_on_sole_box(sole: &(Vec3A, Vec3A, u32), ray: &Ray, t_max: f32) -> Option<Hit> {
    let (min, max, shape) = *sole;
    if moves_away_from_box(ray, min, max) || !finite_ray(ray) {
        return None;
    }
    intersect_box_lanes(ray, min, max, t_max).map(|h| box_record(ray, shape, h))
}

/// True when the ray's origin and direction are finite (three lane compares).
#[inline(always)]
fn finite_ray(ray: &Ray) -> bool {
    let inf = Vec3A::splat(f32::INFINITY);
    (Vec3A::from(ray.o).abs().cmplt(inf) & Vec3A::from(ray.d).abs().cmplt(inf)).all()
}

/// True when `ray` starts strictly outside one of the box `[min, max]`'s slabs and moves away
/// from it (a direction component of the outward sign, below 2 in magnitude): then
/// [`intersect_box`] returns `None` for every `t_max`. On that axis both slab distances
/// `(lo − o)/d` and `(hi − o)/d` are strictly negative (a difference of two unequal floats is
/// nonzero, at least 2^-149 in magnitude, and its quotient by `|d| < 2` does not round to
/// zero), so the exit distance is negative and neither the entry nor the exit is ahead.
/// Rays spawned outward from the box's faces (a path leaving the box) are such rays: their
/// origin is pushed past the face plane ([`crate::math::offset_ray_origin`]).
/// Evaluated in 4-wide lanes, one compare per condition for the three axes.
#[inline(always)]
fn moves_away_from_box(ray: &Ray, min: Vec3A, max: Vec3A) -> bool {
    let (o, d) = (Vec3A::from(ray.o), Vec3A::from(ray.d));
    let two = Vec3A::splat(2.0);
    let beyond_max = o.cmpgt(max) & d.cmpgt(Vec3A::ZERO) & d.cmplt(two);
    let beyond_min = o.cmplt(min) & d.cmplt(Vec3A::ZERO) & d.cmpgt(-two);
    (beyond_max | beyond_min).any()
}

/// The hit record of box hit `h` on shape `shape` along `ray`. Its error bound: the point
/// `p = o + t d` on the face's two other axes (the face's own coordinate is exact), so
/// γ₇ · max(|o| + |t d|, |p|) over the axes. In lanes: `max_element` of non-negative values
/// (no NaN for a finite ray and `t`) is the same whatever the order of its comparisons.
#[inline(always)]
fn box_record(ray: &Ray, shape: u32, h: BoxHit) -> Hit {
    let (o, d, p) = (Vec3A::from(ray.o), Vec3A::from(ray.d), Vec3A::from(h.p));
    let p_error = crate::math::gamma(7) * (o.abs() + (d * h.t).abs()).max(p.abs()).max_element();
    Hit {
        t: h.t,
        p: h.p,
        ng: h.n,
        ns: h.n,
        uv: HitUv::At(h.uv),
        shape,
        prim: 0,
        p_error,
    }
}

/// The unit geometric normal of the triangle `a, b, c` along its winding,
/// `(b − a) × (c − a)` normalised; NaN in every component when that vector cannot be
/// normalised (a degenerate triangle, or a cross product whose squared length overflows).
/// Computed once per triangle when the scene is built, with the operations the hit record
/// used to perform per hit, so the stored normal is the same bit for bit.
fn geometric_normal(a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    (b - a).cross(c - a).normalize_or(Vec3::NAN)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{icosphere, intersect_sphere, TriangleMesh};
    use crate::sampling::{sample_uniform_sphere, Rng};

    /// Asserts that `geometry` and `plain` give ray `i` the same closest hit (its
    /// [`hit_bits`]) and the same occlusion answer; returns `plain`'s hit.
    fn assert_same_answers(
        geometry: &SceneGeometry,
        plain: &SceneGeometry,
        ray: &Ray,
        t_max: f32,
        i: usize,
    ) -> Option<Hit> {
        let (a, b) = (geometry.intersect(ray, t_max), plain.intersect(ray, t_max));
        assert_eq!(hit_bits(a), hit_bits(b), "ray {i}: {ray:?} to {t_max}");
        assert_eq!(
            geometry.occluded(ray, t_max),
            plain.occluded(ray, t_max),
            "ray {i}"
        );
        b
    }

    /// Every field of a hit record as bits: distance, point, both normals, uv, error bound,
    /// shape and primitive.
    fn record_bits(h: Option<Hit>) -> Option<([u32; 13], u32, u32)> {
        h.map(|h| {
            let f = [
                h.t,
                h.p.x,
                h.p.y,
                h.p.z,
                h.ng.x,
                h.ng.y,
                h.ng.z,
                h.ns.x,
                h.ns.y,
                h.ns.z,
                h.uv().x,
                h.uv().y,
                h.p_error,
            ];
            (f.map(f32::to_bits), h.shape, h.prim)
        })
    }

    fn hit_bits(h: Option<Hit>) -> Option<[u32; 6]> {
        h.map(|h| {
            [
                h.t.to_bits(),
                h.p.x.to_bits(),
                h.p.y.to_bits(),
                h.p.z.to_bits(),
                h.shape,
                h.prim,
            ]
        })
    }

    /// Each BVH position's triangle read from its mesh's own vertex and index arrays and
    /// transposed by [`TriangleSoa::new`] (the layout before the compact one), so that the
    /// brute force below does not share the compact layout's indexing or transposition.
    /// The mesh of BVH primitive `p`, and the triangle's corner indices in it.
    fn mesh_triangle<'g>(geometry: &'g SceneGeometry, p: &Prim) -> (&'g TriangleMesh, [usize; 3]) {
        let Some(Shape::Mesh(m)) = geometry.shapes.get(p.shape as usize) else {
            panic!("position of a non-mesh shape");
        };
        (m, m.indices[p.prim as usize].map(|i| i as usize))
    }

    fn triangles_from_meshes(geometry: &SceneGeometry) -> Vec<TriangleSoa> {
        geometry
            .prims
            .iter()
            .map(|p| {
                let (m, tri) = mesh_triangle(geometry, p);
                let [a, b, c] = tri.map(|i| m.positions[i]);
                TriangleSoa::new(a, b, c)
            })
            .collect()
    }

    /// Closest hit by brute force over every triangle (the first of equal distances in BVH
    /// order): (t, triangle position, barycentrics) as bits.
    fn brute_force_hit(triangles: &[TriangleSoa], ray: &Ray, t_max: f32) -> Option<[u32; 5]> {
        let sr = ShearedRay::new(ray);
        let mut best = None;
        let mut t = t_max;
        for (slot, tri) in triangles.iter().enumerate() {
            if let Some(h) = sr.intersect(tri, t) {
                best = Some((slot as u32, h));
                t = h.t;
            }
        }
        best.map(|(slot, h)| {
            [
                h.t.to_bits(),
                slot,
                h.b0.to_bits(),
                h.b1.to_bits(),
                h.b2.to_bits(),
            ]
        })
    }

    /// Closest hit by the traversal: the same fields as [`brute_force_hit`].
    fn traversal_hit(geometry: &SceneGeometry, ray: &Ray, t_max: f32) -> Option<[u32; 5]> {
        let sr = ShearedRay::new(ray);
        let mut best = None;
        geometry.bvh.traverse(ray, t_max, |slot, t| {
            match sr.intersect(&geometry.triangle(slot as usize), t) {
                Some(h) => {
                    best = Some((slot, h));
                    h.t
                }
                None => t,
            }
        });
        best.map(|(slot, h)| {
            [
                h.t.to_bits(),
                slot,
                h.b0.to_bits(),
                h.b1.to_bits(),
                h.b2.to_bits(),
            ]
        })
    }

    /// The skin icosphere's rays: from outside towards the sphere, from inside to the
    /// boundary, short free flights inside, and rays grazing the surface from just inside.
    fn icosphere_ray(rng: &mut Rng, i: usize) -> (Ray, f32) {
        let centre = Vec3::new(10.0, -2.0, 5.0);
        match i % 4 {
            0 => {
                let o = centre + sample_uniform_sphere(rng.next_2d()) * 12.0;
                let target = centre
                    + (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE)
                        * 3.3;
                (Ray::new(o, (target - o).normalize()), f32::INFINITY)
            }
            1 => {
                let o = centre + sample_uniform_sphere(rng.next_2d()) * rng.next_f32().cbrt() * 2.9;
                (
                    Ray::new(o, sample_uniform_sphere(rng.next_2d())),
                    f32::INFINITY,
                )
            }
            2 => {
                let o = centre + sample_uniform_sphere(rng.next_2d()) * rng.next_f32().cbrt() * 2.9;
                let t = -(1.0 - rng.next_f32()).ln() / 8.0;
                (Ray::new(o, sample_uniform_sphere(rng.next_2d())), t)
            }
            _ => {
                let o =
                    centre + sample_uniform_sphere(rng.next_2d()) * (2.99 + 0.01 * rng.next_f32());
                (
                    Ray::new(o, sample_uniform_sphere(rng.next_2d())),
                    0.5 * rng.next_f32(),
                )
            }
        }
    }

    fn skin_icosphere() -> SceneGeometry {
        let mut mesh = icosphere(5);
        for p in &mut mesh.positions {
            *p = *p * 3.0 + Vec3::new(10.0, -2.0, 5.0);
        }
        SceneGeometry::build(vec![Shape::Mesh(mesh)]).expect("geometry")
    }

    #[test]
    fn the_vector_query_check_is_the_componentwise_predicate() {
        let specials = [
            0.0,
            -0.0,
            1.0,
            -2.5,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE * 0.5,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -f32::NAN,
        ];
        let pick = |i: usize| specials[i % specials.len()];
        let n = specials.len();
        let mut rng = Rng::new(3, 5);
        let mut valid = 0;
        for case in 0..200_000usize {
            // Each component special with some probability, else random.
            let mut c = [0.0f32; 7];
            for (k, v) in c.iter_mut().enumerate() {
                *v = if rng.next_f32() < 0.5 {
                    pick((case / 7 + k * 5 + (rng.next_f32() * n as f32) as usize) % n)
                } else {
                    rng.next_f32() * 4.0 - 2.0
                };
            }
            let ray = Ray {
                o: Vec3::new(c[0], c[1], c[2]),
                d: Vec3::new(c[3], c[4], c[5]),
            };
            let old = ray.o.is_finite()
                && ray.d.is_finite()
                && ray.d != Vec3::ZERO
                && !c[6].is_nan()
                && c[6] > 0.0;
            assert_eq!(valid_query(&ray, c[6]), old, "{c:?}");
            valid += usize::from(old);
        }
        // Both answers occur often.
        assert!(valid > 10_000 && valid < 190_000, "{valid}");
        // Zero directions of either sign are not queries.
        let zero = Ray {
            o: Vec3::ZERO,
            d: Vec3::new(-0.0, 0.0, -0.0),
        };
        assert!(!valid_query(&zero, 1.0));
    }

    #[test]
    fn shadow_rays_agree_with_closest_hits_and_stop_at_the_first_hit() {
        let geometry = skin_icosphere();
        for avx2 in [true, false] {
            let mut g = geometry.clone();
            if !avx2 {
                g.bvh = g.bvh.without_avx2();
            }
            let mut rng = Rng::new(33, 2);
            let mut hits = 0;
            for i in 0..200_000 {
                let (ray, t_max) = icosphere_ray(&mut rng, i);
                let closest = traversal_hit(&g, &ray, t_max);
                let mut calls_after_hit = 0;
                let mut found = false;
                let sr = ShearedRay::new(&ray);
                g.bvh.traverse(&ray, t_max, |slot, t| {
                    calls_after_hit += usize::from(found);
                    if sr.intersect(&g.triangle(slot as usize), t).is_some() {
                        found = true;
                        0.0
                    } else {
                        t
                    }
                });
                assert_eq!(found, closest.is_some(), "ray {i} (avx2 {avx2})");
                assert_eq!(calls_after_hit, 0, "ray {i}: the shadow ray went on");
                assert_eq!(g.occluded(&ray, t_max), found, "ray {i}");
                hits += usize::from(found);
            }
            assert!((100_000..190_000).contains(&hits), "{hits} hits");
        }
    }

    /// Rays from inside the skin icosphere through `intersect` and `occluded` (the paths a
    /// walk inside the skin takes, empty-cell test included): from anywhere inside, from just
    /// below the surface, along the axes and diagonals (directions with zero components) and
    /// from points on a coarse lattice; the closest hit and the shadow ray's answer equal
    /// brute force over every triangle, bit for bit.
    #[test]
    fn rays_from_inside_find_the_brute_force_hits_bit_for_bit() {
        let geometry = skin_icosphere();
        let triangles = triangles_from_meshes(&geometry);
        let centre = Vec3::new(10.0, -2.0, 5.0);
        let mut rng = Rng::new(47, 3);
        let mut hits = 0;
        for i in 0..30_000 {
            let o = match i % 3 {
                0 => centre + sample_uniform_sphere(rng.next_2d()) * rng.next_f32().cbrt() * 2.95,
                1 => centre + sample_uniform_sphere(rng.next_2d()) * (2.9 + 0.1 * rng.next_f32()),
                // On a coarse lattice: often exactly on a cell boundary.
                _ => centre + (sample_uniform_sphere(rng.next_2d()) * 2.5 * 8.0).round() / 8.0,
            };
            let d = match i % 5 {
                0 => [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z][i / 5 % 6],
                1 => Vec3::new(
                    if rng.next_f32() < 0.5 { 1.0 } else { -1.0 },
                    if rng.next_f32() < 0.5 { 1.0 } else { -1.0 },
                    if i % 2 == 0 { 0.0 } else { 1.0 },
                )
                .normalize(),
                _ => sample_uniform_sphere(rng.next_2d()),
            };
            let t_max = if i % 4 == 0 {
                -(1.0 - rng.next_f32()).ln() / 4.0
            } else {
                f32::INFINITY
            };
            let ray = Ray::new(o, d);
            let expected = brute_force_hit(&triangles, &ray, t_max);
            let got = geometry
                .intersect(&ray, t_max)
                .map(|h| (h.t.to_bits(), h.prim));
            let want = expected.map(|[t, slot, ..]| (t, geometry.prims[slot as usize].prim));
            assert_eq!(got, want, "ray {i}: {ray:?} to {t_max}");
            assert_eq!(
                geometry.occluded(&ray, t_max),
                expected.is_some(),
                "ray {i}"
            );
            hits += usize::from(expected.is_some());
        }
        assert!(hits > 15_000, "{hits} hits");
    }

    #[test]
    fn traversal_hits_are_those_of_brute_force_bit_for_bit() {
        let geometry = skin_icosphere();
        let triangles = triangles_from_meshes(&geometry);
        let mut rng = Rng::new(35, 2);
        let mut hits = 0;
        for i in 0..20_000 {
            let (ray, t_max) = icosphere_ray(&mut rng, i);
            let expected = brute_force_hit(&triangles, &ray, t_max);
            assert_eq!(traversal_hit(&geometry, &ray, t_max), expected, "ray {i}");
            hits += usize::from(expected.is_some());
        }
        assert!(hits > 10_000, "{hits} hits");
    }

    /// The triangle hit record as it was computed per hit before the geometric normals were
    /// stored: every corner and attribute read from the mesh's own arrays, the normal's cross
    /// product and normalisation done here.
    fn reference_hit(geometry: &SceneGeometry, ray: &Ray, slot: usize, h: TriangleHit) -> Hit {
        let p = geometry.prims[slot];
        let (m, tri) = mesh_triangle(geometry, &p);
        let [a, b, c] = tri.map(|i| m.positions[i]);
        let [a4, b4, c4] = [a, b, c].map(|v| v.extend(0.0));
        let ng = (b - a).cross(c - a).normalize_or(-ray.d);
        let mut ns = ng;
        if let Some(n) = &m.normals {
            let s = (n[tri[0]] * h.b0 + n[tri[1]] * h.b1 + n[tri[2]] * h.b2).normalize_or(ng);
            ns = if s.dot(ng) < 0.0 { -s } else { s };
        }
        let uv = match &m.uvs {
            Some(t) => t[tri[0]] * h.b0 + t[tri[1]] * h.b1 + t[tri[2]] * h.b2,
            None => Vec2::new(h.b1, h.b2),
        };
        Hit {
            t: h.t,
            p: (a4 * h.b0 + b4 * h.b1 + c4 * h.b2).truncate(),
            ng,
            ns,
            uv: HitUv::At(uv),
            shape: p.shape,
            prim: p.prim,
            p_error: crate::math::gamma(7)
                * (a4.abs() * h.b0.abs() + b4.abs() * h.b1.abs() + c4.abs() * h.b2.abs())
                    .truncate()
                    .max_element(),
        }
    }

    /// Every field of a hit as bits.
    fn all_bits(h: &Hit) -> [u32; 15] {
        [
            h.t.to_bits(),
            h.p.x.to_bits(),
            h.p.y.to_bits(),
            h.p.z.to_bits(),
            h.ng.x.to_bits(),
            h.ng.y.to_bits(),
            h.ng.z.to_bits(),
            h.ns.x.to_bits(),
            h.ns.y.to_bits(),
            h.ns.z.to_bits(),
            h.uv().x.to_bits(),
            h.uv().y.to_bits(),
            h.shape,
            h.prim,
            h.p_error.to_bits(),
        ]
    }

    /// Three meshes for the hit record: the skin icosphere moved off the origin, a coarser
    /// icosphere with perturbed vertex normals (some facing inward) and UVs, and a soup of
    /// random triangles with some degenerate ones (a repeated vertex, three collinear
    /// vertices) and two so large that their cross product's squared length overflows (no
    /// normal: the hit record falls back to the reversed ray direction).
    /// Sphere hit records are made only for the nearest hit (`Best::Sphere` keeps a
    /// `SphereCandidate`): the record must be the one `intersect_sphere` makes for that sphere
    /// alone, bit for bit (position, normals, uv, t), with the sphere's `p_error`; the nearest
    /// shape the one an independent search over every shape finds; and `occluded` must agree
    /// with the closest-hit query. Nested and overlapping spheres (a huge floor among them)
    /// and a mesh in front of and behind them, so that sphere hits are superseded by nearer
    /// spheres and triangles as well as kept.
    #[test]
    fn sphere_records_made_for_the_nearest_hit_only_are_intersect_spheres() {
        let mut rng = Rng::new(77, 5);
        let spheres = [
            (Vec3::new(0.0, -1000.0, 0.0), 1000.0),
            (Vec3::new(0.0, 1.0, 0.0), 0.99),
            (Vec3::new(0.4, 1.2, 0.1), 0.5),
            (Vec3::new(-1.5, 0.5, 0.3), 0.7),
            (Vec3::new(0.0, 1.0, 0.0), 0.3),
        ];
        let mut mesh = icosphere(3);
        for p in &mut mesh.positions {
            *p = *p * Vec3::new(1.6, 0.2, 1.6) + Vec3::new(0.0, 1.9, 0.0);
        }
        let mut shapes: Vec<Shape> = spheres
            .iter()
            .map(|&(center, radius)| Shape::Sphere { center, radius })
            .collect();
        shapes.push(Shape::Mesh(mesh.clone()));
        let geo = SceneGeometry::build(shapes).expect("valid shapes");
        let (mut sphere_hits, mut superseded) = (0, 0);
        for i in 0..60_000 {
            let o = Vec3::new(rng.next_f32() - 0.5, rng.next_f32(), rng.next_f32() - 0.5)
                * Vec3::new(5.0, 3.5, 5.0)
                + Vec3::new(0.0, if i % 4 == 0 { -0.5 } else { 0.2 }, 0.0);
            let d = sample_uniform_sphere(rng.next_2d());
            let t_max = if i % 7 == 0 { 1.5 } else { f32::INFINITY };
            let ray = Ray::new(o, d);
            // Every shape on its own, each sphere's record made at once.
            let mut best: Option<(f32, u32)> = None;
            let mut records = Vec::new();
            for (si, &(center, radius)) in spheres.iter().enumerate() {
                let h = intersect_sphere(&ray, center, radius, t_max);
                if let Some(h) = h {
                    if best.is_none_or(|(t, _)| h.t < t) {
                        best = Some((h.t, si as u32));
                    }
                }
                records.push(h);
            }
            let sphere_count = records.iter().flatten().count();
            for t in &mesh.indices {
                let [p0, p1, p2] = t.map(|k| mesh.positions[k as usize]);
                let bound = best.map_or(t_max, |(t, _)| t);
                if let Some(h) = crate::geometry::intersect_triangle(&ray, p0, p1, p2, bound) {
                    best = Some((h.t, spheres.len() as u32));
                }
            }
            let got = geo.intersect(&ray, t_max);
            assert_eq!(geo.occluded(&ray, t_max), got.is_some(), "ray {i}");
            match (best, got) {
                (None, None) => {}
                (Some((t, shape)), Some(h)) => {
                    assert_eq!((h.t.to_bits(), h.shape), (t.to_bits(), shape), "ray {i}");
                    if (shape as usize) < spheres.len() {
                        sphere_hits += 1;
                        let r = records[shape as usize].expect("the nearest sphere was hit");
                        let (center, radius) = spheres[shape as usize];
                        let bits = |v: Vec3| v.to_array().map(f32::to_bits);
                        assert_eq!(bits(h.p), bits(r.p), "ray {i}");
                        assert_eq!(bits(h.ng), bits(r.n), "ray {i}");
                        assert_eq!(bits(h.ns), bits(r.n), "ray {i}");
                        assert_eq!(
                            h.uv().to_array().map(f32::to_bits),
                            r.uv.to_array().map(f32::to_bits),
                            "ray {i}"
                        );
                        let p_error =
                            crate::math::gamma(6) * 4.0 * (center.abs().max_element() + radius);
                        assert_eq!(h.p_error.to_bits(), p_error.to_bits(), "ray {i}");
                        if sphere_count > 1 {
                            superseded += 1;
                        }
                    } else if sphere_count > 0 {
                        superseded += 1;
                    }
                }
                (b, g) => panic!("ray {i}: {b:?} against {g:?}"),
            }
        }
        assert!(
            sphere_hits > 10_000 && superseded > 5_000,
            "{sphere_hits} {superseded}"
        );
    }

    fn hit_record_scene() -> SceneGeometry {
        let mut rng = Rng::new(41, 3);
        let mut skin = icosphere(5);
        for p in &mut skin.positions {
            *p = *p * 3.0 + Vec3::new(10.0, -2.0, 5.0);
        }
        let mut shaded = icosphere(3);
        for p in &mut shaded.positions {
            *p = *p * 0.7 + Vec3::new(10.0, -2.0, 5.0);
        }
        let normals = shaded
            .positions
            .iter()
            .map(|&p| {
                let jitter = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5;
                (p - Vec3::new(10.0, -2.0, 5.0)) * (rng.next_f32() * 2.4 - 0.4) + jitter
            })
            .collect();
        let uvs = (0..shaded.positions.len())
            .map(|_| Vec2::new(rng.next_f32(), rng.next_f32()))
            .collect();
        shaded.normals = Some(normals);
        shaded.uvs = Some(uvs);
        let mut soup = TriangleMesh {
            positions: Vec::new(),
            normals: None,
            uvs: None,
            indices: Vec::new(),
        };
        for i in 0..400u32 {
            let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 8.0 - 4.0;
            let e = |rng: &mut Rng| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5;
            let (a, b) = (c + e(&mut rng), c + e(&mut rng));
            let third = match i % 20 {
                0 => a,
                1 => a + (b - a) * 0.5,
                _ => c + e(&mut rng),
            };
            soup.positions.extend([a, b, third]);
            soup.indices.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        let n = soup.positions.len() as u32;
        let big = 9e14;
        soup.positions.extend([
            Vec3::new(-big, -big, 50.0),
            Vec3::new(big, -big, 50.0),
            Vec3::new(0.0, big, 50.0),
            Vec3::new(-big, -big, -50.0),
            Vec3::new(0.0, big, -50.0),
            Vec3::new(big, -big, -50.0),
        ]);
        soup.indices
            .extend([[n, n + 1, n + 2], [n + 3, n + 4, n + 5]]);
        SceneGeometry::build(vec![
            Shape::Mesh(skin),
            Shape::Mesh(shaded),
            Shape::Mesh(soup),
        ])
        .expect("geometry")
    }

    #[test]
    fn stored_normals_are_the_per_hit_normals_bit_for_bit() {
        let geometry = hit_record_scene();
        let d = Vec3::new(0.36, -0.48, 0.8);
        let mut without = 0;
        for (slot, p) in geometry.prims.iter().enumerate() {
            let (m, tri) = mesh_triangle(&geometry, p);
            let [a, b, c] = tri.map(|i| m.positions[i]);
            let expected = (b - a).cross(c - a).normalize_or(-d);
            let stored = if p.ng.x.is_nan() { -d } else { p.ng };
            assert_eq!(
                stored.to_array().map(f32::to_bits),
                expected.to_array().map(f32::to_bits),
                "position {slot}: shape {} triangle {}",
                p.shape,
                p.prim
            );
            without += usize::from(p.ng.x.is_nan());
        }
        // The triangles with a repeated vertex and the overflowing ones (20 + 2) have none,
        // and some of the 20 with a vertex rounded onto the others' line.
        assert!(
            (22..=42).contains(&without),
            "{without} triangles without a normal"
        );
    }

    #[test]
    fn hit_records_are_those_computed_per_hit_bit_for_bit() {
        let geometry = hit_record_scene();
        let mut rng = Rng::new(43, 5);
        let (mut hits, mut shaded, mut fallback) = (0, 0, 0);
        for i in 0..60_000 {
            let (ray, t_max) = if i % 10 == 9 {
                // Towards the two huge triangles, from between or beyond them.
                let o = Vec3::new(
                    rng.next_f32(),
                    rng.next_f32(),
                    rng.next_f32() * 200.0 - 100.0,
                );
                let d = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, 1.0);
                let d = if rng.next_f32() < 0.5 { d } else { -d };
                (Ray::new(o, d.normalize()), f32::INFINITY)
            } else if i % 10 == 8 {
                // Through the soup.
                let o = sample_uniform_sphere(rng.next_2d()) * 10.0;
                let target = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 8.0 - 4.0;
                (Ray::new(o, (target - o).normalize()), 40.0)
            } else {
                icosphere_ray(&mut rng, i)
            };
            let sr = ShearedRay::new(&ray);
            let mut best = None;
            geometry.bvh.traverse(&ray, t_max, |slot, t| {
                match sr.intersect(&geometry.triangle(slot as usize), t) {
                    Some(h) => {
                        best = Some((slot as usize, h));
                        h.t
                    }
                    None => t,
                }
            });
            let got = geometry.intersect(&ray, t_max);
            assert_eq!(
                got.as_ref().map(all_bits),
                best.map(|(slot, h)| all_bits(&reference_hit(&geometry, &ray, slot, h))),
                "ray {i}: {ray:?} to {t_max}"
            );
            if let Some(h) = got {
                hits += 1;
                shaded += usize::from(h.shape == 1);
                fallback += usize::from(h.ng == -ray.d);
            }
        }
        // Hits on every mesh, on the shaded one and on the triangles without a normal.
        assert!(hits > 30_000, "{hits} hits");
        assert!(shaded > 300, "{shaded} hits on the shaded mesh");
        assert!(fallback > 1_000, "{fallback} hits without a normal");
    }

    #[test]
    fn skipping_empty_cells_changes_no_hit() {
        // The skin icosphere (20,480 triangles) scaled and moved off the origin, and a box.
        let mut mesh = icosphere(5);
        for p in &mut mesh.positions {
            *p = *p * 3.0 + Vec3::new(10.0, -2.0, 5.0);
        }
        let geometry = SceneGeometry::build(vec![
            Shape::Mesh(mesh),
            Shape::Box {
                min: Vec3::new(9.0, -3.0, 4.0),
                max: Vec3::new(9.5, -2.5, 4.5),
            },
        ])
        .expect("geometry");
        let plain = geometry.clone().without_empty_cells();
        let centre = Vec3::new(10.0, -2.0, 5.0);
        let mut rng = Rng::new(21, 4);
        let (mut skipped, mut hits) = (0, 0);
        for i in 0..200_000 {
            // Points inside and around the sphere, short and long segments, some grazing the
            // surface from just inside (the free flights of a dense medium).
            let r = 3.0 * (0.9 + 0.12 * rng.next_f32()).min(1.0) * rng.next_f32().cbrt().max(0.3);
            let o = centre + sample_uniform_sphere(rng.next_2d()) * r;
            let d = sample_uniform_sphere(rng.next_2d());
            let t_max = match i % 4 {
                0 => 0.02 * rng.next_f32(),
                1 => 0.2 * rng.next_f32(),
                2 => 2.0 * rng.next_f32(),
                _ => f32::INFINITY,
            };
            let ray = Ray::new(o, d);
            let b = assert_same_answers(&geometry, &plain, &ray, t_max, i);
            skipped += usize::from(geometry.segment_misses_triangles(&ray, t_max));
            hits += usize::from(b.is_some());
        }
        // The grid must actually be used, and the set must contain hits.
        assert!(skipped > 40_000, "{skipped} segments skipped");
        assert!(hits > 50_000, "{hits} hits");
    }

    /// An eye-like scene: a meshed globe (icosphere, radius 1), analytic spheres nested in it
    /// (radii 0.995 and 0.93 about its centre, 0.64 about a point in front), a small mesh
    /// inside them, and a light sphere outside. Skipping the traversal for segments inside
    /// the shells no triangle touches changes no hit record and no occlusion, and the shells
    /// are used (segments ending on the nested spheres).
    #[test]
    fn skipping_free_shells_changes_no_hit() {
        let mut shapes = vec![Shape::Mesh(icosphere(5))];
        let mut small = icosphere(2);
        for p in &mut small.positions {
            *p = *p * Vec3::new(0.5, 0.5, 0.03) + Vec3::new(0.0, 0.0, 0.72);
        }
        shapes.push(Shape::Mesh(small));
        for (center, radius) in [
            (Vec3::ZERO, 0.995),
            (Vec3::ZERO, 0.93),
            (Vec3::new(0.0, 0.0, 0.57), 0.64),
            (Vec3::new(-3.2, 1.6, 2.4), 0.12),
        ] {
            shapes.push(Shape::Sphere { center, radius });
        }
        let geometry = SceneGeometry::build(shapes).expect("geometry");
        let plain = geometry.clone().without_free_shells();
        let mut rng = Rng::new(23, 9);
        let (mut skipped, mut hits, mut tri_hits) = (0, 0, 0);
        for i in 0..100_000 {
            let r = match i % 3 {
                0 => 0.93 + 0.07 * rng.next_f32(),
                1 => rng.next_f32().cbrt(),
                _ => 1.3 * rng.next_f32(),
            };
            let o = sample_uniform_sphere(rng.next_2d()) * r;
            let d = sample_uniform_sphere(rng.next_2d());
            let t_max = if i % 5 == 0 { 0.3 } else { f32::INFINITY };
            let ray = Ray::new(o, d);
            let b = assert_same_answers(&geometry, &plain, &ray, t_max, i);
            if let Some(h) = b {
                hits += 1;
                tri_hits += usize::from(h.shape < 2);
                let free = geometry.free.as_ref().expect("shells");
                let center = match geometry.shape(h.shape as usize) {
                    Some(Shape::Sphere { center, .. }) => *center,
                    _ => Vec3::NAN,
                };
                skipped += usize::from(free.clear_about(center, ray.o, ray.d, h.t));
            }
        }
        assert!(skipped > 20_000, "{skipped} segments skipped");
        assert!(tri_hits > 3_000 && hits > 80_000, "{tri_hits} {hits}");
    }

    #[test]
    fn rays_moving_away_from_a_sole_box_miss_it() {
        let (min, max) = (Vec3::new(-0.5, -0.25, -0.75), Vec3::new(0.5, 0.75, 0.25));
        let geometry = SceneGeometry::build(vec![Shape::Box { min, max }]).expect("geometry");
        let (lo, hi) = (Vec3A::from(min), Vec3A::from(max));
        assert_eq!(geometry.sole_box, Some((lo, hi, 0)));
        let mut plain = geometry.clone();
        plain.sole_box = None;
        let mut rng = Rng::new(17, 3);
        let (mut escapes, mut away) = (0, 0);
        for i in 0..300_000 {
            // Directions with zero, tiny and exact-unit components among them.
            let mut d = sample_uniform_sphere(rng.next_2d());
            match i % 5 {
                0 => d.x = 0.0,
                1 => d.y = 1e-30,
                2 => d = Vec3::new(0.0, 0.0, if rng.next_f32() < 0.5 { 1.0 } else { -1.0 }),
                _ => {}
            }
            let d = d.normalize_or(Vec3::Z);
            let t_max = match i % 3 {
                0 => f32::INFINITY,
                1 => 3.0 * rng.next_f32(),
                _ => 0.01 * rng.next_f32(),
            };
            // Origins inside, outside, on the faces, edges and corners.
            let mut o = Vec3::new(
                rng.next_f32() * 3.0 - 1.5,
                rng.next_f32() * 3.0 - 1.5,
                rng.next_f32() * 3.0 - 1.5,
            );
            match i % 7 {
                0 => o.x = max.x,
                1 => o.y = min.y,
                2 => {
                    o.x = min.x;
                    o.z = max.z;
                }
                3 => o = min.lerp(max, rng.next_f32()),
                _ => {}
            }
            let ray = Ray::new(o, d);
            let a = geometry.intersect(&ray, t_max);
            // Every field of the record, the normals, uv and error bound included.
            assert_eq!(
                record_bits(a),
                record_bits(plain.intersect(&ray, t_max)),
                "ray {i}: {ray:?}"
            );
            if moves_away_from_box(&ray, lo, hi) {
                away += 1;
                assert!(
                    intersect_box(&ray, min, max, t_max).is_none(),
                    "ray {i}: {ray:?}"
                );
            }
            // A ray from inside leaves through a face; the ray spawned there escapes.
            let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            let inside = Ray::new(min + (max - min) * u, d);
            if let Some(exit) = geometry.intersect(&inside, f32::INFINITY) {
                let escape = Ray::new(exit.spawn_origin(d), d);
                assert!(moves_away_from_box(&escape, lo, hi), "ray {i}: {escape:?}");
                assert!(plain.intersect(&escape, f32::INFINITY).is_none(), "ray {i}");
                escapes += 1;
            }
        }
        assert!(escapes > 290_000, "{escapes} escapes");
        assert!(away > 50_000, "{away} rays moving away");
    }

    /// The sole box's own query ([`closest_on_sole_box`], which checks only the ray's
    /// finiteness) answers queries [`valid_query`] rejects as the general search does: rays
    /// with a NaN or infinite origin or direction component, zero directions, and `t_max`
    /// zero, negative, NaN or tiny, with origins inside, on and outside the box. Every field
    /// of the record is compared, and the queries that hit are counted so that the test
    /// cannot pass by answering `None` throughout.
    #[test]
    fn a_sole_box_answers_degenerate_queries_as_the_general_search() {
        let (min, max) = (Vec3::new(-0.5, -0.25, -0.75), Vec3::new(0.5, 0.75, 0.25));
        let geometry = SceneGeometry::build(vec![Shape::Box { min, max }]).expect("geometry");
        assert!(geometry.sole_box.is_some());
        let mut plain = geometry.clone();
        plain.sole_box = None;
        let odd = [
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            0.0,
            -0.0,
            f32::MAX,
            -f32::MAX,
            1e-40,
        ];
        let t_maxes = [
            f32::INFINITY,
            2.0,
            0.0,
            -0.0,
            -1.0,
            f32::NAN,
            f32::NEG_INFINITY,
            f32::MIN_POSITIVE,
        ];
        let mut rng = Rng::new(29, 5);
        let (mut hits, mut queries) = (0, 0);
        for i in 0..40_000usize {
            let mut d = sample_uniform_sphere(rng.next_2d());
            let mut o = Vec3::new(
                rng.next_f32() * 3.0 - 1.5,
                rng.next_f32() * 3.0 - 1.5,
                rng.next_f32() * 3.0 - 1.5,
            );
            if i % 4 == 1 {
                o = min.lerp(max, rng.next_f32());
            }
            let k = (i / 8) % 3;
            match (i / 24) % 6 {
                0 => o[k] = odd[i % odd.len()],
                1 => d[k] = odd[i % odd.len()],
                2 => d = Vec3::ZERO,
                3 => d = Vec3::splat(-0.0),
                _ => {}
            }
            let t_max = t_maxes[i % t_maxes.len()];
            let ray = Ray::new(o, d);
            let a = geometry.intersect(&ray, t_max);
            assert_eq!(
                record_bits(a),
                record_bits(plain.intersect(&ray, t_max)),
                "ray {i}: {ray:?}, t_max {t_max}"
            );
            queries += 1;
            hits += usize::from(a.is_some());
        }
        assert_eq!(queries, 40_000);
        assert!(hits > 1_000, "{hits} hits");
    }

    /// Rays through the shared edges and vertices of a flat grid mesh (integer vertices, rays
    /// straight down from grid points and edge midpoints, and slanted through them): their
    /// edge functions are exactly zero, so the traversal's triangle test takes the exact
    /// fallback (compiled into the traversal's loop). Every ray inside the grid hits exactly
    /// one triangle (watertight), and `intersect` and `occluded` equal brute force bit for bit
    /// with the 8-wide and the 4-wide node test.
    #[test]
    fn rays_through_shared_edges_and_vertices_take_the_exact_path_in_the_traversal() {
        let n = 12u32;
        let mut grid = TriangleMesh {
            positions: Vec::new(),
            normals: None,
            uvs: None,
            indices: Vec::new(),
        };
        for j in 0..=n {
            for i in 0..=n {
                grid.positions.push(Vec3::new(i as f32, j as f32, 0.0));
            }
        }
        let at = |i: u32, j: u32| j * (n + 1) + i;
        for j in 0..n {
            for i in 0..n {
                // Alternating diagonals, so vertices join four or eight triangles.
                if (i + j) % 2 == 0 {
                    grid.indices
                        .push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                    grid.indices
                        .push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
                } else {
                    grid.indices.push([at(i, j), at(i + 1, j), at(i, j + 1)]);
                    grid.indices
                        .push([at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
                }
            }
        }
        let geometry = SceneGeometry::build(vec![Shape::Mesh(grid)]).expect("geometry");
        let triangles = triangles_from_meshes(&geometry);
        let mut rng = Rng::new(51, 4);
        for avx2 in [true, false] {
            let mut g = geometry.clone();
            if !avx2 {
                g.bvh = g.bvh.without_avx2();
            }
            for k in 0..4_000 {
                // A grid point or an edge's midpoint strictly inside the grid.
                let x = 1.0 + (rng.next_f32() * (n - 2) as f32 * 2.0).floor() * 0.5;
                let y = 1.0 + (rng.next_f32() * (n - 2) as f32 * 2.0).floor() * 0.5;
                let target = Vec3::new(x, y, 0.0);
                let d = match k % 3 {
                    0 => Vec3::new(0.0, 0.0, -1.0),
                    1 => Vec3::new(0.0, 0.0, 1.0),
                    // Slanted by a power of two, so the sheared coordinates stay exact.
                    _ => Vec3::new(0.25, -0.5, if k % 2 == 0 { -1.0 } else { 1.0 }),
                };
                let ray = Ray {
                    o: target - d * 4.0,
                    d,
                };
                let expected = brute_force_hit(&triangles, &ray, f32::INFINITY);
                let hits = triangles
                    .iter()
                    .filter(|t| ShearedRay::new(&ray).intersect(t, f32::INFINITY).is_some())
                    .count();
                assert_eq!(hits, 1, "ray {k}: {ray:?} (watertight)");
                assert_eq!(traversal_hit(&g, &ray, f32::INFINITY), expected, "ray {k}");
                let got = g
                    .intersect(&ray, f32::INFINITY)
                    .map(|h| (h.t.to_bits(), h.prim));
                let want = expected.map(|[t, slot, ..]| (t, g.prims[slot as usize].prim));
                assert_eq!(got, want, "ray {k}: {ray:?} (avx2 {avx2})");
                // The whole record, its point from the corners the exact path's block lane
                // gives back, as computed from the mesh.
                let reference = expected.map(|[t, slot, b0, b1, b2]| {
                    let [t, b0, b1, b2] = [t, b0, b1, b2].map(f32::from_bits);
                    let h = TriangleHit { t, b0, b1, b2 };
                    all_bits(&reference_hit(&g, &ray, slot as usize, h))
                });
                assert_eq!(
                    g.intersect(&ray, f32::INFINITY).as_ref().map(all_bits),
                    reference,
                    "ray {k}: {ray:?} (avx2 {avx2})"
                );
                assert!(g.occluded(&ray, f32::INFINITY), "ray {k}");
            }
        }
    }
}
