//! Bounding volume hierarchy in flat caller-provided arrays.
//!
//! Layout: nodes are stored depth-first, so an interior node's first child is the next node
//! and the second child is at [`BvhNode::offset`]; a leaf's primitives are
//! `prim_order[offset .. offset + count]`. Traversal keeps a fixed [`MAX_DEPTH`]-entry stack and visits the
//! nearer child first. The build (binned SAH, [`build`]) writes straight into caller slices.
//! [`collapse`] turns the binary tree into a wide one ([`WideNode`], 4 or 8 lanes): fewer, vectorised
//! box tests, children visited nearest first, the same hits ([`closest`]).

mod build;
pub mod closest;
mod lanes;
mod packet;
mod traverse;
mod wide;

pub use build::{
    build, build_triangles, build_with, max_nodes, BvhError, MAX_DEPTH, MAX_LEAF_PRIMS, SAH_DEPTH,
};
pub use lanes::{BaselineBoxes, BoxLanes};
pub use packet::{lower_bound, PacketOverflow, PACKET_STACK};
pub use traverse::{Bvh, TRAVERSAL_STACK};
pub use wide::{
    align_leaves, aligned_order_len, collapse, gather_leaf_groups, max_wide_nodes, WideBvh,
    WideNode, MAX_MERGED_GROUPS, NODE_COST, SHORT_TRAVERSAL_STACK, WIDE_LEAF, WIDE_MAX_DEPTH,
    WIDE_TRAVERSAL_STACK, WIDTH,
};

use crate::geometry::{Aabb, TriangleGroup};
use glam::Vec3;

/// The BVH a scene is traced with: the binary tree as built (32-byte nodes, the layout a GPU
/// upload or a C host uses) or its wide collapse (4 or 8 lanes) (fewer, wider nodes: faster on CPUs).
/// Both visit every primitive a ray may hit, and the scene's closest-hit rule does not depend
/// on the visit order, so both give the same hits and the same images.
#[derive(Clone, Copy, Debug)]
pub enum SceneBvh<'a> {
    Binary(Bvh<'a>),
    Wide(WideBvh<'a>),
}

impl<'a> SceneBvh<'a> {
    /// Primitive indices in leaf order.
    #[inline]
    #[must_use]
    pub fn prim_order(&self) -> &'a [u32] {
        match self {
            Self::Binary(b) => b.prim_order,
            Self::Wide(w) => w.prim_order,
        }
    }

    /// The wide tree's [`WideBvh::leaf_groups`] (empty for the binary tree).
    #[inline]
    #[must_use]
    pub fn leaf_groups(&self) -> &'a [TriangleGroup] {
        match self {
            Self::Binary(_) => &[],
            Self::Wide(w) => w.leaf_groups,
        }
    }

    /// [`Bvh::traverse`] or [`WideBvh::traverse`].
    #[inline]
    pub fn traverse<const ANY_HIT: bool, F: FnMut(u32, u32, f32) -> Option<f32>>(
        &self,
        o: Vec3,
        d: Vec3,
        t_max: f32,
        hit: F,
    ) -> bool {
        match self {
            Self::Binary(b) => b.traverse::<ANY_HIT, F>(o, d, t_max, hit),
            Self::Wide(w) => w.traverse::<ANY_HIT, F>(o, d, t_max, hit),
        }
    }

    /// [`Bvh::traverse_leaves`] or [`WideBvh::traverse_leaves`].
    #[inline]
    pub fn traverse_leaves<const ANY_HIT: bool, F: FnMut(u32, u32, f32) -> Option<f32>>(
        &self,
        o: Vec3,
        d: Vec3,
        t_max: f32,
        leaf: F,
    ) -> bool {
        self.traverse_leaves_in::<ANY_HIT, _, F>(crate::simd::Baseline, o, d, t_max, leaf)
    }

    /// [`Self::traverse_leaves`] with the instruction set `isa` for the wide tree's box tests
    /// ([`WideBvh::traverse_leaves_in`]).
    #[inline(always)]
    pub fn traverse_leaves_in<
        const ANY_HIT: bool,
        I: crate::simd::Isa,
        F: FnMut(u32, u32, f32) -> Option<f32>,
    >(
        &self,
        isa: I,
        o: Vec3,
        d: Vec3,
        t_max: f32,
        leaf: F,
    ) -> bool {
        match self {
            Self::Binary(b) => b.traverse_leaves::<ANY_HIT, F>(o, d, t_max, leaf),
            Self::Wide(w) => w.traverse_leaves_in::<ANY_HIT, I, F>(isa, o, d, t_max, leaf),
        }
    }
}

/// A leaf callback (`traverse_leaves`) that calls `hit(slot, prim, t_max)` for each of the
/// leaf's primitives in slot order, shrinking `t_max` after each hit (or, with `ANY_HIT`,
/// stopping at the first).
#[inline]
fn each_primitive<'a, const ANY_HIT: bool, F: FnMut(u32, u32, f32) -> Option<f32> + 'a>(
    prim_order: &'a [u32],
    mut hit: F,
) -> impl FnMut(u32, u32, f32) -> Option<f32> + 'a {
    move |first, count, mut t_max| {
        let mut bound = None;
        for slot in first..first + count {
            if let Some(t) = hit(slot, prim_order[slot as usize], t_max) {
                if ANY_HIT {
                    return Some(t);
                }
                t_max = t_max.min(t);
                bound = Some(t_max);
            }
        }
        bound
    }
}

impl<'a> From<Bvh<'a>> for SceneBvh<'a> {
    fn from(b: Bvh<'a>) -> Self {
        Self::Binary(b)
    }
}

impl<'a> From<WideBvh<'a>> for SceneBvh<'a> {
    fn from(w: WideBvh<'a>) -> Self {
        Self::Wide(w)
    }
}

/// One 32-byte BVH node (`#[repr(C)]`, so hosts can upload it to a GPU as is).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BvhNode {
    pub min: [f32; 3],
    /// Leaf: first index into `prim_order`. Interior: index of the second child.
    pub offset: u32,
    pub max: [f32; 3],
    /// Number of primitives; 0 marks an interior node.
    pub count: u16,
    /// Split axis of an interior node (0, 1, 2); it orders the traversal.
    pub axis: u8,
    pub pad: u8,
}

const _: () = assert!(core::mem::size_of::<BvhNode>() == 32);

impl BvhNode {
    #[inline]
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        Aabb {
            min: Vec3::from_array(self.min),
            max: Vec3::from_array(self.max),
        }
    }

    #[inline]
    #[must_use]
    pub fn is_leaf(&self) -> bool {
        self.count > 0
    }
}
