//! Counts of what the BVH queries do (node tests, leaf tests, triangle tests, rays that leave
//! their packet), for profiling: compiled in only with the cargo feature `counters`
//! (`cargo run --release --features counters -- render scene.json --stats`), as Embree's and
//! pbrt's statistics counters are. Each thread counts into cells of its own, with no atomic
//! operation or shared cache line; the trace system takes a tile's counts on the thread that
//! traced it. Without the feature the counting compiles to nothing and every count stays 0.

use serde::Serialize;

/// What the BVH queries did, summed over some rays: ray packets (all their rays at once) and
/// single rays (a ray traced alone, or gone on alone from its packet), at every level of the
/// scene's trees.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct TraversalCounts {
    /// Nodes tested against a packet's rays at once (all of a node's children).
    pub packet_node_tests: u64,
    /// Triangles tested against a packet's rays at once.
    pub packet_triangle_tests: u64,
    /// Rays that went on alone from a node fewer than a packet's threshold of rays entered.
    pub lone_rays: u64,
    /// Nodes tested against a single ray (all of a node's children).
    pub node_tests: u64,
    /// Leaves a single ray entered and tested.
    pub leaf_tests: u64,
    /// Packets of four triangles tested against a single ray.
    pub triangle_packet_tests: u64,
}

impl TraversalCounts {
    /// Whether this build counts (the cargo feature `counters`); without it every count is 0.
    pub const ENABLED: bool = cfg!(feature = "counters");

    /// Adds another set of counts to this one.
    pub fn add(&mut self, other: &TraversalCounts) {
        for (a, b) in self.cells_mut().into_iter().zip(other.cells()) {
            *a += b;
        }
    }

    fn cells(&self) -> [u64; EVENTS] {
        [
            self.packet_node_tests,
            self.packet_triangle_tests,
            self.lone_rays,
            self.node_tests,
            self.leaf_tests,
            self.triangle_packet_tests,
        ]
    }

    fn cells_mut(&mut self) -> [&mut u64; EVENTS] {
        [
            &mut self.packet_node_tests,
            &mut self.packet_triangle_tests,
            &mut self.lone_rays,
            &mut self.node_tests,
            &mut self.leaf_tests,
            &mut self.triangle_packet_tests,
        ]
    }
}

/// One kind of counted step, in [`TraversalCounts`]' field order.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Event {
    PacketNodeTest,
    PacketTriangleTest,
    LoneRay,
    NodeTest,
    LeafTest,
    TrianglePacketTest,
}

/// Number of [`Event`] kinds.
const EVENTS: usize = 6;

#[cfg(feature = "counters")]
thread_local! {
    static CELLS: [std::cell::Cell<u64>; EVENTS] = const { [const { std::cell::Cell::new(0) }; EVENTS] };
}

/// Counts one `event` on this thread (nothing without the feature `counters`).
#[inline(always)]
pub(crate) fn count(event: Event) {
    #[cfg(feature = "counters")]
    CELLS.with(|cells| {
        let cell = &cells[event as usize];
        cell.set(cell.get() + 1);
    });
    #[cfg(not(feature = "counters"))]
    let _ = event;
}

/// This thread's counts since the last call, which starts them again from 0.
pub fn take() -> TraversalCounts {
    #[cfg(feature = "counters")]
    {
        let mut counts = TraversalCounts::default();
        CELLS.with(|cells| {
            for (count, cell) in counts.cells_mut().into_iter().zip(cells) {
                *count = cell.take();
            }
        });
        counts
    }
    #[cfg(not(feature = "counters"))]
    TraversalCounts::default()
}

#[cfg(all(test, feature = "counters"))]
mod tests {
    use super::*;

    #[test]
    fn each_event_lands_in_its_own_field_and_take_resets() {
        take();
        let events = [
            Event::PacketNodeTest,
            Event::PacketTriangleTest,
            Event::LoneRay,
            Event::NodeTest,
            Event::LeafTest,
            Event::TrianglePacketTest,
        ];
        for (n, &event) in events.iter().enumerate() {
            for _ in 0..=n {
                count(event);
            }
        }
        let counts = take();
        assert_eq!(counts.cells(), [1, 2, 3, 4, 5, 6]);
        assert_eq!(take(), TraversalCounts::default());
        // Another thread's counts are its own.
        count(Event::NodeTest);
        std::thread::spawn(|| count(Event::NodeTest)).join().unwrap();
        assert_eq!(take().node_tests, 1);
    }
}
