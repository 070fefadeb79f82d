//! A model file renders on its own, in a scene made up around it (camera framing it, a
//! light beside the camera, grey where its MTL gives no colour); `--set` reaches that
//! scene's values as a file's. OBJ, PLY (ASCII and binary) and glTF (`.gltf`, `.glb`)
//! alike, on their own and as `[[mesh]] file =` of a TOML scene; the models are made
//! here, a small pyramid.

use magg_tests::*;
use std::path::{Path, PathBuf};

/// A pyramid: a square base in y = 0 and an apex, six triangles wound outward.
const CORNERS: [[f32; 3]; 5] =
    [[-1.0, 0.0, -1.0], [1.0, 0.0, -1.0], [1.0, 0.0, 1.0], [-1.0, 0.0, 1.0], [0.0, 1.5, 0.0]];
const FACES: [[u32; 3]; 6] = [[0, 1, 2], [0, 2, 3], [0, 4, 1], [1, 4, 2], [2, 4, 3], [3, 4, 0]];
/// Small, quick renders.
const QUICK: [&str; 8] = ["--width", "32", "--height", "32", "--light-rays", "2", "--spp", "1"];

/// The pyramid as OBJ, its corners mapped by `f` (no materials).
fn obj(f: impl Fn([f32; 3]) -> [f32; 3]) -> String {
    let mut s: String = CORNERS.iter().map(|&c| f(c)).map(|c| format!("v {} {} {}\n", c[0], c[1], c[2])).collect();
    s.extend(FACES.iter().map(|t| format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1)));
    s
}

/// The pyramid as an ASCII PLY, its base as one quad (fan-triangulated as OBJ's).
fn ply_ascii() -> String {
    let mut s = "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n\
                 element face 5\nproperty list uchar int vertex_indices\nend_header\n"
        .to_string();
    s.extend(CORNERS.iter().map(|c| format!("{} {} {}\n", c[0], c[1], c[2])));
    s.push_str("4 0 1 2 3\n");
    s.extend(FACES[2..].iter().map(|t| format!("3 {} {} {}\n", t[0], t[1], t[2])));
    s
}

/// The pyramid as a binary big-endian PLY.
fn ply_binary() -> Vec<u8> {
    let mut b = "ply\nformat binary_big_endian 1.0\nelement vertex 5\nproperty float x\nproperty float y\n\
                 property float z\nelement face 6\nproperty list uchar uint vertex_indices\nend_header\n"
        .as_bytes()
        .to_vec();
    b.extend(CORNERS.iter().flatten().flat_map(|x| x.to_be_bytes()));
    for t in FACES {
        b.push(3);
        b.extend(t.iter().flat_map(|k| k.to_be_bytes()));
    }
    b
}

/// The pyramid's buffer (positions, then u32 indices) and a glTF document placing it
/// with `nodes`; `uri` is the buffer's (None: a GLB's binary chunk); `extra` adds
/// top-level members (cameras, lights).
fn gltf(nodes: &str, uri: Option<&str>, extra: &str) -> (String, Vec<u8>) {
    let mut bin: Vec<u8> = CORNERS.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
    bin.extend(FACES.iter().flatten().flat_map(|k| k.to_le_bytes()));
    let uri = uri.map_or(String::new(), |u| format!(",\"uri\":\"{u}\""));
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":{nodes},
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1,"material":0}}]}}],
"materials":[{{"name":"stone","pbrMetallicRoughness":{{"baseColorFactor":[0.5,0.6,0.7,1]}}}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":5,"type":"VEC3","min":[-1,0,-1],"max":[1,1.5,1]}},
{{"bufferView":1,"componentType":5125,"count":18,"type":"SCALAR"}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":60}},{{"buffer":0,"byteOffset":60,"byteLength":72}}],
"buffers":[{{"byteLength":132{uri}}}]{extra}}}"#
    );
    (json, bin)
}

/// A GLB of `json` and `bin`.
fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let pad = |mut v: Vec<u8>, with: u8| {
        while v.len() % 4 != 0 {
            v.push(with);
        }
        v
    };
    let (j, b) = (pad(json.as_bytes().to_vec(), b' '), pad(bin.to_vec(), 0));
    let mut out = b"glTF".to_vec();
    for x in [2, (28 + j.len() + b.len()) as u32, j.len() as u32, 0x4E4F_534A] {
        out.extend(u32::to_le_bytes(x));
    }
    out.extend(&j);
    out.extend((b.len() as u32).to_le_bytes());
    out.extend(0x004E_4942u32.to_le_bytes());
    out.extend(&b);
    out
}

/// Writes `bytes` to `dir/name` and returns its path.
fn put(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

/// The linear image of a render, as bytes.
fn pfm_of(model: &Path, dir: &Path, stem: &str, extra: &[&str]) -> Vec<u8> {
    let args: Vec<&str> = QUICK.iter().copied().chain(extra.iter().copied()).collect();
    std::fs::read(render(model, dir, stem, &args).pfm).unwrap()
}

/// The patch count `magg-host info` printed.
fn patches(stdout: &[u8]) -> Option<String> {
    let text = String::from_utf8_lossy(stdout);
    let line = text.lines().find(|l| l.starts_with("patches"))?;
    line.split_whitespace().nth(1).map(String::from)
}

/// A camera and a point light, as glTF members and nodes 1 and 2 under the root.
const STAGE: &str = r#","cameras":[{"type":"perspective","perspective":{"yfov":0.6,"znear":0.1}}],
"extensionsUsed":["KHR_lights_punctual"],
"extensions":{"KHR_lights_punctual":{"lights":[{"type":"point","color":[1,1,1],"intensity":40}]}}"#;
const STAGE_NODES: &str = r#"[{"mesh":0,"children":[1,2]},{"camera":0,"translation":[0,0.6,6]},
{"extensions":{"KHR_lights_punctual":{"light":0}},"translation":[3,4,5]}]"#;

#[test]
fn a_bare_obj_renders_framed_and_lit() {
    let dir = tempfile::tempdir().unwrap();
    let model = workspace_root().join("scenes/meshes/sphere.obj");
    let a =
        render(&model, dir.path(), "sphere", &["--width", "48", "--height", "40", "--light-rays", "2", "--spp", "1"]);
    let (w, h, rgb) = read_png_rgb(&a.png);
    assert_eq!((w, h), (48, 40));
    assert!(not_all_black(&rgb), "the model is not lit");
    // The model is in view: its centre pixel is lit, a corner is background.
    let px = |x: u32, y: u32| rgb[3 * (y * w + x) as usize..][..3].iter().map(|&c| c as u32).sum::<u32>();
    assert!(px(24, 20) > 0 && px(0, 0) == 0, "the model is not framed in the middle");
    let zoomed = render(
        &model,
        dir.path(),
        "zoom",
        &["--width", "48", "--height", "40", "--light-rays", "2", "--spp", "1", "--set", "camera.fov=10"],
    );
    let (_, _, z) = read_png_rgb(&zoomed.png);
    assert!(z[..3].iter().any(|&c| c > 0), "--set camera.fov=10 did not bring the model closer");
    let info = magg_host().arg("info").arg(&model).output().unwrap();
    assert_success(&info, "info on a model");
    assert!(String::from_utf8_lossy(&info.stdout).contains("1280"), "the sphere's 1280 patches");
}

#[test]
fn ply_ascii_and_binary_render_on_their_own_bit_for_bit_as_the_obj() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let from_obj = pfm_of(&put(d, "p.obj", obj(|c| c)), d, "obj", &[]);
    let from_ascii = pfm_of(&put(d, "a.ply", ply_ascii()), d, "ascii", &[]);
    let from_binary = pfm_of(&put(d, "b.ply", ply_binary()), d, "binary", &[]);
    assert!(from_obj == from_ascii, "the ASCII PLY's image differs from the OBJ's");
    assert!(from_obj == from_binary, "the binary PLY's image differs from the OBJ's");
    let (w, h, rgb) = read_png_rgb(&Rendered::at(d, "binary").png);
    assert_eq!((w, h), (32, 32));
    assert!(not_all_black(&rgb), "the PLY is not lit");
    let info = magg_host().arg("info").arg(d.join("b.ply")).output().unwrap();
    assert_success(&info, "info on a PLY");
    assert_eq!(patches(&info.stdout), Some("6".to_string()), "the pyramid's 6 patches");
}

#[test]
fn gltf_and_glb_render_on_their_own_with_their_camera_and_light() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (json, bin) = gltf(STAGE_NODES, Some("pyramid.bin"), STAGE);
    put(d, "pyramid.bin", &bin);
    let from_gltf = pfm_of(&put(d, "p.gltf", &json), d, "gltf", &[]);
    let (json_glb, _) = gltf(STAGE_NODES, None, STAGE);
    let from_glb = pfm_of(&put(d, "p.glb", glb(&json_glb, &bin)), d, "glb", &[]);
    assert!(from_gltf == from_glb, "the .glb's image differs from the .gltf's");
    assert!(not_all_black(&read_png_rgb(&Rendered::at(d, "glb").png).2), "the glTF is not lit");
    // Without its camera and light, the made-up ones frame it: another image.
    let (bare, _) = gltf("[{\"mesh\":0}]", Some("pyramid.bin"), "");
    let framed = pfm_of(&put(d, "bare.gltf", bare), d, "bare", &[]);
    assert!(framed != from_gltf, "the glTF's own camera and light were not used");
    // Its camera is the scene's, and --set still reaches it.
    let zoomed = pfm_of(&d.join("p.gltf"), d, "zoom", &["--set", "camera.fov=10"]);
    assert!(zoomed != from_gltf, "--set camera.fov did not reach the glTF's camera");
    let info = magg_host().arg("info").arg(d.join("p.glb")).output().unwrap();
    assert_success(&info, "info on a GLB");
    assert_eq!(patches(&info.stdout), Some("6".to_string()), "the pyramid's 6 patches");
}

#[test]
fn every_format_is_a_mesh_file_of_a_toml_scene_and_node_transforms_apply() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The glTF places the pyramid under two nodes: translate (0.5, 0, 0), then scale 2.
    let nodes = r#"[{"translation":[0.5,0,0],"children":[1]},{"mesh":0,"scale":[2,2,2]}]"#;
    let (json, bin) = gltf(nodes, Some("pyramid.bin"), "");
    put(d, "pyramid.bin", &bin);
    put(d, "p.gltf", &json);
    let (json_glb, _) = gltf(nodes, None, "");
    put(d, "p.glb", glb(&json_glb, &bin));
    put(d, "moved.obj", obj(|c| [2.0 * c[0] + 0.5, 2.0 * c[1], 2.0 * c[2]]));
    put(d, "p.obj", obj(|c| c));
    put(d, "a.ply", ply_ascii());
    put(d, "b.ply", ply_binary());
    let scene = |file: &str, extra: &str| {
        format!(
            "[camera]\neye = [3, 4, 9]\nlook_at = [0.5, 1, 0]\nfov = 40\n\n[render]\nelement_size = 0.5\n\n\
             [[light]]\nposition = [4, 6, 6]\nintensity = [60, 60, 60]\n\n\
             [[material]]\nname = \"white\"\ndiffuse = [0.7, 0.7, 0.7]\n\n[[mesh]]\nfile = \"{file}\"\n{extra}"
        )
    };
    let white = "material = \"white\"\n";
    let image = |name: &str, text: String| pfm_of(&put(d, name, text), d, name.trim_end_matches(".toml"), &[]);
    let moved_obj = image("moved.toml", scene("moved.obj", white));
    assert!(image("gltf.toml", scene("p.gltf", white)) == moved_obj, "the glTF's node transforms differ from the OBJ");
    assert!(image("glb.toml", scene("p.glb", white)) == moved_obj, "the GLB's node transforms differ from the OBJ");
    let plain_obj = image("obj.toml", scene("p.obj", white));
    assert!(image("ascii.toml", scene("a.ply", white)) == plain_obj, "the ASCII PLY differs from the OBJ");
    assert!(image("binary.toml", scene("b.ply", white)) == plain_obj, "the binary PLY differs from the OBJ");
    assert!(plain_obj != moved_obj, "the transform did nothing");
    // `obj =` is still the name of `file =`; the glTF's own material colours it.
    let _ = image("alias.toml", scene("p.obj", white).replace("file = ", "obj = "));
    let _ = image("stone.toml", scene("p.glb", ""));
}

#[test]
fn broken_model_files_are_one_line_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let error = |model: &Path, what: &str| {
        let out = magg_host().arg("render").arg(model).args(["--out"]).arg(d.join("x.png")).output().unwrap();
        assert_user_error(&out, what)
    };
    let full = ply_binary();
    let line = error(&put(d, "cut.ply", &full[..full.len() - 5]), "a truncated binary PLY");
    assert!(line.contains("cut.ply: ply: face 5 (byte ") && line.contains("truncated"), "{line}");
    let line = error(&put(d, "bad.ply", ply_ascii().replace("3 3 4 0", "3 3 4 9")), "a PLY index out of range");
    assert!(line.contains("bad.ply:19: ply: face 4: vertex index 9 is out of range"), "{line}");
    let (json, bin) = gltf("[{\"mesh\":0}]", Some("pyramid.bin"), "");
    put(d, "pyramid.bin", &bin);
    let line = error(&put(d, "acc.gltf", json.replace("\"indices\":1", "\"indices\":7")), "a bad accessor index");
    assert!(line.contains("acc.gltf: gltf: meshes[0].primitives[0].indices: Index out of bounds"), "{line}");
    let line = error(&put(d, "gone.gltf", json.replace("pyramid.bin", "gone.bin")), "a missing buffer");
    assert!(
        line.contains("gone.gltf: gltf: buffers[0]: cannot read buffer file") && line.contains("gone.bin"),
        "{line}"
    );
    let g = glb(&gltf("[{\"mesh\":0}]", None, "").0, &bin);
    let line = error(&put(d, "cut.glb", &g[..g.len() - 9]), "a truncated GLB");
    assert!(line.contains("cut.glb: gltf: GLB: the header says"), "{line}");
    assert!(!d.join("x.png").exists());
}
