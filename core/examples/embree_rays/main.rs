//! The rays of `deploy/bench-embree.sh`: times magg's kernel on one thread over a scene's
//! primary rays and occlusion rays, and writes the same triangles and rays to a file for
//! the Embree harness (`deploy/embree/harness.c`) to trace.
//!
//! - **primary**: one ray through each pixel centre, nearest hit (`trace::cast`), in
//!   tiles of 4 x 4 pixels (left to right, then down);
//! - **occlusion**: from each light to the centroid of every k-th element, stopped
//!   1e-4 of the distance short of it (`trace::occluded`; Embree's f32 cannot stop
//!   closer), about `--occlusion` rays in all.
//!
//! Each is traced once to warm the block cache (unlimited), then timed `--repeats` times,
//! one ray at a time and then in packets of 16 consecutive rays (`trace::cast_all`,
//! `trace::occluded_all`: the rays of one origin walk the BVH together); the median rates
//! are printed as `magg primary MRAYS occlusion MRAYS hits P O ... packets MRAYS MRAYS`,
//! with the node visits and triangle tests per ray of both (a packet's node visit counts
//! once for all its rays).
//!
//! ```text
//! cargo run --release -p magg-core --example embree_rays -- scenes/large.toml --out /tmp/r.bin
//! cargo run --release -p magg-core --example embree_rays -- --random 50000 --out /tmp/r.bin
//! cargo run --release -p magg-core --example embree_rays -- --spheres 25 --out /tmp/r.bin
//! ```
//! The generated scenes (`--random`, `--spheres`, `--sphere-box`) are in `scenes.rs`.
//! File (little-endian): u32 triangles, u32 primary rays, u32 occlusion rays; then 9 x f32
//! per triangle; then 7 x f32 per ray (origin, direction, tmax).

use glam::DVec3;
use magg_core::blocks::{BlockCache, MemStore};
use magg_core::camera::CameraRig;
use magg_core::geometry::Ray;
use magg_core::prepared::PreparedScene;
use magg_core::scene::*;
use magg_core::trace::{cast, cast_all, occluded, occluded_all, Bundled, TraceScratch, NO_PATCH};
use magg_core::view::SceneView;
use magg_prepare::prepare;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Instant;

mod scenes;
use scenes::Generated;

struct Args {
    scene: Option<PathBuf>,
    generated: Option<Generated>,
    out: PathBuf,
    size: u32,
    occlusion: usize,
    repeats: usize,
}

fn parse_args() -> Result<Args, String> {
    let mut a = Args {
        scene: None,
        generated: None,
        out: PathBuf::from("rays.bin"),
        size: 400,
        occlusion: 200_000,
        repeats: 5,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or_else(|| format!("{flag} needs a value"));
        let num = |v: String| v.parse::<usize>().map_err(|e| format!("{flag}: {e}"));
        match flag.as_str() {
            "--random" => a.generated = Some(Generated::Random(num(value()?)?)),
            "--spheres" => a.generated = Some(Generated::Spheres(num(value()?)?)),
            "--sphere-box" => a.generated = Some(Generated::SphereBox),
            "--out" => a.out = PathBuf::from(value()?),
            "--size" => a.size = num(value()?)?.clamp(1, 16384) as u32,
            "--occlusion" => a.occlusion = num(value()?)?,
            "--repeats" => a.repeats = num(value()?)?.max(1),
            f if !f.starts_with("--") => a.scene = Some(PathBuf::from(f)),
            other => return Err(format!("unknown argument {other}")),
        }
    }
    if a.scene.is_none() && a.generated.is_none() {
        return Err(
            "usage: embree_rays (SCENE.toml | --random N | --spheres N | --sphere-box) [--out FILE] [--size PX] \
                    [--occlusion N] [--repeats N]"
                .into(),
        );
    }
    Ok(a)
}

fn load(a: &Args) -> Result<Scene, String> {
    let Some(path) = &a.scene else {
        return a.generated.map(scenes::generate).ok_or_else(|| "no scene".to_string());
    };
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let base = path.parent().unwrap_or(Path::new("."));
    parse_scene_str(&path.display().to_string(), &text, base, &|p: &Path| std::fs::read(p)).map_err(|e| e.to_string())
}

/// The primary rays, and the occlusion rays with their tmax.
fn rays(p: &PreparedScene, size: u32, occlusion: usize) -> (Vec<Ray>, Vec<(Ray, f64)>) {
    let rig = CameraRig::new(&p.header.camera, size, size);
    // In tiles of 4 x 4 pixels, so that 16 consecutive rays are neighbours.
    let mut primary = Vec::with_capacity((size * size) as usize);
    for ty in (0..size).step_by(4) {
        for tx in (0..size).step_by(4) {
            for y in ty..(ty + 4).min(size) {
                for x in tx..(tx + 4).min(size) {
                    primary.push(rig.ray(x as f64 + 0.5, y as f64 + 0.5));
                }
            }
        }
    }
    let pairs = p.header.lights.len() * p.elements.len();
    let step = (pairs / occlusion.max(1)).max(1);
    let mut shadow = Vec::new();
    for l in &p.header.lights {
        for e in p.elements.iter().step_by(step) {
            let d = e.centroid - l.position;
            let dist = d.length();
            if dist > 0.0 && dist.is_finite() {
                // 1e-4 short: Embree's f32 tfar could not stop shorter of the element.
                shadow.push((Ray::new(l.position, d / dist), dist * (1.0 - 1e-4)));
            }
        }
    }
    (primary, shadow)
}

/// Median seconds of `repeats` timed runs of `f` (after one untimed warm-up run), and
/// what `f` returned.
fn time<T>(repeats: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let warm = f();
    let mut secs: Vec<f64> = (0..repeats)
        .map(|_| {
            let t = Instant::now();
            std::hint::black_box(f());
            t.elapsed().as_secs_f64()
        })
        .collect();
    secs.sort_by(f64::total_cmp);
    (secs[secs.len() / 2], warm)
}

fn write(path: &Path, p: &PreparedScene, primary: &[Ray], shadow: &[(Ray, f64)]) -> std::io::Result<usize> {
    let mut out = Vec::new();
    let tris: Vec<[DVec3; 3]> = {
        let mut view = view(p);
        (0..p.header.counts.patches)
            .filter_map(|i| view.patch(i).ok().map(|r| r.v))
            .filter(|v| (v[1] - v[0]).cross(v[2] - v[0]) != DVec3::ZERO)
            .collect()
    };
    for n in [tris.len(), primary.len(), shadow.len()] {
        out.extend((n as u32).to_le_bytes());
    }
    let mut f32s = |xs: &[f64]| xs.iter().for_each(|x| out.extend((*x as f32).to_le_bytes()));
    for v in &tris {
        for c in v {
            f32s(&c.to_array());
        }
    }
    for (r, tmax) in primary.iter().map(|r| (r, f64::INFINITY)).chain(shadow.iter().map(|(r, t)| (r, *t))) {
        f32s(&[r.origin.x, r.origin.y, r.origin.z, r.direction.x, r.direction.y, r.direction.z, tmax]);
    }
    std::fs::File::create(path)?.write_all(&out)?;
    Ok(tris.len())
}

fn view(p: &PreparedScene) -> SceneView {
    SceneView::new(p.header.clone(), BlockCache::new(Arc::new(MemStore::new(p.blocks.clone())), None))
}

fn main() -> ExitCode {
    let run = || -> Result<(), String> {
        let a = parse_args()?;
        let mut scene = load(&a)?;
        scene.settings.accel = Accel::Bvh;
        let p = prepare(&scene).map_err(|e| e.to_string())?;
        let (primary, shadow) = rays(&p, a.size, a.occlusion);
        let triangles = write(&a.out, &p, &primary, &shadow).map_err(|e| format!("{}: {e}", a.out.display()))?;
        let mut v = view(&p);
        let mut scratch = TraceScratch::default();
        let (tp, hits_p) = time(a.repeats, || {
            primary
                .iter()
                .filter(|r| cast(&mut v, &mut scratch, r, 0.0, f64::INFINITY, NO_PATCH, false).ok().flatten().is_some())
                .count()
        });
        let (to, hits_o) = time(a.repeats, || {
            shadow.iter().filter(|(r, t)| occluded(&mut v, &mut scratch, r, 0.0, *t, NO_PATCH).unwrap_or(false)).count()
        });
        let bundled_p: Vec<Bundled> =
            primary.iter().map(|r| Bundled { ray: *r, tmin: 0.0, tmax: f64::INFINITY, exclude: NO_PATCH }).collect();
        let bundled_o: Vec<Bundled> =
            shadow.iter().map(|(r, t)| Bundled { ray: *r, tmin: 0.0, tmax: *t, exclude: NO_PATCH }).collect();
        let (mut hits, mut occ) = (Vec::new(), Vec::new());
        let (tpp, packed_p) = time(a.repeats, || {
            cast_all(&mut v, &mut scratch, &bundled_p, &mut hits).map(|()| hits.iter().flatten().count())
        });
        let (top, packed_o) = time(a.repeats, || {
            occluded_all(&mut v, &mut scratch, &bundled_o, &mut occ).map(|()| occ.iter().filter(|o| **o).count())
        });
        if packed_p != Ok(hits_p) || packed_o != Ok(hits_o) {
            return Err(format!("packets hit {packed_p:?} {packed_o:?}, single rays {hits_p} {hits_o}"));
        }
        // Node visits and patch tests per ray, from one more pass of each kind.
        let mut per_ray = |rays: usize, pass: &mut dyn FnMut(&mut SceneView, &mut TraceScratch)| {
            let (n0, t0) = (v.counters.grid_steps, v.counters.patch_tests);
            pass(&mut v, &mut scratch);
            let n = rays.max(1) as f64;
            ((v.counters.grid_steps - n0) as f64 / n, (v.counters.patch_tests - t0) as f64 / n)
        };
        let (np, tsp) = per_ray(primary.len(), &mut |v, s| {
            primary.iter().for_each(|r| drop(cast(v, s, r, 0.0, f64::INFINITY, NO_PATCH, false)))
        });
        let (no, tso) = per_ray(shadow.len(), &mut |v, s| {
            shadow.iter().for_each(|(r, t)| drop(occluded(v, s, r, 0.0, *t, NO_PATCH)))
        });
        let (pnp, ptp) = per_ray(primary.len(), &mut |v, s| drop(cast_all(v, s, &bundled_p, &mut Vec::new())));
        let (pno, pto) = per_ray(shadow.len(), &mut |v, s| drop(occluded_all(v, s, &bundled_o, &mut Vec::new())));
        println!(
            "magg triangles {triangles} primary {:.3} occlusion {:.3} hits {hits_p} {hits_o} \
             nodes/ray {np:.1} {no:.1} tests/ray {tsp:.1} {tso:.1} \
             packed nodes/ray {pnp:.2} {pno:.2} tests/ray {ptp:.1} {pto:.1} packets {:.3} {:.3}",
            primary.len() as f64 / tp / 1e6,
            shadow.len() as f64 / to / 1e6,
            primary.len() as f64 / tpp / 1e6,
            shadow.len() as f64 / top / 1e6
        );
        Ok(())
    };
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("embree_rays: {e}");
            ExitCode::FAILURE
        }
    }
}
