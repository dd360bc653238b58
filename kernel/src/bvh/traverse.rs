//! Fixed-stack traversal shared by closest-hit and any-hit queries.

use super::BvhNode;
use glam::Vec3;

/// Capacity of the traversal stack: one entry per level below the root, and the build never
/// makes a tree deeper than [`super::MAX_DEPTH`], so the stack cannot overflow.
pub const TRAVERSAL_STACK: usize = super::MAX_DEPTH;

/// A built BVH borrowed from caller storage.
#[derive(Clone, Copy, Debug)]
pub struct Bvh<'a> {
    pub nodes: &'a [BvhNode],
    pub prim_order: &'a [u32],
}

impl Bvh<'_> {
    /// Visits the leaves that the ray `o + t·d`, `t < t_max`, may hit, nearest child first, and
    /// calls `hit(slot, prim, t_max)` for each primitive (`slot`: its index in `prim_order`).
    /// `hit` returns the distance of a hit closer than the `t_max` it was given. With
    /// `ANY_HIT`, traversal stops at the first hit (shadow rays); otherwise `t_max` shrinks to
    /// the closest hit so far. Returns whether anything was hit.
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
    /// (Always inlined, so that a caller compiled for AVX compiles `leaf` for AVX too.)
    #[inline(always)]
    pub fn traverse_leaves<const ANY_HIT: bool, F: FnMut(u32, u32, f32) -> Option<f32>>(
        &self,
        o: Vec3,
        d: Vec3,
        mut t_max: f32,
        mut leaf: F,
    ) -> bool {
        let inv_d = Vec3::ONE / d;
        let neg = [inv_d.x < 0.0, inv_d.y < 0.0, inv_d.z < 0.0];
        let mut stack = [0u32; TRAVERSAL_STACK];
        let mut sp = 0usize;
        let mut current = 0usize;
        let mut any = false;
        if self.nodes.is_empty() {
            return false;
        }
        loop {
            let node = &self.nodes[current];
            if node.bounds().hit(o, inv_d, neg, t_max) {
                if node.is_leaf() {
                    if let Some(t) = leaf(node.offset, u32::from(node.count), t_max) {
                        any = true;
                        if ANY_HIT {
                            return true;
                        }
                        // Never farther: a hit test may round a distance just past the
                        // `t_max` it was given, and a growing `t_max` would make the visit
                        // depend on when a box is tested.
                        t_max = t_max.min(t);
                    }
                } else {
                    // Near child first: the first child holds the lower half along `axis`.
                    let (near, far) = if neg[usize::from(node.axis)] {
                        (node.offset as usize, current + 1)
                    } else {
                        (current + 1, node.offset as usize)
                    };
                    stack[sp] = far as u32;
                    sp += 1;
                    current = near;
                    continue;
                }
            }
            if sp == 0 {
                break;
            }
            sp -= 1;
            current = stack[sp] as usize;
        }
        any
    }
}
