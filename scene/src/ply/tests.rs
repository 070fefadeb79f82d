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

/// A small deterministic generator (64-bit LCG).
struct Lcg(u64);

impl Lcg {
    fn below(&mut self, n: u64) -> u64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 33) % n.max(1)
    }
}

/// A random PLY file: `vertices` vertices (with normals or not, an extra colour
/// property), faces of 3 to 5 corners, an `edge` element, in `format`; with `bad` set, a
/// value somewhere is spoilt (out of range, not a number, missing) or the file is cut.
fn random_ply(seed: u64, format: &str, vertices: u64, bad: bool) -> Vec<u8> {
    let mut r = Lcg(seed);
    let normals = r.below(2) == 0;
    let faces = vertices;
    let edges = r.below(3);
    let mut head = format!(
        "ply\nformat {format} 1.0\nelement vertex {vertices}\nproperty float x\nproperty double y\nproperty float z\n"
    );
    if normals {
        head += "property float nx\nproperty float ny\nproperty float nz\n";
    }
    head += &format!("property uchar red\nelement face {faces}\nproperty list uchar int vertex_indices\nelement edge {edges}\nproperty int vertex1\nproperty int vertex2\nend_header\n");
    let mut out = head.into_bytes();
    let ascii = format == "ascii";
    let big = format == "binary_big_endian";
    let spoil_at = if bad { r.below(vertices + faces + edges + 1) } else { u64::MAX };
    let mut k = 0u64;
    let put = |out: &mut Vec<u8>, values: &[(f64, u8)]| {
        for &(x, size) in values {
            if ascii {
                out.extend(format!("{x} ").as_bytes());
            } else {
                let b: Vec<u8> = match size {
                    1 => vec![x as u8],
                    4 => (x as i32).to_le_bytes().to_vec(),
                    40 => (x as f32).to_le_bytes().to_vec(),
                    _ => x.to_le_bytes().to_vec(),
                };
                let mut b = b;
                if big {
                    b.reverse();
                }
                out.extend(b);
            }
        }
        if ascii {
            out.push(b'\n');
        }
    };
    for _ in 0..vertices {
        if ascii && r.below(20) == 0 {
            out.extend(b"  \r\n");
        }
        let mut v = vec![(r.below(64) as f64 / 4.0, 40), (r.below(64) as f64 / 8.0, 8), (r.below(9) as f64, 40)];
        if normals {
            v.extend([(0.0, 40), (0.0, 40), (if r.below(2) == 0 { 1.0 } else { -1.0 }, 40)]);
        }
        v.push((r.below(256) as f64, 1));
        if k == spoil_at {
            v[0].0 = 1e300;
        }
        k += 1;
        put(&mut out, &v);
    }
    for _ in 0..faces {
        let n = 3 + r.below(3);
        let mut f = vec![(n as f64, 1)];
        for _ in 0..n {
            f.push((r.below(vertices) as f64, 4));
        }
        if k == spoil_at {
            f[1].0 = (vertices + r.below(3)) as f64;
        }
        k += 1;
        put(&mut out, &f);
    }
    for _ in 0..edges {
        put(&mut out, &[(r.below(vertices) as f64, 4), (r.below(vertices) as f64, 4)]);
    }
    if bad && r.below(4) == 0 {
        let cut = r.below(out.len() as u64 / 4) as usize;
        out.truncate(out.len() - cut);
    }
    out
}

#[test]
fn chunked_reads_give_the_value_by_value_mesh_or_error_in_every_format() {
    let mut errors = 0;
    for seed in 0..90 {
        let format = ["ascii", "binary_little_endian", "binary_big_endian"][(seed % 3) as usize];
        let bad = seed % 2 == 1;
        let bytes = random_ply(seed, format, 40 + seed % 17, bad);
        let want = parse_ply_in("m.ply", &bytes, None);
        errors += usize::from(want.is_err());
        if !bad {
            assert!(want.is_ok(), "seed {seed}: {want:?}");
        }
        for cut in [1, 5, 64, 1 << 20] {
            assert_eq!(parse_ply_in("m.ply", &bytes, Some(cut)), want, "seed {seed} {format}, cut {cut}");
        }
    }
    assert!(errors > 15, "only {errors} of the files are broken");
}

#[test]
fn the_fast_path_reads_clean_files_itself() {
    for (seed, format) in [(3, "ascii"), (4, "binary_little_endian"), (5, "binary_big_endian")] {
        let bytes = random_ply(seed, format, 50, false);
        let header = parse_header(&bytes).unwrap();
        let fast = parallel::read(&header, &bytes, 64).expect(format);
        assert_eq!(Ok(fast), parse_ply_in("m.ply", &bytes, None));
    }
}
