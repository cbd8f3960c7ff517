//! A top-down binned SAH builder (Wald 2007) for the BVH2 of large BLASes.
//!
//! At each node the primitives' centroids are sorted into 32 bins along each axis (8 under 64
//! primitives) and the boundary of lowest surface-area cost is taken. The cost counts a leaf's triangles by the
//! packets of four they are tested in (a leaf of five costs as much as one of eight), so leaves
//! come out as full packets and the wide tree needs fewer nodes than obvhs's PLOC build with
//! leaf collapsing gives at the same SAH cost.
//!
//! Subtrees of 8192 primitives or more are built in parallel, and the passes over nodes of
//! 32768 or more in parallel chunks; the result does not depend on the thread count. Children come after their parents in the node array, the two
//! children of an inner node side by side, as [`obvhs::bvh2::Bvh2`] expects.

use glam::{BVec3A, BVec4A, Vec3A, Vec4};
use obvhs::{
    aabb::Aabb,
    bvh2::{Bvh2, DEFAULT_MAX_STACK_DEPTH, node::Bvh2Node},
};
use rayon::prelude::*;

mod spatial;
pub use spatial::build as build_with_spatial_splits;

/// Centroid bins per axis.
const BINS: usize = 32;

/// Centroid bins per axis for nodes under [`SMALL_NODE`] primitives.
const SMALL_BINS: usize = 8;

/// Primitive count under which a node gets [`SMALL_BINS`] bins.
const SMALL_NODE: usize = 64;

/// Most primitives in a leaf: two packets of four.
pub const MAX_LEAF: usize = 8;

/// Cost of visiting an inner node, relative to testing one packet of four triangles (a node
/// test and a packet test take about as many instructions in the single-ray traversal).
const NODE_COST: f32 = 1.0;

/// Smallest subtree handed to another thread.
const PARALLEL_MIN: usize = 8192;

/// A primitive's bounds and its index in the input, in 32 bytes: the index rides in the spare
/// fourth lane of the minimum (an [`Aabb`] beside a `u32` took 48, 42 MB for the dragon).
#[derive(Clone, Copy)]
struct Ref {
    /// The box's minimum, and the index's bits in `w`.
    min: Vec4,
    max: Vec3A,
}

impl Ref {
    /// Primitive `index` bounded by `aabb`.
    #[inline(always)]
    fn new(aabb: Aabb, index: u32) -> Self {
        Ref { min: aabb.min.extend(f32::from_bits(index)), max: aabb.max }
    }

    /// The primitive's box (its minimum's fourth lane, which no box operation reads, holds the
    /// index).
    #[inline(always)]
    fn aabb(&self) -> Aabb {
        Aabb { min: Vec3A::from_vec4(self.min), max: self.max }
    }

    /// The primitive's index in the input.
    #[inline(always)]
    fn index(&self) -> u32 {
        self.min.w.to_bits()
    }

    /// This ref if `pick`, else `other`, chosen by selects rather than a branch.
    #[inline(always)]
    fn if_else(self, pick: bool, other: Ref) -> Ref {
        Ref {
            min: Vec4::select(BVec4A::splat(pick), self.min, other.min),
            max: Vec3A::select(BVec3A::splat(pick), self.max, other.max),
        }
    }
}

/// Builds a BVH2 over `count` primitives (at least one), primitive `i` bounded by
/// `bounds(i)`, and returns it with its depth (the root alone is 1), counted while building.
/// Leaves hold at most [`MAX_LEAF`] primitives, as ranges of `primitive_indices`. The boxes go
/// straight into the builder's references, in parallel: no array of boxes is made first.
pub fn build(count: usize, bounds: impl Fn(usize) -> Aabb + Sync) -> (Bvh2, usize) {
    let refs: Vec<Ref> =
        (0..count).into_par_iter().with_min_len(PARALLEL_MIN).map(|i| Ref::new(bounds(i), i as u32)).collect();
    build_refs(refs)
}

/// [`build`] over references already made (at least one).
fn build_refs(mut refs: Vec<Ref>) -> (Bvh2, usize) {
    let (nodes, depth) = subtree(&mut refs, 0);
    // obvhs's convention (as its PLOC builder sets it): a bound for its traversal stacks.
    let max_depth = (depth + 1).max(DEFAULT_MAX_STACK_DEPTH);
    let bvh = Bvh2 {
        nodes,
        primitive_indices: refs.iter().map(Ref::index).collect(),
        children_are_ordered_after_parents: true,
        max_depth,
        ..Default::default()
    };
    (bvh, depth)
}

/// Packets of four that `count` triangles take.
#[inline(always)]
fn packets(count: usize) -> f32 {
    count.div_ceil(4) as f32
}

/// What to do with a node's primitives.
enum Split {
    Leaf,
    /// Primitives whose centroid falls in a bin below `bin` on `axis` (whose bins start at
    /// `min`, `scale` bins per unit) go left.
    Bins {
        axis: usize,
        bin: usize,
        min: f32,
        scale: f32,
    },
    /// No boundary separates the centroids (all equal): halves by position.
    Halves,
}

/// The bins, on each axis, of a centroid `c` for axes starting at `min` with `scale` bins per
/// unit, of `bins` bins: the scaled offset truncated, 0 for NaN or below, the last bin at or
/// above it (the last boundary belongs to the last bin).
#[inline(always)]
fn bins_of(c: Vec3A, min: Vec3A, scale: Vec3A, bins: usize) -> [u32; 3] {
    let f = (c - min) * scale;
    // Three lanes at once, clamped before truncating; maxps returns its second operand when
    // either is NaN, so NaN goes to 0. (The scalar saturating conversion is much slower and
    // this runs once per primitive per node.)
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::*;
        // SAFETY: SSE2 is part of the x86_64 baseline; an __m128i holds four i32.
        let [x, y, z, _] = unsafe {
            let f = _mm_min_ps(_mm_max_ps(f.into(), _mm_setzero_ps()), _mm_set1_ps((bins - 1) as f32));
            std::mem::transmute::<__m128i, [u32; 4]>(_mm_cvttps_epi32(f))
        };
        [x, y, z]
    }
    // `as` saturates (NaN gives 0).
    #[cfg(not(target_arch = "x86_64"))]
    f.to_array().map(|v| (v as usize).min(bins - 1) as u32)
}

/// Each axis's bins: the union of the boxes whose centroid falls in each, and how many.
#[derive(Clone, Copy)]
struct Bins<const N: usize>([[(Aabb, u32); N]; 3]);

impl<const N: usize> Bins<N> {
    const EMPTY: Self = Bins([[(Aabb::INVALID, 0); N]; 3]);

    /// The bins of `refs`, whose centroids start at `min` with `scale` bins per unit (0 on an
    /// axis where they do not spread: all in bin 0).
    fn of(refs: &[Ref], min: Vec3A, scale: Vec3A) -> Self {
        let mut bins = Bins::EMPTY;
        for r in refs {
            let index = bins_of(r.aabb().center(), min, scale, N);
            for (axis, &i) in index.iter().enumerate() {
                let bin = &mut bins.0[axis][i as usize];
                bin.0 = bin.0.union(&r.aabb());
                bin.1 += 1;
            }
        }
        bins
    }

    /// Both sets of bins in one.
    fn merge(mut self, other: &Self) -> Self {
        for (a, b) in self.0.iter_mut().flatten().zip(other.0.iter().flatten()) {
            *a = (a.0.union(&b.0), a.1 + b.1);
        }
        self
    }
}

/// The union of `refs`' boxes and of their centroids.
fn bounds_of(refs: &[Ref]) -> (Aabb, Aabb) {
    refs.iter().fold((Aabb::INVALID, Aabb::INVALID), |(b, c), r| {
        (b.union(&r.aabb()), c.union(&Aabb::from_point(r.aabb().center())))
    })
}

/// The bounds of `refs` and the split of lowest cost, with [`BINS`] bins per axis, or
/// [`SMALL_BINS`] under [`SMALL_NODE`] primitives (where setting up and sweeping the bins is
/// most of the work).
fn choose(refs: &[Ref]) -> (Aabb, Split) {
    let best = object_split(refs);
    (best.bounds, decide(refs.len(), best.bounds, best.cost, best.split))
}

/// A node's best split by centroid bins.
struct ObjectSplit {
    /// The union of the node's boxes.
    bounds: Aabb,
    /// The two children's half areas times their packets; ∞ where no boundary separates
    /// the centroids (the split is then [`Split::Halves`]).
    cost: f32,
    /// Half the area of the box where the two children's boxes overlap (0 where they do not).
    overlap: f32,
    split: Split,
}

/// [`ObjectSplit`] of `refs` with [`BINS`] or [`SMALL_BINS`] bins per axis, as [`choose`] uses.
fn object_split(refs: &[Ref]) -> ObjectSplit {
    if refs.len() < SMALL_NODE { object_split_in::<SMALL_BINS>(refs) } else { object_split_in::<BINS>(refs) }
}

/// Whether a node of `count` primitives in `bounds` becomes a leaf, or takes `split`, whose
/// children cost `cost`: a leaf when it fits and splitting does not pay.
fn decide(count: usize, bounds: Aabb, cost: f32, split: Split) -> Split {
    if count == 1 {
        return Split::Leaf;
    }
    let split_cost = bounds.half_area() * NODE_COST + cost;
    let fits = count <= MAX_LEAF;
    // False when either cost is NaN: such a node stays a leaf if it can.
    let split_pays = split_cost < bounds.half_area() * packets(count);
    if fits && !split_pays {
        return Split::Leaf;
    }
    if cost.is_infinite() {
        return if fits { Split::Leaf } else { Split::Halves };
    }
    split
}

/// Half the area of the overlap of `a` and `b`; 0 where they do not overlap.
fn overlap_half_area(a: &Aabb, b: &Aabb) -> f32 {
    let extent = a.max.min(b.max) - a.min.max(b.min);
    if extent.cmpgt(Vec3A::ZERO).all() { extent.x * extent.y + extent.y * extent.z + extent.z * extent.x } else { 0.0 }
}

/// [`object_split`] with `N` bins per axis; the passes over `refs` run in parallel chunks for
/// large nodes (unions and counts, so the result is the same).
fn object_split_in<const N: usize>(refs: &[Ref]) -> ObjectSplit {
    let parallel = refs.len() >= 4 * PARALLEL_MIN;
    let (bounds, centroids) = if parallel {
        let pair = |a: (Aabb, Aabb), b: (Aabb, Aabb)| (a.0.union(&b.0), a.1.union(&b.1));
        refs.par_chunks(PARALLEL_MIN).map(bounds_of).reduce(|| (Aabb::INVALID, Aabb::INVALID), pair)
    } else {
        bounds_of(refs)
    };
    let count = refs.len();
    let none = ObjectSplit { bounds, cost: f32::INFINITY, overlap: 0.0, split: Split::Halves };
    if count == 1 {
        return none;
    }
    let extent = centroids.max - centroids.min;
    // Zero (or NaN, from NaN boxes) where the centroids do not spread: no boundary there.
    let scale = Vec3A::select(extent.cmpgt(Vec3A::ZERO), N as f32 / extent, Vec3A::ZERO);
    let bins = if parallel {
        let min = centroids.min;
        refs.par_chunks(PARALLEL_MIN).map(|c| Bins::<N>::of(c, min, scale)).reduce(|| Bins::EMPTY, |a, b| a.merge(&b))
    } else {
        Bins::<N>::of(refs, centroids.min, scale)
    };
    // (cost of the two children, axis, bin)
    let mut best = (f32::INFINITY, 0, 0);
    for (axis, bins) in bins.0.iter().enumerate() {
        // Cost of everything from bin k up, swept from the right.
        let mut right = [0.0f32; N];
        let (mut b, mut n) = (Aabb::INVALID, 0);
        for k in (1..N).rev() {
            b = b.union(&bins[k].0);
            n += bins[k].1 as usize;
            right[k] = b.half_area() * packets(n);
        }
        let (mut b, mut n) = (Aabb::INVALID, 0);
        for k in 1..N {
            b = b.union(&bins[k - 1].0);
            n += bins[k - 1].1 as usize;
            if n == 0 || n == count {
                continue;
            }
            let cost = b.half_area() * packets(n) + right[k];
            if cost < best.0 {
                best = (cost, axis, k);
            }
        }
    }
    if best.0.is_infinite() {
        return none;
    }
    let (cost, axis, bin) = best;
    // The chosen children's boxes, once, from the winning axis's bins.
    let union = |bins: &[(Aabb, u32)]| bins.iter().fold(Aabb::INVALID, |b, bin| b.union(&bin.0));
    let overlap = overlap_half_area(&union(&bins.0[axis][..bin]), &union(&bins.0[axis][bin..]));
    ObjectSplit {
        bounds,
        cost,
        overlap,
        split: Split::Bins { axis, bin, min: centroids.min[axis], scale: scale[axis] },
    }
}

/// Reorders `refs` for `split` and returns how many go left (neither side empty).
fn partition(refs: &mut [Ref], split: &Split) -> usize {
    match *split {
        Split::Leaf => unreachable!("a leaf is not partitioned"),
        Split::Halves => refs.len() / 2,
        Split::Bins { axis, bin, min, scale } => {
            // The bin below `bin` without the conversion: for a whole `bin` ≥ 1, the truncated
            // (clamped) index is below it exactly when the scaled offset is, and NaN (bin 0)
            // goes left too.
            let limit = bin as f32;
            let mut left = 0;
            for j in 0..refs.len() {
                // obvhs's `center_axis` is `center` on one axis: the centroid binned above.
                let offset = (refs[j].aabb().center_axis(axis) - min) * scale;
                let goes_left = offset < limit || offset.is_nan();
                // `if goes_left { refs.swap(j, left) }` without the branch, whose outcome is as
                // good as random near the root: both places are written, by selects.
                let (a, b) = (refs[j], refs[left]);
                refs[left] = a.if_else(goes_left, b);
                refs[j] = b.if_else(goes_left, a);
                left += usize::from(goes_left);
            }
            left
        }
    }
}

/// The subtree over `refs` (which start at `offset` in the whole array), root first; inner
/// nodes' `first_index` counts from this subtree's root.
fn subtree(refs: &mut [Ref], offset: usize) -> (Vec<Bvh2Node>, usize) {
    if refs.len() < PARALLEL_MIN {
        return subtree_serial(refs, offset);
    }
    let (bounds, split) = choose(refs);
    if let Split::Leaf = split {
        return (vec![Bvh2Node::new(bounds, refs.len() as u32, offset as u32)], 1);
    }
    let mid = partition(refs, &split);
    let (left, right) = refs.split_at_mut(mid);
    let ((l, l_depth), (r, r_depth)) = rayon::join(|| subtree(left, offset), || subtree(right, offset + mid));
    // Root, the two children's roots, then the rest of each child's nodes.
    let mut nodes = Vec::with_capacity(1 + l.len() + r.len());
    nodes.push(Bvh2Node::new(bounds, 0, 1));
    let moved = |node: &Bvh2Node, shift: usize| {
        let mut node = *node;
        if node.prim_count == 0 {
            node.first_index += shift as u32;
        }
        node
    };
    // A node at k ≥ 1 of the left subtree lands at k + 2; of the right, at k + l.len() + 1.
    nodes.push(moved(&l[0], 2));
    nodes.push(moved(&r[0], l.len() + 1));
    nodes.extend(l[1..].iter().map(|n| moved(n, 2)));
    nodes.extend(r[1..].iter().map(|n| moved(n, l.len() + 1)));
    (nodes, 1 + l_depth.max(r_depth))
}

/// [`subtree`] on this thread.
fn subtree_serial(refs: &mut [Ref], offset: usize) -> (Vec<Bvh2Node>, usize) {
    let mut nodes = vec![Bvh2Node::new(Aabb::empty(), 0, 0)];
    let mut depth = 0;
    // (node, first ref, end, the node's depth)
    let mut todo = vec![(0usize, 0usize, refs.len(), 1usize)];
    while let Some((node, start, end, d)) = todo.pop() {
        depth = depth.max(d);
        let (bounds, split) = choose(&refs[start..end]);
        if let Split::Leaf = split {
            nodes[node] = Bvh2Node::new(bounds, (end - start) as u32, (offset + start) as u32);
            continue;
        }
        let mid = start + partition(&mut refs[start..end], &split);
        let children = nodes.len();
        nodes[node] = Bvh2Node::new(bounds, 0, children as u32);
        nodes.extend([Bvh2Node::new(Aabb::empty(), 0, 0); 2]);
        todo.push((children + 1, mid, end, d + 1));
        todo.push((children, start, mid, d + 1));
    }
    (nodes, depth)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{geometry::accel::subtree_depth, random::SplitMix64};

    fn boxes(n: usize, seed: u64) -> Vec<Aabb> {
        let mut rng = SplitMix64::new(seed);
        (0..n)
            .map(|_| {
                let c = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 100.0;
                let h = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
                Aabb::new(c - h, c + h)
            })
            .collect()
    }

    /// Checks the layout obvhs expects and that every node's box is the union of what it holds.
    fn check((bvh, depth): &(Bvh2, usize), aabbs: &[Aabb]) {
        let mut seen = vec![false; aabbs.len()];
        let mut todo = vec![0usize];
        while let Some(n) = todo.pop() {
            let node = &bvh.nodes[n];
            let held = if node.prim_count > 0 {
                assert!(node.prim_count as usize <= MAX_LEAF, "leaf of {}", node.prim_count);
                let range = node.first_index as usize..(node.first_index + node.prim_count) as usize;
                bvh.primitive_indices[range].iter().fold(Aabb::empty(), |acc, &i| {
                    assert!(!std::mem::replace(&mut seen[i as usize], true), "primitive {i} twice");
                    acc.union(&aabbs[i as usize])
                })
            } else {
                let first = node.first_index as usize;
                assert!(first > n, "children after their parent");
                todo.extend([first, first + 1]);
                bvh.nodes[first].aabb().union(bvh.nodes[first + 1].aabb())
            };
            assert_eq!((node.aabb().min, node.aabb().max), (held.min, held.max), "node {n}");
        }
        assert!(seen.iter().all(|&s| s), "every primitive in a leaf");
        assert!(bvh.children_are_ordered_after_parents);
        assert_eq!(*depth, subtree_depth(&bvh.nodes));
        assert_eq!(bvh.max_depth, (depth + 1).max(DEFAULT_MAX_STACK_DEPTH));
    }

    #[test]
    fn every_primitive_lands_in_one_leaf_under_tight_boxes() {
        for n in [1, 2, 7, 8, 9, 100, 3 * PARALLEL_MIN + 5] {
            let aabbs = boxes(n, n as u64);
            check(&build(aabbs.len(), |i| aabbs[i]), &aabbs);
        }
    }

    #[test]
    fn equal_centroids_are_split_in_halves() {
        let aabbs = vec![Aabb::new(Vec3A::ZERO, Vec3A::ONE); 100];
        let built = build(aabbs.len(), |i| aabbs[i]);
        check(&built, &aabbs);
        // 100 → 50 → 25 → 12/13 → 6/7: leaves of six or seven, four levels down.
        assert_eq!(built.1, 5);
    }

    #[test]
    fn the_tree_does_not_depend_on_the_thread_count() {
        let aabbs = boxes(5 * PARALLEL_MIN, 3);
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| build(aabbs.len(), |i| aabbs[i]).0);
        let two = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap()
            .install(|| build(aabbs.len(), |i| aabbs[i]).0);
        assert_eq!(one.primitive_indices, two.primitive_indices);
        let key = |b: &Bvh2| b.nodes.iter().map(|n| (n.first_index, n.prim_count)).collect::<Vec<_>>();
        assert_eq!(key(&one), key(&two));
    }

    #[test]
    fn leaves_fill_packets_of_four() {
        // Sixteen unit boxes in a row: four leaves of four beat any leaf of fewer.
        let aabbs: Vec<Aabb> = (0..16)
            .map(|i| Aabb::new(Vec3A::new(i as f32 * 2.0, 0.0, 0.0), Vec3A::new(i as f32 * 2.0 + 1.0, 1.0, 1.0)))
            .collect();
        let built = build(aabbs.len(), |i| aabbs[i]);
        check(&built, &aabbs);
        let leaves: Vec<u32> = built.0.nodes.iter().filter(|n| n.prim_count > 0).map(|n| n.prim_count).collect();
        assert!(leaves.iter().all(|&c| c % 4 == 0), "leaves {leaves:?}");
    }

    #[test]
    fn partition_swaps_exactly_as_the_branching_loop_did() {
        let aabbs = boxes(1000, 7);
        let mut refs: Vec<Ref> = aabbs.iter().enumerate().map(|(i, &aabb)| Ref::new(aabb, i as u32)).collect();
        // A NaN box goes left, as its bin is 0.
        refs[500] = Ref::new(Aabb::new(Vec3A::splat(f32::NAN), Vec3A::splat(f32::NAN)), 500);
        for (axis, bin) in [(0, 1), (1, 16), (2, 31), (0, 9)] {
            let split = Split::Bins { axis, bin, min: 0.0, scale: 32.0 / 100.0 };
            let mut want = refs.clone();
            let mut left = 0;
            for j in 0..want.len() {
                let offset = want[j].aabb().center_axis(axis) * (32.0 / 100.0);
                if offset < bin as f32 || offset.is_nan() {
                    want.swap(j, left);
                    left += 1;
                }
            }
            assert_eq!(partition(&mut refs, &split), left, "axis {axis}, bin {bin}");
            let key = |r: &[Ref]| r.iter().map(|r| (r.index(), r.aabb().min.x.to_bits())).collect::<Vec<_>>();
            assert_eq!(key(&refs), key(&want), "axis {axis}, bin {bin}");
        }
    }
}
