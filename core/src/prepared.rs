//! The prepared scene: what preparation (`magg-prepare`) makes of a scene and every
//! machine renders. The resident header, every 2 KB block, and the host-side tables
//! (elements, vertex positions, refinement's T-junctions and splits) that interpolation,
//! the energy file and the cluster's shard loads read. Nodes read it through their
//! blocks only; nothing here prepares anything.

use crate::blocks::Block;
use crate::header::SceneHeader;
use glam::DVec3;
use std::sync::Arc;

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
    /// The shares that prepare the scene (on the forks) could not finish it.
    #[error("{file}: preparing the scene in shares ({place}) failed (attempts: {attempts}): {why}")]
    Shares {
        /// Scene label.
        file: String,
        /// Where the shares ran.
        place: String,
        /// Attempts made.
        attempts: u32,
        /// The last attempt's error.
        why: String,
    },
}

/// An element as the host sees it (for interpolation and the energy file).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
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
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
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
    /// it carries exactly the pilots' light ([`crate::kept::KeptPairs`]); empty
    /// otherwise.
    pub kept_pairs: crate::kept::KeptSlot,
    /// What refinement's pilot passes did (all zero without refinement).
    pub refinement: crate::stats::Refinement,
    /// Where and how the scene was prepared.
    pub preparation: crate::stats::Preparation,
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
