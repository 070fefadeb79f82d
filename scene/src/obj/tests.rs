//! Tests of the OBJ and MTL readers.

use super::*;

fn obj(text: &str) -> ObjMesh {
    parse_obj("m.obj", text).unwrap()
}

fn obj_err(text: &str) -> String {
    parse_obj("m.obj", text).unwrap_err().to_string()
}

#[test]
fn polygons_are_fan_triangulated() {
    let m = obj("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0.5 1.5 0\nv 0 1 0\nf 1 2 3 4 5\n");
    let tris: Vec<[u32; 3]> = m.faces.iter().map(|f| f.corners).collect();
    assert_eq!(tris, [[0, 1, 2], [0, 2, 3], [0, 3, 4]]);
    assert!(m.faces.iter().all(|f| f.line == 6 && f.usemtl.is_none()));
}

#[test]
fn negative_indices_count_back_from_the_last_vertex() {
    let m = obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 5 5 5\nf -4 -1 -2\n");
    assert_eq!(m.faces[0].corners, [0, 1, 2]);
    assert_eq!(m.faces[1].corners, [0, 3, 2]);
}

#[test]
fn corner_forms_and_ignored_statements() {
    let text = "# a comment\no thing\ng group\ns 1\nv 0 0 0 1\nv 1 0 0 0.5 0.5 0.5\nv 0 1 0\n\
                vt 0 0\nvn 0 0 1\nf 1/1 2//1 3/1/1 # trailing comment\nl 1 2\n";
    let m = obj(text);
    assert_eq!(m.positions.len(), 3);
    assert_eq!(m.faces.len(), 1);
    assert_eq!(m.faces[0].corners, [0, 1, 2]);
}

#[test]
fn usemtl_and_mtllib_are_recorded() {
    let m = obj("mtllib a.mtl b.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\nusemtl blue\nf 1 2 3\nusemtl red\nf 1 2 3\n");
    assert_eq!(m.mtllibs.iter().map(|l| (l.file.as_str(), l.line)).collect::<Vec<_>>(), [("a.mtl", 1), ("b.mtl", 1)]);
    assert_eq!(m.usemtl_names, ["red", "blue"]);
    assert_eq!(m.faces.iter().map(|f| f.usemtl).collect::<Vec<_>>(), [Some(0), Some(1), Some(0)]);
}

#[test]
fn obj_errors_name_file_and_line() {
    let base = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    assert_eq!(
        obj_err(&format!("{base}f 1 2 4\n")),
        "m.obj:4: obj: f: vertex index 4 is out of range: 3 vertices defined so far"
    );
    assert!(obj_err(&format!("{base}f 1 2 -4\n")).starts_with("m.obj:4: obj: f: vertex index -4 is out of range"));
    assert!(obj_err(&format!("{base}f 0 1 2\n")).contains("index 0 is not valid"));
    assert!(obj_err(&format!("{base}f 1 2\n")).starts_with("m.obj:4: obj: f needs at least 3 vertices"));
    assert!(obj_err(&format!("{base}f 1 2 x\n")).contains("'x' is not a vertex index"));
    assert!(obj_err(&format!("{base}f 1 2 3/1/1/1\n")).contains("not a vertex reference"));
    assert!(obj_err("v 0 0\n").starts_with("m.obj:1: obj: v needs 3 coordinates"));
    assert!(obj_err("v 0 nan 0\n").contains("NaN is not a finite number"));
    assert!(obj_err("v 0 0 0\nbogus 1\n").starts_with("m.obj:2: obj: unknown statement 'bogus'"));
    assert!(obj_err("cstype bspline\n").contains("free-form geometry"));
    assert!(obj_err("usemtl\n").contains("usemtl needs a material name"));
    assert!(obj_err("\u{0}\u{1}garbage\n").starts_with("m.obj:1:"));
}

fn mtl(text: &str) -> Vec<Material> {
    parse_mtl("m.mtl", text).unwrap()
}

#[test]
fn mtl_maps_kd_ks_tf_d_ni() {
    let m = mtl("newmtl a\nKd 0.5 0.25 0.1\nKs 0.2\nNi 1.33\nKa 1 1 1\nillum 2\nmap_Kd x.png\n\nnewmtl glass pane\nTf 0.9 0.9 0.9\nKd 0 0 0\n");
    assert_eq!(m.len(), 2);
    assert_eq!(m[0].name, "a");
    assert_eq!(m[0].diffuse, Rgb::new(0.5, 0.25, 0.1));
    assert_eq!(m[0].mirror, Rgb::splat(0.2));
    assert_eq!(m[0].transmit, Rgb::BLACK);
    assert_eq!(m[0].ior, 1.33);
    assert_eq!(m[0].loc, SourceLoc { file: "m.mtl".into(), line: 1 });
    assert_eq!(m[1].name, "glass pane");
    assert_eq!(m[1].transmit, Rgb::splat(0.9));
    assert_eq!(m[1].ior, 1.5);
}

#[test]
fn mtl_transmission_from_dissolve() {
    let m = mtl(
        "newmtl a\nd 0.25\nnewmtl b\nTr 0.5\nnewmtl opaque\nTf 1 1 1\nd 1\nnewmtl tinted\nTf 1 0.5 0\nd -halo 0.5\n",
    );
    assert_eq!(m[0].transmit, Rgb::splat(0.75));
    assert_eq!(m[1].transmit, Rgb::splat(0.5));
    assert_eq!(m[2].transmit, Rgb::BLACK);
    assert_eq!(m[3].transmit, Rgb::new(0.5, 0.25, 0.0));
}

#[test]
fn mtl_is_clamped_then_scaled_to_conserve_energy() {
    let m = mtl("newmtl a\nKd 0.8 1.5 -0.2\nKs 0.4 0.5 0.1\nd 0.8\nNi 9\n");
    let a = &m[0];
    // red: 0.8 + 0.4 + 0.2 = 1.4 -> scaled by 1/1.4; green: clamp 1, 1 + 0.5 + 0.2 = 1.7;
    // blue: clamp 0, 0 + 0.1 + 0.2 = 0.3 -> unchanged.
    let close = |x: f64, y: f64| (x - y).abs() < 1e-12;
    assert!(close(a.diffuse.0[0], 0.8 / 1.4) && close(a.mirror.0[0], 0.4 / 1.4));
    assert!(close(a.diffuse.0[1], 1.0 / 1.7) && close(a.transmit.0[1], 0.2 / 1.7));
    assert!(close(a.diffuse.0[2], 0.0) && close(a.mirror.0[2], 0.1) && close(a.transmit.0[2], 0.2));
    for k in 0..3 {
        assert!(a.diffuse.0[k] + a.mirror.0[k] + a.transmit.0[k] <= 1.0 + 1e-12);
    }
    assert_eq!(a.ior, 4.0);
}

#[test]
fn mtl_errors_name_file_and_line() {
    let e = parse_mtl("m.mtl", "newmtl a\nKd 0.5 x 0.5\n").unwrap_err().to_string();
    assert_eq!(e, "m.mtl:2: mtl: Kd: 'x' is not a number");
    let e = parse_mtl("m.mtl", "Kd 1 1 1\n").unwrap_err().to_string();
    assert!(e.starts_with("m.mtl:1: mtl: 'Kd' before any newmtl"), "{e}");
    let e = parse_mtl("m.mtl", "newmtl a\nnewmtl a\n").unwrap_err().to_string();
    assert!(e.starts_with("m.mtl:2: mtl: material 'a' is already defined at line 1"), "{e}");
    let e = parse_mtl("m.mtl", "newmtl a\nKd spectral file.rfl\n").unwrap_err().to_string();
    assert!(e.contains("not supported"), "{e}");
}

#[test]
fn mtl_ke_is_the_emitted_radiance() {
    let m = mtl("newmtl lamp\nKd 0.1\nKe 5 4 3\n\nnewmtl dull\nKd 0.5\nKe 0 0 0\n\nnewmtl hot\nKe 2e31 -1 1\n");
    assert_eq!(m[0].emit, Rgb::new(5.0, 4.0, 3.0));
    assert!(!m[1].is_emitter());
    assert_eq!(m[2].emit, Rgb::new(MAX_RADIOMETRIC, 0.0, 1.0), "clamped to [0, MAX_RADIOMETRIC]");
    let e = parse_mtl("m.mtl", "newmtl a\nKe 1 x 1\n").unwrap_err().to_string();
    assert_eq!(e, "m.mtl:2: mtl: Ke: 'x' is not a number");
}
