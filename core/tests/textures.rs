//! Diffuse textures (OBJ `vt` with MTL `map_Kd`): a textured floor shows its texels at
//! VRT with the closed-form radiance `Kd * texel * E / pi`, sRGB texels decoded to linear;
//! light that bounces off it in LRT takes the texel's colour; errors name the MTL line.

mod common;
use common::*;
use glam::DVec3;
use magg_core::camera::CameraRig;
use magg_core::scene::{parse_scene_str, srgb_to_linear, DirectLight, Scene};
use std::collections::HashMap;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

/// An 8 x 8 PNG of four 4 x 4 quadrants: top-left `a`, top-right `b`, bottom-left `b`,
/// bottom-right `a`.
fn checker(a: [u8; 3], b: [u8; 3]) -> Vec<u8> {
    let img = image::RgbImage::from_fn(8, 8, |x, y| image::Rgb(if (x < 4) == (y < 4) { a } else { b }));
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).unwrap();
    png
}

/// A 4 x 4 floor at y = 0 mapped once by its texture: u along x, v along -z (so the
/// image's top row lies at z = -2).
const FLOOR_OBJ: &str = "mtllib f.mtl\nv -2 0 -2\nv -2 0 2\nv 2 0 2\nv 2 0 -2\n\
vt 0 1\nvt 0 0\nvt 1 0\nvt 1 1\nusemtl tex\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n";

fn parse(toml: &str, files: Vec<(&str, Vec<u8>)>) -> Result<Scene, String> {
    let files: HashMap<PathBuf, Vec<u8>> = files.into_iter().map(|(p, b)| (Path::new("mem").join(p), b)).collect();
    let read = move |p: &Path| files.get(p).cloned().ok_or_else(|| std::io::Error::from(std::io::ErrorKind::NotFound));
    parse_scene_str("s.toml", toml, Path::new("mem"), &read).map_err(|e| e.to_string())
}

/// The floor seen from above, lit by one light ([`TOP_DOWN_HEAD`]).
fn scene_text() -> String {
    format!("{TOP_DOWN_HEAD}[[mesh]]\nfile = \"f.obj\"\nsubdivisions = 4\n")
}

fn floor(a: [u8; 3], b: [u8; 3], kd: &str) -> Scene {
    let mtl = format!("newmtl tex\nKd {kd}\nmap_Kd -bm 1 tex.png\n");
    let files = vec![("f.obj", FLOOR_OBJ.as_bytes().to_vec()), ("f.mtl", mtl.into_bytes()), ("tex.png", checker(a, b))];
    parse(&scene_text(), files).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn a_textured_floor_shows_its_texels_with_the_closed_form_radiance() {
    let (a, b) = ([255, 128, 0], [20, 60, 200]);
    let mut s = floor(a, b, "0.8 0.8 0.8");
    (s.settings.width, s.settings.height) = (48, 48);
    assert_eq!(s.textures.len(), 1);
    assert!(s.patches.iter().all(|p| p.uv.is_some() && p.texture == Some(0)));
    s.settings.direct = DirectLight::Vrt;
    let (p, out) = prepare_and_run(&s);
    assert_eq!((p.header.counts.shaded_patches, p.header.counts.texture_blocks), (2, 1));
    let rig = CameraRig::new(&s.camera, s.settings.width, s.settings.height);
    let lp = DVec3::new(0.3, 1.5, 0.2);
    let mut checked = [0; 2];
    for y in 0..s.settings.height {
        for x in 0..s.settings.width {
            let r = rig.ray(x as f64 + 0.5, y as f64 + 0.5);
            let q = r.at(-r.origin.y / r.direction.y);
            let (u, v) = ((q.x + 2.0) / 4.0, (2.0 - q.z) / 4.0);
            // Well inside a quadrant (past the half texel where bilinear blends).
            let inside = |t: f64| (t - 0.5).abs() > 0.07 && t > 0.07 && t < 0.93;
            if !inside(u) || !inside(v) {
                continue;
            }
            // Top-left (u < 0.5, v > 0.5) and bottom-right hold `a`.
            let texel = if (u < 0.5) == (v > 0.5) { a } else { b };
            let d = lp - q;
            let r2 = d.length_squared();
            let e = 2.0 * (d.y / r2.sqrt()) / r2;
            let got = out.frame.get(x, y);
            for c in 0..3 {
                let want = 0.8 * srgb_to_linear(texel[c]) * e / PI;
                assert!(
                    (got[c] as f64 - want).abs() <= 1e-5 * want.max(1e-3),
                    "pixel ({x}, {y}) channel {c}: {got:?} vs {want}"
                );
            }
            checked[(texel == a) as usize] += 1;
        }
    }
    assert!(checked[0] > 100 && checked[1] > 100, "{checked:?} pixels checked");
}

#[test]
fn light_bouncing_off_a_red_texture_is_red() {
    // A pure red texture under a white Kd: the light pass's bounce onto a white ceiling
    // carries no green or blue at all.
    let mut s = floor([255, 0, 0], [255, 0, 0], "1 1 1");
    s.materials.push(material("white", 0.8, 0.0, 0.0));
    let white = s.materials.len() as u32 - 1;
    s.patches.extend(quad(v(-2.0, 2.0, -2.0), v(2.0, 2.0, -2.0), v(2.0, 2.0, 2.0), v(-2.0, 2.0, 2.0), white, 4));
    s.settings.direct = DirectLight::Vrt;
    s.settings.diffuse_bounces = 1;
    let (p, out) = prepare_and_run(&s);
    let ceiling: Vec<usize> = (0..p.elements.len()).filter(|&e| p.elements[e].patch >= 2).collect();
    let red: i64 = ceiling.iter().map(|&e| out.element_flux[e][0]).sum();
    let others: i64 = ceiling.iter().map(|&e| out.element_flux[e][1] + out.element_flux[e][2]).sum();
    assert!(red > 0 && others == 0, "ceiling flux red {red}, green + blue {others}");
    // The floor absorbs what its texture takes away: energy is still accounted for.
    let t = out.stats.light;
    let accounted = t.absorbed.0[1] + t.diffuse_end.0[1] + t.escaped.0[1] + t.cut.0[1];
    assert!((accounted - t.reached.0[1]).abs() <= 1e-12 * t.reached.0[1].max(1.0), "{t:?}");
}

#[test]
fn a_missing_or_broken_texture_names_the_mtl_line() {
    let mtl = b"newmtl tex\nKd 1 1 1\n\nmap_Kd tex.png\n".to_vec();
    let e = parse(&scene_text(), vec![("f.obj", FLOOR_OBJ.as_bytes().to_vec()), ("f.mtl", mtl.clone())]).unwrap_err();
    assert!(e.contains("f.mtl:4") && e.contains("cannot read texture"), "{e}");
    let files = vec![("f.obj", FLOOR_OBJ.as_bytes().to_vec()), ("f.mtl", mtl), ("tex.png", b"GIF89a?".to_vec())];
    let e = parse(&scene_text(), files).unwrap_err();
    assert!(e.contains("f.mtl:4") && e.contains("cannot decode texture"), "{e}");
}

#[test]
fn the_cluster_shapes_give_the_textured_floor_the_same_bits() {
    let mut s = floor([255, 128, 0], [20, 60, 200], "0.8 0.8 0.8");
    s.settings.diffuse_bounces = 1;
    let p = magg_prepare::prepare(&s).unwrap();
    let one = run(&p, 1, None);
    let many = run(&p, 3, Some(4));
    assert_eq!(one.frame.pixels, many.frame.pixels);
    assert_eq!(one.element_flux, many.element_flux);
}
