//! The pinhole camera: viewing rays through the pixels.

use crate::geometry::Ray;
use crate::math::Normalized;
use crate::scene::Camera;
use glam::DVec3;

/// Precomputed camera frame for a given image size.
#[derive(Clone, Copy, Debug)]
pub struct CameraRig {
    eye: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    half_w: f64,
    half_h: f64,
    width: f64,
    height: f64,
}

impl CameraRig {
    /// Sets up the camera for a `width` x `height` image.
    pub fn new(c: &Camera, width: u32, height: u32) -> Self {
        let forward = (c.look_at - c.eye).normalized();
        let mut right = forward.cross(c.up).normalized();
        if right.length_squared() == 0.0 {
            right = forward.any_orthonormal_pair().0;
        }
        let up = right.cross(forward);
        let half_h = (c.fov_y_deg.to_radians() * 0.5).tan();
        let half_w = half_h * width as f64 / height as f64;
        CameraRig { eye: c.eye, forward, right, up, half_w, half_h, width: width as f64, height: height as f64 }
    }

    /// The ray through image position (x, y) in pixels, (0, 0) the top-left corner.
    pub fn ray(&self, x: f64, y: f64) -> Ray {
        let sx = (2.0 * x / self.width - 1.0) * self.half_w;
        let sy = (1.0 - 2.0 * y / self.height) * self.half_h;
        Ray::new(self.eye, (self.forward + self.right * sx + self.up * sy).normalized())
    }
}
