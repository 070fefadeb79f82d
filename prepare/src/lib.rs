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

pub use shares::Shares;

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
    prepare_split_on(scene, plan, splits, Shares::default())
}

/// [`prepare_split`] in `shares` ([`shares`]). The result is the same, bit for bit, for
/// every split.
pub fn prepare_split_on(
    scene: &Scene,
    plan: EffectsPlan,
    splits: &[Vec<u32>],
    shares: Shares,
) -> Result<PreparedScene, PrepareError> {
    // The pool's start and end count as preprocessing.
    let start = Instant::now();
    match rayon::ThreadPoolBuilder::new().thread_name(|i| format!("magg-preprocess-{i}")).build() {
        Ok(pool) => pool.install(|| prepare_here(scene, plan, splits, shares, start)),
        // No threads to be had: the global pool (or this thread) does the work.
        Err(_) => prepare_here(scene, plan, splits, shares, start),
    }
}

/// [`prepare_split`] on the current rayon pool, timed from `start`.
fn prepare_here(
    scene: &Scene,
    plan: EffectsPlan,
    splits: &[Vec<u32>],
    shares: Shares,
    start: Instant,
) -> Result<PreparedScene, PrepareError> {
    if scene.patches.is_empty() {
        return Err(PrepareError::Empty { file: scene.name.clone() });
    }
    let mut mesh = mesh::build(scene, shares)?;
    for round in splits {
        split::split(&mut mesh, round);
    }
    let refined = mesh.elements.len() as u64;
    if refined > scene.settings.max_elements || refined >= u32::MAX as u64 / 2 {
        return Err(PrepareError::TooLarge {
            file: scene.name.clone(),
            what: format!("{refined} elements after refinement"),
        });
    }
    let t_junctions = split::t_junctions(&mesh);
    let (grid, bvh) = match scene.settings.accel {
        Accel::Grid => (grid::build(scene, &mesh), None),
        Accel::Bvh => {
            let solid = mesh.patches.iter().filter(|v| !bvh::degenerate(v));
            let pad = bvh::pad_for(solid.fold(Aabb::EMPTY, |b, v| b.union(Aabb::of_triangle(v))));
            (grid::bounds_only(&mesh), Some(bvh::assemble(mesh.shares.subtrees(pad))))
        }
    };
    let binnings = bvh.as_ref().map_or(0, |b| b.binnings);
    let packed = pack::pack(&mesh, &grid, bvh, &scene.textures);
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
    Ok(PreparedScene {
        name: scene.name.clone(),
        header: Arc::new(header),
        blocks: packed.blocks,
        elements: mesh.elements,
        ops,
        vertex_positions: mesh.vertex_positions,
        t_junctions,
        splits: splits.to_vec(),
        preprocess_s: start.elapsed().as_secs_f64(),
        kept_pairs: Default::default(),
        refinement: Default::default(),
    })
}
