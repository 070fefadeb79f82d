//! The rendered frame (linear radiance) and its tone mapping to 8-bit sRGB.

use crate::color::Rgb;
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

    /// Pixels x..x + w of row y, when they are all inside the frame.
    pub fn row_mut(&mut self, x: u32, y: u32, w: u32) -> Option<&mut [[f32; 3]]> {
        if y >= self.height || x.checked_add(w)? > self.width {
            return None;
        }
        let start = (y * self.width + x) as usize;
        self.pixels.get_mut(start..start + w as usize)
    }

    /// Pixel (x, y).
    pub fn get(&self, x: u32, y: u32) -> [f32; 3] {
        self.pixels[(y * self.width + x) as usize]
    }

    /// The `w` x `h` pixels from (x, y), clipped to the frame, as a frame of their own
    /// (a crop window).
    pub fn crop(&self, x: u32, y: u32, w: u32, h: u32) -> Frame {
        let (x, y) = (x.min(self.width), y.min(self.height));
        let (w, h) = (w.min(self.width - x), h.min(self.height - y));
        let mut out = Frame::new(w, h);
        for row in 0..h {
            let start = ((y + row) * self.width + x) as usize;
            let dst = (row * w) as usize;
            out.pixels[dst..dst + w as usize].copy_from_slice(&self.pixels[start..start + w as usize]);
        }
        out
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

/// sRGB transfer function of a linear value, clamped to [0, 1], to 8 bits: exactly
/// [`encode_srgb_formula`], found by a binary search over the 255 linear values where the
/// 8-bit code steps up (a `powf` per channel cost a 400x400 image about 10 ms).
pub fn encode_srgb(x: f64) -> u8 {
    let x = if x.is_finite() { x.clamp(0.0, 1.0) } else { 0.0 };
    srgb_steps().partition_point(|&t| t <= x) as u8
}

/// The sRGB transfer function evaluated directly (what [`encode_srgb`] reproduces).
pub fn encode_srgb_formula(x: f64) -> u8 {
    let x = if x.is_finite() { x.clamp(0.0, 1.0) } else { 0.0 };
    let v = if x <= 0.003_130_8 { 12.92 * x } else { 1.055 * x.powf(1.0 / 2.4) - 0.055 };
    (v * 255.0 + 0.5).floor().clamp(0.0, 255.0) as u8
}

/// `steps[k]`: the least linear value in [0, 1] that the formula encodes as k + 1 or
/// more. Found by bisection over the bits of non-negative f64s (ordered as the values
/// are), so the table agrees with the formula at every f64, boundaries included.
fn srgb_steps() -> &'static [f64; 255] {
    static STEPS: std::sync::OnceLock<[f64; 255]> = std::sync::OnceLock::new();
    STEPS.get_or_init(|| {
        let mut steps = [0.0; 255];
        for (k, step) in steps.iter_mut().enumerate() {
            let (mut lo, mut hi) = (0u64, 1.0f64.to_bits());
            // Invariant: formula(lo) <= k < formula(hi).
            while hi - lo > 1 {
                let mid = lo + (hi - lo) / 2;
                if (encode_srgb_formula(f64::from_bits(mid)) as usize) > k {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            *step = f64::from_bits(hi);
        }
        steps
    })
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
    fn the_step_table_encodes_as_the_formula_does() {
        for &t in srgb_steps() {
            let below = f64::from_bits(t.to_bits() - 1);
            assert_eq!(encode_srgb(t), encode_srgb_formula(t));
            assert_eq!(encode_srgb(below), encode_srgb_formula(below));
        }
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..200_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let v = (x >> 11) as f64 / (1u64 << 53) as f64 * 1.2 - 0.1;
            assert_eq!(encode_srgb(v), encode_srgb_formula(v), "at {v}");
        }
        for v in [f64::NAN, f64::INFINITY, -f64::INFINITY, -0.0, 0.0, 1.0, 0.003_130_8, 1e-300] {
            assert_eq!(encode_srgb(v), encode_srgb_formula(v), "at {v}");
        }
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
