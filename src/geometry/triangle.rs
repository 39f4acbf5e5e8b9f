//! Watertight ray–triangle intersection (Woop, Benthin & Wald 2013, "Watertight Ray/Triangle
//! Intersection", JCGT 2(1)) with exact tie-breaking on shared edges and vertices.

use glam::{Vec4, Vec4Swizzles};

use crate::math::{Ray, Vec3};

/// Barycentric hit on one triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    /// Distance along the ray (> 0).
    pub t: f32,
    /// Barycentric weight of the first vertex.
    pub b0: f32,
    /// Barycentric weight of the second vertex.
    pub b1: f32,
    /// Barycentric weight of the third vertex.
    pub b2: f32,
}

/// A triangle's vertices transposed for the watertight test: `v[k]` holds coordinate `k` of
/// the three vertices in lanes 0, 1, 2 (lane 3 repeats vertex 0), so the per-ray axis
/// permutation is an indexed load instead of a branch per coordinate.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub(crate) struct TriangleSoa {
    v: [Vec4; 3],
}

impl TriangleSoa {
    pub(crate) fn new(p0: Vec3, p1: Vec3, p2: Vec3) -> Self {
        let lane = |k: usize| Vec4::new(p0[k], p1[k], p2[k], p0[k]);
        TriangleSoa {
            v: [lane(0), lane(1), lane(2)],
        }
    }

    /// The same triangle from three vertices stored as `(x, y, z, _)` (the compact layout:
    /// shared vertices and indices), transposed in registers. Lanes 0–2 hold exactly the
    /// values [`TriangleSoa::new`] stores, so the test gives bit-identical hits; lane 3 is
    /// never read by [`ShearedRay::intersect`].
    #[inline(always)]
    pub(crate) fn from_vertices(a: Vec4, b: Vec4, c: Vec4) -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{
                __m128, _mm_movehl_ps, _mm_movelh_ps, _mm_unpackhi_ps, _mm_unpacklo_ps,
            };
            let (a, b, c) = (__m128::from(a), __m128::from(b), __m128::from(c));
            // SAFETY: SSE is part of the x86-64 baseline; these are register shuffles.
            unsafe {
                let ab_lo = _mm_unpacklo_ps(a, b); // ax bx ay by
                let ab_hi = _mm_unpackhi_ps(a, b); // az bz aw bw
                let ca_lo = _mm_unpacklo_ps(c, a); // cx ax cy ay
                let ca_hi = _mm_unpackhi_ps(c, a); // cz az cw aw
                TriangleSoa {
                    v: [
                        Vec4::from(_mm_movelh_ps(ab_lo, ca_lo)), // ax bx cx ax
                        Vec4::from(_mm_movehl_ps(ca_lo, ab_lo)), // ay by cy ay
                        Vec4::from(_mm_movelh_ps(ab_hi, ca_hi)), // az bz cz az
                    ],
                }
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            TriangleSoa {
                v: [
                    Vec4::new(a.x, b.x, c.x, a.x),
                    Vec4::new(a.y, b.y, c.y, a.y),
                    Vec4::new(a.z, b.z, c.z, a.z),
                ],
            }
        }
    }
}

/// Per-ray constants of the watertight test: the dominant axis `kz`, the two others in an
/// order that keeps the winding, and the shear that maps the ray to `+z` from the origin.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ShearedRay {
    kx: usize,
    ky: usize,
    kz: usize,
    /// Origin coordinates `o[kx]`, `o[ky]`, `o[kz]`, splatted.
    okx: Vec4,
    oky: Vec4,
    okz: Vec4,
    /// `sx`, `sy` splatted.
    sxv: Vec4,
    syv: Vec4,
    sz: f32,
}

impl ShearedRay {
    #[inline]
    pub(crate) fn new(ray: &Ray) -> Self {
        let a = ray.d.abs();
        // (kz, kx, ky) for a positive `d[kz]`; a negative one swaps kx and ky (the winding).
        let (kz, kx, ky) = if a.x >= a.y && a.x >= a.z {
            (0, 1, 2)
        } else if a.y >= a.z {
            (1, 2, 0)
        } else {
            (2, 0, 1)
        };
        // Read from the ray itself (not from a copy of its components).
        let d: &[f32; 3] = ray.d.as_ref();
        let o: &[f32; 3] = ray.o.as_ref();
        let (kx, ky) = if d[kz] < 0.0 { (ky, kx) } else { (kx, ky) };
        // `d[kx] / d[kz]`, `d[ky] / d[kz]` and `1 / d[kz]` in one vector division (the same
        // IEEE quotients as three scalar ones).
        let s = Vec4::new(d[kx], d[ky], 1.0, 1.0) / Vec4::splat(d[kz]);
        ShearedRay {
            kx,
            ky,
            kz,
            okx: Vec4::splat(o[kx]),
            oky: Vec4::splat(o[ky]),
            okz: Vec4::splat(o[kz]),
            sxv: Vec4::splat(s.x),
            syv: Vec4::splat(s.y),
            sz: s.z,
        }
    }

    /// The watertight test. Edge functions are evaluated as `E(P,Q) = Qx·Py − Qy·Px` on
    /// sheared vertex coordinates that depend only on the vertex and the ray, so the two
    /// triangles sharing an edge see exactly negated values; exact zeros are re-evaluated in
    /// f64 (exact for products of f32) and then resolved by a symbolic perturbation of the
    /// ray origin by `(ε, ε²)`, which assigns a point on a shared edge or vertex to exactly
    /// one of the triangles around it. The three vertices are processed in SIMD lanes with
    /// exactly the scalar operations of the paper, so results are bit-identical to a scalar
    /// evaluation.
    #[inline(always)]
    pub(crate) fn intersect(&self, tri: &TriangleSoa, t_max: f32) -> Option<TriangleHit> {
        debug_assert!(self.kx < 3 && self.ky < 3 && self.kz < 3);
        // SAFETY: `kx`, `ky` and `kz` are a permutation of 0, 1, 2 (set by `new`).
        let (vx, vy, vz) = unsafe {
            (
                *tri.v.get_unchecked(self.kx),
                *tri.v.get_unchecked(self.ky),
                *tri.v.get_unchecked(self.kz),
            )
        };
        self.intersect_permuted(vx, vy, vz, t_max)
    }

    /// [`Self::intersect`] of the triangle whose corners are `verts[corners[0]]`,
    /// `verts[corners[1]]` and `verts[corners[2]]` (the compact layout: each vertex stored
    /// as `(x, y, z, _)`), the bit-identical answer of `intersect(&TriangleSoa::from_vertices(…))`.
    /// The ray's three axes are read per corner straight from `verts` into lanes 0–2, so
    /// the triangle is neither transposed in registers nor stored and re-read by axis.
    ///
    /// # Safety
    /// Every corner index must be below `verts.len()`.
    #[inline(always)]
    pub(crate) unsafe fn intersect_corners(
        &self,
        verts: &[Vec4],
        corners: [u32; 3],
        t_max: f32,
    ) -> Option<TriangleHit> {
        debug_assert!(self.kx < 3 && self.ky < 3 && self.kz < 3);
        debug_assert!(corners.iter().all(|&c| (c as usize) < verts.len()));
        let base = verts.as_ptr().cast::<f32>();
        // SAFETY: the corners are below `verts.len()` (the caller's promise) and `kx`, `ky`,
        // `kz` below 3 (set by `new`): every read is a component of a stored vertex.
        let lane = |k: usize| unsafe {
            let [a, b, c] = corners.map(|i| base.add(4 * i as usize + k));
            // (Lane 3 is never read by the test.)
            Vec4::new(*a, *b, *c, 0.0)
        };
        self.intersect_permuted(lane(self.kx), lane(self.ky), lane(self.kz), t_max)
    }

    /// The test on the triangle's coordinates along the ray's axes `kx`, `ky`, `kz` (lane
    /// `i` of each: corner `i`'s; lane 3 is not read).
    #[inline(always)]
    fn intersect_permuted(&self, vx: Vec4, vy: Vec4, vz: Vec4, t_max: f32) -> Option<TriangleHit> {
        // Lanes: vertices 0, 1, 2 (a, b, c) relative to the origin, permuted and sheared.
        let px = vx - self.okx;
        let py = vy - self.oky;
        let pz = vz - self.okz;
        let x = px - self.sxv * pz;
        let y = py - self.syv * pz;
        // Lane 0: E(B, C) = cx·by − cy·bx (weight of vertex 0); lane 1: E(C, A); lane 2: E(A, B).
        let e = x.zxyw() * y.yzxw() - y.zxyw() * x.yzxw();
        let zero = e.cmpeq(Vec4::ZERO).bitmask() & 7;
        // With no edge function zero, the signs are the sign bits (a NaN lane, whatever its
        // sign bit, makes `det` NaN below: no hit either way).
        let sign = e.is_negative_bitmask() & 7;
        if zero == 0 && sign != 0 && sign != 7 {
            return None;
        }
        // `det = (u + v) + w` and `tn = (u·az + v·bz) + w·cz`, with `az = sz·pz[0]` and so
        // on, in lanes 0 and 1: the same IEEE operations, in the same order, as in scalars.
        let e = if zero != 0 {
            let (u, v, w) = edge_functions_exact([x.x, y.x], [x.y, y.y], [x.z, y.z])?;
            Vec4::new(u, v, w, 0.0)
        } else {
            e
        };
        let ez = e * (pz * self.sz);
        let (first, second, third) = interleave(e, ez);
        let sums = (first + second) + third;
        let (det, tn) = (sums.x, sums.y);
        // `det` zero, infinite or NaN needs no test of its own: `t` is then ±∞, 0 or NaN,
        // which the distance test below rejects.
        let inv = 1.0 / det;
        let t = tn * inv;
        if !(t > 0.0 && t < t_max) {
            return None;
        }
        let b = e * inv;
        Some(TriangleHit {
            t,
            b0: b.x,
            b1: b.y,
            b2: b.z,
        })
    }
}

/// Up to four triangles transposed for [`ShearedRay::intersect4`]: `v[j][k]` holds coordinate
/// `k` of vertex `j` of the four triangles, triangle `i` in lane `i` (a leaf of the hierarchy,
/// stored once, so that the test reads its lanes without a gather).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub(crate) struct TriangleBlock {
    v: [[Vec4; 3]; 3],
}

impl TriangleBlock {
    /// The block of `tris` (one to four; lanes past them repeat the first triangle, and the
    /// test is told to ignore them).
    pub(crate) fn new(tris: &[[Vec3; 3]]) -> Self {
        let lane = |i: usize| {
            tris.get(i)
                .or(tris.first())
                .copied()
                .unwrap_or([Vec3::ZERO; 3])
        };
        let l = [lane(0), lane(1), lane(2), lane(3)];
        let coord = |j: usize, k: usize| Vec4::new(l[0][j][k], l[1][j][k], l[2][j][k], l[3][j][k]);
        TriangleBlock {
            v: [0, 1, 2].map(|j| [coord(j, 0), coord(j, 1), coord(j, 2)]),
        }
    }

    /// The corners of the triangle in lane `lane` (taken modulo 4) as `(x, y, z, 0)`: the
    /// values [`Self::new`] was given, read back from the block's lanes (the hit record reads
    /// them here, from lines the test has just loaded, instead of through the mesh's indices).
    #[inline(always)]
    pub(crate) fn corners(&self, lane: usize) -> [Vec4; 3] {
        let l = lane & 3;
        self.v.map(|[x, y, z]| Vec4::new(x[l], y[l], z[l], 0.0))
    }
}

/// The four lanes of [`ShearedRay::intersect4`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct Hits4 {
    t: Vec4,
    b: [Vec4; 3],
    /// Bit `i`: lane `i` is valid, has no edge function exactly zero, and hits with
    /// `0 < t < t_max`.
    pub(crate) hit: u32,
    /// Bit `i`: lane `i` is valid and has an edge function exactly zero in f32; it is not in
    /// `hit` (the caller tests it with [`ShearedRay::intersect`], which takes the exact path).
    pub(crate) unsure: u32,
}

impl Hits4 {
    /// The lane of the nearest hit in `hit` (the lowest lane among equal distances: the one
    /// a one-by-one visit in lane order keeps, as it accepts only `t < t_max`), with its hit.
    /// `hit` must not be empty.
    #[inline(always)]
    pub(crate) fn nearest(&self) -> (usize, TriangleHit) {
        let t = self.t.to_array();
        let mut best = (self.hit.trailing_zeros() & 3) as usize;
        let mut rest = self.hit & self.hit.wrapping_sub(1);
        while rest != 0 {
            let i = (rest.trailing_zeros() & 3) as usize;
            if t[i] < t[best] {
                best = i;
            }
            rest &= rest - 1;
        }
        let [b0, b1, b2] = self.b.map(|b| b.to_array()[best]);
        (
            best,
            TriangleHit {
                t: t[best],
                b0,
                b1,
                b2,
            },
        )
    }
}

impl ShearedRay {
    /// [`ShearedRay::intersect`] on the four lanes of `block` at once, lanes outside `valid`
    /// (a bit mask) ignored. Every lane goes through exactly the IEEE operations of the
    /// one-triangle test, in the same order (no FMA), so a lane's hit is bit-identical to it;
    /// lanes with an edge function exactly zero are reported in `unsure` instead of taking
    /// the exact path.
    #[inline(always)]
    pub(crate) fn intersect4(&self, block: &TriangleBlock, valid: u32, t_max: f32) -> Hits4 {
        debug_assert!(self.kx < 3 && self.ky < 3 && self.kz < 3);
        let sheared = |v: &[Vec4; 3]| {
            // SAFETY: `kx`, `ky` and `kz` are a permutation of 0, 1, 2 (set by `new`).
            let (vx, vy, vz) = unsafe {
                (
                    *v.get_unchecked(self.kx),
                    *v.get_unchecked(self.ky),
                    *v.get_unchecked(self.kz),
                )
            };
            let px = vx - self.okx;
            let py = vy - self.oky;
            let pz = vz - self.okz;
            (px - self.sxv * pz, py - self.syv * pz, pz)
        };
        let (xa, ya, za) = sheared(&block.v[0]);
        let (xb, yb, zb) = sheared(&block.v[1]);
        let (xc, yc, zc) = sheared(&block.v[2]);
        // The one-triangle test's lanes 0, 1, 2: E(B, C), E(C, A), E(A, B).
        let u = xc * yb - yc * xb;
        let v = xa * yc - ya * xc;
        let w = xb * ya - yb * xa;
        let zero = Vec4::ZERO;
        let unsure = (u.cmpeq(zero) | v.cmpeq(zero) | w.cmpeq(zero)).bitmask() & valid;
        // Mixed signs miss. In a lane with no edge function zero, a sign bit is the sign, so
        // the signs agree exactly when the sign bits do ([`same_sign_bits`]); zero lanes
        // are `unsure` and left out of `hit` whatever this says, and a NaN lane, whichever
        // way this goes, has a NaN `t` below, which no distance test accepts.
        let inside = same_sign_bits(u, v, w);
        if valid & inside & !unsure == 0 {
            // No lane left to hit (most leaves a ray enters): skip the division.
            return Hits4 {
                t: zero,
                b: [zero; 3],
                hit: 0,
                unsure,
            };
        }
        let sz = Vec4::splat(self.sz);
        let det = (u + v) + w;
        let tn = (u * (za * sz) + v * (zb * sz)) + w * (zc * sz);
        let inv = Vec4::ONE / det;
        let t = tn * inv;
        let in_range = (t.cmpgt(zero) & t.cmplt(Vec4::splat(t_max))).bitmask();
        Hits4 {
            t,
            b: [u * inv, v * inv, w * inv],
            hit: valid & !unsure & inside & in_range & 15,
            unsure,
        }
    }
}

/// The eight lanes of [`ShearedRay::intersect8`]: lanes 0–3 are the first block's, lanes
/// 4–7 the second's.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Hits8 {
    // The lanes' hits, read by the tests (the occlusion query reads only the bits).
    #[cfg_attr(not(test), allow(dead_code))]
    t: [f32; 8],
    #[cfg_attr(not(test), allow(dead_code))]
    b: [[f32; 8]; 3],
    /// Bit `i`: lane `i` has no edge function exactly zero and hits with `0 < t < t_max`.
    pub(crate) hit: u32,
    /// Bit `i`: lane `i` has an edge function exactly zero in f32 (not in `hit`).
    pub(crate) unsure: u32,
}

impl Hits8 {
    /// As [`Hits4::nearest`], over eight lanes: the lane of the nearest hit in `hit`, the
    /// lowest among equal distances (the one a visit of the two blocks in order keeps, as the
    /// second block accepts only distances below the first's nearest). `hit` must not be
    /// empty. (The occlusion query needs only the bits; the tests compare the lanes.)
    #[cfg(test)]
    pub(crate) fn nearest(&self) -> (usize, TriangleHit) {
        let t = &self.t;
        let mut best = (self.hit.trailing_zeros() & 7) as usize;
        let mut rest = self.hit & self.hit.wrapping_sub(1);
        while rest != 0 {
            let i = (rest.trailing_zeros() & 7) as usize;
            if t[i] < t[best] {
                best = i;
            }
            rest &= rest - 1;
        }
        let [b0, b1, b2] = self.b.map(|b| b[best]);
        (
            best,
            TriangleHit {
                t: t[best],
                b0,
                b1,
                b2,
            },
        )
    }
}

impl ShearedRay {
    /// [`ShearedRay::intersect4`] on every lane of two blocks at once (`lo` in lanes 0–3, `hi`
    /// in lanes 4–7; they may be the same block, whose lanes then come twice): with AVX, one eight-lane pass of the same IEEE operations per
    /// lane, in the same order (no FMA), so that every lane's hit and `unsure` bit are the
    /// four-lane test's bit for bit; the loads, the shear constants, the sign tests and the
    /// caller's loop step are paid once for eight triangles. Without AVX, the two four-lane
    /// tests.
    #[inline(always)]
    pub(crate) fn intersect8(&self, lo: &TriangleBlock, hi: &TriangleBlock, t_max: f32) -> Hits8 {
        debug_assert!(self.kx < 3 && self.ky < 3 && self.kz < 3);
        #[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
        {
            use std::arch::x86_64::{
                __m128, __m256, _mm256_add_ps, _mm256_and_ps, _mm256_cmp_ps, _mm256_div_ps,
                _mm256_movemask_ps, _mm256_mul_ps, _mm256_or_ps, _mm256_set1_ps, _mm256_set_m128,
                _mm256_setzero_ps, _mm256_sub_ps, _mm256_xor_ps, _CMP_EQ_OQ, _CMP_GT_OQ,
                _CMP_LT_OQ,
            };
            // SAFETY: AVX is enabled at compile time (the cfg above), so these are plain
            // register operations; `kx`, `ky` and `kz` are a permutation of 0, 1, 2 (set by
            // `new`), so every read is a stored lane vector of a block.
            unsafe {
                let both = |x: Vec4| _mm256_set_m128(__m128::from(x), __m128::from(x));
                let (okx, oky, okz) = (both(self.okx), both(self.oky), both(self.okz));
                let (sxv, syv) = (both(self.sxv), both(self.syv));
                let sheared = |j: usize| {
                    let load = |k: usize| -> __m256 {
                        _mm256_set_m128(
                            __m128::from(*hi.v[j].get_unchecked(k)),
                            __m128::from(*lo.v[j].get_unchecked(k)),
                        )
                    };
                    let px = _mm256_sub_ps(load(self.kx), okx);
                    let py = _mm256_sub_ps(load(self.ky), oky);
                    let pz = _mm256_sub_ps(load(self.kz), okz);
                    (
                        _mm256_sub_ps(px, _mm256_mul_ps(sxv, pz)),
                        _mm256_sub_ps(py, _mm256_mul_ps(syv, pz)),
                        pz,
                    )
                };
                let (xa, ya, za) = sheared(0);
                let (xb, yb, zb) = sheared(1);
                let (xc, yc, zc) = sheared(2);
                let edge = |p: __m256, q: __m256, r: __m256, s: __m256| {
                    _mm256_sub_ps(_mm256_mul_ps(p, q), _mm256_mul_ps(r, s))
                };
                let u = edge(xc, yb, yc, xb);
                let v = edge(xa, yc, ya, xc);
                let w = edge(xb, ya, yb, xa);
                let zero = _mm256_setzero_ps();
                let unsure = _mm256_movemask_ps(_mm256_or_ps(
                    _mm256_or_ps(
                        _mm256_cmp_ps::<_CMP_EQ_OQ>(u, zero),
                        _mm256_cmp_ps::<_CMP_EQ_OQ>(v, zero),
                    ),
                    _mm256_cmp_ps::<_CMP_EQ_OQ>(w, zero),
                )) as u32;
                // As in `intersect4`: mixed sign bits miss ([`same_sign_bits`]).
                let differ =
                    _mm256_movemask_ps(_mm256_or_ps(_mm256_xor_ps(u, v), _mm256_xor_ps(u, w)))
                        as u32;
                let inside = !differ & 0xff;
                if inside & !unsure == 0 {
                    return Hits8 {
                        t: [0.0; 8],
                        b: [[0.0; 8]; 3],
                        hit: 0,
                        unsure,
                    };
                }
                let sz = _mm256_set1_ps(self.sz);
                let det = _mm256_add_ps(_mm256_add_ps(u, v), w);
                let tn = _mm256_add_ps(
                    _mm256_add_ps(
                        _mm256_mul_ps(u, _mm256_mul_ps(za, sz)),
                        _mm256_mul_ps(v, _mm256_mul_ps(zb, sz)),
                    ),
                    _mm256_mul_ps(w, _mm256_mul_ps(zc, sz)),
                );
                let inv = _mm256_div_ps(_mm256_set1_ps(1.0), det);
                let t = _mm256_mul_ps(tn, inv);
                let in_range = _mm256_movemask_ps(_mm256_and_ps(
                    _mm256_cmp_ps::<_CMP_GT_OQ>(t, zero),
                    _mm256_cmp_ps::<_CMP_LT_OQ>(t, _mm256_set1_ps(t_max)),
                )) as u32;
                let lanes = |x: __m256| std::mem::transmute::<__m256, [f32; 8]>(x);
                Hits8 {
                    t: lanes(t),
                    b: [
                        lanes(_mm256_mul_ps(u, inv)),
                        lanes(_mm256_mul_ps(v, inv)),
                        lanes(_mm256_mul_ps(w, inv)),
                    ],
                    hit: !unsure & inside & in_range & 0xff,
                    unsure,
                }
            }
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "avx")))]
        {
            let (lo, hi) = (
                self.intersect4(lo, 15, t_max),
                self.intersect4(hi, 15, t_max),
            );
            let join = |a: Vec4, b: Vec4| {
                let (a, b) = (a.to_array(), b.to_array());
                [a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3]]
            };
            Hits8 {
                t: join(lo.t, hi.t),
                b: [0, 1, 2].map(|k| join(lo.b[k], hi.b[k])),
                hit: lo.hit | hi.hit << 4,
                unsure: lo.unsure | hi.unsure << 4,
            }
        }
    }
}

/// The lanes (bit `i` for lane `i`, bits 0–3) where `u`, `v` and `w` have the same sign bit:
/// neither `u ^ v` nor `u ^ w` has its sign bit set (two `xor`s, an `or` and one sign mask,
/// where comparing each with zero both ways takes six compares).
#[inline(always)]
fn same_sign_bits(u: Vec4, v: Vec4, w: Vec4) -> u32 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{__m128, _mm_movemask_ps, _mm_or_ps, _mm_xor_ps};
        let (u, v, w) = (__m128::from(u), __m128::from(v), __m128::from(w));
        // SAFETY: SSE is part of the x86-64 baseline; these are register operations.
        let differ = unsafe { _mm_movemask_ps(_mm_or_ps(_mm_xor_ps(u, v), _mm_xor_ps(u, w))) };
        !(differ as u32) & 15
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let (su, sv, sw) = (
            u.is_negative_bitmask(),
            v.is_negative_bitmask(),
            w.is_negative_bitmask(),
        );
        !((su ^ sv) | (su ^ sw)) & 15
    }
}

/// `(a.x, b.x, …)`, `(a.y, b.y, …)` and `(a.z, b.z, …)`: lanes 0 and 1 of each hold one
/// coordinate of `a` and of `b` (lanes 2 and 3 are not used).
#[inline(always)]
fn interleave(a: Vec4, b: Vec4) -> (Vec4, Vec4, Vec4) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{__m128, _mm_movehl_ps, _mm_unpackhi_ps, _mm_unpacklo_ps};
        let (a, b) = (__m128::from(a), __m128::from(b));
        // SAFETY: SSE is part of the x86-64 baseline; these are register shuffles.
        unsafe {
            let lo = _mm_unpacklo_ps(a, b); // ax bx ay by
            let hi = _mm_unpackhi_ps(a, b); // az bz aw bw
            (
                Vec4::from(lo),
                Vec4::from(_mm_movehl_ps(lo, lo)),
                Vec4::from(hi),
            )
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        (
            Vec4::new(a.x, b.x, 0.0, 0.0),
            Vec4::new(a.y, b.y, 0.0, 0.0),
            Vec4::new(a.z, b.z, 0.0, 0.0),
        )
    }
}

/// The edge functions when one of them is exactly zero in f32: re-evaluated in f64 (exact for
/// products of f32), and a zero resolved by the sign the edge function takes when the origin
/// moves by `(ε, ε²)`. `None` when the ray misses or lies in the triangle's plane.
#[cold]
#[inline(always)]
fn edge_functions_exact(a: [f32; 2], b: [f32; 2], c: [f32; 2]) -> Option<(f32, f32, f32)> {
    let ([ax, ay], [bx, by], [cx, cy]) = (a, b, c);
    let ud = f64::from(cx) * f64::from(by) - f64::from(cy) * f64::from(bx);
    let vd = f64::from(ax) * f64::from(cy) - f64::from(ay) * f64::from(cx);
    let wd = f64::from(bx) * f64::from(ay) - f64::from(by) * f64::from(ax);
    let s = if ud > 0.0 || vd > 0.0 || wd > 0.0 {
        1.0
    } else if ud < 0.0 || vd < 0.0 || wd < 0.0 {
        -1.0
    } else {
        return None; // the ray lies in the triangle's plane
    };
    if ud * s < 0.0 || vd * s < 0.0 || wd * s < 0.0 {
        return None;
    }
    // A zero edge function: the ray passes exactly through the edge's line. Decide by the
    // sign the edge function takes when the origin moves by (ε, ε²).
    let inside = |e: f64, px: f32, py: f32, qx: f32, qy: f32| -> bool {
        if e != 0.0 {
            return true;
        }
        let dy = qy - py;
        let pert = if dy != 0.0 { dy } else { px - qx };
        pert != 0.0 && (f64::from(pert) * s) > 0.0
    };
    if !inside(ud, bx, by, cx, cy) || !inside(vd, cx, cy, ax, ay) || !inside(wd, ax, ay, bx, by) {
        return None;
    }
    Some((ud as f32, vd as f32, wd as f32))
}

/// Intersects `ray` (unit direction) with the triangle `(p0, p1, p2)`, accepting hits with
/// `0 < t < t_max`, either facing. Watertight (Woop, Benthin & Wald 2013): a ray through an
/// edge or vertex shared by triangles of a mesh (bit-identical vertex positions) hits
/// exactly one of them where the surface is not folded over in the ray's view.
#[must_use]
pub fn intersect_triangle(
    ray: &Ray,
    p0: Vec3,
    p1: Vec3,
    p2: Vec3,
    t_max: f32,
) -> Option<TriangleHit> {
    if !ray.o.is_finite() || !ray.d.is_finite() || ray.d == Vec3::ZERO {
        return None;
    }
    ShearedRay::new(ray).intersect(&TriangleSoa::new(p0, p1, p2), t_max)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reproducible stream of uniform numbers in [0, 1) (a 64-bit LCG's top 24 bits).
    fn uniform_stream(seed: u64) -> impl FnMut() -> f32 {
        let mut state = seed;
        move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    /// A coordinate in [−2, 2]: on the half-unit grid when `grid` (so that edge functions
    /// come out exactly zero), continuous otherwise.
    fn coordinate(next: &mut impl FnMut() -> f32, grid: bool) -> f32 {
        let x = next() * 4.0 - 2.0;
        if grid {
            (x * 2.0).round() * 0.5
        } else {
            x
        }
    }

    /// The watertight test written out in scalars, step by step as in the paper (the
    /// SIMD-lane test must give exactly its results).
    fn scalar_reference(ray: &Ray, p: [Vec3; 3], t_max: f32) -> Option<TriangleHit> {
        let a = ray.d.abs();
        let (kz, kx, ky) = if a.x >= a.y && a.x >= a.z {
            (0, 1, 2)
        } else if a.y >= a.z {
            (1, 2, 0)
        } else {
            (2, 0, 1)
        };
        let (kx, ky) = if ray.d[kz] < 0.0 { (ky, kx) } else { (kx, ky) };
        let sx = ray.d[kx] / ray.d[kz];
        let sy = ray.d[ky] / ray.d[kz];
        let sz = 1.0 / ray.d[kz];
        let rel = p.map(|v| v - ray.o);
        let xy = rel.map(|q| (q[kx] - sx * q[kz], q[ky] - sy * q[kz]));
        let [(ax, ay), (bx, by), (cx, cy)] = xy;
        let mut u = cx * by - cy * bx;
        let mut v = ax * cy - ay * cx;
        let mut w = bx * ay - by * ax;
        if u == 0.0 || v == 0.0 || w == 0.0 {
            (u, v, w) = edge_functions_exact([ax, ay], [bx, by], [cx, cy])?;
        } else if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return None;
        }
        let det = u + v + w;
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let (az, bz, cz) = (sz * rel[0][kz], sz * rel[1][kz], sz * rel[2][kz]);
        let tn = u * az + v * bz + w * cz;
        let inv = 1.0 / det;
        let t = tn * inv;
        if !(t > 0.0 && t < t_max) {
            return None;
        }
        Some(TriangleHit {
            t,
            b0: u * inv,
            b1: v * inv,
            b2: w * inv,
        })
    }

    fn bits(h: Option<TriangleHit>) -> Option<[u32; 4]> {
        h.map(|h| [h.t, h.b0, h.b1, h.b2].map(f32::to_bits))
    }

    /// The corners read from a shared vertex array by the ray's axes give the transposed
    /// triangle's answer bit for bit, on grid cases (edge functions exactly zero, rays
    /// through shared edges and vertices) and continuous ones; fails if an axis or a corner
    /// is read in the wrong place.
    #[test]
    fn corners_read_by_axis_give_the_transposed_triangles_answer() {
        let mut next = uniform_stream(0x2545_f491_4f6c_dd1d);
        let (mut hits, mut cases) = (0, 0);
        for i in 0..200_000 {
            let grid = i % 2 == 0;
            let mut coord = || coordinate(&mut next, grid);
            // Six shared vertices, a triangle naming three of them in any order.
            let verts: Vec<Vec4> = (0..6)
                .map(|_| Vec4::new(coord(), coord(), coord(), 7.0))
                .collect();
            let o = Vec3::new(coord(), coord(), coord()) * 2.0;
            let target = Vec3::new(coord(), coord(), coord());
            let Some(d) = (target - o).try_normalize() else {
                continue;
            };
            let ray = Ray::new(o, d);
            let mut pick = || ((next() * 6.0) as u32).min(5);
            let corners = [pick(), pick(), pick()];
            let [a, b, c] = corners.map(|i| verts[i as usize]);
            let t_max = if i % 3 == 0 { 2.0 } else { f32::INFINITY };
            let sr = ShearedRay::new(&ray);
            let expected = sr.intersect(&TriangleSoa::from_vertices(a, b, c), t_max);
            // SAFETY: every corner is below 6 = `verts.len()`.
            let got = unsafe { sr.intersect_corners(&verts, corners, t_max) };
            assert_eq!(
                bits(got),
                bits(expected),
                "case {i}: {verts:?} {corners:?} {ray:?}"
            );
            let reference = scalar_reference(&ray, [a, b, c].map(|v| v.truncate()), t_max);
            assert_eq!(bits(got), bits(reference), "case {i}");
            hits += usize::from(expected.is_some());
            cases += 1;
        }
        assert!(
            hits > 5_000 && cases > 150_000,
            "{hits} hits in {cases} cases"
        );
    }

    #[test]
    fn the_lane_test_equals_the_scalar_steps_bit_for_bit() {
        let mut next = uniform_stream(0x9e37_79b9_7f4a_7c15);
        let (mut hits, mut zeros) = (0, 0);
        for i in 0..400_000 {
            // Half the cases on a coarse grid (edge functions exactly zero, rays through
            // vertices and edges, degenerate and axis-aligned triangles), half continuous.
            let grid = i % 2 == 0;
            let mut coord = || coordinate(&mut next, grid);
            let p = [
                Vec3::new(coord(), coord(), coord()),
                Vec3::new(coord(), coord(), coord()),
                Vec3::new(coord(), coord(), coord()),
            ];
            let o = Vec3::new(coord(), coord(), coord()) * 2.0;
            let target = Vec3::new(coord(), coord(), coord());
            let Some(d) = (target - o).try_normalize() else {
                continue;
            };
            let ray = Ray::new(o, d);
            let t_max = if i % 3 == 0 { 2.0 } else { f32::INFINITY };
            let expected = scalar_reference(&ray, p, t_max);
            let got = intersect_triangle(&ray, p[0], p[1], p[2], t_max);
            assert_eq!(bits(got), bits(expected), "case {i}: {p:?} {ray:?}");
            hits += usize::from(expected.is_some());
            let sr = ShearedRay::new(&ray);
            let tri = TriangleSoa::new(p[0], p[1], p[2]);
            let x = tri.v[sr.kx] - sr.okx - sr.sxv * (tri.v[sr.kz] - sr.okz);
            let y = tri.v[sr.ky] - sr.oky - sr.syv * (tri.v[sr.kz] - sr.okz);
            let e = x.zxyw() * y.yzxw() - y.zxyw() * x.yzxw();
            zeros += usize::from(e.cmpeq(Vec4::ZERO).bitmask() & 7 != 0);
        }
        assert!(hits > 20_000, "{hits} hits");
        assert!(
            zeros > 5_000,
            "{zeros} cases with an edge function exactly zero"
        );
    }

    /// Every valid lane of [`ShearedRay::intersect4`] is the one-triangle test bit for bit:
    /// a lane in `hit` has its hit, a lane in `unsure` has an edge function exactly zero, any
    /// other valid lane is a miss; [`Hits4::nearest`] is the first nearest of the lanes, as
    /// the one-by-one visit in lane order keeps. Blocks of one to four triangles, some on a
    /// coarse grid (zero edge functions), some sharing the first triangle's edge.
    #[test]
    fn the_four_lane_test_is_the_one_triangle_test_per_lane() {
        let mut next = uniform_stream(0x2545_f491_4f6c_dd1d);
        let (mut hits, mut unsure, mut nearest_not_first) = (0, 0, 0);
        let mut padded_hits = 0;
        for i in 0..100_000 {
            let grid = i % 3 == 0;
            let mut coord = || coordinate(&mut next, grid);
            let n = 1 + i % 4;
            let mut tris: Vec<[Vec3; 3]> = (0..n)
                .map(|_| {
                    [
                        Vec3::new(coord(), coord(), coord()),
                        Vec3::new(coord(), coord(), coord()),
                        Vec3::new(coord(), coord(), coord()),
                    ]
                })
                .collect();
            if n > 1 && i % 5 == 0 {
                // A neighbour across the first triangle's edge.
                tris[1][0] = tris[0][1];
                tris[1][1] = tris[0][0];
            }
            let o = Vec3::new(coord(), coord(), coord()) * 2.0;
            let target = Vec3::new(coord(), coord(), coord());
            let Some(d) = (target - o).try_normalize() else {
                continue;
            };
            let ray = Ray::new(o, d);
            let t_max = if i % 7 == 0 { 2.0 } else { f32::INFINITY };
            let sr = ShearedRay::new(&ray);
            let block = TriangleBlock::new(&tris);
            let valid = (1u32 << n) - 1;
            let h = sr.intersect4(&block, valid, t_max);
            assert_eq!(
                (h.hit | h.unsure) & !valid,
                0,
                "case {i}: invalid lanes reported"
            );
            assert_eq!(h.hit & h.unsure, 0, "case {i}");
            let mut first_nearest: Option<(usize, TriangleHit)> = None;
            for (lane, p) in tris.iter().enumerate() {
                let one = sr.intersect(&TriangleSoa::new(p[0], p[1], p[2]), t_max);
                if h.unsure & (1 << lane) != 0 {
                    unsure += 1;
                    continue;
                }
                if h.hit & (1 << lane) != 0 {
                    let got = TriangleHit {
                        t: h.t.to_array()[lane],
                        b0: h.b[0].to_array()[lane],
                        b1: h.b[1].to_array()[lane],
                        b2: h.b[2].to_array()[lane],
                    };
                    assert_eq!(bits(Some(got)), bits(one), "case {i}, lane {lane}");
                    hits += 1;
                    if first_nearest.is_none_or(|(_, f)| got.t < f.t) {
                        first_nearest = Some((lane, got));
                    }
                } else {
                    assert_eq!(bits(one), None, "case {i}, lane {lane}: missed");
                }
            }
            if let Some((lane, f)) = first_nearest {
                let (l, g) = h.nearest();
                assert_eq!((l, bits(Some(g))), (lane, bits(Some(f))), "case {i}");
                nearest_not_first += usize::from(lane > 0);
            }
            // All four lanes, as the traversal's visitors test a block: the lanes past `n`
            // repeat the first triangle, so the block is unsure, hits, and has its nearest
            // lane exactly as with the mask.
            let all = sr.intersect4(&block, 15, t_max);
            assert_eq!(
                all.unsure != 0,
                h.unsure != 0,
                "case {i}: all lanes, unsure"
            );
            assert_eq!(all.hit != 0, h.hit != 0, "case {i}: all lanes, hit");
            if h.unsure == 0 && h.hit != 0 {
                let ((l, g), (la, ga)) = (h.nearest(), all.nearest());
                assert_eq!(
                    (la, bits(Some(ga))),
                    (l, bits(Some(g))),
                    "case {i}: all lanes"
                );
                padded_hits += usize::from(n < 4 && all.hit != h.hit);
            }
        }
        assert!(
            padded_hits > 1_000,
            "{padded_hits} blocks whose repeated lanes hit"
        );
        assert!(hits > 10_000, "{hits} lane hits");
        assert!(
            unsure > 1_000,
            "{unsure} lanes with an edge function exactly zero"
        );
        assert!(nearest_not_first > 1_000, "{nearest_not_first}");
    }

    /// [`ShearedRay::intersect8`] on two blocks is the two blocks' [`ShearedRay::intersect4`]
    /// (every lane) bit for bit: the same `hit` and `unsure` bits, the same distance and
    /// barycentrics in every hit lane, and [`Hits8::nearest`] the lane the two blocks' tests
    /// in order keep (the second block with the first's nearest as its `t_max`), on blocks of
    /// one to four triangles, a third on a grid (edge functions exactly zero) and some with
    /// the second block repeating a triangle of the first (equal distances across the blocks).
    /// Fails if a lane's operations differ, a block lands in the wrong lanes, or ties go to
    /// the second block.
    #[test]
    fn the_eight_lane_test_is_the_two_blocks_four_lane_tests() {
        let mut next = uniform_stream(0x5851_f42d_4c95_7f2d);
        let (mut hit_lanes, mut unsure_pairs, mut second_wins, mut ties) = (0, 0, 0, 0);
        for i in 0..100_000 {
            let grid = i % 3 == 0;
            let mut coord = || coordinate(&mut next, grid);
            let mut tri = || [(); 3].map(|_| Vec3::new(coord(), coord(), coord()));
            let first: Vec<[Vec3; 3]> = (0..4).map(|_| tri()).collect();
            let mut second: Vec<[Vec3; 3]> = (0..1 + i % 4).map(|_| tri()).collect();
            if i % 4 == 1 {
                // The same triangle in both blocks: equal distances in lanes 0 and 4 + 0.
                second[0] = first[0];
            }
            let o = Vec3::new(coord(), coord(), coord()) * 2.0;
            let target = Vec3::new(coord(), coord(), coord());
            let Some(d) = (target - o).try_normalize() else {
                continue;
            };
            let ray = Ray::new(o, d);
            let t_max = if i % 7 == 0 { 2.0 } else { f32::INFINITY };
            let sr = ShearedRay::new(&ray);
            let pair = [TriangleBlock::new(&first), TriangleBlock::new(&second)];
            let h = sr.intersect8(&pair[0], &pair[1], t_max);
            let (lo, hi) = (
                sr.intersect4(&pair[0], 15, t_max),
                sr.intersect4(&pair[1], 15, t_max),
            );
            assert_eq!(h.unsure, lo.unsure | hi.unsure << 4, "case {i}: unsure");
            assert_eq!(h.hit, lo.hit | hi.hit << 4, "case {i}: hit");
            for lane in 0..8 {
                if h.hit & (1 << lane) == 0 {
                    continue;
                }
                let four = if lane < 4 { &lo } else { &hi };
                let l = lane & 3;
                let want = [four.t, four.b[0], four.b[1], four.b[2]].map(|x| x.to_array()[l]);
                let got = [h.t[lane], h.b[0][lane], h.b[1][lane], h.b[2][lane]];
                assert_eq!(
                    got.map(f32::to_bits),
                    want.map(f32::to_bits),
                    "case {i}, lane {lane}"
                );
                hit_lanes += 1;
            }
            unsure_pairs += usize::from(h.unsure != 0);
            // One block in both halves (a leaf's last block alone): its lanes twice, and the
            // nearest in the first half, as the four-lane test's.
            let same = sr.intersect8(&pair[0], &pair[0], t_max);
            assert_eq!(same.unsure, lo.unsure * 0x11, "case {i}: one block, unsure");
            assert_eq!(same.hit, lo.hit * 0x11, "case {i}: one block, hit");
            if lo.hit != 0 {
                let ((l, g), (l4, g4)) = (same.nearest(), lo.nearest());
                assert_eq!(
                    (l, bits(Some(g))),
                    (l4, bits(Some(g4))),
                    "case {i}: one block"
                );
            }
            if h.unsure != 0 || h.hit == 0 {
                continue;
            }
            // The two blocks in order: the second accepts only distances below the first's
            // nearest.
            let in_order = if lo.hit != 0 {
                let (l, near) = lo.nearest();
                let later = sr.intersect4(&pair[1], 15, near.t);
                ties += usize::from(hi.hit != 0 && later.hit == 0 && hi.nearest().1.t == near.t);
                if later.hit != 0 {
                    let (l2, h2) = later.nearest();
                    (l2 + 4, h2)
                } else {
                    (l, near)
                }
            } else {
                let (l2, h2) = hi.nearest();
                (l2 + 4, h2)
            };
            let (l, g) = h.nearest();
            second_wins += usize::from(l >= 4 && lo.hit != 0);
            assert_eq!(
                (l, bits(Some(g))),
                (in_order.0, bits(Some(in_order.1))),
                "case {i}: nearest"
            );
        }
        assert!(hit_lanes > 10_000, "{hit_lanes} lane hits");
        assert!(
            unsure_pairs > 1_000,
            "{unsure_pairs} pairs with an unsure lane"
        );
        assert!(
            second_wins > 500,
            "{second_wins} pairs won by the second block"
        );
        assert!(ties > 500, "{ties} ties between the blocks");
    }

    #[test]
    fn a_block_gives_back_each_lanes_corners_as_stored() {
        let mut next = uniform_stream(29);
        let mut coord = move || (next() - 0.5) * 1.0e3;
        for n in 1..=4 {
            let tris: Vec<[Vec3; 3]> = (0..n)
                .map(|_| [(); 3].map(|_| Vec3::new(coord(), -coord(), coord())))
                .collect();
            let block = TriangleBlock::new(&tris);
            for lane in 0..4 {
                // Lanes past the block's triangles repeat the first.
                let want = tris.get(lane).unwrap_or(&tris[0]).map(|v| v.extend(0.0));
                let got = block.corners(lane);
                assert_eq!(
                    got.map(|v| v.to_array().map(f32::to_bits)),
                    want.map(|v| v.to_array().map(f32::to_bits)),
                    "{n} triangles, lane {lane}"
                );
                // The lane is taken modulo 4.
                assert_eq!(
                    block
                        .corners(lane + 4)
                        .map(|v| v.to_array().map(f32::to_bits)),
                    got.map(|v| v.to_array().map(f32::to_bits))
                );
            }
        }
    }
}
