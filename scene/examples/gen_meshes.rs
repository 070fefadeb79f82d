//! Regenerates the procedural meshes under `scenes/meshes/`:
//!
//! - `sphere.obj`: an icosphere (icosahedron subdivided 3 times, 1280 faces), radius 1,
//!   centred at the origin, faces wound counter-clockwise seen from outside.
//! - `terrain.obj` + `terrain.mtl`: a 140 x 140 heightfield (39 200 triangles, 14 m x 14 m,
//!   normals up) with five columns standing on it (`usemtl ground` / `usemtl stone`).
//! - `water.obj`: a wavy water surface, 2 m x 2 m at height 0 (128 x 128 squares, 32 768
//!   triangles, normals up, no vertex normals: a scene smooths it with `crease_angle`),
//!   the sum of three travelling waves 1 to 1.5 cm high and 23 to 55 cm long, whose
//!   crests focus light into caustics about 0.5 to 2 m below (`scenes/water.toml`).
//!
//! And, on request, a benchmark model that is not kept in the repository:
//!
//! - `--knot FACES OUT.obj`: a (3, 7) torus knot swept by a tube, about FACES triangles
//!   (100 000 in docs/PERFORMANCE.md). Like a scanned model (the Stanford dragon), its
//!   triangles crowd along a thin, winding surface and leave most of its bounding box
//!   empty: a uniform grid's worst case, where a height field is its best. Beside it,
//!   `OUT-room.toml`: the knot standing in a 30 m room (floor and back wall), one element
//!   per triangle, as a scanned model is rendered: a small dense mesh in a large scene.
//!
//! ```text
//! cargo run -p magg-scene --example gen_meshes            # writes scenes/meshes/
//! cargo run -p magg-scene --example gen_meshes -- OUTDIR  # writes elsewhere
//! cargo run --release -p magg-scene --example gen_meshes -- --knot 100000 /tmp/knot.obj
//! ```
//! The output is deterministic: no randomness, fixed formatting (6 significant digits).

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::PathBuf;

type P = [f64; 3];

fn sub(a: P, b: P) -> P {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: P, b: P) -> P {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
fn dot(a: P, b: P) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn normalize(a: P) -> P {
    let l = dot(a, a).sqrt();
    [a[0] / l, a[1] / l, a[2] / l]
}

/// A mesh being written: positions and 1-based triangle indices, with material switches.
#[derive(Default)]
struct Obj {
    v: Vec<P>,
    f: Vec<[usize; 3]>,
    /// (index of the first face, material name).
    usemtl: Vec<(usize, &'static str)>,
}

impl Obj {
    fn vertex(&mut self, p: P) -> usize {
        self.v.push(p);
        self.v.len()
    }
    fn tri(&mut self, a: usize, b: usize, c: usize) {
        self.f.push([a, b, c]);
    }
    fn normal(&self, f: &[usize; 3]) -> P {
        let [a, b, c] = f.map(|i| self.v[i - 1]);
        cross(sub(b, a), sub(c, a))
    }
    fn write(&self, header: &str, mtllib: Option<&str>) -> String {
        let mut s = String::new();
        for line in header.lines() {
            let _ = writeln!(s, "# {line}");
        }
        if let Some(m) = mtllib {
            let _ = writeln!(s, "mtllib {m}");
        }
        for p in &self.v {
            let _ = writeln!(s, "v {} {} {}", num(p[0]), num(p[1]), num(p[2]));
        }
        for (k, f) in self.f.iter().enumerate() {
            if let Some((_, m)) = self.usemtl.iter().find(|(first, _)| *first == k) {
                let _ = writeln!(s, "usemtl {m}");
            }
            let _ = writeln!(s, "f {} {} {}", f[0], f[1], f[2]);
        }
        s
    }
}

/// A number with 6 significant digits, without trailing zeros.
fn num(x: f64) -> String {
    if x == 0.0 {
        return "0".into();
    }
    let decimals = (5 - x.abs().log10().floor() as i32).max(0) as usize;
    let s = format!("{x:.decimals$}");
    let s = if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s };
    if s == "-0" {
        "0".into()
    } else {
        s
    }
}

/// Icosahedron subdivided `levels` times, projected on the unit sphere.
fn icosphere(levels: u32) -> Obj {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut verts: Vec<P> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .into_iter()
    .map(normalize)
    .collect();
    let mut faces: Vec<[usize; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mid: HashMap<(usize, usize), usize> = HashMap::new();
        let mut midpoint = |a: usize, b: usize, verts: &mut Vec<P>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let (p, q) = (verts[a], verts[b]);
                verts.push(normalize([(p[0] + q[0]) / 2.0, (p[1] + q[1]) / 2.0, (p[2] + q[2]) / 2.0]));
                verts.len() - 1
            })
        };
        let mut next = Vec::with_capacity(faces.len() * 4);
        for [a, b, c] in faces {
            let ab = midpoint(a, b, &mut verts);
            let bc = midpoint(b, c, &mut verts);
            let ca = midpoint(c, a, &mut verts);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        faces = next;
    }
    let mut obj = Obj::default();
    for p in verts {
        obj.vertex(p);
    }
    for [a, b, c] in faces {
        obj.tri(a + 1, b + 1, c + 1);
    }
    for f in &obj.f {
        let centre = obj.v[f[0] - 1];
        assert!(dot(obj.normal(f), centre) > 0.0, "icosphere face wound inwards");
    }
    obj
}

/// Terrain height at (x, z): a few smooth waves, within +-0.42 m.
fn height(x: f64, z: f64) -> f64 {
    0.25 * (0.9 * x).sin() * (0.7 * z).cos()
        + 0.12 * (2.1 * x + 0.5).sin() * (1.7 * z + 1.3).sin()
        + 0.05 * (4.3 * x - 1.1 * z).sin()
}

/// A 140 x 140 heightfield over [-7, 7]^2 and five columns on it.
fn terrain() -> Obj {
    const N: usize = 140;
    const HALF: f64 = 7.0;
    let mut obj = Obj::default();
    obj.usemtl.push((0, "ground"));
    heightfield(&mut obj, N, HALF, height);
    obj.usemtl.push((obj.f.len(), "stone"));
    for (cx, cz, r, h) in [
        (-3.0, -2.5, 0.3, 2.6),
        (-1.0, -3.5, 0.25, 2.2),
        (1.2, -2.0, 0.3, 2.8),
        (3.4, -3.2, 0.35, 2.4),
        (2.2, 1.5, 0.2, 1.6),
    ] {
        column(&mut obj, cx, cz, r, h);
    }
    obj
}

/// A 24-sided column from below the ground up to `h`, with a top cap; outward winding.
fn column(obj: &mut Obj, cx: f64, cz: f64, r: f64, h: f64) {
    const SIDES: usize = 24;
    let bottom = -0.6;
    let ring = |y: f64, obj: &mut Obj| -> Vec<usize> {
        (0..SIDES)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / SIDES as f64;
                obj.vertex([cx + r * a.cos(), y, cz + r * a.sin()])
            })
            .collect()
    };
    let lo = ring(bottom, obj);
    let hi = ring(h, obj);
    let top = obj.vertex([cx, h, cz]);
    let start = obj.f.len();
    for k in 0..SIDES {
        let n = (k + 1) % SIDES;
        obj.tri(lo[k], hi[n], lo[n]);
        obj.tri(lo[k], hi[k], hi[n]);
        obj.tri(top, hi[n], hi[k]);
    }
    for f in &obj.f[start..] {
        let [a, b, c] = f.map(|i| obj.v[i - 1]);
        let centroid =
            [(a[0] + b[0] + c[0]) / 3.0 - cx, (a[1] + b[1] + c[1]) / 3.0 - h / 2.0, (a[2] + b[2] + c[2]) / 3.0 - cz];
        assert!(dot(obj.normal(f), centroid) > 0.0, "column face wound inwards");
    }
}

/// Adds the heightfield `y = height(x, z)` over [-half, half]^2 to `obj`: n x n squares,
/// each split in two along a diagonal that alternates, so that the triangulation has no
/// preferred direction; wound counter-clockwise seen from above (normals up).
fn heightfield(obj: &mut Obj, n: usize, half: f64, height: fn(f64, f64) -> f64) {
    let d = 2.0 * half / n as f64;
    let (first, faces) = (obj.v.len() + 1, obj.f.len());
    for j in 0..=n {
        for i in 0..=n {
            let (x, z) = (-half + i as f64 * d, -half + j as f64 * d);
            obj.vertex([x, height(x, z), z]);
        }
    }
    let id = |i: usize, j: usize| first + j * (n + 1) + i;
    for j in 0..n {
        for i in 0..n {
            let (a, b, c, e) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            if (i + j) % 2 == 0 {
                obj.tri(a, c, b);
                obj.tri(a, e, c);
            } else {
                obj.tri(a, e, b);
                obj.tri(b, e, c);
            }
        }
    }
    for f in &obj.f[faces..] {
        assert!(obj.normal(f)[1] > 0.0, "heightfield face wound downwards");
    }
}

/// Height of the water surface above its mean level at (x, z), metres: three waves
/// of different lengths and headings, so that their crests cross in a caustic net.
fn wave(x: f64, z: f64) -> f64 {
    use std::f64::consts::TAU;
    0.012 * (TAU * (0.9 * x + 0.44 * z) / 0.55 + 0.3).sin()
        + 0.008 * (TAU * (-0.3 * x + 0.95 * z) / 0.37 + 1.1).sin()
        + 0.005 * (TAU * (0.7 * x - 0.71 * z) / 0.23 + 2.0).sin()
}

/// The water surface of `water.obj`: a 128 x 128 heightfield over [-1, 1]^2, wound
/// counter-clockwise seen from above (normals up, out of the water).
fn water() -> Obj {
    let mut obj = Obj::default();
    heightfield(&mut obj, 128, 1.0, wave);
    obj
}

const MTL: &str = "\
# Materials of terrain.obj (generated by `cargo run -p magg-scene --example gen_meshes`).
newmtl ground
Kd 0.55 0.5 0.38

newmtl stone
Kd 0.72 0.7 0.66
";

/// Centre line of the (p, q) torus knot at parameter `s` in [0, 2 pi): it winds p times
/// around the torus' axis and q times through its hole (radii 2 and 0.8).
fn knot_point(p: f64, q: f64, s: f64) -> P {
    let r = 2.0 + 0.8 * (q * s).cos();
    [r * (p * s).cos(), 0.8 * (q * s).sin() + 1.6, r * (p * s).sin()]
}

/// A tube of radius 0.25 around the (3, 7) torus knot: `around` vertices per ring and as
/// many rings as make about `faces` triangles, wound counter-clockwise seen from outside.
fn knot(faces: usize) -> Obj {
    let around = 48usize;
    let rings = (faces / (2 * around)).max(3);
    let (p, q) = (3.0, 7.0);
    let at = |k: usize| k as f64 * std::f64::consts::TAU / rings as f64;
    let mut obj = Obj::default();
    for k in 0..rings {
        let (s, ds) = (at(k), 1e-4);
        let c = knot_point(p, q, s);
        let tangent = normalize(sub(knot_point(p, q, s + ds), knot_point(p, q, s - ds)));
        // A frame around the tangent: any vector not along it, made perpendicular.
        let up = if tangent[1].abs() < 0.9 { [0.0, 1.0, 0.0] } else { [1.0, 0.0, 0.0] };
        let n = normalize(cross(tangent, up));
        let b = cross(tangent, n);
        for j in 0..around {
            let a = j as f64 * std::f64::consts::TAU / around as f64;
            let (ca, sa) = (a.cos() * 0.25, a.sin() * 0.25);
            obj.vertex([c[0] + ca * n[0] + sa * b[0], c[1] + ca * n[1] + sa * b[1], c[2] + ca * n[2] + sa * b[2]]);
        }
    }
    let id = |k: usize, j: usize| (k % rings) * around + j % around + 1;
    for k in 0..rings {
        for j in 0..around {
            let (a, b, c, d) = (id(k, j), id(k + 1, j), id(k + 1, j + 1), id(k, j + 1));
            obj.tri(a, c, b);
            obj.tri(a, d, c);
        }
    }
    obj
}

/// The knot in a room (`--knot`): the camera and light `magg-host` makes up around the
/// knot alone, a 30 m floor and a 6 m back wall, one element per triangle.
const KNOT_ROOM: &str = r#"# A (3, 7) torus knot (gen_meshes --knot) standing in a 30 m x 30 m room with a back wall.
[camera]
eye = [5.25295, 6.12291, 12.9226]
look_at = [0.083905, 1.6, 0.0]
up = [0.0, 1.0, 0.0]
fov = 40.0

[render]
width = 200
height = 200
light_rays = 8
ambient = [0.05, 0.05, 0.05]

[[light]]
position = [5.25295, 8.29913, 12.9226]
intensity = [214.169, 214.169, 214.169]

[[material]]
name = "grey"
diffuse = [0.7, 0.7, 0.7]

[[material]]
name = "wall"
diffuse = [0.6, 0.6, 0.6]

[[mesh]]
obj = "KNOT_OBJ"    # the older name of `file`: earlier builds read this scene too
material = "grey"
subdivisions = 1

# floor
[[quad]]
vertices = [[-15.0, 0.0, -15.0], [-15.0, 0.0, 15.0], [15.0, 0.0, 15.0], [15.0, 0.0, -15.0]]
material = "wall"
subdivisions = 8

# back wall
[[quad]]
vertices = [[-15.0, 0.0, -15.0], [15.0, 0.0, -15.0], [15.0, 6.0, -15.0], [-15.0, 6.0, -15.0]]
material = "wall"
subdivisions = 8
"#;

fn main() -> std::io::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    if args.get(1).map(String::as_str) == Some("--knot") {
        let (Some(faces), Some(path)) = (args.get(2).and_then(|f| f.parse::<usize>().ok()), args.get(3)) else {
            eprintln!("usage: gen_meshes --knot FACES OUT.obj");
            std::process::exit(2);
        };
        let k = knot(faces);
        let header = format!(
            "(3, 7) torus knot tube: {} vertices, {} faces.\ngenerated by `gen_meshes --knot {faces}`",
            k.v.len(),
            k.f.len()
        );
        std::fs::write(path, k.write(&header, None))?;
        println!("wrote {path} ({} faces)", k.f.len());
        let obj = std::path::Path::new(path);
        let room = obj.with_file_name(format!("{}-room.toml", obj.file_stem().unwrap_or_default().to_string_lossy()));
        let name = obj.file_name().unwrap_or_default().to_string_lossy();
        std::fs::write(&room, KNOT_ROOM.replace("KNOT_OBJ", &name))?;
        println!("wrote {}", room.display());
        return Ok(());
    }
    let out = std::env::args()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join("scenes").join("meshes"));
    std::fs::create_dir_all(&out)?;
    let generated = "generated by `cargo run -p magg-scene --example gen_meshes`; license: same as magg";
    let sphere = icosphere(3);
    assert_eq!(sphere.f.len(), 1280);
    let header = format!(
        "Icosphere, 3 subdivisions: {} vertices, {} faces, radius 1.\n{generated}",
        sphere.v.len(),
        sphere.f.len()
    );
    std::fs::write(out.join("sphere.obj"), sphere.write(&header, None))?;
    let t = terrain();
    let header =
        format!("Heightfield terrain with five columns: {} vertices, {} faces.\n{generated}", t.v.len(), t.f.len());
    std::fs::write(out.join("terrain.obj"), t.write(&header, Some("terrain.mtl")))?;
    std::fs::write(out.join("terrain.mtl"), MTL)?;
    let w = water();
    let header = format!(
        "Wavy water surface, 2 m x 2 m at height 0: {} vertices, {} faces, normals up.\n{generated}",
        w.v.len(),
        w.f.len()
    );
    std::fs::write(out.join("water.obj"), w.write(&header, None))?;
    println!(
        "wrote sphere.obj ({} faces), terrain.obj ({} faces), terrain.mtl, water.obj ({} faces) to {}",
        sphere.f.len(),
        t.f.len(),
        w.f.len(),
        out.display()
    );
    Ok(())
}
