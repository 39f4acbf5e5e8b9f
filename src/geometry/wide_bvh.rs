//! An 8-wide BVH with full-precision boxes in structure-of-arrays layout, traversed nearest
//! child first with SIMD slab tests: one 8-wide AVX2 test per node where the CPU has AVX2 and
//! FMA (detected at run time), its distances fused multiply-adds with directed origin terms
//! ([`FMA_FAR_SCALE`]), else two 4-wide halves (glam's `Vec4`: SSE on x86-64) with an exact
//! subtraction. Both tests are conservative (neither culls a box the ray enters); they may
//! differ on grazed boxes and in the last bits of entry distances, so the order of two
//! children at almost the same distance may differ. The closest hit is the triangle test's
//! nearest, found either way; only two triangles hit at the very same distance could be
//! reported differently.
//!
//! The binary hierarchy is built top-down by a full sweep of the surface area heuristic
//! ([`super::sweep_sah`]), then every node is offered to `obvhs`'s SAH reinsertion
//! ([`REINSERTION_BATCH_RATIO`]); it is collapsed
//! into nodes of up to eight children by the surface area heuristic's dynamic programme of
//! Ylitie, Karras and Laine 2017 ("Efficient incoherent ray traversal on GPUs through
//! compressed wide BVHs"): every binary node becomes a leaf (at most [`MAX_LEAF_PRIMITIVES`]
//! primitives), a wide node, or hands its slots to its two children, whichever is cheapest.
//! Primitives are re-ordered so that every leaf's primitives are contiguous.
//!
//! The node test is conservative: the far slab distance is enlarged by its rounding-error bound
//! (1 + 2γ₃, Ize 2013 "Robust BVH Ray Traversal", as in pbrt-v4), the boxes were padded when they
//! were built, and the interval is clipped to `[0, t_max]`, so a primitive the ray hits is never
//! culled.

use std::mem::MaybeUninit;

use glam::{Vec3A, Vec4};
use obvhs::aabb::Aabb as OAabb;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::bvh2::Bvh2;

use super::sweep_sah;
use crate::math::{Ray, Vec3};

/// Leaves hold at most this many primitives: three blocks of [`LEAF_BLOCK`] (the lanes of the
/// leaf test in [`super::bvh`]); a leaf's count takes the low four bits of its node entry, so
/// at most 15. Twelve rather than eight, with the collapse's block cost 0.4 rather than 0.5.
pub const MAX_LEAF_PRIMITIVES: u32 = 12;

// A leaf's count must fit its bits of the node entry.
const _: () = assert!(MAX_LEAF_PRIMITIVES <= LEAF_COUNT_MASK);

/// A leaf's primitives are tested in blocks of this many (four SIMD lanes); the collapse
/// prices a leaf by its blocks ([`leaf_cost`]).
pub const LEAF_BLOCK: u32 = 4;

/// The most primitives a hierarchy takes (a leaf's first block and its count share 32 bits).
pub const MAX_PRIMITIVES: u32 = u32::MAX >> LEAF_COUNT_BITS;

/// Bits of [`Node8::count`] holding a leaf's primitive count (the rest hold its first block).
const LEAF_COUNT_BITS: u32 = 4;
const LEAF_COUNT_MASK: u32 = (1 << LEAF_COUNT_BITS) - 1;

/// A leaf of the hierarchy: its primitives are the positions `first..first + count`, in
/// blocks of [`LEAF_BLOCK`] numbered from `block`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Leaf {
    /// Index of its first block: leaves number their blocks in build order, without gaps
    /// (see [`WideBvh::leaves`]).
    pub block: u32,
    /// Its first primitive position.
    pub first: u32,
    /// Its number of primitives (1 to [`MAX_LEAF_PRIMITIVES`]).
    pub count: u32,
}

impl Leaf {
    /// The number of blocks of [`LEAF_BLOCK`] primitives its primitives take.
    #[must_use]
    pub fn blocks(&self) -> u32 {
        self.count.div_ceil(LEAF_BLOCK)
    }
}

/// The share of the binary hierarchy's nodes that `obvhs`'s reinsertion optimiser (Meister
/// and Bittner 2018, "Parallel reinsertion for bounding volume hierarchy optimization") tries
/// to move to a cheaper place after the binary build: all of them, in one batch (its medium
/// build's 0.05 and slow build's 0.2 leave more surface area). After `obvhs`'s PLOC build it
/// saved 3.6 % of the instructions a ray from outside and 3.0 % from inside on the 20k
/// icosphere; after the sweep build ([`super::sweep_sah`]) it moves little (node tests a
/// query of the skin scene's recorded `mix20k` rays 4.49 without it, 4.45 with it).
const REINSERTION_BATCH_RATIO: f32 = 1.0;

/// Entries of the traversal stack kept on the machine stack; deeper trees spill to the heap.
const STACK_INLINE: usize = 48;

/// Children per node.
const WIDTH: usize = 8;

/// One node: the boxes of up to eight children, per axis in two 4-wide halves, and what each
/// child is.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct Node8 {
    /// Box planes of the children: minima x, y, z (empty slots hold +∞), then maxima x, y, z
    /// (empty slots hold −∞). One array, so that a ray picks its near and far plane per axis
    /// by index instead of by a branch.
    planes: [[Vec4; 2]; 6],
    /// Child node index, or the first primitive of a leaf.
    child: [u32; WIDTH],
    /// For a leaf child, its primitive count in the low [`LEAF_COUNT_BITS`] bits and its
    /// [`Leaf::block`] above them (0 for an inner child or an empty slot).
    count: [u32; WIDTH],
}

impl Node8 {
    fn empty() -> Self {
        Node8 {
            planes: [
                [Vec4::splat(f32::INFINITY); 2],
                [Vec4::splat(f32::INFINITY); 2],
                [Vec4::splat(f32::INFINITY); 2],
                [Vec4::splat(f32::NEG_INFINITY); 2],
                [Vec4::splat(f32::NEG_INFINITY); 2],
                [Vec4::splat(f32::NEG_INFINITY); 2],
            ],
            child: [0; WIDTH],
            count: [0; WIDTH],
        }
    }
}

/// A wide BVH over primitive boxes. Primitive indices it reports are positions in
/// [`WideBvh::order`].
#[derive(Clone, Debug, Default)]
pub struct WideBvh {
    nodes: Vec<Node8>,
    /// Original primitive index of each position.
    order: Vec<u32>,
    /// Every leaf, in the order of their blocks.
    leaves: Vec<Leaf>,
    /// Blocks the leaves take in all.
    blocks: u32,
    depth: usize,
    /// The traversal stack never outgrows its inline entries ([`WideBvh::shallow`]), set
    /// once the depth is known.
    shallow: bool,
    /// The CPU runs AVX2, FMA and POPCNT (detected when the hierarchy is built): the 8-wide
    /// node test.
    avx2: bool,
    /// The CPU also runs AVX-512 F and VL, and `VELOUR_NO_AVX512` is not set: the
    /// traversal compiled for them ([`WideBvh::traverse_avx512`]).
    avx512: bool,
}

/// The ray quantities the slab test needs, per axis.
struct SlabRay {
    /// Origin, splatted per axis.
    o: [Vec4; 3],
    /// Capped reciprocal direction negated, splatted per axis ([`slab_constants`]).
    ninv: [Vec4; 3],
    /// Per axis: index in [`Node8::planes`] of the plane the ray enters by (the maximum
    /// when the direction is negative) and of the one it leaves by.
    near: [usize; 3],
    far: [usize; 3],
}

impl SlabRay {
    /// The slab constants of `ray`. The reciprocal direction has magnitudes capped at 1e20
    /// (sign kept, `-0` treated as `+0`), so that slab tests never produce `0·∞`; the three
    /// reciprocals are one vector division (the same IEEE quotients as three scalar ones).
    #[inline]
    fn new(ray: &Ray) -> Self {
        let (inv, neg) = slab_constants(ray);
        let p = OCTANT_PLANES[(neg & 7) as usize];
        SlabRay {
            o: [
                Vec4::splat(ray.o.x),
                Vec4::splat(ray.o.y),
                Vec4::splat(ray.o.z),
            ],
            ninv: [
                Vec4::splat(-inv.x),
                Vec4::splat(-inv.y),
                Vec4::splat(-inv.z),
            ],
            near: [p[0], p[1], p[2]],
            far: [p[3], p[4], p[5]],
        }
    }

    #[inline(always)]
    fn test_half(&self, node: &Node8, h: usize, t_max: f32) -> (Vec4, u32) {
        let mut near = Vec4::ZERO;
        let mut far = Vec4::splat(t_max);
        // `(o − P)·(−inv)` is `(P − o)·inv` exactly (IEEE subtraction and multiplication
        // commute with negation), except that a zero may carry the other sign; every use of
        // these distances is a comparison, where ±0 are equal, so the children entered and
        // their order are the same. Written this way, the 8-wide test folds each plane's
        // load into its subtraction.
        for k in 0..3 {
            let n = node.planes[self.near[k]][h];
            let f = node.planes[self.far[k]][h];
            near = near.max((self.o[k] - n) * self.ninv[k]);
            far = far.min((self.o[k] - f) * self.ninv[k] * FAR_SCALE);
        }
        (near, near.cmple(far).bitmask())
    }
}

/// The capped reciprocal direction of `ray` (magnitudes capped at 1e20, sign kept, `-0`
/// treated as `+0`, so that slab tests never produce `0·∞`; the three reciprocals are one
/// vector division, the same IEEE quotients as three scalar ones) and the mask of its
/// negative components (bit `k` for axis `k`).
#[inline(always)]
fn slab_constants(ray: &Ray) -> (Vec4, u32) {
    let d = Vec4::from((ray.d, 1.0));
    let small = d.abs().cmplt(Vec4::splat(1e-20));
    let cap = Vec4::select(d.cmplt(Vec4::ZERO), Vec4::splat(-1e20), Vec4::splat(1e20));
    let inv = Vec4::select(small, cap, Vec4::ONE / d);
    (inv, inv.cmplt(Vec4::ZERO).bitmask())
}

/// Per octant of a ray's direction (bit `k` set when component `k` is negative, as
/// [`slab_constants`] reports it): the indices in [`Node8::planes`] of the planes the ray
/// enters each axis's slab by (first three: the minimum, or the maximum for a negative
/// component) and leaves it by (last three). A table, so that the ray's set-up reads its six
/// indices instead of computing each with a test of its sign bit.
const OCTANT_PLANES: [[usize; 6]; 8] = octant_planes();

const fn octant_planes() -> [[usize; 6]; 8] {
    let mut table = [[0; 6]; 8];
    let mut neg = 0;
    while neg < 8 {
        let mut k = 0;
        while k < 3 {
            let negative = (neg >> k) & 1 != 0;
            table[neg][k] = if negative { k + 3 } else { k };
            table[neg][k + 3] = if negative { k } else { k + 3 };
            k += 1;
        }
        neg += 1;
    }
    table
}

/// 1 + 2γ₃: the relative rounding bound of a slab distance.
const FAR_SCALE: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

/// The slab test of one node: the entry distances of its eight children and the mask of those
/// the ray enters within `[0, t_max]` (bit `i` for child `i`).
trait NodeTest {
    fn test(&self, node: &Node8, t_max: f32) -> ([f32; WIDTH], u32);

    /// The masks of the children whose entry distance in `near` is below `t` and equal to
    /// it (bit `j` for child `j`; entry distances are never NaN where a child is entered).
    #[inline(always)]
    fn before(&self, near: &[f32; WIDTH], t: f32) -> (u32, u32) {
        let (a, b) = (Vec4::from_slice(&near[..4]), Vec4::from_slice(&near[4..]));
        let t = Vec4::splat(t);
        (
            a.cmplt(t).bitmask() | (b.cmplt(t).bitmask() << 4),
            a.cmpeq(t).bitmask() | (b.cmpeq(t).bitmask() << 4),
        )
    }

    /// Writes the children entered in `mask` to `order[..n]` (`n` their number), sorted by
    /// their entry distance in `near`, nearest first, ties by slot: each is put at its rank
    /// (the entered children nearer than it, or as near in a lower slot) without a
    /// data-dependent loop. Entries from `n` on are unspecified.
    #[inline(always)]
    fn order(&self, near: &[f32; WIDTH], mask: u32, order: &mut [Ranked; WIDTH]) {
        let mut rest = mask;
        while rest != 0 {
            let slot = (rest.trailing_zeros() & 7) as usize;
            rest &= rest - 1;
            let t = near[slot];
            let (lt, eq) = self.before(near, t);
            let rank = (mask & (lt | (eq & ((1 << slot) - 1)))).count_ones() as usize;
            order[rank & 7] = Ranked {
                slot: slot as u32,
                t,
            };
        }
    }
}

/// An entered child of a node in the traversal's order: its slot and entry distance.
/// `repr(C)`, so that eight of them are the eight 64-bit lanes `t_bits << 32 | slot` the
/// AVX-512 ordering sorts ([`avx512`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
struct Ranked {
    slot: u32,
    t: f32,
}

impl NodeTest for SlabRay {
    #[inline(always)]
    fn test(&self, node: &Node8, t_max: f32) -> ([f32; WIDTH], u32) {
        let (a, ma) = self.test_half(node, 0, t_max);
        let (b, mb) = self.test_half(node, 1, t_max);
        let mut near = [0.0; WIDTH];
        near[..4].copy_from_slice(&a.to_array());
        near[4..].copy_from_slice(&b.to_array());
        (near, ma | (mb << 4))
    }
}

/// The 8-wide node test's slab distances `P·inv − c` are one fused multiply-add each, with
/// the origin's term `c = o·inv` rounded up for the entry planes and down for the exit planes
/// ([`directed_products`]). With exact subtraction the distance would be `(P − o)·inv`; the
/// directed constants make the computed entry distance at most, and the exit distance at
/// least, the rounding (one rounding, monotonic) of that exact value, whatever the
/// cancellation between `P·inv` and `c`. The reciprocal's own rounding (relative `u`) and the
/// two roundings of the distances are then covered by enlarging the far distance once per
/// node by [`FMA_FAR_SCALE`] ≥ (1 + u)² / (1 − u)³ and [`FMA_FAR_FLOOR`] (absolute errors of
/// subnormal distances): a box the exact slab test enters within `[0, t_max]` is entered.
/// (The 4-wide test, [`SlabRay`], keeps the exact subtraction and the 1 + 2γ₃ bound of Ize
/// 2013; both are conservative, and the closest hit is decided by the triangle test.)
const FMA_FAR_SCALE: f32 = 1.0 + 3.0 * f32::EPSILON;

/// The absolute term added to the far distance with [`FMA_FAR_SCALE`]: the smallest normal
/// float, far above the 2⁻¹⁵⁰ a subnormal distance's rounding can lose.
const FMA_FAR_FLOOR: f32 = f32::MIN_POSITIVE;

/// Per axis, a bound at least and a bound at most the exact product `o·inv`, in four lanes
/// (the last is 0): `c ± (|c|·2⁻²³ + 2⁻¹²⁶)` for `c = o·inv` rounded to nearest. The step is
/// at least one unit in the last place of `c` (`|c|·2⁻²³` is exact for `|c| ≥ 2⁻¹⁰²`, and
/// 2⁻¹²⁶ is at least the unit below that), `c ± ulp(c)` is a float, and rounding is
/// monotonic, so each bound is at least one unit from `c`, where the rounding of `c` was at
/// most half of one. `None` when a bound is not finite (an origin so far out that `o·inv`
/// overflows; such a ray takes the 4-wide test).
#[inline(always)]
fn directed_products(o: Vec3, inv: Vec4) -> Option<(Vec4, Vec4)> {
    let c = Vec4::from((o, 0.0)) * inv;
    let step = c.abs() * f32::EPSILON + Vec4::splat(f32::MIN_POSITIVE);
    let (up, down) = (c + step, c - step);
    (up.is_finite() && down.is_finite()).then_some((up, down))
}

/// The 8-wide AVX2 node test: the entry and exit distances of all eight children, each a fused
/// multiply-add with a directed origin term ([`FMA_FAR_SCALE`]).
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::{
        __m256, _mm256_cmp_ps, _mm256_fmadd_ps, _mm256_fmsub_ps, _mm256_loadu_ps, _mm256_max_ps,
        _mm256_min_ps, _mm256_movemask_ps, _mm256_set1_ps, _mm256_setzero_ps, _mm256_storeu_ps,
        _CMP_EQ_OQ, _CMP_LE_OS, _CMP_LT_OQ,
    };

    use super::{
        directed_products, slab_constants, Node8, NodeTest, FMA_FAR_FLOOR, FMA_FAR_SCALE,
        OCTANT_PLANES, WIDTH,
    };
    use crate::math::Ray;

    /// A ray's constants for the 8-wide test, splatted to 8 lanes. Made only by
    /// [`AvxSlab::from_ray`], which needs AVX2 and FMA.
    pub(super) struct AvxSlab {
        /// The capped reciprocal direction ([`slab_constants`]).
        inv: [__m256; 3],
        /// `o·inv` rounded up: the entry planes' origin term.
        c_near: [__m256; 3],
        /// `o·inv` rounded down: the exit planes' origin term.
        c_far: [__m256; 3],
        near: [usize; 3],
        far: [usize; 3],
    }

    impl AvxSlab {
        /// The constants of `ray`, or `None` when `o·inv` overflows on some axis.
        /// (Not a `target_feature` function, so that it is inlined into the traversal.)
        ///
        /// # Safety
        /// The CPU must support AVX2 and FMA.
        #[inline(always)]
        pub(super) unsafe fn from_ray(ray: &Ray) -> Option<Self> {
            let (inv, neg) = slab_constants(ray);
            let p = OCTANT_PLANES[(neg & 7) as usize];
            let (up, down) = directed_products(ray.o, inv)?;
            // SAFETY: AVX is available (the caller's contract).
            unsafe {
                Some(AvxSlab {
                    inv: [
                        _mm256_set1_ps(inv.x),
                        _mm256_set1_ps(inv.y),
                        _mm256_set1_ps(inv.z),
                    ],
                    c_near: [
                        _mm256_set1_ps(up.x),
                        _mm256_set1_ps(up.y),
                        _mm256_set1_ps(up.z),
                    ],
                    c_far: [
                        _mm256_set1_ps(down.x),
                        _mm256_set1_ps(down.y),
                        _mm256_set1_ps(down.z),
                    ],
                    near: [p[0], p[1], p[2]],
                    far: [p[3], p[4], p[5]],
                })
            }
        }
    }

    impl NodeTest for AvxSlab {
        #[inline(always)]
        fn test(&self, node: &Node8, t_max: f32) -> ([f32; WIDTH], u32) {
            // SAFETY: an `AvxSlab` exists only where AVX2 and FMA are available (its
            // constructor needs them); the plane indices are `k` or `k + 3` (below 6, from
            // `OCTANT_PLANES`); the loads read the 8 contiguous floats of a `[Vec4; 2]`
            // plane, the store writes the 8 floats of `out`.
            unsafe {
                let mut near = _mm256_setzero_ps();
                let mut far = _mm256_set1_ps(t_max);
                for k in 0..3 {
                    let n = _mm256_loadu_ps(
                        node.planes
                            .get_unchecked(self.near[k])
                            .as_ptr()
                            .cast::<f32>(),
                    );
                    let f = _mm256_loadu_ps(
                        node.planes
                            .get_unchecked(self.far[k])
                            .as_ptr()
                            .cast::<f32>(),
                    );
                    near = _mm256_max_ps(near, _mm256_fmsub_ps(n, self.inv[k], self.c_near[k]));
                    far = _mm256_min_ps(far, _mm256_fmsub_ps(f, self.inv[k], self.c_far[k]));
                }
                let far = _mm256_fmadd_ps(
                    far,
                    _mm256_set1_ps(FMA_FAR_SCALE),
                    _mm256_set1_ps(FMA_FAR_FLOOR),
                );
                let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OS>(near, far)) as u32;
                let mut out = [0.0f32; WIDTH];
                _mm256_storeu_ps(out.as_mut_ptr(), near);
                (out, mask)
            }
        }

        #[inline(always)]
        fn before(&self, near: &[f32; WIDTH], t: f32) -> (u32, u32) {
            // SAFETY: AVX2 is available (see `test`); the load reads the 8 floats of `near`.
            unsafe {
                let v = _mm256_loadu_ps(near.as_ptr());
                let t = _mm256_set1_ps(t);
                (
                    _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(v, t)) as u32,
                    _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_EQ_OQ>(v, t)) as u32,
                )
            }
        }
    }
}

/// The traversal compiled for AVX-512 (F and VL) where the CPU has it: the AVX2 node test
/// ([`avx2::AvxSlab`]), the whole traversal in EVEX code with 32 vector registers, and the
/// entered children of a node with three or more ordered at once by a sorting network over
/// eight 64-bit keys ([`sort_entered`]) instead of a rank per child.
#[cfg(target_arch = "x86_64")]
mod avx512 {
    use std::arch::x86_64::{
        __m512i, _mm256_and_si256, _mm256_loadu_si256, _mm256_set1_epi32, _mm512_cvtepu32_epi64,
        _mm512_mask_mov_epi64, _mm512_max_epu64, _mm512_min_epu64, _mm512_or_si512,
        _mm512_permutexvar_epi64, _mm512_set1_epi64, _mm512_set_epi64, _mm512_slli_epi64,
        _mm512_storeu_si512,
    };

    use super::{avx2::AvxSlab, Node8, NodeTest, Ranked, WIDTH};

    /// Whether the CPU runs [`super::WideBvh::traverse_avx512`]: AVX-512 F and VL besides
    /// AVX2, FMA and POPCNT, unless `VELOUR_NO_AVX512` is set (which leaves the AVX2
    /// traversal, for comparisons on one machine).
    pub(super) fn detected() -> bool {
        super::avx2_fma_and_popcnt()
            && std::is_x86_feature_detected!("avx512f")
            && std::is_x86_feature_detected!("avx512vl")
            && std::env::var_os("VELOUR_NO_AVX512").is_none()
    }

    /// The AVX2 node test, in a traversal that may order children with AVX-512. Made only
    /// where [`detected`] holds.
    pub(super) struct Avx512Slab(pub(super) AvxSlab);

    impl NodeTest for Avx512Slab {
        #[inline(always)]
        fn test(&self, node: &Node8, t_max: f32) -> ([f32; WIDTH], u32) {
            self.0.test(node, t_max)
        }

        #[inline(always)]
        fn before(&self, near: &[f32; WIDTH], t: f32) -> (u32, u32) {
            self.0.before(near, t)
        }

        #[inline(always)]
        fn order(&self, near: &[f32; WIDTH], mask: u32, order: &mut [Ranked; WIDTH]) {
            // SAFETY: an `Avx512Slab` exists only where AVX-512 F and VL and AVX2 were
            // detected.
            unsafe { sort_entered(near, mask, order) }
        }
    }

    /// One layer of the bitonic network: lane `i` against lane `partner[i]`, keeping the
    /// larger key in the lanes of `take_max` and the smaller in the others.
    #[inline]
    #[target_feature(enable = "avx2,avx512f,avx512vl")]
    fn layer(x: __m512i, partner: __m512i, take_max: u8) -> __m512i {
        let p = _mm512_permutexvar_epi64(partner, x);
        let lo = _mm512_min_epu64(x, p);
        let hi = _mm512_max_epu64(x, p);
        _mm512_mask_mov_epi64(lo, take_max, hi)
    }

    /// The lanes of a bitonic network's layer (block size `k`, partner distance `j`) that keep
    /// the larger key: in an ascending block (`i & k == 0`) the upper lane of each pair, in a
    /// descending one the lower.
    const fn take_max(k: usize, j: usize) -> u8 {
        let mut m = 0u8;
        let mut i = 0;
        while i < WIDTH {
            let upper = i & j != 0;
            let ascending = i & k == 0;
            if upper == ascending {
                m |= 1 << i;
            }
            i += 1;
        }
        m
    }

    /// [`NodeTest::order`] by sorting eight 64-bit keys, `entry distance bits << 32 | slot`,
    /// in one register: the children not entered get the largest key, so the entered ones
    /// come first, nearest first and ties by slot (the slot breaks them). Entry distances of
    /// entered children are at least zero or `-0`, so with the sign bit cleared (`-0` becomes
    /// `+0`, which compares equal to it) their bits order them as the floats; a sorted key
    /// is its `Ranked` (`repr(C)`: the slot in the low half, the distance in the high).
    /// Bitonic sort (Batcher 1968): six layers of a permute, a min, a max and a blend.
    #[inline]
    #[target_feature(enable = "avx2,avx512f,avx512vl")]
    pub(super) fn sort_entered(near: &[f32; WIDTH], mask: u32, order: &mut [Ranked; WIDTH]) {
        // SAFETY: the load reads the 8 floats of `near`, the store writes the 8 × 8 bytes of
        // `order` (`Ranked` is `repr(C)`, two 4-byte fields).
        let bits = unsafe { _mm256_loadu_si256(near.as_ptr().cast()) };
        let bits = _mm256_and_si256(bits, _mm256_set1_epi32(0x7fff_ffff));
        let keys = _mm512_or_si512(
            _mm512_slli_epi64::<32>(_mm512_cvtepu32_epi64(bits)),
            _mm512_set_epi64(7, 6, 5, 4, 3, 2, 1, 0),
        );
        let mut x = _mm512_mask_mov_epi64(_mm512_set1_epi64(-1), mask as u8, keys);
        // Partners `i ^ j` for j = 1, 2, 4.
        let p1 = _mm512_set_epi64(6, 7, 4, 5, 2, 3, 0, 1);
        let p2 = _mm512_set_epi64(5, 4, 7, 6, 1, 0, 3, 2);
        let p4 = _mm512_set_epi64(3, 2, 1, 0, 7, 6, 5, 4);
        x = layer(x, p1, const { take_max(2, 1) });
        x = layer(x, p2, const { take_max(4, 2) });
        x = layer(x, p1, const { take_max(4, 1) });
        x = layer(x, p4, const { take_max(8, 4) });
        x = layer(x, p2, const { take_max(8, 2) });
        x = layer(x, p1, const { take_max(8, 1) });
        unsafe { _mm512_storeu_si512(order.as_mut_ptr().cast(), x) };
    }
}

/// What [`WideBvh::traverse`] calls for each primitive of an entered leaf: `visit(position,
/// t_max)` returns the new `t_max` (a closer hit's distance, or `t_max`; a value ≤ 0 ends the
/// traversal). Closures are visitors; a query's own type can be one whose `visit` is
/// `#[inline(always)]`, so that the primitive test is compiled into the traversal's loop
/// whatever its size (a closure is inlined at the compiler's discretion).
pub trait LeafVisitor {
    /// Tests primitive `position` against the ray up to `t_max`; returns the new `t_max`.
    fn visit(&mut self, position: u32, t_max: f32) -> f32;

    /// Tests the primitives of `leaf` against the ray up to `t_max`; returns the new
    /// `t_max` (≤ 0 ends the traversal). By default [`Self::visit`] on each position in
    /// order, stopping at a value ≤ 0; a visitor may test a leaf's blocks at once instead
    /// (the triangle queries' four-lane test), with the same answer.
    #[inline(always)]
    fn visit_leaf(&mut self, leaf: Leaf, mut t_max: f32) -> f32 {
        for i in leaf.first..leaf.first + leaf.count {
            t_max = self.visit(i, t_max);
            if t_max <= 0.0 {
                break;
            }
        }
        t_max
    }
}

impl<F: FnMut(u32, f32) -> f32> LeafVisitor for F {
    #[inline(always)]
    fn visit(&mut self, position: u32, t_max: f32) -> f32 {
        self(position, t_max)
    }
}

/// A traversal stack entry: an inner node with the distance the ray enters it.
#[derive(Clone, Copy, Debug, Default)]
struct Entry {
    node: u32,
    t: f32,
}

/// The traversal stack: inline entries, spilling to the heap only for unusually deep trees
/// (`SPILL`; without it, the caller guarantees that the inline entries suffice, see
/// `WideBvh::shallow`). The inline entries are not initialised: only those below `len` are
/// ever read.
struct Stack<'a, const SPILL: bool> {
    inline: &'a mut MaybeUninit<[Entry; STACK_INLINE]>,
    len: usize,
    spill: Vec<Entry>,
}

impl<'a, const SPILL: bool> Stack<'a, SPILL> {
    #[inline(always)]
    fn new(inline: &'a mut MaybeUninit<[Entry; STACK_INLINE]>) -> Self {
        Stack {
            inline,
            len: 0,
            spill: Vec::new(),
        }
    }
    #[inline(always)]
    fn push(&mut self, e: Entry) {
        if !SPILL || self.len < STACK_INLINE {
            debug_assert!(self.len < STACK_INLINE);
            // SAFETY: `len < STACK_INLINE` (checked, or guaranteed by the caller without
            // `SPILL`): the write stays inside the inline array.
            unsafe {
                self.inline
                    .as_mut_ptr()
                    .cast::<Entry>()
                    .add(self.len)
                    .write(e)
            };
            self.len += 1;
        } else {
            self.spill.push(e);
        }
    }
    /// The entry pushed last. The spill is used only once the inline entries are full, so
    /// it is looked at only then.
    #[inline(always)]
    fn pop(&mut self) -> Option<Entry> {
        if self.len == 0 {
            return None;
        }
        if SPILL && self.len == STACK_INLINE {
            if let Some(e) = self.spill.pop() {
                return Some(e);
            }
        }
        self.len -= 1;
        // SAFETY: `len < STACK_INLINE`, and every entry below the old `len` was written by
        // `push`.
        Some(unsafe { self.inline.as_ptr().cast::<Entry>().add(self.len).read() })
    }
}

impl WideBvh {
    /// Builds the hierarchy over `boxes` (min, max per primitive). Primitive positions follow
    /// [`WideBvh::order`].
    #[must_use]
    pub fn build(boxes: &[(Vec3, Vec3)]) -> Self {
        Self::build_with(boxes, Strategy::Sah).0
    }

    /// [`Self::build`] with the collapse `strategy`, and the collapse's predicted cost
    /// ([`Collapse::root_cost`]; NaN when the hierarchy is a single leaf or empty).
    fn build_with(boxes: &[(Vec3, Vec3)], strategy: Strategy) -> (Self, f32) {
        let n = boxes.len();
        if n == 0 {
            return (WideBvh::default(), f32::NAN);
        }
        let prims: Vec<OAabb> = boxes
            .iter()
            .map(|(lo, hi)| OAabb::new(Vec3A::from(*lo), Vec3A::from(*hi)))
            .collect();
        let mut bvh2 = sweep_sah::build(&prims);
        ReinsertionOptimizer::default().run(&mut bvh2, REINSERTION_BATCH_RATIO, None);
        let counts = subtree_counts(&bvh2);
        let mut out = WideBvh {
            avx2: avx2_fma_and_popcnt(),
            avx512: avx512_detected(),
            ..WideBvh::default()
        };
        if counts[0] <= MAX_LEAF_PRIMITIVES {
            let first = out.order.len() as u32;
            collect_primitives(&bvh2, 0, &mut out.order);
            // One node with one leaf child whose box is all of space (always entered).
            let mut node = Node8::empty();
            for k in 0..3 {
                node.planes[k][0][0] = f32::NEG_INFINITY;
                node.planes[k + 3][0][0] = f32::INFINITY;
            }
            node.child[0] = first;
            node.count[0] = out.push_leaf(first);
            out.nodes.push(node);
            out.depth = 1;
            out.shallow = fits_inline_stack(out.depth);
            return (out, f32::NAN);
        }
        let cost = out.collapse(&bvh2, &counts, strategy);
        out.shallow = fits_inline_stack(out.depth);
        (out, cost)
    }

    /// Fills `self` (holding only the detected CPU features) with the wide nodes collapsed
    /// from `bvh2` (more than [`MAX_LEAF_PRIMITIVES`] primitives) by `strategy`; returns the
    /// surface area heuristic's cost of the cheapest collapse.
    fn collapse(&mut self, bvh2: &Bvh2, counts: &[u32], strategy: Strategy) -> f32 {
        let sah = Collapse::new(bvh2, counts);
        self.nodes.push(Node8::empty());
        let mut work = vec![(0usize, 0usize, 1usize)]; // (bvh2 node, wide node, depth)
        let mut children = Vec::with_capacity(WIDTH);
        while let Some((b, w, depth)) = work.pop() {
            self.depth = self.depth.max(depth);
            children.clear();
            match strategy {
                Strategy::Sah => sah.children(bvh2, b, &mut children),
                #[cfg(test)]
                Strategy::Greedy => children.extend(open_children(bvh2, b, counts)),
            }
            let mut node = Node8::empty();
            for (slot, &c) in children.iter().enumerate() {
                let bb = bvh2.nodes[c].aabb;
                for k in 0..3 {
                    node.planes[k][slot / 4][slot % 4] = bb.min[k];
                    node.planes[k + 3][slot / 4][slot % 4] = bb.max[k];
                }
                let leaf = match strategy {
                    Strategy::Sah => sah.is_leaf(c),
                    #[cfg(test)]
                    Strategy::Greedy => counts[c] <= GREEDY_MAX_LEAF,
                };
                if leaf {
                    let first = self.order.len() as u32;
                    collect_primitives(bvh2, c, &mut self.order);
                    node.child[slot] = first;
                    node.count[slot] = self.push_leaf(first);
                } else {
                    let index = self.nodes.len();
                    self.nodes.push(Node8::empty());
                    node.child[slot] = index as u32;
                    work.push((c, index, depth + 1));
                }
            }
            self.nodes[w] = node;
        }
        sah.root_cost
    }

    /// Records the leaf of the positions from `first` to the end of `order`; returns its
    /// [`Node8::count`] entry.
    fn push_leaf(&mut self, first: u32) -> u32 {
        let leaf = Leaf {
            block: self.blocks,
            first,
            count: self.order.len() as u32 - first,
        };
        debug_assert!(leaf.count >= 1 && leaf.count <= MAX_LEAF_PRIMITIVES);
        self.blocks += leaf.blocks();
        self.leaves.push(leaf);
        leaf.count | leaf.block << LEAF_COUNT_BITS
    }

    /// Original primitive index of each position the traversal reports.
    #[must_use]
    pub fn order(&self) -> &[u32] {
        &self.order
    }

    /// The leaves, in the order of their blocks: leaf `i`'s blocks follow leaf `i − 1`'s.
    #[must_use]
    pub fn leaves(&self) -> &[Leaf] {
        &self.leaves
    }

    /// Depth in nodes (0 when empty).
    #[must_use]
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// Visits, nearest first, every leaf the ray enters within `[0, t_max]`, calling
    /// `primitive(position, t_max)` for each of its primitives; `primitive` returns the new
    /// `t_max` (the distance of a closer hit, or the same value). Returns early when
    /// `primitive` returns a value ≤ 0 (an any-hit query that found something).
    ///
    /// Only the choice of traversal, inlined where it is called, so that a query calls the
    /// traversal for its CPU directly (the portable one is out of line: with it inlined here,
    /// this layer saved and restored six registers on every query).
    #[inline(always)]
    pub fn traverse(&self, ray: &Ray, t_max: f32, primitive: impl LeafVisitor) {
        if self.nodes.is_empty() {
            return;
        }
        #[cfg(target_arch = "x86_64")]
        if self.avx512 {
            // SAFETY: `avx512` is set only when the CPU reported AVX-512 F and VL, AVX2,
            // FMA and POPCNT.
            unsafe { self.traverse_avx512(ray, t_max, primitive) };
            return;
        }
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only when the CPU reported AVX2, FMA and POPCNT.
            unsafe { self.traverse_avx2(ray, t_max, primitive) };
            return;
        }
        self.traverse_portable(ray, t_max, primitive);
    }

    /// [`Self::traverse`] with the 4-wide node test (`SlabRay`), for CPUs without AVX2 and
    /// FMA.
    #[inline(never)]
    fn traverse_portable(&self, ray: &Ray, t_max: f32, primitive: impl LeafVisitor) {
        let slab = SlabRay::new(ray);
        if self.shallow() {
            self.traverse_with::<_, false>(&slab, t_max, primitive);
        } else {
            self.traverse_with::<_, true>(&slab, t_max, primitive);
        }
    }

    /// True when the traversal stack never holds more than its inline entries
    /// ([`fits_inline_stack`] of the depth, computed when the hierarchy was built).
    #[inline(always)]
    fn shallow(&self) -> bool {
        debug_assert_eq!(self.shallow, fits_inline_stack(self.depth));
        self.shallow
    }

    /// [`Self::traverse`] compiled for AVX2 and FMA, with the 8-wide node test.
    ///
    /// # Safety
    /// The CPU must support AVX2, FMA and POPCNT.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,popcnt")]
    unsafe fn traverse_avx2(&self, ray: &Ray, t_max: f32, primitive: impl LeafVisitor) {
        // SAFETY: this function runs only with AVX2 and FMA.
        unsafe { self.traverse_wide(ray, t_max, primitive, |slab| slab) }
    }

    /// The body of the AVX2 and AVX-512 traversals, inlined into each (so compiled for its
    /// features): the 8-wide node test made from `ray` and handed to the traversal through
    /// `wrap`, or the 4-wide one where `o·inv` overflows `f32`.
    ///
    /// # Safety
    /// The CPU must support AVX2 and FMA.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn traverse_wide<W: NodeTest>(
        &self,
        ray: &Ray,
        t_max: f32,
        primitive: impl LeafVisitor,
        wrap: impl FnOnce(avx2::AvxSlab) -> W,
    ) {
        // SAFETY: AVX2 and FMA are available (the caller's contract).
        let Some(wide) = (unsafe { avx2::AvxSlab::from_ray(ray) }) else {
            // `o·inv` overflows `f32`: the 4-wide test, which has no such term.
            let slab = SlabRay::new(ray);
            if self.shallow() {
                self.traverse_with::<_, false>(&slab, t_max, primitive);
            } else {
                self.traverse_with::<_, true>(&slab, t_max, primitive);
            }
            return;
        };
        let wide = wrap(wide);
        if self.shallow() {
            self.traverse_with::<_, false>(&wide, t_max, primitive);
        } else {
            self.traverse_with::<_, true>(&wide, t_max, primitive);
        }
    }

    /// [`Self::traverse_avx2`] compiled for AVX-512 F and VL as well: the same node test,
    /// the children of a node with three or more entered ordered by a sorting network
    /// ([`avx512::sort_entered`]); the same visits in the same order.
    ///
    /// # Safety
    /// The CPU must support AVX-512 F and VL, AVX2, FMA and POPCNT.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,popcnt,avx512f,avx512vl")]
    unsafe fn traverse_avx512(&self, ray: &Ray, t_max: f32, primitive: impl LeafVisitor) {
        // SAFETY: this function runs only with AVX-512 F and VL, AVX2, FMA and POPCNT.
        unsafe { self.traverse_wide(ray, t_max, primitive, avx512::Avx512Slab) }
    }

    /// Asks the CPU to bring the four cache lines of inner node `index` towards the core
    /// (a hint: no fault, no visible effect; `index` may be any value). Issued for a child
    /// that waits on the stack or behind leaf tests, so that its lines arrive meanwhile.
    #[inline(always)]
    fn prefetch_node(&self, index: u32) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            let p = self
                .nodes
                .as_ptr()
                .wrapping_add(index as usize)
                .cast::<i8>();
            // SAFETY: a prefetch is a hint that never faults, whatever the address.
            unsafe {
                _mm_prefetch::<_MM_HINT_T0>(p);
                _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64));
                _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(128));
                _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(192));
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = index;
    }

    /// Forces the 4-wide node test (tests compare it with the 8-wide one).
    #[cfg(test)]
    pub(super) fn without_avx2(mut self) -> Self {
        self.avx2 = false;
        self.avx512 = false;
        self
    }

    /// Forces the AVX2 traversal where the AVX-512 one would run (tests compare the two).
    #[cfg(test)]
    pub(super) fn without_avx512(mut self) -> Self {
        self.avx512 = false;
        self
    }

    /// Whether this hierarchy's traversal is the AVX-512 one.
    #[cfg(test)]
    pub(super) fn uses_avx512(&self) -> bool {
        self.avx512
    }

    /// The traversal with node test `slab`. One or two entered children (most nodes) are
    /// ordered without the general insertion sort; every case visits the children in the
    /// order the general one does (nearest first, ties by slot), tests leaves at once and
    /// pushes inner children farthest first, so hits are the same.
    #[inline(always)]
    fn traverse_with<T: NodeTest, const SPILL: bool>(
        &self,
        slab: &T,
        mut t_max: f32,
        mut primitive: impl LeafVisitor,
    ) {
        let mut stack_entries = MaybeUninit::uninit();
        let mut stack = Stack::<SPILL>::new(&mut stack_entries);
        let mut current = 0u32;
        // Scratch for the children of a node with three or more entered (only entries below
        // the counts are read), initialised once per ray.
        let mut order = [Ranked::default(); WIDTH];
        let mut inner = [Entry::default(); WIDTH];
        // Tests the leaf in slot `$slot` of `node`; returns from the traversal when
        // `primitive` ends it.
        macro_rules! leaf {
            ($node:expr, $slot:expr) => {{
                let c = $node.count[$slot];
                t_max = primitive.visit_leaf(
                    Leaf {
                        block: c >> LEAF_COUNT_BITS,
                        first: $node.child[$slot],
                        count: c & LEAF_COUNT_MASK,
                    },
                    t_max,
                );
                if t_max <= 0.0 {
                    return;
                }
            }};
        }
        loop {
            // SAFETY: `current` is the root (the hierarchy is not empty) or a child index the
            // build wrote, both below `nodes.len()`.
            let node = unsafe { self.nodes.get_unchecked(current as usize) };
            let (near, mask) = slab.test(node, t_max);
            // (Slots are below 8: the mask has 8 bits.)
            let s0 = (mask.trailing_zeros() & 7) as usize;
            let rest = mask & mask.wrapping_sub(1);
            if mask == 0 {
                // Nothing entered.
            } else if rest == 0 {
                // One child. (An entered child's entry distance is at most `t_max`: the node
                // test's far distance starts at `t_max`; so no distance test here or for the
                // nearer of two children below.)
                if node.count[s0] == 0 {
                    current = node.child[s0];
                    continue;
                }
                leaf!(node, s0);
            } else if rest & (rest - 1) == 0 {
                // Two children, nearest first (a tie keeps the lower slot first).
                let s1 = (rest.trailing_zeros() & 7) as usize;
                let (a, b) = if near[s1] < near[s0] {
                    (s1, s0)
                } else {
                    (s0, s1)
                };
                let (ta, tb) = (near[a], near[b]);
                if node.count[a] > 0 {
                    if node.count[b] == 0 {
                        self.prefetch_node(node.child[b]);
                    }
                    leaf!(node, a);
                    if !(tb > t_max) {
                        if node.count[b] > 0 {
                            leaf!(node, b);
                        } else {
                            current = node.child[b];
                            continue;
                        }
                    }
                } else if node.count[b] > 0 {
                    leaf!(node, b);
                    // (The leaf may have shortened the ray.)
                    if !(ta > t_max) {
                        current = node.child[a];
                        continue;
                    }
                } else {
                    self.prefetch_node(node.child[b]);
                    stack.push(Entry {
                        node: node.child[b],
                        t: tb,
                    });
                    current = node.child[a];
                    continue;
                }
            } else {
                // Three or more: the entered children sorted by entry distance, nearest
                // first, ties by slot ([`NodeTest::order`]).
                let n = mask.count_ones() as usize;
                slab.order(&near, mask, &mut order);
                // Leaves are intersected at once, nearest first (a hit shortens the ray for
                // the rest); inner children are pushed farthest first, so the nearest is
                // visited next.
                let mut m = 0;
                for &Ranked { slot, t } in &order[..n] {
                    if t > t_max {
                        break;
                    }
                    let slot = (slot & 7) as usize;
                    if node.count[slot] > 0 {
                        leaf!(node, slot);
                    } else {
                        self.prefetch_node(node.child[slot]);
                        inner[m] = Entry {
                            node: node.child[slot],
                            t,
                        };
                        m += 1;
                    }
                }
                // The nearest inner child is visited next; the others wait, farthest
                // deepest.
                if m > 0 {
                    for e in inner[1..m].iter().rev() {
                        stack.push(*e);
                    }
                    // (A leaf after it may have shortened the ray.)
                    if !(inner[0].t > t_max) {
                        current = inner[0].node;
                        continue;
                    }
                }
            }
            loop {
                match stack.pop() {
                    None => return,
                    Some(e) if !(e.t > t_max) => {
                        current = e.node;
                        break;
                    }
                    Some(_) => {}
                }
            }
        }
    }
}

/// True when a hierarchy `depth` nodes deep never needs more than the stack's inline entries:
/// a node pushes at most `WIDTH − 1` children, and the entries on the stack come from the
/// nodes on the path to the current one, one node per level above it.
fn fits_inline_stack(depth: usize) -> bool {
    depth.saturating_sub(1) * (WIDTH - 1) <= STACK_INLINE
}

/// Whether the CPU runs the 8-wide node test: AVX2 ([`crate::math::avx2_enabled`], which
/// `VELOUR_NO_AVX2=1` turns off), FMA (its slab distances) and POPCNT (the ranks of the
/// children it orders).
fn avx2_fma_and_popcnt() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        crate::math::avx2_enabled()
            && std::is_x86_feature_detected!("fma")
            && std::is_x86_feature_detected!("popcnt")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Whether the CPU runs the AVX-512 traversal (see `avx512::detected`).
fn avx512_detected() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        avx512::detected()
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Primitives under each bvh2 node.
fn subtree_counts(bvh2: &Bvh2) -> Vec<u32> {
    let mut counts = vec![0u32; bvh2.nodes.len()];
    // Children come after their parents only sometimes (reinsertion moves nodes): compute iteratively
    // in post-order.
    let mut stack = vec![(0usize, false)];
    while let Some((i, done)) = stack.pop() {
        let node = &bvh2.nodes[i];
        if node.prim_count > 0 {
            counts[i] = node.prim_count;
            continue;
        }
        let (a, b) = (node.first_index as usize, node.first_index as usize + 1);
        if done {
            counts[i] = counts[a].saturating_add(counts[b]);
        } else {
            stack.push((i, true));
            stack.push((a, false));
            stack.push((b, false));
        }
    }
    counts
}

/// What a bvh2 node becomes in the wide tree when it may take up to `i` slots of its parent.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Choice {
    /// One slot: a leaf with all the node's primitives.
    Leaf,
    /// One slot: a wide node of its own.
    Internal,
    /// Its children take the slots: `k` for the first child, the rest for the second.
    Split(u8),
}

/// How the binary hierarchy is collapsed into wide nodes.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Strategy {
    /// [`Collapse`]: the surface-area heuristic's cheapest collapse.
    Sah,
    /// The greedy top-down collapse it replaced ([`open_children`]; tests compare the two).
    #[cfg(test)]
    Greedy,
}

/// The collapse's cost of a wide node, per unit of its box's half area (the probability that
/// a ray enters it): testing its eight boxes.
const NODE_COST: f32 = 1.0;

/// The collapse's cost of one block of a leaf ([`LEAF_BLOCK`] primitives tested at once in
/// SIMD lanes), per unit of the leaf box's half area, relative to [`NODE_COST`]. A leaf of
/// one to four triangles costs the same, so the collapse fills its leaves; at 0.5 the 20k
/// icosphere's tree has 789 nodes (96 % of the slots used) and 5,279 leaves in 6,537 blocks,
/// against 1,702 nodes and 11,655 leaves when a leaf was priced at 0.2 a triangle (costs
/// from 0.3 to 1.2 measured in concurrent pairs: 0.5 was the fastest on closest hits). Those
/// counts are over `obvhs`'s PLOC hierarchy; over the sweep build ([`super::sweep_sah`]) the
/// tree had 704 nodes (97.6 %) and 4,793 leaves in 6,392 blocks at 0.5 with leaves of up to
/// eight. At 0.4 with leaves of up to twelve ([`MAX_LEAF_PRIMITIVES`]) it has 599 nodes: on
/// the skin scene's recorded `mix20k` closest hits 4.29 node tests and 2.24 block tests a
/// query against 4.45 and 1.95 (fewer dependent node loads for more lanes of triangle tests);
/// the skin's whole recorded log ran 1.021 times as fast (median of 16 concurrent pairs, 15
/// above 1, against a control of 1.000).
const BLOCK_COST: f32 = 0.4;

/// The collapse's cost of a leaf with `count` primitives, per unit of its box's half area:
/// [`BLOCK_COST`] per block, as its primitives are tested a block at a time (∞ above
/// [`MAX_LEAF_PRIMITIVES`]).
fn leaf_cost(count: u32) -> f32 {
    if count > MAX_LEAF_PRIMITIVES {
        return f32::INFINITY;
    }
    BLOCK_COST * count.div_ceil(LEAF_BLOCK) as f32
}

/// The surface-area-heuristic collapse of the binary hierarchy into 8-wide nodes (Ylitie,
/// Karras and Laine 2017, "Efficient incoherent ray traversal on GPUs through compressed wide
/// BVHs"): per bvh2 node and slot budget `i`, the cheapest of a leaf, a node of its own, or
/// the two children sharing the `i` slots, found bottom-up by dynamic programming.
struct Collapse {
    /// `choice[n][i - 1]`: what node `n` becomes with at most `i` slots.
    choice: Vec<[Choice; WIDTH]>,
    /// The split of node `n`'s eight slots between its children when it is a wide node.
    split: Vec<u8>,
    /// The cost of the whole collapse, the root as a wide node (tests check it against the
    /// built tree): the sum over wide nodes of half area × [`NODE_COST`] and over leaves of
    /// half area × [`leaf_cost`].
    root_cost: f32,
}

impl Collapse {
    fn new(bvh2: &Bvh2, counts: &[u32]) -> Self {
        let n = bvh2.nodes.len();
        let mut cost = vec![[f32::INFINITY; WIDTH]; n];
        let mut choice = vec![[Choice::Leaf; WIDTH]; n];
        let mut split = vec![0u8; n];
        // Post-order: both children before their parent.
        let mut stack = vec![(0usize, false)];
        while let Some((i, done)) = stack.pop() {
            let node = &bvh2.nodes[i];
            let area = node.aabb.half_area();
            if node.prim_count > 0 {
                cost[i] = [area * leaf_cost(counts[i]); WIDTH];
                continue;
            }
            let (a, b) = (node.first_index as usize, node.first_index as usize + 1);
            if !done {
                stack.push((i, true));
                stack.push((a, false));
                stack.push((b, false));
                continue;
            }
            // The cheapest way for the two children to share `s` slots.
            let distribute = |s: usize| -> (f32, u8) {
                let mut best = (f32::INFINITY, 1u8);
                for k in 1..s {
                    let c = cost[a][k - 1] + cost[b][s - k - 1];
                    if c < best.0 {
                        best = (c, k as u8);
                    }
                }
                best
            };
            let (inner, k8) = distribute(WIDTH);
            split[i] = k8;
            let internal = area * NODE_COST + inner;
            let leaf = area * leaf_cost(counts[i]);
            let mut c = [f32::INFINITY; WIDTH];
            let mut ch = [Choice::Leaf; WIDTH];
            (c[0], ch[0]) = if leaf <= internal {
                (leaf, Choice::Leaf)
            } else {
                (internal, Choice::Internal)
            };
            for s in 2..=WIDTH {
                let (d, k) = distribute(s);
                (c[s - 1], ch[s - 1]) = if d < c[s - 2] {
                    (d, Choice::Split(k))
                } else {
                    (c[s - 2], ch[s - 2])
                };
            }
            cost[i] = c;
            choice[i] = ch;
        }
        let root = &bvh2.nodes[0];
        let root_cost = if root.prim_count == 0 {
            let a = root.first_index as usize;
            let k = split[0] as usize;
            root.aabb.half_area() * NODE_COST + cost[a][k - 1] + cost[a + 1][WIDTH - k - 1]
        } else {
            f32::NAN
        };
        Collapse {
            choice,
            split,
            root_cost,
        }
    }

    /// Whether bvh2 node `c`, a slot of a wide node, is a leaf.
    fn is_leaf(&self, c: usize) -> bool {
        self.choice[c][0] == Choice::Leaf
    }

    /// The bvh2 nodes that fill the slots of the wide node made for bvh2 node `i`.
    fn children(&self, bvh2: &Bvh2, i: usize, out: &mut Vec<usize>) {
        let first = bvh2.nodes[i].first_index as usize;
        let k = self.split[i] as usize;
        self.slots(bvh2, first, k, out);
        self.slots(bvh2, first + 1, WIDTH - k, out);
    }

    fn slots(&self, bvh2: &Bvh2, i: usize, s: usize, out: &mut Vec<usize>) {
        match self.choice[i][s - 1] {
            Choice::Leaf | Choice::Internal => out.push(i),
            Choice::Split(k) => {
                let first = bvh2.nodes[i].first_index as usize;
                self.slots(bvh2, first, k as usize, out);
                self.slots(bvh2, first + 1, s - k as usize, out);
            }
        }
    }
}

/// Appends the primitives under bvh2 node `i` to `order`.
fn collect_primitives(bvh2: &Bvh2, i: usize, order: &mut Vec<u32>) {
    let mut stack = vec![i];
    while let Some(j) = stack.pop() {
        let node = &bvh2.nodes[j];
        if node.prim_count > 0 {
            let first = node.first_index as usize;
            for k in first..first + node.prim_count as usize {
                order.push(bvh2.primitive_indices[k]);
            }
        } else {
            stack.push(node.first_index as usize + 1);
            stack.push(node.first_index as usize);
        }
    }
}

/// The greedy collapse's leaves hold at most this many primitives.
#[cfg(test)]
const GREEDY_MAX_LEAF: u32 = 2;

/// Subtrees of at most this many primitives are opened first when the greedy collapse
/// collects a node's children: left as children, they would become nodes with two or three of
/// their eight slots used.
#[cfg(test)]
const SMALL_SUBTREE: u32 = 6;

/// The greedy top-down collapse (replaced by [`Collapse`]; tests compare the two): up to eight
/// bvh2 nodes that become the children of the wide node for bvh2 node `i`: its two children,
/// then repeatedly an inner one (that is not to become a leaf) opened: the largest of the
/// small subtrees ([`SMALL_SUBTREE`]) while there are any, else the largest (Wald et al. 2008,
/// "Getting Rid of Packets").
#[cfg(test)]
fn open_children(bvh2: &Bvh2, i: usize, counts: &[u32]) -> Vec<usize> {
    let first = bvh2.nodes[i].first_index as usize;
    let mut children = vec![first, first + 1];
    while children.len() < WIDTH {
        let candidate = children
            .iter()
            .enumerate()
            .filter(|(_, &c)| bvh2.nodes[c].prim_count == 0 && counts[c] > GREEDY_MAX_LEAF)
            .max_by(|(_, &a), (_, &b)| {
                let small = |c: usize| counts[c] <= SMALL_SUBTREE;
                small(a).cmp(&small(b)).then(
                    bvh2.nodes[a]
                        .aabb
                        .half_area()
                        .total_cmp(&bvh2.nodes[b].aabb.half_area()),
                )
            })
            .map(|(k, _)| k);
        let Some(k) = candidate else { break };
        let c = children.swap_remove(k);
        let f = bvh2.nodes[c].first_index as usize;
        children.push(f);
        children.push(f + 1);
    }
    children
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator (tests only).
    struct Lcg(u64);

    impl Lcg {
        fn next(&mut self) -> f32 {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (self.0 >> 40) as f32 / (1u64 << 24) as f32
        }
        fn vec(&mut self) -> Vec3 {
            Vec3::new(self.next(), self.next(), self.next()) * 2.0 - Vec3::ONE
        }
        /// `n` boxes centred in [−1, 1]³ with half-extents up to `half` per axis.
        fn boxes(&mut self, n: usize, half: f32) -> Vec<(Vec3, Vec3)> {
            (0..n)
                .map(|_| {
                    let c = self.vec();
                    let e = Vec3::new(self.next(), self.next(), self.next()) * half;
                    (c - e, c + e)
                })
                .collect()
        }
    }

    /// Entry and exit of the ray through a box in f64, or `None`.
    fn slab(ray: &Ray, lo: Vec3, hi: Vec3) -> Option<(f64, f64)> {
        let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
        for k in 0..3 {
            let (o, d) = (f64::from(ray.o[k]), f64::from(ray.d[k]));
            let (a, b) = ((f64::from(lo[k]) - o) / d, (f64::from(hi[k]) - o) / d);
            t0 = t0.max(a.min(b));
            t1 = t1.min(a.max(b));
        }
        (t0 <= t1).then_some((t0, t1))
    }

    /// The node test in its negated form, `(o − P)·(−inv)`, against the plain slab
    /// distances `(P − o)·inv` written out per child: the same entered children and entry
    /// distances equal as numbers (a zero may differ in sign), also for origins exactly on
    /// a child's planes (distances exactly zero) and directions with zero components.
    #[test]
    fn the_negated_slab_distances_are_the_plain_ones() {
        let mut rng = Lcg(29);
        let boxes = rng.boxes(2000, 0.1);
        let bvh = WideBvh::build(&boxes);
        let (mut entered, mut zeros) = (0, 0);
        for i in 0..40_000 {
            let node = &bvh.nodes[i % bvh.nodes.len()];
            let mut d = rng.vec().normalize_or(Vec3::X);
            if i % 5 == 0 {
                d[i % 3] = 0.0;
            }
            let mut o = rng.vec() * 1.5;
            if i % 2 == 0 {
                // On a child's plane along one or more axes.
                let c = i / 2 % WIDTH;
                for k in 0..=(i / 16 % 3) {
                    let plane = node.planes[k + 3 * (i / 4 % 2)][c / 4].to_array()[c % 4];
                    if plane.is_finite() {
                        o[k] = plane;
                    }
                }
            }
            let (ray, t_max) = test_ray(o, d, i, &mut rng);
            let (inv, neg) = slab_constants(&ray);
            let p = OCTANT_PLANES[(neg & 7) as usize];
            let (got, mask) = SlabRay::new(&ray).test(node, t_max);
            for (c, &entry) in got.iter().enumerate() {
                let (mut near, mut far) = (0.0f32, t_max);
                for k in 0..3 {
                    let n = node.planes[p[k]][c / 4].to_array()[c % 4];
                    let f = node.planes[p[k + 3]][c / 4].to_array()[c % 4];
                    near = near.max((n - o[k]) * inv[k]);
                    far = far.min((f - o[k]) * inv[k] * FAR_SCALE);
                    zeros += usize::from(n == o[k]);
                }
                let inside = near <= far;
                assert_eq!(mask & (1 << c) != 0, inside, "ray {i} child {c}");
                if inside {
                    assert_eq!(entry, near, "ray {i} child {c}");
                    entered += 1;
                }
            }
        }
        assert!(
            entered > 10_000 && zeros > 5_000,
            "{entered} entered, {zeros} zeros"
        );
    }

    /// A test ray from `o` along `d` and its bound: for every third `i` a finite `t_max` in
    /// `[0, 2)` drawn from `rng`, otherwise unbounded.
    fn test_ray(o: Vec3, d: Vec3, i: usize, rng: &mut Lcg) -> (Ray, f32) {
        let t_max = if i.is_multiple_of(3) {
            rng.next() * 2.0
        } else {
            f32::INFINITY
        };
        (Ray::new(o, d), t_max)
    }

    /// Entry and exit of the ray through a box in f64 within `[0, t_max]`, or `None`; a zero
    /// direction component leaves its axis unbounded when the origin lies strictly inside
    /// the slab (callers avoid origins on such an axis's planes).
    fn exact_slab(ray: &Ray, lo: Vec3, hi: Vec3, t_max: f32) -> Option<(f64, f64)> {
        let (mut t0, mut t1) = (0.0f64, f64::from(t_max));
        for k in 0..3 {
            let (o, d) = (f64::from(ray.o[k]), f64::from(ray.d[k]));
            let (lo, hi) = (f64::from(lo[k]), f64::from(hi[k]));
            if d == 0.0 {
                if !(lo < o && o < hi) {
                    return None;
                }
                continue;
            }
            let (a, b) = ((lo - o) / d, (hi - o) / d);
            t0 = t0.max(a.min(b));
            t1 = t1.min(a.max(b));
        }
        (t0 <= t1).then_some((t0, t1))
    }

    /// The bounds of `directed_products` enclose the exact product `o·inv` (in f64, where it
    /// is exact) and are at most two units in the last place from it, for magnitudes from
    /// subnormal to near overflow, signs, zeros and exactly representable products.
    #[test]
    fn directed_products_enclose_the_exact_product() {
        let mut rng = Lcg(5);
        let mut checked = 0;
        for i in 0..200_000 {
            let e = |r: f32| 2f32.powi((r * 120.0) as i32 - 60);
            let mut o = rng.vec() * Vec3::new(e(rng.next()), e(rng.next()), e(rng.next()));
            let mut inv =
                Vec4::from((rng.vec(), 1.0)) * Vec4::new(e(rng.next()), e(rng.next()), 1e20, 1.0);
            match i % 7 {
                0 => o[i % 3] = 0.0,
                1 => o = o.round(),
                2 => inv = Vec4::new(0.5, -0.25, 1e20, 1.0),
                3 => o *= 1e-30,
                4 => o = Vec3::splat(f32::MIN_POSITIVE * 3.0),
                _ => {}
            }
            let Some((up, down)) = directed_products(o, inv) else {
                continue;
            };
            for k in 0..3 {
                let exact = f64::from(o[k]) * f64::from(inv[k]);
                let (u, d) = (f64::from(up[k]), f64::from(down[k]));
                assert!(d <= exact && exact <= u, "{i} axis {k}: {d} {exact} {u}");
                let ulp = (exact.abs() * 2f64.powi(-22)).max(2f64.powi(-124));
                assert!(u - d <= 2.0 * ulp, "{i} axis {k}: {d} {exact} {u}");
                checked += 1;
            }
        }
        assert!(checked > 500_000, "{checked}");
        // An overflowing product has no finite bounds.
        let far = Vec3::new(1e30, 0.0, 0.0);
        assert!(directed_products(far, Vec4::new(1e20, 1.0, 1.0, 1.0)).is_none());
    }

    /// The node tests never cull a child the exact slab test (f64) enters within
    /// `[0, t_max]`, the 8-wide test with its fused multiply-adds and the 4-wide one, and
    /// their entry distances stay within a few units of rounding of the exact ones: random
    /// rays, half of them from a point exactly on one or more of a child's planes, a fifth
    /// with a zero direction component, grazing rays along a child's face, long and short
    /// `t_max`.
    #[test]
    fn the_node_tests_never_cull_a_box_the_exact_slab_test_enters() {
        let mut rng = Lcg(23);
        let boxes = rng.boxes(2000, 0.1);
        let bvh = WideBvh::build(&boxes);
        let avx = avx2_fma_and_popcnt();
        let (mut entered, mut on_plane) = (0, 0);
        for i in 0..60_000 {
            let node = &bvh.nodes[i % bvh.nodes.len()];
            let c = i / 2 % WIDTH;
            let plane = |p: usize, c: usize| node.planes[p][c / 4].to_array()[c % 4];
            if !plane(0, c).is_finite() {
                continue;
            }
            let (lo, hi) = (
                Vec3::new(plane(0, c), plane(1, c), plane(2, c)),
                Vec3::new(plane(3, c), plane(4, c), plane(5, c)),
            );
            let mut d = rng.vec().normalize_or(Vec3::X);
            let zero_axis = (i % 5 == 0).then_some(i % 3);
            if let Some(k) = zero_axis {
                d[k] = 0.0;
            }
            let mut o = rng.vec() * 1.5;
            if i % 2 == 0 {
                for k in 0..=(i / 16 % 3) {
                    if Some(k) != zero_axis {
                        o[k] = if i / 4 % 2 == 0 { lo[k] } else { hi[k] };
                        on_plane += 1;
                    }
                }
            }
            if i % 11 == 0 {
                // Grazing: aimed at a point on the child's face, from outside.
                let mut target = lo + (hi - lo) * Vec3::new(rng.next(), rng.next(), rng.next());
                target[i % 3] = lo[i % 3];
                o = target - d * (1.0 + rng.next());
            }
            if let Some(k) = zero_axis {
                if o[k] == lo[k] || o[k] == hi[k] {
                    continue;
                }
            }
            let (ray, t_max) = test_ray(o, d, i, &mut rng);
            let Some((t0, _)) = exact_slab(&ray, lo, hi, t_max) else {
                continue;
            };
            entered += 1;
            let mut tests = vec![SlabRay::new(&ray).test(node, t_max)];
            #[cfg(target_arch = "x86_64")]
            if avx {
                // SAFETY: AVX2 and FMA were detected.
                let wide = unsafe { avx2::AvxSlab::from_ray(&ray) }.expect("a finite ray");
                tests.push(wide.test(node, t_max));
            }
            // The 8-wide test's distances are off by up to two units of `o·inv` (its
            // origin terms), the 4-wide test's by a few units of the distance.
            let origin_term = (0..3)
                .filter(|&k| d[k] != 0.0)
                .map(|k| f64::from(o[k] / d[k]).abs())
                .fold(0.0, f64::max);
            for (which, (near, mask)) in tests.iter().enumerate() {
                assert!(
                    mask & (1 << c) != 0,
                    "ray {i} child {c} test {which}: culled"
                );
                let err = (f64::from(near[c]) - t0).abs();
                assert!(
                    err <= (t0 + origin_term) * 1e-6 + 1e-30,
                    "ray {i} child {c} test {which}: entry {} against {t0}",
                    near[c]
                );
            }
        }
        assert!(
            entered > 8_000 && on_plane > 10_000,
            "{entered} entered, {on_plane} on planes"
        );
    }

    /// The 8-wide node test's slab distances are each one fused multiply-add of the plane by
    /// the reciprocal minus the directed origin term (`P·inv − c`, rounded once), written out
    /// per child with `f32::mul_add`: the same entered children and entry distances (as
    /// numbers: a zero may differ in sign), whatever form the test adds its origin terms in.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_8_wide_node_test_rounds_each_distance_once() {
        if !avx2_fma_and_popcnt() {
            eprintln!("note: no AVX2 and FMA on this CPU; the 8-wide test is not checked");
            return;
        }
        let mut rng = Lcg(37);
        let boxes = rng.boxes(2000, 0.1);
        let bvh = WideBvh::build(&boxes);
        let (mut entered, mut culled) = (0, 0);
        for i in 0..40_000 {
            let node = &bvh.nodes[i % bvh.nodes.len()];
            let o = rng.vec() * if i % 7 == 0 { 40.0 } else { 1.5 };
            // Most rays aimed at a point in one of the node's children.
            let c = i % WIDTH;
            let plane = |p: usize| node.planes[p][c / 4].to_array()[c % 4];
            let mut d = if i % 4 != 0 && plane(0).is_finite() {
                let (lo, hi) = (
                    Vec3::new(plane(0), plane(1), plane(2)),
                    Vec3::new(plane(3), plane(4), plane(5)),
                );
                (lo + (hi - lo) * Vec3::new(rng.next(), rng.next(), rng.next()) - o)
                    .normalize_or(Vec3::X)
            } else {
                rng.vec().normalize_or(Vec3::X)
            };
            if i % 5 == 0 {
                d[i % 3] = 0.0;
            }
            let (ray, t_max) = test_ray(o, d, i, &mut rng);
            let (inv, neg) = slab_constants(&ray);
            let p = OCTANT_PLANES[(neg & 7) as usize];
            let Some((up, down)) = directed_products(o, inv) else {
                continue;
            };
            // SAFETY: AVX2 and FMA were detected.
            let wide = unsafe { avx2::AvxSlab::from_ray(&ray) }.expect("a finite ray");
            let (got, mask) = wide.test(node, t_max);
            for (c, &entry) in got.iter().enumerate() {
                let (mut near, mut far) = (0.0f32, t_max);
                for k in 0..3 {
                    let n = node.planes[p[k]][c / 4].to_array()[c % 4];
                    let f = node.planes[p[k + 3]][c / 4].to_array()[c % 4];
                    near = near.max(n.mul_add(inv[k], -up[k]));
                    far = far.min(f.mul_add(inv[k], -down[k]));
                }
                let inside = near <= far.mul_add(FMA_FAR_SCALE, FMA_FAR_FLOOR);
                assert_eq!(mask & (1 << c) != 0, inside, "ray {i} child {c}");
                if inside {
                    assert_eq!(entry, near, "ray {i} child {c}");
                    entered += 1;
                } else {
                    culled += 1;
                }
            }
        }
        assert!(
            entered > 10_000 && culled > 10_000,
            "{entered} entered, {culled} culled"
        );
    }

    /// `NodeTest::order` of every node test against a stable sort by entry distance (ties by
    /// slot; `-0` and `+0` equal, as the traversal compares them). The list starts filled
    /// with a slot no child has, so an entry `order` leaves unwritten below the count shows.
    #[test]
    fn children_are_ordered_as_a_stable_sort_by_entry_distance() {
        let mut rng = Lcg(91);
        let ray = Ray::new(Vec3::ZERO, Vec3::X);
        let slab = SlabRay::new(&ray);
        #[cfg(target_arch = "x86_64")]
        let avx = avx2_fma_and_popcnt().then(|| {
            // SAFETY: AVX2 and FMA were detected.
            unsafe { avx2::AvxSlab::from_ray(&ray) }.expect("a finite ray")
        });
        #[cfg(target_arch = "x86_64")]
        let wide = avx512::detected().then(|| {
            // SAFETY: AVX-512 F and VL (and AVX2 and FMA) were detected.
            avx512::Avx512Slab(unsafe { avx2::AvxSlab::from_ray(&ray) }.expect("a finite ray"))
        });
        #[cfg(target_arch = "x86_64")]
        if wide.is_none() {
            eprintln!("note: no AVX-512 on this CPU; its ordering is not tested");
        }
        let mut eights = 0;
        for i in 0..50_000 {
            // Few distinct values, so that ties are common; some zeros of either sign, some
            // large distances (exponent bits high) and some subnormal ones.
            let near: [f32; WIDTH] = std::array::from_fn(|_| {
                let v = (rng.next() * 5.0).floor() * 0.5;
                match i % 4 {
                    0 if v == 0.0 && rng.next() < 0.5 => -0.0,
                    1 => v * 1e30,
                    2 => v * 1e-40,
                    _ => v,
                }
            });
            let mask = if i % 16 == 0 {
                0xff
            } else {
                (rng.next() * 256.0) as u32 & 0xff
            };
            eights += usize::from(mask == 0xff);
            let mut expected: Vec<Ranked> = (0..WIDTH as u32)
                .filter(|&s| mask & (1 << s) != 0)
                .map(|slot| Ranked {
                    slot,
                    t: near[slot as usize],
                })
                .collect();
            // Stable: ties keep slot order. (No NaN among the distances.)
            expected.sort_by(|a, b| a.t.partial_cmp(&b.t).unwrap_or(std::cmp::Ordering::Equal));
            let n = mask.count_ones() as usize;
            let placed = |test: &dyn Fn(&mut [Ranked; WIDTH])| {
                let sentinel = Ranked {
                    slot: 99,
                    t: f32::NAN,
                };
                let mut order = [sentinel; WIDTH];
                test(&mut order);
                order[..n].to_vec()
            };
            assert_eq!(placed(&|o| slab.order(&near, mask, o)), expected);
            #[cfg(target_arch = "x86_64")]
            if let Some(avx) = &avx {
                assert_eq!(placed(&|o| avx.order(&near, mask, o)), expected);
            }
            #[cfg(target_arch = "x86_64")]
            if let Some(wide) = &wide {
                let got = placed(&|o| wide.order(&near, mask, o));
                assert_eq!(got, expected, "{near:?} {mask:#x}");
                // The distances come back bit for bit, but for a zero's sign.
                for (g, e) in got.iter().zip(&expected) {
                    assert_eq!(g.t.to_bits(), e.t.to_bits() & 0x7fff_ffff);
                }
            }
        }
        assert!(eights > 1_000);
    }

    /// The surface area heuristic's cost of a built tree, read from its nodes as
    /// [`Collapse::root_cost`] defines it: the root's box (the union of its children's) and
    /// every inner child's at [`NODE_COST`], every leaf's at [`leaf_cost`].
    fn sah_cost(bvh: &WideBvh) -> f64 {
        let half_area = |lo: [f32; 3], hi: [f32; 3]| {
            let d = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
            f64::from((d[0] + d[1]) * d[2] + d[0] * d[1])
        };
        let (mut root_lo, mut root_hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        let mut cost = 0.0;
        for (i, node) in bvh.nodes.iter().enumerate() {
            for slot in 0..WIDTH {
                let plane = |k: usize| node.planes[k][slot / 4][slot % 4];
                if plane(0) == f32::INFINITY {
                    continue; // an empty slot
                }
                let (lo, hi) = (
                    [plane(0), plane(1), plane(2)],
                    [plane(3), plane(4), plane(5)],
                );
                if i == 0 {
                    for k in 0..3 {
                        root_lo[k] = root_lo[k].min(lo[k]);
                        root_hi[k] = root_hi[k].max(hi[k]);
                    }
                }
                let count = node.count[slot] & LEAF_COUNT_MASK;
                assert!(count <= MAX_LEAF_PRIMITIVES, "a leaf of {count} primitives");
                cost += half_area(lo, hi)
                    * if count > 0 {
                        f64::from(leaf_cost(count))
                    } else {
                        f64::from(NODE_COST)
                    };
            }
        }
        cost + half_area(root_lo, root_hi) * f64::from(NODE_COST)
    }

    #[test]
    fn the_sah_collapse_builds_the_tree_it_prices_and_beats_the_greedy_one() {
        let mut rng = Lcg(23);
        // The smallest set is a few boxes more than one leaf holds (a root of one leaf is
        // not collapsed and has no predicted cost).
        let few = MAX_LEAF_PRIMITIVES as usize + 3;
        for (n, half) in [(few, 0.3f32), (40, 0.3), (500, 0.1), (3000, 0.05)] {
            let boxes = rng.boxes(n, half);
            let (sah, predicted) = WideBvh::build_with(&boxes, Strategy::Sah);
            let (greedy, _) = WideBvh::build_with(&boxes, Strategy::Greedy);
            let mut order = sah.order().to_vec();
            order.sort_unstable();
            assert!(
                order.iter().copied().eq(0..n as u32),
                "{n} boxes: not a permutation"
            );
            let (cost, greedy_cost) = (sah_cost(&sah), sah_cost(&greedy));
            assert!(
                (cost - f64::from(predicted)).abs() <= 1e-4 * cost,
                "{n} boxes: built tree costs {cost}, the collapse predicted {predicted}"
            );
            assert!(
                cost < greedy_cost,
                "{n} boxes: SAH collapse {cost} against greedy {greedy_cost}"
            );
        }
    }

    /// The leaves the traversal visits, written plainly: per node the entered children in a
    /// stable sort by entry distance, leaves tested in that order until one starts beyond the
    /// (shortened) ray, inner children pushed farthest first, every pop culled by distance.
    fn reference_visits(
        bvh: &WideBvh,
        ray: &Ray,
        mut t_max: f32,
        mut primitive: impl FnMut(u32, f32) -> f32,
    ) {
        let slab = SlabRay::new(ray);
        let mut stack = vec![(0u32, 0.0f32)];
        while let Some((n, t)) = stack.pop() {
            if t > t_max {
                continue;
            }
            let node = &bvh.nodes[n as usize];
            let (near, mask) = slab.test(node, t_max);
            let mut entered: Vec<usize> = (0..WIDTH).filter(|&s| mask & (1 << s) != 0).collect();
            entered.sort_by(|&a, &b| near[a].total_cmp(&near[b]));
            let mut inner = Vec::new();
            for s in entered {
                if near[s] > t_max {
                    break;
                }
                if node.count[s] == 0 {
                    inner.push((node.child[s], near[s]));
                    continue;
                }
                let count = node.count[s] & LEAF_COUNT_MASK;
                for i in node.child[s]..node.child[s] + count {
                    t_max = primitive(i, t_max);
                    if t_max <= 0.0 {
                        return;
                    }
                }
            }
            stack.extend(inner.into_iter().rev());
        }
    }

    /// The AVX-512 traversal against the AVX2 one: the same primitives visited with the same
    /// `t_max`, in the same order, bit for bit, over boxes with many exact copies (children
    /// entered at the very same distance, ordered by slot) and rays from inside and outside.
    #[test]
    fn the_avx512_traversal_visits_as_the_avx2_one() {
        let mut rng = Lcg(29);
        let mut checked = 0;
        for n in [9, 60, 500, 4000] {
            let mut boxes = rng.boxes(n, 0.1);
            // Every third box repeated three times.
            let copies: Vec<_> = boxes.iter().step_by(3).copied().collect();
            for b in copies {
                boxes.extend([b, b, b]);
            }
            let wide = WideBvh::build(&boxes);
            if !wide.uses_avx512() {
                eprintln!("note: no AVX-512 on this CPU (or VELOUR_NO_AVX512 set); not compared");
                return;
            }
            let narrow = wide.clone().without_avx512();
            for i in 0..6000 {
                let o = if i % 2 == 0 {
                    rng.vec() * 0.9
                } else {
                    rng.vec() * 3.0
                };
                let ray = Ray::new(o, (rng.vec() - o * 0.3).normalize_or(Vec3::X));
                let t_max = if i % 3 == 0 { 1.0 } else { f32::INFINITY };
                let shorten = |pos: u32, t: f32| match pos % 5 {
                    0 => t * 0.9,
                    2 if i % 7 == 0 => 0.0,
                    _ => t,
                };
                let (mut a, mut b) = (Vec::new(), Vec::new());
                wide.traverse(&ray, t_max, |pos, t: f32| {
                    a.push((pos, t.to_bits()));
                    shorten(pos, t)
                });
                narrow.traverse(&ray, t_max, |pos, t: f32| {
                    b.push((pos, t.to_bits()));
                    shorten(pos, t)
                });
                assert_eq!(a, b, "{n} boxes, ray {i}");
                checked += a.len();
            }
        }
        assert!(checked > 100_000, "{checked}");
    }

    #[test]
    fn the_traversal_visits_leaves_in_the_plain_traversals_order() {
        let mut rng = Lcg(17);
        for n in [5, 40, 300, 3000] {
            let boxes = rng.boxes(n, 0.1);
            for bvh in [
                WideBvh::build(&boxes),
                WideBvh::build(&boxes).without_avx512(),
                WideBvh::build(&boxes).without_avx2(),
            ] {
                for i in 0..4000 {
                    let ray = Ray::new(rng.vec() * 1.5, rng.vec().normalize_or(Vec3::X));
                    // Shortens the ray at some primitives, ends it at a few.
                    let shorten = |pos: u32, t: f32| match pos % 7 {
                        0 => t * 0.8,
                        3 if i % 5 == 0 => 0.0,
                        _ => t,
                    };
                    let t_max = if i % 2 == 0 { f32::INFINITY } else { 1.5 };
                    let (mut fast, mut plain) = (Vec::new(), Vec::new());
                    bvh.traverse(&ray, t_max, |pos, t: f32| {
                        fast.push((pos, t.to_bits()));
                        shorten(pos, t)
                    });
                    reference_visits(&bvh, &ray, t_max, |pos, t| {
                        plain.push((pos, t.to_bits()));
                        shorten(pos, t)
                    });
                    assert_eq!(fast, plain, "{n} boxes, ray {i}");
                }
            }
        }
    }

    #[test]
    fn the_octant_table_gives_each_axis_its_entry_and_exit_planes() {
        for neg in 0..8u32 {
            let row = OCTANT_PLANES[neg as usize];
            for k in 0..3 {
                let negative = neg & (1 << k) != 0;
                assert_eq!(row[k], if negative { k + 3 } else { k }, "{neg} {k}");
                assert_eq!(row[k + 3], if negative { k } else { k + 3 }, "{neg} {k}");
            }
        }
        // The slab ray of a direction in each octant reads its row.
        for neg in 0..8u32 {
            let s = |k: u32| if neg & (1 << k) != 0 { -1.0 } else { 1.0 };
            let d = Vec3::new(s(0) * 0.3, s(1) * 0.5, s(2) * 0.7).normalize();
            let slab = SlabRay::new(&Ray::new(Vec3::ZERO, d));
            let row = OCTANT_PLANES[neg as usize];
            assert_eq!(slab.near, [row[0], row[1], row[2]]);
            assert_eq!(slab.far, [row[3], row[4], row[5]]);
            assert!(slab
                .near
                .iter()
                .zip(slab.far)
                .all(|(n, f)| n % 3 == f % 3 && n != &f));
        }
    }

    #[test]
    fn a_node_prefetch_accepts_any_index() {
        let mut rng = Lcg(3);
        let bvh = WideBvh::build(&rng.boxes(100, 0.1));
        for index in [0, 1, bvh.nodes.len() as u32, u32::MAX / 2, u32::MAX] {
            bvh.prefetch_node(index);
        }
    }

    #[test]
    fn the_stack_spills_past_its_inline_entries_and_pops_in_reverse() {
        let mut entries = MaybeUninit::uninit();
        let mut stack = Stack::<true>::new(&mut entries);
        for i in 0..3 * STACK_INLINE as u32 {
            stack.push(Entry {
                node: i,
                t: i as f32,
            });
        }
        for i in (0..3 * STACK_INLINE as u32).rev() {
            let e = stack.pop().map(|e| (e.node, e.t));
            assert_eq!(e, Some((i, i as f32)));
        }
        assert!(stack.pop().is_none());
    }

    #[test]
    fn the_spilling_and_the_inline_stack_visit_the_same_leaves() {
        let mut rng = Lcg(5);
        let boxes = rng.boxes(3000, 0.1);
        let bvh = WideBvh::build(&boxes);
        assert!(bvh.shallow());
        for i in 0..5000 {
            let ray = Ray::new(rng.vec() * 1.5, rng.vec().normalize_or(Vec3::X));
            let slab = SlabRay::new(&ray);
            let mut seen = (Vec::new(), Vec::new());
            let shorten = |pos: u32, t: f32| if pos.is_multiple_of(3) { t * 0.9 } else { t };
            bvh.traverse_with::<_, true>(&slab, f32::INFINITY, |pos, t: f32| {
                seen.0.push((pos, t.to_bits()));
                shorten(pos, t)
            });
            bvh.traverse_with::<_, false>(&slab, f32::INFINITY, |pos, t: f32| {
                seen.1.push((pos, t.to_bits()));
                shorten(pos, t)
            });
            assert_eq!(seen.0, seen.1, "ray {i}");
        }
    }

    #[test]
    fn every_box_a_ray_crosses_is_visited_nearest_leaf_first_and_any_hit_stops() {
        let mut rng = Lcg(3);
        for n in [1usize, 2, 3, 9, 64, 2000] {
            let boxes = rng.boxes(n, 0.2);
            let bvh = WideBvh::build(&boxes);
            let mut seen = vec![false; n];
            for &i in bvh.order() {
                seen[i as usize] = true;
            }
            assert!(
                seen.iter().all(|&s| s),
                "order is a permutation ({n} boxes)"
            );
            for _ in 0..300 {
                let ray = Ray::new(rng.vec() * 1.5, rng.vec().normalize_or(Vec3::X));
                let mut visited = vec![false; n];
                bvh.traverse(&ray, f32::INFINITY, |pos, t| {
                    visited[bvh.order()[pos as usize] as usize] = true;
                    t
                });
                for (i, b) in boxes.iter().enumerate() {
                    if let Some((t0, t1)) = slab(&ray, b.0, b.1) {
                        if t1 - t0 > 1e-4 {
                            assert!(visited[i], "{n} boxes: box {i} crossed but not visited");
                        }
                    }
                }
                let mut calls = 0;
                bvh.traverse(&ray, f32::INFINITY, |_, _| {
                    calls += 1;
                    0.0
                });
                assert!(calls <= 1, "an any-hit query continues after a hit");
            }
        }
    }

    /// Closest hit of a ray with a triangle (Möller–Trumbore in f64), or `None`.
    fn hit_triangle(ray: &Ray, tri: &[Vec3; 3]) -> Option<f64> {
        let f = |v: Vec3| [f64::from(v.x), f64::from(v.y), f64::from(v.z)];
        let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        let cross = |a: [f64; 3], b: [f64; 3]| {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let (v0, v1, v2) = (f(tri[0]), f(tri[1]), f(tri[2]));
        let (o, d) = (f(ray.o), f(ray.d));
        let (e1, e2) = (sub(v1, v0), sub(v2, v0));
        let p = cross(d, e2);
        let det = dot(e1, p);
        if det.abs() < 1e-300 {
            return None;
        }
        let s = sub(o, v0);
        let u = dot(s, p) / det;
        let q = cross(s, e1);
        let v = dot(d, q) / det;
        let t = dot(e2, q) / det;
        (u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0).then_some(t)
    }

    #[test]
    fn traversal_finds_the_brute_force_hits_over_random_rays() {
        let mut rng = Lcg(77);
        for n in [1usize, 4, 5, 37, 600, 4000] {
            let tris: Vec<[Vec3; 3]> = (0..n)
                .map(|_| {
                    let c = rng.vec();
                    [c, c + rng.vec() * 0.15, c + rng.vec() * 0.15]
                })
                .collect();
            let boxes: Vec<(Vec3, Vec3)> = tris
                .iter()
                .map(|t| (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2])))
                .collect();
            let bvh = WideBvh::build(&boxes);
            for narrow in [false, true] {
                let bvh = if narrow {
                    bvh.clone().without_avx2()
                } else {
                    bvh.clone()
                };
                for i in 0..2000 {
                    // Half from outside towards the triangles, half from inside the cloud.
                    let o = if i % 2 == 0 {
                        rng.vec() * 3.0
                    } else {
                        rng.vec() * 0.8
                    };
                    let d = (rng.vec() * 0.9 - o * if i % 2 == 0 { 0.3 } else { 0.0 })
                        .normalize_or(Vec3::X);
                    let ray = Ray::new(o, d);
                    let t_max = if i % 4 == 3 {
                        rng.next() * 2.0
                    } else {
                        f32::INFINITY
                    };
                    // Brute force: the nearest hit below `t_max` (f32 distances, as the
                    // traversal's closure sees them), lowest index on a tie.
                    let mut best: Option<(f32, u32)> = None;
                    for (k, tri) in tris.iter().enumerate() {
                        if let Some(t) = hit_triangle(&ray, tri) {
                            let t = t as f32;
                            if t < t_max && best.is_none_or(|b| t < b.0) {
                                best = Some((t, k as u32));
                            }
                        }
                    }
                    let mut found: Option<(f32, u32)> = None;
                    bvh.traverse(&ray, t_max, |pos, t_cur| {
                        let k = bvh.order()[pos as usize];
                        match hit_triangle(&ray, &tris[k as usize]) {
                            Some(t) if (t as f32) < t_cur => {
                                let t = t as f32;
                                if found.is_none_or(|f| t < f.0 || (t == f.0 && k < f.1)) {
                                    found = Some((t, k));
                                }
                                t
                            }
                            Some(t) if t as f32 == t_cur => {
                                if found.is_some_and(|f| k < f.1) {
                                    found = Some((t as f32, k));
                                }
                                t_cur
                            }
                            _ => t_cur,
                        }
                    });
                    let bits = |h: Option<(f32, u32)>| h.map(|(t, k)| (t.to_bits(), k));
                    assert_eq!(
                        bits(found),
                        bits(best),
                        "{n} triangles, ray {i}, narrow {narrow}"
                    );
                    // Any hit: stops at once, and finds one exactly when there is one.
                    let mut any = false;
                    bvh.traverse(&ray, t_max, |pos, t_cur| {
                        let k = bvh.order()[pos as usize];
                        match hit_triangle(&ray, &tris[k as usize]) {
                            Some(t) if (t as f32) < t_cur => {
                                any = true;
                                0.0
                            }
                            _ => t_cur,
                        }
                    });
                    assert_eq!(any, best.is_some(), "{n} triangles, ray {i}: any hit");
                }
            }
        }
    }

    #[test]
    fn a_leaf_is_priced_by_its_blocks_up_to_three() {
        for count in 1..=MAX_LEAF_PRIMITIVES {
            let blocks = count.div_ceil(LEAF_BLOCK);
            assert!(blocks <= 3, "count {count}");
            assert_eq!(
                leaf_cost(count),
                BLOCK_COST * blocks as f32,
                "count {count}"
            );
        }
        assert_eq!(leaf_cost(12), 3.0 * BLOCK_COST);
        assert_eq!(leaf_cost(13), f32::INFINITY);
        assert!((BLOCK_COST - 0.4).abs() < 1e-6, "block cost {BLOCK_COST}");
    }

    #[test]
    fn clusters_of_twelve_boxes_become_leaves_of_three_blocks() {
        // Twelve coincident boxes per cluster, clusters far apart: a leaf of all twelve
        // (three blocks) is cheaper than a node over smaller leaves of the same box.
        let mut rng = Lcg(5);
        let mut boxes = Vec::new();
        for _ in 0..40 {
            let c = rng.vec() * 100.0;
            let e = Vec3::splat(0.01);
            boxes.extend(std::iter::repeat_n((c - e, c + e), 12));
        }
        let (bvh, _) = WideBvh::build_with(&boxes, Strategy::Sah);
        assert_eq!(bvh.leaves().len(), 40);
        for leaf in bvh.leaves() {
            assert_eq!(leaf.count, 12, "{leaf:?}");
            assert_eq!(leaf.blocks(), 3, "{leaf:?}");
            let cluster = bvh.order()[leaf.first as usize] / 12;
            let positions = leaf.first as usize..(leaf.first + leaf.count) as usize;
            assert!(bvh.order()[positions].iter().all(|&p| p / 12 == cluster));
        }
        let mut blocks = 0;
        for leaf in bvh.leaves() {
            assert_eq!(leaf.block, blocks);
            blocks += leaf.blocks();
        }
    }
}
