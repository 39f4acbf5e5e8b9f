//! Indexed triangle meshes: transforms, bounds and topology checks.

use std::collections::HashMap;
use std::hash::BuildHasherDefault;

use crate::grid::CoordHasher;
use crate::math::{Aabb, Mat3, Mat4, Vec2, Vec3};

use super::GeometryError;

/// An indexed triangle mesh. Triangles are wound counter-clockwise seen from the side their
/// geometric normal `(p1 − p0) × (p2 − p0)` points to.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleMesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Optional per-vertex normals (same length as `positions`).
    pub normals: Option<Vec<Vec3>>,
    /// Optional per-vertex texture coordinates (same length as `positions`).
    pub uvs: Option<Vec<Vec2>>,
    /// Triangles as vertex indices.
    pub indices: Vec<[u32; 3]>,
}

/// Edge statistics of a mesh, computed on vertices welded by exact position (split UV-seam
/// vertices count as one), ignoring triangles with a repeated vertex.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MeshTopology {
    /// Undirected edges.
    pub edges: usize,
    /// Edges used by exactly one triangle (holes).
    pub boundary_edges: usize,
    /// Edges used by more than two triangles.
    pub non_manifold_edges: usize,
    /// Edges used by two triangles with the same orientation (inconsistent winding).
    pub inconsistent_edges: usize,
    /// Triangles skipped because two of their indices are equal.
    pub degenerate_triangles: usize,
}

impl MeshTopology {
    /// Every edge shared by exactly two triangles with opposite orientation.
    #[must_use]
    pub fn is_closed(&self) -> bool {
        self.edges > 0
            && self.boundary_edges == 0
            && self.non_manifold_edges == 0
            && self.inconsistent_edges == 0
    }
}

impl std::fmt::Display for MeshTopology {
    /// A one-line summary for warnings, e.g. "open: 12 boundary edges, 0 non-manifold
    /// edges, 0 inconsistently wound edges (of 3000 edges)".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: {} boundary edges, {} non-manifold edges, {} inconsistently wound edges (of {} edges)",
            if self.is_closed() { "closed" } else { "open" },
            self.boundary_edges,
            self.non_manifold_edges,
            self.inconsistent_edges,
            self.edges
        )
    }
}

impl TriangleMesh {
    /// Checks internal consistency: attribute lengths, index range, finite values.
    /// `shape` is the index reported in the error.
    pub fn validate(&self, shape: usize) -> Result<(), GeometryError> {
        let n = self.positions.len();
        let bad = |message: String| Err(GeometryError::InvalidShape { shape, message });
        if self.indices.is_empty() {
            return bad("mesh has no triangles".to_string());
        }
        if let Some(ns) = &self.normals {
            if ns.len() != n {
                return bad(format!("{} normals for {} positions", ns.len(), n));
            }
        }
        if let Some(uv) = &self.uvs {
            if uv.len() != n {
                return bad(format!("{} uvs for {} positions", uv.len(), n));
            }
        }
        if let Some(i) = self.positions.iter().position(|p| !p.is_finite()) {
            return bad(format!("vertex {i} has a non-finite position"));
        }
        if let Some(i) = self
            .positions
            .iter()
            .position(|p| p.abs().max_element() > MAX_COORDINATE)
        {
            return bad(format!(
                "vertex {i} lies beyond ±{MAX_COORDINATE:e} (world units)"
            ));
        }
        for (f, tri) in self.indices.iter().enumerate() {
            if let Some(&i) = tri.iter().find(|&&i| i as usize >= n) {
                return bad(format!(
                    "triangle {f} refers to vertex {i} but there are only {n} vertices"
                ));
            }
        }
        Ok(())
    }

    /// Applies the affine transform `m`: positions by `m`, normals by the inverse transpose
    /// of its linear part (renormalised); the winding is reversed when `det(m) < 0` so that
    /// geometric normals keep pointing to the same side of the surface.
    pub fn transform(&mut self, m: Mat4) {
        for p in &mut self.positions {
            *p = m.transform_point3(*p);
        }
        let l = Mat3::from_mat4(m);
        let det = l.determinant();
        if let Some(ns) = &mut self.normals {
            let nm = l.inverse().transpose();
            for n in ns.iter_mut() {
                *n = (nm * *n).normalize_or_zero();
            }
        }
        if det < 0.0 {
            for t in &mut self.indices {
                t.swap(1, 2);
            }
        }
    }

    /// Returns a transformed copy (see [`TriangleMesh::transform`]).
    #[must_use]
    pub fn transformed(&self, m: Mat4) -> TriangleMesh {
        let mut c = self.clone();
        c.transform(m);
        c
    }

    /// Bounding box of the vertices referenced by triangles (all vertices if none are).
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        let mut b = Aabb::EMPTY;
        for p in &self.positions {
            b = b.union_point(*p);
        }
        b
    }

    /// Edge statistics (see [`MeshTopology`]).
    #[must_use]
    pub fn topology(&self) -> MeshTopology {
        // Weld by exact position so that seam-split vertices with identical coordinates (which
        // the watertight intersector treats as one) share edges.
        // Integer keys hashed by multiply-rotate (the counts do not depend on the map's order).
        let mut weld: HashMap<(u32, u32, u32), u32, BuildHasherDefault<CoordHasher>> =
            HashMap::with_capacity_and_hasher(self.positions.len(), Default::default());
        let canon: Vec<u32> = self
            .positions
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let key = (bits(p.x), bits(p.y), bits(p.z));
                *weld.entry(key).or_insert(i as u32)
            })
            .collect();
        let mut topo = MeshTopology::default();
        // Directed-edge counts keyed by the undirected edge: (count a<b, count b<a).
        let mut edges: HashMap<(u32, u32), (u32, u32), BuildHasherDefault<CoordHasher>> =
            HashMap::with_capacity_and_hasher(self.indices.len() * 2, Default::default());
        for tri in &self.indices {
            let v = tri.map(|i| canon.get(i as usize).copied().unwrap_or(u32::MAX));
            if v[0] == v[1] || v[1] == v[2] || v[0] == v[2] || v.contains(&u32::MAX) {
                topo.degenerate_triangles += 1;
                continue;
            }
            for k in 0..3 {
                let (a, b) = (v[k], v[(k + 1) % 3]);
                let e = edges.entry((a.min(b), a.max(b))).or_insert((0, 0));
                if a < b {
                    e.0 += 1;
                } else {
                    e.1 += 1;
                }
            }
        }
        topo.edges = edges.len();
        for &(f, b) in edges.values() {
            match f + b {
                1 => topo.boundary_edges += 1,
                2 => {
                    if f != 1 {
                        topo.inconsistent_edges += 1;
                    }
                }
                _ => topo.non_manifold_edges += 1,
            }
        }
        topo
    }

    /// True when every edge is shared by exactly two triangles with opposite orientation
    /// (a watertight, consistently wound 2-manifold; vertices welded by exact position).
    #[must_use]
    pub fn is_closed(&self) -> bool {
        self.topology().is_closed()
    }

    /// Signed enclosed volume `Σ p0·(p1×p2)/6` (divergence theorem), accumulated in f64
    /// about the bounding-box centre; positive when the winding makes normals point outward.
    /// Meaningful for closed meshes only.
    #[must_use]
    pub fn signed_volume(&self) -> f32 {
        let c = self.bounds().center();
        let c = if c.is_finite() {
            c.as_dvec3()
        } else {
            glam::DVec3::ZERO
        };
        let mut vol = 0.0f64;
        for tri in &self.indices {
            let get = |i: u32| self.positions.get(i as usize).map(|p| p.as_dvec3() - c);
            if let (Some(a), Some(b), Some(d)) = (get(tri[0]), get(tri[1]), get(tri[2])) {
                vol += a.dot(b.cross(d));
            }
        }
        (vol / 6.0) as f32
    }

    /// Reverses the winding of every triangle when the signed volume is negative, so that
    /// geometric normals of a closed mesh point outward.
    pub fn make_outward(&mut self) {
        if self.signed_volume() < 0.0 {
            for t in &mut self.indices {
                t.swap(1, 2);
            }
        }
    }

    /// Total surface area (world units squared).
    #[must_use]
    pub fn area(&self) -> f32 {
        let mut a = 0.0f64;
        for tri in &self.indices {
            let p = tri.map(|i| {
                self.positions
                    .get(i as usize)
                    .copied()
                    .unwrap_or(Vec3::ZERO)
            });
            a += f64::from((p[1] - p[0]).cross(p[2] - p[0]).length()) * 0.5;
        }
        a as f32
    }
}

/// Largest accepted coordinate magnitude: beyond it f32 spacing exceeds 1e8 units and box
/// arithmetic in the BVH could overflow.
pub(crate) const MAX_COORDINATE: f32 = 1e15;

fn bits(x: f32) -> u32 {
    // +0 and -0 weld together.
    if x == 0.0 {
        0
    } else {
        x.to_bits()
    }
}
