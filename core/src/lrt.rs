//! Light ray tracing (paper §3.2): the work unit is a (light, element) pair.
//!
//! `n` primary light rays are cast from the light towards the element, stratified
//! uniformly over the element's solid angle, so each carries the same flux
//! `I * Omega / n` (Omega exact). A ray that first hits something else is discarded (the
//! occluder's own pair accounts for that light). A ray that reaches the element deposits
//! its flux there and spawns secondary rays: mirror reflection, Fresnel-weighted
//! reflection and refraction at dielectrics, and (as an extension) cosine-distributed
//! diffuse bounces carrying `rho_d` times the flux. Secondary rays deposit on every
//! element they reach, recursively, to the depth limits of the effects plan.
//!
//! When the effects plan computes direct light at VRT ([`crate::plan::EffectsPlan`]'s
//! `direct_vrt`), the primary rays of every light, point or area, deposit nothing: they
//! only start the secondary rays, and the pairs of elements that neither reflect
//! specularly nor bounce diffusely are not traced at all.
//!
//! Area lights (elements of a material with `emit`) are light sources after the point
//! lights: light index `lights + k` is emitting element k, so their pairs are numbered,
//! leased and deposited exactly like the point lights' ([`area`]).
//!
//! Every random choice is seeded from (scene seed, light, element), and a secondary
//! ray's from its place in the pair's ray trees too, so a pair re-run on another node,
//! or traced in another order (`lrt/waves.rs`), deposits exactly the same values.
//!
//! Here: the batch interface and a point light's pair (its rays sampled over the
//! element's solid angle). `area`: an emitter's pair. `landing`: what every light ray
//! does where it lands (the primary rays' tail, written once for both kinds of pair;
//! secondary rays; scattering). `waves`: a pair's secondary rays a generation at a time.
//! `bin`: raw deposits binned to leaf elements in fixed point. `result`: what a pair did.

use crate::blocks::BlockError;
use crate::geometry::{solid_angle, triangle_normal, Ray, SphericalTriangle};
use crate::lights::{intensity_towards, outside_cone};
use crate::pair::Pair;
use crate::rng::{hammersley, Rng};
use crate::scatter::offset_scale;
use crate::trace::{Bundled, TraceScratch};
use crate::view::SceneView;

mod area;
mod bin;
mod landing;
mod rays;
mod result;
mod waves;

pub use bin::{bin, bin_all};
pub use landing::MIN_RELATIVE_FLUX;
pub use result::{LrtTally, PairResult, RawDeposit, RawPair};

use bin::{binned, merged};
use landing::{land_primaries, Target};
use waves::PairTrees;

/// Traces the pair (`light`, `element`) ([`trace_pairs`] of one pair).
pub fn trace_pair(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    light: u32,
    element: u32,
) -> Result<PairResult, BlockError> {
    let mut one = trace_pairs(view, scratch, &[Pair::new(light, element)])?;
    Ok(one.pop().unwrap_or_default())
}

/// Traces a batch of (light, element) pairs: for each, what [`trace_pair`] gives, in the
/// batch's order. The leaves under the whole batch's deposits are looked up together,
/// in the order of their lattice elements: pairs of neighbouring elements deposit on
/// the same elements, whose blocks are then read once per batch, not once per pair.
pub fn trace_pairs(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    pairs: &[Pair],
) -> Result<Vec<PairResult>, BlockError> {
    let mut results = Vec::with_capacity(pairs.len());
    trace_pairs_each(view, scratch, pairs, |_, r| results.push(r))?;
    Ok(results)
}

/// [`trace_pairs`], each pair's result handed to `each` with the pair's index in the
/// batch, in the batch's order: as soon as the pair is traced when every block is
/// resident, after the whole batch through a bounded cache (whose leaves are looked up
/// together).
pub fn trace_pairs_each(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    pairs: &[Pair],
    mut each: impl FnMut(usize, PairResult),
) -> Result<(), BlockError> {
    let (mut raw, mut trees) = (Vec::new(), PairTrees::default());
    let quantum = view.header.energy_quantum;
    // With every block resident, each pair is binned on its own (its raw deposits are
    // not kept for the batch).
    let together = if view.cache_is_bounded() { pairs.len().max(1) } else { 1 };
    let mut index = 0..pairs.len();
    for group in pairs.chunks(together) {
        raw.clear();
        let mut traced = Vec::with_capacity(group.len());
        for &Pair { light, element } in group {
            let before = raw.len();
            let tally = trace_raw_into(view, scratch, &mut trees, light, element, &mut raw)?;
            traced.push((raw.len() - before, tally));
        }
        let mut leaves = binned(view, &raw)?.into_iter();
        for ((n, tally), i) in traced.into_iter().zip(index.by_ref()) {
            each(i, PairResult { deposits: merged(leaves.by_ref().take(n).collect(), quantum), tally });
        }
    }
    Ok(())
}

/// Traces the pair (`light`, `element`), its deposits raw: what [`bin`] turns into the
/// pair's result under any later refinement of the other elements.
pub fn trace_pair_raw(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    light: u32,
    element: u32,
) -> Result<RawPair, BlockError> {
    let mut deposits = Vec::new();
    let tally = trace_raw_into(view, scratch, &mut PairTrees::default(), light, element, &mut deposits)?;
    Ok(RawPair { deposits, tally })
}

/// Traces the pair (`light`, `element`) with `trees` (whatever they held before),
/// appending its raw deposits to `out`; returns its tally.
fn trace_raw_into(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    trees: &mut PairTrees,
    light: u32,
    element: u32,
    out: &mut Vec<RawDeposit>,
) -> Result<LrtTally, BlockError> {
    trees.clear(view.cache_is_bounded());
    if light as usize >= view.header.lights.len() {
        let header = &view.header;
        let emitter = (light as usize).checked_sub(header.lights.len()).and_then(|k| header.emitters.get(k)).copied();
        return match emitter {
            Some(e) => area::trace_emitter_pair(view, scratch, trees, light, e, element, out),
            None => Err(BlockError::BadId { kind: "light", id: light as u64, count: header.light_sources() as u64 }),
        };
    }
    trace_into(view, scratch, trees, light, element, out)
}

/// Traces point light `light`'s pair with `element` with `trees` (cleared): appends its
/// raw deposits to `out` (in the order of its rays, each ray's secondary rays depth
/// first) and returns its tally.
fn trace_into(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    trees: &mut PairTrees,
    light: u32,
    element: u32,
    out: &mut Vec<RawDeposit>,
) -> Result<LrtTally, BlockError> {
    let header = view.header.clone();
    let Some(l) = header.lights.get(light as usize) else {
        return Err(BlockError::BadId { kind: "point light", id: light as u64, count: header.lights.len() as u64 });
    };
    let plan = &header.plan;
    let mut tally = LrtTally::default();
    if !plan.lrt {
        return Ok(tally);
    }
    let own = view.element(element)?;
    if own.child != 0 {
        // Refinement split it: its four children have pairs of their own.
        return Ok(tally);
    }
    let material = header.materials.get(view.patch(own.patch)?.material as usize);
    if plan.skips_diffuse_pairs() && material.is_none_or(|m| !m.is_specular()) {
        // Its direct light is computed at VRT and nothing bounces on from it. (Decided
        // before its geometry is read: most pairs end here, and a refined element's
        // parents lie in blocks far from it.)
        return Ok(tally);
    }
    // The lattice element it lies in says its face; its own corners are its target.
    let (erec, prec, tri) = view.element_geometry(element, own)?;
    if !prec.receives_on(&erec, prec.v[0] - l.position) {
        // Every ray from the point light arrives on the other face of the patch, whose
        // element (front or back) has a pair of its own.
        return Ok(tally);
    }
    let omega = solid_angle(l.position, &tri);
    if !(omega > 0.0) || outside_cone(l, &tri) {
        return Ok(tally);
    }
    let normal = triangle_normal(&prec.v);
    let (n, fan) = rays_for(view, plan, material, own)?;
    let seed = header.settings.seed;
    let mut rng = Rng::from_words(&[seed, 0x4c5254, light as u64, element as u64]);
    let (sx, sy) = (rng.next_f64(), rng.next_f64());
    let (bx, by) = (rng.next_f64(), rng.next_f64());
    let per_ray = omega / n as f64;
    let eps0 = offset_scale(l.position);
    // Every ray of the pair leaves the light towards the same element.
    let Some(seen) = SphericalTriangle::new(l.position, &tri) else {
        return Ok(tally);
    };
    // The pair's light rays, each with an occlusion query up to (just short of) the
    // element; all leave the light, so the queries walk the BVH in packets.
    trees.shots.clear();
    trees.bundle.clear();
    for k in 0..n {
        let (u0, u1) = hammersley(k, n, sx, sy);
        let Some(w) = seen.sample(u0, u1) else {
            continue;
        };
        let flux = intensity_towards(l, w).scale(per_ray);
        if flux.is_black() {
            continue;
        }
        view.counters.light_rays += 1;
        // Distance to the element's plane along w.
        let denom = normal.dot(w);
        let t_plane = normal.dot(prec.v[0] - l.position) / denom;
        if !(t_plane > 0.0) || !t_plane.is_finite() {
            continue;
        }
        trees.shots.push((k, flux, t_plane));
        let ray = Ray::new(l.position, w);
        trees.bundle.push(Bundled { ray, tmin: eps0, tmax: t_plane * (1.0 - 1e-9), exclude: erec.patch });
    }
    let target = Target { light, element, erec, prec, normal, material, fan, offset: (bx, by) };
    land_primaries(view, scratch, trees, &mut tally, &target, out)?;
    trees.trace(view, scratch, &mut tally, out)?;
    Ok(tally)
}

/// Light rays of a pair (a point light's or an emitter's) whose target is element record
/// `own` (of `material`), and the diffuse bounce rays each sends: the scene's
/// `light_rays` with one bounce each, except for a pair traced only for the diffuse
/// bounces its rays start (direct light at VRT, a target that neither mirrors nor
/// transmits).
///
/// Such a pair sends `light_rays` bounce rays, a quarter as many for each level of
/// refinement that made its element (at least one): the bounce is sent from as many
/// rays per unit area as before the split, for the same noise, not four times as many
/// per level (refinement sharpens where light lands, not where bounced light leaves
/// from). Its light rays only find where on the element the light arrives, which varies
/// little across one element, so each sends `bounce_rays` of them: it casts that many
/// times fewer light rays for the same bounce rays (docs/ACCURACY.md measures it).
pub(crate) fn rays_for(
    view: &mut SceneView,
    plan: &crate::plan::EffectsPlan,
    material: Option<&crate::scene::Material>,
    own: crate::blocks::ElementRecord,
) -> Result<(u32, u32), BlockError> {
    let settings = &view.header.settings;
    let (n, fan) = (settings.light_rays.max(1), settings.bounce_rays);
    let bounce_only = !plan.deposits_direct() && material.is_none_or(|m| !m.is_specular());
    if !bounce_only {
        return Ok((n, 1));
    }
    let bounces = match own.parent() {
        None => n,
        Some(_) => (n >> (2 * view.element_depth(own)?).min(31)).max(1),
    };
    // (A pair with no bounce to send was not traced: `EffectsPlan::skips_diffuse_pairs`.)
    Ok(crate::plan::bounce_split(bounces, fan))
}
