use std::{
    cell::{Cell, RefCell},
    collections::BTreeSet,
    time::Duration,
};

use glam::{Vec3, Vec3A};
use obvhs::{
    BvhBuildParams,
    bvh2::{builder::build_bvh2, node::Bvh2Node},
};

use super::{
    build::{SlotPlan, breadth_first, children_after_parents},
    packet::{FusedPacket, PacketNodeTest, RayPacket},
    *,
};
use crate::{geometry::lanes::RayLanes, random::SplitMix64, simd::Plain};

/// `check(test)` for each eight-wide node test this CPU can run: the portable one, and AVX2's
/// where it has AVX2 (the two decide alike, bit for bit).
fn each_eight_test(mut check: impl FnMut(&dyn Fn(&WideBvh<8>, &Ray) -> (Leaves, Leaves))) {
    check(&|tree, ray| visited(tree, Plain, ray));
    #[cfg(target_arch = "x86_64")]
    if let Some(isa) = crate::simd::HasAvx2::on_cpu() {
        check(&|tree, ray| visited(tree, isa, ray));
    }
}

/// Leaves as (first, count).
type Leaves = BTreeSet<(u32, u32)>;

/// The leaves whose own box the ray enters in [0, tmax], by the scalar slab test (with the
/// same exit widening and NaN rule as the node tests).
fn brute_force(bvh2: &[Bvh2Node], ray: &Ray) -> Leaves {
    let (o, inv) = (ray.origin.to_array(), ray.inv_dir.to_array());
    let mut leaves = Leaves::new();
    for node in bvh2.iter().filter(|n| n.prim_count > 0) {
        let (mut near, mut far) = (NEAR_START, f32::INFINITY);
        for a in 0..3 {
            let (t0, t1) = ((node.aabb().min[a] - o[a]) * inv[a], (node.aabb().max[a] - o[a]) * inv[a]);
            let (tn, tf) = if inv[a] < 0.0 { (t1, t0) } else { (t0, t1) };
            near = if tn > near { tn } else { near };
            far = if tf < far { tf } else { far };
        }
        if near <= (far * far_scale()).min(ray.tmax) {
            leaves.insert((node.first_index, node.prim_count));
        }
    }
    leaves
}

/// The leaves `tree` visits with a callback that never reports a hit, by both traversals.
fn visited<const W: usize>(tree: &WideBvh<W>, test: impl NodeTest<W>, ray: &Ray) -> (Leaves, Leaves) {
    let mut stack = Vec::new();
    let mut any = Leaves::new();
    tree.occluded(test, ray, &mut stack, |first, count, _| {
        assert!(any.insert((first, count)), "leaf ({first}, {count}) visited twice");
        false
    });
    let mut nearest = Leaves::new();
    tree.closest(test, &mut ray.clone(), &mut stack, |first, count, _, _| {
        assert!(nearest.insert((first, count)), "leaf ({first}, {count}) visited twice");
    });
    assert!(stack.is_empty());
    (any, nearest)
}

#[test]
fn a_ray_leaving_a_flat_box_it_starts_on_enters_no_leaf() {
    // A floor of flat boxes at y = 0 and one box above it.
    let mut boxes: Vec<Aabb> = (0..16)
        .map(|i| Aabb::new(Vec3::new(i as f32, 0.0, 0.0).into(), Vec3::new(i as f32 + 1.0, 0.0, 1.0).into()))
        .collect();
    boxes.push(Aabb::new(Vec3::new(3.0, 2.0, 0.0).into(), Vec3::new(4.0, 3.0, 1.0).into()));
    let bvh2 = build_bvh2(&boxes, BvhBuildParams::medium_build(), &mut Duration::default()).nodes;
    let up = Ray::new(Vec3A::new(3.5, 0.0, 0.5), Vec3A::new(0.0, 1.0, 0.2).normalize(), f32::INFINITY);
    let down = Ray::new(Vec3A::new(3.5, 1.0, 0.5), Vec3A::new(0.0, -1.0, 0.2).normalize(), f32::INFINITY);
    let four = Bvh4::from_bvh2(&bvh2);
    let (up4, down4) = (visited(&four, Plain, &up).0, visited(&four, Plain, &down).0);
    assert_eq!(up4.len(), 1, "only the box above, not the floor under the origin: {up4:?}");
    assert_eq!(down4.len(), 1, "the floor box the ray comes down on: {down4:?}");
    assert_ne!(up4, down4);
    if let Some(eight) = Bvh8::from_bvh2(&bvh2) {
        each_eight_test(|visit| {
            assert_eq!((visit(&eight, &up).0, visit(&eight, &down).0), (up4.clone(), down4.clone()))
        });
    }
}

/// Eight rays from one point, traversed as a packet: every ray must visit exactly the
/// leaves it enters (by brute force), whether it went through a leaf with the packet, on
/// its own from a node few rays entered, or both.
#[cfg(target_arch = "x86_64")]
#[test]
fn a_packet_visits_exactly_the_leaves_each_ray_enters() {
    use crate::simd::{Avx, Avx512, HasAvx2, HasAvx512, Portable};
    for (offset, size) in [(0.0, 1.0), (3.0e4, 1.0e-2)] {
        let (bvh2, tree) = packet_test_scene(offset, size);
        let Some(tree) = tree else {
            eprintln!("no eight-wide trees on this architecture: packets are not used and not tested");
            return;
        };
        let general = |r: &RayLanes<Portable>, _| RayPacket::new(r);
        packets_visit_the_leaves_rays_enter::<Portable, _>(Plain, &bvh2, &tree, offset, size, general, true);
        let Some(isa) = HasAvx2::on_cpu() else {
            eprintln!("no AVX2 on this CPU: eight-lane vector packets are not used and not tested");
            return;
        };
        packets_visit_the_leaves_rays_enter::<Avx, _>(isa, &bvh2, &tree, offset, size, |r, _| RayPacket::new(r), true);
        if let Some(isa) = HasAvx512::on_cpu() {
            let general = |r: &RayLanes<Avx512>, _| RayPacket::new(r);
            packets_visit_the_leaves_rays_enter::<Avx512, _>(isa, &bvh2, &tree, offset, size, general, true);
        } else {
            eprintln!("no AVX-512 on this CPU: sixteen-lane packets are not used and not tested");
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[test]
fn a_fused_packet_visits_every_leaf_each_ray_truly_enters() {
    use crate::simd::{Avx, Avx512, HasAvx2, HasAvx512, Portable};
    for (offset, size) in [(0.0, 1.0), (3.0e4, 1.0e-2)] {
        let (bvh2, tree) = packet_test_scene(offset, size);
        let Some(tree) = tree else {
            eprintln!("no eight-wide trees on this architecture: packets are not used and not tested");
            return;
        };
        let fused = |r: &RayLanes<Portable>, live| FusedPacket::new(r, live);
        packets_visit_the_leaves_rays_enter::<Portable, _>(Plain, &bvh2, &tree, offset, size, fused, false);
        let Some(isa) = HasAvx2::on_cpu() else {
            eprintln!("no AVX2 on this CPU: eight-lane vector packets are not used and not tested");
            return;
        };
        let fused = |r: &RayLanes<Avx>, live| FusedPacket::new(r, live);
        packets_visit_the_leaves_rays_enter::<Avx, _>(isa, &bvh2, &tree, offset, size, fused, false);
        let Some(isa) = HasAvx512::on_cpu() else {
            eprintln!("no AVX-512 on this CPU: sixteen-lane fused packets are not used and not tested");
            continue;
        };
        let fused = |r: &RayLanes<Avx512>, live| FusedPacket::new(r, live);
        packets_visit_the_leaves_rays_enter::<Avx512, _>(isa, &bvh2, &tree, offset, size, fused, false);
    }
}

#[cfg(target_arch = "x86_64")]
/// 3,000 random boxes of up to 1.5·`size` in a cube of 20·`size` around (`offset`, 0, 0),
/// plus eight flat ones on y = 0, as a BVH2 and its eight-wide tree (`None` on other architectures).
fn packet_test_scene(offset: f32, size: f32) -> (Vec<Bvh2Node>, Option<Bvh8>) {
    let mut rng = SplitMix64::new(17);
    let base = Vec3::new(offset, 0.0, 0.0);
    let mut point = |scale: f32| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * scale * size;
    let mut boxes: Vec<Aabb> = (0..3_000)
        .map(|_| {
            let min = base + point(20.0) - 10.0 * size;
            Aabb::new(min.into(), (min + point(1.5)).into())
        })
        .collect();
    // Flat boxes some packets start on.
    boxes.extend((0..8).map(|i| {
        let x = offset + i as f32 * size;
        Aabb::new(Vec3A::new(x, 0.0, 0.0), Vec3A::new(x + size, 0.0, size))
    }));
    let bvh2 = build_bvh2(&boxes, BvhBuildParams::medium_build(), &mut Duration::default()).nodes;
    let tree = Bvh8::from_bvh2(&bvh2);
    (bvh2, tree)
}

#[cfg(target_arch = "x86_64")]
/// The leaves whose box the ray truly enters, in f64 from its origin and direction (not its
/// rounded reciprocal), with strict comparisons: boxes the ray only touches are left out.
fn truly_entered(bvh2: &[Bvh2Node], ray: &Ray) -> Leaves {
    let (o, d) = (ray.origin.as_dvec3(), ray.dir.as_dvec3());
    let mut leaves = Leaves::new();
    'nodes: for node in bvh2.iter().filter(|n| n.prim_count > 0) {
        let (lo, hi) = (node.aabb().min.as_dvec3(), node.aabb().max.as_dvec3());
        let (mut near, mut far) = (0.0f64, f64::from(ray.tmax));
        for a in 0..3 {
            if d[a] == 0.0 {
                if o[a] <= lo[a] || o[a] >= hi[a] {
                    continue 'nodes;
                }
                continue;
            }
            let (t0, t1) = ((lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]);
            near = near.max(t0.min(t1));
            far = far.min(t0.max(t1));
        }
        if near < far {
            leaves.insert((node.first_index, node.prim_count));
        }
    }
    leaves
}

/// [`a_packet_visits_exactly_the_leaves_each_ray_enters`] for packets of `L::WIDTH` rays
/// tested by `test(rays, live)`: with `exact`, each lane visits exactly the leaves of its
/// own ray's node test ([`brute_force`]); else every leaf it truly enters
/// ([`truly_entered`]) and only leaves whose box, grown by a thousandth of `size`, its own
/// node test enters.
#[cfg(target_arch = "x86_64")]
fn packets_visit_the_leaves_rays_enter<L: crate::geometry::lanes::PacketLanes, P: PacketNodeTest>(
    isa: L::Isa,
    bvh2: &[Bvh2Node],
    tree: &Bvh8,
    offset: f32,
    size: f32,
    test: impl Fn(&RayLanes<L>, u32) -> P,
    exact: bool,
) {
    let mut rng = SplitMix64::new(18);
    let (packet_leaves, single_leaves) = (Cell::new(0), Cell::new(0));
    let all = (1u32 << L::WIDTH) - 1;
    let grown: Vec<Bvh2Node> = bvh2
        .iter()
        .map(|n| {
            // The fused test's boxes grow by about 4u·|o| (twice that, to be safe).
            let grow = 1e-3 * size + 8.0 * f32::EPSILON * offset.abs();
            let (min, max) = (n.aabb().min - grow, n.aabb().max + grow);
            Bvh2Node::new(Aabb::new(min, max), n.prim_count, n.first_index)
        })
        .collect();
    let base = Vec3A::new(offset, 0.0, 0.0);
    for p in 0..300 {
        let origin = if p % 5 == 0 {
            base + Vec3A::new(rng.next_f32() * 8.0, 0.0, rng.next_f32()) * size
        } else {
            base + (Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 24.0 - 12.0) * size
        };
        let rays: Vec<Ray> = (0..L::WIDTH)
            .map(|i| {
                let mut dir = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
                if i % 3 == 0 {
                    dir[(i + p) % 3] = 0.0;
                }
                let tmax = if i % 2 == 0 { f32::INFINITY } else { rng.next_f32() * 20.0 * size };
                Ray::new(origin, dir.normalize_or(Vec3A::Y), tmax)
            })
            .collect();
        let live = if p % 7 == 0 { 0b1011_0110_1101_0110 & all } else { all };
        let seen = RefCell::new(vec![Leaves::new(); L::WIDTH]);
        let visit = |lane: usize, leaf: (u32, u32), count: &Cell<usize>| {
            assert!(seen.borrow_mut()[lane].insert(leaf), "lane {lane} visits leaf {leaf:?} twice");
            count.set(count.get() + 1);
        };
        let mut stack = Vec::new();
        let blocked = {
            tree.occluded_packet(
                &test(&L::rays(isa, &rays), live),
                0,
                live,
                &mut stack,
                |first, count, lanes, _| {
                    for lane in (0..L::WIDTH).filter(|k| lanes & (1 << k) != 0) {
                        visit(lane, (first, count), &packet_leaves);
                    }
                    0
                },
                |node, lane, stack| {
                    tree.occluded_from(L::node_test8(isa), node, &rays[lane], stack, |first, count, _| {
                        visit(lane, (first, count), &single_leaves);
                        false
                    })
                },
            )
        };
        assert_eq!(blocked, 0);
        for (lane, ray) in rays.iter().enumerate() {
            let seen = &seen.borrow()[lane];
            let at = format!("{} lanes, offset {offset}, packet {p}, lane {lane}", L::WIDTH);
            if live & (1 << lane) == 0 {
                assert!(seen.is_empty(), "{at}");
            } else if exact {
                assert_eq!(*seen, brute_force(bvh2, ray), "{at}");
            } else {
                let truly = truly_entered(bvh2, ray);
                assert!(seen.is_superset(&truly), "{at}: misses {:?}", truly.difference(seen).collect::<Vec<_>>());
                // (A direction component of 0 leaves its axis unculled: any leaf may come.)
                if ray.dir.cmpne(Vec3A::ZERO).all() {
                    let near = brute_force(&grown, ray);
                    assert!(seen.is_subset(&near), "{at}: visits {:?}", seen.difference(&near).collect::<Vec<_>>());
                }
            }
        }
    }
    let (packet_leaves, single_leaves) = (packet_leaves.get(), single_leaves.get());
    assert!(packet_leaves > 1_000 && single_leaves > 1_000, "{packet_leaves} by packet, {single_leaves} alone");
}

/// The leaves of the subtree under node `node` of a wide tree.
#[cfg(target_arch = "x86_64")]
fn leaves_under(tree: &Bvh8, node: u32) -> Leaves {
    let n = &tree.nodes[node as usize];
    let mut leaves = Leaves::new();
    for c in 0..8 {
        if n.count[c] > 0 {
            leaves.insert((n.child[c], n.count[c]));
        } else if n.planes[0][c] <= n.planes[3][c] {
            leaves.extend(leaves_under(tree, n.child[c]));
        }
    }
    leaves
}

/// Random boxes, from points up to a third of the scene across, near the origin and 3·10⁴
/// from it: every leaf whose box overlaps one lies under its entry node, and a box with
/// no entry node overlaps no leaf.
#[cfg(target_arch = "x86_64")]
#[test]
fn the_entry_node_holds_every_leaf_a_box_overlaps() {
    for (offset, size) in [(0.0, 1.0), (3.0e4, 1.0e-2)] {
        let (bvh2, tree) = packet_test_scene(offset, size);
        let Some(tree) = tree else {
            eprintln!("no eight-wide trees on this architecture: packets are not used and not tested");
            return;
        };
        let mut rng = SplitMix64::new(19);
        let (mut deeper, mut empty) = (0, 0);
        for q in 0..2_000 {
            // Boxes from a point to a thousandth of the scene across, up to a third of it.
            let extent = size * 20.0 * [0.0, 0.001, 0.05, 0.3][q % 4];
            let corner = Vec3A::new(offset, 0.0, 0.0)
                + (Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 26.0 - 13.0) * size;
            let (lo, hi) = (corner, corner + Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * extent);
            let overlapping: Leaves = bvh2
                .iter()
                .filter(|n| n.prim_count > 0)
                .filter(|n| n.aabb().min.cmple(hi).all() && n.aabb().max.cmpge(lo).all())
                .map(|n| (n.first_index, n.prim_count))
                .collect();
            let entry = tree.entry_node(Plain, lo, hi);
            if let Some(isa) = crate::simd::HasAvx2::on_cpu() {
                assert_eq!(tree.entry_node(isa, lo, hi), entry, "box {q}: AVX2 and portable lanes differ");
            }
            match entry {
                None => {
                    assert!(overlapping.is_empty(), "box {q}: no entry, yet it overlaps {overlapping:?}");
                    empty += 1;
                }
                Some(node) => {
                    let under = leaves_under(&tree, node);
                    let missed: Vec<_> = overlapping.difference(&under).collect();
                    assert!(missed.is_empty(), "box {q}: node {node} leaves out {missed:?}");
                    deeper += (node != 0) as usize;
                }
            }
        }
        // The test has teeth: many boxes start below the root, and some overlap nothing.
        assert!(deeper > 300 && empty > 50, "offset {offset}: {deeper} below the root, {empty} empty");
    }
}

/// Sum of the surface areas of a wide tree's nodes (each the union of its children's boxes).
fn node_area<const W: usize>(tree: &WideBvh<W>) -> f32 {
    tree.nodes
        .iter()
        .map(|n| {
            let used = (0..W).take_while(|&c| c == 0 || n.count[c] > 0 || n.child[c] > 0);
            let boxes = used.map(|c| {
                Aabb::new(
                    Vec3A::new(n.planes[0][c], n.planes[1][c], n.planes[2][c]),
                    Vec3A::new(n.planes[3][c], n.planes[4][c], n.planes[5][c]),
                )
            });
            boxes.fold(Aabb::empty(), |a, b| a.union(&b)).half_area()
        })
        .sum()
}

/// The least node area of any collapse of `bvh2` into nodes of at most `width` children,
/// by trying every choice of which inner nodes (besides the root) stay nodes.
fn least_node_area(bvh2: &[Bvh2Node], width: usize) -> f32 {
    let inner: Vec<usize> = (1..bvh2.len()).filter(|&n| bvh2[n].prim_count == 0).collect();
    let mut best = f32::INFINITY;
    for kept in 0u32..1 << inner.len() {
        let stays = |n: usize| n == 0 || inner.iter().position(|&m| m == n).is_some_and(|i| kept >> i & 1 == 1);
        // Children of a kept node: its descendants down to the first leaf or kept node.
        let children = |n: usize| {
            let (mut count, mut todo) = (0, vec![bvh2[n].first_index as usize, bvh2[n].first_index as usize + 1]);
            while let Some(m) = todo.pop() {
                if bvh2[m].prim_count > 0 || stays(m) {
                    count += 1;
                } else {
                    todo.extend([bvh2[m].first_index as usize, bvh2[m].first_index as usize + 1]);
                }
            }
            count
        };
        let nodes: Vec<usize> = std::iter::once(0).chain(inner.iter().copied().filter(|&n| stays(n))).collect();
        if nodes.iter().all(|&n| children(n) <= width) {
            best = best.min(nodes.iter().map(|&n| bvh2[n].aabb().half_area()).sum());
        }
    }
    best
}

#[test]
fn the_slot_plan_does_not_depend_on_the_visiting_order() {
    let mut rng = SplitMix64::new(5);
    let boxes: Vec<Aabb> = (0..5000)
        .map(|_| {
            let min = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 100.0;
            Aabb::new(min, min + Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()))
        })
        .collect();
    let binned = crate::geometry::binned_sah::build(boxes.len(), |i| boxes[i]).0.nodes;
    let ploc = build_bvh2(&boxes, BvhBuildParams::medium_build(), &mut Duration::default()).nodes;
    // The binned layout takes the sequential pass.
    assert!(children_after_parents(&binned));
    for bvh2 in [&binned, &ploc] {
        for width in [4, 8] {
            let (fast, reference) =
                (SlotPlan::new(bvh2, width), SlotPlan::filled(bvh2, width, breadth_first(bvh2).into_iter().rev()));
            assert_eq!(fast.left, reference.left, "width {width}");
            let bits = |p: &SlotPlan| p.cost.iter().flatten().map(|c| c.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&fast), bits(&reference), "width {width}");
        }
    }
}

#[test]
fn collapsing_keeps_the_inner_nodes_of_least_total_area() {
    let mut rng = SplitMix64::new(23);
    for round in 0..40 {
        let mut point = |scale: f32| Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * scale;
        let boxes: Vec<Aabb> = (0..10 + round % 5)
            .map(|_| {
                let min = point(10.0);
                Aabb::new(min, min + point(2.0))
            })
            .collect();
        let params = BvhBuildParams { max_prims_per_leaf: 1, ..BvhBuildParams::medium_build() };
        let bvh2 = build_bvh2(&boxes, params, &mut Duration::default()).nodes;
        let four = Bvh4::from_bvh2(&bvh2);
        let least = least_node_area(&bvh2, 4);
        assert!((node_area(&four) - least).abs() <= 1e-4 * least, "round {round}: {} vs {least}", node_area(&four));
        if let Some(eight) = Bvh8::from_bvh2(&bvh2) {
            let least = least_node_area(&bvh2, 8);
            assert!(
                (node_area(&eight) - least).abs() <= 1e-4 * least,
                "round {round}: {} vs {least}",
                node_area(&eight)
            );
        }
    }
}

#[test]
fn both_widths_visit_exactly_the_leaves_the_ray_enters() {
    let mut rng = SplitMix64::new(7);
    let mut point = |scale: f32| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * scale;
    let boxes: Vec<Aabb> = (0..3_000)
        .map(|_| {
            let min = point(20.0) - 10.0;
            Aabb::new(min.into(), (min + point(1.5)).into())
        })
        .collect();
    let bvh2 = build_bvh2(&boxes, BvhBuildParams::medium_build(), &mut Duration::default()).nodes;
    let four = Bvh4::from_bvh2(&bvh2);
    let eight = Bvh8::from_bvh2(&bvh2);
    if eight.is_none() {
        eprintln!("no eight-wide trees on this architecture: not built and not tested");
    }
    let mut rng = SplitMix64::new(8);
    let mut entered = 0;
    for i in 0..2_000 {
        let origin = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 24.0 - 12.0;
        let mut dir = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        // Every fourth ray runs parallel to one or two axes.
        if i % 4 == 0 {
            dir[i % 3] = 0.0;
            dir[(i / 4) % 3] = 0.0;
        }
        let tmax = if i % 2 == 0 { f32::INFINITY } else { rng.next_f32() * 20.0 };
        let ray = Ray::new(origin, dir.normalize_or(Vec3A::X), tmax);
        let expected = brute_force(&bvh2, &ray);
        entered += expected.len();
        assert_eq!(visited(&four, Plain, &ray), (expected.clone(), expected.clone()), "4-wide, ray {i}");
        if let Some(eight) = &eight {
            each_eight_test(|visit| {
                assert_eq!(visit(eight, &ray), (expected.clone(), expected.clone()), "8-wide, ray {i}")
            });
        }
    }
    assert!(entered > 4_000, "rays should enter many leaves ({entered})");
}

/// A rounded distance (a placed instance's, [`LaneHits::offer_inexact`]) within rounding of a
/// lane's closest hit ties the lane, whichever of the two came first; a hit clearly closer wins
/// outright and clears the tie.
#[cfg(target_arch = "x86_64")]
#[test]
fn rounded_distances_tie_only_within_rounding() {
    use packet::LaneHits;
    let rays = [Ray::new(Vec3A::ZERO, Vec3A::X, f32::INFINITY); 3];
    let below = |t: f32| f32::from_bits(t.to_bits() - 2);
    let mut hits = LaneHits::new(&rays);
    // Lane 0: an exact hit, then a rounded one two ulps nearer: tied (though nearer).
    hits.offer(0, 10.0, 1u32);
    hits.offer_inexact(0, below(10.0), 2);
    // Lane 1: a rounded hit, then an exact one two ulps nearer: tied.
    hits.offer_inexact(1, 10.0, 3);
    hits.offer(1, below(10.0), 4);
    // Lane 2: the same, the exact hit a whole unit nearer: not tied, the nearer kept.
    hits.offer_inexact(2, 10.0, 5);
    hits.offer(2, 9.0, 6);
    assert_eq!(hits.tied, 0b011);
    assert_eq!((hits.best[1], hits.best[2], hits.tmax[2]), (Some(4), Some(6), 9.0));
    // A clearly nearer hit settles lane 0.
    hits.offer(0, 5.0, 7);
    assert_eq!((hits.tied, hits.best[0]), (0b010, Some(7)));
}

#[test]
fn the_sah_cost_weighs_each_box_by_its_area_over_the_root_box() {
    // Two leaves side by side (half areas 3 and 3) under a root of half area 7, with 4 and 8
    // primitives: one test and two.
    let bvh2 = vec![
        Bvh2Node::new(Aabb::new(Vec3A::ZERO, Vec3A::new(3.0, 1.0, 1.0)), 0, 1),
        Bvh2Node::new(Aabb::new(Vec3A::ZERO, Vec3A::ONE), 4, 0),
        Bvh2Node::new(Aabb::new(Vec3A::new(2.0, 0.0, 0.0), Vec3A::new(3.0, 1.0, 1.0)), 8, 4),
    ];
    let packets = |count: u32| f64::from(count.div_ceil(4));
    let cost = Bvh4::from_bvh2(&bvh2).sah_cost(packets).expect("a root with area");
    assert_eq!(cost.inner, 1.0);
    assert!((cost.leaves - 9.0 / 7.0).abs() < 1e-12, "{cost:?}");
    assert!(Bvh4::default().sah_cost(packets).is_none());

    // A deep tree at either width: its nodes' boxes, and the binary tree's leaves (each of
    // which stays a leaf), over the root's box.
    let (bvh2, eight) = packet_test_scene(0.0, 1.0);
    let root = f64::from(bvh2[0].aabb().half_area());
    let leaves: f64 =
        bvh2.iter().filter(|n| n.prim_count > 0).map(|n| f64::from(n.aabb().half_area() * n.prim_count as f32)).sum();
    let four = Bvh4::from_bvh2(&bvh2);
    let widths = [(four.sah_cost(f64::from), f64::from(node_area(&four)))];
    let widths = widths.into_iter().chain(eight.map(|t| (t.sah_cost(f64::from), f64::from(node_area(&t)))));
    for (cost, inner) in widths {
        let cost = cost.expect("a root with area");
        assert!((cost.inner - inner / root).abs() < 1e-5 * cost.inner, "{cost:?} against {}", inner / root);
        assert!((cost.leaves - leaves / root).abs() < 1e-5 * cost.leaves, "{cost:?} against {}", leaves / root);
        assert!(cost.inner > 1.0 && (cost.total() - cost.inner - cost.leaves).abs() < 1e-12);
    }
}
