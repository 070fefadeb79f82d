//! A ray: origin and direction.

use glam::DVec3;

/// A half-line `origin + t * direction`, `t > 0`. The direction need not be unit length
/// for intersection, but the kernels keep it unit so that `t` is a distance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Start point.
    pub origin: DVec3,
    /// Direction.
    pub direction: DVec3,
}

impl Ray {
    /// Builds a ray.
    pub fn new(origin: DVec3, direction: DVec3) -> Self {
        Ray { origin, direction }
    }
    /// The point at parameter `t`.
    pub fn at(&self, t: f64) -> DVec3 {
        self.origin + self.direction * t
    }
}
