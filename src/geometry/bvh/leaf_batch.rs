//! The triangles of every leaf a ray enters at one node, tested together four at a time
//! ([`ShearedRay::intersect4`]) instead of one by one in order of the leaves' entry
//! distances. One triangle test per lane replaces a data-dependent branch per triangle
//! (hit or miss, nearer or not) with one per four triangles.
//!
//! The answer is the one-by-one traversal's: the closest hit below `t_max`, which the
//! ordered visit also finds (a leaf it skips lies wholly beyond its current hit, the node
//! test being conservative). Where that order could matter — two hits at exactly the same
//! distance, or an edge function exactly zero (the exact path of the one-triangle test) —
//! the batch answers "unsure" and the caller visits the leaves one by one as before.

use glam::Vec4;

use super::SceneGeometry;
use crate::geometry::triangle::{ShearedRay, TriangleHit};
use crate::geometry::wide_bvh::MAX_ENTERED_PRIMITIVES;

/// What a batch of triangles gives.
pub(super) enum Batch {
    /// No triangle hit below `t_max`.
    Miss,
    /// The closest hit (BVH position, hit), unique at its distance.
    Hit(usize, TriangleHit),
    /// Ties or exact zeros: visit the leaves one by one.
    Unsure,
}

/// Four vertices `(x, y, z, _)` transposed to their x, y and z lanes.
#[inline(always)]
fn transpose(r: [Vec4; 4]) -> [Vec4; 3] {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{
            __m128, _mm_movehl_ps, _mm_movelh_ps, _mm_unpackhi_ps, _mm_unpacklo_ps,
        };
        let [r0, r1, r2, r3] = r.map(__m128::from);
        // SAFETY: SSE is part of the x86-64 baseline; these are register shuffles.
        unsafe {
            let t0 = _mm_unpacklo_ps(r0, r1); // x0 x1 y0 y1
            let t1 = _mm_unpacklo_ps(r2, r3); // x2 x3 y2 y3
            let t2 = _mm_unpackhi_ps(r0, r1); // z0 z1 _ _
            let t3 = _mm_unpackhi_ps(r2, r3); // z2 z3 _ _
            [
                Vec4::from(_mm_movelh_ps(t0, t1)),
                Vec4::from(_mm_movehl_ps(t1, t0)),
                Vec4::from(_mm_movelh_ps(t2, t3)),
            ]
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        [
            Vec4::new(r[0].x, r[1].x, r[2].x, r[3].x),
            Vec4::new(r[0].y, r[1].y, r[2].y, r[3].y),
            Vec4::new(r[0].z, r[1].z, r[2].z, r[3].z),
        ]
    }
}

impl SceneGeometry {
    /// Four triangles (BVH positions) tested at once; lanes from `valid` on are ignored.
    #[inline(always)]
    fn test4(
        &self,
        sr: &ShearedRay,
        quad: [u32; 4],
        valid: usize,
        t_max: f32,
    ) -> crate::geometry::triangle::Hits4 {
        let vert = |v: u32| self.verts.get(v as usize).copied().unwrap_or(Vec4::ZERO);
        let lane = |p: u32| -> [Vec4; 3] {
            let [a, b, c] = self.tris.get(p as usize).copied().unwrap_or([0; 3]);
            [vert(a), vert(b), vert(c)]
        };
        let (l0, l1, l2, l3) = (lane(quad[0]), lane(quad[1]), lane(quad[2]), lane(quad[3]));
        let vertex = |k: usize| transpose([l0[k], l1[k], l2[k], l3[k]]);
        let valid = (1u32 << valid.min(4)) - 1;
        sr.intersect4(&vertex(0), &vertex(1), &vertex(2), valid, t_max)
    }

    /// The closest hit with `0 < t < t_max` among the triangles at `positions`.
    #[inline(always)]
    pub(super) fn closest_in(
        &self,
        sr: &ShearedRay,
        positions: &Positions,
        n: usize,
        t_max: f32,
    ) -> Batch {
        let mut best_t = t_max;
        let mut best: Option<(usize, TriangleHit)> = None;
        let mut tie = false;
        for base in (0..n).step_by(4) {
            let quad = quad_at(positions, base);
            let h = self.test4(sr, quad, n - base, t_max);
            if h.unsure != 0 {
                return Batch::Unsure;
            }
            let mut m = h.hit;
            while m != 0 {
                let lane = m.trailing_zeros() as usize;
                m &= m - 1;
                let hit = h.lane(lane);
                if hit.t < best_t {
                    best_t = hit.t;
                    best = Some((quad[lane & 3] as usize, hit));
                    tie = false;
                } else if hit.t == best_t {
                    tie = true;
                }
            }
        }
        match best {
            _ if tie => Batch::Unsure,
            Some((p, hit)) => Batch::Hit(p, hit),
            None => Batch::Miss,
        }
    }

    /// Whether any triangle at `positions` is hit with `0 < t < t_max`; `None` when unsure
    /// (no sure hit, and an edge function exactly zero).
    #[inline(always)]
    pub(super) fn any_in(
        &self,
        sr: &ShearedRay,
        positions: &Positions,
        n: usize,
        t_max: f32,
    ) -> Option<bool> {
        let mut unsure = false;
        for base in (0..n).step_by(4) {
            let h = self.test4(sr, quad_at(positions, base), n - base, t_max);
            if h.hit != 0 {
                return Some(true);
            }
            unsure |= h.unsure != 0;
        }
        (!unsure).then_some(false)
    }
}

/// The four positions from `base` (a multiple of four below the buffer's length).
#[inline(always)]
fn quad_at(positions: &Positions, base: usize) -> [u32; 4] {
    let m = MAX_ENTERED_PRIMITIVES - 1;
    [
        positions[base & m],
        positions[(base + 1) & m],
        positions[(base + 2) & m],
        positions[(base + 3) & m],
    ]
}

/// Positions buffer for one node's entered leaves.
pub(super) type Positions = [u32; MAX_ENTERED_PRIMITIVES];
