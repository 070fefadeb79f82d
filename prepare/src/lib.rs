//! # magg-prepare: a scene made ready to render
//!
//! Preparation (paper §3.1 and §4.3) turns a [`magg_core::scene::Scene`] into a
//! [`PreparedScene`]: subdivide patches into elements, weld element vertices, build the
//! acceleration structure (the uniform grid of subspaces, or a BVH) and pack everything
//! into 2 KB blocks; adaptive refinement ([`refine`]) drives pilot light passes and
//! prepares the scene again with the elements it splits.
//!
//! The paper ran this stage on one fork processor and named it the main obstacle to
//! speed-up; here every step runs in parallel (rayon), and the result does not depend on
//! the number of threads. The prepared scene's type lives in the rendering core
//! ([`magg_core::prepared`]): machines and nodes render it without this crate.
//!
//! ```no_run
//! use magg_core::{progress::NoProgress, render, scene};
//! let text = std::fs::read_to_string("scenes/cornell.toml").unwrap();
//! let scene = scene::parse_scene_str("scenes/cornell.toml", &text, "scenes".as_ref(),
//!     &|p: &std::path::Path| std::fs::read(p)).unwrap();
//! let prepared = magg_prepare::prepare(&scene).unwrap();
//! let out = render::render(&prepared, &render::RenderOptions::default(), &NoProgress).unwrap();
//! println!("{} elements, {} x {} pixels", prepared.elements.len(), out.frame.width, out.frame.height);
//! ```

mod bvh;
mod grid;
mod mesh;
mod pack;
pub mod shares;
mod split;

pub use shares::{LocalShareSet, ShareError, ShareSet, Shares};

pub mod refine;

use magg_core::geometry::Aabb;
use magg_core::header::{Emitter, SceneHeader};
use magg_core::plan::EffectsPlan;
use magg_core::prepared::{ElementInfo, PrepareError, PrepareOps, PreparedScene};
use magg_core::scene::{Accel, Scene};
use std::sync::Arc;
use std::time::Instant;

pub use mesh::subdivisions_of;

/// The elements of emitting materials, ascending, with the flux each emits.
fn emitters_of(scene: &Scene, elements: &[ElementInfo]) -> Vec<Emitter> {
    elements
        .iter()
        .enumerate()
        .filter(|(_, info)| info.is_leaf())
        .filter_map(|(e, info)| {
            let m = scene.patches.get(info.patch as usize).and_then(|p| scene.materials.get(p.material as usize))?;
            m.is_emitter().then(|| Emitter { element: e as u32, power: m.emit.scale(std::f64::consts::PI * info.area) })
        })
        .collect()
}

/// Prepares `scene` with the plan derived from it.
pub fn prepare(scene: &Scene) -> Result<PreparedScene, PrepareError> {
    prepare_with_plan(scene, EffectsPlan::for_scene(scene))
}

/// Prepares `scene` with an explicit effects plan (e.g. [`EffectsPlan::forced_on`]).
///
/// The parallel steps run on a thread pool of this call's own, which ends with it: the
/// idle workers of a pool that outlives its jobs go on yielding for milliseconds, on the
/// cores that the passes after preprocessing need (measured: 2 ms on one of 2 cores,
/// during which a node thread of the in-process cluster waited 2.4 ms to start).
pub fn prepare_with_plan(scene: &Scene, plan: EffectsPlan) -> Result<PreparedScene, PrepareError> {
    prepare_split(scene, plan, &[])
}

/// [`prepare_with_plan`], then splitting the elements of each round of `splits` in turn
/// (ascending element ids; see [`refine`], which chooses them).
pub fn prepare_split(scene: &Scene, plan: EffectsPlan, splits: &[Vec<u32>]) -> Result<PreparedScene, PrepareError> {
    prepare_split_on(scene, plan, splits, Shares::default(), &mut LocalShareSet::default())
}

/// [`prepare_split`] in `shares` ([`shares`]), run by `set`. The result is the same, bit
/// for bit, for every split and every set.
pub fn prepare_split_on(
    scene: &Scene,
    plan: EffectsPlan,
    splits: &[Vec<u32>],
    shares: Shares,
    set: &mut dyn ShareSet,
) -> Result<PreparedScene, PrepareError> {
    // The pool's start and end count as preprocessing.
    let start = Instant::now();
    match rayon::ThreadPoolBuilder::new().thread_name(|i| format!("magg-preprocess-{i}")).build() {
        Ok(pool) => pool.install(|| prepare_here(scene, plan, splits, shares, set, start)),
        // No threads to be had: the global pool (or this thread) does the work.
        Err(_) => prepare_here(scene, plan, splits, shares, set, start),
    }
}

/// Times a preparation is tried when a share's fork is lost during it: each attempt
/// starts over in a new session (the forks' calls retry until the fork timeout first).
pub const ATTEMPTS: u32 = 3;

/// [`prepare_split_on`] on the current rayon pool, timed from `start`: again, in a new
/// session, while the shares' forks are lost.
fn prepare_here(
    scene: &Scene,
    plan: EffectsPlan,
    splits: &[Vec<u32>],
    shares: Shares,
    set: &mut dyn ShareSet,
    start: Instant,
) -> Result<PreparedScene, PrepareError> {
    if scene.patches.is_empty() {
        return Err(PrepareError::Empty { file: scene.name.clone() });
    }
    let mut attempt = 0;
    loop {
        attempt += 1;
        let session = set.begin_session();
        match prepare_session(scene, plan.clone(), splits, shares, set, session, start)? {
            Ok(mut prepared) => {
                prepared.preparation.attempts = attempt;
                prepared.preparation.place = set.place();
                return Ok(prepared);
            }
            Err(ShareError::Lost { at, why }) if attempt < ATTEMPTS => {
                tracing::warn!("the fork at {at} was lost while preparing the scene ({why}); preparing again");
            }
            Err(e) => {
                return Err(PrepareError::Shares {
                    file: scene.name.clone(),
                    place: set.place(),
                    attempts: attempt,
                    why: e.to_string(),
                })
            }
        }
    }
}

/// One attempt of [`prepare_here`], in session `session`. The outer error is the
/// scene's; the inner, the shares'.
fn prepare_session(
    scene: &Scene,
    plan: EffectsPlan,
    splits: &[Vec<u32>],
    shares: Shares,
    set: &mut dyn ShareSet,
    session: u64,
    start: Instant,
) -> Result<Result<PreparedScene, ShareError>, PrepareError> {
    let mut mesh = match mesh::build(scene, shares, set, session)? {
        Ok(mesh) => mesh,
        Err(e) => return Ok(Err(e)),
    };
    let result = finish(scene, plan, splits, &mut mesh, set, session, start);
    // The shares are dropped on their forks whatever happened (a lost fork has dropped
    // them already).
    let ended = shares::end(set, session, mesh.shares);
    Ok(match result? {
        Ok(prepared) => ended.map(|_| prepared),
        Err(e) => Err(e),
    })
}

/// Refinement's splits, the acceleration structure and the blocks of a welded `mesh`.
fn finish(
    scene: &Scene,
    plan: EffectsPlan,
    splits: &[Vec<u32>],
    mesh: &mut mesh::Mesh,
    set: &mut dyn ShareSet,
    session: u64,
    start: Instant,
) -> Result<Result<PreparedScene, ShareError>, PrepareError> {
    for round in splits {
        split::split(mesh, round);
    }
    let refined = mesh.elements.len() as u64;
    if refined > scene.settings.max_elements || refined >= u32::MAX as u64 / 2 {
        return Err(PrepareError::TooLarge {
            file: scene.name.clone(),
            what: format!("{refined} elements after refinement"),
        });
    }
    let t_junctions = split::t_junctions(mesh);
    let t_accel = Instant::now();
    let (grid, bvh) = match scene.settings.accel {
        Accel::Grid => (grid::build(scene, mesh), None),
        Accel::Bvh => {
            let solid = mesh.patches.iter().filter(|v| !bvh::degenerate(v));
            let pad = bvh::pad_for(solid.fold(Aabb::EMPTY, |b, v| b.union(Aabb::of_triangle(v))));
            match shares::subtrees(set, session, mesh.shares, pad) {
                Ok(trees) => (grid::bounds_only(mesh), Some(bvh::assemble(trees))),
                Err(e) => return Ok(Err(e)),
            }
        }
    };
    let binnings = bvh.as_ref().map_or(0, |b| b.binnings);
    let accel_s = t_accel.elapsed().as_secs_f64();
    let t_pack = Instant::now();
    let shares = mesh.shares;
    let packed =
        match pack::pack(mesh, &grid, bvh, &scene.textures, |layout| shares::pack(set, session, shares, layout)) {
            Ok(packed) => packed,
            Err(e) => return Ok(Err(e)),
        };
    let emitters = emitters_of(scene, &mesh.elements);
    let header = SceneHeader {
        camera: scene.camera.clone(),
        settings: scene.settings.clone(),
        lights: scene.lights.clone(),
        energy_quantum: magg_core::fixed::quantum_for(&scene.lights, &emitters),
        emitters,
        materials: scene.materials.clone(),
        textures: packed.textures,
        grid: packed.grid,
        bvh: packed.bvh,
        layout: packed.layout,
        counts: packed.counts,
        plan,
    };
    let ops = PrepareOps {
        box_tests: grid.box_tests + binnings,
        elements: mesh.elements.len() as u64,
        vertices: mesh.vertex_positions.len() as u64,
        blocks: packed.blocks.len() as u64,
    };
    Ok(Ok(PreparedScene {
        name: scene.name.clone(),
        header: Arc::new(header),
        blocks: packed.blocks,
        elements: std::mem::take(&mut mesh.elements),
        ops,
        vertex_positions: std::mem::take(&mut mesh.vertex_positions),
        t_junctions,
        splits: splits.to_vec(),
        preprocess_s: start.elapsed().as_secs_f64(),
        kept_pairs: Default::default(),
        refinement: Default::default(),
        preparation: magg_core::stats::Preparation {
            shares: shares as u32,
            place: String::new(),
            attempts: 1,
            plan_s: mesh.plan_s,
            weld_s: mesh.weld_s,
            accel_s,
            pack_s: t_pack.elapsed().as_secs_f64(),
        },
    }))
}
