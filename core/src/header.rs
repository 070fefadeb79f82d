//! The resident part of a prepared scene: what the paper's forks send to every node once
//! and never expire (lights, materials, camera, settings, grid and BVH headers, block
//! layout).

use crate::blocks::BlockLayout;
use crate::color::Rgb;
use crate::plan::EffectsPlan;
use crate::scene::{Camera, Light, Material, RenderSettings};
use glam::{DVec3, UVec3};

/// The uniform grid of subspaces.
#[derive(Clone, Debug, PartialEq)]
pub struct GridHeader {
    /// Lower corner of the grid.
    pub min: DVec3,
    /// Upper corner of the grid.
    pub max: DVec3,
    /// Subspaces along x, y, z.
    pub dims: [u32; 3],
    /// First subspace block of each cell (x fastest, then y, then z), or `NO_BLOCK` when
    /// the subspace is empty.
    pub cell_first_block: Vec<u32>,
}

impl GridHeader {
    /// Size of one subspace.
    pub fn cell_size(&self) -> DVec3 {
        (self.max - self.min) / UVec3::from_array(self.dims).as_dvec3()
    }
    /// Number of subspaces.
    pub fn cells(&self) -> usize {
        self.dims.iter().map(|&d| d as usize).product()
    }
    /// Linear index of cell (x, y, z).
    pub fn cell_index(&self, c: [u32; 3]) -> usize {
        (c[2] as usize * self.dims[1] as usize + c[1] as usize) * self.dims[0] as usize + c[0] as usize
    }
}

/// Where the bounding volume hierarchy lies in the BVH blocks ([`crate::blocks::bvh`]):
/// `node_blocks` node blocks from `layout.bvh_base` (the root is node 0), then the leaf
/// triangle blocks. All zero for a scene traced through the grid.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct BvhHeader {
    /// Node records (the last node block may be partly used).
    pub nodes: u32,
    /// Blocks of node records.
    pub node_blocks: u32,
    /// Leaf triangle records (one per patch of non-zero area).
    pub triangles: u32,
    /// Blocks of leaf triangle records.
    pub triangle_blocks: u32,
}

/// Where a texture's texels lie: `width * height` sRGB texels, row by row from the top,
/// from texture block `first_block` (counted from `layout.texture_base`) on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct TextureHeader {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Its first texture block, counted from the first texture block of the scene.
    pub first_block: u32,
}

impl TextureHeader {
    /// Texture blocks its texels fill.
    pub fn blocks(&self) -> u32 {
        (self.width as usize * self.height as usize).div_ceil(crate::blocks::TEXELS_PER_BLOCK) as u32
    }
}

/// Counts of scene entities.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Counts {
    /// Triangle patches.
    pub patches: u32,
    /// Triangle elements.
    pub elements: u32,
    /// Welded element vertices.
    pub vertices: u32,
    /// Subspaces (grid cells).
    pub subspaces: u32,
    /// Blocks of patch-id lists.
    pub subspace_blocks: u32,
    /// Blocks of BVH nodes and leaf triangles.
    pub bvh_blocks: u32,
    /// Blocks of patch records.
    pub patch_blocks: u32,
    /// Patches shaded with normals (each has a shading record).
    pub shaded_patches: u32,
    /// Blocks of shading records.
    pub shading_blocks: u32,
    /// Blocks of texels.
    pub texture_blocks: u32,
    /// Blocks of element records.
    pub element_blocks: u32,
    /// Blocks of vertex energies.
    pub vertex_blocks: u32,
}

/// An element of an emitting material (`emit`): one light source of LRT. Its patch's
/// front radiates `emit` in every direction of its hemisphere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Emitter {
    /// The element.
    pub element: u32,
    /// Flux it emits, W per channel: `pi * emit * area` (a one-sided Lambertian
    /// emitter). Bounds what its pairs may deposit and sizes the energy quantum.
    pub power: Rgb,
}

/// Everything a node keeps resident for the whole render.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneHeader {
    /// The camera.
    pub camera: Camera,
    /// Render settings.
    pub settings: RenderSettings,
    /// Point lights.
    pub lights: Vec<Light>,
    /// Emitting elements (area lights), ascending by element: LRT's light sources after
    /// the point lights, light index `lights.len() + k` being `emitters[k]`.
    pub emitters: Vec<Emitter>,
    /// Materials.
    pub materials: Vec<Material>,
    /// Diffuse textures (their texels are in texture blocks).
    pub textures: Vec<TextureHeader>,
    /// The subspace grid (with `settings.accel` BVH: the scene's bounds, one empty
    /// subspace).
    pub grid: GridHeader,
    /// The bounding volume hierarchy (with `settings.accel` grid: all zero).
    pub bvh: BvhHeader,
    /// Where each kind of block starts.
    pub layout: BlockLayout,
    /// Entity and block counts.
    pub counts: Counts,
    /// Flux of one unit of the fixed-point energy sums, W (see [`crate::energy`]).
    pub energy_quantum: f64,
    /// Which passes run.
    pub plan: EffectsPlan,
}

impl SceneHeader {
    /// LRT's light sources: the point lights, then the emitting elements. Pairs are
    /// numbered over them light-major ([`crate::pair::Pair::id`]).
    pub fn light_sources(&self) -> u32 {
        (self.lights.len() + self.emitters.len()) as u32
    }

    /// Pairs of the light pass: every light source with every element.
    pub fn pair_count(&self) -> u64 {
        self.light_sources() as u64 * self.counts.elements as u64
    }
}
