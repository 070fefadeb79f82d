//! The phase sequence of a render, written once for every [`Machine`]: light ray
//! tracing (or energies given), energy interpolation to the vertices and their
//! publication, one viewing pass per camera, then the stats.
//!
//! The embedded renderer and the cluster differ only in how they run each pass; what
//! comes between the passes (checking given energies, interpolating, timing the phases,
//! handing frames to the sink, assembling [`RenderStats`]) lives here. A new pass (a
//! second light pass) is added to [`run`] and to the trait; adaptive refinement runs its
//! pilot passes while preparing the scene ([`crate::refine`]), before the render's
//! machine starts its phases (a cluster runs each pilot level as a scene of its own).

use crate::energy::{gather_vertices, interpolate};

use crate::fixed::Fixed;
use crate::machine::{FrameSink, Machine, PhaseTimes, RenderError, RenderOutput, Sequence, ViewPass};
use crate::prepared::PreparedScene;
use crate::progress::Progress;
use crate::stats::{RenderStats, Work};
use crate::view::OpCounters;
use std::time::Instant;

/// Runs the phases of a render of `prepared` on `machine`: the light pass once (not at all
/// when `seq` brings energies), then one viewing pass per camera of `seq`, each frame
/// handed to `sink` as it is done. The output's frame is the last one.
pub fn run(
    machine: &mut dyn Machine,
    prepared: &PreparedScene,
    seq: &Sequence,
    progress: &dyn Progress,
    sink: &mut FrameSink<'_>,
) -> Result<RenderOutput, RenderError> {
    let header = &prepared.header;
    let mut times = PhaseTimes::default();

    // --- LRT, unless the energies are given; interpolation (given energies carry theirs).
    let (element_flux, vertex_irradiance, pairs) = match &seq.energies {
        Some(e) => {
            e.check(header)?;
            let t_interp = Instant::now();
            let gather = gather_marks(prepared, &e.element_flux);
            machine.publish_vertex_energies(&e.vertex_irradiance, &gather)?;
            times.interp_s = t_interp.elapsed().as_secs_f64();
            (e.element_flux.clone(), e.vertex_irradiance.clone(), 0)
        }
        None => {
            let t_lrt = Instant::now();
            let light = machine.light_pass(progress)?;
            let lrt_end = t_lrt.elapsed().as_secs_f64();
            times.lrt_s = lrt_end - light.collect_s;
            let t_interp = Instant::now();
            let vertex = interpolate(
                &prepared.elements,
                &prepared.t_junctions,
                &light.element_flux,
                header.counts.vertices as usize,
                header.energy_quantum,
            );
            let gather = gather_marks(prepared, &light.element_flux);
            machine.publish_vertex_energies(&vertex, &gather)?;
            times.interp_s = light.collect_s + t_interp.elapsed().as_secs_f64();
            (light.element_flux, vertex, light.pairs)
        }
    };

    // --- VRT: one viewing pass per camera.
    let cameras = seq.frame_cameras(&header.camera);
    let (mut tiles, mut redivisions) = (0, 0);
    let mut frame = None;
    for (index, camera) in cameras.iter().enumerate() {
        progress.frame_begins(index, cameras.len());
        let t_vrt = Instant::now();
        let viewed =
            machine.view_pass(ViewPass { index, count: cameras.len(), camera, window: seq.window }, progress)?;
        let frame_s = t_vrt.elapsed().as_secs_f64();
        times.vrt_s += frame_s;
        tiles += viewed.tiles;
        redivisions += viewed.redivisions;
        sink(index, &viewed.frame, frame_s).map_err(RenderError::Output)?;
        frame = Some(viewed.frame);
    }
    let frame = frame.unwrap_or_else(|| crate::frame::Frame::new(header.settings.width, header.settings.height));

    // --- Figures.
    let m = machine.figures(times)?;
    let ops = m.per_node.iter().fold(OpCounters::default(), |a, n| a.add(n.ops));
    let stats = RenderStats {
        scene: prepared.name.clone(),
        mode: m.mode,
        nodes: m.nodes,
        forks: m.forks,
        cache_blocks: m.cache_blocks.blocks(),
        profile: m.profile,
        scheme: m.scheme,
        stages: m.stages,
        cache: m.cache.into(),
        traffic: m.traffic,
        work: Work { pairs, tiles, redivisions, light_rays: ops.light_rays, view_rays: ops.view_rays },
        plan: (&header.plan).into(),
        counts: header.counts,
        refine: prepared.refinement.clone(),
        prepare: prepared.preparation.clone(),
        memory: crate::stats::MemoryPeaks { host_bytes: None, fork_bytes: m.fork_peak_bytes },
        light: m.light,
        per_node: m.per_node,
        emulation: m.emulation,
    };
    Ok(RenderOutput { frame, element_flux, vertex_irradiance, stats })
}

/// The vertices whose elements' hits gather the bounced light, where the plan gathers
/// ([`crate::plan::EffectsPlan::gathers`]); none otherwise.
fn gather_marks(prepared: &PreparedScene, element_flux: &[Fixed]) -> Vec<bool> {
    let h = &prepared.header;
    if !h.plan.gathers(h.settings.gather_rays, &h.materials) {
        return Vec::new();
    }
    gather_vertices(&prepared.elements, element_flux, h.counts.vertices as usize)
}
