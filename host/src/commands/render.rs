//! `magg-host render SCENE --out IMAGE`: the main job.
//!
//! One light pass (or none, with `--load-energy`), then one viewing pass per frame: one
//! frame of the scene's camera, or every frame of its camera path, written as numbered
//! images (see [`crate::frames`]).

use crate::cli::{Mode, RenderConfig};
use crate::frames::{FrameRecord, RunStats};
use crate::harness::{ClusterShape, InProcessOptions, StartedCluster};
use crate::live::LiveView;
use crate::partial::{self, PartialImage};
use crate::{energy_csv, frames, images, progress::Bars, saved_energy, scene_file};
use anyhow::Context;
use magg_core::fingerprint::EnergyInputs;
use magg_core::frame::Frame;
use magg_core::machine::{Energies, Sequence};
use magg_core::plan::EffectsPlan;
use magg_core::render;
use magg_prepare::refine::EmbeddedPilots;
use magg_prepare::LocalShareSet;
use std::sync::Arc;

/// Renders per `cfg` and writes every requested output. The frame in progress is kept in
/// `partial`, for a signal that stops the render half-way (see [`crate::partial`]).
pub fn run(cfg: RenderConfig, files: &scene_file::SceneFiles, partial: &partial::Slot) -> anyhow::Result<()> {
    let read_start = std::time::Instant::now();
    let (mut scene, path) = files.load_with_path(&cfg.scene, &cfg.overrides)?;
    let read_s = read_start.elapsed().as_secs_f64();
    if let Some(q) = cfg.quality {
        q.apply(&mut scene);
    }
    cfg.knobs.apply_for(cfg.scheme, &mut scene.settings)?;
    let window = cfg.framing.crop(scene.settings.width, scene.settings.height)?;
    let path_cameras = path.as_ref().map(|p| p.cameras()).unwrap_or_default();
    if cfg.framing.frames.is_some() && path_cameras.is_empty() {
        anyhow::bail!("--frames: {} has no [camera_path]", cfg.scene.display());
    }
    let frame_numbers = cfg.framing.frames(path_cameras.len().max(1))?;
    let image = PartialImage::new(
        scene.settings.width,
        scene.settings.height,
        partial::Outputs {
            out: cfg.out.0.clone(),
            format: cfg.out.1,
            exposure: scene.settings.exposure,
            window,
            first_number: frame_numbers.start,
            path_frames: path_cameras.len().max(1),
        },
    );
    partial.fill(image.clone());
    let forks_here = match &cfg.mode {
        Mode::Cluster { forks_at, .. } if forks_at.is_empty() => cfg.forks,
        _ => 0,
    };
    crate::memory::check(&scene, cfg.max_memory_mb, forks_here)?;
    let plan = if cfg.all_effects { EffectsPlan::forced_on(&scene) } else { EffectsPlan::for_scene(&scene) };
    let opts = render::RenderOptions {
        nodes: cfg.nodes,
        forks: cfg.forks,
        cache_blocks: cfg.cache_blocks,
        subscreen: cfg.subscreen,
    };
    let bars = Bars::new(cfg.quiet);
    // How the cluster's nodes run, for refinement's pilot levels and for the render.
    let mut in_process = match &cfg.mode {
        Mode::Embedded => None,
        Mode::Cluster { external_nodes, min_nodes, stall_timeout, faults, .. } => Some(InProcessOptions {
            nodes: if *external_nodes { 0 } else { opts.node_count() },
            external_nodes: if *external_nodes { *min_nodes } else { 0 },
            cache_blocks: cfg.cache_blocks,
            subscreen: cfg.subscreen,
            stall_timeout: *stall_timeout,
            profile: cfg.profile.clone(),
            scheme: cfg.scheme,
            sequence: Sequence::default(),
            events: None,
            faults: faults.clone(),
        }),
    };
    let (prepared, cluster) = match (&cfg.mode, &in_process) {
        (Mode::Cluster { forks_at, listen, external_nodes, faults, .. }, Some(nodes)) => {
            faults.install_tls(!forks_at.is_empty() || *external_nodes)?;
            let shape = ClusterShape {
                forks: cfg.forks,
                forks_at: forks_at.clone(),
                listen: listen.clone(),
                token: faults.token.clone(),
                transport: cfg.transport,
            };
            // The forks prepare the scene, each its shares of space; refinement's
            // pilot light passes run on the cluster's nodes.
            let mut cluster = StartedCluster::start(&shape)?;
            (cluster.prepare(&scene, plan, nodes, &bars, cfg.shares)?, Some(cluster))
        }
        _ => {
            let mut local = LocalShareSet::default();
            (
                magg_prepare::refine::prepare_with(&scene, plan, &mut EmbeddedPilots, &bars, cfg.shares, &mut local)?,
                None,
            )
        }
    };
    if !prepared.splits.is_empty() {
        let (elements, pairs) = (prepared.elements.len() as u64, prepared.header.pair_count());
        crate::memory::check_refined(&scene, elements, pairs, cfg.max_memory_mb, forks_here)?;
    }
    // The render's clock: the stats' total is preprocessing plus what follows from here.
    let preprocessed = std::time::Instant::now();
    // Shared: the cluster's shard uploads send the scene's blocks without copying them.
    let prepared = Arc::new(prepared);
    if !cfg.quiet {
        eprint!("{}", prepared.header.plan);
    }
    let inputs = (cfg.save_energy.is_some() || cfg.load_energy.is_some()).then(|| EnergyInputs::of(&prepared));
    let energies = match (&cfg.load_energy, &inputs) {
        (Some(p), Some(now)) => Some(Arc::new(saved_energy::load(p, now)?)),
        _ => None,
    };
    // The path's frames in the range, each written under its number in the whole path.
    let n_path = path_cameras.len().max(1);
    let cameras = path_cameras.get(frame_numbers.clone()).map(<[_]>::to_vec).unwrap_or_default();
    let sequence = Sequence { energies, cameras, window };
    let n_frames = sequence.cameras.len().max(1);
    let exposure = scene.settings.exposure;
    // Time spent waiting for a viewer (--view-wait) is not the render's: the stats'
    // total leaves it out.
    let mut viewer_wait = std::time::Duration::ZERO;
    let live = match &cfg.view {
        Some((addr, wait, _)) => {
            let mut live = LiveView::start(addr)?;
            eprintln!("live view: {}", live.url());
            let mode = if cfg.mode == Mode::Embedded { "embedded" } else { "cluster" };
            let s = &scene.settings;
            live.begin(&prepared.name, s.width, s.height, exposure, mode, n_frames);
            let t_wait = std::time::Instant::now();
            if *wait && !live.wait_for_viewer(std::time::Duration::from_secs(600)) {
                tracing::warn!("no page opened the live view in 10 minutes: rendering anyway");
            }
            viewer_wait = t_wait.elapsed();
            if sequence.energies.is_none() && prepared.header.plan.lrt {
                let camera = sequence.cameras.first().unwrap_or(&prepared.header.camera);
                live.preview_light_pass(prepared.clone(), camera)?;
            }
            live.rendering(prepared.header.plan.pixel_samples);
            Some(live)
        }
        None => None,
    };
    let live_progress = live.as_ref().map(|l| l.progress(&bars, cfg.mode != Mode::Embedded));
    let shown: &dyn magg_core::progress::Progress = match &live_progress {
        Some(p) => p,
        None => &bars,
    };
    let partial_progress = image.progress(shown, cfg.mode != Mode::Embedded);
    let progress = &partial_progress;
    let mut records: Vec<FrameRecord> = Vec::with_capacity(n_frames);
    let mut sink = |index: usize, frame: &Frame, vrt_s: f64| -> Result<(), String> {
        let number = frame_numbers.start + index;
        let cropped = window.map(|w| frame.crop(w.x, w.y, w.w, w.h));
        let frame = cropped.as_ref().unwrap_or(frame);
        let out = frames::numbered(&cfg.out.0, number, n_path);
        images::write(frame, &out, cfg.out.1, exposure).map_err(|e| format!("{e:#}"))?;
        if let Some((path, fmt)) = &cfg.linear {
            images::write(frame, &frames::numbered(path, number, n_path), *fmt, exposure)
                .map_err(|e| format!("{e:#}"))?;
        }
        image.frame_written(index);
        records.push(FrameRecord { frame: number, out: out.display().to_string(), vrt_s });
        Ok(())
    };
    let out = match &cfg.mode {
        Mode::Embedded => render::render_sequence(&prepared, &opts, progress, &sequence, &mut sink)?,
        Mode::Cluster { .. } => {
            let mut in_process = in_process.take().context("the cluster's options were not set")?;
            in_process.sequence = sequence.clone();
            // The partial image sees every event first, then the live view.
            in_process.events = Some(
                image
                    .cluster_events(live.as_ref().map(|l| l.cluster_events()))
                    .context("starting the partial image's thread")?,
            );
            let cluster = cluster.context("the cluster was not started")?;
            cluster.render(&prepared, &in_process, preprocessed + viewer_wait, progress, &mut sink)?
        }
    };
    let mut stats = out.stats;
    stats.memory.host_bytes = magg_plumbing::memory::peak_rss_bytes();

    if let Some(path) = &cfg.energy {
        energy_csv::write(path, &prepared, &out.element_flux, &out.vertex_irradiance)
            .with_context(|| format!("cannot write energy file {}", path.display()))?;
    }
    if let (Some(path), Some(inputs)) = (&cfg.save_energy, &inputs) {
        let e = Energies { element_flux: out.element_flux.clone(), vertex_irradiance: out.vertex_irradiance.clone() };
        saved_energy::save(path, &prepared.name, inputs, &e)?;
    }
    let run = RunStats::new(&stats, read_s, cfg.load_energy.as_deref(), cfg.save_energy.as_deref(), records);
    if let Some(path) = &cfg.stats {
        let json = serde_json::to_string_pretty(&run)?;
        std::fs::write(path, json + "\n").with_context(|| format!("cannot write stats file {}", path.display()))?;
    }
    if !cfg.quiet {
        let s = &stats.stages;
        let lrt = match &cfg.load_energy {
            Some(p) => format!("LRT skipped (energies loaded from {})", p.display()),
            None => format!("LRT {:.2}s", s.lrt_s),
        };
        let frames = if n_frames > 1 { format!(" ({n_frames} frames)") } else { String::new() };
        // Under an emulated machine the stage times are the model's, not this machine's.
        let clock = if cfg.profile.is_native() {
            String::new()
        } else {
            format!(" (modelled seconds of the {} machine)", cfg.profile.name)
        };
        eprintln!(
            "{}: {}x{}, {} elements, {} nodes: read {read_s:.2}s, preprocess {:.2}s, {lrt}, interp {:.3}s, VRT {:.2}s{frames}, total {:.2}s{clock}; cache hit ratio {:.3} -> {}",
            stats.scene,
            out.frame.width,
            out.frame.height,
            stats.counts.elements,
            stats.nodes,
            s.preprocess_s,
            s.interp_s,
            s.vrt_s,
            s.total_s,
            stats.cache.hit_ratio,
            run.frames.last().map_or_else(|| cfg.out.0.display().to_string(), |f| f.out.clone())
        );
    }
    if let (Some(live), Some((_, _, linger))) = (&live, &cfg.view) {
        live.finish(&out.frame, exposure, &run)?;
        if *linger > 0 && !cfg.quiet {
            eprintln!("live view stays up at {} for {linger} s", live.url());
        }
        live.linger(*linger);
    }
    Ok(())
}
