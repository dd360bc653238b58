//! Bounding volume hierarchy in flat caller-provided arrays.
//!
//! Layout: nodes are stored depth-first, so an interior node's first child is the next node
//! and the second child is at [`BvhNode::offset`]; a leaf's primitives are
//! `prim_order[offset .. offset + count]`. Traversal keeps a fixed [`MAX_DEPTH`]-entry stack and visits the
//! nearer child first. The build (binned SAH, [`build`]) writes straight into caller slices.

mod build;
mod traverse;

pub use build::{
    build, build_triangles, build_with, max_nodes, BvhError, MAX_DEPTH, MAX_LEAF_PRIMS, SAH_DEPTH,
};
pub use traverse::{Bvh, TRAVERSAL_STACK};

use crate::geometry::Aabb;
use glam::Vec3;

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
