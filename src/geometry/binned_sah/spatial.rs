//! Spatial splits (Stich, Friedrich and Dietrich 2009, "Spatial Splits in Bounding Volume
//! Hierarchies"; Embree's high build quality): where the best centroid split leaves two
//! children whose boxes overlap by more than [`OVERLAP_MIN`] of the root's area, planes through
//! the node's box are tried too. A triangle a plane crosses goes to both sides, each with the
//! box of its part on that side, unless putting it whole on one side costs less ("reference
//! unsplitting"). Large triangles, such as the walls and floors of a building, then stop
//! stretching the boxes of every node they belong to. Each triangle is held by one or more
//! leaves, the extra references bounded by [`SPLIT_BUDGET`] of the triangle count, shared
//! between the children of a split in proportion to their sizes, so that the tree does not
//! depend on the thread count.

use glam::Vec3A;
use obvhs::{
    aabb::Aabb,
    bvh2::{Bvh2, DEFAULT_MAX_STACK_DEPTH, node::Bvh2Node},
};
use rayon::prelude::*;

use super::{PARALLEL_MIN, Ref, Split, decide, object_split, packets, partition};

/// Planes tried per axis: the boundaries of this many equal slabs of the node's box.
const SPATIAL_BINS: usize = 16;

/// Overlap of the centroid split's children, as a fraction of the root's half area, above
/// which spatial splits are tried (Stich et al.'s α).
const OVERLAP_MIN: f32 = 1e-5;

/// Most extra references, as a fraction of the triangle count (a plane that would cross more
/// than a node's share is not tried).
const SPLIT_BUDGET: f32 = 0.3;

/// Fewest references of a node where spatial splits are tried. Below 512 they were hardly ever
/// taken on the peer scenes (trying them from 64 references up left the traversal counts
/// where they were), while trying them made the build much slower.
const SPATIAL_MIN_REFS: usize = 512;

/// Half area, as a fraction of the scene's, above which a triangle counts as large.
const LARGE_TRIANGLE: f32 = 1e-4;

/// Whether a set of triangles (their boxes `refs`, whose union has half area `root_area`) is
/// worth spatial splits: when at least one in a hundred triangles is large ([`LARGE_TRIANGLE`]),
/// as in a building such as Sponza, whose AO rays then trace faster for a little more build.
/// A finely tessellated model on a ground quad has almost none (the dragon: 2 of 871k), and
/// splitting there barely cut its traversal counts for a much longer build.
fn worth_splitting(refs: &[Ref], root_area: f32) -> bool {
    let large = refs.iter().filter(|r| r.aabb().half_area() > LARGE_TRIANGLE * root_area).count();
    large * 100 >= refs.len()
}

/// What every node's build needs: the triangles, and the root's half area.
struct Input<'a, T> {
    triangle: &'a T,
    root_area: f32,
}

/// Builds a BVH2 over `count` triangles (at least one), triangle `i` being `triangle(i)`, with
/// spatial splits; returns it with its depth. Leaves hold at most [`super::MAX_LEAF`]
/// references, as ranges of `primitive_indices`, where a triangle may appear in several leaves
/// (never twice in one).
pub fn build(count: usize, triangle: impl Fn(usize) -> [Vec3A; 3] + Sync) -> (Bvh2, usize) {
    let refs: Vec<Ref> = (0..count)
        .into_par_iter()
        .with_min_len(PARALLEL_MIN)
        .map(|i| {
            let [a, b, c] = triangle(i);
            Ref::new(Aabb::new(a.min(b).min(c), a.max(b).max(c)), i as u32)
        })
        .collect();
    let root_area = refs.iter().fold(Aabb::INVALID, |b, r| b.union(&r.aabb())).half_area();
    if !worth_splitting(&refs, root_area) {
        return super::build_refs(refs);
    }
    let input = Input { triangle: &triangle, root_area };
    let budget = (count as f32 * SPLIT_BUDGET) as usize;
    let (nodes, leaf_refs, depth) = subtree(&input, refs, budget);
    let bvh = Bvh2 {
        nodes,
        primitive_indices: leaf_refs.iter().map(Ref::index).collect(),
        children_are_ordered_after_parents: true,
        max_depth: (depth + 1).max(DEFAULT_MAX_STACK_DEPTH),
        ..Default::default()
    };
    (bvh, depth)
}

/// A node's split: a centroid split of its references in place, or a plane that sends some of
/// them to both sides.
enum NodeSplit {
    Leaf,
    Objects(Split),
    Plane { axis: usize, position: f32 },
}

/// The bounds of `refs` and how to split them, spatial splits allowed to add up to `budget`
/// references.
fn choose<T: Fn(usize) -> [Vec3A; 3] + Sync>(input: &Input<T>, refs: &[Ref], budget: usize) -> (Aabb, NodeSplit) {
    let objects = object_split(refs);
    let bounds = objects.bounds;
    let mut best = (objects.cost, None);
    if budget > 0
        && refs.len() >= SPATIAL_MIN_REFS
        && objects.overlap > OVERLAP_MIN * input.root_area
        && let Some((cost, axis, position)) = best_plane(refs, &bounds, budget)
        && cost < best.0
    {
        best = (cost, Some((axis, position)));
    }
    let split = match best {
        (cost, Some((axis, position))) => match decide(refs.len(), bounds, cost, Split::Halves) {
            Split::Leaf => NodeSplit::Leaf,
            _ => NodeSplit::Plane { axis, position },
        },
        (cost, None) => match decide(refs.len(), bounds, cost, objects.split) {
            Split::Leaf => NodeSplit::Leaf,
            split => NodeSplit::Objects(split),
        },
    };
    (bounds, split)
}

/// One slab's references: the union of their parts' boxes in it, and how many start and end
/// in it.
#[derive(Clone, Copy)]
struct Slab {
    bounds: Aabb,
    entries: u32,
    exits: u32,
}

impl Slab {
    const EMPTY: Slab = Slab { bounds: Aabb::INVALID, entries: 0, exits: 0 };
}

/// The slabs of `refs` along `axis`, [`SPATIAL_BINS`] equal ones from `min`, `width` wide.
fn slabs(refs: &[Ref], axis: usize, min: f32, width: f32) -> [Slab; SPATIAL_BINS] {
    let scale = 1.0 / width;
    let slab_of = |x: f32| (((x - min) * scale) as usize).min(SPATIAL_BINS - 1);
    let mut slabs = [Slab::EMPTY; SPATIAL_BINS];
    for r in refs {
        let (first, last) = (slab_of(r.aabb().min[axis]), slab_of(r.aabb().max[axis]));
        // The reference's box cut at the slab boundaries: as good an estimate of where its
        // triangle's parts lie as clipping the triangle to each slab (the same traversal counts
        // on the peer scenes, within 1 %), at a fraction of the cost.
        let mut rest = r.aabb();
        for (k, slab) in slabs.iter_mut().enumerate().take(last).skip(first) {
            let plane = min + (k + 1) as f32 * width;
            let mut part = rest;
            part.max[axis] = plane;
            slab.bounds = slab.bounds.union(&part);
            rest.min[axis] = plane;
        }
        slabs[last].bounds = slabs[last].bounds.union(&rest);
        slabs[first].entries += 1;
        slabs[last].exits += 1;
    }
    slabs
}

/// The plane of least cost among the slab boundaries of every axis that cross at most
/// `budget` references: (cost, axis, position), the cost counting the references a plane
/// crosses on both sides.
fn best_plane(refs: &[Ref], bounds: &Aabb, budget: usize) -> Option<(f32, usize, f32)> {
    let mut best: Option<(f32, usize, f32)> = None;
    for axis in 0..3 {
        let min = bounds.min[axis];
        let width = (bounds.max[axis] - min) / SPATIAL_BINS as f32;
        // Also skips a NaN width.
        if width.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            continue;
        }
        let slabs = if refs.len() >= 4 * PARALLEL_MIN {
            let merge = |mut a: [Slab; SPATIAL_BINS], b: [Slab; SPATIAL_BINS]| {
                for (a, b) in a.iter_mut().zip(b) {
                    *a = Slab {
                        bounds: a.bounds.union(&b.bounds),
                        entries: a.entries + b.entries,
                        exits: a.exits + b.exits,
                    };
                }
                a
            };
            refs.par_chunks(PARALLEL_MIN)
                .map(|c| slabs(c, axis, min, width))
                .reduce(|| [Slab::EMPTY; SPATIAL_BINS], merge)
        } else {
            slabs(refs, axis, min, width)
        };
        // Cost of, and references ending in, the slabs from k up.
        let (mut right, mut exits) = ([0.0f32; SPATIAL_BINS], [0usize; SPATIAL_BINS]);
        let (mut b, mut n) = (Aabb::INVALID, 0);
        for k in (1..SPATIAL_BINS).rev() {
            b = b.union(&slabs[k].bounds);
            n += slabs[k].exits as usize;
            (right[k], exits[k]) = (if n == 0 { f32::INFINITY } else { b.half_area() * packets(n) }, n);
        }
        let (mut b, mut n) = (Aabb::INVALID, 0);
        for k in 1..SPATIAL_BINS {
            b = b.union(&slabs[k - 1].bounds);
            n += slabs[k - 1].entries as usize;
            let crossed = (n + exits[k]).saturating_sub(refs.len());
            if n == 0 || crossed > budget {
                continue;
            }
            let cost = b.half_area() * packets(n) + right[k];
            if best.is_none_or(|(c, ..)| cost < c) {
                best = Some((cost, axis, min + k as f32 * width));
            }
        }
    }
    best
}

/// The boxes of the parts of triangle `tri` inside `within` on either side of the plane at
/// `position` on `axis`: each padded on the other axes by 2⁻¹⁸ of the triangle's largest
/// coordinate, more than the rounding of the points where its edges cross the plane, so that
/// every point of the triangle in `within` lies in one of them; clipped to `within`.
/// An empty side's box is invalid ([`Aabb::INVALID`]-like: some minimum above its maximum).
fn split_part(tri: &[Vec3A; 3], within: &Aabb, axis: usize, position: f32) -> (Aabb, Aabb) {
    let (mut left, mut right) = (Aabb::INVALID, Aabb::INVALID);
    let mut crossed = false;
    for i in 0..3 {
        let (a, b) = (tri[i], tri[(i + 1) % 3]);
        let (pa, pb) = (a[axis], b[axis]);
        if pa <= position {
            left.extend(a);
        }
        if pa >= position {
            right.extend(a);
        }
        if (pa < position && position < pb) || (pb < position && position < pa) {
            let mut p = a + (b - a) * ((position - pa) / (pb - pa));
            p[axis] = position;
            left.extend(p);
            right.extend(p);
            crossed = true;
        }
    }
    if crossed {
        let largest = tri.iter().fold(0.0f32, |m, p| m.max(p.abs().max_element()));
        let mut pad = Vec3A::splat(largest * (1.0 / (1 << 18) as f32));
        pad[axis] = 0.0;
        for side in [&mut left, &mut right] {
            side.min -= pad;
            side.max += pad;
        }
    }
    left.max[axis] = left.max[axis].min(position);
    right.min[axis] = right.min[axis].max(position);
    let clip = |b: Aabb| Aabb::new(b.min.max(within.min), b.max.min(within.max));
    (clip(left), clip(right))
}

/// Whether `b` holds any point (no minimum above its maximum).
fn is_valid(b: &Aabb) -> bool {
    b.min.cmple(b.max).all()
}

/// `refs` split by the plane at `position` on `axis`: (left, right). A reference the plane
/// crosses goes to both sides with the boxes of its parts, or whole to one side where that
/// costs less than splitting it, with both sides' bounds and counts taken as if every crossed
/// reference were split.
fn split_by_plane<T: Fn(usize) -> [Vec3A; 3]>(
    triangle: &T,
    refs: Vec<Ref>,
    axis: usize,
    position: f32,
) -> (Vec<Ref>, Vec<Ref>) {
    let (mut left, mut right) = (Vec::with_capacity(refs.len()), Vec::with_capacity(refs.len()));
    // (reference, its left part, its right part)
    let mut crossed = Vec::new();
    let (mut left_bounds, mut right_bounds) = (Aabb::INVALID, Aabb::INVALID);
    for r in refs {
        if r.aabb().max[axis] <= position {
            left_bounds = left_bounds.union(&r.aabb());
            left.push(r);
        } else if r.aabb().min[axis] >= position {
            right_bounds = right_bounds.union(&r.aabb());
            right.push(r);
        } else {
            let (l, rr) = split_part(&triangle(r.index() as usize), &r.aabb(), axis, position);
            match (is_valid(&l), is_valid(&rr)) {
                (true, true) => {
                    left_bounds = left_bounds.union(&l);
                    right_bounds = right_bounds.union(&rr);
                    crossed.push((r, l, rr));
                }
                (true, false) => {
                    left_bounds = left_bounds.union(&r.aabb());
                    left.push(r);
                }
                _ => {
                    right_bounds = right_bounds.union(&r.aabb());
                    right.push(r);
                }
            }
        }
    }
    let (n_left, n_right) = ((left.len() + crossed.len()) as f32, (right.len() + crossed.len()) as f32);
    let (area_left, area_right) = (left_bounds.half_area(), right_bounds.half_area());
    let split_cost = area_left * n_left + area_right * n_right;
    for (r, l, rr) in crossed {
        let all_left = left_bounds.union(&r.aabb()).half_area() * n_left + area_right * (n_right - 1.0);
        let all_right = area_left * (n_left - 1.0) + right_bounds.union(&r.aabb()).half_area() * n_right;
        if all_left < split_cost && all_left <= all_right {
            left.push(r);
        } else if all_right < split_cost {
            right.push(r);
        } else {
            left.push(Ref::new(l, r.index()));
            right.push(Ref::new(rr, r.index()));
        }
    }
    (left, right)
}

/// A split node's children: their references, and their budgets (what the split leaves of
/// `budget`, shared in proportion to their sizes). A plane that separates nothing (every
/// reference on one side) gives halves.
fn children<T: Fn(usize) -> [Vec3A; 3]>(
    input: &Input<T>,
    mut refs: Vec<Ref>,
    split: NodeSplit,
    budget: usize,
) -> ((Vec<Ref>, usize), (Vec<Ref>, usize)) {
    let count = refs.len();
    let (left, right) = match split {
        NodeSplit::Leaf => unreachable!("a leaf is not split"),
        NodeSplit::Objects(split) => {
            let mid = partition(&mut refs, &split);
            let right = refs.split_off(mid);
            (refs, right)
        }
        NodeSplit::Plane { axis, position } => {
            let (left, right) = split_by_plane(input.triangle, refs, axis, position);
            if left.is_empty() || right.is_empty() {
                let mut all = if left.is_empty() { right } else { left };
                let right = all.split_off(all.len() / 2);
                (all, right)
            } else {
                (left, right)
            }
        }
    };
    let left_over = budget.saturating_sub(left.len() + right.len() - count);
    let left_budget = left_over * left.len() / (left.len() + right.len());
    ((left, left_budget), (right, left_over - left_budget))
}

/// The subtree over `refs`, root first, and its references in leaf order; leaves' and inner
/// nodes' `first_index` count from this subtree's first reference and root.
fn subtree<T: Fn(usize) -> [Vec3A; 3] + Sync>(
    input: &Input<T>,
    refs: Vec<Ref>,
    budget: usize,
) -> (Vec<Bvh2Node>, Vec<Ref>, usize) {
    if refs.len() < PARALLEL_MIN {
        return subtree_serial(input, refs, budget);
    }
    let (bounds, split) = choose(input, &refs, budget);
    if let NodeSplit::Leaf = split {
        return (vec![Bvh2Node::new(bounds, refs.len() as u32, 0)], refs, 1);
    }
    let ((left, left_budget), (right, right_budget)) = children(input, refs, split, budget);
    let ((l, mut l_refs, l_depth), (r, r_refs, r_depth)) =
        rayon::join(|| subtree(input, left, left_budget), || subtree(input, right, right_budget));
    let mut nodes = Vec::with_capacity(1 + l.len() + r.len());
    nodes.push(Bvh2Node::new(bounds, 0, 1));
    // Inner nodes move by their subtree's shift; the right subtree's leaves also start after
    // the left subtree's references.
    let moved = |node: &Bvh2Node, shift: usize, refs_before: usize| {
        let mut node = *node;
        if node.prim_count == 0 {
            node.first_index += shift as u32;
        } else {
            node.first_index += refs_before as u32;
        }
        node
    };
    let before = l_refs.len();
    nodes.push(moved(&l[0], 2, 0));
    nodes.push(moved(&r[0], l.len() + 1, before));
    nodes.extend(l[1..].iter().map(|n| moved(n, 2, 0)));
    nodes.extend(r[1..].iter().map(|n| moved(n, l.len() + 1, before)));
    l_refs.extend(r_refs);
    (nodes, l_refs, 1 + l_depth.max(r_depth))
}

/// [`subtree`] on this thread.
fn subtree_serial<T: Fn(usize) -> [Vec3A; 3] + Sync>(
    input: &Input<T>,
    refs: Vec<Ref>,
    budget: usize,
) -> (Vec<Bvh2Node>, Vec<Ref>, usize) {
    let mut nodes = vec![Bvh2Node::new(Aabb::empty(), 0, 0)];
    let mut out = Vec::with_capacity(refs.len());
    let mut depth = 0;
    // (node, its references, their budget, the node's depth); the left child is popped first,
    // so leaves come out in left-to-right order.
    let mut todo = vec![(0usize, refs, budget, 1usize)];
    while let Some((node, refs, budget, d)) = todo.pop() {
        depth = depth.max(d);
        let (bounds, split) = choose(input, &refs, budget);
        if let NodeSplit::Leaf = split {
            nodes[node] = Bvh2Node::new(bounds, refs.len() as u32, out.len() as u32);
            out.extend(refs);
            continue;
        }
        let ((left, left_budget), (right, right_budget)) = children(input, refs, split, budget);
        let first = nodes.len();
        nodes[node] = Bvh2Node::new(bounds, 0, first as u32);
        nodes.extend([Bvh2Node::new(Aabb::empty(), 0, 0); 2]);
        todo.push((first + 1, right, right_budget, d + 1));
        todo.push((first, left, left_budget, d + 1));
    }
    (nodes, out, depth)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::SplitMix64;

    /// A room: a floor and two walls of two triangles each, `beams` long diagonal beams across
    /// it, and `small` small triangles scattered inside.
    fn room(rng: &mut SplitMix64, beams: usize, small: usize) -> Vec<[Vec3A; 3]> {
        let v = Vec3A::new;
        let mut tris = vec![
            [v(-10.0, 0.0, -10.0), v(10.0, 0.0, -10.0), v(10.0, 0.0, 10.0)],
            [v(-10.0, 0.0, -10.0), v(10.0, 0.0, 10.0), v(-10.0, 0.0, 10.0)],
            [v(-10.0, 0.0, -10.0), v(10.0, 0.0, -10.0), v(10.0, 8.0, -10.0)],
            [v(-10.0, 0.0, -10.0), v(10.0, 8.0, -10.0), v(-10.0, 8.0, -10.0)],
            [v(-10.0, 0.0, -10.0), v(-10.0, 8.0, 10.0), v(-10.0, 0.0, 10.0)],
            [v(-10.0, 0.0, -10.0), v(-10.0, 8.0, -10.0), v(-10.0, 8.0, 10.0)],
        ];
        for k in 0..beams {
            let (y, s) = (0.5 + k as f32 * 7.0 / beams as f32, rng.next_f32() * 2.0 - 1.0);
            tris.push([v(-9.0, y, -9.0 * s), v(9.0, y + 0.3, 9.0 * s), v(9.0, y + 0.5, 9.0 * s + 0.4)]);
        }
        for _ in 0..small {
            let c = v(rng.next_f32() * 18.0 - 9.0, rng.next_f32() * 7.0, rng.next_f32() * 18.0 - 9.0);
            let e = |rng: &mut SplitMix64| v(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.2 - 0.1;
            tris.push([c, c + e(rng), c + e(rng)]);
        }
        tris
    }

    /// Each leaf's boxes by triangle, after checking that every node's box is the union of its
    /// children's, leaves hold at most [`super::super::MAX_LEAF`] distinct triangles, and every
    /// triangle is in some leaf.
    fn leaf_boxes(bvh: &Bvh2, count: usize) -> Vec<Vec<Aabb>> {
        let mut boxes = vec![Vec::new(); count];
        let mut todo = vec![0usize];
        while let Some(n) = todo.pop() {
            let node = &bvh.nodes[n];
            if node.prim_count > 0 {
                assert!(node.prim_count as usize <= super::super::MAX_LEAF);
                let range = node.first_index as usize..(node.first_index + node.prim_count) as usize;
                let mut held: Vec<u32> = bvh.primitive_indices[range].to_vec();
                held.sort_unstable();
                held.dedup();
                assert_eq!(held.len(), node.prim_count as usize, "a triangle twice in leaf {n}");
                for i in held {
                    boxes[i as usize].push(*node.aabb());
                }
            } else {
                let first = node.first_index as usize;
                assert!(first > n, "children after their parent");
                todo.extend([first, first + 1]);
                let union = bvh.nodes[first].aabb().union(bvh.nodes[first + 1].aabb());
                assert_eq!((node.aabb().min, node.aabb().max), (union.min, union.max), "node {n}");
            }
        }
        assert!(boxes.iter().all(|b| !b.is_empty()), "every triangle in a leaf");
        boxes
    }

    fn contains(b: &Aabb, p: Vec3A) -> bool {
        b.min.cmple(p).all() && p.cmple(b.max).all()
    }

    /// The SAH cost of a BVH2, relative to its root's area: nodes at [`super::super::NODE_COST`],
    /// leaves by their packets.
    fn sah_cost(bvh: &Bvh2) -> f32 {
        let cost: f32 = bvh
            .nodes
            .iter()
            .map(|n| {
                let area = n.aabb().half_area();
                if n.prim_count > 0 { area * packets(n.prim_count as usize) } else { area * super::super::NODE_COST }
            })
            .sum();
        cost / bvh.nodes[0].aabb().half_area()
    }

    #[test]
    fn every_point_of_every_triangle_lies_in_a_leaf_that_holds_it() {
        // Near the origin, and far from it.
        for offset in [Vec3A::ZERO, Vec3A::new(3.0e4, -2.0e4, 1.0e4)] {
            let tris: Vec<[Vec3A; 3]> =
                room(&mut SplitMix64::new(1), 40, 4000).into_iter().map(|t| t.map(|p| p + offset)).collect();
            every_point_in_a_leaf(&tris);
        }
    }

    #[test]
    fn a_split_parts_boxes_hold_the_exact_points_where_its_edges_cross_the_plane() {
        // Crossing points worked out in f64 must lie in both parts' boxes: the rounding of the
        // f32 crossing points is what the padding covers (without it this fails).
        let mut rng = SplitMix64::new(9);
        let mut crossings = 0;
        for k in 0..20_000 {
            let scale = [1.0, 1.0e3, 3.0e4][k % 3];
            let p = |rng: &mut SplitMix64| Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * scale;
            let tri = [p(&mut rng), p(&mut rng), p(&mut rng)];
            let axis = k % 3;
            let position = (tri[0][axis] + tri[1][axis]) * 0.5;
            let within = Aabb::new(tri[0].min(tri[1]).min(tri[2]), tri[0].max(tri[1]).max(tri[2]));
            let (left, right) = split_part(&tri, &within, axis, position);
            for i in 0..3 {
                let (a, b) = (tri[i].as_dvec3(), tri[(i + 1) % 3].as_dvec3());
                let x = position as f64;
                if (a[axis] - x) * (b[axis] - x) >= 0.0 {
                    continue;
                }
                // On the plane exactly; f64's own rounding is far below f32's elsewhere.
                let mut crossing = a + (b - a) * ((x - a[axis]) / (b[axis] - a[axis]));
                crossing[axis] = x;
                for side in [&left, &right] {
                    let inside = (0..3).all(|j| side.min[j] as f64 <= crossing[j] && crossing[j] <= side.max[j] as f64);
                    assert!(inside, "triangle {tri:?}, axis {axis} at {position}: {crossing} outside {side:?}");
                }
                crossings += 1;
            }
        }
        assert!(crossings > 20_000, "{crossings} crossings");
    }

    /// Builds `tris` (the first 46 large) with splits and checks that every point of every
    /// triangle lies in a leaf that holds it.
    fn every_point_in_a_leaf(tris: &[[Vec3A; 3]]) {
        let (bvh, _) = build(tris.len(), |i| tris[i]);
        assert!(bvh.primitive_indices.len() > tris.len() + 50, "spatial splits were made");
        assert!(bvh.primitive_indices.len() <= tris.len() + (tris.len() as f32 * SPLIT_BUDGET) as usize);
        let boxes = leaf_boxes(&bvh, tris.len());
        let mut rng = SplitMix64::new(2);
        for (i, [a, b, c]) in tris.iter().enumerate() {
            let mut points = vec![*a, *b, *c, (*a + *b) * 0.5, (*b + *c) * 0.5, (*c + *a) * 0.5];
            // The large ones densely, along their edges too (where the split planes cross them).
            let large = i < 46;
            for (p, q) in [(*a, *b), (*b, *c), (*c, *a)] {
                let steps = if large { 1000 } else { 4 };
                points.extend((1..steps).map(|k| p + (q - p) * (k as f32 / steps as f32)));
            }
            for _ in 0..if large { 4000 } else { 4 } {
                let (u, v) = (rng.next_f32(), rng.next_f32());
                let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
                points.push(*a + (*b - *a) * u + (*c - *a) * v);
            }
            for p in points {
                assert!(boxes[i].iter().any(|b| contains(b, p)), "triangle {i}: point {p} in none of its leaves");
            }
        }
    }

    #[test]
    fn splits_lower_the_sah_cost_of_a_room() {
        let tris = room(&mut SplitMix64::new(3), 40, 4000);
        let (split, _) = build(tris.len(), |i| tris[i]);
        let (plain, _) = super::super::build(tris.len(), |i| {
            let [a, b, c] = tris[i];
            Aabb::new(a.min(b).min(c), a.max(b).max(c))
        });
        let (with, without) = (sah_cost(&split), sah_cost(&plain));
        assert!(with < 0.95 * without, "SAH cost {with} with splits, {without} without");
    }

    #[test]
    fn sets_with_few_large_triangles_get_the_plain_build() {
        // A floor under 20000 small triangles: 2 large of 20002.
        let tris = room(&mut SplitMix64::new(4), 0, 20_000);
        let tris: Vec<_> = tris[..2].iter().chain(&tris[6..]).copied().collect();
        let (split, depth) = build(tris.len(), |i| tris[i]);
        let boxes = |i: usize| {
            let [a, b, c] = tris[i];
            Aabb::new(a.min(b).min(c), a.max(b).max(c))
        };
        let (plain, plain_depth) = super::super::build(tris.len(), boxes);
        assert_eq!(split.primitive_indices, plain.primitive_indices);
        assert_eq!(depth, plain_depth);
    }

    #[test]
    fn the_tree_does_not_depend_on_the_thread_count() {
        // Large enough for parallel subtrees and the slabs' parallel passes at the top.
        let tris = room(&mut SplitMix64::new(5), 600, 40_000);
        let build_on = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| build(tris.len(), |i| tris[i]).0)
        };
        let (one, two) = (build_on(1), build_on(2));
        assert!(one.primitive_indices.len() > tris.len(), "spatial splits were made");
        assert_eq!(one.primitive_indices, two.primitive_indices);
        let key = |b: &Bvh2| {
            b.nodes.iter().map(|n| (n.first_index, n.prim_count, n.aabb().min.to_array())).collect::<Vec<_>>()
        };
        assert_eq!(key(&one), key(&two));
    }
}
