//! The stats of a render, serialised as the JSON that scripts rely on (docs/USER_GUIDE.md, stats file).

use crate::blocks::CacheStats;
use crate::header::Counts;
use crate::lrt::LrtTally;
use crate::plan::EffectsPlan;
use crate::view::OpCounters;
use serde::Serialize;

/// Seconds per stage.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Stages {
    /// Preprocessing.
    pub preprocess_s: f64,
    /// Light ray tracing.
    pub lrt_s: f64,
    /// Energy interpolation.
    pub interp_s: f64,
    /// Viewing ray tracing.
    pub vrt_s: f64,
    /// Everything, including assembly.
    pub total_s: f64,
}

impl Stages {
    /// Stage times of a render that started (after preprocessing) at `start`.
    pub fn measured(preprocess_s: f64, lrt_s: f64, interp_s: f64, vrt_s: f64, start: std::time::Instant) -> Stages {
        Stages { preprocess_s, lrt_s, interp_s, vrt_s, total_s: preprocess_s + start.elapsed().as_secs_f64() }
    }
}

/// Cache totals.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct CacheSummary {
    /// Hits.
    pub hits: u64,
    /// Misses.
    pub misses: u64,
    /// Blocks fetched ahead of a read, in one request with others (a read of one is
    /// a hit): the blocks fetched are `misses + prefetched`.
    pub prefetched: u64,
    /// hits / (hits + misses).
    pub hit_ratio: f64,
}

impl From<CacheStats> for CacheSummary {
    fn from(c: CacheStats) -> Self {
        CacheSummary { hits: c.hits, misses: c.misses, prefetched: c.prefetched, hit_ratio: c.hit_ratio() }
    }
}

/// Bytes per path of the emulated machine (link, DMA, G-bus) and RPC count.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Traffic {
    /// Serial-link bytes (control, pairs, deposits, pixel rows).
    pub link_bytes: u64,
    /// DMA bytes (blocks fork -> node).
    pub dma_bytes: u64,
    /// G-bus bytes (blocks fetched from another fork).
    pub gbus_bytes: u64,
    /// Remote procedure calls.
    pub rpcs: u64,
}

/// Work done.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Work {
    /// (light, element) pairs traced.
    pub pairs: u64,
    /// Subscreens traced.
    pub tiles: u64,
    /// Adaptive redivisions of subscreens.
    pub redivisions: u64,
    /// Light rays (primary and secondary).
    pub light_rays: u64,
    /// Viewing rays (primary and secondary).
    pub view_rays: u64,
}

/// One node's share.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct NodeStats {
    /// Node index.
    pub node: u32,
    /// Its home fork.
    pub home_fork: u32,
    /// Pairs it traced.
    pub pairs: u64,
    /// Subscreens it traced.
    pub tiles: u64,
    /// Its cache.
    pub cache: CacheSummary,
    /// Its kernel operation counts.
    pub ops: OpCounters,
    /// Modelled seconds its processor and its link were busy (throttled profiles).
    #[serde(skip_serializing_if = "is_zero")]
    pub cpu_s: f64,
    /// See `cpu_s`.
    #[serde(skip_serializing_if = "is_zero")]
    pub link_s: f64,
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// What the throttling layer emulated (throttled profiles only). Stage
/// times of such a run are modelled seconds: real seconds divided by `dilation`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Emulation {
    /// Real seconds per modelled second.
    pub dilation: f64,
    /// Real CPU time of the host process (which holds every fork and node of an
    /// in-process run) over the run, as a share of all cores' wall time: the emulation is
    /// faithful while this stays well below 1 (the sweeps keep it under 0.5).
    pub real_cpu_share: Option<f64>,
    /// Modelled busy seconds, summed over the resources of each kind.
    pub busy: EmulatedBusy,
}

/// Modelled busy seconds per emulated resource kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct EmulatedBusy {
    /// Preprocessing (on one fork processor in the paper's scheme, on every fork in
    /// ours): wall time of the stage.
    pub preprocess_s: f64,
    /// Node processors, from the cost model (deterministic: the same scene and settings
    /// give the same figure whatever the cluster's shape).
    pub node_cpu_s: f64,
    /// Node links, both directions.
    pub link_s: f64,
    /// Fork DMA engines.
    pub dma_s: f64,
    /// The G-bus.
    pub gbus_s: f64,
    /// Fork processors serving requests.
    pub fork_s: f64,
}

/// The plan as written to the stats file.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PlanSummary {
    /// Passes that ran.
    pub passes: Vec<&'static str>,
    /// The decisions.
    #[serde(flatten)]
    pub plan: EffectsPlan,
}

impl From<&EffectsPlan> for PlanSummary {
    fn from(plan: &EffectsPlan) -> Self {
        PlanSummary { passes: plan.passes(), plan: plan.clone() }
    }
}

/// Adaptive refinement (`[render] refine`, [`crate::refine`]): what its pilot light
/// passes did, in preprocessing. All zero when the scene is not refined.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Refinement {
    /// Pilot levels run.
    pub levels: u32,
    /// Elements split, each into four, over all levels.
    pub split: u64,
    /// Pairs the pilots' light passes handed out, over all levels (a pair traced at an
    /// earlier level is binned from its kept deposits, not traced again).
    pub pilot_pairs: u64,
    /// Seconds of the pilots' light passes (part of preprocessing).
    pub pilot_s: f64,
    /// Where the pilots ran: `embedded` (this process's cores) or `nodes` (the
    /// cluster's); empty when none ran.
    pub pilots_on: String,
    /// The most nodes (the embedded machine's threads) that traced pairs of one level.
    pub pilot_nodes: u32,
    /// The render's light pass carries the pilots' light: it bins the pairs they kept
    /// instead of tracing them again.
    pub kept: bool,
}

/// Preparation (`magg_prepare`): where the scene was prepared, in how many shares, and
/// the seconds of its steps (the last preparation's: the render's scene, after any
/// refinement's pilot levels).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Preparation {
    /// Shares of space the scene was prepared in.
    pub shares: u32,
    /// Where they were prepared: `in process` or the forks' addresses.
    pub place: String,
    /// Attempts: 1, plus one for every time a preparation of the render (its scene's or
    /// one of refinement's pilot levels') started again after a fork was lost.
    pub attempts: u32,
    /// Seconds numbering the patches and elements and splitting space (the host).
    pub plan_s: f64,
    /// Seconds of the shares' welding and elements, messages included.
    pub weld_s: f64,
    /// Seconds of the BVH (the shares' subtrees and the top over them) or the grid.
    pub accel_s: f64,
    /// Seconds packing the blocks (the shares' records and the global blocks).
    pub pack_s: f64,
}

/// Peak resident memory of each process of a render (Linux's `VmHWM`), where the
/// platform tells.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct MemoryPeaks {
    /// The host's process (with its in-process forks and nodes), at the end of the render.
    pub host_bytes: Option<u64>,
    /// Each fork by index, as it answered the host's last poll: `null` for a fork in the
    /// host's process (counted in `host_bytes`); empty in the embedded renderer.
    pub fork_bytes: Vec<Option<u64>>,
}

/// Everything a run reports.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RenderStats {
    /// Scene label.
    pub scene: String,
    /// `embedded` (core driven directly) or `cluster`.
    pub mode: String,
    /// Node count.
    pub nodes: u32,
    /// Fork count (block b lives on fork b mod forks).
    pub forks: u32,
    /// Cache blocks per node; `null` for unlimited.
    pub cache_blocks: Option<u64>,
    /// Hardware profile.
    pub profile: String,
    /// Schedule: `paper` or `magg` (docs/ARCHITECTURE.md).
    pub scheme: String,
    /// Stage times.
    pub stages: Stages,
    /// Cache totals over all nodes.
    pub cache: CacheSummary,
    /// Traffic per path.
    pub traffic: Traffic,
    /// Work counts.
    pub work: Work,
    /// Passes run and why.
    pub plan: PlanSummary,
    /// Scene counts.
    pub counts: Counts,
    /// Adaptive refinement's pilot passes.
    pub refine: Refinement,
    /// Preparation's shares and steps.
    pub prepare: Preparation,
    /// Every process's peak memory.
    pub memory: MemoryPeaks,
    /// Where the light went (W per channel).
    pub light: LrtTally,
    /// Per-node figures.
    pub per_node: Vec<NodeStats>,
    /// What the throttling layer emulated (absent under the native profile).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub emulation: Option<Emulation>,
}
