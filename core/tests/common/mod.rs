//! Scene builders for the core's integration tests.
#![allow(dead_code)]

use glam::DVec3;
use magg_core::blocks::{BlockCache, CacheSize, MemStore};
use magg_core::color::Rgb;
use magg_core::machine::RenderOutput;
use magg_core::prepared::PreparedScene;
use magg_core::progress::NoProgress;
use magg_core::render::{render, RenderOptions};
use magg_core::scene::*;
use magg_core::view::SceneView;
use magg_prepare::prepare;
use std::sync::Arc;

pub fn v(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

pub fn loc() -> SourceLoc {
    SourceLoc { file: "<test>".into(), line: 0 }
}

pub fn material(name: &str, diffuse: f64, mirror: f64, transmit: f64) -> Material {
    Material {
        name: name.into(),
        diffuse: Rgb::splat(diffuse),
        mirror: Rgb::splat(mirror),
        transmit: Rgb::splat(transmit),
        ior: 1.5,
        one_sided: false,
        emit: Rgb::BLACK,
        loc: loc(),
    }
}

pub fn light(p: DVec3, i: f64) -> Light {
    Light { position: p, intensity: Rgb::splat(i), spot: None, loc: loc() }
}

/// A quad (a, b, c, d), counter-clockwise from the front, as two triangles sharing n.
pub fn quad(a: DVec3, b: DVec3, c: DVec3, d: DVec3, material: u32, n: u32) -> Vec<PatchDef> {
    vec![tri(a, b, c, material, n), tri(a, c, d, material, n)]
}

/// An axis-aligned box from `lo` to `hi` with faces facing inward (a room) or outward.
pub fn boxed(lo: DVec3, hi: DVec3, material: u32, n: u32, inward: bool) -> Vec<PatchDef> {
    let c = |x: bool, y: bool, z: bool| {
        v(if x { hi.x } else { lo.x }, if y { hi.y } else { lo.y }, if z { hi.z } else { lo.z })
    };
    // Outward-facing faces, counter-clockwise seen from outside.
    let faces = [
        [c(false, false, false), c(false, false, true), c(false, true, true), c(false, true, false)], // -x
        [c(true, false, false), c(true, true, false), c(true, true, true), c(true, false, true)],     // +x
        [c(false, false, false), c(true, false, false), c(true, false, true), c(false, false, true)], // -y
        [c(false, true, false), c(false, true, true), c(true, true, true), c(true, true, false)],     // +y
        [c(false, false, false), c(false, true, false), c(true, true, false), c(true, false, false)], // -z
        [c(false, false, true), c(true, false, true), c(true, true, true), c(false, true, true)],     // +z
    ];
    faces
        .iter()
        .flat_map(|f| {
            if inward {
                quad(f[3], f[2], f[1], f[0], material, n)
            } else {
                quad(f[0], f[1], f[2], f[3], material, n)
            }
        })
        .collect()
}

/// Triangle of element `e` of a prepared scene whose patches fix their subdivisions.
pub fn element_tri(s: &Scene, p: &PreparedScene, e: usize) -> [DVec3; 3] {
    let info = p.elements[e];
    let patch = &s.patches[info.patch as usize];
    // The first element of the same patch and face (back elements follow all the fronts).
    let first = p.elements.iter().position(|x| x.patch == info.patch && x.face == info.face).unwrap();
    magg_core::subdivision::element_triangle(&patch.vertices, patch.subdivisions.unwrap(), (e - first) as u32)
}

/// Whether light from point `from` arrives on the face of its patch that element `e`
/// holds (always for an element of both faces).
pub fn faces_towards(s: &Scene, p: &PreparedScene, e: usize, from: DVec3) -> bool {
    let info = p.elements[e];
    let normal = magg_core::geometry::triangle_normal(&s.patches[info.patch as usize].vertices);
    info.face.takes(from - info.centroid, normal)
}

pub fn scene(patches: Vec<PatchDef>, materials: Vec<Material>, lights: Vec<Light>) -> Scene {
    Scene {
        name: "<test>".into(),
        camera: Camera { eye: v(0.0, 1.0, 3.0), look_at: v(0.0, 0.5, 0.0), up: v(0.0, 1.0, 0.0), fov_y_deg: 50.0 },
        settings: RenderSettings {
            width: 32,
            height: 32,
            pixel_samples: 1,
            light_rays: 16,
            // The suites check the light pass's element energies against closed forms, so
            // light rays deposit direct light; tests/direct_light.rs checks it at VRT.
            direct: magg_core::scene::DirectLight::Lrt,
            ..RenderSettings::default()
        },
        lights,
        materials,
        patches,
        textures: Vec::new(),
    }
}

pub fn run(p: &PreparedScene, nodes: u32, cache: Option<u64>) -> RenderOutput {
    render(
        p,
        &RenderOptions { nodes, forks: 5, cache_blocks: CacheSize::from_blocks(cache), subscreen: 8 },
        &NoProgress,
    )
    .expect("render")
}

pub fn prepare_and_run(s: &Scene) -> (PreparedScene, RenderOutput) {
    let p = prepare(s).expect("prepare");
    let o = run(&p, 2, None);
    (p, o)
}

/// A node's view of a prepared scene with an unlimited cache.
pub fn view_of(p: &PreparedScene) -> SceneView {
    let store = Arc::new(MemStore::new(p.blocks.clone()));
    SceneView::new(p.header.clone(), BlockCache::new(store, None))
}

/// A single triangle patch with a fixed subdivision count.
pub fn tri(a: DVec3, b: DVec3, c: DVec3, material: u32, n: u32) -> PatchDef {
    PatchDef {
        vertices: [a, b, c],
        material,
        subdivisions: Some(n),
        size_hint: None,
        normals: None,
        uv: None,
        texture: None,
        loc: loc(),
    }
}

/// A closed octahedron of 8 patches (vertices at +-1 on each axis, outward winding),
/// n elements per patch edge, one white material, one light at `light_at`, traced
/// through a fixed `grid` of subspaces.
pub fn octahedron(n: u32, light_at: DVec3, grid: [u32; 3]) -> Scene {
    let (px, nx, py, ny, pz, nz) =
        (v(1.0, 0.0, 0.0), v(-1.0, 0.0, 0.0), v(0.0, 1.0, 0.0), v(0.0, -1.0, 0.0), v(0.0, 0.0, 1.0), v(0.0, 0.0, -1.0));
    let faces = [
        [px, py, pz],
        [py, nx, pz],
        [nx, ny, pz],
        [ny, px, pz],
        [py, px, nz],
        [nx, py, nz],
        [ny, nx, nz],
        [px, ny, nz],
    ];
    let patches = faces.iter().map(|f| tri(f[0], f[1], f[2], 0, n)).collect();
    let mut s = scene(patches, vec![material("white", 0.5, 0.0, 0.0)], vec![light(light_at, 1.0)]);
    s.settings.grid = GridSpec::Fixed(grid);
    s.settings.accel = magg_core::scene::Accel::Grid;
    s
}

/// The head of a TOML scene seen from straight above a floor at y = 0: a 32 x 32 image,
/// one viewing ray per pixel, no ambient, one light at (0.3, 1.5, 0.2) of 2 W/sr, and a
/// white diffuse material (0.5). Tests append their `[[mesh]]`.
#[allow(dead_code)]
pub const TOP_DOWN_HEAD: &str = r#"
[camera]
eye = [0.0, 3.0, 0.01]
look_at = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov = 60.0
[render]
width = 32
height = 32
pixel_samples = 1
light_rays = 16
ambient = [0.0, 0.0, 0.0]
[[light]]
position = [0.3, 1.5, 0.2]
intensity = [2.0, 2.0, 2.0]
[[material]]
name = "white"
diffuse = [0.5, 0.5, 0.5]
"#;
