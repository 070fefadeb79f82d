//! Tests of the scene parser: every field, its errors with file, line and field.

use super::*;
use std::collections::HashMap;
use std::path::PathBuf;

/// A small valid scene; line numbers below refer to it.
const MINI: &str = "\
[camera]
eye = [0, 1, 3]
look_at = [0, 1, 0]
fov = 40

[[light]]
position = [0, 1.9, 0]
intensity = [1, 1, 1]

[[material]]
name = \"white\"
diffuse = [0.7, 0.7, 0.7]

[[triangle]]
vertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
material = \"white\"
";

fn parse_with(text: &str, files: &[(&str, &str)]) -> Result<Scene, SceneError> {
    let files: Vec<(&str, &[u8])> = files.iter().map(|(p, t)| (*p, t.as_bytes())).collect();
    parse_with_bytes(text, &files)
}

/// Parses `text` with the files `files` (path, bytes) readable beside it.
pub(super) fn parse_with_bytes(text: &str, files: &[(&str, &[u8])]) -> Result<Scene, SceneError> {
    let files: HashMap<PathBuf, Vec<u8>> = files.iter().map(|(p, t)| (PathBuf::from(p), t.to_vec())).collect();
    let read = move |p: &Path| {
        files.get(p).cloned().ok_or_else(|| std::io::Error::new(std::io::ErrorKind::NotFound, "not found"))
    };
    parse_scene_str("t.toml", text, Path::new("base"), &read)
}

fn parse(text: &str) -> Result<Scene, SceneError> {
    parse_with(text, &[])
}

fn err(text: &str) -> String {
    match parse(text) {
        Ok(_) => panic!("scene unexpectedly parsed:\n{text}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn minimal_scene_parses_with_defaults() {
    let s = parse(MINI).unwrap();
    assert_eq!(s.name, "t.toml");
    assert_eq!(s.camera.up, DVec3::new(0.0, 1.0, 0.0));
    assert_eq!(s.settings, RenderSettings::default());
    assert_eq!(s.patches.len(), 1);
    assert_eq!(s.patches[0].loc, SourceLoc { file: "t.toml".into(), line: 15 });
    assert_eq!(s.lights[0].loc.line, 7);
    assert_eq!(s.materials[0].loc.line, 11);
    assert_eq!(s.materials[0].ior, 1.5);
}

#[test]
fn render_table_sets_every_field() {
    let text = format!(
        "{MINI}\n[render]\nwidth = 640\nheight = 480\npixel_samples = 2\nelement_size = 0.25\nlight_rays = 16\n\
         lrt_depth = 1\nvrt_depth = 2\ndiffuse_bounces = 3\nambient = [0.1, 0.2, 0.3]\ngrid = [8, 7, 6]\n\
         seed = 42\nexposure = 2\nbackground = [0, 0, 1]\nmax_elements = 1000\n"
    );
    let s = parse(&text).unwrap().settings;
    assert_eq!((s.width, s.height, s.pixel_samples, s.light_rays), (640, 480, 2, 16));
    assert_eq!((s.lrt_depth, s.vrt_depth, s.diffuse_bounces, s.seed, s.max_elements), (1, 2, 3, 42, 1000));
    assert_eq!(s.element_size, 0.25);
    assert_eq!(s.ambient, Rgb::new(0.1, 0.2, 0.3));
    assert_eq!(s.background, Rgb::new(0.0, 0.0, 1.0));
    assert_eq!(s.grid, GridSpec::Fixed([8, 7, 6]));
    assert_eq!(s.exposure, Exposure::Fixed(2.0));
    let auto = parse(&format!("{MINI}[render]\ngrid = \"auto\"\nexposure = \"auto\"\n")).unwrap().settings;
    assert_eq!((auto.grid, auto.exposure), (GridSpec::Auto, Exposure::Auto));
}

#[test]
fn toml_syntax_error_names_file_and_line() {
    let e = err(&format!("{MINI}[render]\nwidth = = 3\n"));
    assert!(e.starts_with("t.toml:18: "), "{e}");
}

#[test]
fn undefined_material_names_the_reference() {
    let e = err(&MINI.replace("material = \"white\"", "material = \"gold\""));
    assert_eq!(e, "t.toml:16: triangle[0].material: material 'gold' is not defined");
}

#[test]
fn nan_and_infinity_are_refused() {
    let e = err(&format!("{MINI}[render]\nelement_size = nan\n"));
    assert!(e.starts_with("t.toml:18: render.element_size: NaN is not a finite number"), "{e}");
    let e = err(&MINI.replace("eye = [0, 1, 3]", "eye = [0, inf, 3]"));
    assert!(e.starts_with("t.toml:2: camera.eye: y = inf"), "{e}");
}

#[test]
fn negative_intensity_is_refused() {
    let e = err(&MINI.replace("intensity = [1, 1, 1]", "intensity = [-1, 1, 1]"));
    assert_eq!(e, "t.toml:8: light[0].intensity: red = -1 is out of range [0, 1e30]");
    let e = err(&MINI.replace("intensity = [1, 1, 1]", "intensity = [0, 0, 0]"));
    assert!(e.starts_with("t.toml:8: light[0].intensity"), "{e}");
}

#[test]
fn unknown_key_names_file_line_and_key() {
    let e = err(&MINI.replace("diffuse = [0.7, 0.7, 0.7]", "colour = [0.7, 0.7, 0.7]"));
    assert!(e.starts_with("t.toml:12: material[0].colour: unknown field `colour`"), "{e}");
    let e = err(&format!("{MINI}[render]\nwidht = 3\n"));
    assert!(e.starts_with("t.toml:18: render.widht: unknown field `widht`"), "{e}");
}

#[test]
fn faces_are_apart_unless_the_scene_shares_them() {
    assert!(!parse(MINI).unwrap().settings.shared_faces);
    assert!(parse(&format!("{MINI}[render]\nfaces = \"shared\"\n")).unwrap().settings.shared_faces);
    assert!(!parse(&format!("{MINI}[render]\nfaces = \"apart\"\n")).unwrap().settings.shared_faces);
    let e = err(&format!("{MINI}[render]\nfaces = \"both\"\n"));
    assert_eq!(e, "t.toml:18: render.faces: expected \"apart\" or \"shared\", found \"both\"");
}

#[test]
fn refinement_is_off_unless_the_scene_asks_for_levels() {
    let s = parse(MINI).unwrap().settings;
    assert_eq!((s.refine, s.refine_contrast), (0, 0.2));
    let s = parse(&format!("{MINI}[render]\nrefine = 3\nrefine_contrast = 0.5\n")).unwrap().settings;
    assert_eq!((s.refine, s.refine_contrast), (3, 0.5));
    let e = err(&format!("{MINI}[render]\nrefine = 7\n"));
    assert!(e.starts_with("t.toml:18: render.refine:"), "{e}");
    let e = err(&format!("{MINI}[render]\nrefine_contrast = 0.0\n"));
    assert!(e.starts_with("t.toml:18: render.refine_contrast: 0 is out of range (0, 1]"), "{e}");
}

#[test]
fn bounce_rays_default_to_eight_per_light_ray_and_are_range_checked() {
    assert_eq!(parse(MINI).unwrap().settings.bounce_rays, 8);
    assert_eq!(parse(&format!("{MINI}[render]\nbounce_rays = 1\n")).unwrap().settings.bounce_rays, 1);
    for bad in ["0", "4097", "2.5"] {
        let e = err(&format!("{MINI}[render]\nbounce_rays = {bad}\n"));
        assert!(e.starts_with("t.toml:18: render.bounce_rays:"), "{bad}: {e}");
    }
}

#[test]
fn gather_rays_default_to_128_and_are_range_checked() {
    assert_eq!(parse(MINI).unwrap().settings.gather_rays, 128);
    assert_eq!(parse(&format!("{MINI}[render]\ngather_rays = 0\n")).unwrap().settings.gather_rays, 0);
    for bad in ["-1", "4097", "2.5"] {
        let e = err(&format!("{MINI}[render]\ngather_rays = {bad}\n"));
        assert!(e.starts_with("t.toml:18: render.gather_rays:"), "{bad}: {e}");
    }
}

#[test]
fn accel_is_bvh_unless_the_scene_asks_for_the_grid() {
    assert_eq!(parse(MINI).unwrap().settings.accel, Accel::Bvh);
    let grid = parse(&format!("{MINI}[render]\naccel = \"grid\"\n")).unwrap().settings;
    assert_eq!(grid.accel, Accel::Grid);
    let e = err(&format!("{MINI}[render]\naccel = \"kd-tree\"\n"));
    assert_eq!(e, "t.toml:18: render.accel: expected \"bvh\" or \"grid\", found \"kd-tree\"");
    let e = err(&format!("{MINI}[render]\naccel = 2\n"));
    assert!(e.starts_with("t.toml:18: render.accel: "), "{e}");
}

#[test]
fn wrong_types_name_the_line() {
    let e = err(&format!("{MINI}[render]\nwidth = \"big\"\n"));
    assert!(e.starts_with("t.toml:18: render.width: "), "{e}");
    let e = err(&format!("{MINI}[render]\ngrid = [8, 7]\n"));
    assert!(e.starts_with("t.toml:18: render.grid: "), "{e}");
    let e = err(&MINI.replace("eye = [0, 1, 3]", "eye = [0, 1]"));
    assert_eq!(e, "t.toml:2: camera.eye: expected 3 numbers, found 2");
}

#[test]
fn out_of_range_values_are_refused() {
    for (line, field) in [
        ("width = 0", "render.width"),
        ("height = 20000", "render.height"),
        ("pixel_samples = 5000", "render.pixel_samples"),
        ("element_size = -0.1", "render.element_size"),
        ("light_rays = 0", "render.light_rays"),
        ("lrt_depth = 33", "render.lrt_depth"),
        ("diffuse_bounces = -1", "render.diffuse_bounces"),
        ("ambient = [0, -0.1, 0]", "render.ambient"),
        ("grid = [512, 512, 512]", "render.grid"),
        ("grid = [0, 1, 1]", "render.grid"),
        ("exposure = -1", "render.exposure"),
        ("exposure = \"bright\"", "render.exposure"),
        ("seed = -1", "render.seed"),
    ] {
        let e = err(&format!("{MINI}[render]\n{line}\n"));
        assert!(e.starts_with(&format!("t.toml:18: {field}: ")), "{line}: {e}");
    }
    let e = err(&MINI.replace("fov = 40", "fov = 180"));
    assert!(e.starts_with("t.toml:4: camera.fov: 180 is out of range"), "{e}");
    let e = err(&MINI.replace("diffuse = [0.7, 0.7, 0.7]", "diffuse = [0.7, 0.7, 0.7]\nior = 0.5"));
    assert!(e.starts_with("t.toml:13: material[0].ior"), "{e}");
}

#[test]
fn energy_conservation_names_the_channel() {
    let e = err(&MINI.replace("diffuse = [0.7, 0.7, 0.7]", "diffuse = [0.7, 0.7, 0.7]\nmirror = [0.2, 0.5, 0.2]"));
    assert!(e.starts_with("t.toml:11: material[0]: "), "{e}");
    assert!(e.contains("green channel"), "{e}");
    // Within the 1e-9 tolerance.
    parse(&MINI.replace("diffuse = [0.7, 0.7, 0.7]", "diffuse = [0.7, 0.7, 0.7]\ntransmit = [0.3, 0.3, 0.3]")).unwrap();
}

#[test]
fn duplicate_material_is_refused() {
    let text = MINI.replace("[[triangle]]", "[[material]]\nname = \"white\"\n\n[[triangle]]");
    let e = err(&text);
    assert_eq!(e, "t.toml:15: material[1].name: material 'white' is already defined at line 11");
}

#[test]
fn degenerate_triangle_is_refused() {
    let e = err(&MINI.replace("[[0, 0, 0], [1, 0, 0], [0, 1, 0]]", "[[0, 0, 0], [1, 1, 1], [2, 2, 2]]"));
    assert!(e.starts_with("t.toml:15: triangle[0].vertices: triangle[0] is degenerate"), "{e}");
    let e = err(&MINI.replace("[[0, 0, 0], [1, 0, 0], [0, 1, 0]]", "[[0, 0, 0], [1, 0, 0]]"));
    assert!(e.contains("expected 3 vertices, found 2"), "{e}");
}

#[test]
fn missing_tables_are_refused() {
    assert!(err(&MINI.replace("[camera]\neye = [0, 1, 3]\nlook_at = [0, 1, 0]\nfov = 40\n", "")).contains("camera"));
    let no_light = MINI.replace("[[light]]\nposition = [0, 1.9, 0]\nintensity = [1, 1, 1]\n", "");
    assert!(err(&no_light).contains("no [[light]]"));
    let no_patch =
        MINI.replace("[[triangle]]\nvertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]\nmaterial = \"white\"\n", "");
    assert!(err(&no_patch).contains("no [[triangle]]"));
    let e = err(&MINI
        .replace("look_at = [0, 1, 0]", "look_at = [0, 1, 0]\nup = [0, 2, 0]")
        .replace("eye = [0, 1, 3]", "eye = [0, 5, 0]"));
    assert!(e.contains("camera.up"), "{e}");
}

#[test]
fn spot_light_is_normalized_and_checked() {
    let spot = "intensity = [1, 1, 1]\ndirection = [0, -2, 0]\ncone = 30\nfalloff = 5";
    let s = parse(&MINI.replace("intensity = [1, 1, 1]", spot)).unwrap();
    let sp = s.lights[0].spot.clone().unwrap();
    assert_eq!(sp.direction, DVec3::new(0.0, -1.0, 0.0));
    assert_eq!((sp.half_angle_deg, sp.falloff_deg), (30.0, 5.0));
    let e = err(&MINI.replace("intensity = [1, 1, 1]", "intensity = [1, 1, 1]\ncone = 30"));
    assert!(e.starts_with("t.toml:9: light[0].cone"), "{e}");
    let e = err(&MINI.replace("intensity = [1, 1, 1]", "intensity = [1, 1, 1]\ndirection = [0, 0, 0]\ncone = 30"));
    assert!(e.starts_with("t.toml:9: light[0].direction"), "{e}");
    let e = err(&MINI
        .replace("intensity = [1, 1, 1]", "intensity = [1, 1, 1]\ndirection = [0, -1, 0]\ncone = 170\nfalloff = 20"));
    assert!(e.starts_with("t.toml:11: light[0].falloff"), "{e}");
}

const QUAD: &str = "[[quad]]\nvertices = [[0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0]]\nmaterial = \"white\"\n";

#[test]
fn quad_becomes_two_triangles_with_equal_subdivisions() {
    let s = parse(&format!("{MINI}{QUAD}[render]\nelement_size = 0.5\n")).unwrap();
    assert_eq!(s.patches.len(), 3);
    let (a, b) = (&s.patches[1], &s.patches[2]);
    let v = |x: f64, y: f64| DVec3::new(x, y, 0.0);
    assert_eq!(a.vertices, [v(0.0, 0.0), v(2.0, 0.0), v(2.0, 1.0)]);
    assert_eq!(b.vertices, [v(0.0, 0.0), v(2.0, 1.0), v(0.0, 1.0)]);
    // Both halves carry the quad's longest edge incl. the diagonal: sqrt(5).
    assert_eq!((a.subdivisions, b.subdivisions), (None, None));
    assert_eq!(a.size_hint, b.size_hint);
    assert!((a.size_hint.unwrap() - 5f64.sqrt()).abs() < 1e-12);
    assert_eq!(a.loc.line, 18);
    // Winding kept: normal +z.
    for p in [a, b] {
        assert!((p.vertices[1] - p.vertices[0]).cross(p.vertices[2] - p.vertices[0]).z > 0.0);
    }
    let fixed = parse(&format!("{MINI}{QUAD}subdivisions = 7\n")).unwrap();
    assert_eq!(fixed.patches[2].subdivisions, Some(7));
}

#[test]
fn bad_quads_are_refused() {
    let bent = QUAD.replace("[2, 1, 0]", "[2, 1, 0.01]");
    assert!(err(&format!("{MINI}{bent}")).contains("quad[0] is not planar"));
    let concave = QUAD.replace("[2, 1, 0]", "[0.5, 0.2, 0]");
    assert!(err(&format!("{MINI}{concave}")).contains("quad[0] is not convex"));
    let crossed = QUAD.replace("[2, 1, 0], [0, 1, 0]", "[0, 1, 0], [2, 1, 0]");
    assert!(err(&format!("{MINI}{crossed}")).contains("quad[0]"));
    let e = err(&format!("{MINI}{QUAD}subdivisions = 0\n"));
    assert!(e.starts_with("t.toml:20: quad[0].subdivisions: 0 is out of range 1..=4096"), "{e}");
}

const CUBE_OBJ: &str =
    "mtllib cube.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl red\nf 1 2 3 4\nusemtl white\nf -4 -2 -1\n";
const CUBE_MTL: &str = "newmtl red\nKd 0.8 0.1 0.1\n";

fn mesh_scene(extra: &str) -> String {
    format!("{MINI}\n[[mesh]]\nobj = \"m/cube.obj\"\n{extra}")
}

#[test]
fn mesh_materials_come_from_mtl_then_toml() {
    let s = parse_with(&mesh_scene(""), &[("base/m/cube.obj", CUBE_OBJ), ("base/m/cube.mtl", CUBE_MTL)]).unwrap();
    assert_eq!(s.patches.len(), 1 + 3);
    let names: Vec<&str> = s.materials.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["white", "m/cube.obj:red"]);
    assert_eq!(s.materials[1].diffuse, Rgb::new(0.8, 0.1, 0.1));
    assert_eq!(s.materials[1].loc, SourceLoc { file: "base/m/cube.mtl".into(), line: 1 });
    assert_eq!([s.patches[1].material, s.patches[2].material, s.patches[3].material], [1, 1, 0]);
    assert_eq!(s.patches[3].loc, SourceLoc { file: "t.toml".into(), line: 19 });
    // An explicit material overrides the MTL, which is then not even read.
    let s = parse_with(&mesh_scene("material = \"white\"\n"), &[("base/m/cube.obj", CUBE_OBJ)]).unwrap();
    assert!(s.patches.iter().all(|p| p.material == 0));
    assert_eq!(s.materials.len(), 1);
}

#[test]
fn missing_obj_names_scene_line_and_path() {
    let e = err(&mesh_scene(""));
    assert!(e.starts_with("t.toml:19: mesh[0].obj: cannot read OBJ file 'base/m/cube.obj'"), "{e}");
    let e = parse_with(&mesh_scene(""), &[("base/m/cube.obj", CUBE_OBJ)]).unwrap_err().to_string();
    assert!(e.starts_with("base/m/cube.obj:1: mtllib: cannot read MTL file 'base/m/cube.mtl'"), "{e}");
}

#[test]
fn obj_errors_name_the_obj_file_and_line() {
    let bad = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n";
    let e = parse_with(&mesh_scene("material = \"white\"\n"), &[("base/m/cube.obj", bad)]).unwrap_err();
    assert_eq!(e.loc, SourceLoc { file: "base/m/cube.obj".into(), line: 4 });
    let no_mtl = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    let e = parse_with(&mesh_scene(""), &[("base/m/cube.obj", no_mtl)]).unwrap_err().to_string();
    assert!(e.starts_with("t.toml:19: mesh[0].material: base/m/cube.obj:4: face has no material"), "{e}");
    let unknown = "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl gold\nf 1 2 3\n";
    let e = parse_with(&mesh_scene(""), &[("base/m/cube.obj", unknown)]).unwrap_err().to_string();
    assert!(e.contains("base/m/cube.obj:5: material 'gold' is not defined"), "{e}");
}

#[test]
fn mesh_transform_is_scale_rotate_translate() {
    let obj = "v 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\n";
    let text = mesh_scene("material = \"white\"\nscale = 2\nrotate = [0, 0, 90]\ntranslate = [10, 0, 0]\n");
    let s = parse_with(&text, &[("base/m/cube.obj", obj)]).unwrap();
    let v = s.patches[1].vertices;
    // (1,0,0) -> scale (2,0,0) -> 90 deg about z (0,2,0) -> translate (10,2,0).
    assert!((v[0] - DVec3::new(10.0, 2.0, 0.0)).length() < 1e-12, "{:?}", v[0]);
    assert!((v[2] - DVec3::new(10.0, 0.0, 2.0)).length() < 1e-12, "{:?}", v[2]);
}

#[test]
fn negative_scale_keeps_normals_outward() {
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    let normal = |extra: &str| {
        let s =
            parse_with(&mesh_scene(&format!("material = \"white\"\n{extra}")), &[("base/m/cube.obj", obj)]).unwrap();
        let v = s.patches[1].vertices;
        (v[1] - v[0]).cross(v[2] - v[0]).normalized()
    };
    assert_eq!(normal(""), DVec3::new(0.0, 0.0, 1.0));
    // Mirroring x alone maps the +z normal to +z; without the re-flip it would be -z.
    assert_eq!(normal("scale = [-1, 1, 1]"), DVec3::new(0.0, 0.0, 1.0));
    // Mirroring z mirrors the surface too: its front now faces -z, like a box's top face
    // becoming its bottom face (normal = M^-T n, as for a closed mesh staying outward).
    assert_eq!(normal("scale = [1, 1, -3]"), DVec3::new(0.0, 0.0, -1.0));
    let e = err(&mesh_scene("material = \"white\"\nscale = [1, 0, 1]\n"));
    assert!(e.contains("mesh[0].scale"), "{e}");
}

#[test]
fn degenerate_obj_faces_are_skipped() {
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\n";
    let s = parse_with(&mesh_scene("material = \"white\"\nsubdivisions = 3\n"), &[("base/m/cube.obj", obj)]).unwrap();
    assert_eq!(s.patches.len(), 2);
    assert_eq!(s.patches[1].subdivisions, Some(3));
    let flat = "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n";
    let e = parse_with(&mesh_scene("material = \"white\"\n"), &[("base/m/cube.obj", flat)]).unwrap_err();
    assert!(e.message.contains("no faces of non-zero area"), "{e}");
}

#[test]
fn patches_keep_file_order_across_kinds() {
    let text = MINI.replace("[[triangle]]", &format!("{QUAD}\n[[triangle]]"));
    let s = parse(&text).unwrap();
    assert_eq!(s.patches.iter().map(|p| p.loc.line).collect::<Vec<_>>(), [15, 15, 19]);
}

#[test]
fn mangled_input_never_panics() {
    // Every single-character deletion and a few insertions: an error or a scene, never a panic.
    let text = format!("{MINI}{QUAD}[render]\ngrid = [2, 2, 2]\nexposure = 1.5\n");
    let chars: Vec<char> = text.chars().collect();
    for k in 0..chars.len() {
        let mut deleted = chars.clone();
        deleted.remove(k);
        let _ = parse(&deleted.iter().collect::<String>());
        for c in ['[', '"', '=', '-', '\n', '9'] {
            let mut inserted = chars.clone();
            inserted.insert(k, c);
            let _ = parse(&inserted.iter().collect::<String>());
        }
    }
}

#[test]
fn values_that_would_overflow_are_refused_with_their_field() {
    let e = err(&format!("{MINI}\n[render]\nambient = [1e308, 0, 0]\n"));
    assert!(e.contains("render.ambient") && e.contains("out of range [0, 1e30]"), "{e}");
    let e = err(&format!("{MINI}\n[render]\nbackground = [0, 0, 2e30]\n"));
    assert!(e.contains("render.background"), "{e}");
    let e = err(&format!("{MINI}\n[render]\nexposure = 1e-31\n"));
    assert!(e.contains("render.exposure") && e.contains("out of range"), "{e}");
    let e = err(&MINI.replace("intensity = [1, 1, 1]", "intensity = [1e308, 1, 1]"));
    assert!(e.starts_with("t.toml:8: light[0].intensity"), "{e}");
    let e = err(&MINI.replace("position = [0, 1.9, 0]", "position = [0, 1.1e30, 0]"));
    assert!(e.contains("light[0].position") && e.contains("y = 1.1e30"), "{e}");
    let e = err(&MINI.replace("[1, 0, 0], [0, 1, 0]]", "[1, 0, 0], [0, -1e31, 0]]"));
    assert!(e.contains("triangle[0].vertices") && e.contains("vertex 2"), "{e}");
    // The limits themselves are fine.
    parse(&format!("{MINI}\n[render]\nambient = [1e30, 0, 0]\nexposure = 1e30\n")).unwrap();
}

#[test]
fn obj_coordinates_past_the_limit_name_their_line() {
    let obj = "v 0 0 0\nv 1 0 0\nv 0 2e30 0\nf 1 2 3\n";
    let e = parse_with(&mesh_scene("material = \"white\"\n"), &[("base/m/cube.obj", obj)]).unwrap_err().to_string();
    assert!(e.starts_with("base/m/cube.obj:3: obj: v: 2e30 is out of range"), "{e}");
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    let e = parse_with(&mesh_scene("material = \"white\"\nscale = 1e300\n"), &[("base/m/cube.obj", obj)])
        .unwrap_err()
        .to_string();
    assert!(e.contains("mesh[0].scale") && e.contains("past 1e30"), "{e}");
}

#[test]
fn obj_errors_do_not_print_what_a_foreign_file_holds() {
    let secret = "MAGG_TOKEN=hunter2-very-secret-value\n";
    let e = parse_with(&mesh_scene("material = \"white\"\n"), &[("base/m/cube.obj", secret)]).unwrap_err().to_string();
    assert!(!e.contains("hunter2"), "{e}");
    assert!(e.contains("unknown statement a token of 36 bytes"), "{e}");
    let e = parse_with(&mesh_scene("material = \"white\"\n"), &[("base/m/cube.obj", "vn 0 0 1\nfoo 1\n")])
        .unwrap_err()
        .to_string();
    assert!(e.contains("unknown statement 'foo'"), "{e}");
}

#[test]
fn file_and_its_alias_obj_name_the_mesh_file() {
    let files = [("base/m/cube.obj", CUBE_OBJ), ("base/m/cube.mtl", CUBE_MTL)];
    let by_obj = parse_with(&mesh_scene(""), &files).unwrap();
    let by_file = parse_with(&mesh_scene("").replace("obj = ", "file = "), &files).unwrap();
    assert_eq!(by_obj.patches, by_file.patches);
    let both = mesh_scene("file = \"m/cube.obj\"\n");
    let e = parse_with(&both, &files).unwrap_err().to_string();
    assert_eq!(e, "t.toml:19: mesh[0].obj: `obj` is another name of `file`: give only one of them");
    let e = err(&format!("{MINI}\n[[mesh]]\nmaterial = \"white\"\n"));
    assert!(e.starts_with("t.toml:") && e.contains("mesh[0]: a [[mesh]] needs `file = PATH`"), "{e}");
    let e = err(&format!("{MINI}\n[[mesh]]\nfile = \"m/cube.stl\"\nmaterial = \"white\"\n"));
    assert!(e.starts_with("t.toml:19: mesh[0].file: 'base/m/cube.stl' is not a mesh file"), "{e}");
}

#[test]
fn ply_meshes_take_the_mesh_material_and_match_the_obj() {
    let obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 0.5 1\nf 1 2 3 4\nf 1 2 5\n";
    let text = |file: &str| format!("{MINI}\n[[mesh]]\nfile = \"{file}\"\nmaterial = \"white\"\nscale = 2\n");
    let from_obj = parse_with(&text("m.obj"), &[("base/m.obj", obj)]).unwrap();
    let ascii = crate::ply::tests::ASCII;
    let from_ply = parse_with(&text("m.ply"), &[("base/m.ply", ascii)]).unwrap();
    assert_eq!(from_obj.patches, from_ply.patches);
    let binary = crate::ply::tests::binary(true);
    let from_binary = parse_with_bytes(&text("m.ply"), &[("base/m.ply", &binary)]).unwrap();
    assert_eq!(from_obj.patches, from_binary.patches);
    let no_material = format!("{MINI}\n[[mesh]]\nfile = \"m.ply\"\n");
    let e = parse_with(&no_material, &[("base/m.ply", ascii)]).unwrap_err().to_string();
    assert!(e.contains("mesh[0].material: base/m.ply (a PLY file has no materials): face has no material"), "{e}");
}

#[test]
fn a_non_utf8_obj_names_its_line() {
    let e = parse_with_bytes(&mesh_scene(""), &[("base/m/cube.obj", b"v 0 0 0\nv \xff 0 0\n")]).unwrap_err();
    assert_eq!(e.to_string(), "base/m/cube.obj:2: obj: not UTF-8 text");
}

#[test]
fn emit_makes_an_area_light_and_is_checked() {
    // A scene lit only by an emitting material parses without a [[light]].
    let lamp = MINI
        .replace("[[light]]\nposition = [0, 1.9, 0]\nintensity = [1, 1, 1]\n", "")
        .replace("diffuse = [0.7, 0.7, 0.7]", "diffuse = [0.7, 0.7, 0.7]\nemit = [4, 2, 1]");
    let s = parse(&lamp).unwrap();
    assert!(s.lights.is_empty());
    assert_eq!(s.materials[0].emit, Rgb::new(4.0, 2.0, 1.0));
    assert!(s.materials[0].is_emitter());
    assert!(!parse(MINI).unwrap().materials[0].is_emitter(), "black by default");
    let e = err(&lamp.replace("emit = [4, 2, 1]", "emit = [4, -2, 1]"));
    assert_eq!(e, "t.toml:10: material[0].emit: green = -2 is out of range [0, 1e30]");
    let e = err(&lamp.replace("emit = [4, 2, 1]", "emit = [4, 2, nan]"));
    assert!(e.starts_with("t.toml:10: material[0].emit:"), "{e}");
    let e = err(&lamp.replace("emit = [4, 2, 1]", "emit = [4, 2, 1e31]"));
    assert!(e.starts_with("t.toml:10: material[0].emit: blue = "), "{e}");
    // An emitting material no patch uses lights nothing.
    let unused = lamp
        .replace("emit = [4, 2, 1]", "")
        .replace("[[triangle]]", "[[material]]\nname = \"lamp\"\nemit = [1, 1, 1]\n\n[[triangle]]");
    assert!(err(&unused).contains("no [[light]] and no patch of a material with `emit`"));
}

#[test]
fn a_streamed_obj_reports_its_errors_in_the_order_of_a_whole_read() {
    let files = |obj: &'static str| vec![("base/m/cube.obj", obj), ("base/m/cube.mtl", CUBE_MTL)];
    // A face without a material, then a line that is not OBJ: the text's error first.
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nbogus\n";
    let e = parse_with(&mesh_scene(""), &files(obj)).unwrap_err().to_string();
    assert!(e.starts_with("base/m/cube.obj:5: obj: unknown statement 'bogus'"), "{e}");
    // An MTL that cannot be read, named after the faces: before the faces' materials.
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl gold\nf 1 2 3\nmtllib none.mtl\n";
    let e = parse_with(&mesh_scene(""), &files(obj)).unwrap_err().to_string();
    assert!(e.starts_with("base/m/cube.obj:6: mtllib: cannot read MTL file 'base/m/none.mtl'"), "{e}");
    // A vertex the transform sends too far, then a face without a material: the file's
    // error first, then the placement's.
    let obj = "mtllib cube.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\nusemtl gold\nf 1 2 3\n";
    let e = parse_with(&mesh_scene("scale = 1e300\n"), &files(obj)).unwrap_err().to_string();
    assert!(e.contains("base/m/cube.obj:8: material 'gold' is not defined"), "{e}");
    let obj = "mtllib cube.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n";
    let e = parse_with(&mesh_scene("scale = 1e300\n"), &files(obj)).unwrap_err().to_string();
    assert!(e.starts_with("t.toml:19: mesh[0].scale: the transform sends a vertex past"), "{e}");
    // Only zero-area faces: after everything else.
    let obj = "mtllib cube.mtl\nv 0 0 0\nv 1 0 0\nusemtl red\nf 1 2 1\n";
    let e = parse_with(&mesh_scene(""), &files(obj)).unwrap_err().to_string();
    assert!(e.contains("has no faces of non-zero area"), "{e}");
}
