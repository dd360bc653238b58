//! The closest-hit order: a hit at distance `t` on triangle `i` comes before one at `(t', i')`
//! iff `t < t'`, or `t == t'` and `i < i'`. A total order on hits, so the closest hit of a ray
//! is the first of all its hits whatever order a traversal tests triangles in (two triangles
//! meeting the ray at one distance, at a shared edge or duplicated, no longer resolve to
//! whichever the tree reached first), which frees a tree to visit its children in any order.
//!
//! A traversal shrinks its bound to a hit's distance; to still test the triangles at exactly
//! that distance, [`bound_after`] keeps the bound a few ulps above it (boxes and triangles
//! are decided with rounding), and the hit callback accepts a hit only if it [`precedes`] the
//! best so far.

use crate::math::next_float_up;

/// Whether a hit at `(t, prim)` comes before `best` (`(t, prim)` of the best hit so far).
#[inline]
#[must_use]
pub fn precedes(t: f32, prim: u32, best: Option<(f32, u32)>) -> bool {
    match best {
        None => true,
        Some((bt, bp)) => t < bt || (t == bt && prim < bp),
    }
}

/// Relative margin of [`bound_after`] (4 ulps): a box's entry distance and a triangle's hit
/// distance are each rounded a few ulps, so a box holding a triangle hit at exactly `t` may
/// be entered at a distance that rounded just past `t`.
const MARGIN: f32 = 4.0 * f32::EPSILON;

/// The traversal bound (exclusive) after a hit at `t`: just above `t`, so that boxes entered
/// at `t` and triangles hit at `t` are still tested; anything farther than the margin is not.
#[inline]
#[must_use]
pub fn bound_after(t: f32) -> f32 {
    next_float_up(t).max(t + t.abs() * MARGIN)
}
