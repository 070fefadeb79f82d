//! A ray: origin and direction.

use crate::math::Vec3;

/// A half-line `origin + t * direction`, `t > 0`. The direction need not be unit length
/// for intersection, but the kernels keep it unit so that `t` is a distance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Start point.
    pub origin: Vec3,
    /// Direction.
    pub direction: Vec3,
}

impl Ray {
    /// Builds a ray.
    pub fn new(origin: Vec3, direction: Vec3) -> Self {
        Ray { origin, direction }
    }
    /// The point at parameter `t`.
    pub fn at(&self, t: f64) -> Vec3 {
        self.origin + self.direction * t
    }
}
