//! Packing of the prepared scene into 2 KB blocks.

use super::bvh::Bvh;
use super::grid::Grid;
use super::mesh::Mesh;
use magg_core::blocks::*;
use magg_core::header::{BvhHeader, Counts, GridHeader, TextureHeader};
use magg_core::scene::Texture;

pub(super) struct Packed {
    pub blocks: Vec<Box<Block>>,
    pub layout: BlockLayout,
    pub grid: GridHeader,
    pub bvh: BvhHeader,
    pub counts: Counts,
    pub textures: Vec<TextureHeader>,
}

fn zero_block() -> Box<Block> {
    Box::new([0u8; BLOCK_SIZE])
}

/// Packs the subspace lists of `grid` (none for a scene traced through the BVH), the
/// BVH's blocks if any, then the patches, the shading records of the smooth or textured
/// ones, the texels of `textures`, the elements and vertex energies.
pub(super) fn pack(mesh: &Mesh, grid: &Grid, bvh: Option<Bvh>, textures: &[Texture]) -> Packed {
    let mut blocks: Vec<Box<Block>> = Vec::new();
    // Subspace blocks: one chain per non-empty cell.
    let mut cell_first_block = vec![NO_BLOCK; grid.cells.len()];
    for (c, ids) in grid.cells.iter().enumerate() {
        if ids.is_empty() {
            continue;
        }
        cell_first_block[c] = blocks.len() as u32;
        let chunks: Vec<&[u32]> = ids.chunks(SUBSPACE_IDS_PER_BLOCK).collect();
        let first = blocks.len() as u32;
        for (k, chunk) in chunks.iter().enumerate() {
            let mut b = zero_block();
            let next = if k + 1 < chunks.len() { first + k as u32 + 1 } else { NO_BLOCK };
            encode_subspace_header(&mut b, chunk.len() as u32, next);
            for (i, &id) in chunk.iter().enumerate() {
                encode_subspace_id(&mut b, i, id);
            }
            blocks.push(b);
        }
    }
    let subspace_blocks = blocks.len() as u32;

    let bvh_base = blocks.len() as u32;
    let bvh_header = match bvh {
        Some(mut b) => {
            blocks.append(&mut b.blocks);
            b.header
        }
        None => BvhHeader::default(),
    };
    let patch_base = blocks.len() as u32;
    // Shading records in patch order, numbered as they come: a patch with normals or a
    // texture has one.
    let mut shading_of = Vec::with_capacity(mesh.patches.len());
    let mut smooth: Vec<ShadingRecord> = Vec::new();
    for (n, t) in mesh.normals.iter().zip(&mesh.textured) {
        if n.is_none() && t.is_none() {
            shading_of.push(NO_SHADING);
            continue;
        }
        let (uv, texture) = t.unwrap_or(([glam::DVec2::ZERO; 3], NO_TEXTURE));
        smooth.push(ShadingRecord { normals: n.unwrap_or([glam::DVec3::ZERO; 3]), uv, texture });
        shading_of.push(smooth.len() as u32 - 1);
    }
    for chunk in (0..mesh.patches.len()).collect::<Vec<_>>().chunks(PATCHES_PER_BLOCK) {
        let mut b = zero_block();
        for (k, &p) in chunk.iter().enumerate() {
            PatchRecord {
                v: mesh.patches[p],
                material: mesh.materials[p],
                subdivisions: mesh.subdivisions[p],
                first_element: mesh.first_element[p],
                shading: shading_of[p],
                back_element: mesh.back_element[p],
            }
            .encode(&mut b, k * PATCH_RECORD);
        }
        blocks.push(b);
    }
    let shading_base = blocks.len() as u32;
    for chunk in smooth.chunks(SHADINGS_PER_BLOCK) {
        let mut b = zero_block();
        for (k, rec) in chunk.iter().enumerate() {
            rec.encode(&mut b, k * SHADING_RECORD);
        }
        blocks.push(b);
    }
    let texture_base = blocks.len() as u32;
    let mut texture_headers = Vec::with_capacity(textures.len());
    for t in textures {
        texture_headers.push(TextureHeader {
            width: t.width,
            height: t.height,
            first_block: blocks.len() as u32 - texture_base,
        });
        for chunk in t.texels.chunks(TEXELS_PER_BLOCK) {
            let mut b = zero_block();
            for (k, texel) in chunk.iter().enumerate() {
                b[3 * k..3 * k + 3].copy_from_slice(texel);
            }
            blocks.push(b);
        }
    }
    let element_base = blocks.len() as u32;
    for (chunk_idx, chunk) in mesh.elements.chunks(ELEMENTS_PER_BLOCK).enumerate() {
        let mut b = zero_block();
        for (k, e) in chunk.iter().enumerate() {
            let id = (chunk_idx * ELEMENTS_PER_BLOCK + k) as u32;
            // A back element's local index counts on from its patch's n * n front ones.
            let p = e.patch as usize;
            let local = if e.parent != magg_core::prepared::NO_PARENT {
                magg_core::blocks::REFINED | e.parent
            } else if e.face == magg_core::prepared::Face::Back {
                id - mesh.back_element[p] + (mesh.subdivisions[p] * mesh.subdivisions[p])
            } else {
                id - mesh.first_element[p]
            };
            ElementRecord { patch: e.patch, local, vertices: e.vertices, child: e.child, area: e.area }
                .encode(&mut b, k * ELEMENT_RECORD);
        }
        blocks.push(b);
    }
    let vertex_base = blocks.len() as u32;
    let vertex_blocks = mesh.vertex_positions.len().div_ceil(VERTICES_PER_BLOCK).max(1);
    for _ in 0..vertex_blocks {
        blocks.push(zero_block());
    }
    let total = blocks.len() as u32;
    let layout = BlockLayout { bvh_base, patch_base, shading_base, texture_base, element_base, vertex_base, total };
    let counts = Counts {
        patches: mesh.patches.len() as u32,
        elements: mesh.elements.len() as u32,
        vertices: mesh.vertex_positions.len() as u32,
        subspaces: grid.cells.len() as u32,
        subspace_blocks,
        bvh_blocks: patch_base - bvh_base,
        patch_blocks: shading_base - patch_base,
        shaded_patches: smooth.len() as u32,
        shading_blocks: texture_base - shading_base,
        texture_blocks: element_base - texture_base,
        element_blocks: vertex_base - element_base,
        vertex_blocks: vertex_blocks as u32,
    };
    Packed {
        blocks,
        layout,
        grid: GridHeader { min: grid.min, max: grid.max, dims: grid.dims, cell_first_block },
        bvh: bvh_header,
        counts,
        textures: texture_headers,
    }
}
