//! `floor` of patch index coordinates as integers, three lanes at once.
//!
//! Every fabric lookup floors its patch point (and the point half a voxel on, for the nearest
//! tangent): `f32 as i32` casts are saturating in Rust, which the compiler writes as a
//! truncation plus a NaN and a range fix-up per lane. Here the three lanes share one SSE2
//! truncation (`cvttps2dq`, part of the x86-64 baseline) and the same fix-ups as vector masks:
//! the same integers as the scalar casts for every input, NaN and out-of-range values included.

use glam::{IVec3, Vec3};

/// `p.floor().as_ivec3()` without a libm call (the x86-64 baseline has no rounding
/// instruction): the same result for every `p` within the `i32` range (saturating outside
/// it; NaN gives 0, as the cast does). Below −2³¹ the correction step wraps (to `i32::MAX`)
/// as the scalar form's subtraction does in release builds.
#[inline(always)]
#[must_use]
pub fn floor_ivec3(p: Vec3) -> IVec3 {
    #[cfg(target_arch = "x86_64")]
    {
        floor_ivec3_sse2(p)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        floor_ivec3_scalar(p)
    }
}

/// The scalar form: truncation toward zero (saturating, NaN to 0), one less where that
/// rounded up. It is the grid's [`crate::grid::floor_frac`]'s integer part, the one scalar
/// algorithm both layers use.
#[cfg(any(test, not(target_arch = "x86_64")))]
#[inline(always)]
#[must_use]
pub fn floor_ivec3_scalar(p: Vec3) -> IVec3 {
    crate::grid::floor_frac(p).0
}

/// [`floor_ivec3_scalar`] in SSE2 lanes. `cvttps2dq` truncates toward zero and gives
/// `i32::MIN` for NaN and for values outside the `i32` range; the saturating cast gives
/// `i32::MAX` for values at or above 2³¹ (flipping every bit of `i32::MIN`) and 0 for NaN
/// (masked by the ordered compare). Values at or below −2³¹ already give `i32::MIN`. The
/// correction adds the all-ones mask of `t > p` (−1), wrapping as the scalar form does.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
#[must_use]
fn floor_ivec3_sse2(p: Vec3) -> IVec3 {
    use std::arch::x86_64::{
        _mm_add_epi32, _mm_and_si128, _mm_castps_si128, _mm_cmpge_ps, _mm_cmpgt_ps, _mm_cmpord_ps,
        _mm_cvtepi32_ps, _mm_cvttps_epi32, _mm_set1_ps, _mm_setr_ps, _mm_xor_si128,
    };
    // SAFETY: SSE2 is part of the x86-64 baseline; these intrinsics only compute on
    // registers.
    let lanes: [i32; 4] = unsafe {
        let v = _mm_setr_ps(p.x, p.y, p.z, 0.0);
        let t = _mm_cvttps_epi32(v);
        let big = _mm_castps_si128(_mm_cmpge_ps(v, _mm_set1_ps(2_147_483_648.0)));
        let t = _mm_and_si128(_mm_xor_si128(t, big), _mm_castps_si128(_mm_cmpord_ps(v, v)));
        let above = _mm_castps_si128(_mm_cmpgt_ps(_mm_cvtepi32_ps(t), v));
        std::mem::transmute(_mm_add_epi32(t, above))
    };
    IVec3::new(lanes[0], lanes[1], lanes[2])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    /// The lane form gives the scalar form's integers for random coordinates of every
    /// magnitude, integers and their neighbours, ±0, subnormals, the `i32` range's edges,
    /// infinities and NaN.
    #[test]
    fn lane_floor_equals_the_scalar_casts() {
        let edges = [
            0.0f32,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            1e-40,
            -1e-40,
            0.999_999_94,
            -0.999_999_94,
            8_388_607.5,
            -8_388_607.5,
            16_777_216.0,
            2_147_483_520.0,
            -2_147_483_520.0,
            2_147_483_648.0,
            -2_147_483_648.0,
            -2_147_483_904.0,
            4.0e9,
            -4.0e9,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -f32::NAN,
        ];
        let mut cases = Vec::new();
        for &a in &edges {
            for &b in &edges {
                cases.push(Vec3::new(a, b, 0.25));
                cases.push(Vec3::new(-3.5, a, b));
            }
        }
        let mut rng = Rng::new(23, 0);
        for _ in 0..200_000 {
            let scale = 2.0f32.powi((rng.next_f32() * 70.0) as i32 - 20);
            let r = |rng: &mut Rng| (rng.next_f32() * 2.0 - 1.0) * scale;
            cases.push(Vec3::new(r(&mut rng), r(&mut rng), r(&mut rng)));
            let n = (rng.next_f32() * 4000.0 - 2000.0).round();
            cases.push(Vec3::new(n, n.next_up(), n.next_down()));
        }
        let (mut below, mut saturated) = (0, 0);
        for p in cases {
            let want = floor_ivec3_scalar(p);
            assert_eq!(floor_ivec3(p), want, "{p:?}");
            below += usize::from(p.x < 0.0 && p.x != p.x.trunc());
            saturated += usize::from(want.x == i32::MAX || want.x == i32::MIN);
        }
        // Negative non-integers (the correction) and saturated lanes were both exercised.
        assert!(below > 50_000 && saturated > 100, "{below} {saturated}");
    }
}
