//! Error metrics between two linear images, and a heat map of where the error sits: what
//! `magg-host diff A B` prints, to measure magg against a reference render (B), e.g. one
//! from Mitsuba 3 or a converged magg.
//!
//! ```
//! use magg_core::frame::Frame;
//! use magg_host::image_diff;
//! let (a, b) = (Frame::new(4, 4), Frame::new(4, 4));
//! let d = image_diff::diff(&a, &b).unwrap();
//! assert!(d.identical && d.rel_mse == 0.0);
//! assert_eq!(image_diff::heatmap(&a, &b).unwrap().dimensions(), (4, 4));
//! ```

use image::RgbImage;
use magg_core::frame::Frame;
use serde::Serialize;

/// The epsilon of the relative MSE, `(a - b)^2 / (b^2 + REL_EPS)`: the definition used to
/// compare magg with Mitsuba 3 (issue 16), so numbers match across tools.
pub const REL_EPS: f64 = 0.01;

/// The heat map's scale: a pixel whose relative squared error is at most this is black.
pub const HEAT_LOW: f64 = 1e-6;

/// The heat map's scale: a pixel whose relative squared error is at least this is white.
pub const HEAT_HIGH: f64 = 1.0;

/// Two images that cannot be compared.
#[derive(Debug, PartialEq, thiserror::Error)]
pub enum DiffError {
    /// They are not the same size.
    #[error("sizes differ: {a_width} x {a_height} against {b_width} x {b_height}")]
    Size {
        /// Width of A.
        a_width: u32,
        /// Height of A.
        a_height: u32,
        /// Width of B.
        b_width: u32,
        /// Height of B.
        b_height: u32,
    },
    /// A pixel holds NaN or an infinity, which no metric survives.
    #[error("pixel ({x}, {y}) is {value} (x from the left, y from the top)")]
    NotFinite {
        /// Column.
        x: u32,
        /// Row, from the top.
        y: u32,
        /// The offending channel value.
        value: f32,
    },
}

/// The metrics of A against the reference B, over all pixels and channels.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Diff {
    /// Width of both images.
    pub width: u32,
    /// Height of both images.
    pub height: u32,
    /// Mean of `(a - b)^2 / (b^2 + REL_EPS)`: noise in dark regions counts like in bright ones.
    pub rel_mse: f64,
    /// Mean of `(a - b)^2`.
    pub mse: f64,
    /// Square root of `mse`.
    pub rmse: f64,
    /// Mean of A's channels.
    pub mean_a: f64,
    /// Mean of B's channels.
    pub mean_b: f64,
    /// `mean_a / mean_b`, the brightness ratio; `None` when B is black.
    pub mean_ratio: Option<f64>,
    /// Largest `|a - b|` of any channel.
    pub max_abs_diff: f64,
    /// The pixel (x, y from the top-left) of `max_abs_diff`; `None` when nothing differs.
    pub max_abs_diff_at: Option<[u32; 2]>,
    /// Pixels with any channel unequal.
    pub differing_pixels: u64,
    /// Pixels compared (all, or those of the mask).
    pub pixels: u64,
    /// Whether every channel of every pixel has the same bits.
    pub identical: bool,
}

/// The first pixel of `frame` that is not finite, as an error.
pub fn check_finite(frame: &Frame) -> Result<(), DiffError> {
    for (i, p) in frame.pixels.iter().enumerate() {
        if let Some(&value) = p.iter().find(|c| !c.is_finite()) {
            let (x, y) = (i as u32 % frame.width.max(1), i as u32 / frame.width.max(1));
            return Err(DiffError::NotFinite { x, y, value });
        }
    }
    Ok(())
}

/// The metrics of `a` against the reference `b`; both must be the same size and finite.
pub fn diff(a: &Frame, b: &Frame) -> Result<Diff, DiffError> {
    diff_where(a, b, None)
}

/// Which pixels [`diff_where`] compares: those where `image` (the same size as the two
/// compared) is above `above` in the mean of its channels.
#[derive(Clone, Copy, Debug)]
pub struct Mask<'a> {
    /// The mask image, e.g. a render of the region lit with radiance 1, so that a pixel's
    /// value is the share of it the region covers.
    pub image: &'a Frame,
    /// The threshold: one half keeps pixels mostly inside, just under 1 those wholly inside.
    pub above: f64,
}

/// [`diff`] over the pixels `mask` keeps, every pixel without one: the metrics of a
/// region, such as the pixels a reference renderer can compute.
pub fn diff_where(a: &Frame, b: &Frame, mask: Option<Mask>) -> Result<Diff, DiffError> {
    same_size(a, b)?;
    check_finite(a)?;
    check_finite(b)?;
    if let Some(m) = mask {
        same_size(a, m.image)?;
    }
    let kept =
        |i: usize| mask.is_none_or(|m| m.image.pixels[i].iter().map(|&c| f64::from(c)).sum::<f64>() > 3.0 * m.above);
    let (mut rel, mut sq, mut sum_a, mut sum_b) = (0.0, 0.0, 0.0, 0.0);
    let (mut max_abs_diff, mut max_abs_diff_at, mut differing_pixels) = (0.0, None, 0);
    let mut identical = true;
    let mut pixels = 0u64;
    for (i, (p, q)) in a.pixels.iter().zip(&b.pixels).enumerate() {
        if !kept(i) {
            continue;
        }
        pixels += 1;
        differing_pixels += u64::from(p != q);
        identical &= p.iter().zip(q).all(|(x, y)| x.to_bits() == y.to_bits());
        for (&x, &y) in p.iter().zip(q) {
            let (x, y) = (f64::from(x), f64::from(y));
            let d = x - y;
            rel += d * d / (y * y + REL_EPS);
            sq += d * d;
            sum_a += x;
            sum_b += y;
            if d.abs() > max_abs_diff {
                max_abs_diff = d.abs();
                max_abs_diff_at = Some([i as u32 % a.width, i as u32 / a.width]);
            }
        }
    }
    let n = (pixels * 3).max(1) as f64;
    let (mean_a, mean_b) = (sum_a / n, sum_b / n);
    Ok(Diff {
        width: a.width,
        height: a.height,
        rel_mse: rel / n,
        mse: sq / n,
        rmse: (sq / n).sqrt(),
        mean_a,
        mean_b,
        mean_ratio: (mean_b != 0.0).then(|| mean_a / mean_b),
        max_abs_diff,
        max_abs_diff_at,
        differing_pixels,
        pixels,
        identical,
    })
}

/// Each pixel's relative squared error (its channels' mean of `(a - b)^2 / (b^2 + REL_EPS)`,
/// so the image's mean is the relMSE) on a log scale as a colour: black at or below
/// [`HEAT_LOW`], then red (1e-4), yellow (1e-2) and white at or above [`HEAT_HIGH`], two
/// decades a step.
pub fn heatmap(a: &Frame, b: &Frame) -> Result<RgbImage, DiffError> {
    same_size(a, b)?;
    let mut img = RgbImage::new(a.width, a.height);
    for (px, (p, q)) in img.pixels_mut().zip(a.pixels.iter().zip(&b.pixels)) {
        let e =
            p.iter().zip(q).map(|(&x, &y)| (f64::from(x) - f64::from(y)).powi(2) / (f64::from(y).powi(2) + REL_EPS));
        px.0 = ramp(e.sum::<f64>() / 3.0);
    }
    Ok(img)
}

/// The heat map's colour of a relative squared error `e`: black -> red -> yellow -> white
/// over log10 `e` from [`HEAT_LOW`] to [`HEAT_HIGH`] (NaN is white: it is an error too).
pub fn ramp(e: f64) -> [u8; 3] {
    let t = if e.is_nan() {
        1.0
    } else {
        ((e.log10() - HEAT_LOW.log10()) / (HEAT_HIGH / HEAT_LOW).log10()).clamp(0.0, 1.0)
    };
    let channel = |from: f64| ((3.0 * t - from).clamp(0.0, 1.0) * 255.0).round() as u8;
    [channel(0.0), channel(1.0), channel(2.0)]
}

fn same_size(a: &Frame, b: &Frame) -> Result<(), DiffError> {
    if (a.width, a.height) == (b.width, b.height) {
        return Ok(());
    }
    Err(DiffError::Size { a_width: a.width, a_height: a.height, b_width: b.width, b_height: b.height })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 3 x 2 frame with values from 0 to 1, binary fractions (so sums are exact).
    fn frame() -> Frame {
        let mut f = Frame::new(3, 2);
        for (i, p) in f.pixels.iter_mut().enumerate() {
            *p = [i as f32 / 8.0, 0.5, 1.0 - i as f32 / 8.0];
        }
        f
    }

    #[test]
    fn an_image_against_itself_is_identical_with_zero_error() {
        let d = diff(&frame(), &frame()).unwrap();
        assert!(d.identical);
        assert_eq!((d.rel_mse, d.mse, d.rmse, d.max_abs_diff, d.differing_pixels), (0.0, 0.0, 0.0, 0.0, 0));
        assert_eq!((d.max_abs_diff_at, d.mean_ratio, d.pixels), (None, Some(1.0), 6));
    }

    #[test]
    fn a_mask_keeps_only_its_pixels() {
        let b = frame();
        let mut a = b.clone();
        a.pixels[4][1] += 0.25; // pixel (1, 1): masked out below
        a.pixels[0][2] += 0.5; // pixel (0, 0): kept
        let mut mask = Frame::new(3, 2);
        mask.pixels[0] = [1.0; 3];
        mask.pixels[5] = [0.9, 0.6, 0.1]; // mean 0.53: kept
        mask.pixels[4] = [1.0, 0.5, 0.0]; // mean 0.5: not above one half
        let d = diff_where(&a, &b, Some(Mask { image: &mask, above: 0.5 })).unwrap();
        assert_eq!((d.pixels, d.differing_pixels, d.max_abs_diff_at), (2, 1, Some([0, 0])));
        let rel = 0.25 / (1.0 + REL_EPS) / 6.0;
        assert!((d.rel_mse - rel).abs() < 1e-15, "{} against {rel}", d.rel_mse);
        let wholly = diff_where(&a, &b, Some(Mask { image: &mask, above: 0.99 })).unwrap();
        assert_eq!((wholly.pixels, wholly.max_abs_diff_at), (1, Some([0, 0])), "only the pixel wholly inside");
        let other = Frame::new(2, 3);
        assert!(diff_where(&a, &b, Some(Mask { image: &other, above: 0.5 })).is_err(), "a mask of another size");
    }

    #[test]
    fn a_constant_offset_gives_the_closed_form_errors() {
        let b = frame();
        let mut a = b.clone();
        a.pixels[4][1] += 0.25; // pixel (1, 1)
        for p in &mut a.pixels {
            p[0] += 0.125;
        }
        let d = diff(&a, &b).unwrap();
        let n = 18.0;
        let mse = (6.0 * 0.125f64.powi(2) + 0.25f64.powi(2)) / n;
        let rel: f64 = b.pixels.iter().map(|p| 0.125f64.powi(2) / (f64::from(p[0]).powi(2) + REL_EPS)).sum::<f64>()
            + 0.25f64.powi(2) / (0.25 + REL_EPS);
        assert!((d.mse - mse).abs() < 1e-12 && (d.rmse - mse.sqrt()).abs() < 1e-12, "{d:?}");
        assert!((d.rel_mse - rel / n).abs() < 1e-12, "{d:?}");
        assert!((d.max_abs_diff - 0.25).abs() < 1e-7 && d.max_abs_diff_at == Some([1, 1]), "{d:?}");
        assert_eq!((d.differing_pixels, d.identical), (6, false));
        // B's channels sum to 9 (1.5 a pixel), A adds 6 x 0.125 + 0.25 = 1.
        assert!((d.mean_b - 9.0 / n).abs() < 1e-12 && (d.mean_ratio.unwrap() - 10.0 / 9.0).abs() < 1e-12, "{d:?}");
    }

    #[test]
    fn different_sizes_and_nan_are_errors() {
        let e = diff(&Frame::new(3, 2), &Frame::new(2, 3)).unwrap_err();
        assert_eq!(e.to_string(), "sizes differ: 3 x 2 against 2 x 3");
        assert!(heatmap(&Frame::new(3, 2), &Frame::new(3, 1)).is_err());
        let mut a = frame();
        a.pixels[5][2] = f32::NAN;
        assert_eq!(
            diff(&a, &frame()).unwrap_err().to_string(),
            "pixel (2, 1) is NaN (x from the left, y from the top)"
        );
        assert!(diff(&frame(), &a).is_err(), "a NaN in the reference too");
    }

    #[test]
    fn the_heat_map_has_the_images_size_and_runs_black_to_white() {
        let b = frame();
        let mut a = b.clone();
        a.pixels[2] = [100.0; 3];
        let img = heatmap(&a, &b).unwrap();
        assert_eq!(img.dimensions(), (3, 2));
        assert_eq!(img.get_pixel(0, 0).0, [0, 0, 0], "no error: black");
        assert_eq!(img.get_pixel(2, 0).0, [255, 255, 255], "a huge error: white");
        assert_eq!((ramp(0.0), ramp(HEAT_LOW), ramp(HEAT_HIGH), ramp(1e9)), ([0; 3], [0; 3], [255; 3], [255; 3]));
        assert_eq!((ramp(1e-4), ramp(1e-2)), ([255, 0, 0], [255, 255, 0]), "red, then yellow");
        assert_eq!(ramp(f64::NAN), [255; 3]);
    }
}
