//! An 8-wide BVH with full-precision boxes in structure-of-arrays layout, traversed nearest
//! child first with SIMD slab tests: one 8-wide AVX2 test per node where the CPU has AVX2
//! (detected at run time), else two 4-wide halves (glam's `Vec4`: SSE on x86-64). Both do
//! the same IEEE operations per child in the same order (no FMA), so they cull the same
//! children and report the same entry distances: hits are bit-identical either way.
//!
//! The binary hierarchy comes from `obvhs` (PLOC build with SAH reinsertion); it is collapsed
//! into nodes of up to eight children by repeatedly opening the child with the largest surface
//! area (Wald et al. 2008, "Getting Rid of Packets"), and subtrees of at most
//! [`MAX_LEAF_PRIMITIVES`] primitives become leaves. Primitives are re-ordered so that every
//! leaf's primitives are contiguous.
//!
//! The node test is conservative: the far slab distance is enlarged by its rounding-error bound
//! (1 + 2γ₃, Ize 2013 "Robust BVH Ray Traversal", as in pbrt-v4), the boxes were padded when they
//! were built, and the interval is clipped to `[0, t_max]`, so a primitive the ray hits is never
//! culled.

use glam::{Vec3A, Vec4};
use obvhs::aabb::Aabb as OAabb;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::bvh2::Bvh2;
use obvhs::ploc::PlocBuilder;
use obvhs::{Boundable, BvhBuildParams};

use crate::math::{Ray, Vec3};

/// Leaves hold at most this many primitives.
pub const MAX_LEAF_PRIMITIVES: u32 = 2;

/// Entries of the traversal stack kept on the machine stack; deeper trees spill to the heap.
const STACK_INLINE: usize = 48;

/// Children per node.
const WIDTH: usize = 8;

/// One node in two cache lines: the boxes of up to eight children quantised to 8 bits per
/// plane on a per-axis grid (Ylitie, Karras & Laine 2017, "Efficient Incoherent Ray Traversal
/// on GPUs Using Compressed Wide BVHs"), and what each child is.
///
/// A plane decodes as `q · scale + origin` (one f32 product, exact since `scale` is a power of
/// two, and one rounded sum, the same operations in every node test); the builder picks each
/// byte so that the decoded box contains the child's box: minima rounded down, maxima up.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct Node8 {
    /// Quantised planes of the children: minima x, y, z, then maxima x, y, z, one byte per
    /// child (empty slots hold 255 for the minima and 0 for the maxima). One array, so that a
    /// ray picks its near and far plane per axis by index instead of by a branch.
    q: [[u8; WIDTH]; 6],
    /// The grid's origin per axis (world units).
    origin: [f32; 3],
    /// The grid's step per axis (world units, a power of two).
    scale: [f32; 3],
    /// What each child is ([`leaf_ref`] for a leaf, else the child node's index; 0 for an
    /// empty slot, which the ray never enters).
    refs: [u32; WIDTH],
}

impl Node8 {
    /// The node over `boxes` (min, max; at most [`WIDTH`], finite) with children `refs`.
    fn new(boxes: &[(Vec3A, Vec3A)], refs: [u32; WIDTH]) -> Self {
        let mut node = Node8 {
            q: [
                [255; WIDTH],
                [255; WIDTH],
                [255; WIDTH],
                [0; WIDTH],
                [0; WIDTH],
                [0; WIDTH],
            ],
            origin: [0.0; 3],
            scale: [1.0; 3],
            refs,
        };
        for k in 0..3 {
            let lo: Vec<f32> = boxes.iter().map(|b| b.0[k]).collect();
            let hi: Vec<f32> = boxes.iter().map(|b| b.1[k]).collect();
            let (origin, scale, qlo, qhi) = quantise_axis(&lo, &hi);
            node.origin[k] = origin;
            node.scale[k] = scale;
            for (slot, (a, b)) in qlo.into_iter().zip(qhi).enumerate() {
                node.q[k][slot] = a;
                node.q[k + 3][slot] = b;
            }
        }
        node
    }

    /// Plane `p` (index in [`Node8::q`]) of child `slot`, decoded (world units).
    #[inline(always)]
    fn plane(&self, p: usize, slot: usize) -> f32 {
        decode(self.q[p][slot], self.scale[p % 3], self.origin[p % 3])
    }

    /// Bit `i` set when slot `i` holds a child.
    #[inline(always)]
    fn occupied(&self) -> u32 {
        let mut mask = 0;
        for (i, r) in self.refs.iter().enumerate() {
            mask |= u32::from(*r != 0) << i;
        }
        mask
    }
}

/// A quantised plane's value: `q · scale + origin`, a product then a sum (never fused), as in
/// every node test.
#[inline(always)]
fn decode(q: u8, scale: f32, origin: f32) -> f32 {
    f32::from(q) * scale + origin
}

/// One axis of a node's grid over children spanning `[lo[i], hi[i]]`: the origin (the lowest
/// minimum), the smallest power-of-two step for which every maximum is reached within 255
/// steps, and per child the largest byte whose plane is ≤ its minimum and the smallest byte
/// whose plane is ≥ its maximum (checked on the decoded values, so the rounding of the sum
/// can only widen a box).
fn quantise_axis(lo: &[f32], hi: &[f32]) -> (f32, f32, Vec<u8>, Vec<u8>) {
    if lo.is_empty() {
        return (0.0, 1.0, Vec::new(), Vec::new());
    }
    let origin = lo.iter().copied().fold(f32::INFINITY, f32::min);
    let top = hi.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let mut scale = f32::MIN_POSITIVE;
    while scale * 255.0 < top - origin {
        scale *= 2.0;
    }
    loop {
        let qlo: Vec<u8> = lo
            .iter()
            .map(|&l| {
                // `as u8` saturates (and maps NaN to 0).
                let mut q = ((l - origin) / scale).floor() as u8;
                while q > 0 && decode(q, scale, origin) > l {
                    q -= 1;
                }
                q
            })
            .collect();
        let qhi: Vec<u8> = hi
            .iter()
            .map(|&h| {
                let mut q = ((h - origin) / scale).ceil() as u8;
                while q < 255 && decode(q, scale, origin) < h {
                    q += 1;
                }
                q
            })
            .collect();
        // Coordinates are bounded (the geometry rejects larger ones), so the step stays
        // finite: a coarser grid always reaches the maxima eventually.
        let fits = qhi
            .iter()
            .zip(hi)
            .all(|(&q, &h)| decode(q, scale, origin) >= h);
        if fits || !(scale * 2.0).is_finite() {
            return (origin, scale, qlo, qhi);
        }
        scale *= 2.0;
    }
}

/// A wide BVH over primitive boxes. Primitive indices it reports are positions in
/// [`WideBvh::order`].
#[derive(Clone, Debug, Default)]
pub struct WideBvh {
    nodes: Vec<Node8>,
    /// Original primitive index of each position.
    order: Vec<u32>,
    depth: usize,
    /// The CPU runs AVX2 (detected when the hierarchy is built): the 8-wide node test.
    avx2: bool,
}

struct BoxPrim(OAabb);

impl Boundable for BoxPrim {
    fn aabb(&self) -> OAabb {
        self.0
    }
}

/// The ray quantities the slab test needs, per axis.
struct SlabRay {
    /// Origin, splatted per axis.
    o: [Vec4; 3],
    /// Capped reciprocal direction, splatted per axis.
    inv: [Vec4; 3],
    /// Per axis: index in [`Node8::q`] of the plane the ray enters by (the maximum
    /// when the direction is negative) and of the one it leaves by.
    near: [usize; 3],
    far: [usize; 3],
}

/// Reciprocal direction with magnitudes capped at 1e20 (sign kept, `-0` treated as `+0`),
/// so that slab tests never produce `0·∞`.
fn capped_inverse(x: f32) -> f32 {
    if x.abs() < 1e-20 {
        if x < 0.0 {
            -1e20
        } else {
            1e20
        }
    } else {
        1.0 / x
    }
}

impl SlabRay {
    fn new(ray: &Ray) -> Self {
        let inv = [
            capped_inverse(ray.d.x),
            capped_inverse(ray.d.y),
            capped_inverse(ray.d.z),
        ];
        SlabRay {
            o: [
                Vec4::splat(ray.o.x),
                Vec4::splat(ray.o.y),
                Vec4::splat(ray.o.z),
            ],
            inv: inv.map(Vec4::splat),
            near: [0, 1, 2].map(|k| if inv[k] < 0.0 { k + 3 } else { k }),
            far: [0, 1, 2].map(|k| if inv[k] < 0.0 { k } else { k + 3 }),
        }
    }

    #[inline(always)]
    fn test_half(&self, node: &Node8, h: usize, t_max: f32) -> (Vec4, u32) {
        let plane = |p: usize| {
            let s = 4 * h;
            Vec4::new(
                node.plane(p, s),
                node.plane(p, s + 1),
                node.plane(p, s + 2),
                node.plane(p, s + 3),
            )
        };
        let mut near = Vec4::ZERO;
        let mut far = Vec4::splat(t_max);
        for k in 0..3 {
            let n = plane(self.near[k]);
            let f = plane(self.far[k]);
            near = near.max((n - self.o[k]) * self.inv[k]);
            far = far.min((f - self.o[k]) * self.inv[k] * FAR_SCALE);
        }
        let occupied = (node.occupied() >> (4 * h)) & 0xF;
        (near, near.cmple(far).bitmask() & occupied)
    }
}

/// 1 + 2γ₃: the relative rounding bound of a slab distance.
const FAR_SCALE: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

/// The slab test of one node: the entry distances of its eight children and the mask of those
/// the ray enters within `[0, t_max]` (bit `i` for child `i`).
trait NodeTest {
    fn test(&self, node: &Node8, t_max: f32) -> ([f32; WIDTH], u32);
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

/// The 8-wide AVX2 node test: [`SlabRay`]'s operations on all eight children at once.
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::{
        __m128i, __m256, __m256i, _mm256_add_ps, _mm256_andnot_si256, _mm256_castps_si256,
        _mm256_castsi256_ps, _mm256_cmp_ps, _mm256_cmpeq_epi32, _mm256_cvtepi32_ps,
        _mm256_cvtepu8_epi32, _mm256_loadu_si256, _mm256_max_ps, _mm256_min_ps, _mm256_movemask_ps,
        _mm256_mul_ps, _mm256_set1_ps, _mm256_setzero_ps, _mm256_setzero_si256, _mm256_storeu_ps,
        _mm256_sub_ps, _mm_loadl_epi64, _CMP_LE_OS,
    };

    use super::{Node8, NodeTest, SlabRay, FAR_SCALE, WIDTH};

    /// The ray of a [`SlabRay`] splatted to 8 lanes. Made only by [`AvxSlab::new`], which
    /// needs AVX.
    pub(super) struct AvxSlab {
        o: [__m256; 3],
        inv: [__m256; 3],
        near: [usize; 3],
        far: [usize; 3],
    }

    impl AvxSlab {
        /// # Safety
        /// The CPU must support AVX2.
        #[target_feature(enable = "avx2")]
        pub(super) unsafe fn new(s: &SlabRay) -> Self {
            AvxSlab {
                o: s.o.map(|v| _mm256_set1_ps(v.x)),
                inv: s.inv.map(|v| _mm256_set1_ps(v.x)),
                near: s.near,
                far: s.far,
            }
        }
    }

    /// The eight bytes of a quantised plane, decoded: `q · scale + origin` as in
    /// [`super::decode`].
    #[inline(always)]
    unsafe fn decode_plane(q: &[u8; WIDTH], scale: __m256, origin: __m256) -> __m256 {
        // SAFETY: the caller runs with AVX2; the load reads the 8 bytes of `q`.
        unsafe {
            let q = _mm_loadl_epi64(q.as_ptr().cast::<__m128i>());
            let q = _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(q));
            _mm256_add_ps(_mm256_mul_ps(q, scale), origin)
        }
    }

    impl NodeTest for AvxSlab {
        #[inline(always)]
        fn test(&self, node: &Node8, t_max: f32) -> ([f32; WIDTH], u32) {
            // SAFETY: an `AvxSlab` exists only where AVX2 is available (its constructor needs
            // it); the loads read the 8 bytes of a plane and the 8 refs, the store writes the
            // 8 floats of `out`.
            unsafe {
                let mut near = _mm256_setzero_ps();
                let mut far = _mm256_set1_ps(t_max);
                for k in 0..3 {
                    let scale = _mm256_set1_ps(node.scale[k]);
                    let origin = _mm256_set1_ps(node.origin[k]);
                    let n = decode_plane(&node.q[self.near[k]], scale, origin);
                    let f = decode_plane(&node.q[self.far[k]], scale, origin);
                    near = _mm256_max_ps(
                        near,
                        _mm256_mul_ps(_mm256_sub_ps(n, self.o[k]), self.inv[k]),
                    );
                    far = _mm256_min_ps(
                        far,
                        _mm256_mul_ps(
                            _mm256_mul_ps(_mm256_sub_ps(f, self.o[k]), self.inv[k]),
                            _mm256_set1_ps(FAR_SCALE),
                        ),
                    );
                }
                let children = _mm256_loadu_si256(node.refs.as_ptr().cast::<__m256i>());
                let empty = _mm256_cmpeq_epi32(children, _mm256_setzero_si256());
                let hit = _mm256_andnot_si256(
                    empty,
                    _mm256_castps_si256(_mm256_cmp_ps::<_CMP_LE_OS>(near, far)),
                );
                let mask = _mm256_movemask_ps(_mm256_castsi256_ps(hit)) as u32;
                let mut out = [0.0f32; WIDTH];
                _mm256_storeu_ps(out.as_mut_ptr(), near);
                (out, mask)
            }
        }
    }
}

/// A traversal stack entry: an inner node with the distance the ray enters it.
#[derive(Clone, Copy, Debug, Default)]
struct Entry {
    node: u32,
    t: f32,
}

/// The traversal stack: inline entries, spilling to the heap only for unusually deep trees.
struct Stack {
    inline: [Entry; STACK_INLINE],
    len: usize,
    spill: Vec<Entry>,
}

impl Stack {
    fn new() -> Self {
        Stack {
            inline: [Entry::default(); STACK_INLINE],
            len: 0,
            spill: Vec::new(),
        }
    }
    #[inline(always)]
    fn push(&mut self, e: Entry) {
        if self.len < STACK_INLINE {
            self.inline[self.len] = e;
            self.len += 1;
        } else {
            self.spill.push(e);
        }
    }
    #[inline(always)]
    fn pop(&mut self) -> Option<Entry> {
        if let Some(e) = self.spill.pop() {
            return Some(e);
        }
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        Some(self.inline[self.len])
    }
}

impl WideBvh {
    /// Builds the hierarchy over `boxes` (min, max per primitive). Primitive positions follow
    /// [`WideBvh::order`].
    #[must_use]
    pub fn build(boxes: &[(Vec3, Vec3)]) -> Self {
        let n = boxes.len();
        if n == 0 {
            return WideBvh::default();
        }
        let prims: Vec<BoxPrim> = boxes
            .iter()
            .map(|(lo, hi)| BoxPrim(OAabb::new(Vec3A::from(*lo), Vec3A::from(*hi))))
            .collect();
        let params = BvhBuildParams::medium_build();
        let mut bvh2 = PlocBuilder::with_capacity(n).build(
            params.ploc_search_distance,
            &prims,
            (0..n as u32).collect(),
            params.sort_precision,
            params.search_depth_threshold,
        );
        ReinsertionOptimizer::default().run(&mut bvh2, params.reinsertion_batch_ratio, None);
        let counts = subtree_counts(&bvh2);
        let mut out = WideBvh {
            avx2: has_avx2(),
            ..WideBvh::default()
        };
        if counts[0] <= MAX_LEAF_PRIMITIVES {
            let first = out.order.len() as u32;
            collect_primitives(&bvh2, 0, &mut out.order);
            // One node with one leaf child.
            let mut refs = [0; WIDTH];
            refs[0] = leaf_ref(first, out.order.len() as u32 - first);
            let bb = bvh2.nodes[0].aabb;
            out.nodes.push(Node8::new(&[(bb.min, bb.max)], refs));
            out.depth = 1;
            return out;
        }
        out.nodes.push(Node8::new(&[], [0; WIDTH]));
        let mut work = vec![(0usize, 0usize, 1usize)]; // (bvh2 node, wide node, depth)
        while let Some((b, w, depth)) = work.pop() {
            out.depth = out.depth.max(depth);
            let children = open_children(&bvh2, b, &counts);
            let mut refs = [0; WIDTH];
            let mut boxes = Vec::with_capacity(WIDTH);
            for (slot, &c) in children.iter().enumerate() {
                let bb = bvh2.nodes[c].aabb;
                boxes.push((bb.min, bb.max));
                if counts[c] <= MAX_LEAF_PRIMITIVES {
                    let first = out.order.len() as u32;
                    collect_primitives(&bvh2, c, &mut out.order);
                    refs[slot] = leaf_ref(first, out.order.len() as u32 - first);
                } else {
                    let index = out.nodes.len();
                    out.nodes.push(Node8::new(&[], [0; WIDTH]));
                    refs[slot] = index as u32;
                    work.push((c, index, depth + 1));
                }
            }
            out.nodes[w] = Node8::new(&boxes, refs);
        }
        out
    }

    /// Original primitive index of each position the traversal reports.
    #[must_use]
    pub fn order(&self) -> &[u32] {
        &self.order
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
    #[inline]
    pub fn traverse(&self, ray: &Ray, t_max: f32, primitive: impl FnMut(u32, f32) -> f32) {
        if self.nodes.is_empty() {
            return;
        }
        let slab = SlabRay::new(ray);
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only when the CPU reported AVX2.
            unsafe { self.traverse_avx2(&slab, t_max, primitive) };
            return;
        }
        self.traverse_with(&slab, t_max, primitive);
    }

    /// [`Self::traverse`] compiled for AVX2, with the 8-wide node test.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn traverse_avx2(
        &self,
        slab: &SlabRay,
        t_max: f32,
        primitive: impl FnMut(u32, f32) -> f32,
    ) {
        // SAFETY: this function runs only with AVX2.
        let wide = unsafe { avx2::AvxSlab::new(slab) };
        self.traverse_with(&wide, t_max, primitive);
    }

    /// Forces the 4-wide node test (tests compare it with the 8-wide one).
    #[cfg(test)]
    pub(super) fn without_avx2(mut self) -> Self {
        self.avx2 = false;
        self
    }

    /// The traversal with node test `slab`.
    #[inline(always)]
    fn traverse_with<T: NodeTest>(
        &self,
        slab: &T,
        mut t_max: f32,
        mut primitive: impl FnMut(u32, f32) -> f32,
    ) {
        let mut stack = Stack::new();
        let mut current = 0u32;
        // Scratch for the children of the node visited (only entries below the counts are
        // read), initialised once per ray.
        let mut order = [(0usize, 0.0f32); WIDTH];
        let mut inner = [Entry::default(); WIDTH];
        loop {
            let node = &self.nodes[current as usize];
            let (near, mut mask) = slab.test(node, t_max);
            // The entered children sorted by entry distance, nearest first.
            let mut n = 0;
            while mask != 0 {
                let slot = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                let t = near[slot];
                let mut j = n;
                while j > 0 && order[j - 1].1 > t {
                    order[j] = order[j - 1];
                    j -= 1;
                }
                order[j] = (slot, t);
                n += 1;
            }
            // Leaves are intersected at once, nearest first (a hit shortens the ray for the
            // rest); inner children are pushed farthest first, so the nearest is visited next.
            let mut m = 0;
            for &(slot, t) in &order[..n] {
                if t > t_max {
                    break;
                }
                let r = node.refs[slot];
                if r & LEAF != 0 {
                    let first = (r & !LEAF) >> 2;
                    for i in first..=first + (r & 3) {
                        t_max = primitive(i, t_max);
                        if t_max <= 0.0 {
                            return;
                        }
                    }
                } else {
                    inner[m] = Entry { node: r, t };
                    m += 1;
                }
            }
            // The nearest inner child is visited next; the others wait, farthest deepest.
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

/// The [`Node8::refs`] entry of a leaf: the leaf flag, its first primitive position and its
/// primitive count less one in the low two bits.
fn leaf_ref(first: u32, count: u32) -> u32 {
    LEAF | (first << 2) | (count - 1)
}

/// The flag of a leaf in [`Node8::refs`].
const LEAF: u32 = 1 << 31;

/// True when the CPU runs AVX2 (the 8-wide node test) and the environment variable
/// `VELOUR_NO_AVX2` is not set (it forces the 4-wide test, for A/B measurements in one
/// binary; the hits are the same either way).
fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2") && std::env::var_os("VELOUR_NO_AVX2").is_none()
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Primitives under each bvh2 node.
fn subtree_counts(bvh2: &Bvh2) -> Vec<u32> {
    let mut counts = vec![0u32; bvh2.nodes.len()];
    // Children come after their parents in PLOC's layout only sometimes: compute iteratively
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

/// Up to four bvh2 nodes that become the children of the wide node for bvh2 node `i`: its
/// two children, then repeatedly the largest inner one (that is not to become a leaf) opened.
fn open_children(bvh2: &Bvh2, i: usize, counts: &[u32]) -> Vec<usize> {
    let first = bvh2.nodes[i].first_index as usize;
    let mut children = vec![first, first + 1];
    while children.len() < WIDTH {
        let candidate = children
            .iter()
            .enumerate()
            .filter(|(_, &c)| bvh2.nodes[c].prim_count == 0 && counts[c] > MAX_LEAF_PRIMITIVES)
            .max_by(|(_, &a), (_, &b)| {
                bvh2.nodes[a]
                    .aabb
                    .half_area()
                    .total_cmp(&bvh2.nodes[b].aabb.half_area())
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

    #[test]
    fn the_8_wide_and_4_wide_node_tests_visit_the_same_leaves_in_the_same_order() {
        if !has_avx2() {
            eprintln!("no AVX2 on this CPU: only the 4-wide test runs");
            return;
        }
        let mut rng = Lcg(17);
        let boxes: Vec<(Vec3, Vec3)> = (0..3000)
            .map(|_| {
                let c = rng.vec();
                let e = Vec3::new(rng.next(), rng.next(), rng.next()) * 0.1;
                (c - e, c + e)
            })
            .collect();
        let wide = WideBvh::build(&boxes);
        assert!(wide.avx2);
        let narrow = wide.clone().without_avx2();
        // Direct node tests too: entry distances and masks bit for bit.
        for i in 0..20_000 {
            let mut d = rng.vec().normalize_or(Vec3::X);
            if i % 5 == 0 {
                d[i % 3] = 0.0;
            }
            let ray = Ray::new(rng.vec() * 1.5, d);
            let t_max = if i % 3 == 0 {
                rng.next() * 2.0
            } else {
                f32::INFINITY
            };
            let slab = SlabRay::new(&ray);
            // SAFETY: AVX2 was detected above.
            let avx = unsafe { avx2::AvxSlab::new(&slab) };
            let node = &wide.nodes[i % wide.nodes.len()];
            let (a, ma) = slab.test(node, t_max);
            let (b, mb) = avx.test(node, t_max);
            assert_eq!(ma, mb, "ray {i}");
            for k in 0..WIDTH {
                if ma & (1 << k) != 0 {
                    assert_eq!(a[k].to_bits(), b[k].to_bits(), "ray {i} child {k}");
                }
            }
            let mut seen = (Vec::new(), Vec::new());
            // A closest-hit-like query: every third leaf primitive shortens the ray.
            let shorten = |pos: u32, t: f32| if pos % 3 == 0 { t * 0.9 } else { t };
            wide.traverse(&ray, t_max, |pos, t| {
                seen.0.push((pos, t.to_bits()));
                shorten(pos, t)
            });
            narrow.traverse(&ray, t_max, |pos, t| {
                seen.1.push((pos, t.to_bits()));
                shorten(pos, t)
            });
            assert_eq!(seen.0, seen.1, "ray {i}");
        }
    }

    #[test]
    fn quantised_boxes_contain_every_primitive_box_below_them() {
        let mut rng = Lcg(9);
        // Boxes of very different sizes, far from the origin and near it, and thin ones.
        for (n, offset, size) in [
            (5000usize, 1000.0f32, 0.01f32),
            (3000, 0.0, 0.3),
            (2, 7.0, 1e-6),
        ] {
            let boxes: Vec<(Vec3, Vec3)> = (0..n)
                .map(|i| {
                    let c = rng.vec() + Vec3::splat(offset);
                    let mut e = Vec3::new(rng.next(), rng.next(), rng.next()) * size;
                    e[i % 3] *= 1e-3;
                    (c - e, c + e)
                })
                .collect();
            let bvh = WideBvh::build(&boxes);
            let decoded = |node: &Node8, slot: usize| {
                let lo = Vec3::new(
                    node.plane(0, slot),
                    node.plane(1, slot),
                    node.plane(2, slot),
                );
                let hi = Vec3::new(
                    node.plane(3, slot),
                    node.plane(4, slot),
                    node.plane(5, slot),
                );
                (lo, hi)
            };
            // Depth-first with the decoded boxes of the slots on the path.
            let mut work = vec![(0u32, Vec::<(Vec3, Vec3)>::new())];
            let mut seen = 0;
            while let Some((index, path)) = work.pop() {
                let node = &bvh.nodes[index as usize];
                for slot in 0..WIDTH {
                    let r = node.refs[slot];
                    if r == 0 {
                        continue;
                    }
                    let mut path = path.clone();
                    path.push(decoded(node, slot));
                    if r & LEAF == 0 {
                        work.push((r, path));
                        continue;
                    }
                    let first = (r & !LEAF) >> 2;
                    for i in first..=first + (r & 3) {
                        let b = boxes[bvh.order()[i as usize] as usize];
                        for (lo, hi) in &path {
                            assert!(
                                lo.cmple(b.0).all() && hi.cmpge(b.1).all(),
                                "{n} boxes: box {i} {b:?} outside {lo:?} {hi:?}"
                            );
                        }
                        seen += 1;
                    }
                }
            }
            assert_eq!(seen, n);
        }
    }

    #[test]
    fn every_box_a_ray_crosses_is_visited_nearest_leaf_first_and_any_hit_stops() {
        let mut rng = Lcg(3);
        for n in [1usize, 2, 3, 9, 64, 2000] {
            let boxes: Vec<(Vec3, Vec3)> = (0..n)
                .map(|_| {
                    let c = rng.vec();
                    let e = Vec3::new(rng.next(), rng.next(), rng.next()) * 0.2;
                    (c - e, c + e)
                })
                .collect();
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
}
