//! Tests of the mesh placement and the format choice.

use super::*;

#[test]
fn rotation_is_x_then_y_then_z() {
    let t = Transform::new(DVec3::new(1.0, 1.0, 1.0), DVec3::new(90.0, 90.0, 0.0), DVec3::ZERO);
    // (0,1,0) --X 90--> (0,0,1) --Y 90--> (1,0,0).
    let p = t.apply(DVec3::new(0.0, 1.0, 0.0));
    assert!((p - DVec3::new(1.0, 0.0, 0.0)).length() < 1e-12, "{p:?}");
    let t = Transform::new(DVec3::new(2.0, 3.0, 4.0), DVec3::new(0.0, 0.0, 90.0), DVec3::new(1.0, 1.0, 1.0));
    // (1,1,1) --scale--> (2,3,4) --Z 90--> (-3,2,4) --translate--> (-2,3,5).
    let p = t.apply(DVec3::new(1.0, 1.0, 1.0));
    assert!((p - DVec3::new(-2.0, 3.0, 5.0)).length() < 1e-12, "{p:?}");
    assert!(!t.flips_winding());
    assert!(Transform::new(DVec3::new(-1.0, 1.0, 1.0), DVec3::ZERO, DVec3::ZERO).flips_winding());
    assert!(!Transform::new(DVec3::new(-1.0, -1.0, 1.0), DVec3::ZERO, DVec3::ZERO).flips_winding());
}

#[test]
fn the_format_follows_the_extension_in_any_case() {
    assert_eq!(MeshFormat::of(Path::new("a/b.OBJ")), Some(MeshFormat::Obj));
    assert_eq!(MeshFormat::of(Path::new("b.ply")), Some(MeshFormat::Ply));
    assert_eq!(MeshFormat::of(Path::new("b.gltf")), Some(MeshFormat::Gltf));
    assert_eq!(MeshFormat::of(Path::new("b.Glb")), Some(MeshFormat::Gltf));
    assert_eq!(MeshFormat::of(Path::new("b.stl")), None);
    assert_eq!(MeshFormat::of(Path::new("obj")), None);
}

#[test]
fn non_utf8_text_names_its_line_and_not_its_bytes() {
    let e = utf8("m.obj", "obj", b"v 0 0 0\nv 1 \xff\xfe secret\n").unwrap_err().to_string();
    assert_eq!(e, "m.obj:2: obj: not UTF-8 text");
}
