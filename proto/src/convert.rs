//! Conversions between protobuf messages and the rendering core's types: the one place
//! where prost types meet `magg-core`.
//!
//! Going out ([`From`]) is infallible. Coming in ([`TryFrom`], [`block_from_wire`]) trusts
//! nothing: missing sub-messages, non-finite numbers, out-of-range settings, a block
//! layout that does not match the counts, or a grid whose cell table has the wrong length
//! are refused with a [`ConvertError`] that names the field and the value. A header that
//! converts is one the kernels can use without panicking.
//!
//! The light pass's messages (shards, pair leases, deposit batches, fork and node
//! reports) convert to the domain values of [`magg_core::cluster`] in `convert/cluster.rs`.
//!
//! ```
//! use magg_proto::{convert, v1};
//! let block = Box::new([7u8; magg_core::blocks::BLOCK_SIZE]);
//! let wire: v1::Block = convert::block_to_wire(3, &block);
//! let (id, back) = convert::block_from_wire(wire).unwrap();
//! assert_eq!((id, &back[..]), (3, &block[..]));
//! ```

use crate::v1;
use glam::DVec3;
use magg_core::blocks::{
    bvh::{BVH_NODES_PER_BLOCK, BVH_TRIANGLES_PER_BLOCK},
    Block, BlockLayout, CacheSize, BLOCK_SIZE, ELEMENTS_PER_BLOCK, NO_BLOCK, PATCHES_PER_BLOCK, SHADINGS_PER_BLOCK,
    VERTICES_PER_BLOCK,
};
use magg_core::color::Rgb;
use magg_core::header::{BvhHeader, Counts, GridHeader, SceneHeader, TextureHeader};
use magg_core::scene::{Accel, SourceLoc};

mod cluster;
mod scene;
pub use cluster::ledger_digest;
use scene::{
    camera_from_wire, camera_to_wire, emitter_to_wire, emitters_from_wire, light_from_wire, light_to_wire,
    material_from_wire, material_to_wire, plan_from_wire, plan_to_wire, settings_from_wire, settings_to_wire,
};

/// Most blocks a scene may have (32 GiB of scene data).
pub const MAX_BLOCKS: u32 = 1 << 24;
/// Most elements a scene may have (on top of its own `max_elements`).
pub const MAX_ELEMENTS: u32 = 1 << 27;
/// Most lights a header may carry.
pub const MAX_LIGHTS: usize = 65_536;
/// Most materials a header may carry.
pub const MAX_MATERIALS: usize = 65_536;
/// Most subspaces of a grid (the scene parser's limit).
pub const MAX_SUBSPACES: u64 = 16_777_216;
/// Most lines of an effects plan's reasons.
pub const MAX_REASONS: usize = 256;
/// Longest string (material name, plan reason) accepted, bytes.
pub const MAX_STRING: usize = 4096;
/// Largest depth of the effects plan.
pub const MAX_PLAN_DEPTH: u32 = 32;

/// A wire message that cannot become a core value.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ConvertError {
    /// A required sub-message is absent.
    #[error("{field} is missing")]
    Missing {
        /// Dotted field name.
        field: String,
    },
    /// A value is out of range, non-finite, or inconsistent with another.
    #[error("{field} = {value}: {expected}")]
    Invalid {
        /// Dotted field name.
        field: String,
        /// The offending value as received.
        value: String,
        /// What was expected instead.
        expected: String,
    },
    /// A block whose payload is not exactly [`BLOCK_SIZE`] bytes.
    #[error("block {id} has {len} bytes, expected {BLOCK_SIZE}")]
    BlockSize {
        /// Block id.
        id: u32,
        /// Bytes received.
        len: usize,
    },
}

fn invalid(field: impl Into<String>, value: impl std::fmt::Display, expected: impl Into<String>) -> ConvertError {
    ConvertError::Invalid { field: field.into(), value: value.to_string(), expected: expected.into() }
}

fn missing(field: &str) -> ConvertError {
    ConvertError::Missing { field: field.to_string() }
}

fn require<T>(v: Option<T>, field: &str) -> Result<T, ConvertError> {
    v.ok_or_else(|| missing(field))
}

fn finite(x: f64, field: &str) -> Result<f64, ConvertError> {
    if x.is_finite() {
        Ok(x)
    } else {
        Err(invalid(field, x, "a finite number"))
    }
}

fn in_range<T: PartialOrd + std::fmt::Display + Copy>(x: T, lo: T, hi: T, field: &str) -> Result<T, ConvertError> {
    if x >= lo && x <= hi {
        Ok(x)
    } else {
        Err(invalid(field, x, format!("in {lo}..={hi}")))
    }
}

fn short_string(s: String, field: &str) -> Result<String, ConvertError> {
    if s.len() > MAX_STRING {
        Err(invalid(field, format!("<{} bytes>", s.len()), format!("at most {MAX_STRING} bytes")))
    } else {
        Ok(s)
    }
}

fn wire_loc() -> SourceLoc {
    SourceLoc { file: "<wire>".into(), line: 0 }
}

// ------------------------------------------------------------------ small values

fn vec3_to_wire(v: DVec3) -> v1::Vec3 {
    v1::Vec3 { x: v.x, y: v.y, z: v.z }
}

fn vec3_from_wire(v: Option<v1::Vec3>, field: &str) -> Result<DVec3, ConvertError> {
    let v = require(v, field)?;
    for (x, axis) in [(v.x, "x"), (v.y, "y"), (v.z, "z")] {
        finite(x, &format!("{field}.{axis}"))?;
    }
    Ok(DVec3::new(v.x, v.y, v.z))
}

fn rgb_to_wire(c: Rgb) -> v1::Rgb {
    v1::Rgb { r: c.0[0], g: c.0[1], b: c.0[2] }
}

/// A colour whose channels are finite and in `[0, max]`.
fn rgb_from_wire(c: Option<v1::Rgb>, field: &str, max: f64) -> Result<Rgb, ConvertError> {
    let c = require(c, field)?;
    for (x, ch) in [(c.r, "r"), (c.g, "g"), (c.b, "b")] {
        let f = format!("{field}.{ch}");
        finite(x, &f)?;
        if !(0.0..=max).contains(&x) {
            return Err(invalid(f, x, format!("in [0, {max}]")));
        }
    }
    Ok(Rgb::new(c.r, c.g, c.b))
}

// ------------------------------------------------------------------ grid, layout, counts

fn counts_from_wire(c: v1::Counts) -> Counts {
    Counts {
        patches: c.patches,
        elements: c.elements,
        vertices: c.vertices,
        subspaces: c.subspaces,
        subspace_blocks: c.subspace_blocks,
        bvh_blocks: c.bvh_blocks,
        patch_blocks: c.patch_blocks,
        shaded_patches: c.shaded_patches,
        shading_blocks: c.shading_blocks,
        texture_blocks: c.texture_blocks,
        element_blocks: c.element_blocks,
        vertex_blocks: c.vertex_blocks,
    }
}

/// The textures of a header, checked against the texture blocks: each texture's texels
/// fill its own run of blocks, the runs one after another from the first texture block.
fn textures_from_wire(t: Vec<v1::TextureHeader>, c: &Counts) -> Result<Vec<TextureHeader>, ConvertError> {
    let mut next = 0u64;
    let mut out = Vec::with_capacity(t.len());
    for (i, w) in t.into_iter().enumerate() {
        let h = TextureHeader { width: w.width, height: w.height, first_block: w.first_block };
        let side = 1..=magg_core::scene::MAX_TEXTURE_SIDE;
        if !side.contains(&h.width) || !side.contains(&h.height) {
            let v = format!("{} x {}", h.width, h.height);
            return Err(invalid(&format!("textures[{i}]"), v, "each side 1..=16384"));
        }
        if h.first_block as u64 != next {
            return Err(invalid(&format!("textures[{i}].first_block"), h.first_block, format!("{next}")));
        }
        next += h.blocks() as u64;
        out.push(h);
    }
    if next != c.texture_blocks as u64 {
        return Err(invalid("counts.texture_blocks", c.texture_blocks, format!("{next} (from the textures)")));
    }
    Ok(out)
}

/// Checks that the layout's bases are ordered, that each kind's block count matches the
/// entity counts (and the BVH header), that only the scene's acceleration structure has
/// blocks, and that the total is bounded.
fn check_layout(l: &BlockLayout, c: &Counts, bvh: &BvhHeader, accel: Accel) -> Result<(), ConvertError> {
    if l.total > MAX_BLOCKS {
        return Err(invalid("layout.total", l.total, format!("at most {MAX_BLOCKS} blocks")));
    }
    if !(l.bvh_base <= l.patch_base
        && l.patch_base <= l.shading_base
        && l.shading_base <= l.texture_base
        && l.texture_base <= l.element_base
        && l.element_base <= l.vertex_base
        && l.vertex_base < l.total)
    {
        let v = format!(
            "bvh {} patch {} shading {} texture {} element {} vertex {} total {}",
            l.bvh_base, l.patch_base, l.shading_base, l.texture_base, l.element_base, l.vertex_base, l.total
        );
        let want = "bvh_base <= patch_base <= shading_base <= texture_base <= element_base <= vertex_base < total";
        return Err(invalid("layout", v, want));
    }
    let blocks_for = |n: u32, per: usize| (n as usize).div_ceil(per) as u64;
    let (grid, uses_bvh) = (accel == Accel::Grid, accel == Accel::Bvh);
    let checks: [(&str, u64, u64); 17] = [
        ("counts.subspace_blocks", c.subspace_blocks as u64, l.bvh_base as u64),
        ("counts.bvh_blocks", c.bvh_blocks as u64, (l.patch_base - l.bvh_base) as u64),
        ("counts.bvh_blocks", c.bvh_blocks as u64, bvh.node_blocks as u64 + bvh.triangle_blocks as u64),
        ("bvh.node_blocks", bvh.node_blocks as u64, blocks_for(bvh.nodes, BVH_NODES_PER_BLOCK)),
        // Grid scenes have no BVH; BVH scenes have a root and no subspace block, and at
        // most one leaf-triangle block per triangle, at least as many as they fill (below).
        ("bvh.nodes", (bvh.nodes > 0) as u64, uses_bvh as u64),
        ("counts.subspace_blocks", (c.subspace_blocks > 0 && uses_bvh) as u64, 0),
        ("counts.patch_blocks", c.patch_blocks as u64, (l.shading_base - l.patch_base) as u64),
        ("counts.shading_blocks", c.shading_blocks as u64, (l.texture_base - l.shading_base) as u64),
        ("counts.texture_blocks", c.texture_blocks as u64, (l.element_base - l.texture_base) as u64),
        ("counts.shading_blocks", c.shading_blocks as u64, blocks_for(c.shaded_patches, SHADINGS_PER_BLOCK)),
        ("counts.shaded_patches", (c.shaded_patches > c.patches) as u64, 0),
        ("counts.element_blocks", c.element_blocks as u64, (l.vertex_base - l.element_base) as u64),
        ("counts.vertex_blocks", c.vertex_blocks as u64, (l.total - l.vertex_base) as u64),
        ("counts.patch_blocks", c.patch_blocks as u64, blocks_for(c.patches, PATCHES_PER_BLOCK)),
        ("counts.element_blocks", c.element_blocks as u64, blocks_for(c.elements, ELEMENTS_PER_BLOCK)),
        ("counts.vertex_blocks", c.vertex_blocks as u64, blocks_for(c.vertices, VERTICES_PER_BLOCK).max(1)),
        // A subspace block holds at least one patch id of a non-empty subspace.
        (
            "counts.subspace_blocks",
            (c.subspace_blocks > 0 || !grid) as u64,
            (c.subspaces > 0 && c.patches > 0 || !grid) as u64,
        ),
    ];
    for (field, got, want) in checks {
        if got != want {
            return Err(invalid(field, got, format!("{want} (from the layout and the counts)")));
        }
    }
    if bvh.triangles > c.patches {
        return Err(invalid("bvh.triangles", bvh.triangles, format!("at most counts.patches = {}", c.patches)));
    }
    let (lo, hi) = (blocks_for(bvh.triangles, BVH_TRIANGLES_PER_BLOCK), bvh.triangles as u64);
    if !(lo..=hi).contains(&(bvh.triangle_blocks as u64)) {
        return Err(invalid("bvh.triangle_blocks", bvh.triangle_blocks, format!("{lo}..={hi} (from bvh.triangles)")));
    }
    if c.elements > MAX_ELEMENTS {
        return Err(invalid("counts.elements", c.elements, format!("at most {MAX_ELEMENTS}")));
    }
    if c.patches == 0 || c.elements < c.patches {
        let v = format!("{} patches, {} elements", c.patches, c.elements);
        return Err(invalid("counts", v, "at least one patch and one element per patch"));
    }
    Ok(())
}

fn grid_from_wire(g: v1::GridHeader, layout: &BlockLayout, counts: &Counts) -> Result<GridHeader, ConvertError> {
    let min = vec3_from_wire(g.min, "grid.min")?;
    let max = vec3_from_wire(g.max, "grid.max")?;
    let dims: [u32; 3] =
        g.dims.as_slice().try_into().map_err(|_| invalid("grid.dims", format!("{:?}", g.dims), "3 values"))?;
    if dims.contains(&0) {
        return Err(invalid("grid.dims", format!("{dims:?}"), "no zero"));
    }
    let cells = dims.iter().map(|&d| d as u128).product::<u128>();
    if cells > MAX_SUBSPACES as u128 {
        return Err(invalid("grid.dims", format!("{dims:?}"), format!("at most {MAX_SUBSPACES} subspaces")));
    }
    for a in 0..3 {
        let cell_positive = min[a] < max[a] && (max[a] - min[a]) / dims[a] as f64 > 0.0;
        if !cell_positive {
            let v = format!("min {min:?} max {max:?}");
            return Err(invalid("grid", v, "min < max on every axis, with non-empty subspaces"));
        }
    }
    let cells = cells as u64;
    if cells != counts.subspaces as u64 {
        return Err(invalid("counts.subspaces", counts.subspaces, format!("{cells} (the grid's dims product)")));
    }
    if g.cell_first_block.len() as u64 != cells {
        return Err(invalid(
            "grid.cell_first_block",
            format!("<{} entries>", g.cell_first_block.len()),
            format!("{cells} entries"),
        ));
    }
    if let Some((i, b)) = g.cell_first_block.iter().enumerate().find(|&(_, &b)| b != NO_BLOCK && b >= layout.bvh_base) {
        return Err(invalid(format!("grid.cell_first_block[{i}]"), b, "a subspace block id or NO_BLOCK"));
    }
    Ok(GridHeader { min, max, dims, cell_first_block: g.cell_first_block })
}

// ------------------------------------------------------------------ scene header

impl From<&SceneHeader> for v1::SceneHeader {
    fn from(h: &SceneHeader) -> Self {
        let (l, c) = (&h.layout, &h.counts);
        v1::SceneHeader {
            camera: Some(camera_to_wire(&h.camera)),
            settings: Some(settings_to_wire(&h.settings)),
            lights: h.lights.iter().map(light_to_wire).collect(),
            emitters: h.emitters.iter().map(emitter_to_wire).collect(),
            materials: h.materials.iter().map(material_to_wire).collect(),
            textures: h
                .textures
                .iter()
                .map(|t| v1::TextureHeader { width: t.width, height: t.height, first_block: t.first_block })
                .collect(),
            grid: Some(v1::GridHeader {
                min: Some(vec3_to_wire(h.grid.min)),
                max: Some(vec3_to_wire(h.grid.max)),
                dims: h.grid.dims.to_vec(),
                cell_first_block: h.grid.cell_first_block.clone(),
            }),
            bvh: Some(v1::BvhHeader {
                nodes: h.bvh.nodes,
                node_blocks: h.bvh.node_blocks,
                triangles: h.bvh.triangles,
                triangle_blocks: h.bvh.triangle_blocks,
            }),
            layout: Some(v1::BlockLayout {
                bvh_base: l.bvh_base,
                patch_base: l.patch_base,
                shading_base: l.shading_base,
                texture_base: l.texture_base,
                element_base: l.element_base,
                vertex_base: l.vertex_base,
                total: l.total,
            }),
            counts: Some(v1::Counts {
                patches: c.patches,
                elements: c.elements,
                vertices: c.vertices,
                subspaces: c.subspaces,
                subspace_blocks: c.subspace_blocks,
                bvh_blocks: c.bvh_blocks,
                patch_blocks: c.patch_blocks,
                shaded_patches: c.shaded_patches,
                shading_blocks: c.shading_blocks,
                texture_blocks: c.texture_blocks,
                element_blocks: c.element_blocks,
                vertex_blocks: c.vertex_blocks,
            }),
            energy_quantum: h.energy_quantum,
            plan: Some(plan_to_wire(&h.plan)),
        }
    }
}

impl TryFrom<v1::SceneHeader> for SceneHeader {
    type Error = ConvertError;

    fn try_from(h: v1::SceneHeader) -> Result<Self, ConvertError> {
        let camera = camera_from_wire(require(h.camera, "camera")?)?;
        let settings = settings_from_wire(require(h.settings, "settings")?)?;
        if h.lights.len() > MAX_LIGHTS {
            return Err(invalid("lights", format!("<{} lights>", h.lights.len()), format!("at most {MAX_LIGHTS}")));
        }
        let lights =
            h.lights.into_iter().enumerate().map(|(i, l)| light_from_wire(i, l)).collect::<Result<Vec<_>, _>>()?;
        if h.materials.is_empty() || h.materials.len() > MAX_MATERIALS {
            let v = format!("<{} materials>", h.materials.len());
            return Err(invalid("materials", v, format!("1..={MAX_MATERIALS} materials")));
        }
        let materials = h
            .materials
            .into_iter()
            .enumerate()
            .map(|(i, m)| material_from_wire(i, m))
            .collect::<Result<Vec<_>, _>>()?;
        let counts = counts_from_wire(require(h.counts, "counts")?);
        let l = require(h.layout, "layout")?;
        let layout = BlockLayout {
            bvh_base: l.bvh_base,
            patch_base: l.patch_base,
            shading_base: l.shading_base,
            texture_base: l.texture_base,
            element_base: l.element_base,
            vertex_base: l.vertex_base,
            total: l.total,
        };
        // A scene traced through the grid may leave the BVH header out (all zero).
        let b = h.bvh.unwrap_or_default();
        let bvh = BvhHeader {
            nodes: b.nodes,
            node_blocks: b.node_blocks,
            triangles: b.triangles,
            triangle_blocks: b.triangle_blocks,
        };
        check_layout(&layout, &counts, &bvh, settings.accel)?;
        let textures = textures_from_wire(h.textures, &counts)?;
        if counts.elements as u64 > settings.max_elements {
            let expected = format!("at most settings.max_elements = {}", settings.max_elements);
            return Err(invalid("counts.elements", counts.elements, expected));
        }
        let grid = grid_from_wire(require(h.grid, "grid")?, &layout, &counts)?;
        let q = finite(h.energy_quantum, "energy_quantum")?;
        if q <= 0.0 {
            return Err(invalid("energy_quantum", q, "a positive number"));
        }
        let plan = plan_from_wire(require(h.plan, "plan")?)?;
        let emitters = emitters_from_wire(h.emitters, counts.elements)?;
        Ok(SceneHeader {
            camera,
            settings,
            lights,
            emitters,
            materials,
            textures,
            grid,
            bvh,
            layout,
            counts,
            energy_quantum: q,
            plan,
        })
    }
}

// ------------------------------------------------------------------ blocks

/// A block from the wire: its id and its 2 KB payload (refused unless exactly
/// [`BLOCK_SIZE`] bytes). The id is not range-checked here: the receiver knows the layout.
pub fn block_from_wire(b: v1::Block) -> Result<(u32, Box<Block>), ConvertError> {
    let (id, data) = block_bytes_from_wire(b)?;
    let mut block = Box::new([0u8; BLOCK_SIZE]);
    block.copy_from_slice(&data);
    Ok((id, block))
}

/// A block from the wire as the received bytes themselves (no copy), refused unless
/// exactly [`BLOCK_SIZE`] bytes.
pub fn block_bytes_from_wire(b: v1::Block) -> Result<(u32, bytes::Bytes), ConvertError> {
    if b.data.len() != BLOCK_SIZE {
        return Err(ConvertError::BlockSize { id: b.id, len: b.data.len() });
    }
    Ok((b.id, b.data))
}

/// A node's cache size as `RegisterReply.cache_blocks` carries it: the count, 0 for
/// unlimited.
pub fn cache_size_to_wire(c: CacheSize) -> u64 {
    c.blocks().unwrap_or(0)
}

/// The cache size of `RegisterReply.cache_blocks` (0: unlimited).
pub fn cache_size_from_wire(blocks: u64) -> CacheSize {
    match blocks {
        0 => CacheSize::Unlimited,
        n => CacheSize::from_blocks(Some(n)),
    }
}

/// A block for the wire.
pub fn block_to_wire(id: u32, block: &Block) -> v1::Block {
    v1::Block { id, data: bytes::Bytes::copy_from_slice(block) }
}

/// The (element, r g b fixed point) pairs of a fork's `GetEnergies` reply, once its
/// packed arrays are read ([`crate::packed`]) and checked to fit (three energy values
/// per element).
pub fn element_energies(r: &v1::GetEnergiesReply) -> Result<impl Iterator<Item = (u32, [i64; 3])> + '_, ConvertError> {
    let elements = crate::packed::varints_u32(&r.elements)
        .map_err(|e| invalid("GetEnergiesReply.elements", format!("{} bytes", r.elements.len()), e.to_string()))?;
    if r.energy.len() != 24 * elements.len() {
        return Err(invalid(
            "GetEnergiesReply.energy",
            format!("{} bytes", r.energy.len()),
            format!("3 values (24 bytes) for each of {} elements", elements.len()),
        ));
    }
    let value = |c: &[u8]| i64::from_le_bytes(c.try_into().unwrap_or_default());
    Ok(elements
        .into_iter()
        .zip(r.energy.chunks_exact(24))
        .map(move |(e, v)| (e, [value(&v[..8]), value(&v[8..16]), value(&v[16..])])))
}

/// Block `i` of a prepared scene, as the owner of a [`bytes::Bytes`] payload.
struct SceneBlock(std::sync::Arc<magg_core::prepared::PreparedScene>, usize);

impl AsRef<[u8]> for SceneBlock {
    fn as_ref(&self) -> &[u8] {
        &self.0.blocks[self.1][..]
    }
}

/// Every block of a prepared scene for the wire, by id, without copying: each payload
/// borrows the scene's own block (and keeps the scene alive). The host uploads the
/// shards from these; only the encoding copies the bytes.
pub fn scene_blocks_to_wire(prepared: &std::sync::Arc<magg_core::prepared::PreparedScene>) -> Vec<v1::Block> {
    (0..prepared.blocks.len())
        .map(|i| v1::Block { id: i as u32, data: bytes::Bytes::from_owner(SceneBlock(prepared.clone(), i)) })
        .collect()
}

// ------------------------------------------------------------------ pixel rows

/// Pixels for a [`v1::Row`]: r, g, b of each pixel as little-endian f32 (the bytes of a
/// packed `repeated float`).
pub fn pixels_to_wire(px: impl IntoIterator<Item = f32>) -> bytes::Bytes {
    px.into_iter().flat_map(f32::to_le_bytes).collect::<Vec<u8>>().into()
}

/// The floats of a [`v1::Row`]'s pixels; trailing bytes short of a float are ignored
/// (the receiver checks the length: 12 bytes a pixel).
pub fn pixels_from_wire(b: &[u8]) -> impl ExactSizeIterator<Item = f32> + '_ {
    b.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
}

/// Decodes wire pixels (see [`pixels_to_wire`]) straight into `out`, one RGB triple per
/// 12 bytes; stops at the shorter of the two. The host's hot path for every row.
pub fn pixels_into(b: &[u8], out: &mut [[f32; 3]]) {
    let f = |c: &[u8]| f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
    for (px, c) in out.iter_mut().zip(b.chunks_exact(12)) {
        *px = [f(&c[0..4]), f(&c[4..8]), f(&c[8..12])];
    }
}

#[cfg(test)]
mod tests;
