//! One share of the scene as the fork that prepares it holds it: its patches (ids given by
//! the host), their lattice points, and the steps that turn them into elements on welded,
//! globally numbered vertices.
//!
//! The steps, in order (the driver moves the messages between them):
//! 1. [`Share::lattice`]: lattice points; each boundary point goes to its home.
//! 2. [`Share::resolve`] (at the homes): every point's vertex root and back owner.
//! 3. [`Share::settle`]: each patch's count of vertices it roots and back copies it owns,
//!    for the host's prefix sums in patch order.
//! 4. [`Share::number`]: ids of its own vertices; questions for the others' ids.
//! 5. [`Share::answer`]: ids asked of it.
//! 6. [`Share::elements`]: its elements, on their vertices, and its vertices' positions.

use super::space::SpaceSplit;
use super::weld::{self, PointId, WeldAnswer, WeldPoint};
use glam::{DVec2, DVec3};
use magg_core::blocks::{
    Block, BlockLayout, ElementRecord, PatchRecord, ShadingRecord, BLOCK_SIZE, NO_BACK, NO_SHADING, NO_TEXTURE,
};
use magg_core::geometry::{triangle_area, triangle_normal};
use magg_core::idhash::IdMap;
use magg_core::prepared::{ElementInfo, Face, NO_PARENT};
use magg_core::subdivision::{element_corners, lattice_count, lattice_index, lattice_point, on_boundary};
use rayon::prelude::*;

/// A patch as a share receives it: corners, subdivision and the ids the host gave it.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SharePatch {
    /// Its id (input order).
    pub id: u32,
    /// Corners.
    pub v: [DVec3; 3],
    /// Subdivisions per edge (n x n elements).
    pub n: u32,
    /// Its first front element.
    pub first_element: u32,
    /// Its first back element, or [`NO_BACK`].
    pub back_element: u32,
    /// Whether its front elements hold one face's light or both.
    pub front_face: Face,
    /// Its material.
    pub material: u32,
    /// Its shading record, or [`NO_SHADING`] (numbered in patch order by the host).
    pub shading: u32,
    /// Shading normals at its corners, `None` for a flat patch.
    pub normals: Option<[DVec3; 3]>,
    /// Texture coordinates at its corners and its texture.
    pub uv: Option<([DVec2; 3], u32)>,
}

impl SharePatch {
    fn has_back(&self) -> bool {
        self.back_element != NO_BACK
    }
}

/// Where a lattice point's vertex is rooted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Root {
    point: PointId,
    share: u32,
    /// The root's index among its share's lattice points.
    index: u32,
}

/// A question for another share: the id of a vertex it roots (front), or of the back
/// copy it holds, the vertex named by its root.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct IdQuery {
    /// The back copy, not the vertex.
    pub back: bool,
    /// The vertex's root.
    pub root: PointId,
}

/// Per own patch, for the host's prefix sums: (patch, vertices it roots, back copies it
/// holds).
pub type PatchCounts = (u32, u32, u32);

/// A share's vertices, by global id: those it roots, and the back copies it holds.
pub type ShareVertices = Vec<(u32, DVec3)>;

/// One share.
pub struct Share {
    index: u32,
    patches: Vec<SharePatch>,
    /// First lattice point of each patch in `points`.
    offset: Vec<usize>,
    /// Every lattice point of every patch.
    points: Vec<DVec3>,
    /// Each lattice point's root (points that are no boundary point root themselves).
    roots: Vec<Root>,
    /// Each lattice point's back owner (patch, share), `None` without one.
    back_owner: Vec<Option<(u32, u32)>>,
    /// Vertex id of each lattice point.
    front_id: Vec<u32>,
    /// Back copies this share holds, by their vertex's root: (id, an own point of the
    /// vertex).
    back_ids: IdMap<u64, (u32, usize)>,
    /// The questions asked of other shares: (own point, question), in the order asked.
    pending: Vec<(usize, IdQuery)>,
    /// Its elements, once made: (id, local index in its patch's record, element).
    made: Vec<(u32, u32, ElementInfo)>,
}

/// Blocks a share wrote records into: (block id, the block with only those records; zero
/// elsewhere), ascending ids. Shares write disjoint records, so the scene's block is the
/// bitwise OR of every share's.
pub type PartialBlocks = Vec<(u32, Box<Block>)>;

/// A point's 64-bit key for hash tables: the lattice index above the patch, so that the
/// key's low bits vary with the patch.
fn pack(p: PointId) -> u64 {
    ((p.1 as u64) << 32) | p.0 as u64
}

impl Share {
    /// Share `index` of the patches `patches` (ascending ids).
    pub fn new(index: u32, patches: Vec<SharePatch>) -> Share {
        debug_assert!(patches.windows(2).all(|w| w[0].id < w[1].id));
        Share {
            index,
            patches,
            offset: Vec::new(),
            points: Vec::new(),
            roots: Vec::new(),
            back_owner: Vec::new(),
            front_id: Vec::new(),
            back_ids: IdMap::default(),
            pending: Vec::new(),
            made: Vec::new(),
        }
    }

    /// More patches (ascending ids, after the last), before the first step.
    pub fn extend(&mut self, more: Vec<SharePatch>) {
        self.patches.extend(more);
    }

    /// The share's patches.
    pub fn patches(&self) -> &[SharePatch] {
        &self.patches
    }

    /// Local index of patch `id`.
    fn local(&self, id: u32) -> Option<usize> {
        self.patches.binary_search_by_key(&id, |p| p.id).ok()
    }

    /// Index in `points` of lattice point `p` of an own patch.
    fn point_index(&self, p: PointId) -> Option<usize> {
        self.local(p.0).map(|k| self.offset[k] + p.1 as usize)
    }

    /// Step 1: every lattice point; the boundary points, one list per home share.
    pub fn lattice(&mut self, split: &SpaceSplit) -> Vec<Vec<WeldPoint>> {
        let mut offset = Vec::with_capacity(self.patches.len());
        let mut total = 0usize;
        for p in &self.patches {
            offset.push(total);
            total += lattice_count(p.n) as usize;
        }
        self.points = self
            .patches
            .par_iter()
            .flat_map_iter(|p| {
                let (n, v) = (p.n, p.v);
                (0..=n).flat_map(move |j| (0..=n - j).map(move |i| lattice_point(&v, n, i, j)))
            })
            .collect();
        // Every point roots itself until its home says otherwise; an interior point's
        // back copy is its own patch's.
        self.roots = Vec::with_capacity(total);
        self.back_owner = Vec::with_capacity(total);
        for p in &self.patches {
            let count = lattice_count(p.n) as u32;
            let owner = p.has_back().then_some((p.id, self.index));
            for l in 0..count {
                let index = self.roots.len() as u32;
                self.roots.push(Root { point: (p.id, l), share: self.index, index });
                self.back_owner.push(owner);
            }
        }
        self.offset = offset;
        let index = self.index;
        let boundary: Vec<WeldPoint> = self
            .patches
            .par_iter()
            .enumerate()
            .flat_map_iter(|(k, p)| {
                let (n, normal, has_back, off) = (p.n, triangle_normal(&p.v), p.has_back(), self.offset[k]);
                let points = &self.points;
                (0..=n).flat_map(move |j| {
                    (0..=n - j).filter(move |&i| on_boundary(n, i, j)).map(move |i| {
                        let local = lattice_index(n, i, j);
                        let at = points[off + local as usize];
                        let point = (off + local as usize) as u32;
                        WeldPoint {
                            key: weld::key(at),
                            patch: p.id,
                            local,
                            normal,
                            has_back,
                            share: index,
                            index: point,
                        }
                    })
                })
            })
            .collect();
        if split.shares() == 1 {
            return vec![boundary];
        }
        let mut homes: Vec<Vec<WeldPoint>> = vec![Vec::new(); split.shares()];
        for point in boundary {
            // The point's position is its key's bits (the sign of zero aside).
            let at =
                DVec3::new(f64::from_bits(point.key[0]), f64::from_bits(point.key[1]), f64::from_bits(point.key[2]));
            homes[split.share_of(at) as usize].push(point);
        }
        homes
    }

    /// Step 2, at the home: resolves every point it received; takes the answers about
    /// its own points at once and returns the others, one list per share that sent them.
    pub fn resolve(&mut self, shares: usize, received: Vec<WeldPoint>) -> Vec<Vec<WeldAnswer>> {
        let mut to: Vec<Vec<WeldAnswer>> = vec![Vec::new(); shares];
        for a in weld::resolve(received) {
            if a.share == self.index {
                self.take(&a);
            } else if let Some(list) = to.get_mut(a.share as usize) {
                list.push(a);
            }
        }
        to
    }

    /// Records what a home says of an own point.
    fn take(&mut self, a: &WeldAnswer) {
        let i = a.index as usize;
        if i < self.roots.len() {
            self.roots[i] = Root { point: a.root, share: a.root_share, index: a.root_index };
            self.back_owner[i] = a.back_owner;
        }
    }

    /// Step 3: takes the homes' answers about its points; returns each own patch's
    /// count of vertices it roots and of back copies it holds (in patch order).
    pub fn settle(&mut self, answers: impl IntoIterator<Item = WeldAnswer>) -> Vec<PatchCounts> {
        for a in answers {
            self.take(&a);
        }
        let mut backs: Vec<u64> = Vec::new();
        self.patches
            .iter()
            .enumerate()
            .map(|(k, p)| {
                let range = self.offset[k]..self.offset[k] + lattice_count(p.n) as usize;
                let mut roots = 0u32;
                backs.clear();
                for i in range {
                    if self.roots[i].point == (p.id, (i - self.offset[k]) as u32) {
                        roots += 1;
                    }
                    if self.back_owner[i].map(|o| o.0) == Some(p.id) {
                        backs.push(pack(self.roots[i].point));
                    }
                }
                backs.sort_unstable();
                backs.dedup();
                (p.id, roots, backs.len() as u32)
            })
            .collect()
    }

    /// Step 4: numbers the vertices it roots and the back copies it holds from each
    /// patch's bases (front, back: the counts of the patches before it); returns, per
    /// share, the ids to ask of it.
    pub fn number(&mut self, shares: usize, bases: &[(u32, u32)]) -> Vec<Vec<IdQuery>> {
        let total = self.points.len();
        self.front_id = vec![u32::MAX; total];
        self.back_ids = IdMap::default();
        // Own roots, patch by patch, in lattice order.
        for (k, p) in self.patches.iter().enumerate() {
            let mut next = bases[k].0;
            for l in 0..lattice_count(p.n) as u32 {
                let i = self.offset[k] + l as usize;
                if self.roots[i].point == (p.id, l) {
                    self.front_id[i] = next;
                    next += 1;
                }
            }
        }
        // Own back copies, patch by patch, in order of first use by the patch's elements.
        for (k, p) in self.patches.iter().enumerate() {
            if !p.has_back() {
                continue;
            }
            let mut next = bases[k].1;
            for local in 0..p.n * p.n {
                for (ci, cj) in element_corners(p.n, local) {
                    let i = self.offset[k] + lattice_index(p.n, ci, cj) as usize;
                    if self.back_owner[i].map(|o| o.0) == Some(p.id) {
                        let root = pack(self.roots[i].point);
                        if let std::collections::hash_map::Entry::Vacant(e) = self.back_ids.entry(root) {
                            e.insert((next, i));
                            next += 1;
                        }
                    }
                }
            }
        }
        // Points rooted elsewhere: on this share, look up; on another, ask.
        let mut asks: Vec<Vec<IdQuery>> = vec![Vec::new(); shares];
        self.pending.clear();
        for i in 0..total {
            let r = self.roots[i];
            if self.front_id[i] != u32::MAX {
                continue;
            }
            if r.share == self.index {
                match self.front_id.get(r.index as usize) {
                    Some(&id) => self.front_id[i] = id,
                    None => continue,
                }
            } else {
                let q = IdQuery { back: false, root: r.point };
                asks[r.share as usize].push(q);
                self.pending.push((i, q));
            }
        }
        // Back copies held elsewhere, for the points of own patches with a back face.
        for (k, p) in self.patches.iter().enumerate() {
            if !p.has_back() {
                continue;
            }
            for l in 0..lattice_count(p.n) as usize {
                let i = self.offset[k] + l;
                if let Some((_, share)) = self.back_owner[i] {
                    if share != self.index {
                        let q = IdQuery { back: true, root: self.roots[i].point };
                        asks[share as usize].push(q);
                        self.pending.push((i, q));
                    }
                }
            }
        }
        asks
    }

    /// Step 5: the ids asked of this share, in the order asked (`u32::MAX` for a vertex
    /// it does not hold, which a correct exchange never asks).
    pub fn answer(&self, asked: &[IdQuery]) -> Vec<u32> {
        asked
            .iter()
            .map(|q| {
                if q.back {
                    self.back_ids.get(&pack(q.root)).map_or(u32::MAX, |&(id, _)| id)
                } else {
                    self.point_index(q.root).map_or(u32::MAX, |i| self.front_id[i])
                }
            })
            .collect()
    }

    /// Step 6: the answers to its questions (per share, in the order asked), then its
    /// elements and vertices.
    pub fn elements(&mut self, answers: Vec<Vec<u32>>) -> ShareVertices {
        let mut foreign_back: IdMap<u64, u32> = IdMap::default();
        let mut cursor = vec![0usize; answers.len()];
        for &(i, q) in &self.pending {
            let share = if q.back { self.back_owner[i].map_or(0, |o| o.1) } else { self.roots[i].share } as usize;
            let id = answers.get(share).and_then(|a| a.get(cursor[share])).copied().unwrap_or(u32::MAX);
            cursor[share] += 1;
            if q.back {
                foreign_back.insert(pack(q.root), id);
            } else {
                self.front_id[i] = id;
            }
        }
        let back_id = |i: usize| -> u32 {
            let root = pack(self.roots[i].point);
            match self.back_ids.get(&root) {
                Some(&(id, _)) => id,
                None => foreign_back.get(&root).copied().unwrap_or(u32::MAX),
            }
        };
        let mut vertices = ShareVertices::new();
        let mut made = Vec::new();
        for (k, p) in self.patches.iter().enumerate() {
            let (n, off) = (p.n, self.offset[k]);
            let corner_points =
                |local: u32| element_corners(n, local).map(|(i, j)| off + lattice_index(n, i, j) as usize);
            for local in 0..n * n {
                let c = corner_points(local);
                let tri = c.map(|i| self.points[i]);
                let info = ElementInfo {
                    patch: p.id,
                    vertices: c.map(|i| self.front_id[i]),
                    area: triangle_area(&tri),
                    centroid: (tri[0] + tri[1] + tri[2]) / 3.0,
                    face: p.front_face,
                    parent: NO_PARENT,
                    child: 0,
                };
                made.push((p.first_element + local, local, info));
                if p.has_back() {
                    let back = ElementInfo { vertices: c.map(back_id), face: Face::Back, ..info };
                    made.push((p.back_element + local, n * n + local, back));
                }
            }
            for l in 0..lattice_count(n) as usize {
                let i = off + l;
                if self.roots[i].point == (p.id, l as u32) {
                    vertices.push((self.front_id[i], self.points[i]));
                }
            }
        }
        // A back copy sits where its vertex does: at its own member point.
        vertices.extend(self.back_ids.values().map(|&(id, i)| (id, self.points[i])));
        self.made = made;
        vertices
    }

    /// Its elements, once made: (id, element).
    pub fn made(&self) -> impl Iterator<Item = (u32, &ElementInfo)> {
        self.made.iter().map(|(id, _, e)| (*id, e))
    }

    /// Step 7: the records of its patches, their shading and its elements, written where
    /// `layout` puts them.
    pub fn pack(&self, layout: &BlockLayout) -> PartialBlocks {
        let mut blocks: IdMap<u32, Box<Block>> = IdMap::default();
        fn at(blocks: &mut IdMap<u32, Box<Block>>, block: u32) -> &mut Block {
            blocks.entry(block).or_insert_with(|| Box::new([0u8; BLOCK_SIZE]))
        }
        for p in &self.patches {
            let (b, off) = layout.patch_slot(p.id);
            PatchRecord {
                v: p.v,
                material: p.material,
                subdivisions: p.n,
                first_element: p.first_element,
                shading: p.shading,
                back_element: p.back_element,
            }
            .encode(at(&mut blocks, b), off);
            if p.shading != NO_SHADING {
                let (uv, texture) = p.uv.unwrap_or(([DVec2::ZERO; 3], NO_TEXTURE));
                let (b, off) = layout.shading_slot(p.shading);
                ShadingRecord { normals: p.normals.unwrap_or([DVec3::ZERO; 3]), uv, texture }
                    .encode(at(&mut blocks, b), off);
            }
        }
        for &(id, local, e) in &self.made {
            let (b, off) = layout.element_slot(id);
            ElementRecord { patch: e.patch, local, vertices: e.vertices, child: e.child, area: e.area }
                .encode(at(&mut blocks, b), off);
        }
        let mut out: PartialBlocks = blocks.into_iter().collect();
        out.sort_unstable_by_key(|b| b.0);
        out
    }
}
