//! A binary hierarchy built top-down by the surface area heuristic with a full sweep over
//! sorted centroids (MacDonald and Booth 1990, "Heuristics for ray tracing using space
//! subdivision"; the sweep as in Wald, Boulos and Shirley 2007, "Ray tracing deformable scenes
//! using dynamic bounding volume hierarchies", §3): at every node, every split of the
//! primitives sorted by their box centres along x, y or z is priced as `A(L)·|L| + A(R)·|R|`
//! (half areas) and the cheapest is taken, down to leaves of one primitive. The wide BVH's
//! collapse ([`super::wide_bvh`]) then decides which subtrees become leaves.
//!
//! The primitives are sorted once per axis (by centre, then index, a total order) and each
//! split partitions the three lists stably, so a node costs time linear in its primitives.

use glam::Vec3A;
use obvhs::aabb::Aabb;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::bvh2::Bvh2;

/// The three per-axis sorted lists of a node's primitives, each holding the same set.
struct Lists {
    sorted: [Vec<u32>; 3],
    /// Scratch for the stable partitions.
    scratch: Vec<u32>,
    /// Per primitive: goes to the left child in the current split.
    left: Vec<bool>,
    /// `right[k]`: the priced cost of the primitives from `k` to the end of the range.
    right: Vec<f32>,
}

/// The cheapest split of a range: (cost, axis, primitives on the left).
type Split = (f32, usize, usize);

impl Lists {
    /// The cheapest split of `lo..hi` (at least two primitives) over the three axes; the first
    /// axis and then the smallest left count win ties.
    fn best_split(&mut self, boxes: &[Aabb], lo: usize, hi: usize) -> (Split, Aabb) {
        let m = hi - lo;
        let mut best: Split = (f32::INFINITY, 0, m / 2);
        let mut whole = Aabb::empty();
        for (axis, list) in self.sorted.iter().enumerate() {
            let idx = &list[lo..hi];
            let mut r = Aabb::empty();
            for k in (1..m).rev() {
                r = r.union(&boxes[idx[k] as usize]);
                self.right[k] = r.half_area() * (m - k) as f32;
            }
            let mut l = Aabb::empty();
            for k in 1..m {
                l = l.union(&boxes[idx[k - 1] as usize]);
                let c = l.half_area() * k as f32 + self.right[k];
                if c < best.0 {
                    best = (c, axis, k);
                }
            }
            if axis == 0 {
                whole = l.union(&r);
            }
        }
        (best, whole)
    }

    /// Splits `lo..hi` after its first `k` primitives along `axis`: the other lists are
    /// partitioned stably, so they stay sorted.
    fn partition(&mut self, lo: usize, hi: usize, axis: usize, k: usize) {
        for (j, &p) in self.sorted[axis][lo..hi].iter().enumerate() {
            self.left[p as usize] = j < k;
        }
        for other in (0..3).filter(|&a| a != axis) {
            let list = &mut self.sorted[other][lo..hi];
            self.scratch.clear();
            self.scratch
                .extend(list.iter().copied().filter(|&p| self.left[p as usize]));
            self.scratch
                .extend(list.iter().copied().filter(|&p| !self.left[p as usize]));
            list.copy_from_slice(&self.scratch);
        }
    }
}

/// `x`'s place in [`f32::total_cmp`]'s order as an unsigned integer: the bits with the
/// negative values' magnitude bits flipped (as `total_cmp` does), then the sign bit flipped so
/// that unsigned comparison agrees.
#[inline]
fn total_order_key(x: f32) -> u32 {
    let b = x.to_bits() as i32;
    let t = b ^ ((((b >> 31) as u32) >> 1) as i32);
    (t as u32) ^ 0x8000_0000
}

/// The primitives sorted by their centre's `axis` coordinate ([`f32::total_cmp`]), then by
/// index: each as one `u64` key (order key above the index), all distinct, so an unstable sort
/// of plain integers gives that order without a comparison closure.
fn sorted_by_key(centres: &[Vec3A], axis: usize) -> Vec<u32> {
    let mut keys: Vec<u64> = centres
        .iter()
        .enumerate()
        .map(|(i, c)| (u64::from(total_order_key(c[axis])) << 32) | i as u64)
        .collect();
    keys.sort_unstable();
    keys.into_iter().map(|k| k as u32).collect()
}

/// Builds the binary hierarchy over `boxes` (at least one): the root is node 0, a node's
/// children are `first_index` and `first_index + 1`, and each leaf holds one primitive.
pub(crate) fn build(boxes: &[Aabb]) -> Bvh2 {
    let n = boxes.len();
    assert!(n > 0, "a hierarchy needs at least one primitive");
    let centres: Vec<Vec3A> = boxes.iter().map(Aabb::center).collect();
    let sorted_by = |axis: usize| sorted_by_key(&centres, axis);
    let mut lists = Lists {
        sorted: [sorted_by(0), sorted_by(1), sorted_by(2)],
        scratch: Vec::with_capacity(n),
        left: vec![false; n],
        right: vec![0.0; n],
    };
    let mut nodes = vec![Bvh2Node::default(); 2 * n - 1];
    let mut next = 1usize;
    let mut depth = 1usize;
    // (node, first position, end position, depth)
    let mut work = vec![(0usize, 0usize, n, 1usize)];
    while let Some((node, lo, hi, d)) = work.pop() {
        depth = depth.max(d);
        if hi - lo == 1 {
            nodes[node] = Bvh2Node::new(boxes[lists.sorted[0][lo] as usize], 1, lo as u32);
            continue;
        }
        let ((_, axis, k), whole) = lists.best_split(boxes, lo, hi);
        lists.partition(lo, hi, axis, k);
        let first = next;
        next += 2;
        nodes[node] = Bvh2Node::new(whole, 0, first as u32);
        work.push((first, lo, lo + k, d + 1));
        work.push((first + 1, lo + k, hi, d + 1));
    }
    let [order, _, _] = lists.sorted;
    Bvh2 {
        nodes,
        primitive_indices: order,
        max_depth: depth.max(obvhs::bvh2::DEFAULT_MAX_STACK_DEPTH),
        ..Bvh2::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn boxes(seed: u64, n: usize) -> Vec<Aabb> {
        let mut s = seed;
        let mut next = move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 40) as f32 / (1u64 << 24) as f32
        };
        (0..n)
            .map(|_| {
                let c = Vec3A::new(next(), next(), next()) * 10.0;
                let h = Vec3A::new(next(), next(), next()) * 0.5;
                // A few boxes share their centre's coordinates, to exercise the ties.
                let c = if next() < 0.1 { c.floor() } else { c };
                Aabb::new(c - h, c + h)
            })
            .collect()
    }

    fn union(boxes: &[Aabb], ids: &[u32]) -> Aabb {
        ids.iter()
            .fold(Aabb::empty(), |b, &i| b.union(&boxes[i as usize]))
    }

    /// Primitives under node `i`, in leaf order.
    fn under(bvh: &Bvh2, i: usize, out: &mut Vec<u32>) {
        let node = &bvh.nodes[i];
        if node.prim_count > 0 {
            let f = node.first_index as usize;
            out.extend_from_slice(&bvh.primitive_indices[f..f + node.prim_count as usize]);
        } else {
            under(bvh, node.first_index as usize, out);
            under(bvh, node.first_index as usize + 1, out);
        }
    }

    /// The integer keys sort the centres exactly as `total_cmp` then the index do: random
    /// coordinates with repeats, ±0, subnormals, infinities and NaNs of both signs.
    #[test]
    fn integer_keys_sort_as_total_cmp_then_index() {
        let specials = [
            0.0f32,
            -0.0,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            1e-45,
            -1e-45,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -f32::NAN,
            f32::MAX,
            f32::MIN,
            1.0,
            -1.0,
        ];
        let mut s = 7u64;
        let mut next = move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 33) as u32
        };
        let centres: Vec<Vec3A> = (0..5000)
            .map(|_| {
                let mut c = [0.0f32; 3];
                for v in &mut c {
                    let r = next();
                    *v = match r % 4 {
                        0 => specials[(r / 4) as usize % specials.len()],
                        1 => ((r / 4) % 16) as f32 - 8.0, // repeats
                        _ => f32::from_bits(next()),
                    };
                }
                Vec3A::from_array(c)
            })
            .collect();
        for axis in 0..3 {
            let mut expected: Vec<u32> = (0..centres.len() as u32).collect();
            expected.sort_by(|&a, &b| {
                centres[a as usize][axis]
                    .total_cmp(&centres[b as usize][axis])
                    .then(a.cmp(&b))
            });
            assert_eq!(sorted_by_key(&centres, axis), expected, "axis {axis}");
        }
    }

    #[test]
    fn every_node_takes_the_cheapest_centroid_split_and_bounds_its_primitives() {
        for (seed, n) in [(1, 1), (2, 2), (3, 3), (4, 17), (5, 64), (6, 300)] {
            let b = boxes(seed, n);
            let bvh = build(&b);
            assert_eq!(bvh.nodes.len(), 2 * n - 1);
            let mut all = Vec::new();
            under(&bvh, 0, &mut all);
            all.sort_unstable();
            assert_eq!(
                all,
                (0..n as u32).collect::<Vec<_>>(),
                "each primitive once"
            );
            for (i, node) in bvh.nodes.iter().enumerate() {
                let mut ids = Vec::new();
                under(&bvh, i, &mut ids);
                assert_eq!(node.aabb, union(&b, &ids), "node {i} bounds its primitives");
                if node.prim_count > 0 {
                    assert_eq!(node.prim_count, 1);
                    continue;
                }
                let (mut l, mut r) = (Vec::new(), Vec::new());
                under(&bvh, node.first_index as usize, &mut l);
                under(&bvh, node.first_index as usize + 1, &mut r);
                let cost = |l: &[u32], r: &[u32]| {
                    union(&b, l).half_area() * l.len() as f32
                        + union(&b, r).half_area() * r.len() as f32
                };
                let chosen = cost(&l, &r);
                // Every split of the node's primitives sorted by centre along each axis
                // costs at least as much as the chosen one.
                for axis in 0..3 {
                    let mut s = ids.clone();
                    s.sort_by(|&x, &y| {
                        let (cx, cy) = (b[x as usize].center(), b[y as usize].center());
                        cx[axis].total_cmp(&cy[axis]).then(x.cmp(&y))
                    });
                    for k in 1..s.len() {
                        let c = cost(&s[..k], &s[k..]);
                        assert!(
                            chosen <= c * (1.0 + 1e-5),
                            "node {i}: chosen {chosen}, axis {axis} split {k} costs {c}"
                        );
                    }
                }
            }
        }
    }
}
