//! `magg-host info SCENE`: counts and the effects plan.

use crate::cli::InfoArgs;
use crate::scene_file;

/// Prints the counts of the prepared scene and its plan.
pub fn run(args: &InfoArgs, files: &scene_file::SceneFiles) -> anyhow::Result<()> {
    let read_start = std::time::Instant::now();
    let (mut scene, _, mut chosen) = files.load_explained(&args.scene, &args.set.overrides()?)?;
    let read_s = read_start.elapsed().as_secs_f64();
    if let Some(q) = args.quality {
        q.apply(&mut scene);
        let s = &scene.settings;
        chosen.lines.push(format!(
            "--quality {q:?}: element_size {}, light_rays {}, pixel_samples {}, refine {}",
            s.element_size, s.light_rays, s.pixel_samples, s.refine
        ));
    }
    let p = magg_prepare::refine::prepare(&scene, magg_core::plan::EffectsPlan::for_scene(&scene))?;
    let h = &p.header;
    let c = h.counts;
    // What a render in one process would hold (the memory check's estimate, with the
    // cluster's five in-process forks).
    let memory_mb = crate::memory::estimate(&scene, 5).2 / (1u64 << 20) as f64;
    if args.json {
        let v = serde_json::json!({
            "scene": p.name,
            "lights": h.lights.len(),
            "emitters": h.emitters.len(),
            "pairs": h.pair_count(),
            "materials": h.materials.len(),
            "counts": c,
            "accel": h.settings.accel.name(),
            "grid": h.grid.dims,
            "bvh": h.bvh,
            "blocks": h.layout.total,
            "plan": { "passes": h.plan.passes(), "reasons": h.plan.reasons },
            "read_s": read_s,
            "chosen": chosen.lines,
            "preprocess_s": p.preprocess_s,
            "prepare": p.preparation,
            "memory_estimate_mb": memory_mb,
            "refined": p.splits.iter().map(Vec::len).collect::<Vec<_>>(),
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    println!("scene      {}", p.name);
    println!("lights     {}", h.lights.len());
    if !h.emitters.is_empty() {
        println!("emitters   {:>9}  emitting elements (area lights), {} pairs", h.emitters.len(), h.pair_count());
    }
    println!("materials  {}", h.materials.len());
    println!("patches    {:>9}  in {:>6} patch blocks", c.patches, c.patch_blocks);
    if c.shaded_patches > 0 {
        println!(
            "smooth     {:>9}  in {:>6} shading blocks (patches with vertex normals or a texture)",
            c.shaded_patches, c.shading_blocks
        );
    }
    println!("elements   {:>9}  in {:>6} element blocks", c.elements, c.element_blocks);
    if !p.splits.is_empty() {
        let split: Vec<String> = p.splits.iter().map(|r| r.len().to_string()).collect();
        println!("refined    {:>9}  levels, elements split per level: {}", p.splits.len(), split.join(", "));
    }
    println!("vertices   {:>9}  in {:>6} vertex-energy blocks", c.vertices, c.vertex_blocks);
    let g = h.grid.dims;
    println!(
        "subspaces  {:>9}  in {:>6} subspace blocks (grid {}x{}x{})",
        c.subspaces, c.subspace_blocks, g[0], g[1], g[2]
    );
    if c.bvh_blocks > 0 {
        let b = h.bvh;
        println!(
            "bvh nodes  {:>9}  in {:>6} node blocks, {} leaf triangles in {} blocks",
            b.nodes, b.node_blocks, b.triangles, b.triangle_blocks
        );
    }
    println!("accel      {}", h.settings.accel.name());
    println!("blocks     {:>9}  (2 KB each, {:.1} MB)", h.layout.total, h.layout.total as f64 * 2048.0 / 1e6);
    println!(
        "image      {}x{}, {} samples/pixel, {} light rays/pair",
        h.settings.width, h.settings.height, h.settings.pixel_samples, h.settings.light_rays
    );
    println!("read       {read_s:.3} s  (the scene file and its meshes)");
    println!("preprocess {:.3} s", p.preprocess_s);
    let f = &p.preparation;
    println!(
        "prepared   {:>9}  shares {}: plan {:.3} s, weld {:.3} s, accel {:.3} s, blocks {:.3} s",
        f.shares, f.place, f.plan_s, f.weld_s, f.accel_s, f.pack_s
    );
    println!("memory     about {memory_mb:.0} MB for a render in one process (the memory check's estimate)");
    for line in &chosen.lines {
        println!("chosen     {line}");
    }
    print!("{}", h.plan);
    Ok(())
}
