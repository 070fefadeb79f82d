//! The machine interface: what a renderer that runs magg's passes offers to the phase
//! sequence ([`crate::phases::run`]).
//!
//! The paper's machine is a host, forks and nodes; ours comes in two implementations of
//! [`Machine`]: the embedded renderer ([`crate::render::EmbeddedMachine`]: node threads over
//! the in-memory block store) and the cluster (the host library's machine, driving forks
//! and nodes over gRPC). Each supplies the passes; the order of the phases, the energies'
//! interpolation, the frames handed to a sink and the stats are written once, in
//! [`crate::phases`], so that a new pass or statistic is added in one place.
//!
//! ```no_run
//! use magg_core::{phases, progress::NoProgress, render};
//! # fn f(prepared: &magg_core::prepared::PreparedScene) -> Result<(), magg_core::machine::RenderError> {
//! let mut machine = render::EmbeddedMachine::new(prepared, &render::RenderOptions::default());
//! let out = phases::run(&mut machine, prepared, &Default::default(), &NoProgress, &mut |_, _, _| Ok(()))?;
//! # Ok(()) }
//! ```

use crate::blocks::CacheSize;
use crate::blocks::{BlockError, CacheStats};
use crate::color::Rgb;
use crate::fixed::Fixed;
use crate::frame::Frame;
use crate::lrt::LrtTally;
use crate::scene::Camera;
use crate::stats::{Emulation, NodeStats, Stages, Traffic};
use crate::subscreen::Subscreen;
use std::sync::Arc;

/// Why a render failed.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// A block could not be read.
    #[error(transparent)]
    Block(#[from] BlockError),
    /// The scene could not be prepared (refinement prepares it again).
    #[error(transparent)]
    Prepare(#[from] crate::prepared::PrepareError),
    /// A worker thread died.
    #[error("a node worker panicked: {0}")]
    Worker(String),
    /// Given energies do not fit the scene.
    #[error("the energies do not fit the scene: {0}")]
    Energies(String),
    /// The frame sink refused a frame (e.g. an image could not be written).
    #[error("{0}")]
    Output(String),
    /// The machine failed in a way of its own (a cluster: a fork lost for good, a stall).
    #[error(transparent)]
    Machine(Box<dyn std::error::Error + Send + Sync>),
}

/// Energies of an earlier light pass (e.g. read back from a saved energy file): given
/// them, a render skips LRT and interpolation and goes straight to VRT.
#[derive(Clone, Debug, PartialEq)]
pub struct Energies {
    /// Flux per element, fixed point.
    pub element_flux: Vec<Fixed>,
    /// Irradiance per vertex (as interpolated from `element_flux`).
    pub vertex_irradiance: Vec<Rgb>,
}

impl Energies {
    /// Checks that the energies fit `header`'s element and vertex counts.
    pub fn check(&self, header: &crate::header::SceneHeader) -> Result<(), RenderError> {
        let (e, v) = (header.counts.elements as usize, header.counts.vertices as usize);
        if self.element_flux.len() != e || self.vertex_irradiance.len() != v {
            return Err(RenderError::Energies(format!(
                "{} elements and {} vertices given, the scene has {e} and {v}",
                self.element_flux.len(),
                self.vertex_irradiance.len()
            )));
        }
        Ok(())
    }
}

/// What a render runs beyond one frame of the scene's camera: energies computed before
/// (no light pass), and several cameras (one light pass, one viewing pass per camera).
#[derive(Clone, Debug, Default)]
pub struct Sequence {
    /// Energies to use instead of tracing the light pass.
    pub energies: Option<Arc<Energies>>,
    /// One frame per camera; empty means one frame of the scene's camera.
    pub cameras: Vec<Camera>,
    /// Trace only the pixels of this rectangle (a crop window); the rest of each frame
    /// stays black. `None`: the whole frame.
    pub window: Option<Subscreen>,
}

impl Sequence {
    /// The cameras of the frames: `cameras`, or the scene's camera alone.
    pub fn frame_cameras(&self, scene_camera: &Camera) -> Vec<Camera> {
        if self.cameras.is_empty() {
            vec![scene_camera.clone()]
        } else {
            self.cameras.clone()
        }
    }
}

/// Receives every finished frame: its index, the frame, and the seconds its viewing pass
/// took. An error stops the render.
pub type FrameSink<'a> = dyn FnMut(usize, &Frame, f64) -> Result<(), String> + 'a;

/// What a render produces.
#[derive(Clone, Debug)]
pub struct RenderOutput {
    /// Linear image (the last frame of a sequence).
    pub frame: Frame,
    /// Flux per element, fixed point.
    pub element_flux: Vec<Fixed>,
    /// Irradiance per vertex.
    pub vertex_irradiance: Vec<Rgb>,
    /// Figures of the run.
    pub stats: crate::stats::RenderStats,
}

/// The result of a light pass: every (light, element) pair traced, the deposits summed.
#[derive(Clone, Debug)]
pub struct LightPass {
    /// Flux per element, fixed point (the same bits whatever the machine's shape).
    pub element_flux: Vec<Fixed>,
    /// Pairs traced.
    pub pairs: u64,
    /// Seconds of the pass spent collecting the energies from where they were accumulated
    /// (the cluster's forks) after the last pair: counted as interpolation, as the paper's
    /// host does.
    pub collect_s: f64,
}

/// One viewing pass to run: frame `index` of `count`, seen by `camera`.
#[derive(Clone, Copy, Debug)]
pub struct ViewPass<'a> {
    /// The frame's index in the sequence.
    pub index: usize,
    /// Frames in the sequence (the last one may let the machine wind down early).
    pub count: usize,
    /// The frame's camera.
    pub camera: &'a Camera,
    /// The pixels to trace: a crop window, or `None` for the whole frame.
    pub window: Option<Subscreen>,
}

impl ViewPass<'_> {
    /// The subscreens of this pass: `tiles` (the whole frame's) clipped to the window.
    pub fn tiles(&self, tiles: &[Subscreen]) -> Vec<Subscreen> {
        crate::subscreen::clip(tiles, self.window)
    }
}

impl ViewPass<'_> {
    /// Whether this is the sequence's last frame.
    pub fn is_last(&self) -> bool {
        self.index + 1 == self.count
    }
}

/// A finished viewing pass.
#[derive(Clone, Debug)]
pub struct ViewedFrame {
    /// The linear image.
    pub frame: Frame,
    /// Subscreens the screen was divided into.
    pub tiles: u64,
    /// Adaptive redivisions of subscreens during the pass.
    pub redivisions: u64,
}

/// Seconds of each phase as the sequence measured them (real time).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PhaseTimes {
    /// Light ray tracing.
    pub lrt_s: f64,
    /// Energy collection, interpolation and publication of the vertex energies.
    pub interp_s: f64,
    /// Viewing ray tracing, all frames.
    pub vrt_s: f64,
}

/// What a machine reports of itself after the last pass: the parts of the stats that
/// depend on how the work was spread.
#[derive(Clone, Debug, Default)]
pub struct MachineFigures {
    /// `embedded` or `cluster`.
    pub mode: String,
    /// Nodes that took part.
    pub nodes: u32,
    /// Forks the blocks were interleaved over.
    pub forks: u32,
    /// Cache blocks per node.
    pub cache_blocks: CacheSize,
    /// Hardware profile.
    pub profile: String,
    /// Schedule: `paper` or `magg`.
    pub scheme: String,
    /// Cache totals over all nodes.
    pub cache: CacheStats,
    /// Traffic per path.
    pub traffic: Traffic,
    /// Where the light went, summed over the nodes.
    pub light: LrtTally,
    /// Per-node figures, by node index.
    pub per_node: Vec<NodeStats>,
    /// What the throttling layer emulated (absent under the native profile).
    pub emulation: Option<Emulation>,
    /// The stage times to report.
    pub stages: Stages,
    /// Each fork process's peak memory (see [`crate::stats::MemoryPeaks`]).
    pub fork_peak_bytes: Vec<Option<u64>>,
}

/// A machine that runs magg's passes: the embedded renderer or the cluster.
///
/// [`crate::phases::run`] calls, in order: [`Machine::light_pass`] (unless the energies
/// are given), [`Machine::publish_vertex_energies`], [`Machine::view_pass`] once per frame,
/// and [`Machine::figures`] last. Every method may fail; the sequence stops at the first
/// error and the machine, when dropped, lets its workers go.
pub trait Machine {
    /// Traces every (light, element) pair of the scene and returns the summed flux.
    fn light_pass(&mut self, progress: &dyn crate::progress::Progress) -> Result<LightPass, RenderError>;
    /// Makes the interpolated vertex irradiance readable by the viewing pass (the
    /// vertex-energy blocks of every node's store), with the vertices marked for
    /// gathering (`gather`, [`crate::energy::gather_vertices`]; empty: none).
    fn publish_vertex_energies(&mut self, vertex_irradiance: &[Rgb], gather: &[bool]) -> Result<(), RenderError>;
    /// Traces one frame.
    fn view_pass(
        &mut self,
        pass: ViewPass<'_>,
        progress: &dyn crate::progress::Progress,
    ) -> Result<ViewedFrame, RenderError>;
    /// The machine's figures after the last pass, with the stage times it reports for
    /// `times` (real seconds natively; modelled ones on an emulated machine).
    fn figures(&mut self, times: PhaseTimes) -> Result<MachineFigures, RenderError>;
}
