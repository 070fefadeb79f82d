//! Adaptive element refinement (Heckbert 1990, "Adaptive radiosity textures for
//! bidirectional ray tracing", the paper's ref. [11]): where the light on neighbouring
//! elements differs sharply (a shadow's or a caustic's edge, light reflected by a mirror),
//! one element of blur is too much, so those elements are split in four on their patch's
//! lattice and the light pass is run on the finer elements.
//!
//! [`prepare_with`] does it as part of preprocessing: it prepares the scene, runs a pilot
//! light pass with the light that makes edges (direct light and light via mirrors and
//! glass; diffuse bounces are smooth) on the machine its [`Pilots`] name (this process's
//! cores for [`prepare`]; a cluster's nodes for `magg-host`, each level a scene of the
//! cluster's own: the same energies, bit for bit), chooses the elements to split
//! ([`choose`]), prepares the scene again with them split, and repeats up to
//! `[render] refine` times. A pilot traces each pair once: refinement splits diffuse
//! elements and leaves every other element, and so every pair's rays, as they were, so
//! a pair's deposits are kept raw (where in which lattice element) and binned again to
//! the leaves at each level ([`KeptPairs`]); only the new elements' pairs are traced.
//! The result is an ordinary prepared scene whose split elements are elements like any
//! other: they get owners, pairs and vertex-energy blocks, so the final render runs
//! unchanged in the embedded renderer and in the cluster, the same bits in every shape.
//!
//! Where the render's light pass carries exactly the pilots' light (no diffuse bounce,
//! the same effects plan), its pairs are the last pilot's and those of the elements the
//! last level split: the pilots' raw pairs are then kept with the prepared scene
//! ([`KeptPairs`], [`magg_core::stats::Refinement::kept`]), and the light pass bins them
//! instead of tracing them again ([`magg_core::kept::trace_pairs_kept`]): in the embedded
//! renderer and on the cluster's nodes of the host's process all of them, on a node of
//! a process of its own those it traced itself; the others are traced. The result is
//! the same, bit for bit, as tracing every pair.
//!
//! ```
//! use magg_core::{plan::EffectsPlan, scene};
//! use magg_prepare::refine;
//! let text = include_str!("../../scenes/magg-paper.toml");
//! let read = |p: &std::path::Path| std::fs::read(p);
//! let mut scene = scene::parse_scene_str("magg-paper.toml", text, "scenes".as_ref(), &read).unwrap();
//! scene.settings.refine = 1;
//! let prepared = refine::prepare(&scene, EffectsPlan::for_scene(&scene)).unwrap();
//! // One level at most: the elements split, if any, are listed.
//! assert!(prepared.splits.len() <= 1);
//! assert_eq!(prepared.elements.len(), 1664 + 4 * prepared.splits.iter().map(Vec::len).sum::<usize>());
//! ```

use crate::{prepare_split_on, LocalShareSet, ShareSet, Shares};
use magg_core::color::Rgb;
use magg_core::energy::{element_irradiance, interpolate};
use magg_core::fixed::Fixed;
use magg_core::kept::{KeptPairs, KeptSlot};
use magg_core::machine::{LightPass, RenderError};
use magg_core::pair::Pair;
use magg_core::plan::EffectsPlan;
use magg_core::prepared::PreparedScene;
use magg_core::progress::{NoProgress, Progress, Renamed};
use magg_core::render::{EmbeddedMachine, RenderOptions};
use magg_core::scene::{Scene, MAX_REFINE_LEVELS};
use magg_core::stats::Refinement;
use magg_core::trace::TraceScratch;
use magg_core::view::SceneView;
use std::sync::Arc;
use std::time::Instant;

/// Where refinement's pilot light passes run: this process's cores ([`EmbeddedPilots`],
/// what [`prepare`] uses), or a cluster's nodes (the host's, which runs each level as a
/// session of the cluster). Wherever they run, a level's energies are the same bits.
pub trait Pilots {
    /// The light pass of one pilot level on `pilot` (the scene prepared with the pilots'
    /// plan and the splits so far), its point lights' pairs traced through `pairs`
    /// ([`KeptPairs::trace`]: each traced once over the levels).
    /// `progress` hears of the pass (as a stage of its own).
    fn light_pass(
        &mut self,
        pilot: &Arc<PreparedScene>,
        pairs: &Arc<KeptPairs>,
        progress: &dyn Progress,
    ) -> Result<LightPass, RenderError>;

    /// Where they run, for the stats: `embedded` or `nodes`.
    fn place(&self) -> &'static str;

    /// How many nodes traced pairs of the last level (the embedded machine's threads).
    fn nodes(&self) -> u32;
}

/// Pilots on this process's cores: the embedded machine with its default options.
#[derive(Clone, Copy, Debug, Default)]
pub struct EmbeddedPilots;

impl Pilots for EmbeddedPilots {
    fn light_pass(
        &mut self,
        pilot: &Arc<PreparedScene>,
        pairs: &Arc<KeptPairs>,
        progress: &dyn Progress,
    ) -> Result<LightPass, RenderError> {
        let trace = |view: &mut SceneView, scratch: &mut TraceScratch, batch: &[Pair]| {
            let mut results = Vec::with_capacity(batch.len());
            pairs.trace_each(view, scratch, batch, |_, r| results.push(r))?;
            Ok(results)
        };
        EmbeddedMachine::new(pilot, &RenderOptions::default()).light_pass_with(&trace, progress)
    }

    fn place(&self) -> &'static str {
        "embedded"
    }

    fn nodes(&self) -> u32 {
        RenderOptions::default().node_count()
    }
}

/// Prepares `scene` with `plan`, refined `scene.settings.refine` times with pilots on
/// this process's cores (see the module doc); preprocessing time includes the pilot
/// passes.
pub fn prepare(scene: &Scene, plan: EffectsPlan) -> Result<PreparedScene, RenderError> {
    prepare_with(scene, plan, &mut EmbeddedPilots, &NoProgress, Shares::default(), &mut LocalShareSet::default())
}

/// [`prepare`] with the pilot light passes run by `pilots`, each level prepared in
/// `shares` by `set`; `progress` hears of each (level `k` of `n` as the stage
/// "refinement k/n").
pub fn prepare_with(
    scene: &Scene,
    plan: EffectsPlan,
    pilots: &mut dyn Pilots,
    progress: &dyn Progress,
    shares: Shares,
    set: &mut dyn ShareSet,
) -> Result<PreparedScene, RenderError> {
    let start = Instant::now();
    let mut splits: Vec<Vec<u32>> = Vec::new();
    let mut kept = None;
    let mut figures = Refinement::default();
    // Attempts past the first of every preparation (a fork lost during one).
    let mut retries = 0;
    if scene.settings.refine > 0 {
        // The pilot carries the light that makes edges: direct light from the lights and
        // light via mirrors and glass. Diffuse interreflection is smooth (and noisy in a
        // pilot's few rays), so it takes no part in the choice.
        let mut pilot_scene = scene.clone();
        pilot_scene.settings.diffuse_bounces = 0;
        let pilot_plan = EffectsPlan::for_scene(&pilot_scene);
        let pairs = Arc::new(KeptPairs::default());
        // The render's light pass carries the pilots' light when the scene has no
        // diffuse bounce to drop and the plan is the pilots'.
        let keep = scene.settings.diffuse_bounces == 0 && plan == pilot_plan;
        let levels = scene.settings.refine.min(MAX_REFINE_LEVELS);
        for level in 1..=levels {
            let pilot = Arc::new(prepare_split_on(&pilot_scene, pilot_plan.clone(), &splits, shares, set)?);
            retries += pilot.preparation.attempts.saturating_sub(1);
            if !pilot.header.plan.lrt {
                break;
            }
            let t = Instant::now();
            let shown = Renamed { inner: progress, stage: format!("refinement {level}/{levels}") };
            let light = pilots.light_pass(&pilot, &pairs, &shown)?;
            figures.levels += 1;
            figures.pilot_pairs += light.pairs;
            figures.pilot_s += t.elapsed().as_secs_f64();
            figures.pilot_nodes = figures.pilot_nodes.max(pilots.nodes());
            let room = scene.settings.max_elements.saturating_sub(pilot.elements.len() as u64) / 4;
            let split = choose(scene, &pilot, &light.element_flux, room as usize);
            if split.is_empty() {
                break;
            }
            figures.split += split.len() as u64;
            splits.push(split);
        }
        figures.pilots_on = pilots.place().to_string();
        figures.kept = keep;
        if keep {
            kept = Some(pairs);
        }
    }
    let mut prepared = prepare_split_on(scene, plan, &splits, shares, set)?;
    prepared.preprocess_s = start.elapsed().as_secs_f64();
    prepared.kept_pairs = KeptSlot::new(kept.filter(|k| !k.is_empty()));
    prepared.refinement = figures;
    prepared.preparation.attempts += retries;
    Ok(prepared)
}

/// Luminance-like weight of a colour (the channels' mean: no channel is preferred).
fn level(c: Rgb) -> f64 {
    (c.0[0] + c.0[1] + c.0[2]) / 3.0
}

/// The leaf elements to split, ascending, at most `room` of them: those of a diffuse
/// (shown) material, not emitting, where the interpolated irradiance of two of their
/// corners differs by more than `refine_contrast` of its sum (there the linear
/// interpolation across the element misses what the pilot saw), the sharpest first when
/// there are more than `room`. Corners, rather than the elements themselves, are
/// compared because each averages the elements around it: a pilot's noise moves them
/// less than an edge does. A floor of 1e-3 of the mean irradiance keeps noise in the
/// dark from counting as an edge.
pub fn choose(scene: &Scene, prepared: &PreparedScene, flux: &[Fixed], room: usize) -> Vec<u32> {
    let elements = &prepared.elements;
    let quantum = prepared.header.energy_quantum;
    let e: Vec<f64> = element_irradiance(elements, flux, quantum).into_iter().map(level).collect();
    let leaves: Vec<usize> = (0..elements.len()).filter(|&i| elements[i].is_leaf()).collect();
    if leaves.is_empty() {
        return Vec::new();
    }
    let mean = leaves.iter().map(|&i| e[i]).sum::<f64>() / leaves.len() as f64;
    let floor = 1e-3 * mean;
    if !(mean > 0.0) {
        return Vec::new();
    }
    // The interpolated irradiance at the vertices: each averages the elements around it,
    // so a pilot's noise counts for less than an edge, which moves the vertices on its
    // two sides apart.
    let vertex: Vec<f64> = interpolate(elements, &prepared.t_junctions, flux, prepared.vertex_positions.len(), quantum)
        .into_iter()
        .map(level)
        .collect();
    let shown = |i: usize| {
        let p = &scene.patches[elements[i].patch as usize];
        scene.materials.get(p.material as usize).is_some_and(|m| !m.diffuse.is_black() && !m.is_emitter())
    };
    let mut sharp: Vec<(f64, u32)> = leaves
        .iter()
        .copied()
        .filter(|&i| shown(i))
        .filter_map(|i| {
            let v = elements[i].vertices.map(|k| vertex.get(k as usize).copied().unwrap_or(0.0));
            let c = |a: f64, b: f64| (a - b).abs() / (a + b + floor);
            let contrast = c(v[0], v[1]).max(c(v[1], v[2])).max(c(v[2], v[0]));
            (contrast > scene.settings.refine_contrast).then_some((contrast, i as u32))
        })
        .collect();
    if sharp.len() > room {
        sharp.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        sharp.truncate(room);
    }
    let mut ids: Vec<u32> = sharp.into_iter().map(|(_, i)| i).collect();
    ids.sort_unstable();
    ids
}
