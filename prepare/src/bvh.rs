//! The bounding volume hierarchy over the patches: a binned SAH build (Wald 2007; pbrt-v4
//! builds the same way), then node and leaf-triangle blocks ([`magg_core::blocks::bvh`]).
//!
//! The build splits the two halves of a large node on two threads (rayon), but every
//! split depends only on the primitives of its node, in the order the partition left
//! them, so the tree and its blocks are the same whatever the number of threads. The
//! binary tree is then widened to nodes of eight children (the levels below a node
//! opened by surface area), written in depth-first order (a node's first inner child
//! follows it) with the leaves in the same order, a leaf never straddling two triangle
//! blocks.

use glam::DVec3;
use magg_core::blocks::bvh::*;
use magg_core::blocks::{Block, BLOCK_SIZE};
use magg_core::geometry::Aabb;
use magg_core::header::BvhHeader;

/// SAH bins per axis.
const BINS: usize = 16;
/// Nodes with at least this many primitives build their halves in parallel.
const PARALLEL_MIN: usize = 4096;
/// Below this depth the split is the SAH's; deeper (a pathological distribution), the
/// node is halved at its median so that the depth stays logarithmic.
const SAH_DEPTH: u32 = 48;

/// A patch as the build sees it.
#[derive(Clone, Copy)]
struct Prim {
    bounds: Aabb,
    centroid: DVec3,
    id: u32,
}

/// The built tree, before packing.
enum Tree {
    /// Patch ids, ascending.
    Leaf(Vec<u32>),
    /// Two children and their bounds.
    Inner(Box<[(Aabb, Tree); 2]>),
}

/// The packed hierarchy.
pub(super) struct Bvh {
    /// Node blocks, then leaf-triangle blocks.
    pub blocks: Vec<Box<Block>>,
    /// Where they are.
    pub header: BvhHeader,
    /// Primitive binnings made (the build's work, for the cost model).
    pub binnings: u64,
}

fn area(b: &Aabb) -> f64 {
    let e = b.extent();
    if e.min_element() < 0.0 {
        0.0
    } else {
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }
}

fn bounds_of(prims: &[Prim]) -> (Aabb, Aabb) {
    prims.iter().fold((Aabb::EMPTY, Aabb::EMPTY), |(b, c), p| (b.union(p.bounds), c.grow(p.centroid)))
}

fn leaf(prims: &[Prim]) -> Tree {
    let mut ids: Vec<u32> = prims.iter().map(|p| p.id).collect();
    ids.sort_unstable();
    Tree::Leaf(ids)
}

/// In-place partition: the primitives for which `left` holds first; returns their count.
fn partition(prims: &mut [Prim], left: impl Fn(&Prim) -> bool) -> usize {
    let mut mid = 0;
    for i in 0..prims.len() {
        if left(&prims[i]) {
            prims.swap(i, mid);
            mid += 1;
        }
    }
    mid
}

/// The best SAH split of `prims`: (cost, axis, first bin of the right side), the
/// lowest axis and bin among equal costs.
fn best_split(prims: &[Prim], cb: &Aabb, node_area: f64) -> Option<(f64, usize, usize)> {
    let mut best: Option<(f64, usize, usize)> = None;
    for axis in 0..3 {
        let (lo, ext) = (cb.min[axis], cb.extent()[axis]);
        if !(ext > 0.0) {
            continue;
        }
        let scale = BINS as f64 / ext;
        let mut count = [0usize; BINS];
        let mut bbox = [Aabb::EMPTY; BINS];
        for p in prims {
            let b = (((p.centroid[axis] - lo) * scale) as usize).min(BINS - 1);
            count[b] += 1;
            bbox[b] = bbox[b].union(p.bounds);
        }
        // Right-side sweep, then left-side sweep evaluating each split.
        let mut right_area = [0.0; BINS];
        let mut right_count = [0usize; BINS];
        let (mut acc, mut n) = (Aabb::EMPTY, 0);
        for b in (1..BINS).rev() {
            acc = acc.union(bbox[b]);
            n += count[b];
            right_area[b] = area(&acc);
            right_count[b] = n;
        }
        let (mut acc, mut n) = (Aabb::EMPTY, 0);
        for split in 1..BINS {
            acc = acc.union(bbox[split - 1]);
            n += count[split - 1];
            if n == 0 || right_count[split] == 0 {
                continue;
            }
            let cost = 1.0 + (area(&acc) * n as f64 + right_area[split] * right_count[split] as f64) / node_area;
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, split));
            }
        }
    }
    best
}

/// Builds the subtree of `prims` (reordering them); returns it and the binnings made.
fn build(prims: &mut [Prim], depth: u32) -> (Tree, u64) {
    let n = prims.len();
    if n <= 2 {
        return (leaf(prims), 0);
    }
    let (bounds, cb) = bounds_of(prims);
    let node_area = area(&bounds);
    let split = if depth < SAH_DEPTH && node_area > 0.0 { best_split(prims, &cb, node_area) } else { None };
    let mid = match split {
        Some((cost, _, _)) if cost >= n as f64 && n <= BVH_MAX_LEAF as usize => return (leaf(prims), n as u64),
        Some((_, axis, split)) => {
            let (lo, scale) = (cb.min[axis], BINS as f64 / cb.extent()[axis]);
            partition(prims, |p| ((((p.centroid[axis] - lo) * scale) as usize).min(BINS - 1)) < split)
        }
        None if n <= BVH_MAX_LEAF as usize => return (leaf(prims), 0),
        None => {
            // No SAH split (centroids all equal, or too deep): halve at the median of
            // the longest axis of the centroids, ties by patch id.
            let e = cb.extent();
            let axis = if e.x >= e.y && e.x >= e.z {
                0
            } else if e.y >= e.z {
                1
            } else {
                2
            };
            prims.sort_unstable_by(|a, b| a.centroid[axis].total_cmp(&b.centroid[axis]).then(a.id.cmp(&b.id)));
            n / 2
        }
    };
    let (l, r) = prims.split_at_mut(mid);
    let ((lt, lo), (rt, ro)) = if n >= PARALLEL_MIN {
        rayon::join(|| build(l, depth + 1), || build(r, depth + 1))
    } else {
        (build(l, depth + 1), build(r, depth + 1))
    };
    let (lb, rb) = (bounds_of(l).0, bounds_of(r).0);
    (Tree::Inner(Box::new([(lb, lt), (rb, rt)])), n as u64 + lo + ro)
}

/// Writes nodes and leaves depth first.
struct Packer<'a> {
    /// The tree's patches, ascending by id: (id, corners).
    corners: &'a [(u32, [DVec3; 3])],
    /// Outward padding of every box (absolute, from the scene's scale).
    pad: f64,
    nodes: Vec<BvhNode>,
    triangle_blocks: Vec<Box<Block>>,
    /// Records used in the last triangle block.
    used: usize,
    triangles: u32,
}

impl Packer<'_> {
    fn child(&mut self, bounds: &Aabb, t: &Tree) -> BvhChild {
        let (lo, hi) = (bounds.min - DVec3::splat(self.pad), bounds.max + DVec3::splat(self.pad));
        let lo = [f32_down(lo.x), f32_down(lo.y), f32_down(lo.z)];
        let hi = [f32_up(hi.x), f32_up(hi.y), f32_up(hi.z)];
        match t {
            Tree::Leaf(ids) => {
                if self.triangle_blocks.is_empty() || self.used + ids.len() > BVH_TRIANGLES_PER_BLOCK {
                    self.triangle_blocks.push(Box::new([0u8; BLOCK_SIZE]));
                    self.used = 0;
                }
                let block = self.triangle_blocks.len() - 1;
                let first = ((block as u32) << BVH_TRIANGLE_SHIFT) | self.used as u32;
                for &id in ids {
                    let v = match self.corners.binary_search_by_key(&id, |c| c.0) {
                        Ok(k) => self.corners[k].1,
                        Err(_) => [DVec3::ZERO; 3],
                    };
                    let rec = BvhTriangle { v, patch: id };
                    rec.encode(&mut self.triangle_blocks[block], self.used * BVH_TRIANGLE_RECORD);
                    self.used += 1;
                }
                self.triangles += ids.len() as u32;
                BvhChild { lo, hi, index: first, count: ids.len() as u32 }
            }
            Tree::Inner(children) => BvhChild { lo, hi, index: self.inner(children), count: 0 },
        }
    }

    /// Writes an inner node and its subtree; returns its index. The binary tree's node
    /// is widened to [`BVH_WIDTH`] children by opening, while there is room, the inner
    /// child of largest surface area into its two children (in place, so that the
    /// children keep the build's order).
    fn inner(&mut self, children: &[(Aabb, Tree); 2]) -> u32 {
        let mut open: Vec<(&Aabb, &Tree)> = children.iter().map(|(b, t)| (b, t)).collect();
        while open.len() < BVH_WIDTH {
            let widest = open.iter().enumerate().filter(|(_, (_, t))| matches!(t, Tree::Inner(_))).fold(
                None::<(usize, f64)>,
                |best, (k, (b, _))| match best {
                    Some((_, a)) if a >= area(b) => best,
                    _ => Some((k, area(b))),
                },
            );
            let Some((k, _)) = widest else { break };
            let Tree::Inner(grand) = open[k].1 else { break };
            open.splice(k..=k, grand.iter().map(|(b, t)| (b, t)));
        }
        let at = self.nodes.len();
        self.nodes.push(BvhNode { children: [BvhChild::NONE; BVH_WIDTH] });
        let mut node = BvhNode { children: [BvhChild::NONE; BVH_WIDTH] };
        for (slot, (b, t)) in node.children.iter_mut().zip(open) {
            *slot = self.child(b, t);
        }
        self.nodes[at] = node;
        at as u32
    }
}

/// One share's tree, packed on its own: node records numbered from 0, triangle blocks
/// from 0 ([`relocate`] moves them to where they go in the scene's BVH blocks).
pub struct SubTree {
    /// Node records (node 0 is the root when the tree has inner nodes).
    pub nodes: Vec<BvhNode>,
    /// Leaf triangle blocks.
    pub triangle_blocks: Vec<Box<Block>>,
    /// Leaf triangle records.
    pub triangles: u32,
    /// The whole tree as a child of a node: node 0, or the one leaf, or none.
    pub root: BvhChild,
    /// Primitive binnings made (the build's work, for the cost model).
    pub binnings: u64,
}

/// Whether a triangle has zero area (no BVH, no subspace lists it: it can carry no light,
/// and rounding in the watertight test could report a hit through a corner).
pub fn degenerate(v: &[DVec3; 3]) -> bool {
    (v[1] - v[0]).cross(v[2] - v[0]) == DVec3::ZERO
}

/// The padding of every box for a scene whose patches of non-zero area have bounds
/// `bounds` (`Aabb::EMPTY`: none): 2^-20 of the largest coordinate.
pub fn pad_for(bounds: Aabb) -> f64 {
    let scale = if bounds.min.x <= bounds.max.x {
        bounds.min.abs().max(bounds.max.abs()).max_element().max(1e-30)
    } else {
        1.0
    };
    scale * 2f64.powi(-20)
}

/// Builds and packs the tree of `patches` ((id, corners), ascending ids; those of zero
/// area are left out), every box padded by `pad`.
pub fn build_subtree(patches: &[(u32, [DVec3; 3])], pad: f64) -> SubTree {
    let mut prims: Vec<Prim> = patches
        .iter()
        .filter(|(_, v)| !degenerate(v))
        .map(|&(id, v)| {
            let bounds = Aabb::of_triangle(&v);
            Prim { bounds, centroid: (bounds.min + bounds.max) * 0.5, id }
        })
        .collect();
    let all = bounds_of(&prims).0;
    let (tree, binnings) = build(&mut prims, 0);
    let mut p = Packer { corners: patches, pad, nodes: Vec::new(), triangle_blocks: Vec::new(), used: 0, triangles: 0 };
    let root = match &tree {
        Tree::Leaf(ids) if ids.is_empty() => BvhChild::NONE,
        _ => p.child(&all, &tree),
    };
    SubTree { nodes: p.nodes, triangle_blocks: p.triangle_blocks, triangles: p.triangles, root, binnings }
}

/// `child` of a subtree whose nodes start at node `node_base` and whose triangle blocks
/// start at triangle block `triangle_base`.
pub fn relocate(child: BvhChild, node_base: u32, triangle_base: u32) -> BvhChild {
    match child {
        c if c.index == BVH_NO_CHILD => c,
        c if c.count == 0 => BvhChild { index: c.index + node_base, ..c },
        c => BvhChild { index: c.index + (triangle_base << BVH_TRIANGLE_SHIFT), ..c },
    }
}

/// The nodes above the shares' roots `roots` (in share order): none for one root that is
/// an inner node (it is the scene's root, node 0); otherwise a root node over them, with
/// nodes of eight below it while there are more than eight. Node 0 is the root.
pub fn top(roots: &[BvhChild]) -> Vec<BvhNode> {
    let roots: Vec<BvhChild> = roots.iter().copied().filter(|c| c.index != BVH_NO_CHILD).collect();
    if roots.len() == 1 && roots[0].count == 0 {
        return Vec::new();
    }
    // Levels of groups of eight, from the roots up; then numbered from the top.
    let mut levels: Vec<Vec<Vec<BvhChild>>> = Vec::new();
    let mut current: Vec<BvhChild> = roots;
    while current.len() > BVH_WIDTH {
        let groups: Vec<Vec<BvhChild>> = current.chunks(BVH_WIDTH).map(<[_]>::to_vec).collect();
        current = groups.iter().map(|g| union(g)).collect();
        levels.push(groups);
    }
    levels.push(vec![current]);
    // Number the nodes: the root first, then each level down, in order.
    let mut nodes: Vec<BvhNode> = Vec::new();
    let mut first_of_level = 0u32;
    for (depth, level) in levels.iter().rev().enumerate() {
        let next_first = first_of_level + level.len() as u32;
        for (g, group) in level.iter().enumerate() {
            let mut node = BvhNode { children: [BvhChild::NONE; BVH_WIDTH] };
            for (k, c) in group.iter().enumerate() {
                node.children[k] = match depth + 1 < levels.len() {
                    // An inner group: the node of the level below.
                    true => BvhChild { index: next_first + (g * BVH_WIDTH + k) as u32, count: 0, ..*c },
                    false => *c,
                };
            }
            nodes.push(node);
        }
        first_of_level = next_first;
    }
    nodes
}

/// A child whose box holds all of `children`, its index to be set.
fn union(children: &[BvhChild]) -> BvhChild {
    let mut u = BvhChild { index: 0, count: 0, ..BvhChild::NONE };
    for c in children {
        for a in 0..3 {
            u.lo[a] = u.lo[a].min(c.lo[a]);
            u.hi[a] = u.hi[a].max(c.hi[a]);
        }
    }
    u
}

/// The scene's BVH from its shares' subtrees (in share order): the top nodes, then each
/// subtree's nodes and triangle blocks after those of the subtrees before it. With one
/// share whose tree has inner nodes, the subtree is the whole hierarchy as it was built.
pub fn assemble(subtrees: Vec<SubTree>) -> Bvh {
    let roots: Vec<BvhChild> = relocated_roots(&subtrees);
    let mut nodes = top(&roots);
    if nodes.is_empty() && roots.iter().all(|r| r.index == BVH_NO_CHILD || r.count > 0) {
        // No patch at all, or a single leaf: a root record holding it.
        let mut root = BvhNode { children: [BvhChild::NONE; BVH_WIDTH] };
        if let Some(r) = roots.iter().find(|r| r.index != BVH_NO_CHILD) {
            root.children[0] = *r;
        }
        nodes.push(root);
    }
    let (mut triangle_blocks, mut triangles, mut binnings) = (Vec::new(), 0, 0);
    for t in subtrees {
        let (node_base, triangle_base) = (nodes.len() as u32, triangle_blocks.len() as u32);
        nodes.extend(
            t.nodes.iter().map(|n| BvhNode { children: n.children.map(|c| relocate(c, node_base, triangle_base)) }),
        );
        triangle_blocks.extend(t.triangle_blocks);
        triangles += t.triangles;
        binnings += t.binnings;
    }
    let mut blocks: Vec<Box<Block>> = nodes
        .chunks(BVH_NODES_PER_BLOCK)
        .map(|chunk| {
            let mut b = Box::new([0u8; BLOCK_SIZE]);
            for (k, n) in chunk.iter().enumerate() {
                n.encode(&mut b, k * BVH_NODE_RECORD);
            }
            b
        })
        .collect();
    let header = BvhHeader {
        nodes: nodes.len() as u32,
        node_blocks: blocks.len() as u32,
        triangles,
        triangle_blocks: triangle_blocks.len() as u32,
    };
    blocks.append(&mut triangle_blocks);
    Bvh { blocks, header, binnings }
}

/// Each subtree's root where [`assemble`] puts it: nodes after the top's and the subtrees'
/// before, triangle blocks after the subtrees' before.
fn relocated_roots(subtrees: &[SubTree]) -> Vec<BvhChild> {
    // The top's size depends only on how many roots there are and what they are.
    let local: Vec<BvhChild> = subtrees.iter().map(|t| t.root).collect();
    let top_nodes = top(&local).len() as u32;
    let (mut node_base, mut triangle_base) = (top_nodes, 0u32);
    let mut roots = Vec::with_capacity(subtrees.len());
    for t in subtrees {
        roots.push(relocate(t.root, node_base, triangle_base));
        node_base += t.nodes.len() as u32;
        triangle_base += t.triangle_blocks.len() as u32;
    }
    roots
}

#[cfg(test)]
mod tests {
    use super::*;
    use magg_core::rng::Rng;
    use rayon::prelude::*;

    /// The patches of a test scene and the share each belongs to (empty: one share).
    struct Mesh {
        patches: Vec<[DVec3; 3]>,
        share_of: Vec<u32>,
    }

    /// The scene's hierarchy, each share's patches built side by side.
    fn build_and_pack(mesh: &Mesh) -> Bvh {
        let shares = mesh.share_of.iter().map(|&s| s as usize + 1).max().unwrap_or(1);
        let mut of_share: Vec<Vec<(u32, [DVec3; 3])>> = vec![Vec::new(); shares];
        let mut bounds = Aabb::EMPTY;
        for (i, v) in mesh.patches.iter().enumerate() {
            of_share[mesh.share_of.get(i).copied().unwrap_or(0) as usize].push((i as u32, *v));
            if !degenerate(v) {
                bounds = bounds.union(Aabb::of_triangle(v));
            }
        }
        let pad = pad_for(bounds);
        assemble(of_share.par_iter().map(|p| build_subtree(p, pad)).collect())
    }

    fn mesh(n: usize, seed: u64) -> Mesh {
        let mut rng = Rng::from_words(&[seed, 0xb0]);
        let mut u = move || rng.next_f64() * 2.0 - 1.0;
        let mut patches = Vec::new();
        for i in 0..n {
            let c = DVec3::new(u(), u(), u()) * 10.0;
            let mut corner = || c + DVec3::new(u(), u(), u()) * 0.5;
            patches.push([corner(), corner(), corner()]);
            if i % 97 == 0 {
                // Coincident copies and a zero-area sliver.
                patches.push(patches[patches.len() - 1]);
                patches.push([c, c + DVec3::X, c + 2.0 * DVec3::X]);
            }
        }
        Mesh { patches, share_of: Vec::new() }
    }

    fn contains(outer: &BvhChild, inner_lo: [f32; 3], inner_hi: [f32; 3]) -> bool {
        (0..3).all(|a| outer.lo[a] <= inner_lo[a] && inner_hi[a] <= outer.hi[a])
    }

    /// Walks the packed tree from the root; returns the patch ids found in its leaves
    /// and the number of node records visited, checking bounds and packing on the way.
    fn walk(bvh: &Bvh) -> (Vec<u32>, u32) {
        let h = bvh.header;
        let node = |n: u32| {
            let b = &bvh.blocks[(n >> BVH_NODE_SHIFT) as usize];
            BvhNode::decode(b, (n as usize & (BVH_NODES_PER_BLOCK - 1)) * BVH_NODE_RECORD)
        };
        let (mut ids, mut visited) = (Vec::new(), 0);
        let mut stack = vec![(0u32, None::<BvhChild>)];
        while let Some((n, parent)) = stack.pop() {
            assert!(n < h.nodes, "node {n} of {}", h.nodes);
            visited += 1;
            for c in node(n).children {
                if c.index == BVH_NO_CHILD {
                    continue;
                }
                if let Some(p) = parent {
                    assert!(contains(&p, c.lo, c.hi), "child box outside its parent's");
                }
                if c.count == 0 {
                    stack.push((c.index, Some(c)));
                    continue;
                }
                assert!(c.count <= BVH_MAX_LEAF, "leaf of {}", c.count);
                let (block, slot) = ((c.index >> BVH_TRIANGLE_SHIFT) as usize, (c.index & 31) as usize);
                assert!(slot + c.count as usize <= BVH_TRIANGLES_PER_BLOCK, "leaf straddles a block");
                assert!(block < h.triangle_blocks as usize);
                let b = &bvh.blocks[h.node_blocks as usize + block];
                for k in 0..c.count as usize {
                    let t = BvhTriangle::decode(&b[..], (slot + k) * BVH_TRIANGLE_RECORD);
                    for p in t.v {
                        let q = [p.x as f32, p.y as f32, p.z as f32];
                        assert!(contains(&c, q, q), "corner {p} outside its leaf's box");
                    }
                    ids.push(t.patch);
                }
            }
        }
        (ids, visited)
    }

    #[test]
    fn every_patch_of_non_zero_area_is_in_exactly_one_leaf() {
        for n in [0, 1, 2, 7, 300, 5000] {
            let m = mesh(n, n as u64);
            let bvh = build_and_pack(&m);
            let (mut ids, visited) = walk(&bvh);
            assert_eq!(visited, bvh.header.nodes, "{n}: every node record reachable once");
            ids.sort_unstable();
            let want: Vec<u32> = (0..m.patches.len() as u32)
                .filter(|&i| {
                    let v = m.patches[i as usize];
                    (v[1] - v[0]).cross(v[2] - v[0]) != DVec3::ZERO
                })
                .collect();
            assert_eq!(ids, want, "{n}");
            assert_eq!(bvh.header.triangles as usize, want.len());
        }
    }

    #[test]
    fn a_tree_over_shares_holds_every_patch_once() {
        for shares in [2u32, 3, 7] {
            let mut m = mesh(4000, shares as u64);
            m.share_of = m.patches.iter().map(|v| ((v[0].x + 10.0) / 20.0 * shares as f64) as u32 % shares).collect();
            let bvh = build_and_pack(&m);
            let (mut ids, visited) = walk(&bvh);
            assert_eq!(visited, bvh.header.nodes);
            ids.sort_unstable();
            let want = (0..m.patches.len() as u32).filter(|&i| {
                let v = m.patches[i as usize];
                (v[1] - v[0]).cross(v[2] - v[0]) != DVec3::ZERO
            });
            assert!(ids.iter().copied().eq(want), "{shares} shares");
        }
    }

    #[test]
    fn blocks_are_2_kb_and_counted_in_the_header() {
        let bvh = build_and_pack(&mesh(3000, 5));
        let h = bvh.header;
        assert_eq!(bvh.blocks.len() as u32, h.node_blocks + h.triangle_blocks);
        assert_eq!(h.node_blocks as usize, (h.nodes as usize).div_ceil(BVH_NODES_PER_BLOCK));
        assert!(bvh.blocks.iter().all(|b| b.len() == BLOCK_SIZE));
        // Leaves pack densely: at most one block in 4 wasted on leaves that do not fit.
        assert!((h.triangle_blocks as usize) < (h.triangles as usize).div_ceil(BVH_TRIANGLES_PER_BLOCK) * 5 / 4 + 1);
    }

    #[test]
    fn the_tree_does_not_depend_on_the_thread_count() {
        let m = mesh(20_000, 3);
        let on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| build_and_pack(&m))
        };
        let (one, four) = (on(1), on(4));
        assert_eq!(one.header, four.header);
        assert!(one.blocks == four.blocks, "blocks differ between 1 and 4 threads");
        assert_eq!(one.binnings, four.binnings);
    }
}
