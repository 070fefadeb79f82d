//! Image files: PNG (tone-mapped sRGB), OpenEXR and PFM (linear radiance).

use crate::cli::ImageFormat;
use anyhow::Context;
use magg_core::frame::Frame;
use magg_core::scene::Exposure;
use std::io::Write;
use std::path::Path;

/// Writes `frame` to `path` in `format`; PNG uses `exposure` for tone mapping.
pub fn write(frame: &Frame, path: &Path, format: ImageFormat, exposure: Exposure) -> anyhow::Result<()> {
    match format {
        ImageFormat::Png => write_png(frame, path, exposure),
        ImageFormat::Exr => write_exr(frame, path),
        ImageFormat::Pfm => write_pfm(frame, path),
    }
    .with_context(|| format!("cannot write image {}", path.display()))
}

/// Tone-mapped 8-bit sRGB PNG.
pub fn write_png(frame: &Frame, path: &Path, exposure: Exposure) -> anyhow::Result<()> {
    let file = std::fs::File::create(path)?;
    encode_png_to(frame, exposure, std::io::BufWriter::new(file))
}

/// The PNG of [`write_png`], in memory (the live view serves it).
pub fn encode_png(frame: &Frame, exposure: Exposure) -> anyhow::Result<Vec<u8>> {
    let mut out = Vec::new();
    encode_png_to(frame, exposure, &mut out)?;
    Ok(out)
}

fn encode_png_to(frame: &Frame, exposure: Exposure, out: impl Write) -> anyhow::Result<()> {
    let mut enc = png::Encoder::new(out, frame.width, frame.height);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    let mut w = enc.write_header()?;
    w.write_image_data(&frame.to_srgb8(frame.exposure_scale(exposure)))?;
    w.finish()?;
    Ok(())
}

/// Linear f32 OpenEXR.
pub fn write_exr(frame: &Frame, path: &Path) -> anyhow::Result<()> {
    std::fs::write(path, encode_exr(frame)?)?;
    Ok(())
}

/// The OpenEXR of [`write_exr`], in memory.
pub fn encode_exr(frame: &Frame) -> anyhow::Result<Vec<u8>> {
    use exr::prelude::*;
    let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
        let p = frame.get(x as u32, y as u32);
        (p[0], p[1], p[2])
    });
    let mut out = std::io::Cursor::new(Vec::new());
    Image::from_channels((frame.width as usize, frame.height as usize), channels)
        .write()
        .to_buffered(&mut out)
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(out.into_inner())
}

/// Linear f32 portable float map (little-endian, bottom row first).
pub fn write_pfm(frame: &Frame, path: &Path) -> anyhow::Result<()> {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    write!(out, "PF\n{} {}\n-1.0\n", frame.width, frame.height)?;
    for y in (0..frame.height).rev() {
        for x in 0..frame.width {
            for c in frame.get(x, y) {
                out.write_all(&c.to_le_bytes())?;
            }
        }
    }
    out.flush()?;
    Ok(())
}
