//! Tests of the glTF reader: documents made here, a triangle in a buffer.

use super::*;
use crate::mesh::Transform;
use base64::Engine;
use std::collections::HashMap;

/// The buffer: the triangle (0,0,0), (1,0,0), (0,1,0) as floats, then u16 indices 0 1 2.
fn buffer() -> Vec<u8> {
    let mut b: Vec<u8> =
        [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0].iter().flat_map(|x| x.to_le_bytes()).collect();
    b.extend([0u16, 1, 2, 0].iter().flat_map(|x| x.to_le_bytes()));
    b
}

/// A document placing the triangle with `nodes` (node 0 is the scene's root); `uri` is
/// the buffer's (None: a GLB's binary chunk).
fn document(nodes: &str, uri: Option<&str>) -> String {
    let uri = uri.map_or(String::new(), |u| format!(",\"uri\":\"{u}\""));
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":{nodes},
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1,"material":0}}]}}],
"materials":[{{"name":"red","pbrMetallicRoughness":{{"baseColorFactor":[0.8,0.1,0.1,1],"metallicFactor":0}}}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}},
{{"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":36}},{{"buffer":0,"byteOffset":36,"byteLength":6}}],
"buffers":[{{"byteLength":44{uri}}}]}}"#
    )
}

fn data_uri() -> String {
    format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(buffer()))
}

/// A GLB of `json` with `bin` as its binary chunk.
pub(crate) fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut j = json.as_bytes().to_vec();
    while j.len() % 4 != 0 {
        j.push(b' ');
    }
    let mut b = bin.to_vec();
    while b.len() % 4 != 0 {
        b.push(0);
    }
    let total = 12 + 8 + j.len() + 8 + b.len();
    let mut out = b"glTF".to_vec();
    for x in [2u32, total as u32, j.len() as u32, 0x4E4F_534A] {
        out.extend(x.to_le_bytes());
    }
    out.extend(&j);
    out.extend((b.len() as u32).to_le_bytes());
    out.extend(0x004E_4942u32.to_le_bytes());
    out.extend(&b);
    out
}

struct Loaded {
    triangles: Vec<ModelTriangle>,
    materials: Vec<Material>,
}

fn load_with(bytes: &[u8], files: &[(&str, Vec<u8>)], material: Option<u32>) -> Result<Loaded, SceneError> {
    let files: HashMap<PathBuf, Vec<u8>> = files.iter().map(|(p, b)| (PathBuf::from(p), b.clone())).collect();
    let read = move |p: &Path| files.get(p).cloned().ok_or_else(|| std::io::Error::from(std::io::ErrorKind::NotFound));
    let entry = MeshEntry {
        file: "m.gltf",
        key: "file",
        at: SourceLoc { file: "s.toml".into(), line: 3 },
        field: "mesh[0]".into(),
        transform: Transform::new(DVec3::ONE, DVec3::ZERO, DVec3::ZERO),
        material,
        shading: Default::default(),
    };
    let mut table = MaterialTable::new();
    let triangles = load(&entry, Path::new("d/m.gltf"), "d/m.gltf", bytes, &read, &mut table)?;
    Ok(Loaded { triangles, materials: table.list })
}

fn load_ok(json: &str) -> Loaded {
    load_with(json.as_bytes(), &[], None).unwrap_or_else(|e| panic!("{e}"))
}

fn load_err(bytes: &[u8]) -> String {
    match load_with(bytes, &[], None) {
        Ok(_) => panic!("loaded"),
        Err(e) => e.to_string(),
    }
}

fn close(a: DVec3, b: [f64; 3]) -> bool {
    (a - DVec3::from_array(b)).length() < 1e-6
}

#[test]
fn a_triangle_comes_with_its_base_colour_as_diffuse() {
    let l = load_ok(&document("[{\"mesh\":0}]", Some(&data_uri())));
    assert_eq!(l.triangles.len(), 1);
    let (v, m) = (l.triangles[0].v, l.triangles[0].material);
    assert_eq!(v, [DVec3::ZERO, DVec3::X, DVec3::Y]);
    assert_eq!(m, 0);
    assert_eq!(l.materials[0].name, "m.gltf:red");
    let d = l.materials[0].diffuse.0;
    assert!((d[0] - 0.8).abs() < 1e-6 && (d[1] - 0.1).abs() < 1e-6, "{d:?}");
    assert!(l.materials[0].mirror.is_black(), "metallic is ignored");
    // `material =` on the [[mesh]] wins.
    let l = load_with(document("[{\"mesh\":0}]", Some(&data_uri())).as_bytes(), &[], Some(7)).unwrap();
    assert_eq!(l.triangles[0].material, 7);
    assert!(l.materials.is_empty());
}

#[test]
fn node_transforms_compose_down_the_tree() {
    // Root: translate (10, 0, 0); child: rotate 90 degrees about z, scale 2.
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let nodes = format!(
        "[{{\"translation\":[10,0,0],\"children\":[1]}},{{\"mesh\":0,\"rotation\":[0,0,{s},{s}],\"scale\":[2,2,2]}}]"
    );
    let l = load_ok(&document(&nodes, Some(&data_uri())));
    let v = l.triangles[0].v;
    assert!(close(v[0], [10.0, 0.0, 0.0]) && close(v[1], [10.0, 2.0, 0.0]) && close(v[2], [8.0, 0.0, 0.0]), "{v:?}");
    // The same as one column-major matrix.
    let nodes = "[{\"mesh\":0,\"matrix\":[0,2,0,0, -2,0,0,0, 0,0,2,0, 10,0,0,1]}]";
    let m = load_ok(&document(nodes, Some(&data_uri())));
    for (a, b) in m.triangles[0].v.iter().zip(v) {
        assert!(close(*a, b.to_array()), "{:?}", m.triangles[0].v);
    }
}

#[test]
fn a_mirroring_node_keeps_the_triangle_facing_the_same_way() {
    let normal = |nodes: &str| {
        let v = load_ok(&document(nodes, Some(&data_uri()))).triangles[0].v;
        (v[1] - v[0]).cross(v[2] - v[0]).normalize()
    };
    assert!(close(normal("[{\"mesh\":0}]"), [0.0, 0.0, 1.0]));
    assert!(close(normal("[{\"mesh\":0,\"scale\":[-1,1,1]}]"), [0.0, 0.0, 1.0]));
}

#[test]
fn glb_and_external_buffers_read_as_the_embedded_one() {
    let embedded = load_ok(&document("[{\"mesh\":0}]", Some(&data_uri()))).triangles;
    let g = glb(&document("[{\"mesh\":0}]", None), &buffer());
    assert_eq!(load_with(&g, &[], None).unwrap().triangles, embedded);
    let external = document("[{\"mesh\":0}]", Some("my%20buffer.bin"));
    let l = load_with(external.as_bytes(), &[("d/my buffer.bin", buffer())], None).unwrap();
    assert_eq!(l.triangles, embedded);
}

#[test]
fn a_missing_buffer_names_it() {
    let e = load_err(document("[{\"mesh\":0}]", Some("gone.bin")).as_bytes());
    assert!(e.starts_with("d/m.gltf: gltf: buffers[0]: cannot read buffer file 'd/gone.bin'"), "{e}");
    let e = load_err(document("[{\"mesh\":0}]", Some("/etc/passwd")).as_bytes());
    assert!(e.contains("buffers[0]: a URI that is not a relative file name"), "{e}");
    let e = load_err(document("[{\"mesh\":0}]", Some("https://x.invalid/b.bin")).as_bytes());
    assert!(e.contains("not a relative file name"), "{e}");
    let short =
        format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode([0u8; 8]));
    let e = load_err(document("[{\"mesh\":0}]", Some(&short)).as_bytes());
    assert!(e.contains("buffers[0]: 8 bytes where byteLength says 44"), "{e}");
    let e = load_err(&glb(&document("[{\"mesh\":0}]", Some(&data_uri())).replace("\"uri\"", "\"x\""), &[]));
    assert!(e.contains("buffers[0]"), "{e}");
}

#[test]
fn bad_indices_name_their_json_path() {
    let doc = document("[{\"mesh\":0}]", Some(&data_uri()));
    let e = load_err(doc.replace("\"POSITION\":0", "\"POSITION\":9").as_bytes());
    assert!(
        e.starts_with("d/m.gltf: gltf: meshes[0].primitives[0].attributes[\"POSITION\"]: accessor 9 does not exist"),
        "{e}"
    );
    let e = load_err(doc.replace("\"indices\":1", "\"indices\":5").as_bytes());
    assert!(e.starts_with("d/m.gltf: gltf: meshes[0].primitives[0].indices: Index out of bounds"), "{e}");
    let e = load_err(doc.replace("\"nodes\":[0]}]", "\"nodes\":[3]}]").as_bytes());
    assert!(e.contains("scenes[0].nodes[0]: Index out of bounds"), "{e}");
    // Indices past the vertices, views past the buffer.
    let three = base64::engine::general_purpose::STANDARD.encode({
        let mut b = buffer();
        b[36] = 3;
        b
    });
    let e = load_err(doc.replace(&data_uri(), &format!("data:;base64,{three}")).as_bytes());
    assert!(e.contains("meshes[0].primitives[0]: index 3 is out of range: 3 vertices"), "{e}");
    let e =
        load_err(doc.replace("\"byteOffset\":36,\"byteLength\":6", "\"byteOffset\":40,\"byteLength\":6").as_bytes());
    assert!(e.contains("bufferViews[1] lies past the end of its buffer"), "{e}");
    let e = load_err(doc.replace("\"count\":3,\"type\":\"VEC3\"", "\"count\":4,\"type\":\"VEC3\"").as_bytes());
    assert!(e.contains("accessors[0]: element 3 lies past the end of its buffer view"), "{e}");
}

#[test]
fn broken_json_and_glb_are_errors_with_where() {
    let e = load_err(b"{\"asset\": {\"version\": \"2.0\"},\n \"nodes\": [}");
    assert!(e.starts_with("d/m.gltf:2: gltf: JSON syntax error at column"), "{e}");
    let e = load_err(b"{\"asset\": 3, \"secret\": \"hunter2\"}");
    assert!(e.contains("not a glTF document") && !e.contains("hunter2"), "{e}");
    let g = glb(&document("[{\"mesh\":0}]", None), &buffer());
    // Cut anywhere: an error, never a panic.
    for n in 0..g.len() {
        assert!(load_with(&g[..n], &[], None).is_err(), "cut at {n}");
    }
    let e = load_err(&g[..g.len() - 4]);
    assert!(e.contains("GLB: the header says"), "{e}");
}

#[test]
fn a_primitive_without_material_needs_the_mesh_s() {
    let doc = document("[{\"mesh\":0}]", Some(&data_uri())).replace(",\"material\":0", "");
    let e = load_err(doc.as_bytes());
    assert!(
        e.starts_with("s.toml:3: mesh[0].material: d/m.gltf: meshes[0].primitives[0]: face has no material"),
        "{e}"
    );
}

#[test]
fn the_stage_has_the_first_camera_and_the_point_and_spot_lights() {
    let nodes = r#"[{"mesh":0,"children":[1,2,3,4]},
        {"camera":1,"translation":[0,0,5]},
        {"camera":0,"translation":[0,1,5]},
        {"extensions":{"KHR_lights_punctual":{"light":0}},"translation":[2,3,4]},
        {"extensions":{"KHR_lights_punctual":{"light":1}},"rotation":[-0.7071068,0,0,0.7071068],"translation":[0,4,0]}]"#;
    let doc = document(nodes, Some(&data_uri())).replace(
        "\"buffers\"",
        r#""cameras":[{"type":"perspective","perspective":{"yfov":0.5,"znear":0.1,"aspectRatio":1.5}},
            {"type":"perspective","perspective":{"yfov":1.0,"znear":0.1}}],
        "extensionsUsed":["KHR_lights_punctual"],
        "extensions":{"KHR_lights_punctual":{"lights":[{"type":"point","color":[1,0.5,0.5],"intensity":20},
            {"type":"spot","intensity":5,"spot":{"innerConeAngle":0.2,"outerConeAngle":0.5}},
            {"type":"directional","intensity":3}]}},
        "buffers""#,
    );
    let stage = gltf_stage("m.gltf", doc.as_bytes()).unwrap_or_else(|e| panic!("{e}"));
    let cam = stage.camera.unwrap();
    assert!(close(cam.eye, [0.0, 1.0, 5.0]) && close(cam.look_at, [0.0, 1.0, 4.0]), "camera 0: {cam:?}");
    assert!((cam.fov_y_deg - 0.5f64.to_degrees()).abs() < 1e-4);
    assert_eq!(stage.aspect_ratio, Some(1.5));
    assert_eq!(stage.lights.len(), 2, "the directional light is left out");
    assert!(close(stage.lights[0].position, [2.0, 3.0, 4.0]));
    assert_eq!(stage.lights[0].intensity, Rgb::new(20.0, 10.0, 10.0));
    assert!(stage.lights[0].spot.is_none());
    let spot = stage.lights[1].spot.clone().unwrap();
    assert!(close(spot.direction, [0.0, -1.0, 0.0]), "{spot:?}");
    assert!((spot.half_angle_deg - 0.2f64.to_degrees()).abs() < 1e-4);
    assert!((spot.half_angle_deg + spot.falloff_deg - 0.5f64.to_degrees()).abs() < 1e-4);
}

#[test]
fn normals_come_through_the_node_transform_by_its_inverse_transpose() {
    let s = 0.5f32.sqrt();
    let mut bin = buffer();
    bin.extend([s, 0.0, s, s, 0.0, s, s, 0.0, s].iter().flat_map(|x| x.to_le_bytes()));
    let json = document(r#"[{"mesh":0,"scale":[2,1,1]}]"#, None)
        .replace(r#""attributes":{"POSITION":0}"#, r#""attributes":{"POSITION":0,"NORMAL":2}"#)
        .replace(
            r#"{"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}]"#,
            r#"{"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"},
{"bufferView":2,"componentType":5126,"count":3,"type":"VEC3"}]"#,
        )
        .replace(
            r#"{"buffer":0,"byteOffset":36,"byteLength":6}]"#,
            r#"{"buffer":0,"byteOffset":36,"byteLength":6},{"buffer":0,"byteOffset":44,"byteLength":36}]"#,
        )
        .replace(r#""byteLength":44"#, r#""byteLength":80"#);
    let l = load_with(&glb(&json, &bin), &[], None).unwrap_or_else(|e| panic!("{e}"));
    let n = l.triangles[0].normals.expect("NORMAL read");
    // Stretching x by 2 halves the normal's x.
    let want = DVec3::new(0.5, 0.0, 1.0).normalize();
    for c in n {
        assert!((c.normalize() - want).length() < 1e-6, "{c:?}");
    }
}

#[test]
fn a_base_colour_texture_and_its_texcoords_are_read() {
    let mut png = Vec::new();
    image::RgbImage::from_pixel(2, 1, image::Rgb([10, 200, 30]))
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let mut bin = buffer();
    bin.extend([0.0f32, 0.0, 1.0, 0.0, 0.0, 1.0].iter().flat_map(|x| x.to_le_bytes()));
    bin.extend(&png);
    let json = document(r#"[{"mesh":0}]"#, None)
        .replace(r#""attributes":{"POSITION":0}"#, r#""attributes":{"POSITION":0,"TEXCOORD_0":2}"#)
        .replace(
            r#""metallicFactor":0}"#,
            r#""metallicFactor":0,"baseColorTexture":{"index":0}}"#,
        )
        .replace(
            r#"{"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}]"#,
            r#"{"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"},
{"bufferView":2,"componentType":5126,"count":3,"type":"VEC2"}],
"textures":[{"source":0}],"images":[{"bufferView":3,"mimeType":"image/png"}]"#,
        )
        .replace(
            r#"{"buffer":0,"byteOffset":36,"byteLength":6}]"#,
            &format!(
                r#"{{"buffer":0,"byteOffset":36,"byteLength":6}},{{"buffer":0,"byteOffset":44,"byteLength":24}},{{"buffer":0,"byteOffset":68,"byteLength":{}}}]"#,
                png.len()
            ),
        )
        .replace(r#""byteLength":44"#, &format!(r#""byteLength":{}"#, 68 + png.len()));
    let l = load_with(&glb(&json, &bin), &[], None).unwrap_or_else(|e| panic!("{e}"));
    let t = &l.triangles[0];
    assert_eq!(t.texture, Some(0));
    // glTF's t runs down the image, magg's v up.
    assert_eq!(t.uv, Some([glam::DVec2::new(0.0, 1.0), glam::DVec2::new(1.0, 1.0), glam::DVec2::new(0.0, 0.0)]));
}

#[test]
fn the_emissive_factor_times_its_strength_is_the_emitted_radiance() {
    let plain = document("[{\"mesh\":0}]", Some(&data_uri()));
    assert!(!load_ok(&plain).materials[0].is_emitter(), "no emissiveFactor: black");
    let lamp = plain.replace("\"metallicFactor\":0}", "\"metallicFactor\":0},\"emissiveFactor\":[1,0.5,0.25]");
    assert_eq!(load_ok(&lamp).materials[0].emit, Rgb::new(1.0, 0.5, 0.25));
    let strong = lamp.replace(
        "\"emissiveFactor\":[1,0.5,0.25]",
        "\"emissiveFactor\":[1,0.5,0.25],\"extensions\":{\"KHR_materials_emissive_strength\":{\"emissiveStrength\":8}}",
    );
    assert_eq!(load_ok(&strong).materials[0].emit, Rgb::new(8.0, 4.0, 2.0));
}

/// A grid of `n` x `n` quads (two triangles each, with normals) as one indexed
/// primitive and the same vertices as a strip, placed by a node with `scale`.
fn grid_document(n: u32, scale: f64) -> String {
    let mut b: Vec<u8> = Vec::new();
    let side = n + 1;
    for j in 0..side {
        for i in 0..side {
            let p = [i as f32, j as f32, ((i * 7 + j * 3) % 5) as f32 * 0.1];
            b.extend(p.iter().flat_map(|x| x.to_le_bytes()));
        }
    }
    let normals_at = b.len();
    for _ in 0..side * side {
        b.extend([0.0f32, 0.0, 1.0].iter().flat_map(|x| x.to_le_bytes()));
    }
    let indices_at = b.len();
    let mut count = 0;
    for j in 0..n {
        for i in 0..n {
            let k = j * side + i;
            for x in [k, k + 1, k + side + 1, k, k + side + 1, k + side] {
                b.extend(x.to_le_bytes());
                count += 1;
            }
        }
    }
    let uri = format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&b));
    let v = side * side;
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],
"nodes":[{{"mesh":0,"scale":[{scale},-1,1]}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"NORMAL":1}},"indices":2}},
{{"attributes":{{"POSITION":0}},"indices":2,"mode":5}}]}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":{v},"type":"VEC3","min":[0,0,0],"max":[{n},{n},1]}},
{{"bufferView":1,"componentType":5126,"count":{v},"type":"VEC3"}},
{{"bufferView":2,"componentType":5125,"count":{count},"type":"SCALAR"}}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{normals_at}}},
{{"buffer":0,"byteOffset":{normals_at},"byteLength":{}}},
{{"buffer":0,"byteOffset":{indices_at},"byteLength":{}}}],
"buffers":[{{"byteLength":{},"uri":"{uri}"}}]}}"#,
        indices_at - normals_at,
        b.len() - indices_at,
        b.len()
    )
}

#[test]
fn a_mesh_reads_the_same_on_one_core_as_on_several() {
    let pool = |threads| rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    for scale in ["1.5", "1e30"] {
        let doc = grid_document(40, scale.parse().unwrap());
        let read = || load_with(doc.as_bytes(), &[], Some(0)).map(|l| l.triangles);
        let one = pool(1).install(read);
        let four = pool(4).install(read);
        if scale == "1.5" {
            assert_eq!(one.as_ref().map(Vec::len), Ok(2 * 40 * 40 + 3 * 40 * 40 * 2 - 2));
        } else {
            assert!(one.as_ref().is_err_and(|e| e.message.contains("places a vertex past")), "{one:?}");
        }
        assert_eq!(one, four, "scale {scale}");
    }
}
