//! Image files, chosen by the output's extension: tone-mapped 8-bit sRGB (PNG, JPEG,
//! TIFF) and linear radiance (OpenEXR, Radiance HDR, PFM).
//!
//! The 8-bit pixels are the core's ([`Frame::to_srgb8`], its one sRGB encoder); the `image`
//! crate only packs them into a file. The linear formats get the frame's f32 radiance as it
//! is. PFM, which `image` does not handle, keeps a small writer and reader of its own.
//! [`read`] turns any of these files back into linear radiance (8-bit ones decoded from
//! sRGB), for `magg-host diff`.
//!
//! ```no_run
//! # fn demo(frame: &magg_core::frame::Frame, exposure: magg_core::scene::Exposure) -> anyhow::Result<()> {
//! use magg_host::images::{self, ImageFormat};
//! let path = std::path::Path::new("shot.jpg");
//! images::write(frame, path, ImageFormat::of(path)?, exposure)?;
//! # Ok(()) }
//! ```

use anyhow::Context;
use image::{ImageEncoder, Rgb32FImage, RgbImage};
use magg_core::frame::Frame;
use magg_core::scene::Exposure;
use std::io::{Cursor, Write};
use std::path::Path;

/// Quality of JPEG output (1-100): high, since a render is looked at closely.
pub const JPEG_QUALITY: u8 = 92;

/// The extensions [`ImageFormat::of`] knows, as its error lists them.
pub const SUPPORTED: &str = ".png, .jpg/.jpeg, .tif/.tiff (tone-mapped sRGB), .hdr, .exr, .pfm (linear)";

/// Image formats, by extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    /// PNG, tone-mapped 8-bit sRGB.
    Png,
    /// JPEG, tone-mapped 8-bit sRGB (lossy, quality [`JPEG_QUALITY`]).
    Jpeg,
    /// TIFF, tone-mapped 8-bit sRGB.
    Tiff,
    /// Radiance RGBE, linear (8-bit mantissas with a shared exponent).
    Hdr,
    /// OpenEXR, linear f32.
    Exr,
    /// Portable float map, linear f32.
    Pfm,
}

/// An output path whose extension names no format [`ImageFormat::of`] knows.
#[derive(Debug, thiserror::Error)]
#[error("{path}: unknown image format {ext:?} (supported: {SUPPORTED})")]
pub struct UnknownFormat {
    /// The path as given.
    pub path: String,
    /// Its extension (empty when it has none).
    pub ext: String,
}

impl ImageFormat {
    /// The format of `path`, from its extension (any case).
    pub fn of(path: &Path) -> Result<ImageFormat, UnknownFormat> {
        let ext = path.extension().map(|e| e.to_string_lossy().into_owned()).unwrap_or_default();
        Ok(match ext.to_ascii_lowercase().as_str() {
            "png" => ImageFormat::Png,
            "jpg" | "jpeg" => ImageFormat::Jpeg,
            "tif" | "tiff" => ImageFormat::Tiff,
            "hdr" => ImageFormat::Hdr,
            "exr" => ImageFormat::Exr,
            "pfm" => ImageFormat::Pfm,
            _ => return Err(UnknownFormat { path: path.display().to_string(), ext }),
        })
    }

    /// Whether the format holds linear radiance (no tone mapping, no exposure).
    pub fn is_linear(self) -> bool {
        matches!(self, ImageFormat::Hdr | ImageFormat::Exr | ImageFormat::Pfm)
    }
}

/// Writes `frame` to `path` in `format`; the 8-bit formats use `exposure` for tone mapping.
pub fn write(frame: &Frame, path: &Path, format: ImageFormat, exposure: Exposure) -> anyhow::Result<()> {
    encode(frame, format, exposure)
        .and_then(|bytes| Ok(std::fs::write(path, bytes)?))
        .with_context(|| format!("cannot write image {}", path.display()))
}

/// The file bytes of `frame` in `format`, in memory.
pub fn encode(frame: &Frame, format: ImageFormat, exposure: Exposure) -> anyhow::Result<Vec<u8>> {
    let mut out = Cursor::new(Vec::new());
    match format {
        ImageFormat::Png => srgb8(frame, exposure)?.write_to(&mut out, image::ImageFormat::Png)?,
        ImageFormat::Jpeg => image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, JPEG_QUALITY).write_image(
            &srgb8(frame, exposure)?,
            frame.width,
            frame.height,
            image::ExtendedColorType::Rgb8,
        )?,
        ImageFormat::Tiff => srgb8(frame, exposure)?.write_to(&mut out, image::ImageFormat::Tiff)?,
        ImageFormat::Hdr => linear(frame)?.write_to(&mut out, image::ImageFormat::Hdr)?,
        ImageFormat::Exr => linear(frame)?.write_to(&mut out, image::ImageFormat::OpenExr)?,
        ImageFormat::Pfm => write_pfm(frame, &mut out)?,
    }
    Ok(out.into_inner())
}

/// The PNG of `frame`, in memory (the live view serves it).
pub fn encode_png(frame: &Frame, exposure: Exposure) -> anyhow::Result<Vec<u8>> {
    encode(frame, ImageFormat::Png, exposure)
}

/// The OpenEXR of `frame`, in memory (the live view serves it).
pub fn encode_exr(frame: &Frame) -> anyhow::Result<Vec<u8>> {
    encode(frame, ImageFormat::Exr, Exposure::Fixed(1.0))
}

/// The core's tone-mapped sRGB bytes as an `image` buffer.
fn srgb8(frame: &Frame, exposure: Exposure) -> anyhow::Result<RgbImage> {
    RgbImage::from_raw(frame.width, frame.height, frame.to_srgb8(frame.exposure_scale(exposure)))
        .context("frame size does not match its pixels")
}

/// The frame's linear radiance as an `image` buffer.
fn linear(frame: &Frame) -> anyhow::Result<Rgb32FImage> {
    Rgb32FImage::from_raw(frame.width, frame.height, frame.pixels.iter().flatten().copied().collect())
        .context("frame size does not match its pixels")
}

/// Linear f32 portable float map (little-endian, bottom row first).
fn write_pfm(frame: &Frame, out: &mut impl Write) -> std::io::Result<()> {
    write!(out, "PF\n{} {}\n-1.0\n", frame.width, frame.height)?;
    for y in (0..frame.height).rev() {
        for x in 0..frame.width {
            for c in frame.get(x, y) {
                out.write_all(&c.to_le_bytes())?;
            }
        }
    }
    Ok(())
}

/// Reads `path` as linear radiance, by its extension: the linear formats as they are, the
/// tone-mapped ones (any bit depth) decoded from sRGB. Alpha is dropped.
pub fn read(path: &Path) -> anyhow::Result<Frame> {
    let format = ImageFormat::of(path)?;
    let what = || format!("cannot read image {}", path.display());
    if format == ImageFormat::Pfm {
        return read_pfm(&std::fs::read(path).with_context(what)?).with_context(what);
    }
    let img = image::open(path).with_context(what)?.into_rgb32f();
    let decode = |c: f32| if format.is_linear() { c } else { decode_srgb(c) };
    let pixels = img.pixels().map(|p| p.0.map(decode)).collect();
    Ok(Frame { width: img.width(), height: img.height(), pixels })
}

/// The sRGB transfer function inverted: an encoded value in [0, 1] to linear.
pub fn decode_srgb(v: f32) -> f32 {
    let v = f64::from(v);
    (if v <= 0.040_45 { v / 12.92 } else { ((v + 0.055) / 1.055).powf(2.4) }) as f32
}

/// A portable float map: `PF` (RGB) or `Pf` (grey), width and height, then a scale whose
/// sign gives the byte order (negative: little-endian); rows run bottom-up.
fn read_pfm(bytes: &[u8]) -> anyhow::Result<Frame> {
    // Three whitespace-separated header tokens after the magic, then one whitespace byte.
    let mut at = 0;
    let mut token = || -> anyhow::Result<&str> {
        while bytes.get(at).is_some_and(u8::is_ascii_whitespace) {
            at += 1;
        }
        let start = at;
        while bytes.get(at).is_some_and(|b| !b.is_ascii_whitespace()) {
            at += 1;
        }
        anyhow::ensure!(at > start && at < bytes.len(), "PFM header ends early");
        Ok(std::str::from_utf8(&bytes[start..at])?)
    };
    let channels = match token()? {
        "PF" => 3,
        "Pf" => 1,
        magic => anyhow::bail!("not a PFM file (starts with {magic:?}, not PF or Pf)"),
    };
    let width: u32 = token()?.parse().context("bad PFM width")?;
    let height: u32 = token()?.parse().context("bad PFM height")?;
    let scale: f32 = token()?.parse().context("bad PFM scale")?;
    let data = &bytes[at + 1..];
    let count = width as usize * height as usize * channels;
    anyhow::ensure!(
        data.len() == count * 4,
        "PFM data is {} bytes, a {width} x {height} map of {channels} channel(s) needs {}",
        data.len(),
        count * 4
    );
    let samples: Vec<f32> = data
        .chunks_exact(4)
        .map(|c| {
            let c = [c[0], c[1], c[2], c[3]];
            if scale < 0.0 {
                f32::from_le_bytes(c)
            } else {
                f32::from_be_bytes(c)
            }
        })
        .collect();
    let mut frame = Frame::new(width, height);
    for (i, px) in frame.pixels.iter_mut().enumerate() {
        let (x, y) = (i % width as usize, i / width as usize);
        let s = &samples[((height as usize - 1 - y) * width as usize + x) * channels..][..channels];
        *px = if channels == 3 { [s[0], s[1], s[2]] } else { [s[0]; 3] };
    }
    Ok(frame)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small frame with a smooth gradient (JPEG keeps it well) and values above 1.
    fn frame() -> Frame {
        let mut f = Frame::new(24, 16);
        for y in 0..f.height {
            for x in 0..f.width {
                let v = [x as f32 / 23.0, y as f32 / 15.0, 0.25 + (x + y) as f32 / 20.0];
                f.pixels[(y * f.width + x) as usize] = v;
            }
        }
        f
    }

    fn exposure() -> Exposure {
        Exposure::Auto
    }

    fn written(f: &Frame, ext: &str) -> image::DynamicImage {
        let dir = std::env::temp_dir().join(format!("magg-images-{}-{ext}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(format!("a.{ext}"));
        write(f, &path, ImageFormat::of(&path).unwrap(), exposure()).unwrap();
        let img = image::open(&path).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        img
    }

    #[test]
    fn eight_bit_formats_hold_the_cores_srgb_bytes() {
        let f = frame();
        let want = f.to_srgb8(f.exposure_scale(exposure()));
        for ext in ["png", "PNG", "tif", "tiff"] {
            let img = written(&f, ext).into_rgb8();
            assert_eq!((img.width(), img.height()), (24, 16), "{ext}");
            assert_eq!(img.as_raw(), &want, "{ext}: pixels changed");
        }
        assert_eq!(image::load_from_memory(&encode_png(&f, exposure()).unwrap()).unwrap().into_rgb8().as_raw(), &want);
        // JPEG is lossy: close, not equal.
        for ext in ["jpg", "jpeg"] {
            let img = written(&f, ext).into_rgb8();
            assert_eq!((img.width(), img.height()), (24, 16), "{ext}");
            let worst = img.as_raw().iter().zip(&want).map(|(&a, &b)| a.abs_diff(b)).max().unwrap();
            assert!(worst <= 12, "{ext}: a byte is off by {worst}");
        }
    }

    #[test]
    fn linear_formats_hold_the_radiance() {
        let f = frame();
        let want: Vec<f32> = f.pixels.iter().flatten().copied().collect();
        let exr = written(&f, "exr").into_rgb32f();
        assert_eq!(exr.as_raw(), &want, "exr: radiance changed");
        assert_eq!(&encode_exr(&f).unwrap()[..4], &[0x76, 0x2f, 0x31, 0x01]);
        // RGBE keeps 8 bits of mantissa per channel against the pixel's largest.
        let hdr = written(&f, "hdr").into_rgb32f();
        assert_eq!((hdr.width(), hdr.height()), (24, 16));
        for (px, b) in hdr.pixels().zip(f.pixels.iter()) {
            let peak = b.iter().copied().fold(0.0f32, f32::max);
            for c in 0..3 {
                assert!((px.0[c] - b[c]).abs() <= peak / 64.0, "hdr: {:?} against {b:?}", px.0);
            }
        }
    }

    #[test]
    fn pfm_is_bottom_row_first() {
        let f = frame();
        let bytes = encode(&f, ImageFormat::Pfm, exposure()).unwrap();
        let head = b"PF\n24 16\n-1.0\n";
        assert_eq!(&bytes[..head.len()], head);
        assert_eq!(bytes.len(), head.len() + 24 * 16 * 12);
        let first = f32::from_le_bytes(bytes[head.len() + 4..head.len() + 8].try_into().unwrap());
        assert_eq!(first, f.get(0, 15)[1]);
    }

    #[test]
    fn every_format_reads_back_as_linear_radiance() {
        let f = frame();
        let dir = tempfile::tempdir().unwrap();
        for ext in ["pfm", "exr"] {
            let path = dir.path().join(format!("a.{ext}"));
            write(&f, &path, ImageFormat::of(&path).unwrap(), exposure()).unwrap();
            assert_eq!(read(&path).unwrap(), f, "{ext}");
        }
        // 8-bit: the decoded value encodes back to the byte that was written.
        let path = dir.path().join("a.png");
        write(&f, &path, ImageFormat::Png, exposure()).unwrap();
        let back = read(&path).unwrap();
        let bytes: Vec<u8> = back.pixels.iter().flatten().map(|&c| magg_core::frame::encode_srgb(c as f64)).collect();
        assert_eq!(bytes, f.to_srgb8(f.exposure_scale(exposure())));
    }

    #[test]
    fn pfm_reads_big_endian_and_grey_and_refuses_short_data() {
        let mut big = b"Pf\n2 1\n1.0\n".to_vec();
        big.extend([1.5f32, -2.0].iter().flat_map(|v| v.to_be_bytes()));
        let f = read_pfm(&big).unwrap();
        assert_eq!(f.pixels, vec![[1.5; 3], [-2.0; 3]]);
        let e = read_pfm(&big[..big.len() - 1]).unwrap_err().to_string();
        assert!(e.contains("2 x 1"), "{e}");
        assert!(read_pfm(b"P6\n1 1\n255\n...").is_err());
        assert!(read_pfm(b"PF\n1").is_err());
    }

    #[test]
    fn an_unknown_extension_names_it_and_the_supported_ones() {
        let e = ImageFormat::of(Path::new("out/x.bmp")).unwrap_err().to_string();
        assert!(e.contains("x.bmp") && e.contains("\"bmp\""), "{e}");
        assert!(e.contains(".png") && e.contains(".jpg") && e.contains(".tiff") && e.contains(".hdr"), "{e}");
        assert!(ImageFormat::of(Path::new("x")).is_err());
        assert!(ImageFormat::of(Path::new("x.exr")).unwrap().is_linear());
        assert!(!ImageFormat::of(Path::new("x.JPEG")).unwrap().is_linear());
    }
}
