//! Packing of the prepared scene into 2 KB blocks.
//!
//! The shares write the records of their patches, shading and elements
//! ([`crate::shares::Share::pack`]); what is global is written here: the subspace lists,
//! the BVH's blocks, the texels, and the records refinement changed or made (the split
//! elements, now with their children, and the children).

use super::bvh::Bvh;
use super::grid::Grid;
use super::mesh::Mesh;
use super::shares::{PartialBlocks, ShareError};
use magg_core::blocks::*;
use magg_core::header::{BvhHeader, Counts, GridHeader, TextureHeader};
use magg_core::prepared::{Face, NO_PARENT};
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
/// ones, the texels of `textures`, the elements and vertex energies (zero).
/// The shares write their own records (patches, shading, elements) where the layout puts
/// them: `records` asks them for their blocks.
pub(super) fn pack(
    mesh: &Mesh,
    grid: &Grid,
    bvh: Option<Bvh>,
    textures: &[Texture],
    records: impl FnOnce(&BlockLayout) -> Result<Vec<PartialBlocks>, ShareError>,
) -> Result<Packed, ShareError> {
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
    let shading_base = patch_base + mesh.patches.len().div_ceil(PATCHES_PER_BLOCK) as u32;
    let texture_base = shading_base + (mesh.shaded as usize).div_ceil(SHADINGS_PER_BLOCK) as u32;
    let mut texture_headers = Vec::with_capacity(textures.len());
    let mut texels: Vec<Box<Block>> = Vec::new();
    for t in textures {
        texture_headers.push(TextureHeader { width: t.width, height: t.height, first_block: texels.len() as u32 });
        for chunk in t.texels.chunks(TEXELS_PER_BLOCK) {
            let mut b = zero_block();
            for (k, texel) in chunk.iter().enumerate() {
                b[3 * k..3 * k + 3].copy_from_slice(texel);
            }
            texels.push(b);
        }
    }
    let element_base = texture_base + texels.len() as u32;
    let vertex_base = element_base + mesh.elements.len().div_ceil(ELEMENTS_PER_BLOCK) as u32;
    let vertex_blocks = mesh.vertex_positions.len().div_ceil(VERTICES_PER_BLOCK).max(1) as u32;
    let total = vertex_base + vertex_blocks;
    let layout = BlockLayout { bvh_base, patch_base, shading_base, texture_base, element_base, vertex_base, total };
    blocks.resize_with(texture_base as usize, zero_block);
    blocks.append(&mut texels);
    blocks.resize_with(total as usize, zero_block);
    // The shares' records: disjoint, so OR-ed together.
    for partial in records(&layout)? {
        for (id, part) in partial {
            if let Some(b) = blocks.get_mut(id as usize) {
                for (x, y) in b.iter_mut().zip(part.iter()) {
                    *x |= *y;
                }
            }
        }
    }
    // Refinement's elements: the split ones (with their children) and the children.
    for (id, e) in mesh.elements.iter().enumerate().filter(|(_, e)| e.child != 0 || e.parent != NO_PARENT) {
        let id = id as u32;
        let p = e.patch as usize;
        let local = if e.parent != NO_PARENT {
            REFINED | e.parent
        } else if e.face == Face::Back {
            id - mesh.back_element[p] + mesh.subdivisions[p] * mesh.subdivisions[p]
        } else {
            id - mesh.first_element[p]
        };
        let (b, off) = layout.element_slot(id);
        ElementRecord { patch: e.patch, local, vertices: e.vertices, child: e.child, area: e.area }
            .encode(&mut blocks[b as usize], off);
    }
    let counts = Counts {
        patches: mesh.patches.len() as u32,
        elements: mesh.elements.len() as u32,
        vertices: mesh.vertex_positions.len() as u32,
        subspaces: grid.cells.len() as u32,
        subspace_blocks,
        bvh_blocks: patch_base - bvh_base,
        patch_blocks: shading_base - patch_base,
        shaded_patches: mesh.shaded,
        shading_blocks: texture_base - shading_base,
        texture_blocks: element_base - texture_base,
        element_blocks: vertex_base - element_base,
        vertex_blocks,
    };
    Ok(Packed {
        blocks,
        layout,
        grid: GridHeader { min: grid.min, max: grid.max, dims: grid.dims, cell_first_block },
        bvh: bvh_header,
        counts,
        textures: texture_headers,
    })
}
