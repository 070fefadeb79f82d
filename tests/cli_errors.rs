//! Bad input of every kind ends in one readable line, `magg-host: error: ...`, and exit
//! code 1: never a panic, never a partial render.

use magg_tests::{assert_user_error, magg_host};
use std::path::{Path, PathBuf};
use std::process::Output;

/// A valid scene: one white floor under one light. Line numbers below refer to it.
const GOOD: &str = r#"[camera]
eye = [0.0, 1.0, 3.0]
look_at = [0.0, 1.0, 0.0]
fov = 40.0

[render]
width = 16
height = 16
light_rays = 2
pixel_samples = 1

[[light]]
position = [0.0, 1.9, 0.0]
intensity = [3.0, 3.0, 3.0]

[[material]]
name = "white"
diffuse = [0.5, 0.5, 0.5]

[[quad]]
vertices = [[-1, 0, -1], [-1, 0, 1], [1, 0, 1], [1, 0, -1]]
material = "white"
"#;

/// Writes `text` as `name` in `dir`.
fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// `GOOD` with `from` replaced by `to` (which must occur).
fn good_with(from: &str, to: &str) -> String {
    assert!(GOOD.contains(from), "{from:?} not in the good scene");
    GOOD.replacen(from, to, 1)
}

/// Renders `scene` into `dir` with `args` (no `--quiet`: errors must come before any
/// output).
fn render(dir: &Path, scene: &Path, args: &[&str]) -> Output {
    magg_host().current_dir(dir).arg("render").arg(scene).args(args).output().unwrap()
}

fn assert_contains(line: &str, parts: &[&str]) {
    for p in parts {
        assert!(line.contains(p), "error {line:?} does not contain {p:?}");
    }
}

#[test]
fn the_good_scene_renders() {
    // The baseline every other case here breaks in one place.
    let dir = tempfile::tempdir().unwrap();
    let s = write(dir.path(), "good.toml", GOOD);
    let out = render(dir.path(), &s, &["--out", "good.png", "--quiet"]);
    magg_tests::assert_success(&out, "the good scene");
    assert!(dir.path().join("good.png").is_file());
}

#[test]
fn missing_scene_file_names_the_path() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("no-such-scene.toml");
    let out = render(dir.path(), &missing, &["--out", "x.png"]);
    let line = assert_user_error(&out, "missing scene");
    assert_contains(&line, &[&missing.display().to_string()]);
    assert!(!dir.path().join("x.png").exists(), "an image was written");

    let out = magg_host().arg("info").arg(&missing).output().unwrap();
    let line = assert_user_error(&out, "info on a missing scene");
    assert_contains(&line, &["no-such-scene.toml"]);
}

#[test]
fn toml_syntax_error_gives_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    // Line 4: two numbers after `fov =`.
    let s = write(dir.path(), "syntax.toml", &good_with("fov = 40.0", "fov = 40.0 0"));
    let out = render(dir.path(), &s, &["--out", "x.png"]);
    let line = assert_user_error(&out, "TOML syntax error");
    assert_contains(&line, &["syntax.toml:4"]);

    // An unclosed array on line 13.
    let s = write(dir.path(), "unclosed.toml", &good_with("position = [0.0, 1.9, 0.0]", "position = [0.0, 1.9, 0.0"));
    let out = render(dir.path(), &s, &["--out", "x.png"]);
    let line = assert_user_error(&out, "unclosed array");
    assert_contains(&line, &["unclosed.toml:"]);
}

#[test]
fn undefined_material_names_file_line_and_material() {
    let dir = tempfile::tempdir().unwrap();
    let s = write(dir.path(), "gold.toml", &good_with("material = \"white\"", "material = \"gold\""));
    let out = render(dir.path(), &s, &["--out", "x.png"]);
    let line = assert_user_error(&out, "undefined material");
    // The `[[quad]]`'s material is on line 22.
    assert_contains(&line, &["gold.toml:22", "'gold'", "quad[0].material"]);

    // `info` reads the scene the same way.
    let out = magg_host().current_dir(dir.path()).args(["info", "gold.toml"]).output().unwrap();
    let line = assert_user_error(&out, "info, undefined material");
    assert_contains(&line, &["gold.toml:22", "'gold'"]);
}

#[test]
fn nan_and_bad_intensities_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    for (name, value, needle) in [
        ("nan.toml", "[3.0, nan, 3.0]", "light[0].intensity"),
        ("inf.toml", "[inf, 3.0, 3.0]", "light[0].intensity"),
        ("negative.toml", "[3.0, 3.0, -1.0]", "light[0].intensity"),
        ("dark.toml", "[0.0, 0.0, 0.0]", "light[0].intensity"),
    ] {
        let s = write(dir.path(), name, &good_with("intensity = [3.0, 3.0, 3.0]", &format!("intensity = {value}")));
        let out = render(dir.path(), &s, &["--out", "x.png"]);
        let line = assert_user_error(&out, name);
        assert_contains(&line, &[&format!("{name}:14"), needle]);
    }
}

#[test]
fn bad_flags_are_refused_before_reading_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    let s = write(dir.path(), "good.toml", GOOD);
    for (args, needle) in [
        (&["--out", "x.png", "--cache-blocks", "0"][..], "--cache-blocks 0"),
        (&["--out", "x.png", "--cache-blocks", "lots"][..], "--cache-blocks"),
        (&["--out", "x.bmp"][..], "x.bmp"),
        (&["--out", "x.png", "--linear", "y.png"][..], "--linear"),
        (&["--out", "x.png", "--forks", "0"][..], "--forks 0"),
        (&["--out", "x.png", "--subscreen", "0"][..], "--subscreen 0"),
        (&["--out", "x.png", "--profile", "t800"][..], "--profile t800"),
        (&["--out", "x.png", "--width", "0"][..], "--width 0"),
        (&["--out", "x.png", "--element-size=-1"][..], "--element-size -1"),
        (&["--out", "x.png", "--element-size=nan"][..], "--element-size NaN"),
    ] {
        let out = render(dir.path(), &s, args);
        let line = assert_user_error(&out, &args.join(" "));
        assert_contains(&line, &[needle]);
        assert!(std::fs::read_dir(dir.path()).unwrap().count() == 1, "{}: wrote a file", args.join(" "));
    }
}

#[test]
fn too_many_elements_is_refused_with_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    // A 1 km quad at 1 mm elements: 1414214 x 1414214 subdivisions per half.
    let big = good_with(
        "[[-1, 0, -1], [-1, 0, 1], [1, 0, 1], [1, 0, -1]]",
        "[[-500, 0, -500], [-500, 0, 500], [500, 0, 500], [500, 0, -500]]",
    )
    .replacen("pixel_samples = 1", "pixel_samples = 1\nelement_size = 0.001", 1);
    let s = write(dir.path(), "big.toml", &big);
    let out = render(dir.path(), &s, &["--out", "x.png"]);
    let line = assert_user_error(&out, "1 km quad");
    assert_contains(&line, &["big.toml:", "1414214", "max_elements", "20000000"]);

    // Triangles are counted at preprocessing, with a lower limit from the file.
    let tri = good_with(
        "[[quad]]\nvertices = [[-1, 0, -1], [-1, 0, 1], [1, 0, 1], [1, 0, -1]]",
        "[[triangle]]\nvertices = [[-1, 0, -1], [-1, 0, 1], [1, 0, 1]]",
    )
    .replacen("pixel_samples = 1", "pixel_samples = 1\nelement_size = 0.01\nmax_elements = 1000", 1);
    let s = write(dir.path(), "tri.toml", &tri);
    // ceil(2.83 / 0.01) = 283 subdivisions: 283^2 = 80089 elements.
    let out = render(dir.path(), &s, &["--out", "x.png", "--quiet"]);
    let line = assert_user_error(&out, "triangle over max_elements");
    assert_contains(&line, &["tri.toml", "80089", "max_elements", "1000"]);
    let out = magg_host().current_dir(dir.path()).args(["info", "tri.toml"]).output().unwrap();
    let line = assert_user_error(&out, "info, triangle over max_elements");
    assert_contains(&line, &["80089", "max_elements"]);
    assert!(!dir.path().join("x.png").exists(), "an image was written");
}

#[test]
fn unknown_render_key_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let s = write(dir.path(), "typo.toml", &good_with("width = 16", "widht = 16"));
    let out = render(dir.path(), &s, &["--out", "x.png"]);
    let line = assert_user_error(&out, "unknown key");
    assert_contains(&line, &["typo.toml:7", "widht"]);
}

#[test]
fn unknown_section_and_wrong_type_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let s = write(dir.path(), "section.toml", &format!("{GOOD}\n[lens]\nf = 2\n"));
    let out = render(dir.path(), &s, &["--out", "x.png"]);
    let line = assert_user_error(&out, "unknown section");
    assert_contains(&line, &["section.toml", "lens"]);

    let s = write(dir.path(), "type.toml", &good_with("width = 16", "width = \"wide\""));
    let out = render(dir.path(), &s, &["--out", "x.png"]);
    let line = assert_user_error(&out, "wrong type");
    assert_contains(&line, &["type.toml:7"]);
}

#[test]
fn scene_without_lights_or_patches_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let no_light = good_with("[[light]]\nposition = [0.0, 1.9, 0.0]\nintensity = [3.0, 3.0, 3.0]\n", "");
    let s = write(dir.path(), "nolight.toml", &no_light);
    let out = render(dir.path(), &s, &["--out", "x.png"]);
    let line = assert_user_error(&out, "no light");
    assert_contains(&line, &["nolight.toml"]);

    let no_patch =
        good_with("[[quad]]\nvertices = [[-1, 0, -1], [-1, 0, 1], [1, 0, 1], [1, 0, -1]]\nmaterial = \"white\"\n", "");
    let s = write(dir.path(), "nopatch.toml", &no_patch);
    let out = render(dir.path(), &s, &["--out", "x.png"]);
    let line = assert_user_error(&out, "no patch");
    assert_contains(&line, &["nopatch.toml"]);
}

#[test]
fn missing_obj_mesh_names_the_obj() {
    let dir = tempfile::tempdir().unwrap();
    let s = write(
        dir.path(),
        "mesh.toml",
        &format!("{GOOD}\n[[mesh]]\nobj = \"meshes/nothere.obj\"\nmaterial = \"white\"\n"),
    );
    let out = render(dir.path(), &s, &["--out", "x.png"]);
    let line = assert_user_error(&out, "missing OBJ");
    assert_contains(&line, &["mesh.toml", "nothere.obj"]);
}

#[test]
fn unwritable_output_is_an_error_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let s = write(dir.path(), "good.toml", GOOD);
    let out = render(dir.path(), &s, &["--out", "no/such/dir/x.png", "--quiet"]);
    let line = assert_user_error(&out, "unwritable output");
    assert_contains(&line, &["no/such/dir/x.png"]);
}

#[test]
fn devices_and_files_outside_the_scene_folder_are_not_read() {
    let (dir, other) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    // A device as the scene, or as its mesh: refused at once, not read until memory runs out.
    let out = render(dir.path(), Path::new("/dev/zero"), &["--out", "x.png"]);
    assert_contains(&assert_user_error(&out, "/dev/zero as the scene"), &["/dev/zero", "not a regular file"]);
    let mesh = |obj: &str| format!("{GOOD}\n[[mesh]]\nobj = \"{obj}\"\nmaterial = \"white\"\n");
    let s = write(dir.path(), "dev.toml", &mesh("/dev/zero"));
    assert_contains(
        &assert_user_error(&render(dir.path(), &s, &["--out", "x.png"]), "/dev/zero mesh"),
        &["dev.toml", "obj"],
    );
    // A file beside another folder: refused, and what it holds is not printed.
    write(other.path(), "secret.obj", "MAGG_TOKEN=hunter2-very-secret-value\n");
    let outside = other.path().join("secret.obj");
    let s = write(dir.path(), "out.toml", &mesh(&outside.display().to_string()));
    let line = assert_user_error(&render(dir.path(), &s, &["--out", "x.png"]), "a mesh outside the scene's folder");
    assert_contains(&line, &["out.toml", "outside the scene's folder", "--allow-path"]);
    assert!(!line.contains("hunter2"), "{line}");
    // Allowed, it is read; it is not an OBJ, and the error still hides its contents.
    let out = magg_host()
        .current_dir(dir.path())
        .args(["--allow-path", &other.path().display().to_string(), "render"])
        .arg(&s)
        .args(["--out", "x.png"])
        .output()
        .unwrap();
    let line = assert_user_error(&out, "an allowed foreign file");
    assert_contains(&line, &["secret.obj:1", "unknown statement a token of"]);
    assert!(!line.contains("hunter2"), "{line}");
    assert!(!dir.path().join("x.png").exists());
}
