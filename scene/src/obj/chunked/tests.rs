//! The chunked OBJ reader against the line-by-line one: the same mesh or the same error
//! (file, line, field, words) for every cut, on files made at random from a fixed seed.

use super::*;
use crate::obj::reference::parse_obj_by_lines;

/// A small deterministic generator (64-bit LCG), so that the files are the same on every
/// run.
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        self.0 >> 33
    }
    fn below(&mut self, n: u64) -> i64 {
        (self.next() % n.max(1)) as i64
    }
}

/// A random OBJ text of about `lines` lines; `bad` in 1000 of its lines are broken.
fn random_obj(seed: u64, lines: usize, bad: u64) -> String {
    let mut r = Lcg(seed);
    let mut out = String::new();
    let (mut v, mut vt, mut vn) = (0i64, 0i64, 0i64);
    for _ in 0..lines {
        let eol = if r.below(10) == 0 { "\r\n" } else { "\n" };
        if (r.below(1000) as u64) < bad {
            let broken = [
                "f 1 2",
                "v 1 x 3",
                "v 1 2",
                "bogus 1",
                "f 1/x 2 3",
                "f 1 2 3/1/1/1",
                "usemtl",
                "mtllib",
                "curv 1 2",
                "vt",
                "vn 1 2",
                "f 0 1 2",
                "f 1 2 99999",
                "v 1e300 0 0",
                "f 1 -99999 z",
            ];
            out += broken[r.below(broken.len() as u64) as usize];
            out += eol;
            continue;
        }
        let line = match r.below(12) {
            0..=2 => {
                v += 1;
                format!("v {} {} {}", r.below(100), r.below(100) as f64 / 8.0, -r.below(50))
            }
            3 => {
                vt += 1;
                format!("vt {} {}", r.below(8) as f64 / 8.0, r.below(8) as f64 / 8.0)
            }
            4 => {
                vn += 1;
                format!("vn 0 {} 1", r.below(3))
            }
            5..=8 if v > 0 => {
                let n = 3 + r.below(3);
                let form = r.below(4);
                let mut f = String::from("f");
                for _ in 0..n {
                    let pick = |r: &mut Lcg, count: i64| {
                        let k = 1 + r.below(count.max(1) as u64);
                        if r.below(3) == 0 {
                            k - count - 1
                        } else {
                            k
                        }
                    };
                    let i = pick(&mut r, v);
                    let c = match form {
                        0 => format!(" {i}"),
                        1 if vt > 0 => format!(" {i}/{}", pick(&mut r, vt)),
                        2 if vn > 0 => format!(" {i}//{}", pick(&mut r, vn)),
                        3 if vt > 0 && vn > 0 => format!(" {i}/{}/{}", pick(&mut r, vt), pick(&mut r, vn)),
                        _ => format!(" {i}"),
                    };
                    f += &c;
                }
                f
            }
            9 => format!("usemtl m{}", r.below(4)),
            10 => ["# a comment", "", "g part", "s 1", "o thing", "mtllib a.mtl b.mtl"][r.below(6) as usize].into(),
            _ => format!("  v {} 0 0   # trailing", {
                v += 1;
                r.below(9)
            }),
        };
        out += &line;
        out += eol;
    }
    if r.below(2) == 0 {
        out.pop();
    }
    out
}

#[test]
fn chunked_reads_give_the_line_by_line_mesh_for_every_cut() {
    for seed in 0..60 {
        let text = random_obj(seed, 300, 0);
        let want = parse_obj_by_lines("m.obj", &text);
        assert!(want.is_ok(), "seed {seed}: {want:?}");
        for cut in [1, 7, 64, 1000, usize::MAX] {
            assert_eq!(parse("m.obj", &text, cut), want, "seed {seed}, cut {cut}");
        }
    }
}

#[test]
fn chunked_reads_give_the_line_by_line_error_for_every_cut() {
    let mut errors = 0;
    for seed in 0..300 {
        let text = random_obj(seed, 200, 8);
        let want = parse_obj_by_lines("m.obj", &text);
        errors += usize::from(want.is_err());
        for cut in [1, 13, 200, usize::MAX] {
            assert_eq!(parse("m.obj", &text, cut), want, "seed {seed}, cut {cut}\n{text}");
        }
    }
    assert!(errors > 100, "only {errors} of the files are broken");
}

#[test]
fn an_error_on_a_face_names_the_first_bad_corner_in_file_order() {
    // A corner out of range before a corner that is not one: the range error, as read
    // line by line; the same with the vertices in another chunk.
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\n# pad\nf 1 5 x\n";
    let want = parse_obj_by_lines("m.obj", text).unwrap_err();
    assert_eq!(want.to_string(), "m.obj:5: obj: f: vertex index 5 is out of range: 3 vertices defined so far");
    for cut in [1, 8, 100] {
        assert_eq!(parse("m.obj", text, cut).unwrap_err(), want);
    }
}

#[test]
fn a_stream_hands_on_every_face_once_in_order() {
    let text = random_obj(7, 3000, 0);
    let whole = parse("m.obj", &text, usize::MAX).unwrap();
    let mut seen = Vec::new();
    let mut windows = 0;
    let rest = stream("m.obj", &text, 64, &mut |mesh, faces| {
        windows += 1;
        assert!(mesh.faces.is_empty());
        seen.extend_from_slice(faces);
    })
    .unwrap();
    assert!(windows > 1);
    assert_eq!(seen, whole.faces);
    assert_eq!(rest, ObjMesh { faces: Vec::new(), ..whole });
}

#[test]
fn the_quick_pass_finds_the_material_statements_the_reader_records() {
    for seed in 0..40 {
        let text = random_obj(seed, 400, 0) + "\nv 1 2 3 # usemtl not_this\n   usemtl  two words \nmtllib c.mtl";
        let mesh = parse("m.obj", &text, 100).unwrap();
        let (mtllibs, names) = crate::obj::statements::material_statements(&text);
        assert_eq!((mtllibs, names), (mesh.mtllibs, mesh.usemtl_names), "seed {seed}");
    }
}
