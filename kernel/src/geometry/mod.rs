//! Rays, watertight triangle intersection, and ray origins offset by floating-point error bounds.

mod aabb;
mod ray;
mod ray_lanes;
mod triangle;
mod triangle_group;

pub use aabb::Aabb;
pub use ray::{offset_ray_origin, shadow_ray, spawn_connection, spawn_ray, spawn_ray_to, Ray};
pub use ray_lanes::{LaneHits, RayLanes, F8, M8, PACKET};
pub use triangle::{
    inset_barycentrics, intersect_triangle, triangle_point, triangle_point_error, TriangleHit,
    WatertightRay,
};
pub use triangle_group::{GroupHits, PairHits, TriangleGroup, TriangleHits, GROUP_WIDTH};
