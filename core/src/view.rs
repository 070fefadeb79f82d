//! A node's view of the scene: the resident header plus every block read through the
//! node's LRU cache. All scene access of the kernels goes through here, so the cache's
//! hit ratio is the real one.

use crate::blocks::bvh::{
    node_record, BVH_NODE_RECORD, BVH_NODE_SHIFT, BVH_TRIANGLES_PER_BLOCK, BVH_TRIANGLE_RECORD, BVH_TRIANGLE_SHIFT,
};
use crate::blocks::*;
use crate::color::Rgb;
use crate::header::SceneHeader;
use crate::scene::MAX_REFINE_LEVELS;
use crate::subdivision::{child_of, child_triangle, element_triangle};
use glam::DVec3;
use std::sync::Arc;

mod batched;
pub use batched::{element_block, patch_block, vertex_block, ElementPoint, LeafPoint, NO_BLOCK};

/// Operation counts of the kernels (the basis of the compute cost model).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct OpCounters {
    /// Traversal steps of the acceleration structure: subspaces entered by rays through
    /// the grid, node records read by rays through the BVH.
    pub grid_steps: u64,
    /// Ray/patch intersection tests.
    pub patch_tests: u64,
    /// Light rays traced (primary and secondary).
    pub light_rays: u64,
    /// Viewing rays traced (primary and secondary).
    pub view_rays: u64,
    /// Shading evaluations at diffuse hits.
    pub shades: u64,
}

impl OpCounters {
    /// The counts done since `earlier` (a snapshot of the same counters).
    pub fn since(self, earlier: OpCounters) -> OpCounters {
        OpCounters {
            grid_steps: self.grid_steps.saturating_sub(earlier.grid_steps),
            patch_tests: self.patch_tests.saturating_sub(earlier.patch_tests),
            light_rays: self.light_rays.saturating_sub(earlier.light_rays),
            view_rays: self.view_rays.saturating_sub(earlier.view_rays),
            shades: self.shades.saturating_sub(earlier.shades),
        }
    }

    /// Sum of two counts.
    pub fn add(self, o: OpCounters) -> OpCounters {
        OpCounters {
            grid_steps: self.grid_steps + o.grid_steps,
            patch_tests: self.patch_tests + o.patch_tests,
            light_rays: self.light_rays + o.light_rays,
            view_rays: self.view_rays + o.view_rays,
            shades: self.shades + o.shades,
        }
    }
}

/// The scene as one node sees it.
///
/// Aligned to 128 bytes (two cache lines, the prefetch pair of x86): each node thread
/// updates its view's counters and cache statistics on every ray, and views side by side
/// in one `Vec` would otherwise share a line between threads (false sharing).
#[repr(align(128))]
pub struct SceneView {
    /// Resident data.
    pub header: Arc<SceneHeader>,
    cache: BlockCache,
    /// Operation counts so far.
    pub counters: OpCounters,
    /// The emitters' powers summed over channels, running totals in the header's order:
    /// area lights are sampled in proportion to them ([`SceneView::pick_emitter`]).
    emitter_cdf: Arc<[f64]>,
}

impl SceneView {
    /// A view reading blocks through `cache`.
    pub fn new(header: Arc<SceneHeader>, cache: BlockCache) -> Self {
        let mut total = 0.0;
        let emitter_cdf = header
            .emitters
            .iter()
            .map(|e| {
                let p = e.power.0.iter().sum::<f64>();
                total += if p.is_finite() && p > 0.0 { p } else { 0.0 };
                total
            })
            .collect();
        SceneView { header, cache, counters: OpCounters::default(), emitter_cdf }
    }

    /// The emitter (index into the header's `emitters`) that `u` in [0, 1) picks, with
    /// probability proportional to its power, and the probability; `None` when no
    /// emitter has power.
    pub fn pick_emitter(&self, u: f64) -> Option<(usize, f64)> {
        let total = *self.emitter_cdf.last()?;
        if !(total > 0.0) {
            return None;
        }
        let x = u * total;
        let k = self.emitter_cdf.partition_point(|&c| c <= x).min(self.emitter_cdf.len() - 1);
        let below = if k == 0 { 0.0 } else { self.emitter_cdf[k - 1] };
        let share = self.emitter_cdf[k] - below;
        if !(share > 0.0) {
            return None;
        }
        Some((k, share / total))
    }

    /// Cache hit and miss counts.
    pub fn cache_stats(&self) -> CacheStats {
        self.cache.stats()
    }

    /// True when the view reads through a cache that may evict blocks: the kernels
    /// then trace rays that read the same blocks together (docs/ARCHITECTURE.md, "Rays
    /// kept together"); with every block resident they trace the cheapest way.
    pub fn cache_is_bounded(&self) -> bool {
        self.cache.is_bounded()
    }

    /// Forgets cached vertex-energy blocks (they are rewritten after interpolation).
    pub fn invalidate_vertex_energy(&mut self) {
        let l = self.header.layout;
        self.cache.invalidate_range(l.vertex_base..l.total);
    }

    /// Patch record `id`.
    pub fn patch(&mut self, id: u32) -> Result<PatchRecord, BlockError> {
        let count = self.header.counts.patches;
        if id >= count {
            return Err(BlockError::BadId { kind: "patch", id: id as u64, count: count as u64 });
        }
        let (b, at) = self.header.layout.patch_slot(id);
        Ok(PatchRecord::decode(self.cache.get(b)?, at))
    }

    /// The shading record of patch record `p` (normals, texture coordinates), `None` for
    /// a flat, untextured patch.
    pub fn shading(&mut self, p: &PatchRecord) -> Result<Option<ShadingRecord>, BlockError> {
        if p.shading == NO_SHADING {
            return Ok(None);
        }
        let count = self.header.counts.shaded_patches;
        if p.shading >= count {
            return Err(BlockError::BadId { kind: "shading", id: p.shading as u64, count: count as u64 });
        }
        let (b, at) = self.header.layout.shading_slot(p.shading);
        Ok(Some(ShadingRecord::decode(self.cache.get(b)?, at)))
    }

    /// The linear diffuse albedo of texture `id` at texture coordinates `uv`: bilinear
    /// over its sRGB texels, read through the cache (texture coordinates repeat).
    pub fn texture_albedo(&mut self, id: u32, uv: glam::DVec2) -> Result<Rgb, BlockError> {
        let Some(&t) = self.header.textures.get(id as usize) else {
            let count = self.header.textures.len() as u64;
            return Err(BlockError::BadId { kind: "texture", id: id as u64, count });
        };
        let mut sum = [0.0f64; 3];
        for ((x, y), w) in crate::scene::texture_taps(t.width, t.height, uv.x, uv.y) {
            let i = y as usize * t.width as usize + x as usize;
            let block = self.header.layout.texture_base + t.first_block + (i / TEXELS_PER_BLOCK) as u32;
            let at = 3 * (i % TEXELS_PER_BLOCK);
            let b = self.cache.get(block)?;
            for (s, &c) in sum.iter_mut().zip(&b[at..at + 3]) {
                *s += w * crate::scene::srgb_to_linear(c);
            }
        }
        Ok(Rgb(sum))
    }

    /// Element record `id`.
    pub fn element(&mut self, id: u32) -> Result<ElementRecord, BlockError> {
        let count = self.header.counts.elements;
        if id >= count {
            return Err(BlockError::BadId { kind: "element", id: id as u64, count: count as u64 });
        }
        let (b, at) = self.header.layout.element_slot(id);
        Ok(ElementRecord::decode(self.cache.get(b)?, at))
    }

    /// The leaf element under a point: element `id` (record `rec`), or the child of it
    /// that refinement made and that holds the point, down to a leaf; with the point's
    /// barycentrics `w` in it.
    pub fn leaf_element(
        &mut self,
        mut id: u32,
        mut rec: ElementRecord,
        mut w: [f64; 3],
    ) -> Result<(u32, ElementRecord, [f64; 3]), BlockError> {
        let mut depth = 0;
        while rec.child != 0 {
            depth += 1;
            let (slot, inner) = child_of(w);
            let Some(child) = rec.child.checked_add(slot as u32).filter(|_| depth <= MAX_REFINE_LEVELS) else {
                return Err(BlockError::Unavailable { id, reason: "corrupt element refinement".into() });
            };
            (id, rec, w) = (child, self.element(child)?, inner);
        }
        Ok((id, rec, w))
    }

    /// The corners of element `id` (record `rec`), with the record of the element of its
    /// patch's lattice it lies in (itself, unless refinement made it: then its parents
    /// are followed up) and that patch's record.
    pub fn element_geometry(
        &mut self,
        id: u32,
        rec: ElementRecord,
    ) -> Result<(ElementRecord, PatchRecord, [DVec3; 3]), BlockError> {
        let corrupt = || BlockError::Unavailable { id, reason: "corrupt element refinement".into() };
        let mut slots = Vec::new();
        let (mut at, mut rec) = (id, rec);
        while let Some(parent) = rec.parent() {
            let up = self.element(parent)?;
            let slot = at.checked_sub(up.child).filter(|&s| s < 4 && up.child != 0).ok_or_else(corrupt)?;
            if slots.len() > MAX_REFINE_LEVELS as usize {
                return Err(corrupt());
            }
            slots.push(slot as usize);
            (at, rec) = (parent, up);
        }
        let p = self.patch(rec.patch)?;
        let n = p.subdivisions;
        let mut tri = element_triangle(&p.v, n, rec.lattice_local(n));
        for &slot in slots.iter().rev() {
            tri = child_triangle(&tri, slot);
        }
        Ok((rec, p, tri))
    }

    /// How many times refinement split the lattice element that element record `rec`
    /// descends from to make it: 0 for an element of its patch's lattice.
    pub fn element_depth(&mut self, mut rec: ElementRecord) -> Result<u32, BlockError> {
        let mut depth = 0;
        while let Some(parent) = rec.parent() {
            if depth >= MAX_REFINE_LEVELS {
                return Err(BlockError::Unavailable { id: parent, reason: "corrupt element refinement".into() });
            }
            rec = self.element(parent)?;
            depth += 1;
        }
        Ok(depth)
    }

    /// Vertex `id`'s irradiance (valid after energy interpolation), and whether it is
    /// marked for gathering ([`crate::energy::gather_vertices`]).
    pub fn vertex_light(&mut self, id: u32) -> Result<(Rgb, bool), BlockError> {
        let count = self.header.counts.vertices;
        if id >= count {
            return Err(BlockError::BadId { kind: "vertex", id: id as u64, count: count as u64 });
        }
        let (b, at) = self.header.layout.vertex_slot(id);
        let block = self.cache.get(b)?;
        Ok((decode_vertex_energy(block, at), decode_vertex_gather(block, at)))
    }

    /// The bytes of BVH node `n`'s record (node 0 is the root), to be read in place (the
    /// traversal loads its bounds straight into vector registers;
    /// [`crate::blocks::bvh::BvhNodeLanes::read`] decodes it).
    #[inline(always)]
    pub fn bvh_node_record(&mut self, n: u32) -> Result<&[u8; BVH_NODE_RECORD], BlockError> {
        let bvh = self.header.bvh;
        if n >= bvh.nodes {
            return Err(BlockError::BadId { kind: "BVH node", id: n as u64, count: bvh.nodes as u64 });
        }
        let b = self.header.layout.bvh_base + (n >> BVH_NODE_SHIFT);
        let at = (n & ((1 << BVH_NODE_SHIFT) - 1)) as usize * BVH_NODE_RECORD;
        Ok(node_record(self.cache.get(b)?, at))
    }

    /// The bytes of the `count` leaf-triangle records from address `first` (all in one
    /// block), to be read in place: [`bvh::BvhTriangle::parts`] gives a record's corner
    /// bytes and patch id, [`bvh::BvhTriangle::decode`] the decoded triangle.
    #[inline(always)]
    pub fn bvh_leaf(&mut self, first: u32, count: u32) -> Result<&[u8], BlockError> {
        let bvh = self.header.bvh;
        let (block, slot) = (first >> BVH_TRIANGLE_SHIFT, (first & ((1 << BVH_TRIANGLE_SHIFT) - 1)) as usize);
        if block >= bvh.triangle_blocks || slot + count as usize > BVH_TRIANGLES_PER_BLOCK {
            let id = first as u64;
            return Err(BlockError::BadId { kind: "BVH leaf", id, count: bvh.triangle_blocks as u64 });
        }
        let b = self.header.layout.bvh_base + bvh.node_blocks + block;
        let at = slot * BVH_TRIANGLE_RECORD;
        Ok(&self.cache.get(b)?[at..at + count as usize * BVH_TRIANGLE_RECORD])
    }

    /// Replaces `out` with the patch ids of subspace `cell`, following its block chain.
    pub fn subspace(&mut self, cell: usize, out: &mut Vec<u32>) -> Result<(), BlockError> {
        out.clear();
        let cells = self.header.grid.cell_first_block.len();
        let mut b = match self.header.grid.cell_first_block.get(cell) {
            Some(&b) => b,
            None => return Err(BlockError::BadId { kind: "subspace", id: cell as u64, count: cells as u64 }),
        };
        let mut guard = 0u32;
        while b != NO_BLOCK {
            if self.header.layout.kind(b) != Some(BlockKind::Subspace) || guard > self.header.layout.patch_base {
                return Err(BlockError::Unavailable { id: b, reason: "corrupt subspace chain".into() });
            }
            b = decode_subspace(self.cache.get(b)?, out);
            guard += 1;
        }
        Ok(())
    }
}
