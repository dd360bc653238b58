//! Packet traversal: the wide tree walked once for up to [`PACKET`] rays, one per lane
//! ([`RayLanes`]), each child box tested against all of them at once.
//!
//! Each lane decides whether it enters a box exactly as the one-ray walk decides it
//! (`Slab::hit` in [`super::wide`]: the same subtraction, multiplication, NaN-ignoring
//! `max`/`min` and rounding margin, per lane), and a leaf's triangles are tested for exactly
//! the lanes that entered its box. The packet visits the union of its rays' boxes in its own
//! order, and the closest-hit rule is a total order on hits ([`super::closest`]), so every lane
//! gets the hit its one-ray walk gets.
//!
//! A packet whose walk would need more than [`PACKET_STACK`] deferred children is abandoned
//! ([`Err`]): the caller traces its rays one at a time instead, which gives the same hits.

use super::closest;
use super::wide::{WideBvh, WIDE_LEAF, WIDTH};
use crate::geometry::{RayLanes, F8, PACKET};
use crate::math::gamma;
use core::ops::{Mul, Sub};

/// A packet walk outgrew [`PACKET_STACK`] and was abandoned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PacketOverflow;

/// Deferred children a packet walk holds at most before it is abandoned.
pub const PACKET_STACK: usize = 4 * WIDTH;

/// A deferred child: its node index (or [`WIDE_LEAF`] | first primitive), its primitive count
/// (leaves), the lanes that entered its box and their entry distances.
#[derive(Clone, Copy)]
struct Deferred {
    child: u32,
    count: u32,
    lanes: u32,
    entry: F8,
}

impl WideBvh<'_> {
    /// Walks the tree with the rays of `rays` whose bit is set in `live`, lane `i` bounded by
    /// `t_max[i]`, and calls `leaf(first, count, lanes, t_max)` for each leaf (primitives
    /// `prim_order[first .. first + count]`) with the lanes that enter its box. A closest-hit
    /// `leaf` lowers the bounds of the lanes it finds hits for; an any-hit one (`ANY_HIT`)
    /// returns the lanes it found a hit for, which take no further part. Returns the lanes
    /// found hit by an any-hit walk (0 for a closest-hit one), or `Err` if the walk outgrew
    /// [`PACKET_STACK`] (the bounds a closest-hit `leaf` set stay valid bounds).
    #[inline]
    pub fn traverse_packet<const ANY_HIT: bool, F: FnMut(u32, u32, u32, &mut F8) -> u32>(
        &self,
        rays: &RayLanes,
        t_max: &mut F8,
        live: u32,
        mut leaf: F,
    ) -> Result<u32, PacketOverflow> {
        let mut active = live & ((1 << PACKET) - 1);
        if self.nodes.is_empty() || active == 0 {
            return Ok(0);
        }
        let scale = F8::splat(1.0 + 2.0 * gamma(3));
        let zero = F8::splat(0.0);
        let mut found = 0u32;
        let mut stack = [Deferred {
            child: 0,
            count: 0,
            lanes: 0,
            entry: zero,
        }; PACKET_STACK];
        let mut sp = 0usize;
        let mut index = 0usize;
        // The lanes that entered the current node's box.
        let mut node_lanes = active;
        loop {
            if sp + WIDTH > PACKET_STACK {
                return Err(PacketOverflow);
            }
            let node = &self.nodes[index];
            let base = sp;
            for c in 0..WIDTH {
                let child = node.child[c];
                let count = u32::from(node.count[c]);
                if child & WIDE_LEAF != 0 && count == 0 {
                    continue;
                }
                let mut t0 = F8::splat(f32::NEG_INFINITY);
                let mut t1 = F8::splat(f32::INFINITY);
                for axis in 0..3 {
                    let lo = F8::splat(node.lo[axis][c]);
                    let hi = F8::splat(node.hi[axis][c]);
                    let near = F8::select(rays.neg[axis], hi, lo);
                    let far = F8::select(rays.neg[axis], lo, hi);
                    let tn = near.sub(rays.o[axis]).mul(rays.inv_d[axis]);
                    let tf = far.sub(rays.o[axis]).mul(rays.inv_d[axis]);
                    t0 = tn.max_or(t0);
                    t1 = tf.min_or(t1);
                }
                let t1 = t1.mul(scale);
                let lanes =
                    t0.le(t1).and(t0.lt(*t_max)).and(t1.gt(zero)).bits() & node_lanes & active;
                if lanes == 0 {
                    continue;
                }
                if ANY_HIT && child & WIDE_LEAF != 0 {
                    let hit = leaf(child & !WIDE_LEAF, count, lanes, t_max) & lanes;
                    found |= hit;
                    active &= !hit;
                    if active == 0 {
                        return Ok(found);
                    }
                    continue;
                }
                let entry = Deferred {
                    child,
                    count,
                    lanes,
                    entry: t0,
                };
                // Nearest first by the nearest entry among the lanes (any-hit walks: in node
                // order, their bounds never shrink).
                let key = nearest(&t0, lanes);
                let mut at = sp;
                while !ANY_HIT
                    && at > base
                    && nearest(&stack[at - 1].entry, stack[at - 1].lanes) < key
                {
                    stack[at] = stack[at - 1];
                    at -= 1;
                }
                stack[at] = entry;
                sp += 1;
            }
            // The next deferred child some lane still enters before its bound.
            loop {
                if sp == 0 {
                    return Ok(found);
                }
                sp -= 1;
                let d = stack[sp];
                let lanes = d.lanes & active & d.entry.lt(*t_max).bits();
                if lanes == 0 {
                    continue;
                }
                if d.child & WIDE_LEAF == 0 {
                    index = d.child as usize;
                    node_lanes = lanes;
                    break;
                }
                let hit = leaf(d.child & !WIDE_LEAF, d.count, lanes, t_max);
                if ANY_HIT {
                    found |= hit & lanes;
                    active &= !(hit & lanes);
                    if active == 0 {
                        return Ok(found);
                    }
                }
            }
        }
    }
}

/// The smallest entry distance among `lanes`.
#[inline(always)]
fn nearest(entry: &F8, lanes: u32) -> f32 {
    let mut m = f32::INFINITY;
    for i in 0..PACKET {
        if lanes >> i & 1 != 0 && entry.0[i] < m {
            m = entry.0[i];
        }
    }
    m
}

/// The bound after a lane's hit at `t` ([`closest::bound_after`]), lowering `t_max` only.
#[inline(always)]
pub fn lower_bound(t_max: &mut F8, lane: usize, t: f32) {
    t_max.0[lane] = t_max.0[lane].min(closest::bound_after(t));
}
