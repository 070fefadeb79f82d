//! The rendered frame (linear radiance) and its tone mapping to 8-bit sRGB.

use crate::math::Rgb;
use crate::scene::Exposure;

/// A linear-radiance image, row-major from the top-left pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// RGB radiance per pixel.
    pub pixels: Vec<[f32; 3]>,
}

impl Frame {
    /// A black frame.
    pub fn new(width: u32, height: u32) -> Self {
        Frame { width, height, pixels: vec![[0.0; 3]; width as usize * height as usize] }
    }

    /// Sets pixel (x, y).
    pub fn set(&mut self, x: u32, y: u32, v: Rgb) {
        if x < self.width && y < self.height {
            self.pixels[(y * self.width + x) as usize] = [v.0[0] as f32, v.0[1] as f32, v.0[2] as f32];
        }
    }

    /// Pixel (x, y).
    pub fn get(&self, x: u32, y: u32) -> [f32; 3] {
        self.pixels[(y * self.width + x) as usize]
    }

    /// The multiplier applied before tone mapping: fixed, or auto (99th percentile of
    /// luminance mapped to 0.8).
    pub fn exposure_scale(&self, exposure: Exposure) -> f64 {
        match exposure {
            Exposure::Fixed(s) => s,
            Exposure::Auto => {
                let mut lum: Vec<f64> = self
                    .pixels
                    .iter()
                    .map(|p| Rgb([p[0] as f64, p[1] as f64, p[2] as f64]).luminance())
                    .filter(|l| l.is_finite() && *l > 0.0)
                    .collect();
                if lum.is_empty() {
                    return 1.0;
                }
                let k = ((lum.len() - 1) as f64 * 0.99) as usize;
                let (_, p99, _) = lum.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
                0.8 / *p99
            }
        }
    }

    /// 8-bit sRGB pixels (RGB, row-major): `scale` times radiance, clamped, sRGB-encoded.
    pub fn to_srgb8(&self, scale: f64) -> Vec<u8> {
        self.pixels.iter().flat_map(|p| p.map(|c| encode_srgb(c as f64 * scale))).collect()
    }
}

/// sRGB transfer function of a linear value, clamped to [0, 1], to 8 bits.
pub fn encode_srgb(x: f64) -> u8 {
    let x = if x.is_finite() { x.clamp(0.0, 1.0) } else { 0.0 };
    let v = if x <= 0.003_130_8 { 12.92 * x } else { 1.055 * x.powf(1.0 / 2.4) - 0.055 };
    (v * 255.0 + 0.5).floor().clamp(0.0, 255.0) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_endpoints_and_midpoint() {
        assert_eq!(encode_srgb(0.0), 0);
        assert_eq!(encode_srgb(1.0), 255);
        assert_eq!(encode_srgb(2.0), 255);
        assert_eq!(encode_srgb(f64::NAN), 0);
        // Linear 0.214 is sRGB ~0.5.
        assert!((127..=128).contains(&encode_srgb(0.214)));
    }

    #[test]
    fn auto_exposure_maps_bright_pixels_near_white() {
        let mut f = Frame::new(10, 10);
        for y in 0..10 {
            for x in 0..10 {
                f.set(x, y, Rgb::splat((x + 10 * y) as f64));
            }
        }
        let s = f.exposure_scale(Exposure::Auto);
        assert!((s * 98.0 - 0.8).abs() < 1e-9);
    }
}
