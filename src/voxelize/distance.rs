//! Exact unsigned distances from voxel centres to a triangle soup, in a narrow band: triangles
//! are binned into the 8³ bricks they can reach, and each brick takes the minimum point–triangle
//! distance (closest point on the triangle, Ericson, "Real-Time Collision Detection" §5.1.5)
//! over its bin, in index units (voxels).

use glam::{DVec3, IVec3};
use rayon::prelude::*;

use crate::grid::{BRICK_DIM, BRICK_VOXELS};

/// Half the diagonal of a brick's voxel centres: 3.5 √3 voxels.
const BRICK_HALF_DIAGONAL: f64 = 3.5 * 1.732_050_807_568_877_2;

/// Closest point to `p` on the segment `a–b`.
fn closest_on_segment(p: DVec3, a: DVec3, b: DVec3) -> DVec3 {
    let ab = b - a;
    let l2 = ab.length_squared();
    if l2 <= 0.0 {
        return a;
    }
    a + ab * ((p - a).dot(ab) / l2).clamp(0.0, 1.0)
}

/// Squared distance from `p` to the triangle `t` (Ericson's Voronoi-region walk; degenerate
/// triangles fall back to their three edges).
#[must_use]
pub fn point_triangle_distance_sq(p: DVec3, t: &[DVec3; 3]) -> f64 {
    let [a, b, c] = *t;
    let ab = b - a;
    let ac = c - a;
    let n2 = ab.cross(ac).length_squared();
    if n2 <= 1e-30 * (ab.length_squared() * ac.length_squared()).max(f64::MIN_POSITIVE) {
        let q = [
            closest_on_segment(p, a, b),
            closest_on_segment(p, b, c),
            closest_on_segment(p, c, a),
        ];
        return q
            .iter()
            .map(|q| (p - *q).length_squared())
            .fold(f64::INFINITY, f64::min);
    }
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.length_squared();
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return bp.length_squared();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (p - (a + ab * v)).length_squared();
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return cp.length_squared();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (p - (a + ac * w)).length_squared();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (p - (b + (c - b) * w)).length_squared();
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    (p - (a + ab * v + ac * w)).length_squared()
}

/// Unsigned distances (voxels) of one brick's 512 voxel centres, in voxel order
/// `(x << 6) | (y << 3) | z`; `f32::INFINITY` where no triangle lies within the reach.
#[derive(Clone, Debug)]
pub(crate) struct BrickDistances {
    /// Brick key (voxel coordinate >> 3).
    pub key: IVec3,
    /// Distances in voxels.
    pub d: Box<[f32; BRICK_VOXELS]>,
}

/// Distances of every brick within `reach` voxels of a triangle, sorted by brick key.
pub(crate) fn band_distances(tris: &[[DVec3; 3]], reach: f64) -> Vec<BrickDistances> {
    // (brick key, triangle) pairs: every brick whose voxel centres may lie within `reach`.
    let mut pairs: Vec<([i32; 3], u32)> = tris
        .par_iter()
        .enumerate()
        .flat_map_iter(|(i, t)| {
            let lo = t[0].min(t[1]).min(t[2]) - DVec3::splat(reach);
            let hi = t[0].max(t[1]).max(t[2]) + DVec3::splat(reach);
            let k0 = (lo / f64::from(BRICK_DIM)).floor().as_ivec3();
            let k1 = (hi / f64::from(BRICK_DIM)).floor().as_ivec3();
            let limit = (reach + BRICK_HALF_DIAGONAL + 1e-9).powi(2);
            let mut out = Vec::new();
            for x in k0.x..=k1.x {
                for y in k0.y..=k1.y {
                    for z in k0.z..=k1.z {
                        let c = IVec3::new(x, y, z).as_dvec3() * f64::from(BRICK_DIM)
                            + DVec3::splat(3.5);
                        if point_triangle_distance_sq(c, t) <= limit {
                            out.push(([x, y, z], i as u32));
                        }
                    }
                }
            }
            out
        })
        .collect();
    pairs.par_sort_unstable();
    // Group boundaries.
    let mut starts = Vec::new();
    for (i, p) in pairs.iter().enumerate() {
        if i == 0 || pairs.get(i - 1).is_some_and(|q| q.0 != p.0) {
            starts.push(i);
        }
    }
    starts.push(pairs.len());
    let reach2 = reach * reach;
    starts
        .par_windows(2)
        .map(|w| {
            let group = pairs.get(w[0]..w[1]).unwrap_or(&[]);
            let key = IVec3::from_array(group.first().map_or([0; 3], |g| g.0));
            let origin = (key * BRICK_DIM).as_dvec3();
            let mut d = Box::new([f32::INFINITY; BRICK_VOXELS]);
            for (v, out) in d.iter_mut().enumerate() {
                let local = DVec3::new((v >> 6) as f64, ((v >> 3) & 7) as f64, (v & 7) as f64);
                let p = origin + local;
                let mut best = f64::INFINITY;
                for &(_, t) in group {
                    if let Some(tri) = tris.get(t as usize) {
                        best = best.min(point_triangle_distance_sq(p, tri));
                    }
                }
                if best < reach2 {
                    *out = best.sqrt() as f32;
                }
            }
            BrickDistances { key, d }
        })
        .collect()
}
