//! Wide BVH: the binary build collapsed so that one node holds the boxes of up to [`WIDTH`]
//! children (eight on x86-64, four elsewhere: [`super::lanes`]), tested
//! together by one SIMD slab test.
//!
//! Why: on small scenes such as the Cornell box a binary traversal spends most of its time on
//! one data-dependent branch per box. A wide node answers four or eight boxes with
//! straight-line vector code, and the tree has a quarter to an eighth as many nodes.
//!
//! Visiting order: the children a ray enters are taken nearest first (by the entry distance of
//! their boxes), each tested again against the shrinking `t_max` when it is taken from the
//! stack. The order decides only how much work a ray costs, not its hit: the scene's
//! closest-hit rule is a total order on hits ([`super::closest`]), so any traversal that tests
//! every triangle a ray may hit before its bound finds the same one, whatever the width.
//! (The first version replayed the binary tree's visiting order, per ray octant, to make the
//! same triangle tests in the same order; nearest first traces camera rays 1.4–1.5 times as
//! fast.)
//!
//! Tried and not kept: child boxes quantised to a byte per bound in a per-node frame (Embree's
//! compressed nodes; 128-byte nodes instead of 256, decoded exactly as `origin + q·step` with a
//! power-of-two step and rounded outwards, so hits stayed the same). The looser boxes cost
//! only 1.5% more leaf visits, and the walk took 37% fewer L1 misses (callgrind), but decoding
//! added 26% instructions to the traversal with SSE2, and with AVX-512 seven of eight ray sets
//! ran 2–14% slower (`bench/embree`, medians of 8 alternating runs, Intel Xeon, 2026-12-06),
//! the 1M-triangle sphere's camera rays by 14%. Embree's default BVH8 keeps float boxes too.
//!
//! Determinism: the slab test uses subtraction, multiplication, comparisons and `min`/`max`
//! that ignore a NaN slab ([`super::lanes`]), which every backend (AVX, SSE2, NEON, wasm SIMD,
//! scalar) computes identically to the scalar [`crate::geometry::Aabb::hit`].

use super::lanes::{BoxLanes, LANES};
use super::{BvhError, BvhNode, MAX_DEPTH};
use crate::geometry::{TriangleGroup, GROUP_WIDTH};
use crate::math::gamma;
use crate::prefetch::prefetch;
use crate::simd::{Baseline, Isa};
use glam::Vec3;

/// Children per node: the slab test's lanes ([`super::lanes`]), 8 on x86-64 (one AVX register
/// or two SSE ones), 4 elsewhere.
pub const WIDTH: usize = LANES;
/// Deepest wide level. Each wide level spans at least one binary level of a tree at most
/// [`MAX_DEPTH`] deep (the collapse opens the largest child first, so a small sibling may stay
/// one level down), so no tree from [`super::build`] is refused.
pub const WIDE_MAX_DEPTH: usize = MAX_DEPTH;
/// Traversal stack capacity: at most `WIDTH − 1` deferred children per level plus the
/// at most `WIDTH` entries of the node being expanded.
pub const WIDE_TRAVERSAL_STACK: usize = (WIDTH - 1) * WIDE_MAX_DEPTH + WIDTH;
/// The stack a ray's walk starts with. Safe Rust zeroes a stack before use, and zeroing the
/// full [`WIDE_TRAVERSAL_STACK`] for every ray was 3% of a render's instructions; few rays
/// ever defer this many children, and a walk that would is abandoned and made again with the
/// full stack (the second walk gives the hit, and the first one's calls change nothing: the
/// closest-hit order does not depend on which triangles were tested before). Trees of up to
/// `(SHORT_TRAVERSAL_STACK − WIDTH) / (WIDTH − 1)` nodes never need more: each node is expanded
/// once and leaves at most `WIDTH − 1` more entries than it took. Sixteen entries (128 bytes;
/// two nodes' worth with eight lanes) are few enough for the compiler to zero in registers
/// instead of calling `memset` (2.2% of the cubebox bake's profile with 64 entries; 3% fewer
/// instructions, though no wall-time change measurable on this latency-bound walk): 0.04% of
/// the walks on the 1M-triangle sphere of `bench/embree` outgrow it, none on the Cornell boxes
/// or the cubebox bake.
pub const SHORT_TRAVERSAL_STACK: usize = 16;
const _: () = assert!(SHORT_TRAVERSAL_STACK >= WIDTH);
/// Marks a leaf child in [`WideNode::child`]; the bits below it are the first index into the
/// primitive order.
pub const WIDE_LEAF: u32 = 1 << 31;
/// What visiting a wide node costs, in tests of one triangle group, when the collapse weighs a
/// small subtree as one leaf against the node it would otherwise become ([`collapse`]). Twice a
/// group test: a node is as many bytes as a group (256 against 288 with eight lanes) but its
/// visit also sorts and pushes the children entered. The tree shapes of `ember-bvh-embree`
/// (8 lanes, Intel Xeon with AVX-512, 2026-12-06) at 0 (no merging), 1.0, 1.5, 2.0 and 3.0:
/// lanes used per node 3.8, 4.5, 5.1, 6.0, 7.1 on the 1M-triangle sphere. At 2.0 its rays were
/// 10–32% faster than without merging and the Cornell box's 6–16% (medians of three
/// alternating runs); 3.0 was slower than 2.0 on both. Timed again pass by pass against 2.0
/// (`bench/embree/lockstep.py`, one pair of processes, 21 rounds, one thread), 1.5 and 3.0
/// measured 0.95–1.02 of its speed on the Cornell box and the 1k and 10k spheres, within what
/// two processes of one binary differ by (up to 8%).
pub const NODE_COST: f32 = 2.0;
/// Largest subtree, in triangle groups, that the collapse considers making one leaf.
pub const MAX_MERGED_GROUPS: usize = 8;

/// One wide node of 128 bytes (four lanes) or 256 (eight) (`#[repr(C)]`; structure of arrays,
/// so that each axis loads as one vector). Unused lanes hold empty boxes and empty leaves.
#[repr(C, align(64))]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WideNode {
    /// `lo[axis][lane]`: lower corners of the child boxes.
    pub lo: [[f32; WIDTH]; 3],
    /// `hi[axis][lane]`: upper corners of the child boxes.
    pub hi: [[f32; WIDTH]; 3],
    /// Interior child: index of its wide node. Leaf child: [`WIDE_LEAF`] | first index into
    /// the primitive order.
    pub child: [u32; WIDTH],
    /// Number of primitives of a leaf child (0 for interior children and unused lanes).
    pub count: [u16; WIDTH],
    /// Zero: the padding to 32 bytes a lane made a field, so that every byte of a node is
    /// defined (the C API's acceleration structure is a function of its input, byte for byte).
    pub pad: [u16; WIDTH],
}

const _: () = assert!(core::mem::size_of::<WideNode>() == 32 * WIDTH);

impl Default for WideNode {
    fn default() -> Self {
        Self {
            lo: [[f32::INFINITY; WIDTH]; 3],
            hi: [[f32::NEG_INFINITY; WIDTH]; 3],
            child: [WIDE_LEAF; WIDTH],
            count: [0; WIDTH],
            pad: [0; WIDTH],
        }
    }
}

impl WideNode {
    /// Whether `lane` holds a leaf (or is unused).
    #[inline]
    #[must_use]
    pub fn is_leaf(&self, lane: usize) -> bool {
        self.child[lane] & WIDE_LEAF != 0
    }
}

/// Wide nodes the caller must provide for a binary tree of `binary_nodes` nodes: every wide
/// node except a root over a single leaf stands for at least one binary interior node.
#[must_use]
pub const fn max_wide_nodes(binary_nodes: usize) -> usize {
    if binary_nodes < 3 {
        1
    } else {
        binary_nodes / 2
    }
}

/// Collapses the binary tree `binary` (as written by [`super::build`]) into `wide`, keeping
/// its primitive order; returns the number of wide nodes written (breadth-first, root first,
/// so every child comes after its parent).
///
/// A wide node opens the binary children of largest surface area until its lanes are full;
/// each interior child then left is a wide node of its own or, if small, one leaf: a subtree of at
/// most [`MAX_MERGED_GROUPS`] groups whose surface-area cost as a leaf, `groups · A`, is at
/// most that of a node over its leaves, `NODE_COST · A + Σ groups(leaf) · A(leaf)` ([`NODE_COST`];
/// a lower bound when the subtree has more leaves than a node has lanes). The binary build
/// stops at one group per leaf, so without this the nodes above the leaves held two or three
/// of them: 3.8 of 8 lanes used on average on the 1M-triangle sphere, 4.0 on the Cornell box.
///
/// # Errors
/// [`BvhError::NodeCapacity`] if `wide` is shorter than [`max_wide_nodes`];
/// [`BvhError::TooManyPrims`] if a leaf starts at or beyond [`WIDE_LEAF`];
/// [`BvhError::TooDeep`] if the wide tree would be deeper than [`WIDE_MAX_DEPTH`] (never for a
/// tree from [`super::build`]);
/// [`BvhError::Malformed`] if `binary` is not a tree as the build writes it.
pub fn collapse(binary: &[BvhNode], wide: &mut [WideNode]) -> Result<usize, BvhError> {
    let needed = max_wide_nodes(binary.len());
    if wide.len() < needed {
        return Err(BvhError::NodeCapacity {
            needed,
            given: wide.len(),
        });
    }
    wide[0] = WideNode::default();
    let Some(root) = binary.first() else {
        return Ok(1);
    };
    if root.is_leaf() || binary.len() == 1 {
        // A single leaf, or the box-less node of an empty scene (no lanes).
        if root.is_leaf() {
            wide[0] = WideNode::default();
            set_lane(&mut wide[0], 0, root, leaf_reference(root)?);
        }
        return Ok(1);
    }
    if let Some(leaf) = as_leaf(binary, 0)? {
        // A scene small enough to be one leaf.
        set_lane(&mut wide[0], 0, &leaf, leaf_reference(&leaf)?);
        return Ok(1);
    }
    let children = |b: u32| -> Result<[u32; 2], BvhError> {
        let node = binary.get(b as usize).ok_or(BvhError::Malformed)?;
        let kids = [b + 1, node.offset];
        // Pre-order layout: both children come after their parent and exist.
        if kids.iter().any(|&k| k <= b || k as usize >= binary.len()) {
            return Err(BvhError::Malformed);
        }
        Ok(kids)
    };
    // The output doubles as the work queue: a wide node waiting to be filled holds the index
    // of its binary source in `child[0]` and its depth in `child[1]`.
    wide[0].child[0] = 0;
    wide[0].child[1] = 1;
    let mut used = 1usize;
    let mut next = 0usize;
    while next < used {
        let [source, depth, ..] = wide[next].child;
        // Open the interior child of largest surface area (the likeliest to be entered) until
        // there are `WIDTH` children or only binary leaves. (Opening first the children too
        // costly as one leaf, and the others only into lanes left free, made the Cornell box's
        // leaves larger and 3.5 instead of 2.1 group tests per ray through its box.)
        let mut lanes = [0u32; WIDTH];
        lanes[..2].copy_from_slice(&children(source)?);
        let mut n = 2;
        while n < WIDTH {
            let mut open = None;
            let mut largest = f32::NEG_INFINITY;
            for (l, &b) in lanes[..n].iter().enumerate() {
                let node = &binary[b as usize];
                let area = node.bounds().surface_area();
                if !node.is_leaf() && (open.is_none() || area > largest) {
                    (open, largest) = (Some(l), area);
                }
            }
            let Some(open) = open else {
                break;
            };
            let parent = lanes[open];
            lanes.copy_within(open + 1..n, open);
            lanes[n - 1..n + 1].copy_from_slice(&children(parent)?);
            n += 1;
        }
        // Then each interior child is one leaf or a wide node of its own.
        let mut filled = WideNode::default();
        for (lane, &b) in lanes[..n].iter().enumerate() {
            let child = &binary[b as usize];
            if let Some(leaf) = as_leaf(binary, b)? {
                set_lane(&mut filled, lane, &leaf, leaf_reference(&leaf)?);
                continue;
            }
            if used == wide.len() {
                return Err(BvhError::Malformed);
            }
            // The traversal stack holds `WIDTH − 1` entries per level of this depth.
            if depth as usize >= WIDE_MAX_DEPTH {
                return Err(BvhError::TooDeep);
            }
            wide[used] = WideNode::default();
            wide[used].child[0] = b;
            wide[used].child[1] = depth + 1;
            set_lane(&mut filled, lane, child, used as u32);
            used += 1;
        }
        wide[next] = filled;
        next += 1;
    }
    Ok(used)
}

/// The binary node `b` as one wide leaf: itself if it is a leaf, a leaf over its whole
/// subtree if the surface-area cost says so ([`collapse`]), or `None`.
fn as_leaf(binary: &[BvhNode], b: u32) -> Result<Option<BvhNode>, BvhError> {
    let get = |i: u32| binary.get(i as usize).ok_or(BvhError::Malformed);
    let node = get(b)?;
    if node.is_leaf() {
        return Ok(Some(*node));
    }
    // Pre-order: the subtree is `binary[b..=last]`, its leftmost leaf first and its rightmost
    // last, and its primitives are adjacent in the order (the build partitions in place).
    let mut first = b;
    while !get(first)?.is_leaf() {
        first += 1;
    }
    let mut last = b;
    while !get(last)?.is_leaf() {
        let next = get(last)?.offset;
        if next <= last {
            return Err(BvhError::Malformed);
        }
        last = next;
    }
    let (start, end) = (get(first)?.offset, get(last)?.offset);
    let Some(count) = (end + u32::from(get(last)?.count)).checked_sub(start) else {
        return Err(BvhError::Malformed);
    };
    let groups = (count as usize).div_ceil(GROUP_WIDTH);
    if groups > MAX_MERGED_GROUPS {
        return Ok(None);
    }
    let area = node.bounds().surface_area();
    let mut as_node = NODE_COST * area;
    for n in &binary[b as usize..=last as usize] {
        if n.is_leaf() {
            as_node +=
                usize::from(n.count).div_ceil(GROUP_WIDTH) as f32 * n.bounds().surface_area();
        }
    }
    Ok((groups as f32 * area <= as_node).then_some(BvhNode {
        offset: start,
        count: count as u16,
        ..*node
    }))
}

fn leaf_reference(leaf: &BvhNode) -> Result<u32, BvhError> {
    if leaf.offset & WIDE_LEAF != 0 {
        return Err(BvhError::TooManyPrims);
    }
    Ok(WIDE_LEAF | leaf.offset)
}

fn set_lane(node: &mut WideNode, lane: usize, child: &BvhNode, target: u32) {
    for axis in 0..3 {
        node.lo[axis][lane] = child.min[axis];
        node.hi[axis][lane] = child.max[axis];
    }
    node.child[lane] = target;
    node.count[lane] = child.count;
}

/// Length of the primitive order [`align_leaves`] writes for `nodes`: each leaf's primitives
/// rounded up to whole groups of [`GROUP_WIDTH`].
#[must_use]
pub fn aligned_order_len(nodes: &[WideNode]) -> usize {
    nodes
        .iter()
        .flat_map(|n| (0..WIDTH).filter(|&l| n.is_leaf(l)).map(|l| n.count[l]))
        .map(|c| usize::from(c).div_ceil(GROUP_WIDTH) * GROUP_WIDTH)
        .sum()
}

/// Lays the leaves of `nodes` out in `aligned` so that each starts at a multiple of
/// [`GROUP_WIDTH`] (its primitives from `prim_order`, then copies of its last one up to the
/// next multiple), and points the leaves there; returns the length written
/// ([`aligned_order_len`]). Leaves come in node order, so the leaves of one node are adjacent.
///
/// Why: a leaf then occupies whole [`TriangleGroup`]s ([`gather_leaf_groups`]), and its
/// triangles are tested by one lane-wise test per four instead of one per group it straddles.
///
/// # Errors
/// [`BvhError::NodeCapacity`] if `aligned` is shorter than [`aligned_order_len`];
/// [`BvhError::Malformed`] if a leaf names primitives beyond `prim_order`;
/// [`BvhError::TooManyPrims`] if the aligned order reaches [`WIDE_LEAF`].
pub fn align_leaves(
    nodes: &mut [WideNode],
    prim_order: &[u32],
    aligned: &mut [u32],
) -> Result<usize, BvhError> {
    let needed = aligned_order_len(nodes);
    if aligned.len() < needed {
        return Err(BvhError::NodeCapacity {
            needed,
            given: aligned.len(),
        });
    }
    if needed >= WIDE_LEAF as usize {
        return Err(BvhError::TooManyPrims);
    }
    let mut next = 0usize;
    for node in nodes.iter_mut() {
        for lane in 0..WIDTH {
            let count = usize::from(node.count[lane]);
            if !node.is_leaf(lane) || count == 0 {
                continue;
            }
            let first = (node.child[lane] & !WIDE_LEAF) as usize;
            let prims = prim_order
                .get(first..first + count)
                .ok_or(BvhError::Malformed)?;
            let padded = count.div_ceil(GROUP_WIDTH) * GROUP_WIDTH;
            let out = &mut aligned[next..next + padded];
            out[..count].copy_from_slice(prims);
            out[count..].fill(prims[count - 1]);
            node.child[lane] = WIDE_LEAF | next as u32;
            next += padded;
        }
    }
    Ok(next)
}

/// Writes the vertices of the triangles `prim_order[4g .. 4g + 4]` to `out[g]` (the
/// [`WideBvh::leaf_groups`] of a tree over `triangles`); lanes past the end of `prim_order`
/// repeat its last triangle.
///
/// # Errors
/// [`BvhError::NodeCapacity`] if `out` does not hold `prim_order.len()` lanes rounded up to
/// whole groups; [`BvhError::Malformed`] if `prim_order` names a triangle `triangles` lacks or a
/// triangle a vertex `positions` lacks.
pub fn gather_leaf_groups(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    prim_order: &[u32],
    out: &mut [TriangleGroup],
) -> Result<(), BvhError> {
    let needed = prim_order.len().div_ceil(GROUP_WIDTH);
    if out.len() != needed {
        return Err(BvhError::NodeCapacity {
            needed,
            given: out.len(),
        });
    }
    let vertices = |prim: u32| -> Result<[Vec3; 3], BvhError> {
        let tri = triangles.get(prim as usize).ok_or(BvhError::Malformed)?;
        let mut v = [Vec3::ZERO; 3];
        for (v, &i) in v.iter_mut().zip(tri) {
            *v = *positions.get(i as usize).ok_or(BvhError::Malformed)?;
        }
        Ok(v)
    };
    for (group, prims) in out.iter_mut().zip(prim_order.chunks(GROUP_WIDTH)) {
        let last = prims[prims.len() - 1];
        for lane in 0..GROUP_WIDTH {
            group.set(lane, vertices(*prims.get(lane).unwrap_or(&last))?);
        }
    }
    Ok(())
}

/// A collapsed wide BVH borrowed from caller storage.
#[derive(Clone, Copy, Debug)]
pub struct WideBvh<'a> {
    pub nodes: &'a [WideNode],
    pub prim_order: &'a [u32],
    /// The triangles of `prim_order` in groups of [`GROUP_WIDTH`], structure of arrays
    /// (`leaf_groups[g]` holds those of slots `w·g .. w·g + w`, [`gather_leaf_groups`]), tested
    /// by one lane-wise test each; or empty, and the scene tests triangle by triangle through
    /// its index buffer. With leaves aligned to groups ([`align_leaves`]), a leaf is whole groups.
    pub leaf_groups: &'a [TriangleGroup],
}

impl WideBvh<'_> {
    /// As [`super::Bvh::traverse`], nearest child first: visits the leaves that the ray
    /// `o + t·d`, `t < t_max`, may hit and calls `hit(slot, prim, t_max)` for each primitive
    /// (`slot`: its index in `prim_order` and [`Self::leaf_groups`]' lanes); `hit`
    /// returns the distance of a hit closer than the `t_max` it was given. With `ANY_HIT`,
    /// traversal stops at the first hit (shadow rays); otherwise `t_max` shrinks to the
    /// closest hit so far. Returns whether anything was hit.
    ///
    /// A walk that outgrows [`SHORT_TRAVERSAL_STACK`] is made again from the root with the full
    /// stack, so `hit` may be offered a primitive twice, the second time with a larger `t_max`:
    /// a closest-hit callback must keep the closest hit itself (by the closest-hit order, as
    /// `SceneView::intersect` does) rather than take every hit it is offered.
    #[inline]
    pub fn traverse<const ANY_HIT: bool, F: FnMut(u32, u32, f32) -> Option<f32>>(
        &self,
        o: Vec3,
        d: Vec3,
        t_max: f32,
        hit: F,
    ) -> bool {
        let order = self.prim_order;
        self.traverse_leaves::<ANY_HIT, _>(
            o,
            d,
            t_max,
            super::each_primitive::<ANY_HIT, F>(order, hit),
        )
    }

    /// [`Self::traverse`] a leaf at a time: `leaf(first, count, t_max)` is called for the
    /// leaves with primitives `prim_order[first .. first + count]` and returns the bound after
    /// its hits closer than `t_max` (or, with `ANY_HIT`, the distance of one), if any.
    #[inline]
    pub fn traverse_leaves<const ANY_HIT: bool, F: FnMut(u32, u32, f32) -> Option<f32>>(
        &self,
        o: Vec3,
        d: Vec3,
        t_max: f32,
        leaf: F,
    ) -> bool {
        self.traverse_leaves_in::<ANY_HIT, _, F>(Baseline, o, d, t_max, leaf)
    }

    /// [`Self::traverse_leaves`] with the box lanes of the instruction set `isa`
    /// ([`crate::simd`]): the same leaves in the same order.
    #[inline(always)]
    pub fn traverse_leaves_in<
        const ANY_HIT: bool,
        I: Isa,
        F: FnMut(u32, u32, f32) -> Option<f32>,
    >(
        &self,
        isa: I,
        o: Vec3,
        d: Vec3,
        t_max: f32,
        mut leaf: F,
    ) -> bool {
        let slab = Slab::<I::Boxes>::new(isa, o, d);
        match self
            .traverse_with::<ANY_HIT, _, _, SHORT_TRAVERSAL_STACK>(isa, &slab, t_max, &mut leaf)
        {
            Ok(any) => any,
            // (An abandoned any-hit walk has found nothing: it would have stopped.)
            Err(any) => {
                let again = self.traverse_with::<ANY_HIT, _, _, WIDE_TRAVERSAL_STACK>(
                    isa, &slab, t_max, &mut leaf,
                );
                any | again.unwrap_or_else(|any| any)
            }
        }
    }

    /// [`Self::traverse`] with a stack of `STACK` entries: `Ok(anything hit)`, or
    /// `Err(anything hit so far)` if the walk needed more room and was abandoned (never with
    /// [`WIDE_TRAVERSAL_STACK`]).
    #[inline(always)]
    fn traverse_with<
        const ANY_HIT: bool,
        I: Isa,
        F: FnMut(u32, u32, f32) -> Option<f32>,
        const STACK: usize,
    >(
        &self,
        isa: I,
        slab: &Slab<I::Boxes>,
        mut t_max: f32,
        // By reference, not as `&mut F: FnMut`, whose call shim would not be inlined, and
        // with AVX the leaf test must be (`crate::simd::Avx::run`).
        leaf: &mut F,
    ) -> Result<bool, bool> {
        if self.nodes.is_empty() {
            return Ok(false);
        }
        // Children still to visit, the next one on top: (node index, or WIDE_LEAF | parent
        // index · WIDTH + lane for a leaf; entry distance of the box).
        let mut stack = [(0u32, 0f32); STACK];
        let mut sp = 0usize;
        let mut any = false;
        let mut index = 0usize;
        loop {
            let node = &self.nodes[index];
            let (t0, bits) = slab.hit(isa, node, t_max);
            // One interior child entered (the common case deep in the tree): go down to it
            // without the stack.
            if bits != 0 && bits & (bits - 1) == 0 {
                let lane = bits.trailing_zeros() as usize % WIDTH;
                if !node.is_leaf(lane) {
                    index = node.child[lane] as usize;
                    continue;
                }
            }
            // Push the children the ray enters, farthest first, so that the nearest is taken
            // next (insertion by entry distance; the closest hit does not depend on the order,
            // `bvh::closest`, only the work does). Tried and dropped (2026-12-06): keys of
            // distance bits and lane sorted by a branch-free 19-comparator network and all
            // `WIDTH` entries written at once. cachegrind's branch simulation on `bench/embree`'s
            // 1k-triangle sphere gave 22% fewer mispredictions but 16% more instructions (the
            // scalar network, key packing and gather are ~170 per push), and it measured slower,
            // not faster, in alternating runs. Also dropped: keys of the distance bits and
            // reference, inserted by a fixed pass of integer compare-and-selects over the
            // entries already pushed (no branch on the distances): in lockstep
            // (`bench/embree/lockstep.py`, 6 epochs of 4 rounds) 0.90 (0.87–0.98) of this
            // insertion's speed on the 1k sphere's camera rays, level on the other ray sets and
            // on the Cornell box. Also dropped (2026-12-08, AMD EPYC Zen 3, AVX2): two entered
            // children, 2.4 per node on the 1k sphere's camera rays, put in order by a select
            // instead of this loop: 15% fewer mispredictions in cachegrind's model, but 0.95–1.01
            // of this loop's speed in lockstep (1M sphere's camera rays 0.95, the Cornell box's
            // 0.975–0.987). An AVX2 network (`vpmaxud`, `vpermd`; some 40 instructions) is
            // untried.
            let base = sp;
            // The lanes entered, lowest first: one iteration per entered box rather than a
            // branch per lane on the mask (that branch was the traversal's costliest
            // misprediction).
            let mut entered = bits;
            while entered != 0 {
                let lane = entered.trailing_zeros() as usize % WIDTH;
                entered &= entered - 1;
                // An any-hit query tests a leaf as soon as it enters its box: it may end the
                // walk there, and costs no stack traffic.
                if ANY_HIT && node.is_leaf(lane) {
                    let first = node.child[lane] & !WIDE_LEAF;
                    if leaf(first, u32::from(node.count[lane]), t_max).is_some() {
                        return Ok(true);
                    }
                    continue;
                }
                let entry_t = t0[lane];
                let reference = if node.is_leaf(lane) {
                    let first = (node.child[lane] & !WIDE_LEAF) as usize;
                    if let Some(g) = self.leaf_groups.get(first / GROUP_WIDTH) {
                        prefetch(g);
                    }
                    WIDE_LEAF | (index * WIDTH + lane) as u32
                } else {
                    if let Some(n) = self.nodes.get(node.child[lane] as usize) {
                        prefetch(n);
                    }
                    node.child[lane]
                };
                let entry = (reference, entry_t);
                // Room for it (a check the full stack does not need).
                if STACK < WIDE_TRAVERSAL_STACK && sp == STACK {
                    return Err(any);
                }
                let mut at = sp;
                // An any-hit query visits every box on the segment unless it stops, and
                // its bound never shrinks: the order buys nothing, so it is not sorted.
                while !ANY_HIT && at > base && stack[at - 1].1 < entry.1 {
                    stack[at] = stack[at - 1];
                    at -= 1;
                }
                stack[at] = entry;
                sp += 1;
            }
            // Take the next child whose box the ray still enters before the closest hit so
            // far (the bound may have shrunk since it was pushed); run the leaves.
            loop {
                if sp == 0 {
                    return Ok(any);
                }
                sp -= 1;
                let (reference, entry) = stack[sp];
                // (Never true for an any-hit query: its bound does not shrink.)
                if !ANY_HIT && entry >= t_max {
                    continue;
                }
                if reference & WIDE_LEAF == 0 {
                    index = reference as usize;
                    break;
                }
                let at = (reference & !WIDE_LEAF) as usize;
                let parent = &self.nodes[at / WIDTH];
                let lane = at % WIDTH;
                let first = parent.child[lane] & !WIDE_LEAF;
                if let Some(t) = leaf(first, u32::from(parent.count[lane]), t_max) {
                    any = true;
                    if ANY_HIT {
                        return Ok(true);
                    }
                    // Never farther: a hit test may round a distance just past the `t_max` it
                    // was given, and a growing `t_max` would make the visit depend on when a
                    // box is tested.
                    t_max = t_max.min(t);
                }
            }
        }
    }
}

/// Per-ray constants of the slab test, one lane per child box.
struct Slab<L> {
    o: [L; 3],
    inv_d: [L; 3],
    neg: [bool; 3],
}

impl<L: BoxLanes<WIDTH>> Slab<L> {
    #[inline(always)]
    fn new(isa: L::Isa, o: Vec3, d: Vec3) -> Self {
        let inv_d = Vec3::ONE / d;
        let neg = [inv_d.x < 0.0, inv_d.y < 0.0, inv_d.z < 0.0];
        // (Not `array::map`, which need not be inlined, and must be with AVX.)
        let splat = |v: Vec3| [L::splat(isa, v.x), L::splat(isa, v.y), L::splat(isa, v.z)];
        Self {
            o: splat(o),
            inv_d: splat(inv_d),
            neg,
        }
    }

    /// Entry distances and the bit mask of lanes whose box the ray enters within
    /// `[0, t_max)`, each decided as [`crate::geometry::Aabb::hit`] decides for one box
    /// (pbrt's conservative rounding of the exit distance; a NaN slab, 0·∞ for an origin on a
    /// slab plane with a zero direction component, does not constrain the ray).
    #[inline(always)]
    fn hit(&self, isa: L::Isa, node: &WideNode, t_max: f32) -> ([f32; WIDTH], u32) {
        let scale = L::splat(isa, 1.0 + 2.0 * gamma(3));
        let mut t0 = L::splat(isa, f32::NEG_INFINITY);
        let mut t1 = L::splat(isa, f32::INFINITY);
        for axis in 0..3 {
            // (Selecting the corners by index instead of this branch, which goes the same way
            // at every node a ray visits, measured level or slower in lockstep: 0.97–1.01.)
            let (near, far) = if self.neg[axis] {
                (&node.hi[axis], &node.lo[axis])
            } else {
                (&node.lo[axis], &node.hi[axis])
            };
            let tn = L::load(isa, near).sub(self.o[axis]).mul(self.inv_d[axis]);
            let tf = L::load(isa, far).sub(self.o[axis]).mul(self.inv_d[axis]);
            t0 = tn.max_ignoring_nan(t0);
            t1 = tf.min_ignoring_nan(t1);
        }
        // Scaling the smallest far distance is scaling each one and taking the smallest:
        // rounding is monotonic, so `min(a·s, b·s) = min(a, b)·s` for `s > 0`, NaN ignored
        // alike (`Aabb::hit` scales after its minimum too).
        (t0.to_array(), L::entered(isa, t0, t1.mul(scale), t_max))
    }
}
