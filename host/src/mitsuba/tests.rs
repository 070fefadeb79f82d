use super::*;
use glam::DVec3;
use magg_core::scene::{Camera, Light, PatchDef, RenderSettings, SourceLoc};

fn material(name: &str, diffuse: f64, mirror: f64, transmit: f64) -> Material {
    Material {
        name: name.into(),
        diffuse: Rgb::splat(diffuse),
        mirror: Rgb::splat(mirror),
        transmit: Rgb::splat(transmit),
        ior: 1.5,
        one_sided: false,
        emit: Rgb::BLACK,
        loc: SourceLoc::default(),
    }
}

fn scene() -> Scene {
    let tri = |material, z| PatchDef {
        vertices: [DVec3::new(0.0, 0.0, z), DVec3::new(1.0, 0.0, z), DVec3::new(0.0, 1.0, z)],
        material,
        subdivisions: None,
        size_hint: None,
        normals: None,
        uv: None,
        texture: None,
        loc: SourceLoc::default(),
    };
    Scene {
        name: "t".into(),
        camera: Camera {
            eye: DVec3::new(0.0, 1.0, 4.0),
            look_at: DVec3::new(0.0, 1.0, 0.0),
            up: DVec3::Y,
            fov_y_deg: 40.0,
        },
        settings: RenderSettings { width: 64, height: 48, ..Default::default() },
        lights: vec![Light {
            position: DVec3::new(0.0, 1.75, 0.0),
            intensity: Rgb::splat(3.0),
            spot: None,
            loc: SourceLoc::default(),
        }],
        materials: vec![
            material("white", 0.75, 0.0, 0.0),
            material("half", 0.5, 0.25, 0.0),
            material("unused", 0.1, 0.0, 0.0),
        ],
        patches: vec![tri(0, 0.0), tri(0, -1.0), tri(1, -2.0)],
        textures: Vec::new(),
    }
}

fn export(scene: &Scene) -> (String, std::path::PathBuf) {
    // One folder per call: tests run in parallel and export the same scene.
    static CALLS: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("magg-mitsuba-{}-{call}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    write(scene, &dir).unwrap();
    (std::fs::read_to_string(dir.join("scene.xml")).unwrap(), dir)
}

#[test]
fn the_camera_film_and_lights_are_the_scenes() {
    let (xml, _) = export(&scene());
    assert!(xml.contains("<float name=\"fov\" value=\"40\"/>"), "{xml}");
    assert!(xml.contains("<lookat origin=\"0, 1, 4\" target=\"0, 1, 0\" up=\"0, 1, 0\"/>"), "{xml}");
    assert!(xml.contains("<integer name=\"width\" value=\"64\"/>") && xml.contains("value=\"48\""), "{xml}");
    assert!(xml.contains("<point name=\"position\" value=\"0, 1.75, 0\"/>"), "{xml}");
    assert!(xml.contains("<rgb name=\"intensity\" value=\"3, 3, 3\"/>"), "{xml}");
    // One mesh per material that has patches.
    assert_eq!(xml.matches("<shape type=\"ply\">").count(), 2, "{xml}");
}

#[test]
fn blended_parts_keep_each_parts_reflectance() {
    let (xml, _) = export(&scene());
    // diffuse 0.5 + mirror 0.25: weight 1/3 to the mirror, each part divided by its share.
    assert!(xml.contains("<float name=\"weight\" value=\"0.3333333333333333\"/>"), "{xml}");
    let shares: Vec<f64> = xml
        .split("value=\"")
        .skip(1)
        .filter_map(|v| v.split(',').next()?.parse::<f64>().ok())
        .filter(|x| (x - 0.75).abs() < 1e-12)
        .collect();
    assert_eq!(shares.len(), 3, "white, and both parts of half at 0.75: {xml}");
}

#[test]
fn meshes_hold_the_patches() {
    let (_, dir) = export(&scene());
    let bytes = std::fs::read(dir.join("meshes/material-0.ply")).unwrap();
    let end = b"end_header\n";
    let at = bytes.windows(end.len()).position(|w| w == end).unwrap() + end.len();
    let header = std::str::from_utf8(&bytes[..at]).unwrap();
    assert!(header.contains("element vertex 6\n") && header.contains("element face 2\n"), "{header}");
    assert_eq!(bytes.len() - at, 6 * 12 + 2 * 13);
    let f = |i: usize| f32::from_le_bytes(bytes[at + 4 * i..at + 4 * i + 4].try_into().unwrap());
    // Second triangle's first vertex: (0, 0, -1).
    assert_eq!((f(9), f(10), f(11)), (0.0, 0.0, -1.0));
    assert!(!dir.join("meshes/material-2.ply").exists(), "no file for a material without patches");
}

#[test]
fn what_is_left_out_is_said() {
    let mut s = scene();
    s.settings.ambient = Rgb::splat(0.01);
    let dir = std::env::temp_dir().join(format!("magg-mitsuba-notes-{}", std::process::id()));
    let notes = write(&s, &dir).unwrap();
    assert!(notes.lines.iter().any(|l| l.contains("ambient")), "{notes:?}");
}

#[test]
fn textured_and_smooth_patches_get_their_own_plys_with_uv_normals_and_an_exr_bitmap() {
    let mut s = scene();
    s.textures.push(Texture { name: "t.png".into(), width: 2, height: 1, texels: vec![[255, 255, 255], [0, 0, 0]] });
    s.patches[0].uv = Some([glam::DVec2::ZERO, glam::DVec2::X, glam::DVec2::Y]);
    s.patches[0].texture = Some(0);
    s.patches[1].normals = Some([DVec3::Z; 3]);
    // A fourth patch, so that this export's folder is not the other tests'.
    s.patches.push(s.patches[2].clone());
    let (xml, dir) = export(&s);
    // white: one textured, one smooth; half: flat.
    assert_eq!(xml.matches("<shape type=\"ply\">").count(), 3, "{xml}");
    assert!(xml.contains("meshes/material-0-texture-0.exr") && xml.contains("type=\"bitmap\""), "{xml}");
    let ply = std::fs::read(dir.join("meshes/material-0-texture-0.ply")).unwrap();
    let header = String::from_utf8_lossy(&ply[..200]).into_owned();
    assert!(header.contains("property float u\nproperty float v\n"), "{header}");
    let smooth = std::fs::read(dir.join("meshes/material-0-smooth.ply")).unwrap();
    assert!(String::from_utf8_lossy(&smooth[..200]).contains("property float nx"));
    // The bitmap holds Kd times the linear texels: 0.75 and 0.
    let exr = image::open(dir.join("meshes/material-0-texture-0.exr")).unwrap().into_rgb32f();
    assert_eq!((exr.get_pixel(0, 0).0[0], exr.get_pixel(1, 0).0[0]), (0.75, 0.0));
}

#[test]
fn an_emitting_material_gets_an_area_emitter() {
    let mut s = scene();
    assert!(!export(&s).0.contains("type=\"area\""));
    s.materials[0].emit = Rgb::new(4.0, 2.0, 1.0);
    let (xml, _) = export(&s);
    assert_eq!(
        xml.matches("<emitter type=\"area\"><rgb name=\"radiance\" value=\"4, 2, 1\"/></emitter>").count(),
        1,
        "{xml}"
    );
}
