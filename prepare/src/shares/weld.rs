//! Welding at a point's home: every lattice point on a patch boundary is sent to the share
//! whose part of space holds it ([`super::space::SpaceSplit::share_of`]), so the points of
//! all patches meeting there, on whatever shares, are resolved in one place.
//!
//! The rule is the whole scene's: points at bitwise-equal positions (the sign of zero
//! aside) are merged when their patches are coplanar and face the same way, each point
//! linked to the first earlier point of its position, in (patch, lattice index) order,
//! whose patch's normal agrees with its own. A merged set of points is one vertex; its
//! *root*, the point first in that order, numbers it. The home also names the set's
//! first patch that keeps a back face: the back copy of the vertex belongs to it, as the
//! first back element to use the vertex is one of that patch's.

use glam::DVec3;
use rayon::slice::ParallelSliceMut;

/// A boundary lattice point on its way to its home.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct WeldPoint {
    /// Its position's bits ([`key`]).
    pub key: [u64; 3],
    /// Its patch.
    pub patch: u32,
    /// Its index in its patch's lattice.
    pub local: u32,
    /// Its patch's unit normal.
    pub normal: DVec3,
    /// Whether its patch keeps a back face.
    pub has_back: bool,
    /// The share that holds its patch.
    pub share: u32,
    /// Its index among that share's lattice points.
    pub index: u32,
}

/// A lattice point, named by its patch and its index in the patch's lattice.
pub type PointId = (u32, u32);

/// What the home says of a point: the root of its vertex and who holds the vertex's
/// back copy.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct WeldAnswer {
    /// The point.
    pub point: PointId,
    /// The share that sent it.
    pub share: u32,
    /// Its index among that share's lattice points.
    pub index: u32,
    /// The root of its vertex, and the share holding the root's patch.
    pub root: PointId,
    /// Share of the root's patch.
    pub root_share: u32,
    /// The root's index among its share's lattice points.
    pub root_index: u32,
    /// The vertex's first patch with a back face and that patch's share, if any.
    pub back_owner: Option<(u32, u32)>,
}

/// The bits welding compares: equal points weld; +0.0 and -0.0 are one.
pub fn key(p: DVec3) -> [u64; 3] {
    let b = |x: f64| if x == 0.0 { 0u64 } else { x.to_bits() };
    [b(p.x), b(p.y), b(p.z)]
}

/// Whether two patches' unit normals are close enough to weld.
fn coplanar(a: DVec3, b: DVec3) -> bool {
    a.dot(b) > 1.0 - 1e-9
}

/// Resolves every point a home received (its own included): one answer per point, in
/// the order of the points after sorting by (key, patch, lattice index).
pub fn resolve(mut points: Vec<WeldPoint>) -> Vec<WeldAnswer> {
    points.par_sort_unstable_by(|a, b| (a.key, a.patch, a.local).cmp(&(b.key, b.patch, b.local)));
    let mut answers = Vec::with_capacity(points.len());
    let mut start = 0;
    let mut parent: Vec<usize> = Vec::new();
    while start < points.len() {
        let mut end = start + 1;
        while end < points.len() && points[end].key == points[start].key {
            end += 1;
        }
        let group = &points[start..end];
        // Union-find over the group, the lower index always the root.
        parent.clear();
        parent.extend(0..group.len());
        for b in 1..group.len() {
            if let Some(a) = (0..b).find(|&a| coplanar(group[a].normal, group[b].normal)) {
                let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
                let (lo, hi) = (ra.min(rb), ra.max(rb));
                parent[hi] = lo;
            }
        }
        let roots: Vec<usize> = (0..group.len()).map(|k| find(&mut parent, k)).collect();
        for (k, p) in group.iter().enumerate() {
            let r = &group[roots[k]];
            // The first member of the vertex (in patch order) that keeps a back face.
            let back_owner = (0..group.len())
                .filter(|&m| roots[m] == roots[k] && group[m].has_back)
                .map(|m| (group[m].patch, group[m].share))
                .next();
            answers.push(WeldAnswer {
                point: (p.patch, p.local),
                share: p.share,
                index: p.index,
                root: (r.patch, r.local),
                root_share: r.share,
                root_index: r.index,
                back_owner,
            });
        }
        start = end;
    }
    answers
}

fn find(parent: &mut [usize], mut x: usize) -> usize {
    while parent[x] != x {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(p: DVec3, patch: u32, local: u32, normal: DVec3, share: u32) -> WeldPoint {
        WeldPoint { key: key(p), patch, local, normal, has_back: false, share, index: patch * 100 + local }
    }

    #[test]
    fn coplanar_points_weld_to_the_first_and_others_stay_apart() {
        let (up, side) = (DVec3::Z, DVec3::X);
        let at = DVec3::new(1.0, 2.0, 0.0);
        let answers = resolve(vec![
            point(at, 7, 3, up, 1),
            point(at, 2, 5, up, 0),
            point(at, 4, 0, side, 2),
            point(DVec3::new(-0.0, 0.0, 0.0), 9, 1, up, 0),
            point(DVec3::ZERO, 8, 1, up, 2),
        ]);
        let of = |pt: PointId| answers.iter().find(|a| a.point == pt).unwrap();
        assert_eq!(of((7, 3)).root, (2, 5));
        assert_eq!(of((7, 3)).root_share, 0);
        assert_eq!(of((2, 5)).root, (2, 5));
        assert_eq!(of((4, 0)).root, (4, 0), "a wall meeting the floor keeps its own vertex");
        assert_eq!(of((9, 1)).root, (8, 1), "-0.0 and +0.0 weld");
    }

    #[test]
    fn the_back_copy_belongs_to_the_first_patch_with_a_back_face() {
        let at = DVec3::ONE;
        let mut pts = vec![point(at, 1, 0, DVec3::Z, 0), point(at, 5, 0, DVec3::Z, 1), point(at, 3, 0, DVec3::Z, 2)];
        pts[1].has_back = true;
        pts[2].has_back = true;
        let answers = resolve(pts);
        assert!(answers.iter().all(|a| a.back_owner == Some((3, 2))), "{answers:?}");
        assert!(answers.iter().all(|a| a.root == (1, 0)));
    }

    #[test]
    fn linking_follows_the_first_compatible_point_through_a_chain() {
        // b agrees with a only through a third normal: the union-find rule of the whole
        // scene (link to the first earlier compatible point) is kept.
        let at = DVec3::ZERO;
        let n1 = DVec3::Z;
        let n2 = DVec3::new(0.0, 1e-5, 1.0).normalize();
        let answers = resolve(vec![point(at, 0, 0, n1, 0), point(at, 1, 0, n2, 0), point(at, 2, 0, n1, 0)]);
        assert!(answers.iter().all(|a| a.root == (0, 0)), "{answers:?}");
    }
}
