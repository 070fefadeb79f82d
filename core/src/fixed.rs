//! Element energies in fixed point.
//!
//! Deposits are summed as integers (units of a per-scene quantum), so the total for an
//! element does not depend on the order in which pairs finish or on which node traced
//! them: integer addition is associative, floating-point addition is not. The quantum
//! is `(4 pi * sum of max light intensities + sum of max emitter powers) / 2^52`: all
//! deposits of a render sum to at most `(1 + lrt_depth + diffuse_bounces)` times the
//! emitted flux, far inside `i64`.

use crate::color::Rgb;
use crate::header::Emitter;
use crate::scene::Light;

/// Flux per channel in units of the scene's energy quantum.
pub type Fixed = [i64; 3];

/// The energy quantum (W per unit) for a set of point lights and emitting elements.
pub fn quantum_for(lights: &[Light], emitters: &[Emitter]) -> f64 {
    let mut total: f64 = lights.iter().map(|l| 4.0 * std::f64::consts::PI * l.intensity.max_channel()).sum();
    if !emitters.is_empty() {
        // Scenes without emitters keep the quantum (and so the energies) they had.
        total += emitters.iter().map(|e| e.power.max_channel()).sum::<f64>();
    }
    if total > 0.0 && total.is_finite() {
        total / (1u64 << 52) as f64
    } else {
        1.0
    }
}

/// Flux to fixed point (rounded to nearest).
pub fn to_fixed(flux: Rgb, quantum: f64) -> Fixed {
    let q = |x: f64| {
        let v = (x / quantum).round();
        if v.is_finite() {
            v.clamp(i64::MIN as f64 / 4.0, i64::MAX as f64 / 4.0) as i64
        } else {
            0
        }
    };
    [q(flux.0[0]), q(flux.0[1]), q(flux.0[2])]
}

/// Fixed point to flux.
pub fn from_fixed(f: Fixed, quantum: f64) -> Rgb {
    Rgb([f[0] as f64 * quantum, f[1] as f64 * quantum, f[2] as f64 * quantum])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fixed_point_round_trips_to_quantum() {
        let q = 1e-12;
        let f = Rgb::new(0.123456789, 2.5, 0.0);
        let back = from_fixed(to_fixed(f, q), q);
        for c in 0..3 {
            assert!((back.0[c] - f.0[c]).abs() <= q);
        }
    }
}
