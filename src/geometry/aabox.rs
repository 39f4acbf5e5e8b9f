//! Ray intersection with an analytic axis-aligned box (the slab method, Kay & Kajiya 1986), for
//! boxes that bound a volume (the `bounds` shape): one test instead of twelve triangles through
//! the BVH. The hit point lies exactly on the face plane; the normal is the face's outward axis.

use glam::Vec3A;

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

/// One slab of the slab test: the ray's entry and exit distances across the planes
/// `lo`, `hi` of axis `k` narrow `near` and `far` (distance, axis). False when the ray runs
/// parallel to the slab outside it.
#[inline(always)]
fn slab(
    o: f32,
    d: f32,
    lo: f32,
    hi: f32,
    k: usize,
    near: &mut (f32, usize),
    far: &mut (f32, usize),
) -> bool {
    if d == 0.0 {
        return !(o < lo || o > hi);
    }
    let (a, b) = ((lo - o) / d, (hi - o) / d);
    let (enter, leave) = if a <= b { (a, b) } else { (b, a) };
    if enter > near.0 {
        *near = (enter, k);
    }
    if leave < far.0 {
        *far = (leave, k);
    }
    true
}

/// Intersects `ray` with the box `[min, max]`, returning the nearest hit with `0 < t < t_max`:
/// the entry face from outside, the exit face from inside.
#[must_use]
#[inline(always)]
pub fn intersect_box(ray: &Ray, min: Vec3, max: Vec3, t_max: f32) -> Option<BoxHit> {
    // The three slabs written out by axis (indexing a `Vec3` by a loop variable compiles to
    // a branch per access); the same operations in the same order as a loop over the axes.
    let mut near = (f32::NEG_INFINITY, 0usize);
    let mut far = (f32::INFINITY, 0usize);
    let (o, d) = (ray.o, ray.d);
    if !(slab(o.x, d.x, min.x, max.x, 0, &mut near, &mut far)
        && slab(o.y, d.y, min.y, max.y, 1, &mut near, &mut far)
        && slab(o.z, d.z, min.z, max.z, 2, &mut near, &mut far))
    {
        return None;
    }
    let ((t_near, near_axis), (t_far, far_axis)) = (near, far);
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
    let d_axis = match axis {
        0 => d.x,
        1 => d.y,
        _ => d.z,
    };
    // Entering through the face the ray moves towards, leaving through the opposite one.
    let at_max = (d_axis > 0.0) != entering;
    let face = if at_max { max } else { min };
    let sign = if at_max { 1.0 } else { -1.0 };
    let mut p = ray.at(t);
    let n = match axis {
        0 => {
            p.x = face.x;
            Vec3::new(sign, 0.0, 0.0)
        }
        1 => {
            p.y = face.y;
            Vec3::new(0.0, sign, 0.0)
        }
        _ => {
            p.z = face.z;
            Vec3::new(0.0, 0.0, sign)
        }
    };
    let p = p.clamp(min, max);
    let extent = (max - min).max(Vec3::splat(f32::MIN_POSITIVE));
    Some(BoxHit {
        t,
        p,
        n,
        uv: face_uv((p - min) / extent, axis),
    })
}

/// [`intersect_box`] for a ray with a finite origin and direction, in 4-wide lanes: the six
/// slab distances by two vector divisions, the entry and exit distances as the largest and
/// smallest lanes (the written-out slabs' chains of strict comparisons give the same values for
/// lanes without NaN), and the face's axis as the first lane that holds the distance chosen.
/// Every lane performs the operations of the scalar form in the same order, and SSE's
/// `min`/`max` pick the same operand as glam's scalar ones (the second unless the first is
/// strictly smaller/larger), so the hit is the same bit for bit
/// (`tests::lanes_match_the_written_out_slabs_bit_for_bit`). `min`, `max`: the box's corners.
#[must_use]
#[inline(always)]
pub fn intersect_box_lanes(ray: &Ray, min: Vec3A, max: Vec3A, t_max: f32) -> Option<BoxHit> {
    let (o, d) = (Vec3A::from(ray.o), Vec3A::from(ray.d));
    // A ray parallel to a slab misses unless it runs inside it; such a slab constrains nothing.
    let parallel = d.cmpeq(Vec3A::ZERO);
    if (parallel & (o.cmplt(min) | o.cmpgt(max))).any() {
        return None;
    }
    let (a, b) = ((min - o) / d, (max - o) / d);
    // The nearer and farther slab plane per lane: lanes that are not parallel hold no NaN, so
    // `min`/`max` give the written-out slabs' `a <= b` choice, up to the sign of a zero when
    // `a == b` (a zero distance is never a hit's: see below).
    let enter = Vec3A::select(parallel, Vec3A::NEG_INFINITY, a.min(b));
    let leave = Vec3A::select(parallel, Vec3A::INFINITY, a.max(b));
    // No lane is NaN (a finite ray's slab distances are quotients of a finite difference by
    // a nonzero finite component, parallel lanes are ±∞), so the largest entry and the
    // smallest exit are the written-out chains' values whatever the order of the lanes'
    // comparisons: equal lanes hold the same float, up to the sign of a zero, and a zero is
    // only compared below (with `t_far`, with 0), never returned.
    let t_near = enter.max_element();
    let t_far = leave.min_element();
    // `!(t_near <= t_far)`: empty, or unordered.
    if !matches!(
        t_near.partial_cmp(&t_far),
        Some(std::cmp::Ordering::Less | std::cmp::Ordering::Equal)
    ) {
        return None;
    }
    let (t, lanes, entering) = if t_near > 0.0 && t_near < t_max {
        (t_near, enter, true)
    } else if t_far > 0.0 && t_far < t_max {
        (t_far, leave, false)
    } else {
        return None;
    };
    // The written-out slabs keep the first axis that reached the final distance (a later
    // equal one does not replace it); `t` is finite and positive, so only slabs that are not
    // parallel can hold it.
    let (axis, d_axis) = match lanes.cmpeq(Vec3A::splat(t)).bitmask().trailing_zeros() {
        0 => (0, d.x),
        1 => (1, d.y),
        _ => (2, d.z),
    };
    // Entering through the face the ray moves towards, leaving through the opposite one.
    let at_max = (d_axis > 0.0) != entering;
    let face = if at_max { max } else { min };
    let on_axis = glam::BVec3A::new(axis == 0, axis == 1, axis == 2);
    let p = Vec3A::select(on_axis, face, o + d * t).clamp(min, max);
    let sign = if at_max { 1.0 } else { -1.0 };
    let n = Vec3A::select(on_axis, Vec3A::splat(sign), Vec3A::ZERO);
    let rel = (p - min) / (max - min).max(Vec3A::splat(f32::MIN_POSITIVE));
    Some(BoxHit {
        t,
        p: p.into(),
        n: n.into(),
        uv: face_uv(rel.into(), axis),
    })
}

/// The texture coordinates on the face across `axis` of the point at `rel` (its position in
/// the box, 0 to 1 per axis): the two other axes in order.
#[inline(always)]
fn face_uv(rel: Vec3, axis: usize) -> Vec2 {
    match axis {
        0 => Vec2::new(rel.y, rel.z),
        1 => Vec2::new(rel.x, rel.z),
        _ => Vec2::new(rel.x, rel.y),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    /// The slab test as a loop over the axes (the form before the axes were written out).
    fn by_loop(ray: &Ray, min: Vec3, max: Vec3, t_max: f32) -> Option<BoxHit> {
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
        let at_max = (ray.d[axis] > 0.0) != entering;
        let mut p = ray.at(t);
        p[axis] = if at_max { max[axis] } else { min[axis] };
        let p = p.clamp(min, max);
        let mut n = Vec3::ZERO;
        n[axis] = if at_max { 1.0 } else { -1.0 };
        let rel = (p - min) / (max - min).max(Vec3::splat(f32::MIN_POSITIVE));
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

    fn bits(h: Option<BoxHit>) -> Option<[u32; 9]> {
        h.map(|h| {
            [
                h.t, h.p.x, h.p.y, h.p.z, h.n.x, h.n.y, h.n.z, h.uv.x, h.uv.y,
            ]
            .map(f32::to_bits)
        })
    }

    #[test]
    fn lanes_match_the_written_out_slabs_bit_for_bit() {
        let mut rng = Rng::new(23, 8);
        // A box with zero coordinates (signed zeros in the clamp), a thin one, a large one.
        let boxes = [
            (Vec3::new(-0.5, -0.25, -1.0), Vec3::new(0.5, 0.75, 0.3)),
            (Vec3::new(0.0, -1.0, 0.0), Vec3::new(1.0, 0.0, 2.0)),
            (Vec3::new(-1.0, 0.2, -1.0), Vec3::new(1.0, 0.2 + 1e-6, 1.0)),
            (Vec3::splat(-3.0e4), Vec3::new(2.0e4, 1.0e5, 3.0e4)),
        ];
        let (mut hits, mut ties) = ([0usize; 2], 0usize);
        for n in 0..400_000 {
            let (min, max) = boxes[n % boxes.len()];
            let size = max - min;
            let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            let mut o = min - size + u * size * 3.0;
            let mut d = crate::sampling::sample_uniform_sphere(rng.next_2d());
            let k = (n / 8) % 3;
            // Axis-parallel and diagonal rays, rays from the faces, edges and corners, and
            // origins at zero.
            match (n / 4) % 10 {
                0 => d[k] = 0.0,
                1 => d[k] = -0.0,
                2 => o[k] = if n % 2 == 0 { min[k] } else { max[k] },
                3 => o = if n % 2 == 0 { min } else { max },
                4 => {
                    o[k] = min[k];
                    o[(k + 1) % 3] = max[(k + 1) % 3];
                }
                5 => o[k] = 0.0,
                6 => {
                    // Diagonals through a corner: equal slab distances on several axes.
                    let c = if n % 2 == 0 { min } else { max };
                    d = Vec3::new(
                        if rng.next_f32() < 0.5 { 1.0 } else { -1.0 },
                        if rng.next_f32() < 0.5 { 1.0 } else { -1.0 },
                        if rng.next_f32() < 0.5 { 1.0 } else { -1.0 },
                    );
                    o = c - d * (1.0 + rng.next_f32());
                }
                7 => d = Vec3::ZERO.with_x(if n % 2 == 0 { 1.0 } else { -1.0 }),
                _ => {}
            }
            let d = if d == Vec3::ZERO { Vec3::Y } else { d };
            let ray = Ray { o, d };
            let t_max = match n % 5 {
                0 => f32::INFINITY,
                1 => size.length() * rng.next_f32(),
                2 => f32::MIN_POSITIVE,
                _ => 10.0 * size.max_element(),
            };
            let want = intersect_box(&ray, min, max, t_max);
            assert_eq!(
                bits(intersect_box_lanes(&ray, min.into(), max.into(), t_max)),
                bits(want),
                "ray {n}: {ray:?}, box {min} {max}, t_max {t_max}"
            );
            if let Some(h) = want {
                hits[usize::from(h.n.dot(d) > 0.0)] += 1;
                let t = |m: Vec3, k: usize| (m[k] - o[k]) / d[k];
                let slabs = [0, 1, 2].map(|k| [t(min, k), t(max, k)]);
                ties += usize::from(
                    slabs
                        .iter()
                        .flatten()
                        .filter(|&&v| v.to_bits() == h.t.to_bits())
                        .count()
                        > 1,
                );
            }
        }
        assert!(hits[0] > 10_000 && hits[1] > 10_000, "{hits:?}");
        // Hits at equal distances on two slabs, where the first axis must win.
        assert!(ties > 500, "{ties} ties");
    }

    #[test]
    fn written_out_slabs_match_the_loop_bit_for_bit() {
        let mut rng = Rng::new(11, 5);
        let (min, max) = (Vec3::new(-0.5, -0.25, -1.0), Vec3::new(0.5, 0.75, 0.3));
        let mut hits = [0usize; 2];
        for n in 0..200_000 {
            let mut o =
                Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 4.0 - Vec3::splat(2.0);
            let mut d = crate::sampling::sample_uniform_sphere(rng.next_2d());
            // Axis-parallel rays, rays from the faces and from the corners.
            match n % 8 {
                0 => d[(n / 8) % 3] = 0.0,
                1 => {
                    o[(n / 8) % 3] = if n % 16 == 1 {
                        min[(n / 8) % 3]
                    } else {
                        max[(n / 8) % 3]
                    }
                }
                2 => o = if n % 16 == 2 { min } else { max },
                _ => {}
            }
            let d = d.normalize_or_zero();
            let ray = Ray::new(o, d);
            let t_max = if n % 5 == 0 { 1.0 } else { f32::INFINITY };
            let want = by_loop(&ray, min, max, t_max);
            assert_eq!(
                bits(intersect_box(&ray, min, max, t_max)),
                bits(want),
                "ray {n}"
            );
            if let Some(h) = want {
                hits[usize::from(h.n.dot(d) > 0.0)] += 1;
            }
        }
        // Both entry and exit faces were tested.
        assert!(hits[0] > 5_000 && hits[1] > 5_000, "{hits:?}");
    }
}
