//! Smooth shading normals (OBJ `vn`, PLY and glTF normals, or made behind a mesh's
//! `crease_angle`): read and placed right, bitwise neutral where they equal the face's
//! normal, the cosine of direct light taken with them (closed form), energy conserved by
//! the specular bounces they bend, and no NaN at grazing angles.

mod common;
#[path = "common/hard.rs"]
mod hard;

use common::*;
use glam::DVec3;
use hard::{accounted, assert_render_finite};
use magg_core::camera::CameraRig;
use magg_core::scene::{parse_scene_str, DirectLight, Scene};
use std::collections::HashMap;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

/// Parses `toml` with the in-memory files `files` (path relative to the scene's folder)
/// and, for any other path, the repository's own files (`meshes/sphere.obj`).
fn parse(toml: &str, files: &[(&str, &str)]) -> Scene {
    let files: HashMap<PathBuf, Vec<u8>> =
        files.iter().map(|(p, t)| (Path::new("mem").join(p), t.as_bytes().to_vec())).collect();
    let read = move |p: &Path| match files.get(p) {
        Some(b) => Ok(b.clone()),
        None => std::fs::read(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes").join(p.strip_prefix("mem").unwrap_or(p)),
        ),
    };
    parse_scene_str("s.toml", toml, Path::new("mem"), &read).unwrap_or_else(|e| panic!("{e}"))
}

const HEAD: &str = TOP_DOWN_HEAD;

/// A 4 x 4 floor quad at y = 0 (two triangles, wound upward) whose corners all carry the
/// normal `n` (`None`: no `vn`).
fn floor_obj(n: Option<[f64; 3]>) -> String {
    let mut s = String::from("v -2 0 -2\nv -2 0 2\nv 2 0 2\nv 2 0 -2\n");
    match n {
        Some([x, y, z]) => s += &format!("vn {x} {y} {z}\nf 1//1 2//1 3//1\nf 1//1 3//1 4//1\n"),
        None => s += "f 1 2 3\nf 1 3 4\n",
    }
    s
}

fn mesh_entry(file: &str, extra: &str) -> String {
    format!("[[mesh]]\nfile = \"{file}\"\nmaterial = \"white\"\nsubdivisions = 4\n{extra}\n")
}

#[test]
fn obj_normals_become_unit_patch_normals_and_normals_false_drops_them() {
    let obj = floor_obj(Some([0.0, 2.0, 1.0]));
    let s = parse(&format!("{HEAD}{}", mesh_entry("f.obj", "")), &[("f.obj", &obj)]);
    let want = DVec3::new(0.0, 2.0, 1.0).normalize();
    for p in &s.patches {
        let n = p.normals.expect("vn read");
        for c in n {
            assert!((c - want).length() < 1e-15, "{c:?}");
        }
    }
    let s = parse(&format!("{HEAD}{}", mesh_entry("f.obj", "normals = false")), &[("f.obj", &obj)]);
    assert!(s.patches.iter().all(|p| p.normals.is_none()));
    // A transform bends normals by the inverse transpose: squashing y tilts them.
    let s = parse(&format!("{HEAD}{}", mesh_entry("f.obj", "scale = [1.0, 0.5, 1.0]")), &[("f.obj", &obj)]);
    let want = DVec3::new(0.0, 4.0, 1.0).normalize();
    assert!((s.patches[0].normals.unwrap()[0] - want).length() < 1e-15);
}

#[test]
fn bad_normals_are_scene_errors_with_file_and_line() {
    let read = |p: &Path| -> std::io::Result<Vec<u8>> {
        match p.file_name().and_then(|n| n.to_str()) {
            Some("two.obj") => Ok(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 1\nf 1//1 2//1 3//1\n".to_vec()),
            _ => Ok(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//2 3//1\n".to_vec()),
        }
    };
    for (file, line, says) in [("two.obj", 4, "vn needs 3 numbers"), ("range.obj", 5, "normal index 2 is out of range")]
    {
        let toml = format!("{HEAD}{}", mesh_entry(file, ""));
        let e = parse_scene_str("s.toml", &toml, Path::new("mem"), &read).unwrap_err().to_string();
        assert!(e.contains(&format!("{file}:{line}")) && e.contains(says), "{e}");
    }
    let toml = format!("{HEAD}{}", mesh_entry("x.obj", "crease_angle = 200.0"));
    let e = parse_scene_str("s.toml", &toml, Path::new("mem"), &read).unwrap_err().to_string();
    assert!(e.contains("mesh[0].crease_angle") && e.contains("out of range"), "{e}");
}

#[test]
fn a_crease_angle_smooths_the_sphere_and_keeps_a_cube_faceted() {
    let s = parse(&format!("{HEAD}{}", mesh_entry("meshes/sphere.obj", "crease_angle = 60.0")), &[]);
    assert_eq!(s.patches.len(), 1280);
    let mut worst: f64 = 1.0;
    for p in &s.patches {
        let n = p.normals.expect("every face of the sphere is smoothed");
        for (c, q) in n.iter().zip(p.vertices) {
            // The icosphere's vertices lie on the unit sphere: the smooth normal is radial.
            worst = worst.min(c.dot(q.normalize()));
        }
    }
    assert!(worst > 0.999, "smallest cosine to the radial direction {worst}");
    // A cube: faces meet at 90 degrees, beyond a 60 degree crease: normals stay the faces'.
    let mut cube = String::new();
    for v in 0..8 {
        cube += &format!("v {} {} {}\n", v & 1, (v >> 1) & 1, (v >> 2) & 1);
    }
    cube += "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n";
    let s = parse(&format!("{HEAD}{}", mesh_entry("cube.obj", "crease_angle = 60.0")), &[("cube.obj", &cube)]);
    for p in &s.patches {
        let ng = (p.vertices[1] - p.vertices[0]).cross(p.vertices[2] - p.vertices[0]).normalize();
        for c in p.normals.unwrap() {
            assert!((c - ng).length() < 1e-12, "{c:?} on a face of normal {ng:?}");
        }
    }
}

#[test]
fn normals_equal_to_the_face_give_the_flat_image_bit_for_bit() {
    for direct in [DirectLight::Vrt, DirectLight::Lrt] {
        let render = |n| {
            let mut s = parse(&format!("{HEAD}{}", mesh_entry("f.obj", "")), &[("f.obj", &floor_obj(n))]);
            s.settings.direct = direct;
            let (p, out) = prepare_and_run(&s);
            (p.header.counts.shaded_patches, out.frame.pixels.clone(), out.element_flux)
        };
        let (flat_count, flat, flat_flux) = render(None);
        let (smooth_count, smooth, smooth_flux) = render(Some([0.0, 1.0, 0.0]));
        assert_eq!((flat_count, smooth_count), (0, 2));
        assert_eq!(flat, smooth, "{direct:?}");
        assert_eq!(flat_flux, smooth_flux, "{direct:?}");
    }
}

#[test]
fn direct_light_takes_the_cosine_of_the_shading_normal() {
    // Every corner's normal tilted 30 degrees towards +x: the floor is shaded as if it
    // faced that way, I max(0, n_s . w) / r^2, while staying where it is.
    let t = DVec3::new(0.5, 3f64.sqrt() / 2.0, 0.0);
    let toml = format!("{HEAD}{}", mesh_entry("f.obj", ""));
    let mut s = parse(&toml, &[("f.obj", &floor_obj(Some(t.to_array())))]);
    s.settings.direct = DirectLight::Vrt;
    // Low enough that the tilted normal turns away from it past x = 1.17.
    let (lp, intensity, rho) = (DVec3::new(0.3, 0.5, 0.2), 2.0, 0.5);
    s.lights[0].position = lp;
    let (_, out) = prepare_and_run(&s);
    let rig = CameraRig::new(&s.camera, s.settings.width, s.settings.height);
    let (mut lit, mut dark) = (0, 0);
    for y in 0..s.settings.height {
        for x in 0..s.settings.width {
            let r = rig.ray(x as f64 + 0.5, y as f64 + 0.5);
            let p = r.at(-r.origin.y / r.direction.y);
            if p.x.abs() > 1.9 || p.z.abs() > 1.9 {
                continue;
            }
            let d = lp - p;
            let r2 = d.length_squared();
            let cos = t.dot(d / r2.sqrt());
            let want = rho / PI * intensity * cos.max(0.0) / r2;
            let got = out.frame.get(x, y)[0] as f64;
            // The stored normal is rounded to f32.
            assert!((got - want).abs() <= 1e-6 * want.max(1e-3), "pixel ({x}, {y}): {got} vs {want}");
            if want > 0.0 {
                lit += 1;
            } else {
                dark += 1;
            }
        }
    }
    assert!(lit > 300 && dark > 20, "{lit} lit and {dark} dark pixels checked");
}

/// A closed box of diffuse walls around the icosphere at the origin (radius 0.5),
/// smooth (`crease_angle`) or flat, with `sphere` as its material's parts.
fn sphere_in_a_box(smooth: bool, mirror: f64, transmit: f64) -> Scene {
    let toml = format!(
        "{HEAD}[[material]]\nname = \"ball\"\nmirror = [{mirror}, {mirror}, {mirror}]\ntransmit = [{transmit}, {transmit}, {transmit}]\nior = 1.5\n\
         [[mesh]]\nfile = \"meshes/sphere.obj\"\nmaterial = \"ball\"\nscale = 0.5\ntranslate = [0.0, 0.6, 0.0]\nsubdivisions = 1\n{}\n",
        if smooth { "crease_angle = 60.0" } else { "" }
    );
    let mut s = parse(&toml, &[]);
    s.patches.extend(boxed(v(-1.0, 0.0, -1.0), v(1.0, 2.0, 1.0), 0, 3, true));
    s.lights[0].position = v(0.13, 1.61, -0.07);
    s.settings.direct = DirectLight::Lrt;
    s.settings.lrt_depth = 6;
    s.settings.light_rays = 8;
    s
}

#[test]
fn bent_specular_bounces_conserve_energy_in_a_closed_box() {
    let emitted = 4.0 * PI * 2.0;
    for (mirror, transmit) in [(1.0, 0.0), (0.0, 1.0), (0.4, 0.6)] {
        let (mut fluxes, mut reached_by) = (Vec::new(), Vec::new());
        for smooth in [false, true] {
            let s = sphere_in_a_box(smooth, mirror, transmit);
            let (p, out) = prepare_and_run(&s);
            assert_eq!(p.header.counts.shaded_patches > 0, smooth);
            assert_render_finite("sphere in a box", &out);
            let t = out.stats.light;
            // Primary light rays do not depend on the normals; what they bring is about
            // the light's 4 pi I (the sphere's partial shadows are sampled per ray).
            let reached = t.reached.0[0];
            assert!((reached - emitted).abs() < 1e-3 * emitted, "{t:?}");
            reached_by.push(reached);
            // No bent ray leaves a closed box or goes through a wall.
            assert_eq!(t.escaped.0[0], 0.0, "smooth {smooth}, mirror {mirror}, transmit {transmit}");
            assert!((accounted(&t) - reached).abs() < 1e-12 * reached, "{t:?}");
            fluxes.push(out.element_flux);
        }
        // The normals do change where the light goes (the caustic and reflections).
        assert_ne!(fluxes[0], fluxes[1]);
        assert!((reached_by[0] - reached_by[1]).abs() < 1e-12 * emitted);
    }
}

#[test]
fn grazing_views_of_smooth_glass_and_tilted_normals_stay_finite() {
    // The camera skims the sphere's silhouette, where viewing rays meet the surface at
    // grazing angles and interpolated normals face away from them.
    let mut s = sphere_in_a_box(true, 0.3, 0.7);
    s.camera.eye = v(0.0, 0.6, 0.98);
    s.camera.look_at = v(0.5, 0.6, 0.0);
    s.settings.direct = DirectLight::Vrt;
    s.settings.vrt_depth = 6;
    let (_, out) = prepare_and_run(&s);
    assert_render_finite("grazing smooth glass", &out);
    // Normals nearly in the plane of their face (pulled to the front), lit from the side.
    let obj = floor_obj(Some([1.0, 1e-9, 0.0]));
    let mut s = parse(&format!("{HEAD}{}", mesh_entry("f.obj", "")), &[("f.obj", &obj)]);
    s.settings.direct = DirectLight::Vrt;
    let (_, out) = prepare_and_run(&s);
    assert_render_finite("normals in the plane", &out);
    assert!(out.frame.pixels.iter().all(|p| p.iter().all(|c| *c >= 0.0)));
}
