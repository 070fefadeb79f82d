//! Regular subdivision of a triangle patch into n*n triangle elements (paper §3).
//!
//! Lattice point (i, j) of a patch with corners v0, v1, v2 is
//! `(k v0 + i v1 + j v2) / n` with `k = n - i - j`. Element `local` is found from the
//! patch barycentrics alone, so a hit on a patch needs no element data to know which
//! element it landed on. Points on a patch edge are computed from the edge's endpoints in
//! a canonical order, so two patches sharing an edge with the same n produce bitwise
//! identical points there (which is what lets preprocessing weld them).

use glam::DVec3;
use std::cmp::Ordering;

/// Number of elements of a patch subdivided n times per edge.
pub fn element_count(n: u32) -> u64 {
    n as u64 * n as u64
}

/// Number of lattice points of a patch subdivided n times per edge.
pub fn lattice_count(n: u32) -> u64 {
    (n as u64 + 1) * (n as u64 + 2) / 2
}

/// Index of lattice point (i, j) (i + j <= n), row by row in j.
pub fn lattice_index(n: u32, i: u32, j: u32) -> u32 {
    j * (n + 1) - j * j.saturating_sub(1) / 2 + i
}

fn lex(a: DVec3, b: DVec3) -> Ordering {
    a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)).then(a.z.total_cmp(&b.z))
}

/// Point `m / n` of the way along the edge (a, b), computed from the lexicographically
/// smaller endpoint so that both patches sharing the edge get the same bits.
fn edge_point(a: DVec3, b: DVec3, m: u32, n: u32) -> DVec3 {
    if m == 0 {
        return a;
    }
    if m == n {
        return b;
    }
    if lex(a, b) == Ordering::Greater {
        return edge_point(b, a, n - m, n);
    }
    a + (b - a) * (m as f64 / n as f64)
}

/// Position of lattice point (i, j) of the patch `v` subdivided n times.
pub fn lattice_point(v: &[DVec3; 3], n: u32, i: u32, j: u32) -> DVec3 {
    let k = n - i - j;
    if j == 0 {
        edge_point(v[0], v[1], i, n)
    } else if i == 0 {
        edge_point(v[0], v[2], j, n)
    } else if k == 0 {
        edge_point(v[1], v[2], j, n)
    } else {
        let nf = n as f64;
        v[0] + (v[1] - v[0]) * (i as f64 / nf) + (v[2] - v[0]) * (j as f64 / nf)
    }
}

/// True when lattice point (i, j) lies on the patch boundary.
pub fn on_boundary(n: u32, i: u32, j: u32) -> bool {
    i == 0 || j == 0 || i + j == n
}

/// Lattice coordinates of the three corners of element `local` (counter-clockwise like
/// the patch). Row j holds `2 (n - j) - 1` elements: lower ones at even positions.
pub fn element_corners(n: u32, local: u32) -> [(u32, u32); 3] {
    // Find row j: start(j) = 2 n j - j^2.
    let n64 = n as u64;
    let l = local as u64;
    // Solve j^2 - 2 n j + l = 0 for the row: j = n - sqrt(n^2 - l), floored.
    let disc = (n64 * n64).saturating_sub(l);
    let mut j = n64 - isqrt(disc);
    while j > 0 && 2 * n64 * j - j * j > l {
        j -= 1;
    }
    while 2 * n64 * (j + 1) - (j + 1) * (j + 1) <= l && j + 1 < n64 {
        j += 1;
    }
    let within = l - (2 * n64 * j - j * j);
    let i = (within / 2) as u32;
    let j = j as u32;
    if within % 2 == 0 {
        [(i, j), (i + 1, j), (i, j + 1)]
    } else {
        [(i + 1, j), (i + 1, j + 1), (i, j + 1)]
    }
}

fn isqrt(x: u64) -> u64 {
    let mut r = (x as f64).sqrt() as u64;
    while r * r > x {
        r -= 1;
    }
    while (r + 1) * (r + 1) <= x {
        r += 1;
    }
    r
}

/// Corner positions of element `local` of patch `v` subdivided n times.
pub fn element_triangle(v: &[DVec3; 3], n: u32, local: u32) -> [DVec3; 3] {
    let c = element_corners(n, local);
    [lattice_point(v, n, c[0].0, c[0].1), lattice_point(v, n, c[1].0, c[1].1), lattice_point(v, n, c[2].0, c[2].1)]
}

/// Corners of child `slot` (0 to 3) of an element with corners `t` split at its edge
/// midpoints (see `magg_prepare`'s `split`): the corner children of `t[0]`, `t[1]` and
/// `t[2]`, then the middle one, each wound like `t`.
pub fn child_triangle(t: &[DVec3; 3], slot: usize) -> [DVec3; 3] {
    let (ab, bc, ca) = ((t[0] + t[1]) * 0.5, (t[1] + t[2]) * 0.5, (t[2] + t[0]) * 0.5);
    match slot {
        0 => [t[0], ab, ca],
        1 => [ab, t[1], bc],
        2 => [ca, bc, t[2]],
        _ => [bc, ca, ab],
    }
}

/// The child (see [`child_triangle`]) a point with barycentrics `w` in its parent falls
/// in, and the point's barycentrics in that child. A point on the border between two
/// children goes to the corner child, deterministically.
pub fn child_of(w: [f64; 3]) -> (usize, [f64; 3]) {
    let (slot, c) = if w[0] >= 0.5 {
        (0, [2.0 * w[0] - 1.0, 2.0 * w[1], 2.0 * w[2]])
    } else if w[1] >= 0.5 {
        (1, [2.0 * w[0], 2.0 * w[1] - 1.0, 2.0 * w[2]])
    } else if w[2] >= 0.5 {
        (2, [2.0 * w[0], 2.0 * w[1], 2.0 * w[2] - 1.0])
    } else {
        (3, [1.0 - 2.0 * w[0], 1.0 - 2.0 * w[1], 1.0 - 2.0 * w[2]])
    };
    let c = c.map(|x| x.max(0.0));
    let s = c[0] + c[1] + c[2];
    if s > 0.0 {
        (slot, c.map(|x| x / s))
    } else {
        (slot, [1.0 / 3.0; 3])
    }
}

/// The element a point with patch barycentrics `bary` falls in, and the point's
/// barycentrics within that element (weights of its corners in
/// [`element_corners`] order). Points on an element edge go to the element with the
/// lower lattice cell, deterministically.
pub fn locate(n: u32, bary: [f64; 3]) -> (u32, [f64; 3]) {
    let nf = n as f64;
    let fi_max = n.saturating_sub(1) as f64;
    let ci = (bary[1] * nf).clamp(0.0, nf);
    let cj = (bary[2] * nf).clamp(0.0, nf);
    let fj = cj.floor().min(fi_max);
    let fi = ci.floor().min((fi_max - fj).max(0.0));
    let (ui, uj) = (ci - fi, cj - fj);
    let (i, j) = (fi as u32, fj as u32);
    let row = 2 * n * j - j * j;
    let upper = ui + uj > 1.0 && i + j + 1 < n;
    if upper {
        let wb = (ui + uj - 1.0).clamp(0.0, 1.0);
        let wa = (1.0 - uj).clamp(0.0, 1.0);
        let wc = (1.0 - ui).clamp(0.0, 1.0);
        let s = wa + wb + wc;
        (row + 2 * i + 1, [wa / s, wb / s, wc / s])
    } else {
        let w0 = (1.0 - ui - uj).max(0.0);
        let s = w0 + ui + uj;
        (row + 2 * i, [w0 / s, ui / s, uj / s])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_point_lands_in_the_child_that_holds_it_with_the_same_position() {
        let t = [DVec3::new(0.0, 0.0, 0.0), DVec3::new(2.0, 0.1, 0.0), DVec3::new(0.3, 1.7, 0.5)];
        let at = |t: &[DVec3; 3], w: [f64; 3]| t[0] * w[0] + t[1] * w[1] + t[2] * w[2];
        let mut seen = [false; 4];
        for i in 0..=20 {
            for j in 0..=(20 - i) {
                let w = [i as f64 / 20.0, j as f64 / 20.0, (20 - i - j) as f64 / 20.0];
                let (slot, c) = child_of(w);
                seen[slot] = true;
                assert!(c.iter().all(|&x| (0.0..=1.0).contains(&x)), "{w:?} -> {c:?}");
                let (p, q) = (at(&t, w), at(&child_triangle(&t, slot), c));
                assert!((p - q).length() < 1e-12, "{w:?}: {p} in the parent, {q} in child {slot}");
            }
        }
        assert_eq!(seen, [true; 4]);
        // The four children tile the parent: their areas sum to its area.
        let area = |t: &[DVec3; 3]| (t[1] - t[0]).cross(t[2] - t[0]).length() * 0.5;
        let sum: f64 = (0..4).map(|k| area(&child_triangle(&t, k))).sum();
        assert!((sum - area(&t)).abs() < 1e-12 * area(&t));
        // Each child is wound like the parent.
        let n = (t[1] - t[0]).cross(t[2] - t[0]);
        for k in 0..4 {
            let c = child_triangle(&t, k);
            assert!((c[1] - c[0]).cross(c[2] - c[0]).dot(n) > 0.0, "child {k}");
        }
    }

    #[test]
    fn corners_enumerate_every_element_once() {
        for n in 1..12 {
            let mut seen = std::collections::HashSet::new();
            for l in 0..n * n {
                let c = element_corners(n, l);
                for (i, j) in c {
                    assert!(i + j <= n);
                }
                assert!(seen.insert(c));
            }
        }
    }

    #[test]
    fn locate_inverts_element_centroids() {
        let n = 7;
        for l in 0..n * n {
            let c = element_corners(n, l);
            let ci = (c[0].0 + c[1].0 + c[2].0) as f64 / 3.0;
            let cj = (c[0].1 + c[1].1 + c[2].1) as f64 / 3.0;
            let bary = [1.0 - (ci + cj) / n as f64, ci / n as f64, cj / n as f64];
            let (got, w) = locate(n, bary);
            assert_eq!(got, l);
            for x in w {
                assert!((x - 1.0 / 3.0).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn locate_handles_corners_and_edges() {
        for n in [1, 2, 5] {
            for bary in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.5, 0.5, 0.0], [0.0, 0.5, 0.5]] {
                let (l, w) = locate(n, bary);
                assert!(l < n * n);
                assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn shared_edge_points_are_bitwise_equal() {
        let a = DVec3::new(0.1, 0.2, 0.3);
        let b = DVec3::new(1.7, -0.3, 0.9);
        let c = DVec3::new(0.4, 1.1, -0.2);
        let d = DVec3::new(2.0, 1.0, 0.0);
        // Triangles (a, b, c) and (b, d, c) share edge b-c in opposite directions.
        let t1 = [a, b, c];
        let t2 = [b, d, c];
        let n = 9;
        for m in 0..=n {
            // On t1, edge v1-v2 is the k == 0 edge: point (n - m, m).
            let p1 = lattice_point(&t1, n, n - m, m);
            // On t2, edge v0-v2 is the i == 0 edge: point (0, m).
            let p2 = lattice_point(&t2, n, 0, m);
            assert_eq!(p1, p2);
        }
    }

    #[test]
    fn lattice_index_is_dense() {
        let n = 6;
        let mut ids: Vec<u32> = (0..=n).flat_map(|j| (0..=n - j).map(move |i| lattice_index(n, i, j))).collect();
        ids.sort();
        assert_eq!(ids, (0..lattice_count(n) as u32).collect::<Vec<_>>());
    }
}
