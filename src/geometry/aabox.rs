//! Ray intersection with an analytic axis-aligned box (the slab method, Kay & Kajiya 1986), for
//! boxes that bound a volume (the `bounds` shape): one test instead of twelve triangles through
//! the BVH. The hit point lies exactly on the face plane; the normal is the face's outward axis.

use crate::math::{Ray, Vec2, Vec3};

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
#[must_use]
pub fn intersect_box(ray: &Ray, min: Vec3, max: Vec3, t_max: f32) -> Option<BoxHit> {
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
