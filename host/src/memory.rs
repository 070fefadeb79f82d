//! Memory bound: a scene whose preprocessing and render would need more memory than
//! `--max-memory-mb` is refused up front, with the estimate, before anything is built.
//!
//! The estimate counts elements the way preprocessing will make them
//! ([`subdivisions_of`]) and charges each one what a render costs per element (host
//! tables, blocks on the forks, node caches, energies: about 400 bytes, measured 270 on
//! the embedded path with 1 and 4 million elements), each patch what preparing and
//! holding it costs (the parsed patch, its share's copy, lattice points and their
//! welding messages, its records and BVH leaf: about 2.5 KB, from a 1M-triangle model's
//! 3.8 GB peak), plus the frame, plus the pair
//! bookkeeping of the forks this process runs: one bit per pair of the scene on each
//! fork for the deposits it applied, and one bit per own pair for its complete pairs and
//! for each other fork they may deposit on ([`magg_fork::shard::pair_state_bytes`]),
//! about `2 F` bits per pair for `F` forks. Forks of other processes check their own
//! limit at `LoadShard`.

use anyhow::bail;
use magg_core::scene::{PatchDef, Scene};
use magg_prepare::subdivisions_of;

/// Bytes charged per element.
pub const BYTES_PER_ELEMENT: f64 = 400.0;
/// Bytes charged per patch.
pub const BYTES_PER_PATCH: f64 = 2560.0;
/// Bytes charged per pixel (linear frame, tone-mapped copy, rows in flight).
pub const BYTES_PER_PIXEL: f64 = 64.0;
/// Default limit of `--max-memory-mb`.
pub const DEFAULT_MAX_MEMORY_MB: u64 = 4096;

/// Estimated (elements, pairs, bytes) of rendering `scene` with `forks` forks in this
/// process (0: none, as with `--embedded` or `--forks-at`).
pub fn estimate(scene: &Scene, forks: u32) -> (f64, f64, f64) {
    let s = &scene.settings;
    let elements_of = |p: &PatchDef| subdivisions_of(&p.vertices, p.subdivisions, p.size_hint, s.element_size).powi(2);
    // A patch that keeps its back face apart has as many back elements as front ones.
    let faces = |p: &PatchDef| {
        let back = !s.shared_faces && scene.materials.get(p.material as usize).is_some_and(|m| m.has_back_face());
        if back {
            2.0
        } else {
            1.0
        }
    };
    let elements: f64 = scene.patches.iter().map(|p| elements_of(p) * faces(p)).sum();
    // Emitting elements are light sources too.
    let emitting = |p: &&PatchDef| scene.materials.get(p.material as usize).is_some_and(|m| m.is_emitter());
    let emitters: f64 = scene.patches.iter().filter(emitting).map(elements_of).sum();
    let pairs = elements * (scene.lights.len() as f64 + emitters);
    (elements, pairs, bytes(scene, elements, pairs, forks))
}

/// Bytes charged for `elements` elements and `pairs` pairs of `scene` with `forks` forks.
fn bytes(scene: &Scene, elements: f64, pairs: f64, forks: u32) -> f64 {
    let pixels = scene.settings.width as f64 * scene.settings.height as f64;
    let pair_bytes = pairs * 2.0 * forks as f64 / 8.0;
    let patches = scene.patches.len() as f64;
    elements * BYTES_PER_ELEMENT + patches * BYTES_PER_PATCH + pixels * BYTES_PER_PIXEL + pair_bytes
}

/// After adaptive refinement (which adds elements no estimate can foresee): refuses the
/// refined scene, `elements` elements and `pairs` pairs, when it is over `max_mb` MiB.
pub fn check_refined(scene: &Scene, elements: u64, pairs: u64, max_mb: u64, forks: u32) -> anyhow::Result<()> {
    let mb = bytes(scene, elements as f64, pairs as f64, forks) / (1u64 << 20) as f64;
    if !(mb <= max_mb as f64) {
        bail!(
            "{}: after {} levels of refinement, rendering would need about {mb:.0} MB ({elements} elements), over \
             --max-memory-mb {max_mb}; lower render.refine, raise render.refine_contrast, or raise the limit",
            scene.name,
            scene.settings.refine,
        );
    }
    Ok(())
}

/// Refuses `scene` when its estimate with `forks` forks in this process is over
/// `max_mb` MiB. A scene over its own `max_elements` is left to preprocessing, which
/// names the largest patch.
pub fn check(scene: &Scene, max_mb: u64, forks: u32) -> anyhow::Result<()> {
    let (elements, pairs, bytes) = estimate(scene, forks);
    if !(elements <= scene.settings.max_elements as f64) {
        return Ok(());
    }
    let mb = bytes / (1u64 << 20) as f64;
    if !(mb <= max_mb as f64) {
        let s = &scene.settings;
        bail!(
            "{}: rendering would need about {:.0} MB ({:.0} elements, {:.0} (light, element) pairs on {forks} forks, \
             {}x{} pixels), over --max-memory-mb {max_mb}; raise element_size, use fewer lights, lower the \
             resolution, or raise the limit",
            scene.name,
            mb.min(1e18),
            elements.min(1e18),
            pairs.min(1e18),
            s.width,
            s.height
        );
    }
    Ok(())
}
