//! Closest points on one mesh: a small binary BVH over the mesh's triangles answering "which
//! point of the surface is nearest to `p`, and what are its texture coordinates". Used by
//! interiors whose textured parameters are projected back to their boundary
//! (`projection = "surface"`, docs/textures.md).
//!
//! The closest point on a triangle is found by Voronoi regions of its vertices, edges and face
//! (Ericson 2005, "Real-Time Collision Detection" §5.1.5; docs/references.md §14.4); the
//! traversal visits the nearer child first and prunes boxes farther than the best distance
//! found, and in a leaf skips each triangle whose own box lies beyond the best distance by
//! more than the rounding of the computed distances ([`skip_threshold`]), so the answers are
//! those of testing every triangle of the leaf. Queries allocate nothing: the traversal stack is a fixed array (the build splits at
//! the median, so the tree's depth is about log2(triangles / leaf size)).

use crate::math::{Aabb, Vec2, Vec3};
use glam::Vec3A;

use super::{GeometryError, TriangleMesh};

/// Triangles per leaf at most.
const LEAF_SIZE: usize = 4;

/// Depth of the traversal stack: median splits keep the tree at most
/// ⌈log2(triangles)⌉ deep, far below this for any mesh that fits in memory.
const STACK: usize = 64;

/// A node: an inner node's children are `first` and `first + 1`; a leaf holds triangles
/// `first..first + count` (in tree order).
#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: Aabb,
    first: u32,
    count: u32,
}

/// The nearest surface point found by [`ClosestPointMesh::nearest`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NearestPoint {
    /// The point on the surface (world units).
    pub p: Vec3,
    /// Its texture coordinates, interpolated from the triangle's corners.
    pub uv: Vec2,
    /// Squared distance from the query point.
    pub distance2: f32,
    /// The triangle (index in the mesh).
    pub prim: u32,
}

/// One mesh prepared for closest-point queries (immutable once built).
#[derive(Clone, Debug)]
pub struct ClosestPointMesh {
    nodes: Vec<Node>,
    /// Corners per triangle, tree order.
    tris: Vec<[Vec3; 3]>,
    /// Texture coordinates per corner, tree order.
    uvs: Vec<[Vec2; 3]>,
    /// The mesh's triangle index per tree slot.
    prims: Vec<u32>,
    /// Each triangle's bounding box, tree order: its squared distance is a lower bound on
    /// the triangle's, tested before the exact closest point (see [`skip_threshold`]).
    tri_bounds: Vec<[Vec3A; 2]>,
    /// The absolute part of the skip margin (world units): a bound on how far rounding can
    /// move a computed closest point outside its triangle's box (see [`skip_threshold`]).
    margin: f32,
}

impl ClosestPointMesh {
    /// Prepares `mesh`, which must have texture coordinates and at least one triangle
    /// (`what` names the mesh in errors).
    pub fn build(mesh: &TriangleMesh, what: &str) -> Result<Self, GeometryError> {
        let invalid = |message: &str| GeometryError::InvalidShape {
            shape: 0,
            message: format!("{what}: {message}"),
        };
        let Some(uvs) = mesh.uvs.as_ref() else {
            return Err(invalid("the mesh has no texture coordinates"));
        };
        if mesh.indices.is_empty() {
            return Err(invalid("the mesh has no triangles"));
        }
        let mut tris = Vec::with_capacity(mesh.indices.len());
        let mut corner_uvs = Vec::with_capacity(mesh.indices.len());
        for t in &mesh.indices {
            let corner = |i: u32| {
                let i = i as usize;
                match (mesh.positions.get(i), uvs.get(i)) {
                    (Some(p), Some(uv)) => Ok((*p, *uv)),
                    _ => Err(invalid("a triangle names a vertex that does not exist")),
                }
            };
            let (a, b, c) = (corner(t[0])?, corner(t[1])?, corner(t[2])?);
            tris.push([a.0, b.0, c.0]);
            corner_uvs.push([a.1, b.1, c.1]);
        }
        let mut order: Vec<u32> = (0..tris.len() as u32).collect();
        let centroids: Vec<Vec3> = tris.iter().map(|t| (t[0] + t[1] + t[2]) / 3.0).collect();
        let mut nodes = vec![Node {
            bounds: Aabb::EMPTY,
            first: 0,
            count: 0,
        }];
        build_node(&mut nodes, 0, &mut order, 0, &tris, &centroids);
        let tris: Vec<[Vec3; 3]> = order.iter().map(|&i| tris[i as usize]).collect();
        let tri_bounds = tris
            .iter()
            .map(|t| {
                let b = Aabb::EMPTY
                    .union_point(t[0])
                    .union_point(t[1])
                    .union_point(t[2]);
                [Vec3A::from(b.min), Vec3A::from(b.max)]
            })
            .collect();
        let magnitude = tris
            .iter()
            .flatten()
            .map(|v| v.abs().max_element())
            .fold(0.0f32, f32::max);
        Ok(ClosestPointMesh {
            nodes,
            tris,
            uvs: order.iter().map(|&i| corner_uvs[i as usize]).collect(),
            prims: order,
            tri_bounds,
            margin: MARGIN_RELATIVE * magnitude + MARGIN_FLOOR,
        })
    }

    /// The nearest point of the surface to `p`, or `None` for a non-finite `p`.
    #[must_use]
    pub fn nearest(&self, p: Vec3) -> Option<NearestPoint> {
        let mut none = u32::MAX;
        self.nearest_from(p, &mut none)
    }

    /// [`Self::nearest`] starting from the triangle of an earlier answer: `hint` holds the
    /// triangle's slot in this structure (any value, e.g. `u32::MAX`, for none) and is set to
    /// the answer's. Successive queries along one ray are close together, so the old
    /// triangle's distance is a tight first bound and prunes most of the tree.
    #[must_use]
    pub fn nearest_from(&self, p: Vec3, hint: &mut u32) -> Option<NearestPoint> {
        if !p.is_finite() {
            return None;
        }
        let mut best = f32::INFINITY;
        let mut found: Option<(usize, Vec3, [f32; 3])> = None;
        // The hint's slot, or none: visited again in its leaf it would give the same
        // distance, which is not below `best` (best only falls), so it is not recomputed.
        let mut hinted = usize::MAX;
        if let Some(t) = self.tris.get(*hint as usize) {
            let (q, bary) = closest_on_triangle(p, t[0], t[1], t[2]);
            best = (q - p).length_squared();
            found = Some((*hint as usize, q, bary));
            hinted = *hint as usize;
        }
        let mut skip = skip_threshold(best, self.margin);
        let pa = Vec3A::from(p);
        // Nodes still to visit, with their boxes' squared distances (the root's is 0: it is
        // tested against the best distance only through its children).
        let mut stack = [(0u32, 0.0f32); STACK];
        let mut len = 1usize;
        while len > 0 {
            len -= 1;
            let (index, d2) = stack[len];
            if d2 >= best {
                continue;
            }
            let Some(node) = self.nodes.get(index as usize) else {
                continue;
            };
            if node.count > 0 {
                let first = node.first as usize;
                for i in first..first + node.count as usize {
                    let (Some(t), Some(b)) = (self.tris.get(i), self.tri_bounds.get(i)) else {
                        break;
                    };
                    // A triangle whose box is beyond the margin cannot come out strictly
                    // nearer than `best`, so skipping it keeps every answer bit for bit.
                    if i == hinted || box_distance2_simd(b, pa) > skip {
                        continue;
                    }
                    let (q, bary) = closest_on_triangle(p, t[0], t[1], t[2]);
                    let d2 = (q - p).length_squared();
                    if d2 < best {
                        best = d2;
                        skip = skip_threshold(best, self.margin);
                        found = Some((i, q, bary));
                    }
                }
                continue;
            }
            let (l, r) = (node.first, node.first + 1);
            let dist = |i: u32| {
                self.nodes
                    .get(i as usize)
                    .map_or(f32::INFINITY, |n| box_distance2(&n.bounds, p))
            };
            let (dl, dr) = (dist(l), dist(r));
            // The nearer child on top of the stack; children out of reach are not pushed.
            let (near, far) = if dl <= dr {
                ((l, dl), (r, dr))
            } else {
                ((r, dr), (l, dl))
            };
            for child in [far, near] {
                if child.1 < best && len < STACK {
                    stack[len] = child;
                    len += 1;
                }
            }
        }
        let (i, q, bary) = found?;
        *hint = i as u32;
        let uv = self.uvs.get(i)?;
        Some(NearestPoint {
            p: q,
            uv: uv[0] * bary[0] + uv[1] * bary[1] + uv[2] * bary[2],
            distance2: best,
            prim: *self.prims.get(i)?,
        })
    }

    /// Triangles in the mesh.
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }

    /// The mesh's mean texture scale, texture units per world unit: √(Σ UV area / Σ world
    /// area) over its triangles (0 for a mesh whose UVs or triangles span no area).
    #[must_use]
    pub fn mean_uv_scale(&self) -> f32 {
        let (mut uv_area, mut area) = (0.0f64, 0.0f64);
        for (t, uv) in self.tris.iter().zip(&self.uvs) {
            area += f64::from((t[1] - t[0]).cross(t[2] - t[0]).length());
            let (a, b) = (uv[1] - uv[0], uv[2] - uv[0]);
            uv_area += f64::from((a.x * b.y - a.y * b.x).abs());
        }
        if area > 0.0 && uv_area > 0.0 {
            (uv_area / area).sqrt() as f32
        } else {
            0.0
        }
    }
}

/// Builds node `index` over `order[first..]` (its slice is `order`), splitting at the median
/// centroid along the widest axis of the centroids' box.
fn build_node(
    nodes: &mut Vec<Node>,
    index: usize,
    order: &mut [u32],
    first: usize,
    tris: &[[Vec3; 3]],
    centroids: &[Vec3],
) {
    let mut bounds = Aabb::EMPTY;
    let mut cbounds = Aabb::EMPTY;
    for &i in order.iter() {
        let t = tris[i as usize];
        bounds = bounds.union_point(t[0]).union_point(t[1]).union_point(t[2]);
        cbounds = cbounds.union_point(centroids[i as usize]);
    }
    if order.len() <= LEAF_SIZE {
        nodes[index] = Node {
            bounds,
            first: first as u32,
            count: order.len() as u32,
        };
        return;
    }
    let extent = cbounds.max - cbounds.min;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let mid = order.len() / 2;
    order.select_nth_unstable_by(mid, |&a, &b| {
        centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis])
    });
    let left = nodes.len();
    let empty = Node {
        bounds: Aabb::EMPTY,
        first: 0,
        count: 0,
    };
    nodes.push(empty);
    nodes.push(empty);
    nodes[index] = Node {
        bounds,
        first: left as u32,
        count: 0,
    };
    let (lo, hi) = order.split_at_mut(mid);
    build_node(nodes, left, lo, first, tris, centroids);
    build_node(nodes, left + 1, hi, first + mid, tris, centroids);
}

/// Relative part of the skip margin: covers the rounding of the box's squared distance, of the
/// triangle's computed squared distance and of [`skip_threshold`] itself (a few units of f32
/// rounding, 2⁻²⁴ ≈ 6e-8, each; 1e-5 is ~80 of them).
const MARGIN_RELATIVE: f32 = 1e-5;

/// Least absolute margin (world units): keeps the margin's square a normal f32, so that
/// underflow near distance 0 cannot eat it.
const MARGIN_FLOOR: f32 = 1e-18;

/// The squared box distance beyond which a triangle cannot beat `best` (a squared distance):
/// (√best·(1 + 1e-5) + `margin`)². A triangle's computed closest point is a convex combination
/// of its corners up to rounding (weights in [0, 1], summing to at most 1 + 4·2⁻²⁴), so it lies
/// within ~16·2⁻²⁴·M of the triangle's box per axis, M the largest corner coordinate
/// magnitude; `margin` = 1e-5·M is over 40 times that times √3. A box farther than the
/// threshold therefore holds only triangles whose computed squared distance exceeds `best`,
/// never equals it, so skipping them cannot change which triangle wins, ties included.
/// Infinite for an infinite `best` (or a margin whose square overflows): nothing is skipped.
#[inline]
fn skip_threshold(best: f32, margin: f32) -> f32 {
    let r = best.sqrt() * (1.0 + MARGIN_RELATIVE) + margin;
    r * r
}

/// [`box_distance2`] for a box `[min, max]` held in SIMD lanes: the same value up to the order
/// of the final sum, which only the margin-protected triangle skip uses.
#[inline]
fn box_distance2_simd(b: &[Vec3A; 2], p: Vec3A) -> f32 {
    let d = (b[0] - p).max(p - b[1]).max(Vec3A::ZERO);
    d.length_squared()
}

/// Squared distance from `p` to the box (0 inside).
#[inline]
fn box_distance2(b: &Aabb, p: Vec3) -> f32 {
    let d = (b.min - p).max(p - b.max).max(Vec3::ZERO);
    d.length_squared()
}

/// The point of triangle `abc` nearest to `p` and its barycentric coordinates (weights of
/// `a`, `b`, `c`): the Voronoi region of a vertex, an edge or the face contains `p`
/// (Ericson 2005 §5.1.5). Degenerate triangles fall to a vertex or an edge.
#[must_use]
pub fn closest_on_triangle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> (Vec3, [f32; 3]) {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, [1.0, 0.0, 0.0]);
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (b, [0.0, 1.0, 0.0]);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + ab * v, [1.0 - v, v, 0.0]);
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return (c, [0.0, 0.0, 1.0]);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + ac * w, [1.0 - w, 0.0, w]);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w, [0.0, 1.0 - w, w]);
    }
    let denom = va + vb + vc;
    if !(denom.abs() > 0.0) || !denom.is_finite() {
        // A degenerate triangle whose regions did not decide: its first vertex.
        return (a, [1.0, 0.0, 0.0]);
    }
    let v = vb / denom;
    let w = vc / denom;
    (a + ab * v + ac * w, [1.0 - v - w, v, w])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fixed-seed uniform number in [0, 1) for point `i`, dimension `d`.
    fn hash_uniform(seed: u32, i: u32, d: u32) -> f32 {
        let mut x = (seed as u64) << 40 ^ (i as u64) << 8 ^ d as u64;
        x = x.wrapping_mul(0x9E37_79B9_7F4A_7C15);
        x ^= x >> 31;
        x = x.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        x ^= x >> 29;
        (x >> 40) as f32 / (1u64 << 24) as f32
    }

    /// An axis-aligned box mesh [-1,1]×[-0.5,0.5]×[-2,2] with u = x-ish UVs per face.
    fn box_mesh() -> TriangleMesh {
        let (hx, hy, hz) = (1.0f32, 0.5f32, 2.0f32);
        let mut positions = Vec::new();
        let mut uvs = Vec::new();
        let mut indices = Vec::new();
        // Each face: 4 corners, 2 triangles; uv = the corner's x and y scaled into [0, 1].
        let faces: [[Vec3; 4]; 6] = [
            [
                Vec3::new(hx, -hy, -hz),
                Vec3::new(hx, hy, -hz),
                Vec3::new(hx, hy, hz),
                Vec3::new(hx, -hy, hz),
            ],
            [
                Vec3::new(-hx, -hy, -hz),
                Vec3::new(-hx, -hy, hz),
                Vec3::new(-hx, hy, hz),
                Vec3::new(-hx, hy, -hz),
            ],
            [
                Vec3::new(-hx, hy, -hz),
                Vec3::new(-hx, hy, hz),
                Vec3::new(hx, hy, hz),
                Vec3::new(hx, hy, -hz),
            ],
            [
                Vec3::new(-hx, -hy, -hz),
                Vec3::new(hx, -hy, -hz),
                Vec3::new(hx, -hy, hz),
                Vec3::new(-hx, -hy, hz),
            ],
            [
                Vec3::new(-hx, -hy, hz),
                Vec3::new(hx, -hy, hz),
                Vec3::new(hx, hy, hz),
                Vec3::new(-hx, hy, hz),
            ],
            [
                Vec3::new(-hx, -hy, -hz),
                Vec3::new(-hx, hy, -hz),
                Vec3::new(hx, hy, -hz),
                Vec3::new(hx, -hy, -hz),
            ],
        ];
        for f in faces {
            let base = positions.len() as u32;
            for p in f {
                positions.push(p);
                uvs.push(Vec2::new((p.x + hx) / (2.0 * hx), (p.z + hz) / (2.0 * hz)));
            }
            indices.push([base, base + 1, base + 2]);
            indices.push([base, base + 2, base + 3]);
        }
        TriangleMesh {
            positions,
            normals: None,
            uvs: Some(uvs),
            indices,
        }
    }

    fn brute(mesh: &TriangleMesh, p: Vec3) -> f32 {
        mesh.indices
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
                (closest_on_triangle(p, a, b, c).0 - p).length_squared()
            })
            .fold(f32::INFINITY, f32::min)
    }

    #[test]
    fn box_interior_distance_is_the_nearest_face() {
        let mesh = box_mesh();
        let cp = ClosestPointMesh::build(&mesh, "box").unwrap();
        for i in 0..2000u32 {
            let u = |d: u32| hash_uniform(7, i, d);
            let p = Vec3::new(-1.0 + 2.0 * u(0), -0.5 + u(1), -2.0 + 4.0 * u(2));
            let n = cp.nearest(p).unwrap();
            // Closed form inside a box: the distance to the nearest face plane.
            let d = (1.0 - p.x.abs()).min(0.5 - p.y.abs()).min(2.0 - p.z.abs());
            assert!((n.distance2.sqrt() - d).abs() < 1e-5, "{p:?}: {n:?} vs {d}");
            assert!((n.p - p).length() - d < 1e-5);
            // The UV of the projected point is its own (x, z) layout on every face.
            let uv = Vec2::new((n.p.x + 1.0) / 2.0, (n.p.z + 2.0) / 4.0);
            assert!((n.uv - uv).length() < 1e-5, "{p:?}: {:?} vs {uv:?}", n.uv);
        }
    }

    #[test]
    fn bvh_agrees_with_brute_force_on_an_icosphere() {
        let mut mesh = crate::geometry::icosphere(3);
        mesh.uvs = Some(vec![Vec2::ZERO; mesh.positions.len()]);
        let cp = ClosestPointMesh::build(&mesh, "ico").unwrap();
        for i in 0..500u32 {
            let u = |d: u32| 3.0 * hash_uniform(11, i, d) - 1.5;
            let p = Vec3::new(u(0), u(1), u(2));
            let n = cp.nearest(p).unwrap();
            // Starting from any triangle gives the same distance.
            let mut hint = i % 1280;
            assert_eq!(
                cp.nearest_from(p, &mut hint).unwrap().distance2,
                n.distance2
            );
            let b = brute(&mesh, p);
            assert!((n.distance2 - b).abs() <= 1e-6 * b.max(1.0), "{p:?}");
        }
    }

    #[test]
    fn no_uvs_or_no_triangles_is_an_error() {
        let mut mesh = box_mesh();
        mesh.uvs = None;
        let e = ClosestPointMesh::build(&mesh, "box")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("box") && e.contains("texture coordinates"),
            "{e}"
        );
        let empty = TriangleMesh {
            positions: vec![],
            normals: None,
            uvs: Some(vec![]),
            indices: vec![],
        };
        assert!(ClosestPointMesh::build(&empty, "e").is_err());
        assert!(ClosestPointMesh::build(&box_mesh(), "b")
            .unwrap()
            .nearest(Vec3::NAN)
            .is_none());
    }

    /// The box's UVs span the two y faces only (u from x, v from z: the x and z faces map
    /// to lines), each face onto the whole unit square: UV area 2 against a world area of
    /// 2·(2·4) + 2·(1·4) + 2·(2·1) = 28.
    #[test]
    fn mean_uv_scale_is_the_root_of_the_area_ratio() {
        let mesh = ClosestPointMesh::build(&box_mesh(), "b").unwrap();
        let expected = (2.0f32 / 28.0).sqrt();
        let got = mesh.mean_uv_scale();
        assert!(
            (got - expected).abs() < 1e-6 * expected,
            "{got} against {expected}"
        );
    }

    /// The traversal as it was before the per-triangle box test and the hint skip, written out:
    /// every triangle of a visited leaf goes through `closest_on_triangle`.
    fn reference_nearest_from(
        cp: &ClosestPointMesh,
        p: Vec3,
        hint: &mut u32,
    ) -> Option<NearestPoint> {
        if !p.is_finite() {
            return None;
        }
        let mut best = f32::INFINITY;
        let mut found: Option<(usize, Vec3, [f32; 3])> = None;
        if let Some(t) = cp.tris.get(*hint as usize) {
            let (q, bary) = closest_on_triangle(p, t[0], t[1], t[2]);
            best = (q - p).length_squared();
            found = Some((*hint as usize, q, bary));
        }
        let mut stack = vec![(0u32, 0.0f32)];
        while let Some((index, d2)) = stack.pop() {
            if d2 >= best {
                continue;
            }
            let node = cp.nodes[index as usize];
            if node.count > 0 {
                let first = node.first as usize;
                for i in first..first + node.count as usize {
                    let t = cp.tris[i];
                    let (q, bary) = closest_on_triangle(p, t[0], t[1], t[2]);
                    let d2 = (q - p).length_squared();
                    if d2 < best {
                        best = d2;
                        found = Some((i, q, bary));
                    }
                }
                continue;
            }
            let (l, r) = (node.first, node.first + 1);
            let dl = box_distance2(&cp.nodes[l as usize].bounds, p);
            let dr = box_distance2(&cp.nodes[r as usize].bounds, p);
            let (near, far) = if dl <= dr {
                ((l, dl), (r, dr))
            } else {
                ((r, dr), (l, dl))
            };
            for child in [far, near] {
                if child.1 < best {
                    stack.push(child);
                }
            }
        }
        let (i, q, bary) = found?;
        *hint = i as u32;
        let uv = cp.uvs[i];
        Some(NearestPoint {
            p: q,
            uv: uv[0] * bary[0] + uv[1] * bary[1] + uv[2] * bary[2],
            distance2: best,
            prim: cp.prims[i],
        })
    }

    /// Asserts that `nearest_from` from hint `h_new` and the written-out reference from hint
    /// `h_old` give `p` the same answer and leave the same hint, bit for bit.
    fn assert_matches_reference(
        cp: &ClosestPointMesh,
        p: Vec3,
        h_new: &mut u32,
        h_old: &mut u32,
        what: &str,
    ) {
        let new = cp.nearest_from(p, h_new);
        let old = reference_nearest_from(cp, p, h_old);
        assert_eq!(bits(new, *h_new), bits(old, *h_old), "{what}, {p:?}");
    }

    /// Bits of an answer and its hint, for exact comparison (NaN-safe).
    fn bits(n: Option<NearestPoint>, hint: u32) -> Option<([u32; 6], u32, u32)> {
        n.map(|n| {
            (
                [
                    n.p.x.to_bits(),
                    n.p.y.to_bits(),
                    n.p.z.to_bits(),
                    n.uv.x.to_bits(),
                    n.uv.y.to_bits(),
                    n.distance2.to_bits(),
                ],
                n.prim,
                hint,
            )
        })
    }

    /// An irregular mesh: an icosphere with jittered corners, stretched, moved away from the
    /// origin, with slivers (corners pulled onto their neighbours) and varied UVs.
    fn irregular_mesh(offset: Vec3) -> TriangleMesh {
        let mut mesh = crate::geometry::icosphere(3);
        for (i, v) in mesh.positions.iter_mut().enumerate() {
            let u = |d: u32| hash_uniform(5, i as u32, d) - 0.5;
            *v = Vec3::new(v.x * 3.0, v.y * 0.7, v.z * 1.3)
                + Vec3::new(u(0), u(1), u(2)) * 0.2
                + offset;
        }
        // Slivers and degenerate triangles: some corners copied onto, or next to, another.
        for i in (0..mesh.indices.len()).step_by(17) {
            let [a, b, _] = mesh.indices[i];
            let pa = mesh.positions[a as usize];
            mesh.positions[b as usize] = if i % 2 == 0 {
                pa
            } else {
                pa + Vec3::splat(1e-6)
            };
        }
        mesh.uvs = Some(
            (0..mesh.positions.len() as u32)
                .map(|i| Vec2::new(hash_uniform(9, i, 0), hash_uniform(9, i, 1)))
                .collect(),
        );
        mesh
    }

    #[test]
    fn nearest_from_matches_the_unpruned_traversal_bit_for_bit() {
        let mut ico = crate::geometry::icosphere(3);
        ico.uvs = Some(
            ico.positions
                .iter()
                .map(|p| Vec2::new(p.x * 0.5 + 0.5, p.y * 0.5 + 0.5))
                .collect(),
        );
        let meshes = [
            ico,
            irregular_mesh(Vec3::ZERO),
            irregular_mesh(Vec3::new(100.0, -40.0, 7.0)),
            box_mesh(),
        ];
        let mut compared = 0u32;
        for (m, mesh) in meshes.iter().enumerate() {
            let cp = ClosestPointMesh::build(mesh, "m").unwrap();
            let centre = mesh.positions.iter().copied().sum::<Vec3>() / mesh.positions.len() as f32;
            let count = cp.triangle_count() as u32;
            // One walk of successive queries (hints carried over), as along a ray, plus fresh
            // hints: none, out of range and every kind of slot.
            let (mut walk_new, mut walk_old) = (u32::MAX, u32::MAX);
            for i in 0..4000u32 {
                let u = |d: u32| hash_uniform(31 + m as u32, i, d) - 0.5;
                // Near (within 0.05 of a corner), inside/around, and far (up to 200 away).
                let scale = match i % 4 {
                    0 => 0.1,
                    1 => 4.0,
                    2 => 12.0,
                    _ => 400.0,
                };
                let base = if i % 4 == 0 {
                    mesh.positions[(i as usize * 7) % mesh.positions.len()]
                } else {
                    centre
                };
                let p = base + Vec3::new(u(0), u(1), u(2)) * scale;
                for start in [u32::MAX, count, i % count, (i * 13 + 5) % count] {
                    let (mut h_new, mut h_old) = (start, start);
                    let what = format!("mesh {m}, hint {start}");
                    assert_matches_reference(&cp, p, &mut h_new, &mut h_old, &what);
                    compared += 1;
                }
                let what = format!("mesh {m}, walk");
                assert_matches_reference(&cp, p, &mut walk_new, &mut walk_old, &what);
                // Points along a short ray from p: the case the hint serves.
                for k in 1..4 {
                    let q = p + Vec3::new(u(3), u(4), u(5)) * (0.02 * k as f32);
                    assert_matches_reference(&cp, q, &mut walk_new, &mut walk_old, &what);
                }
            }
            assert!(cp.nearest_from(Vec3::INFINITY, &mut walk_new).is_none());
        }
        assert_eq!(compared, 4 * 4000 * 4);
    }

    /// The skip threshold never excludes a triangle that would tie or win: with `best` set to
    /// a triangle's own computed squared distance, its box's squared distance stays at or
    /// under the threshold — for random, sliver and far-off triangles and points near them.
    #[test]
    fn skip_threshold_never_excludes_a_tying_triangle() {
        let (mut tightest, mut nan) = (f32::INFINITY, 0u32);
        for i in 0..200_000u32 {
            let u = |d: u32| hash_uniform(77, i, d) - 0.5;
            let offset = Vec3::new(u(0), u(1), u(2)) * [1.0, 50.0, 1000.0][i as usize % 3];
            let size = [1e-3, 1.0, 30.0][(i / 3) as usize % 3];
            let a = offset + Vec3::new(u(3), u(4), u(5)) * size;
            let mut b = offset + Vec3::new(u(6), u(7), u(8)) * size;
            let c = offset + Vec3::new(u(9), u(10), u(11)) * size;
            if i % 5 == 0 {
                b = a + (c - a) * u(12).abs(); // a sliver: b on the segment ac (up to rounding)
            }
            let reach = [1e-4, 1e-2, 1.0, 100.0][(i / 9) as usize % 4];
            let p = a + Vec3::new(u(13), u(14), u(15)) * reach;
            let (q, _) = closest_on_triangle(p, a, b, c);
            let d2 = (q - p).length_squared();
            if d2.is_nan() {
                // A degenerate edge's 0/0: NaN never compares below `best`, so never wins.
                nan += 1;
                continue;
            }
            let magnitude = [a, b, c]
                .iter()
                .map(|v| v.abs().max_element())
                .fold(0.0f32, f32::max);
            let margin = MARGIN_RELATIVE * magnitude + MARGIN_FLOOR;
            let bounds = Aabb::EMPTY.union_point(a).union_point(b).union_point(c);
            let box2 = box_distance2(&bounds, p);
            let simd = [Vec3A::from(bounds.min), Vec3A::from(bounds.max)];
            let box2 = box2.max(box_distance2_simd(&simd, Vec3A::from(p)));
            let threshold = skip_threshold(d2, margin);
            assert!(
                box2 <= threshold,
                "{a:?} {b:?} {c:?} {p:?}: {box2} > {threshold}"
            );
            if d2 > 0.0 {
                tightest = tightest.min(threshold / d2);
            }
        }
        // The margin is a margin, not a free pass: thresholds stay close to `best` for far points.
        assert!(tightest < 1.001, "{tightest}");
        assert!(nan < 2_000, "{nan}");
        assert_eq!(skip_threshold(f32::INFINITY, 1.0), f32::INFINITY);
    }
}
