//! Every scene shipped in `scenes/` parses, and the ones that reproduce something have
//! the shape they claim (patch, light and element counts, materials, winding).

use std::path::{Path, PathBuf};

use glam::DVec3;
use magg_scene::math::Normalized;
use magg_scene::{parse_scene_str, GridSpec, PatchDef, Scene};

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join("scenes")
}

fn load(name: &str) -> Scene {
    let dir = scenes_dir();
    let path = dir.join(name);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    parse_scene_str(name, &text, &dir, &|p: &Path| std::fs::read(p)).unwrap_or_else(|e| panic!("{e}"))
}

fn normal(p: &PatchDef) -> DVec3 {
    let [a, b, c] = p.vertices;
    (b - a).cross(c - a).normalized()
}

fn centroid(p: &PatchDef) -> DVec3 {
    let [a, b, c] = p.vertices;
    (a + b + c) / 3.0
}

#[test]
fn every_scene_file_parses() {
    let mut names: Vec<String> = std::fs::read_dir(scenes_dir())
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".toml"))
        .collect();
    names.sort();
    assert!(names.len() >= 5, "expected the shipped scenes, found {names:?}");
    for name in &names {
        let s = load(name);
        let emits = s.patches.iter().any(|p| s.materials[p.material as usize].is_emitter());
        assert!(!s.patches.is_empty() && (!s.lights.is_empty() || emits), "{name}: nothing lit");
        for p in &s.patches {
            assert!((p.material as usize) < s.materials.len(), "{name}: patch material out of range");
        }
    }
}

#[test]
fn area_scene_is_lit_only_by_a_ceiling_lamp_facing_down() {
    let s = load("area.toml");
    assert!(s.lights.is_empty());
    let lamps: Vec<&PatchDef> = s.patches.iter().filter(|p| s.materials[p.material as usize].is_emitter()).collect();
    assert_eq!(lamps.len(), 2, "one quad");
    for p in lamps {
        assert!((normal(p) - DVec3::NEG_Y).length() < 1e-12, "the lamp's front faces the floor");
        assert!(centroid(p).y > 1.9);
    }
}

#[test]
fn magg_paper_matches_section_5_1() {
    let s = load("magg-paper.toml");
    assert_eq!(s.patches.len(), 8);
    assert_eq!(s.lights.len(), 1);
    assert_eq!(s.settings.grid, GridSpec::Fixed([8, 7, 6]));
    assert_eq!((s.settings.width, s.settings.height), (400, 400));
    assert_eq!((s.settings.lrt_depth, s.settings.vrt_depth), (1, 1));
    let elements: u32 = s.patches.iter().map(|p| p.subdivisions.expect("explicit subdivisions").pow(2)).sum();
    assert_eq!(elements, 1664);
    assert!(s.materials.iter().any(|m| m.is_mirror()));
}

#[test]
fn cornell_has_mirror_glass_and_inward_walls() {
    let s = load("cornell.toml");
    assert!(s.materials.iter().any(|m| m.is_mirror()), "no mirror material");
    assert!(s.materials.iter().any(|m| m.is_transmissive()), "no transmissive material");
    let centre = DVec3::new(0.0, 1.0, 0.0);
    let glass = s.materials.iter().position(|m| m.name == "glass").unwrap() as u32;
    let sphere_centre = DVec3::new(0.45, 0.351, 0.35);
    let mut sphere_faces = 0;
    for p in &s.patches {
        let name = &s.materials[p.material as usize].name;
        if ["white", "red", "green"].contains(&name.as_str()) {
            assert!(normal(p).dot(centre - centroid(p)) > 0.0, "wall at line {} faces out", p.loc.line);
        }
        if p.material == glass {
            sphere_faces += 1;
            assert!(normal(p).dot(centroid(p) - sphere_centre) > 0.0, "sphere face wound inwards");
            assert!(p.vertices.iter().all(|v| v.y >= 0.0), "sphere below the floor");
        }
    }
    assert_eq!(sphere_faces, 1280);
}

#[test]
fn diffuse_scene_has_no_specular_material() {
    let s = load("diffuse.toml");
    assert!(s.materials.iter().all(|m| !m.is_specular()));
    assert_eq!(s.settings.diffuse_bounces, 1);
}

#[test]
fn spot_scene_has_a_spot_and_glass() {
    let s = load("spot.toml");
    assert!(s.lights.iter().any(|l| l.spot.is_some()));
    assert!(s.materials.iter().any(|m| m.is_transmissive()));
}

#[test]
fn large_scene_reads_tens_of_thousands_of_triangles_with_mtl_materials() {
    let s = load("large.toml");
    assert!(s.patches.len() > 30_000, "{} patches", s.patches.len());
    assert_eq!(s.lights.len(), 2);
    assert_eq!((s.settings.width, s.settings.height), (640, 480));
    let names: Vec<&str> = s.materials.iter().map(|m| m.name.as_str()).collect();
    assert!(names.contains(&"meshes/terrain.obj:ground") && names.contains(&"meshes/terrain.obj:stone"), "{names:?}");
    let ground = names.iter().position(|n| *n == "meshes/terrain.obj:ground").unwrap() as u32;
    assert!(s.patches.iter().filter(|p| p.material == ground).all(|p| normal(p).y > 0.0), "terrain faces down");
}

#[test]
fn readme_example_parses() {
    let dir = scenes_dir();
    let readme = std::fs::read_to_string(dir.join("README.md")).unwrap();
    let start = readme.find("```toml\n").expect("a ```toml block") + "```toml\n".len();
    let len = readme[start..].find("```").unwrap();
    let s = parse_scene_str("README.md", &readme[start..start + len], &dir, &|p: &Path| std::fs::read(p))
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(s.patches.len(), 2 + 1280);
    // An unknown key is reported as the README says.
    let bad = readme[start..start + len].replace("ior = 1.5", "ior = 1.5\ncolour = [1, 1, 1]");
    let e = parse_scene_str("x.toml", &bad, &dir, &|p: &Path| std::fs::read(p)).unwrap_err().to_string();
    assert!(e.contains("material[1].colour: unknown field `colour`, expected one of `name`, `diffuse`"), "{e}");
}
