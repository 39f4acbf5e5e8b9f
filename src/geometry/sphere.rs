//! Numerically careful ray–sphere intersection (Haines, Günther & Akenine-Möller 2019,
//! "Precision Improvements for Ray/Sphere Intersection", Ray Tracing Gems ch. 7).

use crate::math::{Ray, Vec2, Vec3, INV_PI};

/// A hit on an analytic sphere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereHit {
    /// Distance along the ray (> 0).
    pub t: f32,
    /// Hit point, re-projected onto the sphere.
    pub p: Vec3,
    /// Unit outward (radial) normal.
    pub n: Vec3,
    /// `(φ/2π, θ/π)`, θ measured from +y, φ = atan2(z, x) in [0, 2π).
    pub uv: Vec2,
}

/// Intersects `ray` (unit direction) with the sphere `(center, radius)`, returning the
/// nearest hit with `0 < t < t_max`, from outside or inside.
///
/// The discriminant is computed from the perpendicular vector `f − (f·d)d` rather than
/// `b² − c` (no cancellation for distant spheres), and the near root uses the stable
/// quadratic form `c/q` (Haines et al. 2019, eqs. 7.8–7.11 with `a = 1`).
#[must_use]
pub fn intersect_sphere(ray: &Ray, center: Vec3, radius: f32, t_max: f32) -> Option<SphereHit> {
    sphere_candidate(ray, center, radius, t_max).map(|c| c.finish(center, radius))
}

/// The part of [`intersect_sphere`] that decides whether and where `ray` hits the sphere
/// (the distance and the offset of the hit point from the centre): a closest-hit search
/// over several shapes finishes the hit record ([`SphereCandidate::finish`]) only for the
/// nearest, and an occlusion test not at all. `intersect_sphere` is this and `finish`, so
/// either way the record is the same bit for bit.
#[must_use]
#[inline]
pub fn sphere_candidate(
    ray: &Ray,
    center: Vec3,
    radius: f32,
    t_max: f32,
) -> Option<SphereCandidate> {
    let f = ray.o - center;
    let b = -f.dot(ray.d);
    let l = f + b * ray.d;
    let l_len = l.length();
    // r² − |l|² as a product of sum and difference (one rounding on the small factor).
    let disc = (radius - l_len) * (radius + l_len);
    if disc.is_nan() || disc < 0.0 {
        return None;
    }
    let f_len = f.length();
    let c = (f_len - radius) * (f_len + radius);
    let q = b + disc.sqrt().copysign(b);
    if q == 0.0 {
        return None;
    }
    let mut t0 = c / q;
    let mut t1 = q;
    if t0 > t1 {
        std::mem::swap(&mut t0, &mut t1);
    }
    let t = if t0 > 0.0 && t0 < t_max {
        t0
    } else if t1 > 0.0 && t1 < t_max {
        t1
    } else {
        return None;
    };
    let dir = ray.at(t) - center;
    let len = dir.length();
    if len.is_nan() || len <= 0.0 {
        return None;
    }
    Some(SphereCandidate { t, dir, len })
}

/// A sphere hit found by [`sphere_candidate`] whose record is not made yet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereCandidate {
    /// Distance along the ray (> 0).
    pub t: f32,
    /// `ray.at(t) − center`.
    dir: Vec3,
    /// `dir.length()`, finite and positive.
    len: f32,
}

impl SphereCandidate {
    /// The candidate with distance `t`, offset `dir = ray.at(t) − center` and its length
    /// `len` (finite and positive), as the lanes of [`super::sphere_lanes`] compute them.
    #[inline(always)]
    pub(super) fn from_parts(t: f32, dir: Vec3, len: f32) -> SphereCandidate {
        SphereCandidate { t, dir, len }
    }

    /// Every field as bits (tests compare candidates bit for bit).
    #[cfg(test)]
    pub(super) fn bits(&self) -> [u32; 5] {
        [
            self.t.to_bits(),
            self.dir.x.to_bits(),
            self.dir.y.to_bits(),
            self.dir.z.to_bits(),
            self.len.to_bits(),
        ]
    }

    /// The hit record of [`intersect_sphere`] on the sphere `(center, radius)` the candidate
    /// was found on.
    #[must_use]
    pub fn finish(self, center: Vec3, radius: f32) -> SphereHit {
        let (p, n) = self.point_and_normal(center, radius);
        SphereHit {
            t: self.t,
            p,
            n,
            uv: sphere_uv(n),
        }
    }

    /// The record's hit point (re-projected onto the sphere `(center, radius)`) and unit
    /// radial normal, without the texture coordinates: [`SphereCandidate::finish`] is these
    /// and [`sphere_uv`] of the normal, so a record whose uv is read later from the normal
    /// has the same bits.
    #[must_use]
    #[inline]
    pub fn point_and_normal(self, center: Vec3, radius: f32) -> (Vec3, Vec3) {
        let n = self.dir / self.len;
        (center + n * radius, n)
    }
}

/// A sphere hit's texture coordinates `(φ/2π, θ/π)` from its unit radial normal `n`: θ
/// measured from +y, φ = atan2(z, x) in [0, 2π) (u kept below 1).
#[must_use]
pub fn sphere_uv(n: Vec3) -> Vec2 {
    let phi = {
        let a = n.z.atan2(n.x);
        if a < 0.0 {
            a + 2.0 * std::f32::consts::PI
        } else {
            a
        }
    };
    let theta = n.y.clamp(-1.0, 1.0).acos();
    Vec2::new(
        (phi * 0.5 * INV_PI).min(1.0 - f32::EPSILON * 0.5),
        theta * INV_PI,
    )
}
