//! Tests of the PLY reader.

use super::*;

/// A unit square in z = 0 as one quad face and a triangle, in ASCII.
pub(crate) const ASCII: &str = "ply\nformat ascii 1.0\ncomment made by hand\nelement vertex 5\n\
property float x\nproperty float y\nproperty float z\nelement face 2\n\
property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 0.5 1\n4 0 1 2 3\n3 0 1 4\n";

/// The same mesh as [`ASCII`] in binary, little- or big-endian, with an extra `uchar red`
/// vertex property and an `edge` element that must be read past.
pub(crate) fn binary(big_endian: bool) -> Vec<u8> {
    let kind = if big_endian { "binary_big_endian" } else { "binary_little_endian" };
    let mut out = format!(
        "ply\r\nformat {kind} 1.0\r\nelement vertex 5\r\nproperty float x\r\nproperty double y\r\n\
         property float z\r\nproperty uchar red\r\nelement face 2\r\nproperty list uchar uint vertex_indices\r\n\
         element edge 1\r\nproperty int vertex1\r\nproperty int vertex2\r\nend_header\r\n"
    )
    .into_bytes();
    let f32b = |x: f32| if big_endian { x.to_be_bytes() } else { x.to_le_bytes() };
    let f64b = |x: f64| if big_endian { x.to_be_bytes() } else { x.to_le_bytes() };
    let u32b = |x: u32| if big_endian { x.to_be_bytes() } else { x.to_le_bytes() };
    for p in [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.5, 0.5, 1.0]] {
        out.extend(f32b(p[0] as f32));
        out.extend(f64b(p[1]));
        out.extend(f32b(p[2] as f32));
        out.push(200);
    }
    for face in [&[0u32, 1, 2, 3][..], &[0, 1, 4]] {
        out.push(face.len() as u8);
        for &k in face {
            out.extend(u32b(k));
        }
    }
    out.extend(u32b(0));
    out.extend(u32b(1));
    out
}

fn tris(m: &PlyMesh) -> Vec<[[f64; 3]; 3]> {
    m.triangles.iter().map(|(t, _)| t.map(|v| v.to_array())).collect()
}

#[test]
fn polygons_are_fan_triangulated_like_obj() {
    let m = parse_ply("m.ply", ASCII.as_bytes()).unwrap();
    assert_eq!(
        tris(&m),
        [
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]],
            [[0.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 0.5, 1.0]],
        ]
    );
    assert!(!m.normals);
}

#[test]
fn binary_of_either_endianness_reads_as_the_ascii() {
    let ascii = parse_ply("m.ply", ASCII.as_bytes()).unwrap();
    for big in [false, true] {
        assert_eq!(parse_ply("m.ply", &binary(big)).unwrap(), ascii, "big endian: {big}");
    }
}

#[test]
fn vertex_normals_orient_the_triangles() {
    let text = |nz: &str| {
        format!(
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
             property float nx\nproperty float ny\nproperty float nz\nelement face 1\n\
             property list uchar int vertex_index\nend_header\n0 0 0 0 0 {nz}\n1 0 0 0 0 {nz}\n0 1 0 0 0 {nz}\n3 0 1 2\n"
        )
    };
    let up = parse_ply("m.ply", text("1").as_bytes()).unwrap();
    assert!(up.normals);
    assert_eq!(tris(&up)[0], [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    let down = parse_ply("m.ply", text("-1").as_bytes()).unwrap();
    assert_eq!(tris(&down)[0], [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]], "swapped to face -z");
    // The normals come along, for smooth shading.
    assert_eq!(up.triangles[0].1, Some([DVec3::Z; 3]));
    assert_eq!(down.triangles[0].1, Some([DVec3::NEG_Z; 3]));
}

#[test]
fn ascii_errors_name_the_line() {
    let e = |text: &str| parse_ply("m.ply", text.as_bytes()).unwrap_err().to_string();
    assert_eq!(
        e(&ASCII.replace("3 0 1 4\n", "3 0 1 9\n")),
        "m.ply:17: ply: face 1: vertex index 9 is out of range: 5 vertices"
    );
    assert_eq!(e(&ASCII.replace("1 1 0\n", "1 x 0\n")), "m.ply:13: ply: vertex 2: 'x' is not a number");
    assert_eq!(
        e(&ASCII.replace("0 1 0\n", "0 1\n")),
        "m.ply:14: ply: vertex 3: fewer values on the line than the header's properties"
    );
    assert_eq!(e(&ASCII.replace("3 0 1 4\n", "")), "m.ply:17: ply: face 1: the file ends early (truncated?)");
    assert_eq!(
        e(&ASCII.replace("4 0 1 2 3\n", "2 0 1\n")),
        "m.ply:16: ply: face 0: a face needs at least 3 vertices, found 2"
    );
    assert_eq!(e(&ASCII.replace("property float y\n", "property quad y\n")), "m.ply:6: ply: unknown type 'quad'");
    assert_eq!(e(&ASCII.replace("format ascii 1.0\n", "")), "m.ply:9: ply: the header has no format line");
    assert_eq!(e(&ASCII.replace("end_header\n", "")), "m.ply:10: ply: unknown header line '0'");
    assert!(e("solid stl\n").starts_with("m.ply:1: ply: not a PLY file"));
}

#[test]
fn a_truncated_binary_file_says_where_it_ends() {
    let full = binary(false);
    let e = parse_ply("m.ply", &full[..full.len() - 12]).unwrap_err().to_string();
    assert!(e.starts_with("m.ply: ply: face 1 (byte "), "{e}");
    assert!(e.ends_with(&format!("the file ends at byte {} (truncated?)", full.len() - 12)), "{e}");
    // Cut anywhere: an error, never a panic.
    for n in 0..full.len() - 8 {
        assert!(parse_ply("m.ply", &full[..n]).is_err(), "cut at {n}");
    }
}

#[test]
fn errors_do_not_print_what_a_foreign_file_holds() {
    let e = parse_ply("m.ply", b"ply\nMAGG_TOKEN=hunter2-very-secret-value\n").unwrap_err().to_string();
    assert!(!e.contains("hunter2") && e.contains("a token of"), "{e}");
    let e = parse_ply("m.ply", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\nhunter2\n")
        .unwrap_err()
        .to_string();
    assert!(!e.contains("hunter2"), "{e}");
}

#[test]
fn a_header_count_reserves_no_more_than_the_file_holds() {
    let text = "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\n\
                property float y\nproperty float z\nend_header\n";
    let e = parse_ply("m.ply", text.as_bytes()).unwrap_err().to_string();
    assert!(e.contains("vertex 0") && e.contains("truncated"), "{e}");
}
