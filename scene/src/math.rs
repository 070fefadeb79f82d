//! Vector math on glam's `f64` types, and the one operation whose rounding stays ours.
//!
//! Geometry is computed in `f64` ([`glam::DVec3`], [`glam::DMat3`]): scenes far from the
//! origin (coordinates around 1e5) keep sub-micrometre precision, and watertight
//! intersection stays exact on shared edges. Colours are [`crate::color::Rgb`].
//!
//! ```
//! use glam::DVec3;
//! use magg_scene::math::Normalized;
//! assert_eq!(DVec3::new(0.0, 3.0, 4.0).normalized(), DVec3::new(0.0, 0.6, 0.8));
//! assert_eq!(DVec3::ZERO.normalized(), DVec3::ZERO);
//! ```

use glam::DVec3;

/// Normalisation by division by the length, for bitwise-stable renders.
///
/// glam's [`DVec3::normalize`] multiplies by the reciprocal of the length, which rounds
/// twice; the renderer divides each component by the length, and every shipped scene's
/// image and energies depend on those bits (a direction one unit in the last place off
/// can hit a neighbouring element). The zero vector stays zero (glam's `normalize` gives
/// NaN), so a degenerate triangle keeps a zero normal.
pub trait Normalized {
    /// Unit vector in the same direction, each component divided by the length; the zero
    /// vector stays zero.
    fn normalized(self) -> Self;
}

impl Normalized for DVec3 {
    fn normalized(self) -> DVec3 {
        let l = self.length();
        if l > 0.0 {
            self / l
        } else {
            self
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normalized_divides_where_glam_multiplies_by_the_reciprocal() {
        // A vector whose two roundings differ from one: the division is the exact
        // rounding of x / l, which the reciprocal product need not be.
        let v = DVec3::new(0.1, 0.7, 3.0);
        let l = v.length();
        let n = v.normalized();
        assert_eq!(n.to_array(), [0.1 / l, 0.7 / l, 3.0 / l]);
        assert!((n.length() - 1.0).abs() < 1e-15);
        assert!(DVec3::new(f64::NAN, 0.0, 0.0).normalized().is_nan());
    }

    #[test]
    fn orthonormal_pair_is_orthonormal() {
        for n in [DVec3::new(0.0, 0.0, 1.0), DVec3::new(0.0, 0.0, -1.0), DVec3::new(1.0, 2.0, -3.0).normalized()] {
            let (t, b) = n.any_orthonormal_pair();
            assert!(t.dot(n).abs() < 1e-12 && b.dot(n).abs() < 1e-12 && t.dot(b).abs() < 1e-12);
            assert!((t.length() - 1.0).abs() < 1e-12 && (b.length() - 1.0).abs() < 1e-12);
        }
    }
}
