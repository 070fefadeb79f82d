//! Geometric primitives: rays, triangles (watertight intersection, exact solid angle),
//! boxes (exact triangle/box overlap) and sampling of directions.

mod aabb;
mod ray;
mod sampling;
mod triangle;

pub use aabb::{triangle_overlaps_box, Aabb};
pub use ray::Ray;
pub use sampling::{cosine_hemisphere, sample_spherical_triangle, SphericalTriangle};
pub use triangle::{intersect_watertight, solid_angle, triangle_area, triangle_normal, TriHit, WatertightRay};
