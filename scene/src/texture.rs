//! Diffuse textures (MTL `map_Kd`): decoded once when the scene is read, kept as sRGB
//! bytes (what the files hold; 682 texels fit a 2 KB block), decoded to linear
//! reflectance through a 256-entry table at every lookup.
//!
//! A texture multiplies the diffuse reflectance of the patches that carry it: at VRT per
//! hit (bilinear, wrapping), and in LRT where a light ray bounces diffusely off a textured
//! point, so light that bounces off a red texel leaves red.

use crate::color::Rgb;

/// Largest width or height of a texture: 16k texels, far past what a 2 KB-block scene
/// sensibly carries (a 16k x 16k texture is 768 MB of blocks).
pub const MAX_TEXTURE_SIDE: u32 = 16_384;

/// A decoded texture.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    /// The file it came from, as the scene or MTL named it.
    pub name: String,
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// sRGB-encoded texels, row by row from the image's top row.
    pub texels: Vec<[u8; 3]>,
}

impl Texture {
    /// Decodes an image file's bytes (PNG, JPEG, TIFF, ... by content); `name` labels it.
    /// Alpha is dropped; 16-bit and float images are converted to 8-bit sRGB as the
    /// `image` crate does.
    pub fn decode(name: &str, bytes: &[u8]) -> Result<Texture, String> {
        let img = image::load_from_memory(bytes).map_err(|e| format!("cannot decode texture '{name}': {e}"))?;
        let (width, height) = (img.width(), img.height());
        if width == 0 || height == 0 || width > MAX_TEXTURE_SIDE || height > MAX_TEXTURE_SIDE {
            return Err(format!("texture '{name}' is {width} x {height}: each side must be 1..={MAX_TEXTURE_SIDE}"));
        }
        let rgb = img.to_rgb8();
        let texels = rgb.pixels().map(|p| p.0).collect();
        Ok(Texture { name: name.to_string(), width, height, texels })
    }

    /// The mean linear reflectance of every texel.
    pub fn mean(&self) -> Rgb {
        let mut sum = [0.0f64; 3];
        for t in &self.texels {
            for (s, &c) in sum.iter_mut().zip(t) {
                *s += srgb_to_linear(c);
            }
        }
        let n = self.texels.len().max(1) as f64;
        Rgb(sum.map(|s| s / n))
    }
}

/// Linear value of an 8-bit sRGB code (the IEC 61966-2-1 curve), from a table.
pub fn srgb_to_linear(c: u8) -> f64 {
    static TABLE: std::sync::OnceLock<[f64; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        let mut t = [0.0; 256];
        for (k, v) in t.iter_mut().enumerate() {
            let x = k as f64 / 255.0;
            *v = if x <= 0.040_45 { x / 12.92 } else { ((x + 0.055) / 1.055).powf(2.4) };
        }
        t
    })[c as usize]
}

/// The four texels of a bilinear lookup at `(u, v)` (texture coordinates, repeating
/// outside [0, 1), `v` up from the image's bottom row as OBJ and PLY give it) and their
/// weights: `((x, y), w)` with `x, y` texel indices.
pub fn bilinear_taps(width: u32, height: u32, u: f64, v: f64) -> [((u32, u32), f64); 4] {
    let wrap = |x: f64| if x.is_finite() { x - x.floor() } else { 0.0 };
    // Texel centres at (i + 0.5) / width; the image's first row is the top (v = 1).
    let fx = wrap(u) * width as f64 - 0.5;
    let fy = (1.0 - wrap(v)) * height as f64 - 0.5;
    let (x0, y0) = (fx.floor(), fy.floor());
    let (tx, ty) = (fx - x0, fy - y0);
    let ix = |x: f64| x.rem_euclid(width as f64) as u32 % width;
    let iy = |y: f64| y.rem_euclid(height as f64) as u32 % height;
    [
        ((ix(x0), iy(y0)), (1.0 - tx) * (1.0 - ty)),
        ((ix(x0 + 1.0), iy(y0)), tx * (1.0 - ty)),
        ((ix(x0), iy(y0 + 1.0)), (1.0 - tx) * ty),
        ((ix(x0 + 1.0), iy(y0 + 1.0)), tx * ty),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_decoding_matches_the_standard() {
        assert_eq!(srgb_to_linear(0), 0.0);
        assert_eq!(srgb_to_linear(255), 1.0);
        // Code 188 is about linear 0.5 (0.5029).
        assert!((srgb_to_linear(188) - 0.5029).abs() < 1e-3);
        assert!((srgb_to_linear(10) - 10.0 / 255.0 / 12.92).abs() < 1e-15);
    }

    #[test]
    fn bilinear_taps_wrap_and_sum_to_one() {
        for (u, v) in [(0.0, 0.0), (0.3, 0.9), (-0.25, 1.75), (0.999, 0.001)] {
            let taps = bilinear_taps(4, 3, u, v);
            let w: f64 = taps.iter().map(|t| t.1).sum();
            assert!((w - 1.0).abs() < 1e-12);
            assert!(taps.iter().all(|((x, y), _)| *x < 4 && *y < 3));
        }
        // A texel's centre takes only that texel: (0.5/4, 1 - 0.5/3) is texel (0, 0).
        let taps = bilinear_taps(4, 3, 0.125, 1.0 - 0.5 / 3.0);
        let on_first: f64 = taps.iter().filter(|t| t.0 == (0, 0)).map(|t| t.1).sum();
        assert!((on_first - 1.0).abs() < 1e-12, "{taps:?}");
    }

    #[test]
    fn a_png_decodes_to_its_texels() {
        let mut img = image::RgbImage::new(2, 1);
        img.put_pixel(0, 0, image::Rgb([255, 0, 0]));
        img.put_pixel(1, 0, image::Rgb([0, 0, 255]));
        let mut png = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).unwrap();
        let t = Texture::decode("t.png", &png).unwrap();
        assert_eq!((t.width, t.height, t.texels.clone()), (2, 1, vec![[255, 0, 0], [0, 0, 255]]));
        assert_eq!(t.mean(), Rgb([0.5, 0.0, 0.5]));
        assert!(Texture::decode("x.png", b"not an image").unwrap_err().contains("x.png"));
    }
}
