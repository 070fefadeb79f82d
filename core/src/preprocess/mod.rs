//! Preprocessing (paper §3.1 and §4.3): subdivide patches into elements, weld element
//! vertices, build the acceleration structure (the uniform grid of subspaces, or a BVH)
//! and pack everything into 2 KB blocks.
//!
//! The paper ran this stage on one fork processor and named it the main obstacle to
//! speed-up; here every step runs in parallel (rayon), and the result does not depend on
//! the number of threads.

mod bvh;
mod grid;
mod mesh;
mod pack;
mod split;
mod weld;

use crate::blocks::Block;
use crate::header::{Emitter, SceneHeader};
use crate::plan::EffectsPlan;
use crate::scene::{Accel, Scene};
use glam::DVec3;
use std::sync::Arc;
use std::time::Instant;

pub use mesh::subdivisions_of;

/// Why a scene cannot be prepared.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PrepareError {
    /// The element count is over the scene's `max_elements`.
    #[error("{file}: the scene would have {estimate} elements, over the limit of {limit} (render.max_elements); the largest patch is at {worst}; raise element_size or the limit")]
    TooManyElements {
        /// Where the patch with the most elements is defined, and its subdivisions.
        worst: String,
        /// Scene label.
        file: String,
        /// Elements it would create.
        estimate: u64,
        /// The limit.
        limit: u64,
    },
    /// An id space (u32) would overflow.
    #[error("{file}: the scene is too large: {what}")]
    TooLarge {
        /// Scene label.
        file: String,
        /// What overflowed.
        what: String,
    },
    /// The scene has nothing to render.
    #[error("{file}: the scene has no patches")]
    Empty {
        /// Scene label.
        file: String,
    },
}

/// An element as the host sees it (for interpolation and the energy file).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ElementInfo {
    /// Owning patch.
    pub patch: u32,
    /// Welded vertex ids.
    pub vertices: [u32; 3],
    /// Area.
    pub area: f64,
    /// Centroid.
    pub centroid: DVec3,
    /// Which light it holds: the light arriving on either face of its patch, on the
    /// front only, or on the back only.
    pub face: Face,
    /// The element refinement split it from, or [`NO_PARENT`].
    pub parent: u32,
    /// First of its four children when refinement split it, 0 for a leaf.
    pub child: u32,
}

/// [`ElementInfo::parent`] of an element of a patch lattice.
pub const NO_PARENT: u32 = u32::MAX;

impl ElementInfo {
    /// True unless refinement split it (only leaves hold light).
    pub fn is_leaf(&self) -> bool {
        self.child == 0
    }
}

/// The faces of a patch whose light an element holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Face {
    /// Both: a two-sided patch that keeps no back face (no diffuse part, or emitting).
    Both,
    /// The front: a one-sided patch's element, or the front element of a patch that
    /// keeps its back face apart.
    Front,
    /// The back: a back element ([`crate::scene::Material::has_back_face`]).
    Back,
}

impl Face {
    /// Whether light arriving from direction `towards_light` (from the element to the
    /// light) onto a surface of geometric normal `normal` lands on this face.
    pub fn takes(self, towards_light: DVec3, normal: DVec3) -> bool {
        match self {
            Face::Both => true,
            Face::Front => towards_light.dot(normal) > 0.0,
            Face::Back => towards_light.dot(normal) < 0.0,
        }
    }
}

/// A scene ready to render: the resident header, every block, and the host-side tables.
#[derive(Clone, Debug)]
pub struct PreparedScene {
    /// Scene label (file name).
    pub name: String,
    /// Data every node keeps resident.
    pub header: Arc<SceneHeader>,
    /// Every block (vertex-energy blocks zero until interpolation).
    pub blocks: Vec<Box<Block>>,
    /// Elements by id.
    pub elements: Vec<ElementInfo>,
    /// Welded vertex positions by id.
    pub vertex_positions: Vec<DVec3>,
    /// Refinement's T-junctions: (edge end, edge end, midpoint), see
    /// [`crate::energy::interpolate`].
    pub t_junctions: Vec<[u32; 3]>,
    /// The elements refinement split, round by round (empty without refinement).
    pub splits: Vec<Vec<u32>>,
    /// Wall-clock seconds spent preparing.
    pub preprocess_s: f64,
    /// The pairs refinement's pilot passes traced, kept for the first light pass where
    /// it carries exactly the pilots' light ([`crate::refine::KeptPairs`]); empty
    /// otherwise.
    pub kept_pairs: crate::refine::KeptSlot,
    /// What refinement's pilot passes did (all zero without refinement).
    pub refinement: crate::stats::Refinement,
    /// Operations preprocessing did (for the throttling layer's cost model).
    pub ops: PrepareOps,
}

/// What preprocessing did, counted: the cost model of the throttling layer prices it as
/// the paper's fork processor would have spent it. Deterministic for a scene.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PrepareOps {
    /// Triangle/subspace overlap tests (grid), or primitive binnings of the SAH build
    /// (BVH).
    pub box_tests: u64,
    /// Elements made.
    pub elements: u64,
    /// Vertices welded.
    pub vertices: u64,
    /// 2 KB blocks packed.
    pub blocks: u64,
}

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
/// (ascending element ids; see [`crate::refine`], which chooses them).
pub fn prepare_split(scene: &Scene, plan: EffectsPlan, splits: &[Vec<u32>]) -> Result<PreparedScene, PrepareError> {
    // The pool's start and end count as preprocessing.
    let start = Instant::now();
    match rayon::ThreadPoolBuilder::new().thread_name(|i| format!("magg-preprocess-{i}")).build() {
        Ok(pool) => pool.install(|| prepare_here(scene, plan, splits, start)),
        // No threads to be had: the global pool (or this thread) does the work.
        Err(_) => prepare_here(scene, plan, splits, start),
    }
}

/// [`prepare_split`] on the current rayon pool, timed from `start`.
fn prepare_here(
    scene: &Scene,
    plan: EffectsPlan,
    splits: &[Vec<u32>],
    start: Instant,
) -> Result<PreparedScene, PrepareError> {
    if scene.patches.is_empty() {
        return Err(PrepareError::Empty { file: scene.name.clone() });
    }
    let mut mesh = mesh::build(scene)?;
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
        Accel::Bvh => (grid::bounds_only(&mesh), Some(bvh::build_and_pack(&mesh))),
    };
    let binnings = bvh.as_ref().map_or(0, |b| b.binnings);
    let packed = pack::pack(&mesh, &grid, bvh, &scene.textures);
    let emitters = emitters_of(scene, &mesh.elements);
    let header = SceneHeader {
        camera: scene.camera.clone(),
        settings: scene.settings.clone(),
        lights: scene.lights.clone(),
        energy_quantum: crate::energy::quantum_for(&scene.lights, &emitters),
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
