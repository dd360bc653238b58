//! Binned surface-area-heuristic build straight into caller slices, no allocation.

use super::BvhNode;
use crate::geometry::{Aabb, GROUP_WIDTH};
use glam::Vec3;

/// Leaves hold at most this many primitives unless the centroids cannot be separated: one
/// group of the lane-wise leaf test ([`GROUP_WIDTH`]: 8 in AVX builds, 4 elsewhere).
pub const MAX_LEAF_PRIMS: usize = GROUP_WIDTH;
/// Deepest level a node can have (the root is level 0); traversal stacks of this size never
/// overflow. Below [`SAH_DEPTH`] the build switches to object-median splits, which halve the
/// primitive count at every level, so up to 2³² primitives fit.
pub const MAX_DEPTH: usize = 96;
/// Levels built with the SAH before the build falls back to median splits.
pub const SAH_DEPTH: u32 = 48;
/// Bins per axis of the SAH's split search. 32 and 64 tried (2026-12-08, AMD EPYC Zen 3,
/// `bench/embree`'s trees after the collapse): with 64 the 1k-triangle sphere's rays took 4–8%
/// fewer instructions (cachegrind, camera and incoherent rays), the 10k sphere's 3–11% more;
/// its surface-area estimates moved both ways too, and the builds took 1.5–2 times as long.
const BINS: usize = 16;
/// Cost of visiting an interior node relative to one test of a group of primitives.
const TRAVERSAL_COST: f32 = 1.0;

/// The SAH's cost of testing `n` primitives: one lane-wise test per group of
/// [`GROUP_WIDTH`] (`SceneView`'s leaf test), so a full leaf costs what a leaf of one does.
/// Counting primitives instead made leaves of one or two triangles, half-empty groups, and 135
/// bytes per triangle (with groups of four).
#[inline]
fn test_cost(n: u32) -> f32 {
    n.div_ceil(GROUP_WIDTH as u32) as f32
}

/// Number of nodes the caller must provide for `prims` primitives (a binary tree with at most
/// one primitive per leaf has `2n − 1` nodes). Extra capacity is left untouched.
#[must_use]
pub const fn max_nodes(prims: usize) -> usize {
    if prims == 0 {
        1
    } else {
        2 * prims - 1
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BvhError {
    /// `nodes` is shorter than [`max_nodes`] of the primitive count.
    NodeCapacity { needed: usize, given: usize },
    /// `prim_order` and `bounds` differ in length.
    PrimOrderLength { needed: usize, given: usize },
    /// More primitives than a u32 index can address.
    TooManyPrims,
    /// The tree would be deeper than [`MAX_DEPTH`] with a leaf too large to stop there.
    TooDeep,
    /// A triangle refers to a vertex that does not exist ([`build_triangles`]).
    VertexIndex { triangle: usize, index: u32 },
    /// A binary tree given to [`super::collapse`] is not laid out as the build writes it.
    Malformed,
}

impl core::fmt::Display for BvhError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::NodeCapacity { needed, given } => {
                write!(f, "BVH needs {needed} nodes but {given} were provided")
            }
            Self::PrimOrderLength { needed, given } => {
                write!(
                    f,
                    "BVH needs {needed} primitive slots but {given} were provided"
                )
            }
            Self::TooManyPrims => write!(f, "too many primitives for 32-bit indices"),
            Self::TooDeep => write!(f, "BVH deeper than {MAX_DEPTH} levels"),
            Self::VertexIndex { triangle, index } => {
                write!(f, "triangle {triangle} refers to missing vertex {index}")
            }
            Self::Malformed => write!(f, "not a binary BVH as the build writes it"),
        }
    }
}

#[derive(Clone, Copy, Default)]
struct Bin {
    bounds: Aabb,
    count: u32,
}

#[derive(Clone, Copy, Default)]
struct Task {
    start: u32,
    end: u32,
    /// Node whose `offset` must point at this task's node (second children), or u32::MAX.
    parent: u32,
    /// Level of this task's node.
    depth: u32,
}

struct Split {
    axis: usize,
    bin: usize,
    cost: f32,
}

/// Builds a BVH over primitives with the given bounds. Writes `prim_order` (a permutation of
/// `0..bounds.len()`) and the first `n` entries of `nodes`, and returns `n`.
///
/// # Errors
/// When the slices are too short (see [`max_nodes`]) or there are more than `u32::MAX` prims.
pub fn build(
    bounds: &[Aabb],
    nodes: &mut [BvhNode],
    prim_order: &mut [u32],
) -> Result<usize, BvhError> {
    build_with(bounds.len(), |p| bounds[p as usize], nodes, prim_order)
}

/// Builds a BVH over the triangles `triangles` of `positions`, computing each triangle's bounds
/// when the build needs them, so no bounds array is needed (the C API and engines that keep no
/// scratch memory). The tree is the one [`build`] makes from `Aabb::from_points` of each
/// triangle, bit for bit.
///
/// # Errors
/// A triangle referring to a missing vertex, or as [`build`].
pub fn build_triangles(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    nodes: &mut [BvhNode],
    prim_order: &mut [u32],
) -> Result<usize, BvhError> {
    for (t, tri) in triangles.iter().enumerate() {
        if let Some(&index) = tri.iter().find(|&&v| v as usize >= positions.len()) {
            return Err(BvhError::VertexIndex { triangle: t, index });
        }
    }
    let bounds = |p: u32| {
        let [a, b, c] = triangles[p as usize];
        Aabb::from_points(
            positions[a as usize],
            positions[b as usize],
            positions[c as usize],
        )
    };
    build_with(triangles.len(), bounds, nodes, prim_order)
}

/// [`build`] over `n` primitives whose bounds `bounds(i)` returns (called several times per
/// primitive; it must return the same box every time).
///
/// # Errors
/// As [`build`].
pub fn build_with<B: Fn(u32) -> Aabb>(
    n: usize,
    bounds: B,
    nodes: &mut [BvhNode],
    prim_order: &mut [u32],
) -> Result<usize, BvhError> {
    let bounds = &bounds;
    if u32::try_from(n).is_err() {
        return Err(BvhError::TooManyPrims);
    }
    if nodes.len() < max_nodes(n) {
        return Err(BvhError::NodeCapacity {
            needed: max_nodes(n),
            given: nodes.len(),
        });
    }
    if prim_order.len() != n {
        return Err(BvhError::PrimOrderLength {
            needed: n,
            given: prim_order.len(),
        });
    }
    for (i, p) in prim_order.iter_mut().enumerate() {
        *p = i as u32;
    }
    if n == 0 {
        // An empty scene: one empty leaf-less node that no ray can hit.
        nodes[0] = BvhNode {
            min: [f32::INFINITY; 3],
            max: [f32::NEG_INFINITY; 3],
            ..BvhNode::default()
        };
        return Ok(1);
    }

    // Pending second children: at most one per level of the current path.
    let mut stack = [Task::default(); MAX_DEPTH];
    let mut sp = 1;
    stack[0] = Task {
        start: 0,
        end: n as u32,
        parent: u32::MAX,
        depth: 0,
    };
    let mut used = 0usize;
    while sp > 0 {
        sp -= 1;
        let mut task = stack[sp];
        // Descend the left spine of this subtree, pushing right halves.
        loop {
            let index = used;
            used += 1;
            if task.parent != u32::MAX {
                nodes[task.parent as usize].offset = index as u32;
            }
            let (start, end) = (task.start as usize, task.end as usize);
            let prims = &mut prim_order[start..end];
            let mut node_bounds = Aabb::EMPTY;
            let mut centroid_bounds = Aabb::EMPTY;
            for &p in prims.iter() {
                let b = bounds(p);
                node_bounds = node_bounds.union(b);
                centroid_bounds = centroid_bounds.grow(b.centroid());
            }
            let count = end - start;
            let make_leaf = |nodes: &mut [BvhNode]| {
                nodes[index] = BvhNode {
                    min: node_bounds.min.to_array(),
                    max: node_bounds.max.to_array(),
                    offset: start as u32,
                    count: count as u16,
                    axis: 0,
                    pad: 0,
                };
            };
            let mid = if task.depth as usize + 1 >= MAX_DEPTH {
                if count > usize::from(u16::MAX) {
                    return Err(BvhError::TooDeep);
                }
                None
            } else if task.depth >= SAH_DEPTH {
                (count > MAX_LEAF_PRIMS).then(|| median_split(bounds, prims, &centroid_bounds))
            } else {
                // Split where the SAH says it pays, or where the leaf would be too large.
                let split = if count > 1 {
                    choose_split(bounds, prims, &node_bounds, &centroid_bounds)
                } else {
                    None
                };
                split
                    .filter(|s| s.cost < test_cost(count as u32) || count > MAX_LEAF_PRIMS)
                    .and_then(|s| {
                        partition(bounds, prims, &centroid_bounds, s.axis, s.bin)
                            .map(|m| (s.axis, m))
                    })
                    // Centroids that binning cannot separate.
                    .or_else(|| {
                        (count > MAX_LEAF_PRIMS)
                            .then(|| median_split(bounds, prims, &centroid_bounds))
                    })
            };
            let Some((axis, mid)) = mid else {
                make_leaf(nodes);
                break;
            };
            nodes[index] = BvhNode {
                min: node_bounds.min.to_array(),
                max: node_bounds.max.to_array(),
                offset: 0,
                count: 0,
                axis: axis as u8,
                pad: 0,
            };
            let mid = (start + mid) as u32;
            stack[sp] = Task {
                start: mid,
                end: task.end,
                parent: index as u32,
                depth: task.depth + 1,
            };
            sp += 1;
            task = Task {
                start: task.start,
                end: mid,
                parent: u32::MAX,
                depth: task.depth + 1,
            };
        }
    }
    Ok(used)
}

#[inline]
fn bin_of(c: f32, lo: f32, extent: f32) -> usize {
    let b = ((c - lo) / extent * BINS as f32) as usize;
    b.min(BINS - 1)
}

/// Best binned-SAH split over all three axes, with the cost in units of group tests.
fn choose_split(
    bounds: &impl Fn(u32) -> Aabb,
    prims: &[u32],
    node_bounds: &Aabb,
    centroid_bounds: &Aabb,
) -> Option<Split> {
    let extent = centroid_bounds.extent();
    let area = node_bounds.surface_area();
    let mut best: Option<Split> = None;
    for axis in 0..3 {
        if extent[axis].is_nan() || extent[axis] <= 0.0 {
            continue;
        }
        let mut bins = [Bin::default(); BINS];
        for &p in prims {
            let b = bounds(p);
            let i = bin_of(b.centroid()[axis], centroid_bounds.min[axis], extent[axis]);
            bins[i].count += 1;
            bins[i].bounds = bins[i].bounds.union(b);
        }
        // Sweep from the right to get the suffix areas and counts.
        let mut right_area = [0.0f32; BINS];
        let mut right_count = [0u32; BINS];
        let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
        for i in (1..BINS).rev() {
            acc = acc.union(bins[i].bounds);
            cnt += bins[i].count;
            right_area[i] = acc.surface_area();
            right_count[i] = cnt;
        }
        let (mut acc, mut cnt) = (Aabb::EMPTY, 0);
        for i in 0..BINS - 1 {
            acc = acc.union(bins[i].bounds);
            cnt += bins[i].count;
            let (rc, ra) = (right_count[i + 1], right_area[i + 1]);
            if cnt == 0 || rc == 0 {
                continue;
            }
            let cost = TRAVERSAL_COST
                + (test_cost(cnt) * acc.surface_area() + test_cost(rc) * ra)
                    / area.max(f32::MIN_POSITIVE);
            if best.as_ref().is_none_or(|b| cost < b.cost) {
                best = Some(Split { axis, bin: i, cost });
            }
        }
    }
    best
}

/// Object-median split along the widest centroid axis: the first half of `prims` gets the
/// primitives with the smaller centroids. Always makes two non-empty halves.
fn median_split(
    bounds: &impl Fn(u32) -> Aabb,
    prims: &mut [u32],
    centroid_bounds: &Aabb,
) -> (usize, usize) {
    let axis = centroid_bounds.extent().max_position();
    let mid = prims.len() / 2;
    prims.select_nth_unstable_by(mid, |&a, &b| {
        let ca = bounds(a).centroid()[axis];
        let cb = bounds(b).centroid()[axis];
        ca.total_cmp(&cb)
    });
    (axis, mid)
}

/// Moves primitives whose centroid falls in bins `0..=bin` to the front; returns their count,
/// or `None` if one side would be empty.
fn partition(
    bounds: &impl Fn(u32) -> Aabb,
    prims: &mut [u32],
    centroid_bounds: &Aabb,
    axis: usize,
    bin: usize,
) -> Option<usize> {
    let (lo, extent) = (centroid_bounds.min[axis], centroid_bounds.extent()[axis]);
    let left = |p: u32| bin_of(bounds(p).centroid()[axis], lo, extent) <= bin;
    let mut i = 0;
    let mut j = prims.len();
    while i < j {
        if left(prims[i]) {
            i += 1;
        } else {
            j -= 1;
            prims.swap(i, j);
        }
    }
    (i > 0 && i < prims.len()).then_some(i)
}
