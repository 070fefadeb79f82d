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
//! `direct_vrt`), the primary rays deposit nothing: they only start the secondary rays,
//! and the pairs of elements that neither reflect specularly nor bounce diffusely are not
//! traced at all.
//!
//! Area lights (elements of a material with `emit`) are light sources after the point
//! lights: light index `lights + k` is emitting element k, so their pairs are numbered,
//! leased and deposited exactly like the point lights' ([`area`]).
//!
//! Every random choice is seeded from (scene seed, light, element), and a secondary
//! ray's from its place in the pair's ray trees too, so a pair re-run on another node,
//! or traced in another order (`lrt/waves.rs`), deposits exactly the same values.

use crate::blocks::BlockError;
use crate::color::Rgb;
use crate::energy::{to_fixed, Fixed};
use crate::geometry::{cosine_hemisphere, solid_angle, triangle_normal, Ray, SphericalTriangle};
use crate::rng::{halton35, hammersley, Rng};
use crate::scatter::{arrive, offset_scale, Arrival, Dielectric};
use crate::scene::Light;
use crate::subdivision::locate;
use crate::trace::{cast, occluded_all, Bundled, TraceScratch};
use crate::view::{element_block, SceneView, NO_BLOCK};
use glam::DVec3;

mod area;
mod rays;
mod waves;

use rays::{Branch, RayId};
use waves::PairTrees;

/// Secondary rays whose flux falls below this fraction of their primary ray's flux are
/// cut off (and counted as such in the tally).
pub const MIN_RELATIVE_FLUX: f64 = 1e-6;

/// Where the flux of a pair went. All fields in W per channel.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct LrtTally {
    /// Flux of primary rays that reached their element (`I * Omega` when unoccluded).
    pub reached: Rgb,
    /// Flux of primary rays blocked before their element.
    pub occluded: Rgb,
    /// Absorbed at surfaces (`1 - diffuse - mirror - transmit`).
    pub absorbed: Rgb,
    /// Diffusely reflected but not followed (no diffuse bounce left): the paper's end of
    /// a light path, shown in VRT through the element's energy.
    pub diffuse_end: Rgb,
    /// Carried by secondary rays that left the scene.
    pub escaped: Rgb,
    /// Carried by rays stopped by a depth limit or the minimum-flux cut.
    pub cut: Rgb,
}

impl LrtTally {
    /// Sum of two tallies.
    pub fn add(self, o: LrtTally) -> LrtTally {
        LrtTally {
            reached: self.reached.add(o.reached),
            occluded: self.occluded.add(o.occluded),
            absorbed: self.absorbed.add(o.absorbed),
            diffuse_end: self.diffuse_end.add(o.diffuse_end),
            escaped: self.escaped.add(o.escaped),
            cut: self.cut.add(o.cut),
        }
    }
}

/// The deposits and tally of one pair.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PairResult {
    /// (element id, flux) sorted by element id, one entry per element.
    pub deposits: Vec<(u32, Fixed)>,
    /// Where the flux went.
    pub tally: LrtTally,
}

/// A deposit as a pair's rays make it, before refinement's leaves are looked up: on an
/// element itself (the pair's own target), or at local coordinates `w` within a lattice
/// element, which refinement may have split (the leaf under `w` takes it). A pair's raw
/// deposits stay the same while other elements are split, so refinement's pilot passes
/// trace a pair once and bin its deposits again at each level ([`bin`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RawDeposit {
    /// On this element.
    On(u32, Rgb),
    /// On the leaf under local coordinates `w` of lattice element `element`.
    Under {
        /// The lattice element (on the face the ray arrived at).
        element: u32,
        /// Local (barycentric) coordinates within it.
        w: [f64; 3],
        /// The flux.
        flux: Rgb,
    },
}

/// A pair's raw deposits, in the order its rays made them, and its tally.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RawPair {
    /// The deposits, in generation order.
    pub deposits: Vec<RawDeposit>,
    /// Where the flux went.
    pub tally: LrtTally,
}

/// A pair's deposits binned to leaf elements, in their order. Through a bounded cache
/// the leaves are looked up in the order of their lattice elements, a level of
/// refinement at a time, so that each element block the lookups read is read once a
/// level, fetched ahead with the level's others, however the pair's rays spread their
/// deposits.
fn binned(view: &mut SceneView, raw: &[RawDeposit]) -> Result<Vec<(u32, Rgb)>, BlockError> {
    let leaf = |view: &mut SceneView, d: &RawDeposit| match *d {
        RawDeposit::On(e, f) => Ok((e, f)),
        RawDeposit::Under { element, w, flux } => Ok((leaf_under(view, element, w)?, flux)),
    };
    if view.header.settings.refine == 0 || !view.cache_is_bounded() {
        // Every lattice element is a leaf (nothing to look up), or every block is at
        // hand (the order of the lookups costs nothing).
        return raw.iter().map(|d| leaf(view, d)).collect();
    }
    let mut deposits = vec![(0, Rgb::BLACK); raw.len()];
    // (lattice element, deposit index) as one key, with the deposit's coordinates.
    let mut under: Vec<(u64, [f64; 3])> = Vec::with_capacity(raw.len());
    for (i, d) in raw.iter().enumerate() {
        match *d {
            RawDeposit::On(e, f) => deposits[i] = (e, f),
            RawDeposit::Under { element, w, flux } => {
                deposits[i].1 = flux;
                under.push(((element as u64) << 32 | i as u64, w));
            }
        }
    }
    under.sort_unstable_by_key(|u| u.0);
    // The leaves under the deposits a level of refinement at a time, each level's
    // blocks fetched ahead (SceneView::leaf_elements).
    let points: Vec<(u32, [f64; 3])> = under.iter().map(|&(k, w)| ((k >> 32) as u32, w)).collect();
    let mut leaves = Vec::with_capacity(points.len());
    view.leaf_elements(&points, &mut leaves)?;
    for (&(k, _), &(leaf, _, _)) in under.iter().zip(&leaves) {
        deposits[k as u32 as usize].0 = leaf;
    }
    Ok(deposits)
}

/// The leaf element under local coordinates `w` of lattice element `element`.
fn leaf_under(view: &mut SceneView, element: u32, w: [f64; 3]) -> Result<u32, BlockError> {
    if view.header.settings.refine == 0 {
        return Ok(element);
    }
    // Refinement may have split it: the deposit goes to the leaf under the hit.
    let rec = view.element(element)?;
    Ok(view.leaf_element(element, rec, w)?.0)
}

/// Radiant intensity of `light` in unit direction `w`.
pub fn intensity_towards(light: &Light, w: DVec3) -> Rgb {
    match &light.spot {
        None => light.intensity,
        Some(s) => {
            let angle = w.dot(s.direction).clamp(-1.0, 1.0).acos().to_degrees();
            let f = if angle <= s.half_angle_deg {
                1.0
            } else if s.falloff_deg > 0.0 && angle < s.half_angle_deg + s.falloff_deg {
                let x = 1.0 - (angle - s.half_angle_deg) / s.falloff_deg;
                x * x * (3.0 - 2.0 * x)
            } else {
                0.0
            };
            light.intensity.scale(f)
        }
    }
}

/// True when no direction from `light` towards triangle `tri` can carry light (outside
/// a spot cone, with a margin for the triangle's angular size).
fn outside_cone(light: &Light, tri: &[DVec3; 3]) -> bool {
    let Some(s) = &light.spot else { return false };
    let c = (tri[0] + tri[1] + tri[2]) / 3.0 - light.position;
    let dist = c.length();
    if dist == 0.0 {
        return false;
    }
    let radius = tri.iter().map(|v| (*v - (tri[0] + tri[1] + tri[2]) / 3.0).length()).fold(0.0, f64::max);
    if radius >= dist {
        return false;
    }
    let spread = (radius / dist).asin().to_degrees();
    let angle = (c / dist).dot(s.direction).clamp(-1.0, 1.0).acos().to_degrees();
    angle - spread > s.half_angle_deg + s.falloff_deg
}

/// A secondary light ray waiting to be followed.
struct Pending {
    ray: Ray,
    flux: Rgb,
    from_patch: u32,
    specular: u32,
    diffuse: u32,
    floor: f64,
    /// How it left the surface that spawned it.
    branch: Branch,
    /// Who it is in its pair.
    id: RayId,
}

/// Traces the pair (`light`, `element`) ([`trace_pairs`] of one pair).
pub fn trace_pair(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    light: u32,
    element: u32,
) -> Result<PairResult, BlockError> {
    let mut one = trace_pairs(view, scratch, &[(light, element)])?;
    Ok(one.pop().unwrap_or_default())
}

/// Traces a batch of (light, element) pairs: for each, what [`trace_pair`] gives, in the
/// batch's order. The leaves under the whole batch's deposits are looked up together,
/// in the order of their lattice elements: pairs of neighbouring elements deposit on
/// the same elements, whose blocks are then read once per batch, not once per pair.
pub fn trace_pairs(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    pairs: &[(u32, u32)],
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
    pairs: &[(u32, u32)],
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
        for &(light, element) in group {
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

/// [`trace_pairs_each`], where the pairs of `kept` (refinement's pilot pairs, see
/// [`crate::kept::KeptPairs`]) are binned from their kept deposits rather than traced:
/// the same results, handed to `each` in the batch's order.
pub fn trace_pairs_kept(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    pairs: &[(u32, u32)],
    kept: Option<&crate::kept::KeptPairs>,
    mut each: impl FnMut(usize, PairResult),
) -> Result<(), BlockError> {
    let Some(kept) = kept else {
        return trace_pairs_each(view, scratch, pairs, each);
    };
    let raws: Vec<Option<std::sync::Arc<RawPair>>> =
        pairs.iter().map(|&(light, element)| kept.raw(light, element)).collect();
    let mut kept_results = bin_all(view, pairs, &raws)?.into_iter();
    // Runs of pairs not kept are traced together (as trace_pairs_each would).
    let mut run = 0;
    for i in 0..=pairs.len() {
        let binned = kept_results.next().flatten();
        if binned.is_some() || i == pairs.len() {
            trace_pairs_each(view, scratch, &pairs[run..i], |k, r| each(run + k, r))?;
            run = i + 1;
        }
        if let Some(r) = binned {
            each(i, r);
        }
    }
    Ok(())
}

/// Whether refinement split the element of each of `pairs` that `wanted` names (a kept
/// pair's element split since its pilot: the pair then deposits nothing, as [`bin`]
/// says); false for the others. The elements' records are read first, a run of blocks
/// fetched ahead at a time, rather than one at a time between binnings.
fn split_elements(
    view: &mut SceneView,
    pairs: &[(u32, u32)],
    wanted: impl Fn(usize) -> bool,
) -> Result<Vec<bool>, BlockError> {
    let header = view.header.clone();
    let mut split = vec![false; pairs.len()];
    view.in_prefetched_runs(
        &mut split,
        pairs.len(),
        |_, i| [if wanted(i) { element_block(&header, pairs[i].1) } else { NO_BLOCK }, NO_BLOCK, NO_BLOCK],
        |view, split, i| {
            if wanted(i) {
                split[i] = view.element(pairs[i].1)?.child != 0;
            }
            Ok(())
        },
    )?;
    Ok(split)
}

/// [`bin`] of each of `raws` (the raw deposits of `pairs[i]`, `None` for a pair that has
/// none: its answer is `None` too). The same results, but the elements' records are read
/// first and the leaves under all the pairs' deposits are looked up together (through a
/// bounded cache a level of refinement at a time, each level's blocks fetched ahead), not
/// pair by pair.
pub fn bin_all(
    view: &mut SceneView,
    pairs: &[(u32, u32)],
    raws: &[Option<std::sync::Arc<RawPair>>],
) -> Result<Vec<Option<PairResult>>, BlockError> {
    let split = split_elements(view, pairs, |i| raws[i].is_some())?;
    let mut all = Vec::new();
    for (raw, &split) in raws.iter().zip(&split) {
        if let Some(raw) = raw.as_deref().filter(|_| !split) {
            all.extend_from_slice(&raw.deposits);
        }
    }
    let mut leaves = binned(view, &all)?.into_iter();
    let quantum = view.header.energy_quantum;
    Ok(raws
        .iter()
        .zip(split)
        .map(|(raw, split)| {
            raw.as_deref().map(|raw| match split {
                true => PairResult::default(),
                false => PairResult {
                    deposits: merged(leaves.by_ref().take(raw.deposits.len()).collect(), quantum),
                    tally: raw.tally,
                },
            })
        })
        .collect())
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

/// The result of pair (`_`, `element`) from its raw deposits, binned to the leaves of
/// `view`'s elements: exactly what [`trace_pair`] returns on `view`'s scene, as long as
/// the pair's rays are the same (its element is a leaf there, as when it was traced).
pub fn bin(view: &mut SceneView, element: u32, raw: &RawPair) -> Result<PairResult, BlockError> {
    if view.element(element)?.child != 0 {
        return Ok(PairResult::default());
    }
    bin_leaf(view, raw)
}

/// [`bin`] of a pair whose element is known to be a leaf of `view`'s elements.
fn bin_leaf(view: &mut SceneView, raw: &RawPair) -> Result<PairResult, BlockError> {
    let deposits = binned(view, &raw.deposits)?;
    Ok(PairResult { deposits: merged(deposits, view.header.energy_quantum), tally: raw.tally })
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
    // Every ray from the point light reaches the element's plane from the same side.
    let on_back = material.is_some_and(|m| m.refuses(prec.v[0] - l.position, normal));
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

    // The pair's light rays first: all leave the light, so their occlusion queries walk
    // the BVH in packets (`occluded_all`); then each ray in order, as before.
    let (mut shots, mut bundle, mut occluded) =
        (std::mem::take(&mut trees.shots), std::mem::take(&mut trees.bundle), std::mem::take(&mut trees.occluded));
    shots.clear();
    bundle.clear();
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
        // An occlusion query up to (just short of) the element; secondary rays below are
        // nearest-hit queries. Both go through the scene's acceleration structure.
        let ray = Ray::new(l.position, w);
        shots.push((k, flux, t_plane));
        bundle.push(Bundled { ray, tmin: eps0, tmax: t_plane * (1.0 - 1e-9), exclude: erec.patch });
    }
    let answered = occluded_all(view, scratch, &bundle, &mut occluded);
    let traced = answered.and_then(|()| {
        for ((&(k, flux, t_plane), b), &blocked) in shots.iter().zip(&bundle).zip(&occluded) {
            if blocked {
                tally.occluded = tally.occluded.add(flux);
                continue;
            }
            tally.reached = tally.reached.add(flux);
            if on_back {
                // The back of a one-sided patch: absorbed, nothing deposited or reflected.
                tally.absorbed = tally.absorbed.add(flux);
                continue;
            }
            let (ray, w) = (b.ray, b.ray.direction);
            let p = ray.at(t_plane);
            let floor = flux.max_channel() * MIN_RELATIVE_FLUX;
            // Shading normals bend specular directions and a texture colours what bounces
            // diffusely (deposits are flux, taken on the geometric surface).
            let (at, albedo) = arrive(view, &prec, p, w, normal, None)?;
            let bounce = Some(Strata { first: k * fan, count: fan, offset: (bx, by) });
            let s = Surface { at, albedo, material: prec.material, patch: erec.patch };
            let id = RayId::primary(seed, light, element, k);
            scatter(view, id, &mut trees.spawned, &mut tally, s, bounce, flux, 0, 0, floor);
            let deposit = plan.deposits_direct(false).then_some(RawDeposit::On(element, flux));
            trees.root(view, scratch, &mut tally, deposit, out)?;
        }
        Ok(())
    });
    (trees.shots, trees.bundle, trees.occluded) = (shots, bundle, occluded);
    traced?;
    trees.trace(view, scratch, &mut tally, out)?;
    Ok(tally)
}

/// Light rays of a point light's pair whose target is element record `own` (of
/// `material`), and the diffuse bounce rays each sends: the scene's `light_rays` with
/// one bounce each, except for a pair traced only for the diffuse bounces its rays
/// start (direct light at VRT, a target that neither mirrors nor transmits).
///
/// Such a pair sends `light_rays` bounce rays, a quarter as many for each level of
/// refinement that made its element (at least one): the bounce is sent from as many
/// rays per unit area as before the split, for the same noise, not four times as many
/// per level (refinement sharpens where light lands, not where bounced light leaves
/// from). Its light rays only find where on the element the light arrives, which varies
/// little across one element, so each sends `bounce_rays` of them: it casts that many
/// times fewer light rays for the same bounce rays (docs/ACCURACY.md measures it).
fn rays_for(
    view: &mut SceneView,
    plan: &crate::plan::EffectsPlan,
    material: Option<&crate::scene::Material>,
    own: crate::blocks::ElementRecord,
) -> Result<(u32, u32), BlockError> {
    let settings = &view.header.settings;
    let (n, fan) = (settings.light_rays.max(1), settings.bounce_rays);
    let bounce_only = !plan.deposits_direct(false) && material.is_none_or(|m| !m.is_specular());
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

/// Follows secondary ray `s`: returns what it deposits where it arrives (raw: under the
/// lattice element it reached), and pushes the rays it spawns there onto `spawned`.
fn follow_one(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    spawned: &mut Vec<Pending>,
    tally: &mut LrtTally,
    s: &Pending,
) -> Result<Option<RawDeposit>, BlockError> {
    view.counters.light_rays += 1;
    let tmin = offset_scale(s.ray.origin);
    let Some(hit) = cast(view, scratch, &s.ray, tmin, f64::INFINITY, s.from_patch, false)? else {
        tally.escaped = tally.escaped.add(s.flux);
        return Ok(None);
    };
    let hp = view.patch(hit.patch)?;
    let hn = triangle_normal(&hp.v);
    if view.header.materials.get(hp.material as usize).is_some_and(|m| m.refuses(s.ray.direction, hn)) {
        tally.absorbed = tally.absorbed.add(s.flux);
        return Ok(None);
    }
    let (local, w) = locate(hp.subdivisions, hit.bary);
    let deposit = RawDeposit::Under { element: hp.element_on_face(local, s.ray.direction), w, flux: s.flux };
    let (at, albedo) = arrive(view, &hp, s.ray.at(hit.t), s.ray.direction, hn, Some(hit.bary))?;
    let surface = Surface { at, albedo, material: hp.material, patch: hit.patch };
    scatter(view, s.id, spawned, tally, surface, None, s.flux, s.specular, s.diffuse, s.floor);
    Ok(Some(deposit))
}

/// One entry per element, sorted by element, each summed in generation order
/// (deterministic), in fixed point. (The order is that of a stable sort by element,
/// found by sorting the deposits' (element, index) keys, 8 bytes each, rather than
/// moving the 32-byte deposits themselves.)
fn merged(deposits: Vec<(u32, Rgb)>, quantum: f64) -> Vec<(u32, Fixed)> {
    let mut keys: Vec<u64> = deposits.iter().enumerate().map(|(i, d)| (d.0 as u64) << 32 | i as u64).collect();
    keys.sort_unstable();
    let mut merged: Vec<(u32, Rgb)> = Vec::new();
    for k in keys {
        let (e, f) = deposits[(k & 0xffff_ffff) as usize];
        match merged.last_mut() {
            Some(last) if last.0 == e => last.1 = last.1.add(f),
            _ => merged.push((e, f)),
        }
    }
    merged.into_iter().map(|(e, f)| (e, to_fixed(f, quantum))).collect()
}

/// Where a light ray arrived: the point and its frame, the texture's albedo there, the
/// patch and its material.
struct Surface {
    at: Arrival,
    albedo: Rgb,
    material: u32,
    patch: u32,
}

/// Stratified samples of the diffuse bounce's direction for one primary light ray:
/// `count` points of the pair's Halton (3, 5) sequence from index `first`, shifted by
/// `offset` (Cranley-Patterson rotation), each sending an equal share of the flux.
#[derive(Clone, Copy, Debug)]
struct Strata {
    first: u32,
    count: u32,
    offset: (f64, f64),
}

/// Splits the flux arriving at a surface point into absorbed, diffusely ended and
/// secondary rays, per the material and the effects plan. `bounce` holds the stratified
/// samples of the diffuse bounce's directions for a pair's primary ray (its rays bounce
/// in directions spread evenly over the hemisphere, so the light they carry on lands as
/// evenly), among which the diffuse flux is shared; deeper bounces draw one direction
/// from the generator of `from`, the ray that arrived.
#[allow(clippy::too_many_arguments)]
fn scatter(
    view: &SceneView,
    from: RayId,
    stack: &mut Vec<Pending>,
    tally: &mut LrtTally,
    surface: Surface,
    bounce: Option<Strata>,
    flux: Rgb,
    specular: u32,
    diffuse: u32,
    floor: f64,
) {
    let Surface { at, albedo, material, patch } = surface;
    let header = &view.header;
    let plan = &header.plan;
    let Some(m) = header.materials.get(material as usize) else {
        tally.absorbed = tally.absorbed.add(flux);
        return;
    };
    // A texture scales the diffuse part; what it takes away is absorbed.
    let rho = m.diffuse.mul(albedo);
    let absorbed = Rgb([
        (1.0 - rho.0[0] - m.mirror.0[0] - m.transmit.0[0]).max(0.0),
        (1.0 - rho.0[1] - m.mirror.0[1] - m.transmit.0[1]).max(0.0),
        (1.0 - rho.0[2] - m.mirror.0[2] - m.transmit.0[2]).max(0.0),
    ]);
    tally.absorbed = tally.absorbed.add(flux.mul(absorbed));

    let (base, mut path) = (stack.len(), None);
    let mut push = |tally: &mut LrtTally, branch: Branch, dir: DVec3, f: Rgb, spec: u32, diff: u32| {
        if f.is_black() {
            return;
        }
        if f.max_channel() < floor {
            tally.cut = tally.cut.add(f);
            return;
        }
        let path = *path.get_or_insert_with(|| from.path());
        let (ray, id) = (at.spawn(dir), from.child(path, stack.len() - base));
        stack.push(Pending { ray, flux: f, from_patch: patch, specular: spec, diffuse: diff, floor, branch, id });
    };

    // Specular parts.
    let spec_flux_mirror = flux.mul(m.mirror);
    let spec_flux_transmit = flux.mul(m.transmit);
    if specular < plan.lrt_depth {
        if !spec_flux_mirror.is_black() {
            push(tally, Branch::Mirror, at.reflected(), spec_flux_mirror, specular + 1, diffuse);
        }
        if !spec_flux_transmit.is_black() {
            match at.dielectric(m.ior, plan.refraction) {
                Dielectric::Split { fresnel, refracted } => {
                    let (reflected, through) =
                        (spec_flux_transmit.scale(fresnel), spec_flux_transmit.scale(1.0 - fresnel));
                    push(tally, Branch::Reflected, at.reflected(), reflected, specular + 1, diffuse);
                    push(tally, Branch::Refracted, refracted, through, specular + 1, diffuse);
                }
                Dielectric::Reflected => {
                    push(tally, Branch::Reflected, at.reflected(), spec_flux_transmit, specular + 1, diffuse)
                }
            }
        }
    } else {
        tally.cut = tally.cut.add(spec_flux_mirror).add(spec_flux_transmit);
    }

    // Diffuse part.
    let diff_flux = flux.mul(rho);
    if diff_flux.is_black() {
        return;
    }
    if diffuse < plan.diffuse_bounces {
        match bounce {
            Some(Strata { first, count, offset: (bx, by) }) => {
                // (One share of one is the whole flux, exactly: x * 1.0 == x.)
                let share = diff_flux.scale(1.0 / count as f64);
                for j in 0..count {
                    let (u0, u1) = halton35(first + j, bx, by);
                    push(tally, Branch::Diffuse, cosine_hemisphere(at.normal, u0, u1), share, specular, diffuse + 1);
                }
            }
            None => {
                let mut rng = from.rng();
                let (u0, u1) = (rng.next_f64(), rng.next_f64());
                push(tally, Branch::Diffuse, cosine_hemisphere(at.normal, u0, u1), diff_flux, specular, diffuse + 1);
            }
        }
    } else {
        tally.diffuse_end = tally.diffuse_end.add(diff_flux);
    }
}

/// Pair id of (light, element): pairs are numbered light-major (the point lights, then
/// the emitting elements, [`crate::header::SceneHeader::light_sources`]).
pub fn pair_id(light: u32, element: u32, elements: u32) -> u64 {
    light as u64 * elements as u64 + element as u64
}
