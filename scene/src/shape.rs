//! Whether a patch is a shape magg can trace: a triangle of non-zero area, a quad that is
//! planar and strictly convex with its vertices in order. The scene parser and the OBJ
//! loader ask these; the tolerances are relative to the patch's size, so that a scene
//! scaled by 1e6 or 1e-6 is judged the same.

use crate::math::Normalized;
use glam::DVec3;

/// Relative tolerance of the zero-area test: `|cross| <= EPS_AREA * longest_edge^2`.
pub(super) const EPS_AREA: f64 = 1e-12;
/// Relative tolerance of the quad planarity test (distance / longest edge).
pub(super) const EPS_PLANAR: f64 = 1e-6;

/// True when a triangle has (numerically) zero area: `|cross| <= 1e-12 * longest_edge^2`.
pub(super) fn is_degenerate(v: &[DVec3; 3]) -> bool {
    let (e0, e1, e2) = (v[1] - v[0], v[2] - v[1], v[0] - v[2]);
    let longest2 = e0.length_squared().max(e1.length_squared()).max(e2.length_squared());
    let area2 = e0.cross(v[2] - v[0]).length();
    area2.is_nan() || area2 <= EPS_AREA * longest2
}

/// Checks that a quad is planar (within 1e-6 of its longest edge) and strictly convex with
/// its vertices in order; the error says why not.
pub(super) fn check_quad(v: &[DVec3; 4]) -> Result<(), String> {
    let longest =
        (0..4).flat_map(|a| (a + 1..4).map(move |b| (a, b))).map(|(a, b)| (v[b] - v[a]).length()).fold(0.0, f64::max);
    let n = (v[2] - v[0]).cross(v[3] - v[1]);
    let area2 = n.length();
    if area2.is_nan() || area2 <= EPS_AREA * longest * longest {
        return Err("is degenerate (zero area)".to_string());
    }
    let n = n.normalized();
    let centre = (v[0] + v[1] + v[2] + v[3]) / 4.0;
    for (k, p) in v.iter().enumerate() {
        let off = (*p - centre).dot(n).abs();
        if off > EPS_PLANAR * longest {
            return Err(format!(
                "is not planar: vertex {k} is {off:e} off the plane (tolerance {:e})",
                EPS_PLANAR * longest
            ));
        }
    }
    for k in 0..4 {
        let (a, b, c) = (v[k], v[(k + 1) % 4], v[(k + 2) % 4]);
        let turn = (b - a).cross(c - b).dot(n);
        if turn.is_nan() || turn <= EPS_AREA * longest * longest {
            return Err(format!("is not convex at vertex {} (or its vertices are out of order)", (k + 1) % 4));
        }
    }
    Ok(())
}
