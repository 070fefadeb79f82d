//! The generated scenes of the Embree benchmark: the random triangles, and the two
//! scenes of the kernel issue's table that are not in `scenes/` (25 spheres in a box; a
//! box with a block and a sphere), rebuilt from their triangle counts.

use glam::DVec3;
use magg_core::color::Rgb;
use magg_core::rng::Rng;
use magg_core::scene::*;

/// A scene the benchmark makes up.
#[derive(Clone, Copy, Debug)]
pub enum Generated {
    /// `n` random triangles in a closed box (`--random N`).
    Random(usize),
    /// `n` spheres of 2 208 triangles in an open box (`--spheres N`; 25: 55 210 triangles).
    Spheres(usize),
    /// An open box with a block and a sphere of 3 968 triangles (`--sphere-box`: 3 988).
    SphereBox,
}

/// The scene `g`.
pub fn generate(g: Generated) -> Scene {
    match g {
        Generated::Random(n) => random(n),
        Generated::Spheres(n) => spheres(n),
        Generated::SphereBox => sphere_box(),
    }
}

fn loc(what: &str) -> SourceLoc {
    SourceLoc { file: format!("<{what}>").into(), line: 0 }
}

fn c(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

/// A one-element triangle patch of the white material.
fn tri(v: [DVec3; 3], what: &str) -> PatchDef {
    PatchDef {
        vertices: v,
        material: 0,
        subdivisions: Some(1),
        size_hint: None,
        normals: None,
        uv: None,
        texture: None,
        loc: loc(what),
    }
}

/// A white scene of `patches` seen by `camera`, lit by one light at `light`.
fn white(name: String, patches: Vec<PatchDef>, camera: Camera, light: DVec3) -> Scene {
    Scene {
        name,
        camera,
        settings: RenderSettings { max_elements: u64::MAX, ..RenderSettings::default() },
        lights: vec![Light { position: light, intensity: Rgb::splat(1.0), spot: None, loc: loc("light") }],
        materials: vec![Material {
            name: "white".into(),
            diffuse: Rgb::splat(0.5),
            mirror: Rgb::BLACK,
            transmit: Rgb::BLACK,
            ior: 1.5,
            one_sided: false,
            emit: Rgb::BLACK,
            loc: loc("material"),
        }],
        patches,
        textures: Vec::new(),
    }
}

/// The faces of the box `lo`..`hi` (two triangles each, facing in or out), leaving out
/// those listed in `open` (0..6: -x, +x, -y, +y, -z, +z).
fn box_faces(lo: DVec3, hi: DVec3, inward: bool, open: &[usize], what: &str) -> Vec<PatchDef> {
    let p = |x: bool, y: bool, z: bool| {
        c(if x { hi.x } else { lo.x }, if y { hi.y } else { lo.y }, if z { hi.z } else { lo.z })
    };
    // Outward-facing, counter-clockwise seen from outside.
    let faces = [
        [p(false, false, false), p(false, false, true), p(false, true, true), p(false, true, false)],
        [p(true, false, false), p(true, true, false), p(true, true, true), p(true, false, true)],
        [p(false, false, false), p(true, false, false), p(true, false, true), p(false, false, true)],
        [p(false, true, false), p(false, true, true), p(true, true, true), p(true, true, false)],
        [p(false, false, false), p(false, true, false), p(true, true, false), p(true, false, false)],
        [p(false, false, true), p(true, false, true), p(true, true, true), p(false, true, true)],
    ];
    let mut out = Vec::new();
    for (_, [a, b, cc, d]) in faces.into_iter().enumerate().filter(|(k, _)| !open.contains(k)) {
        if inward {
            out.push(tri([d, cc, b], what));
            out.push(tri([d, b, a], what));
        } else {
            out.push(tri([a, b, cc], what));
            out.push(tri([a, cc, d], what));
        }
    }
    out
}

/// A UV sphere of `segments` x `rings` (2 segments (rings - 1) triangles), each
/// triangle wound to face out.
fn uv_sphere(center: DVec3, radius: f64, segments: usize, rings: usize) -> Vec<PatchDef> {
    use std::f64::consts::PI;
    let p = |i: usize, j: usize| {
        let (theta, phi) = (PI * i as f64 / rings as f64, 2.0 * PI * j as f64 / segments as f64);
        center + c(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()) * radius
    };
    let outward = |v: [DVec3; 3]| {
        let n = (v[1] - v[0]).cross(v[2] - v[0]);
        if n.dot((v[0] + v[1] + v[2]) / 3.0 - center) >= 0.0 {
            v
        } else {
            [v[0], v[2], v[1]]
        }
    };
    let mut out = Vec::new();
    for i in 0..rings {
        for j in 0..segments {
            let (a, b, cc, d) = (p(i, j), p(i, j + 1), p(i + 1, j + 1), p(i + 1, j));
            // The poles' rows are fans: their quads have lost a corner.
            if i > 0 {
                out.push(tri(outward([a, b, cc]), "sphere"));
            }
            if i + 1 < rings {
                out.push(tri(outward([a, cc, d]), "sphere"));
            }
        }
    }
    out
}

/// The camera in front of the open side (+z) of the box [-4, 4]^3.
fn front_camera() -> Camera {
    Camera { eye: c(0.0, 0.0, 11.0), look_at: c(0.0, 0.0, 0.0), up: c(0.0, 1.0, 0.0), fov_y_deg: 45.0 }
}

/// `n` spheres of radius 0.7 and 48 x 24 segments on a square grid in the box
/// [-4, 4]^3, open towards the camera.
fn spheres(n: usize) -> Scene {
    let mut patches = box_faces(c(-4.0, -4.0, -4.0), c(4.0, 4.0, 4.0), true, &[5], "box");
    let k = (n as f64).sqrt().ceil().max(1.0) as usize;
    let at = |i: usize| -3.2 + 6.4 * i as f64 / (k.max(2) - 1) as f64;
    for s in 0..n {
        patches.extend(uv_sphere(c(at(s % k), at(s / k), -1.0), 0.7, 48, 24));
    }
    white(format!("spheres-{n}"), patches, front_camera(), c(0.3, 3.5, 2.0))
}

/// The box [-4, 4]^3 open towards the camera, a block standing on its floor and a
/// sphere of 64 x 32 segments beside it.
fn sphere_box() -> Scene {
    let mut patches = box_faces(c(-4.0, -4.0, -4.0), c(4.0, 4.0, 4.0), true, &[5], "box");
    patches.extend(box_faces(c(-3.0, -4.0, -3.0), c(-1.0, -1.5, -1.0), false, &[2], "block"));
    patches.extend(uv_sphere(c(1.5, -2.5, -1.0), 1.5, 64, 32));
    white("sphere-box".into(), patches, front_camera(), c(0.3, 3.5, 2.0))
}

/// `n` random triangles (edges up to about 0.3) in a closed box [-4, 4]^3, one light.
fn random(n: usize) -> Scene {
    let mut rng = Rng::from_words(&[n as u64, 0xe5b]);
    let mut u = move || rng.next_f64() * 2.0 - 1.0;
    // The box's walls (the material is two-sided: which way they face does not matter).
    let mut patches = box_faces(c(-4.0, -4.0, -4.0), c(4.0, 4.0, 4.0), false, &[], "random");
    while patches.len() < n {
        let p = c(u() * 3.0, u() * 3.0, u() * 3.0);
        let mut corner = || p + c(u(), u(), u()) * 0.15;
        patches.push(tri([corner(), corner(), corner()], "random"));
    }
    let camera = Camera { eye: c(0.0, 0.0, 3.9), look_at: c(0.0, 0.0, 0.0), up: c(0.0, 1.0, 0.0), fov_y_deg: 60.0 };
    white(format!("random-{n}"), patches, camera, c(0.5, 3.5, 0.5))
}
