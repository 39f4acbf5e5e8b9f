//! Up to four analytic spheres tested against one ray at once, in SSE lanes, with the IEEE
//! operations of [`sphere_candidate`] per lane, so that every lane's answer is the scalar
//! test's bit for bit (`tests::lanes_match_sphere_candidate_bit_for_bit`).
//!
//! A scene whose analytic shapes are all spheres (the eye's three nested media and its
//! light, the cloth's floor and ball) tests them in blocks of four instead of one by one:
//! the closest-hit query's loop over spheres was a third of its cost on the eye.

use glam::{BVec4A, Vec4};

use super::sphere::SphereCandidate;
use crate::math::{Ray, Vec3};

/// Four spheres, one per lane; unused lanes have a NaN radius (no hit).
#[derive(Clone, Copy, Debug)]
pub(super) struct SphereBlock {
    cx: Vec4,
    cy: Vec4,
    cz: Vec4,
    r: Vec4,
}

/// The lanes' answers: which lanes hit with `0 < t < t_max` and what
/// [`sphere_candidate`] found there.
#[derive(Clone, Copy, Debug)]
pub(super) struct LaneCandidates {
    /// Bit `i` set when lane `i` hits.
    pub hits: u32,
    t: Vec4,
    dx: Vec4,
    dy: Vec4,
    dz: Vec4,
    /// The offset's squared length (`dir · dir`, glam's order); its square root, the
    /// candidate's length, is taken for the lanes read only ([`LaneCandidates::candidate`]).
    len2: Vec4,
}

/// Lane-wise square root: `sqrtps` (correctly rounded, as `f32::sqrt`) where SSE is the
/// baseline, else glam's per-lane `sqrt`.
#[inline(always)]
fn sqrt4(v: Vec4) -> Vec4 {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    {
        // SAFETY: SSE2 is enabled at compile time (the cfg above).
        unsafe { Vec4::from(std::arch::x86_64::_mm_sqrt_ps(v.into())) }
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
    {
        v.sqrt()
    }
}

/// `(x·x' + y·y') + z·z'` per lane: glam's `Vec3::dot` order.
#[inline(always)]
fn dot3(ax: Vec4, ay: Vec4, az: Vec4, bx: Vec4, by: Vec4, bz: Vec4) -> Vec4 {
    (ax * bx + ay * by) + az * bz
}

impl SphereBlock {
    /// The blocks holding `spheres` (`(center, radius)`) in order, four to a block, the last
    /// padded with NaN radii.
    pub(super) fn blocks(spheres: &[(Vec3, f32)]) -> Vec<SphereBlock> {
        spheres
            .chunks(4)
            .map(|chunk| {
                let lane = |k: usize| chunk.get(k).copied().unwrap_or((Vec3::ZERO, f32::NAN));
                let [a, b, c, d] = [0, 1, 2, 3].map(lane);
                SphereBlock {
                    cx: Vec4::new(a.0.x, b.0.x, c.0.x, d.0.x),
                    cy: Vec4::new(a.0.y, b.0.y, c.0.y, d.0.y),
                    cz: Vec4::new(a.0.z, b.0.z, c.0.z, d.0.z),
                    r: Vec4::new(a.1, b.1, c.1, d.1),
                }
            })
            .collect()
    }

    /// [`sphere_candidate`] of `ray` against the four spheres with bound `t_max`.
    #[inline(always)]
    pub(super) fn candidates(&self, ray: &Ray, t_max: f32) -> LaneCandidates {
        let (ox, oy, oz) = (
            Vec4::splat(ray.o.x),
            Vec4::splat(ray.o.y),
            Vec4::splat(ray.o.z),
        );
        let (dx, dy, dz) = (
            Vec4::splat(ray.d.x),
            Vec4::splat(ray.d.y),
            Vec4::splat(ray.d.z),
        );
        let r = self.r;
        let (fx, fy, fz) = (ox - self.cx, oy - self.cy, oz - self.cz);
        let b = -dot3(fx, fy, fz, dx, dy, dz);
        let (lx, ly, lz) = (fx + b * dx, fy + b * dy, fz + b * dz);
        let l_len = sqrt4(dot3(lx, ly, lz, lx, ly, lz));
        let disc = (r - l_len) * (r + l_len);
        // `!(disc.is_nan() || disc < 0)`.
        let mut ok: BVec4A = disc.cmpge(Vec4::ZERO);
        let f_len = sqrt4(dot3(fx, fy, fz, fx, fy, fz));
        let c = (f_len - r) * (f_len + r);
        let q = b + sqrt4(disc).copysign(b);
        // `!(q == 0)` (true for NaN, as in the scalar test).
        ok &= q.cmpne(Vec4::ZERO);
        let t0 = c / q;
        let swap = t0.cmpgt(q);
        let (lo, hi) = (Vec4::select(swap, q, t0), Vec4::select(swap, t0, q));
        let bound = Vec4::splat(t_max);
        let pick_lo = lo.cmpgt(Vec4::ZERO) & lo.cmplt(bound);
        let pick_hi = hi.cmpgt(Vec4::ZERO) & hi.cmplt(bound);
        ok &= pick_lo | pick_hi;
        let t = Vec4::select(pick_lo, lo, hi);
        // `ray.at(t) − center` and its squared length.
        let (px, py, pz) = (
            (ox + dx * t) - self.cx,
            (oy + dy * t) - self.cy,
            (oz + dz * t) - self.cz,
        );
        let len2 = dot3(px, py, pz, px, py, pz);
        // `!(len.is_nan() || len <= 0)` for `len = √len2`: `√x > 0` exactly when `x > 0`
        // (NaN and negative `x` have a NaN root, ±0 its own, and every positive `x`, the
        // least subnormal included, a positive one). The root is taken for the lanes read.
        ok &= len2.cmpgt(Vec4::ZERO);
        LaneCandidates {
            hits: ok.bitmask(),
            t,
            dx: px,
            dy: py,
            dz: pz,
            len2,
        }
    }
}

impl LaneCandidates {
    /// Lane `i`'s distance (meaningful where [`LaneCandidates::hits`] has bit `i`).
    #[inline(always)]
    pub(super) fn t(&self, i: usize) -> f32 {
        self.t[i]
    }

    /// Lane `i`'s candidate, as [`sphere_candidate`] returns it for that sphere.
    #[inline(always)]
    pub(super) fn candidate(&self, i: usize) -> SphereCandidate {
        // `f32::sqrt` is correctly rounded, as `sqrtps` is: the length the scalar test takes.
        SphereCandidate::from_parts(
            self.t[i],
            Vec3::new(self.dx[i], self.dy[i], self.dz[i]),
            self.len2[i].sqrt(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::super::sphere::sphere_candidate;
    use super::*;
    use crate::sampling::{sample_uniform_sphere, Rng};

    /// The lanes' hit test on the squared length is the scalar test on the length (`√x > 0`
    /// exactly when `x > 0`), and `sqrtps` is `f32::sqrt`, over every 4099th bit pattern
    /// and the special values (the candidate's length is the scalar root of the lane's).
    #[test]
    fn squared_length_test_and_roots_match_the_scalar_root() {
        let specials = [
            0.0f32,
            -0.0,
            f32::from_bits(1),
            f32::MIN_POSITIVE,
            f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -f32::from_bits(1),
        ];
        let sweep = (0..=u32::MAX / 4099).map(|k| f32::from_bits(k * 4099));
        let (mut positive, mut other) = (0, 0);
        for x in specials.into_iter().chain(sweep) {
            assert_eq!(x > 0.0, x.sqrt() > 0.0, "{x:e} ({:#x})", x.to_bits());
            let (lane, scalar) = (sqrt4(Vec4::splat(x)).x, x.sqrt());
            assert!(
                lane.to_bits() == scalar.to_bits() || (lane.is_nan() && scalar.is_nan()),
                "{x:e}: {lane:e} {scalar:e}"
            );
            if x > 0.0 {
                positive += 1;
            } else {
                other += 1;
            }
        }
        assert!(positive > 400_000 && other > 400_000, "{positive} {other}");
    }

    /// Every lane's answer against `sphere_candidate` of its sphere alone, bit for bit (hit or
    /// not, `t`, the offset and its length), on rays from inside, outside and on the spheres,
    /// tangent rays, origins at a centre (the degenerate length), bounds cutting hits off,
    /// huge and tiny spheres and non-finite bounds.
    #[test]
    fn lanes_match_sphere_candidate_bit_for_bit() {
        let mut rng = Rng::new(19, 7);
        let (mut hits, mut misses, mut far_roots) = (0, 0, 0);
        for n in 0..40_000 {
            let count = 1 + n % 6;
            let spheres: Vec<(Vec3, f32)> = (0..count)
                .map(|k| {
                    let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 4.0
                        - Vec3::splat(2.0);
                    let r = match k {
                        0 if n % 5 == 0 => 1.0e4,
                        1 if n % 7 == 0 => 1.0e-3,
                        _ => 0.05 + 1.5 * rng.next_f32(),
                    };
                    let c = if k == 0 && n % 5 == 0 {
                        c - Vec3::new(0.0, 1.0e4, 0.0)
                    } else {
                        c
                    };
                    (c, r)
                })
                .collect();
            let d = sample_uniform_sphere(rng.next_2d());
            let o = match n % 4 {
                // At a centre: the offset of the hit is `t·d`, fine; but from the centre
                // along a ray missing nothing.
                0 => spheres[0].0,
                // On a sphere's surface.
                1 => {
                    spheres[count - 1].0
                        + sample_uniform_sphere(rng.next_2d()) * spheres[count - 1].1
                }
                _ => {
                    Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 6.0
                        - Vec3::splat(3.0)
                }
            };
            // Tangent rays: aimed at a point on the sphere perpendicular to the radius.
            let ray = if n % 9 == 0 {
                let (c, r) = spheres[0];
                let side = d.cross(Vec3::Y).normalize_or(Vec3::X);
                let p = c + side * r;
                Ray::new(p - d * 3.0, d)
            } else {
                Ray::new(o, d)
            };
            let t_max = match n % 5 {
                0 => f32::INFINITY,
                1 => 0.7,
                2 => f32::NAN,
                _ => 2.0 + 3.0 * rng.next_f32(),
            };
            for (b, block) in SphereBlock::blocks(&spheres).iter().enumerate() {
                let lanes = block.candidates(&ray, t_max);
                for i in 0..4 {
                    let want = spheres
                        .get(4 * b + i)
                        .and_then(|&(c, r)| sphere_candidate(&ray, c, r, t_max));
                    let got = (lanes.hits & (1 << i) != 0).then(|| lanes.candidate(i));
                    assert_eq!(
                        got.map(|g| g.bits()),
                        want.map(|w| w.bits()),
                        "ray {n}: {ray:?}, lane {i} of block {b}, t_max {t_max}"
                    );
                    match want {
                        Some(w) => {
                            hits += 1;
                            assert_eq!(lanes.t(i).to_bits(), w.t.to_bits());
                            let (c, r) = spheres[4 * b + i];
                            // The far root: the origin inside the sphere.
                            far_roots += usize::from((ray.o - c).length() < r);
                        }
                        None => misses += 1,
                    }
                }
            }
        }
        assert!(
            hits > 15_000 && misses > 20_000 && far_roots > 3_000,
            "{hits} {misses} {far_roots}"
        );
    }
}
