//! `magg-host render SCENE --out IMAGE`: the main job.

use crate::cli::{Mode, RenderConfig};
use crate::cluster::{render_in_process, InProcessOptions};
use crate::{energy_csv, images, progress::Bars, scene_file};
use anyhow::Context;
use magg_core::plan::EffectsPlan;
use magg_core::{preprocess, render};

/// Renders per `cfg` and writes every requested output.
pub fn run(cfg: RenderConfig) -> anyhow::Result<()> {
    let mut scene = scene_file::load(&cfg.scene)?;
    if let Some(q) = cfg.quality {
        q.apply(&mut scene);
    }
    cfg.knobs.apply(&mut scene.settings)?;
    crate::memory::check(&scene, cfg.max_memory_mb)?;
    let plan = if cfg.all_effects { EffectsPlan::forced_on(&scene) } else { EffectsPlan::for_scene(&scene) };
    let prepared = preprocess::prepare_with_plan(&scene, plan)?;
    if !cfg.quiet {
        eprint!("{}", prepared.header.plan);
    }
    let opts = render::RenderOptions {
        nodes: cfg.nodes,
        forks: cfg.forks,
        cache_blocks: cfg.cache_blocks,
        subscreen: cfg.subscreen,
    };
    let bars = Bars::new(cfg.quiet);
    let out = match &cfg.mode {
        Mode::Embedded => render::render(&prepared, &opts, &bars)?,
        Mode::Cluster { forks_at, listen, external_nodes, stall_timeout, faults } => {
            let cluster = InProcessOptions {
                nodes: if *external_nodes { 0 } else { opts.node_count() },
                forks: cfg.forks,
                forks_at: forks_at.clone(),
                listen: listen.clone(),
                cache_blocks: cfg.cache_blocks,
                subscreen: cfg.subscreen,
                stall_timeout: *stall_timeout,
                faults: faults.clone(),
            };
            render_in_process(&prepared, &cluster, &bars)?
        }
    };
    let mut stats = out.stats;
    stats.profile = cfg.profile.clone();

    images::write(&out.frame, &cfg.out.0, cfg.out.1, scene.settings.exposure)?;
    if let Some((path, fmt)) = &cfg.linear {
        images::write(&out.frame, path, *fmt, scene.settings.exposure)?;
    }
    if let Some(path) = &cfg.energy {
        energy_csv::write(path, &prepared, &out.element_flux, &out.vertex_irradiance)
            .with_context(|| format!("cannot write energy file {}", path.display()))?;
    }
    if let Some(path) = &cfg.stats {
        let json = serde_json::to_string_pretty(&stats)?;
        std::fs::write(path, json + "\n").with_context(|| format!("cannot write stats file {}", path.display()))?;
    }
    if !cfg.quiet {
        let s = &stats.stages;
        eprintln!(
            "{}: {}x{}, {} elements, {} nodes: preprocess {:.2}s, LRT {:.2}s, interp {:.3}s, VRT {:.2}s, total {:.2}s; cache hit ratio {:.3} -> {}",
            stats.scene,
            out.frame.width,
            out.frame.height,
            stats.counts.elements,
            stats.nodes,
            s.preprocess_s,
            s.lrt_s,
            s.interp_s,
            s.vrt_s,
            s.total_s,
            stats.cache.hit_ratio,
            cfg.out.0.display()
        );
    }
    Ok(())
}
