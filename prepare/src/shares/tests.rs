//! The shares weld exactly as the whole scene welded in one place: the same elements
//! and vertices, bit for bit, for every number of shares.

use super::*;
use magg_core::blocks::NO_BACK;
use magg_core::prepared::Face;
use magg_core::rng::Rng;
use magg_core::subdivision::element_count;

/// A scene of welding's hard cases: tiled floors and walls (coplanar, welded, at two
/// subdivisions), corners between them (not welded), coincident and opposite-facing
/// copies, -0.0 coordinates, loose triangles; some patches with back faces.
fn patches(seed: u64, tiles: usize) -> Vec<SharePatch> {
    let mut rng = Rng::from_words(&[seed, 0x5ba3e]);
    let mut tris: Vec<([DVec3; 3], u32)> = Vec::new();
    let n_of = |rng: &mut Rng| 1 + (rng.next_f64() * 3.0) as u32;
    for axis in 0..3 {
        let n = n_of(&mut rng);
        for i in 0..tiles {
            for j in 0..tiles {
                let at = |a: f64, b: f64| match axis {
                    0 => DVec3::new(a, -0.0, b),
                    1 => DVec3::new(-0.0, a, b),
                    _ => DVec3::new(a, b, 0.0),
                };
                let (x0, x1, y0, y1) = (i as f64, i as f64 + 1.0, j as f64, j as f64 + 1.0);
                tris.push(([at(x0, y0), at(x1, y0), at(x1, y1)], n));
                tris.push(([at(x0, y0), at(x1, y1), at(x0, y1)], n));
            }
        }
    }
    let copies = tris.len() / 7;
    for k in 0..copies {
        let (t, n) = tris[k * 5 % tris.len()];
        tris.push((t, n));
        tris.push(([t[0], t[2], t[1]], n));
    }
    for _ in 0..tiles * 4 {
        let c = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * tiles as f64;
        let mut corner = || c + DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64());
        let t = [corner(), corner(), corner()];
        tris.push((t, n_of(&mut rng)));
    }
    // Shuffle, so that neighbours are far apart in id order.
    for k in (1..tris.len()).rev() {
        let j = (rng.next_f64() * (k + 1) as f64) as usize % (k + 1);
        tris.swap(k, j);
    }
    let backs: Vec<bool> = (0..tris.len()).map(|_| rng.next_f64() < 0.4).collect();
    let mut out = Vec::new();
    let mut acc = 0u32;
    for &(v, n) in &tris {
        out.push(SharePatch {
            id: out.len() as u32,
            v,
            n,
            first_element: acc,
            back_element: NO_BACK,
            front_face: Face::Both,
            material: 0,
            shading: magg_core::blocks::NO_SHADING,
            normals: None,
            uv: None,
        });
        acc += element_count(n) as u32;
    }
    for (p, &b) in out.iter_mut().zip(&backs) {
        if b {
            p.back_element = acc;
            p.front_face = Face::Front;
            acc += element_count(p.n) as u32;
        }
    }
    out
}

fn elements(p: &[SharePatch]) -> usize {
    p.iter().map(|p| element_count(p.n) as usize * if p.back_element == NO_BACK { 1 } else { 2 }).sum()
}

#[test]
fn shares_weld_every_element_and_vertex_as_one_place_does() {
    for seed in 0..4 {
        let scene = patches(seed, 6);
        let (want_e, want_v) = oracle::elements(&scene);
        for shares in [1usize, 2, 3, 5, 7] {
            let split = split_space(&scene, shares);
            let (got_e, got_v) = weld_local(&scene, &split);
            assert_eq!(got_v.len(), want_v.len(), "seed {seed}, {shares} shares: vertex count");
            assert_eq!(format!("{got_v:?}"), format!("{want_v:?}"), "seed {seed}, {shares} shares: vertices");
            assert_eq!(format!("{got_e:?}"), format!("{want_e:?}"), "seed {seed}, {shares} shares: elements");
        }
    }
}

#[test]
fn a_split_that_cuts_through_welded_floors_still_welds_them() {
    let scene = patches(9, 10);
    let split = split_space(&scene, 7);
    let homes: std::collections::HashSet<u32> = scene.iter().map(|p| split.share_of(p.v[0])).collect();
    assert!(homes.len() >= 5, "the split should spread the scene: {homes:?}");
    let (want_e, want_v) = oracle::elements(&scene);
    let (got_e, got_v) = weld_local(&scene, &split);
    assert_eq!(format!("{got_v:?}"), format!("{want_v:?}"));
    assert_eq!(format!("{got_e:?}"), format!("{want_e:?}"));
}

/// Welds `scene` in the shares of `split`, all in this process.
fn weld_local(scene: &[SharePatch], split: &SpaceSplit) -> (Vec<ElementInfo>, Vec<glam::DVec3>) {
    let mut set = LocalShareSet::default();
    let session = set.begin_session();
    weld(&mut set, session, split, by_share(scene.to_vec(), split), elements(scene)).unwrap()
}

/// Every share in this process, each request and reply through its bytes, as a fork's.
#[derive(Default)]
struct ThroughBytes(LocalShareSet);

impl ShareSet for ThroughBytes {
    fn begin_session(&mut self) -> u64 {
        self.0.begin_session()
    }
    fn run(&mut self, session: u64, requests: Vec<(u32, steps::Request)>) -> Result<Vec<steps::Reply>, ShareError> {
        let requests =
            requests.into_iter().map(|(s, r)| (s, wire::decode_request(&wire::encode_request(&r)).unwrap())).collect();
        let replies = self.0.run(session, requests)?;
        Ok(replies.into_iter().map(|r| wire::decode_reply(&wire::encode_reply(&r)).unwrap()).collect())
    }
    fn place(&self) -> String {
        "bytes".into()
    }
}

#[test]
fn shares_served_through_their_bytes_weld_as_in_process() {
    let scene = patches(3, 8);
    let split = split_space(&scene, 5);
    let mut set = ThroughBytes::default();
    let session = set.begin_session();
    let got = weld(&mut set, session, &split, by_share(scene.clone(), &split), elements(&scene)).unwrap();
    let want = weld_local(&scene, &split);
    assert_eq!(format!("{got:?}"), format!("{want:?}"));
}

#[test]
fn a_step_of_another_session_or_out_of_order_is_refused() {
    use steps::{serve, Request, Serving, StepError};
    let scene = patches(1, 3);
    let split = split_space(&scene, 2);
    let mut serving = Serving::default();
    let mut mine = by_share(scene, &split);
    let begin = Request::Begin { split: split.clone(), patches: std::mem::take(&mut mine[0]) };
    assert!(serve(&mut serving, 7, 0, begin).is_ok());
    assert!(matches!(serve(&mut serving, 8, 0, Request::Lattice), Err(StepError::Unknown { session: 8, share: 0 })));
    assert!(matches!(serve(&mut serving, 7, 1, Request::Lattice), Err(StepError::Unknown { .. })));
    assert!(matches!(serve(&mut serving, 7, 0, Request::Number(vec![])), Err(StepError::Bad { .. })));
    assert!(serve(&mut serving, 7, 0, Request::Lattice).is_ok());
    // A point that names a share past the split's.
    let p = WeldPoint { key: [0; 3], patch: 0, local: 0, normal: glam::DVec3::Z, has_back: false, share: 9, index: 0 };
    assert!(matches!(serve(&mut serving, 7, 0, Request::Resolve(vec![p])), Err(StepError::Bad { .. })));
    // A new session's Begin replaces the old one's shares.
    let again = Request::Begin { split: split.clone(), patches: vec![] };
    assert!(serve(&mut serving, 9, 1, again).is_ok());
    assert_eq!(serving.held(), 1);
    assert!(matches!(serve(&mut serving, 7, 0, Request::Lattice), Err(StepError::Unknown { .. })));
    // Patches out of order, a share past the split, absurd subdivisions.
    let bad = |patches: Vec<SharePatch>, share: u32| {
        let mut s = Serving::default();
        matches!(serve(&mut s, 1, share, Request::Begin { split: split.clone(), patches }), Err(StepError::Bad { .. }))
    };
    let one = patches(2, 2);
    assert!(bad(vec![one[1], one[0]], 0));
    assert!(bad(vec![], 5));
    assert!(bad(vec![SharePatch { n: u32::MAX, ..one[0] }], 0));
}
