//! Error of a render against the converged reference: mean squared errors of the linear
//! image (absolute and relative), of the tone-mapped 8-bit image (reported as PSNR), and
//! of element irradiance. Every function returns a finite number or `None`, never NaN,
//! so that the CSV has no NaN in it.

use magg_core::color::Rgb;
use magg_core::frame::Frame;

/// PSNR reported for identical 8-bit images (and the ceiling of any PSNR), in dB.
pub const PSNR_CAP_DB: f64 = 100.0;

/// The epsilon of the relative MSE: `(a - b)^2 / (b^2 + REL_EPS)`.
pub const REL_EPS: f64 = 1e-3;

/// Mean over pixels and channels of `(a - b)^2`; `None` if the sizes differ or a pixel
/// is not finite.
pub fn image_mse(a: &Frame, reference: &Frame) -> Option<f64> {
    mean_over_pixels(a, reference, |x, b| (x - b) * (x - b))
}

/// Mean over pixels and channels of `(a - b)^2 / (b^2 + 1e-3)`: noise in dark regions
/// counts as much as in bright ones.
pub fn image_rel_mse(a: &Frame, reference: &Frame) -> Option<f64> {
    mean_over_pixels(a, reference, |x, b| (x - b) * (x - b) / (b * b + REL_EPS))
}

fn mean_over_pixels(a: &Frame, reference: &Frame, f: impl Fn(f64, f64) -> f64) -> Option<f64> {
    if a.width != reference.width || a.height != reference.height || a.pixels.is_empty() {
        return None;
    }
    let sum: f64 = a
        .pixels
        .iter()
        .zip(&reference.pixels)
        .flat_map(|(p, q)| (0..3).map(move |c| (p[c] as f64, q[c] as f64)))
        .map(|(x, b)| f(x, b))
        .sum();
    finite(sum / (a.pixels.len() * 3) as f64)
}

/// Mean squared error of two 8-bit images of equal length.
pub fn srgb8_mse(a: &[u8], reference: &[u8]) -> Option<f64> {
    if a.len() != reference.len() || a.is_empty() {
        return None;
    }
    let sum: f64 = a.iter().zip(reference).map(|(&x, &y)| (x as f64 - y as f64).powi(2)).sum();
    finite(sum / a.len() as f64)
}

/// PSNR of an 8-bit MSE in dB, capped at [`PSNR_CAP_DB`] (so a zero error is finite).
pub fn psnr_db(mse: f64) -> f64 {
    if mse > 0.0 && mse.is_finite() {
        (10.0 * (255.0 * 255.0 / mse).log10()).min(PSNR_CAP_DB)
    } else if mse == 0.0 {
        PSNR_CAP_DB
    } else {
        0.0
    }
}

/// Mean over elements and channels of the squared irradiance difference; `None` when the
/// element sets differ in size (another element size: not comparable element by element).
pub fn irradiance_mse(a: &[Rgb], reference: &[Rgb]) -> Option<f64> {
    if a.len() != reference.len() || a.is_empty() {
        return None;
    }
    let sum: f64 = a.iter().zip(reference).flat_map(|(p, q)| (0..3).map(move |c| (p.0[c] - q.0[c]).powi(2))).sum();
    finite(sum / (a.len() * 3) as f64)
}

fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(values: &[f64]) -> Frame {
        let mut f = Frame::new(values.len() as u32, 1);
        for (x, v) in values.iter().enumerate() {
            f.set(x as u32, 0, Rgb::splat(*v));
        }
        f
    }

    #[test]
    fn identical_images_have_zero_error_and_capped_psnr() {
        let a = frame(&[0.0, 0.5, 2.0, 10.0]);
        assert_eq!(image_mse(&a, &a), Some(0.0));
        assert_eq!(image_rel_mse(&a, &a), Some(0.0));
        let s = a.to_srgb8(a.exposure_scale(magg_core::scene::Exposure::Auto));
        let mse = srgb8_mse(&s, &s).unwrap();
        assert_eq!(mse, 0.0);
        assert_eq!(psnr_db(mse), PSNR_CAP_DB);
        assert!(psnr_db(mse).is_finite());
    }

    #[test]
    fn known_errors() {
        let a = frame(&[1.0, 1.0]);
        let b = frame(&[0.0, 2.0]);
        assert_eq!(image_mse(&a, &b), Some(1.0));
        let rel = image_rel_mse(&a, &b).unwrap();
        let want = (1.0 / REL_EPS + 1.0 / (4.0 + REL_EPS)) / 2.0;
        assert!((rel - want).abs() < 1e-9 * want);
        // One 8-bit level off everywhere: MSE 1, PSNR 20 log10(255).
        let p = psnr_db(srgb8_mse(&[10, 20], &[11, 19]).unwrap());
        assert!((p - 20.0 * 255f64.log10()).abs() < 1e-9);
    }

    #[test]
    fn mismatched_or_bad_inputs_give_none_not_nan() {
        assert_eq!(image_mse(&frame(&[1.0]), &frame(&[1.0, 2.0])), None);
        assert_eq!(image_mse(&frame(&[f64::NAN]), &frame(&[1.0])), None);
        assert_eq!(irradiance_mse(&[Rgb::splat(1.0)], &[]), None);
        assert_eq!(irradiance_mse(&[Rgb::splat(1.0)], &[Rgb::splat(3.0)]), Some(4.0));
        assert_eq!(psnr_db(f64::NAN), 0.0);
    }
}
