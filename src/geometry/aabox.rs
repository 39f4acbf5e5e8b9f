//! Ray intersection with an analytic axis-aligned box (the slab method, Kay & Kajiya 1986), for
//! boxes that bound a volume (the `bounds` shape): one test instead of twelve triangles through
//! the BVH. The hit point lies exactly on the face plane; the normal is the face's outward axis.

use crate::math::{Ray, Vec2, Vec3};
use glam::Vec3A;

/// A hit on an axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxHit {
    /// Distance along the ray (> 0).
    pub t: f32,
    /// Hit point, with the face's coordinate set exactly to the plane.
    pub p: Vec3,
    /// Unit outward normal of the face hit (± a coordinate axis).
    pub n: Vec3,
    /// Position on the face in [0, 1]², along the face's two other axes in x, y, z order.
    pub uv: Vec2,
}

/// Intersects `ray` with the box `[min, max]`, returning the nearest hit with `0 < t < t_max`:
/// the entry face from outside, the exit face from inside.
///
/// The six slab distances are computed as two 4-wide divisions (the same IEEE operations as
/// one division per plane, so the result is bit-identical to the per-axis loop); rays parallel
/// to an axis take the per-axis path, which tests the origin against that slab instead.
#[must_use]
#[inline]
pub fn intersect_box(ray: &Ray, min: Vec3, max: Vec3, t_max: f32) -> Option<BoxHit> {
    let (o, d) = (Vec3A::from(ray.o), Vec3A::from(ray.d));
    if d.cmpeq(Vec3A::ZERO).any() {
        return intersect_box_axis_parallel(ray, min, max, t_max);
    }
    let a = (Vec3A::from(min) - o) / d;
    let b = (Vec3A::from(max) - o) / d;
    let a_first = a.cmple(b);
    let lo = Vec3A::select(a_first, a, b);
    let hi = Vec3A::select(a_first, b, a);
    // The first axis wins ties, as in the per-axis loop.
    let (mut t_near, mut near_axis) = (lo.x, 0usize);
    if lo.y > t_near {
        t_near = lo.y;
        near_axis = 1;
    }
    if lo.z > t_near {
        t_near = lo.z;
        near_axis = 2;
    }
    let (mut t_far, mut far_axis) = (hi.x, 0usize);
    if hi.y < t_far {
        t_far = hi.y;
        far_axis = 1;
    }
    if hi.z < t_far {
        t_far = hi.z;
        far_axis = 2;
    }
    box_hit(ray, min, max, t_max, (t_near, near_axis), (t_far, far_axis))
}

/// [`intersect_box`] for a ray with a zero direction component: per axis, a slab the ray
/// does not cross either contains the origin or misses it.
#[cold]
#[inline(never)]
fn intersect_box_axis_parallel(ray: &Ray, min: Vec3, max: Vec3, t_max: f32) -> Option<BoxHit> {
    let (mut t_near, mut near_axis) = (f32::NEG_INFINITY, 0usize);
    let (mut t_far, mut far_axis) = (f32::INFINITY, 0usize);
    for k in 0..3 {
        let (o, d) = (ray.o[k], ray.d[k]);
        if d == 0.0 {
            if o < min[k] || o > max[k] {
                return None;
            }
            continue;
        }
        let (a, b) = ((min[k] - o) / d, (max[k] - o) / d);
        let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
        if lo > t_near {
            t_near = lo;
            near_axis = k;
        }
        if hi < t_far {
            t_far = hi;
            far_axis = k;
        }
    }
    box_hit(ray, min, max, t_max, (t_near, near_axis), (t_far, far_axis))
}

/// The hit from the slab interval `[t_near, t_far]` and the axes that bound it.
#[inline]
fn box_hit(
    ray: &Ray,
    min: Vec3,
    max: Vec3,
    t_max: f32,
    (t_near, near_axis): (f32, usize),
    (t_far, far_axis): (f32, usize),
) -> Option<BoxHit> {
    if !(t_near <= t_far) {
        return None;
    }
    let (t, axis, entering) = if t_near > 0.0 && t_near < t_max {
        (t_near, near_axis, true)
    } else if t_far > 0.0 && t_far < t_max {
        (t_far, far_axis, false)
    } else {
        return None;
    };
    let d = ray.d[axis];
    // Entering through the face the ray moves towards, leaving through the opposite one.
    let at_max = (d > 0.0) != entering;
    let mut p = ray.at(t);
    p[axis] = if at_max { max[axis] } else { min[axis] };
    let p = p.clamp(min, max);
    let mut n = Vec3::ZERO;
    n[axis] = if at_max { 1.0 } else { -1.0 };
    let extent = (max - min).max(Vec3::splat(f32::MIN_POSITIVE));
    let rel = (p - min) / extent;
    let (u, v) = match axis {
        0 => (rel.y, rel.z),
        1 => (rel.x, rel.z),
        _ => (rel.x, rel.y),
    };
    Some(BoxHit {
        t,
        p,
        n,
        uv: Vec2::new(u, v),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    /// The per-axis slab loop [`intersect_box`] replaced (kept as the oracle).
    fn reference(ray: &Ray, min: Vec3, max: Vec3, t_max: f32) -> Option<BoxHit> {
        let (mut t_near, mut near_axis) = (f32::NEG_INFINITY, 0usize);
        let (mut t_far, mut far_axis) = (f32::INFINITY, 0usize);
        for k in 0..3 {
            let (o, d) = (ray.o[k], ray.d[k]);
            if d == 0.0 {
                if o < min[k] || o > max[k] {
                    return None;
                }
                continue;
            }
            let (a, b) = ((min[k] - o) / d, (max[k] - o) / d);
            let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
            if lo > t_near {
                t_near = lo;
                near_axis = k;
            }
            if hi < t_far {
                t_far = hi;
                far_axis = k;
            }
        }
        box_hit(ray, min, max, t_max, (t_near, near_axis), (t_far, far_axis))
    }

    fn bits(h: Option<BoxHit>) -> Option<[u32; 9]> {
        h.map(|h| {
            [
                h.t.to_bits(),
                h.p.x.to_bits(),
                h.p.y.to_bits(),
                h.p.z.to_bits(),
                h.n.x.to_bits(),
                h.n.y.to_bits(),
                h.n.z.to_bits(),
                h.uv.x.to_bits(),
                h.uv.y.to_bits(),
            ]
        })
    }

    #[test]
    fn matches_the_per_axis_loop_bit_for_bit() {
        let mut rng = Rng::new(11, 3);
        let (min, max) = (Vec3::new(-0.5, -0.25, -1.0), Vec3::new(0.5, 0.75, 0.125));
        let mut hits = 0;
        for i in 0..200_000 {
            let mut o =
                Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 4.0 - Vec3::splat(2.0);
            let mut d = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - Vec3::ONE;
            // Axis-parallel rays, rays starting on a face and ties between slabs.
            match i % 7 {
                0 => d[i % 3] = 0.0,
                1 => {
                    o[(i / 7) % 3] = if i % 2 == 0 {
                        min[(i / 7) % 3]
                    } else {
                        max[(i / 7) % 3]
                    }
                }
                2 => {
                    d = Vec3::new(1.0, 1.0, 1.0) * if i % 2 == 0 { 1.0 } else { -1.0 };
                    o = Vec3::splat(-3.0 + 6.0 * (i % 2) as f32);
                }
                3 => d = Vec3::new(0.0, 0.0, d.z.signum()),
                _ => {}
            }
            let ray = Ray::new(o, d);
            let t_max = if i % 5 == 0 { 1.5 } else { f32::INFINITY };
            let (new, old) = (
                intersect_box(&ray, min, max, t_max),
                reference(&ray, min, max, t_max),
            );
            hits += usize::from(old.is_some());
            assert_eq!(bits(new), bits(old), "ray {i}: {ray:?}");
        }
        assert!(hits > 20_000, "{hits} hits");
    }
}
