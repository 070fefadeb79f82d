//! Memory bound: a scene whose preprocessing and render would need more memory than
//! `--max-memory-mb` is refused up front, with the estimate, before anything is built.
//!
//! The estimate counts elements the way preprocessing will make them
//! ([`subdivisions_of`]) and charges each one what a render costs per element (host
//! tables, blocks on the forks, node caches, energies: about 400 bytes, measured 270 on
//! the embedded path with 1 and 4 million elements), plus the frame.

use anyhow::bail;
use magg_core::preprocess::subdivisions_of;
use magg_core::scene::Scene;

/// Bytes charged per element.
pub const BYTES_PER_ELEMENT: f64 = 400.0;
/// Bytes charged per pixel (linear frame, tone-mapped copy, rows in flight).
pub const BYTES_PER_PIXEL: f64 = 64.0;
/// Default limit of `--max-memory-mb`.
pub const DEFAULT_MAX_MEMORY_MB: u64 = 4096;

/// Estimated (elements, bytes) of rendering `scene`.
pub fn estimate(scene: &Scene) -> (f64, f64) {
    let s = &scene.settings;
    let elements: f64 = scene
        .patches
        .iter()
        .map(|p| subdivisions_of(&p.vertices, p.subdivisions, p.size_hint, s.element_size).powi(2))
        .sum();
    let pixels = s.width as f64 * s.height as f64;
    (elements, elements * BYTES_PER_ELEMENT + pixels * BYTES_PER_PIXEL)
}

/// Refuses `scene` when its estimate is over `max_mb` MiB. A scene over its own
/// `max_elements` is left to preprocessing, which names the largest patch.
pub fn check(scene: &Scene, max_mb: u64) -> anyhow::Result<()> {
    let (elements, bytes) = estimate(scene);
    if !(elements <= scene.settings.max_elements as f64) {
        return Ok(());
    }
    let mb = bytes / (1u64 << 20) as f64;
    if !(mb <= max_mb as f64) {
        let s = &scene.settings;
        bail!(
            "{}: rendering would need about {:.0} MB ({:.0} elements, {}x{} pixels), over --max-memory-mb {max_mb}; \
             raise element_size, lower the resolution, or raise the limit",
            scene.name,
            mb.min(1e18),
            elements.min(1e18),
            s.width,
            s.height
        );
    }
    Ok(())
}
