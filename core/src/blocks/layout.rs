//! Byte layout of the four block kinds. Little-endian, fixed-size records.

use crate::color::Rgb;
use glam::DVec3;

/// Bytes per block (paper §4.3: "packed in 2KB blocks").
pub const BLOCK_SIZE: usize = 2048;
/// One block of scene data.
pub type Block = [u8; BLOCK_SIZE];
/// Marks "no block" (an empty subspace, the end of a chain).
pub const NO_BLOCK: u32 = u32::MAX;

/// Bytes of one patch record: 3 corners (9 x f64), material, subdivisions, first element.
pub const PATCH_RECORD: usize = 96;
/// Patch records per block.
pub const PATCHES_PER_BLOCK: usize = BLOCK_SIZE / PATCH_RECORD;
/// Bytes of one shading record: the unit shading normals of a patch's 3 corners (9 x
/// f32), their texture coordinates (6 x f32) and the texture (u32).
pub const SHADING_RECORD: usize = 64;
/// Shading records per block.
pub const SHADINGS_PER_BLOCK: usize = BLOCK_SIZE / SHADING_RECORD;
/// A patch record's `shading` when the patch has no shading record (shaded flat).
pub const NO_SHADING: u32 = u32::MAX;
/// A shading record's `texture` when the patch has none.
pub const NO_TEXTURE: u32 = u32::MAX;
/// sRGB texels (3 bytes each) per texture block.
pub const TEXELS_PER_BLOCK: usize = BLOCK_SIZE / 3;
/// Bytes of one element record: patch, local index, 3 vertex ids, area.
pub const ELEMENT_RECORD: usize = 32;
/// Element records per block.
pub const ELEMENTS_PER_BLOCK: usize = BLOCK_SIZE / ELEMENT_RECORD;
/// Bytes of one vertex-energy record: irradiance RGB as 3 x f32.
pub const VERTEX_RECORD: usize = 12;
/// Vertex-energy records per block.
pub const VERTICES_PER_BLOCK: usize = BLOCK_SIZE / VERTEX_RECORD;
/// Header of a subspace block: entry count, next block of the chain.
pub const SUBSPACE_HEADER: usize = 8;
/// Patch ids per subspace block.
pub const SUBSPACE_IDS_PER_BLOCK: usize = (BLOCK_SIZE - SUBSPACE_HEADER) / 4;

/// The kind of a block, derived from its id and the scene's [`BlockLayout`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BlockKind {
    /// Patch-id list of a subspace.
    Subspace,
    /// Nodes or leaf triangles of the bounding volume hierarchy ([`super::bvh`]).
    Bvh,
    /// Patch records.
    Patch,
    /// Shading normals and texture coordinates of the patches that have them.
    Shading,
    /// Texels of diffuse textures.
    Texture,
    /// Element records.
    Element,
    /// Vertex irradiance records.
    VertexEnergy,
}

/// Where each kind of block starts in the global id space:
/// `[subspace blocks][BVH blocks][patch blocks][shading blocks][texture blocks][element
/// blocks][vertex-energy blocks]`. A scene traced through the grid has no BVH block, one
/// traced through the BVH no subspace block, one shaded flat no shading block, one without
/// textures no texture block.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct BlockLayout {
    /// First BVH block (the subspace blocks are those before it).
    pub bvh_base: u32,
    /// First patch block.
    pub patch_base: u32,
    /// First shading block (the patch blocks are those before it).
    pub shading_base: u32,
    /// First texture block.
    pub texture_base: u32,
    /// First element block.
    pub element_base: u32,
    /// First vertex-energy block.
    pub vertex_base: u32,
    /// Total number of blocks.
    pub total: u32,
}

impl BlockLayout {
    /// Kind of block `id`, `None` when out of range.
    pub fn kind(&self, id: u32) -> Option<BlockKind> {
        if id >= self.total {
            None
        } else if id >= self.vertex_base {
            Some(BlockKind::VertexEnergy)
        } else if id >= self.element_base {
            Some(BlockKind::Element)
        } else if id >= self.texture_base {
            Some(BlockKind::Texture)
        } else if id >= self.shading_base {
            Some(BlockKind::Shading)
        } else if id >= self.patch_base {
            Some(BlockKind::Patch)
        } else if id >= self.bvh_base {
            Some(BlockKind::Bvh)
        } else {
            Some(BlockKind::Subspace)
        }
    }
    /// Block and byte offset of patch `p`.
    pub fn patch_slot(&self, p: u32) -> (u32, usize) {
        let p = p as usize;
        (self.patch_base + (p / PATCHES_PER_BLOCK) as u32, (p % PATCHES_PER_BLOCK) * PATCH_RECORD)
    }
    /// Block and byte offset of shading record `s`.
    pub fn shading_slot(&self, s: u32) -> (u32, usize) {
        let s = s as usize;
        (self.shading_base + (s / SHADINGS_PER_BLOCK) as u32, (s % SHADINGS_PER_BLOCK) * SHADING_RECORD)
    }
    /// Block and byte offset of element `e`.
    pub fn element_slot(&self, e: u32) -> (u32, usize) {
        let e = e as usize;
        (self.element_base + (e / ELEMENTS_PER_BLOCK) as u32, (e % ELEMENTS_PER_BLOCK) * ELEMENT_RECORD)
    }
    /// Block and byte offset of vertex `v`.
    pub fn vertex_slot(&self, v: u32) -> (u32, usize) {
        let v = v as usize;
        (self.vertex_base + (v / VERTICES_PER_BLOCK) as u32, (v % VERTICES_PER_BLOCK) * VERTEX_RECORD)
    }
    /// Number of vertex-energy blocks.
    pub fn vertex_blocks(&self) -> u32 {
        self.total - self.vertex_base
    }
}

/// A triangle patch as stored in a patch block.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PatchRecord {
    /// Corners.
    pub v: [DVec3; 3],
    /// Material index.
    pub material: u32,
    /// Subdivision count n (n*n elements).
    pub subdivisions: u32,
    /// Id of the patch's first element; its elements are consecutive.
    pub first_element: u32,
    /// Its shading record ([`ShadingRecord`]), or [`NO_SHADING`] when shaded flat.
    pub shading: u32,
    /// Id of the first of its back elements (consecutive, after every front element of
    /// the scene), or [`NO_BACK`] when its material keeps no back face
    /// ([`crate::scene::Material::has_back_face`]).
    pub back_element: u32,
}

/// Marks a patch without back elements.
pub const NO_BACK: u32 = u32::MAX;

impl PatchRecord {
    /// The element holding local element `local` (from [`crate::subdivision::locate`])
    /// on the face that light or a viewing ray travelling along `d` arrives on: a back
    /// element when it arrives on the back of a patch that keeps its back face apart, the
    /// front element otherwise.
    #[inline]
    pub fn element_on_face(&self, local: u32, d: DVec3) -> u32 {
        if self.back_element != NO_BACK && self.arrives_on_back(d) {
            self.back_element + local
        } else {
            self.first_element + local
        }
    }
    /// True when light travelling along `d` arrives on the face of which element
    /// record `e` (of this patch) is part: always, unless the patch keeps a back face
    /// and `d` arrives on the other one.
    #[inline]
    pub fn receives_on(&self, e: &ElementRecord, d: DVec3) -> bool {
        self.back_element == NO_BACK || self.arrives_on_back(d) == e.is_back(self.subdivisions)
    }
    /// True when light travelling along `d` arrives on the back of the patch (the side
    /// its winding's normal points away from).
    #[inline]
    fn arrives_on_back(&self, d: DVec3) -> bool {
        d.dot(crate::geometry::triangle_normal(&self.v)) > 0.0
    }
}

/// How a patch is shaded, as stored in a shading block: one unit normal per corner, on
/// the front of the patch's plane (all zero: flat), and texture coordinates per corner
/// for its texture. Kept as `f32` (their rounding, about 6e-8, is far below what shading
/// can show) so that 32 fit in a block.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadingRecord {
    /// Normals at the corners, in the patch's corner order; zero for a flat patch.
    pub normals: [DVec3; 3],
    /// Texture coordinates at the corners.
    pub uv: [glam::DVec2; 3],
    /// Index of the texture in the scene header, or [`NO_TEXTURE`].
    pub texture: u32,
}

/// An element as stored in an element block.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ElementRecord {
    /// Owning patch.
    pub patch: u32,
    /// Index within the patch's regular subdivision, plus n*n for a back element; for
    /// an element made by refinement, [`REFINED`] plus its parent's id.
    pub local: u32,
    /// Global (welded) vertex ids.
    pub vertices: [u32; 3],
    /// First of its four children when refinement split it, 0 for a leaf (children come
    /// after every element of the patch lattices, so no child has id 0).
    pub child: u32,
    /// Area.
    pub area: f64,
}

/// Marks [`ElementRecord::local`] of an element made by refinement (its parent's id in
/// the other bits; element ids stay below 2^31).
pub const REFINED: u32 = 1 << 31;

pub(super) fn put_u32(b: &mut [u8], at: usize, v: u32) {
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
}
pub(super) fn put_f64(b: &mut [u8], at: usize, v: f64) {
    b[at..at + 8].copy_from_slice(&v.to_le_bytes());
}
pub(super) fn get_u32(b: &[u8], at: usize) -> u32 {
    let mut a = [0u8; 4];
    a.copy_from_slice(&b[at..at + 4]);
    u32::from_le_bytes(a)
}
pub(super) fn get_f64(b: &[u8], at: usize) -> f64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[at..at + 8]);
    f64::from_le_bytes(a)
}
/// Writes three corners (9 x f64, 72 bytes) at byte offset `at`.
pub(super) fn put_corners(b: &mut [u8], at: usize, v: &[DVec3; 3]) {
    for (i, p) in v.iter().enumerate() {
        put_f64(b, at + 24 * i, p.x);
        put_f64(b, at + 24 * i + 8, p.y);
        put_f64(b, at + 24 * i + 16, p.z);
    }
}
/// Reads three corners written by [`put_corners`].
#[inline]
pub(super) fn get_corners(b: &[u8], at: usize) -> [DVec3; 3] {
    let p = |i: usize| DVec3::new(get_f64(b, at + 24 * i), get_f64(b, at + 24 * i + 8), get_f64(b, at + 24 * i + 16));
    [p(0), p(1), p(2)]
}
pub(super) fn get_f32(b: &[u8], at: usize) -> f32 {
    let mut a = [0u8; 4];
    a.copy_from_slice(&b[at..at + 4]);
    f32::from_le_bytes(a)
}

impl PatchRecord {
    /// Writes the record at byte offset `at`.
    pub fn encode(&self, b: &mut Block, at: usize) {
        put_corners(b, at, &self.v);
        put_u32(b, at + 72, self.material);
        put_u32(b, at + 76, self.subdivisions);
        put_u32(b, at + 80, self.first_element);
        put_u32(b, at + 84, self.shading);
        put_u32(b, at + 88, self.back_element);
    }
    /// Reads the record at byte offset `at`.
    pub fn decode(b: &Block, at: usize) -> PatchRecord {
        PatchRecord {
            v: get_corners(b, at),
            material: get_u32(b, at + 72),
            subdivisions: get_u32(b, at + 76),
            first_element: get_u32(b, at + 80),
            shading: get_u32(b, at + 84),
            back_element: get_u32(b, at + 88),
        }
    }
}

impl ShadingRecord {
    /// Writes the record at byte offset `at` (each component rounded to `f32`).
    pub fn encode(&self, b: &mut Block, at: usize) {
        let normals = self.normals.iter().flat_map(|n| n.to_array());
        let uv = self.uv.iter().flat_map(|t| t.to_array());
        for (k, c) in normals.chain(uv).enumerate() {
            b[at + 4 * k..at + 4 * k + 4].copy_from_slice(&(c as f32).to_le_bytes());
        }
        put_u32(b, at + 60, self.texture);
    }
    /// Reads the record at byte offset `at`.
    pub fn decode(b: &Block, at: usize) -> ShadingRecord {
        let c = |k: usize| f64::from(get_f32(b, at + 4 * k));
        let n = |i: usize| DVec3::new(c(3 * i), c(3 * i + 1), c(3 * i + 2));
        let t = |i: usize| glam::DVec2::new(c(9 + 2 * i), c(10 + 2 * i));
        ShadingRecord { normals: [n(0), n(1), n(2)], uv: [t(0), t(1), t(2)], texture: get_u32(b, at + 60) }
    }
}

impl ElementRecord {
    /// The element it was split from, for an element made by refinement.
    #[inline]
    pub fn parent(&self) -> Option<u32> {
        (self.local & REFINED != 0).then_some(self.local & !REFINED)
    }
    /// True for a back element of a patch subdivided `n` times.
    #[inline]
    pub fn is_back(&self, n: u32) -> bool {
        self.local as u64 >= crate::subdivision::element_count(n)
    }
    /// Its index in the patch's regular subdivision (the same for a front element and
    /// the back element behind it), for a patch subdivided `n` times.
    #[inline]
    pub fn lattice_local(&self, n: u32) -> u32 {
        let count = crate::subdivision::element_count(n);
        if self.local as u64 >= count {
            (self.local as u64 - count) as u32
        } else {
            self.local
        }
    }
    /// Writes the record at byte offset `at`.
    pub fn encode(&self, b: &mut Block, at: usize) {
        put_u32(b, at, self.patch);
        put_u32(b, at + 4, self.local);
        for i in 0..3 {
            put_u32(b, at + 8 + 4 * i, self.vertices[i]);
        }
        put_u32(b, at + 20, self.child);
        put_f64(b, at + 24, self.area);
    }
    /// Reads the record at byte offset `at`.
    pub fn decode(b: &Block, at: usize) -> ElementRecord {
        ElementRecord {
            patch: get_u32(b, at),
            local: get_u32(b, at + 4),
            vertices: [get_u32(b, at + 8), get_u32(b, at + 12), get_u32(b, at + 16)],
            child: get_u32(b, at + 20),
            area: get_f64(b, at + 24),
        }
    }
}

/// Writes a vertex irradiance at byte offset `at` (stored as f32).
pub fn encode_vertex_energy(b: &mut Block, at: usize, e: Rgb, gather: bool) {
    for i in 0..3 {
        // Irradiance is never negative: the first channel's sign bit carries the mark
        // (-0.0 for a zero).
        let v = (e.0[i] as f32).abs();
        let v = if i == 0 && gather { -v } else { v };
        b[at + 4 * i..at + 4 * i + 4].copy_from_slice(&v.to_le_bytes());
    }
}

/// Reads a vertex irradiance at byte offset `at`.
pub fn decode_vertex_energy(b: &Block, at: usize) -> Rgb {
    Rgb([get_f32(b, at).abs() as f64, get_f32(b, at + 4) as f64, get_f32(b, at + 8) as f64])
}

/// Whether the vertex record at byte offset `at` is marked for gathering
/// ([`crate::energy::gather_vertices`]).
pub fn decode_vertex_gather(b: &Block, at: usize) -> bool {
    get_f32(b, at).is_sign_negative()
}

/// Writes the header of a subspace block: number of ids in it, next block of the chain.
pub fn encode_subspace_header(b: &mut Block, count: u32, next: u32) {
    put_u32(b, 0, count);
    put_u32(b, 4, next);
}

/// Reads a subspace block: appends its patch ids to `out` and returns the next block of
/// the chain (or [`NO_BLOCK`]). A corrupt count is clamped to the block's capacity.
pub fn decode_subspace(b: &Block, out: &mut Vec<u32>) -> u32 {
    let count = (get_u32(b, 0) as usize).min(SUBSPACE_IDS_PER_BLOCK);
    out.extend((0..count).map(|i| get_u32(b, SUBSPACE_HEADER + 4 * i)));
    get_u32(b, 4)
}

/// Writes patch id number `i` of a subspace block.
pub fn encode_subspace_id(b: &mut Block, i: usize, id: u32) {
    put_u32(b, SUBSPACE_HEADER + 4 * i, id);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_round_trip() {
        let mut b = [0u8; BLOCK_SIZE];
        let p = PatchRecord {
            v: [DVec3::new(1.0, 2.0, 3.0), DVec3::new(-4.0, 5.5, 6.0), DVec3::new(1e5, 0.1, -0.0)],
            material: 7,
            subdivisions: 20,
            first_element: 12345,
            shading: 6,
            back_element: 99999,
        };
        p.encode(&mut b, PATCH_RECORD * (PATCHES_PER_BLOCK - 1));
        assert_eq!(PatchRecord::decode(&b, PATCH_RECORD * (PATCHES_PER_BLOCK - 1)), p);
        let uv = [glam::DVec2::new(0.0, 1.0), glam::DVec2::new(0.5, 0.25), glam::DVec2::new(-2.0, 3.0)];
        let normals = [DVec3::Z, DVec3::new(0.6, 0.0, 0.8), DVec3::new(0.0, -0.5, 0.75)];
        let s = ShadingRecord { normals, uv, texture: 3 };
        s.encode(&mut b, SHADING_RECORD * (SHADINGS_PER_BLOCK - 1));
        let back = ShadingRecord::decode(&b, SHADING_RECORD * (SHADINGS_PER_BLOCK - 1));
        for (a, b) in back.normals.iter().zip(&s.normals) {
            assert!((*a - *b).length() < 1e-7);
        }
        assert_eq!((back.uv, back.texture), (uv, 3));
        let e = ElementRecord { patch: 3, local: 9, vertices: [1, 2, 3], child: 77, area: 0.25 };
        e.encode(&mut b, 0);
        assert_eq!(ElementRecord::decode(&b, 0), e);
        encode_vertex_energy(&mut b, 24, Rgb::new(1.5, 2.0, 0.25), false);
        assert_eq!(decode_vertex_energy(&b, 24), Rgb::new(1.5, 2.0, 0.25));
        assert!(!decode_vertex_gather(&b, 24));
        // The gather mark rides on the first channel's sign, zero included.
        for e in [Rgb::new(1.5, 2.0, 0.25), Rgb::BLACK] {
            encode_vertex_energy(&mut b, 36, e, true);
            assert_eq!(decode_vertex_energy(&b, 36), e);
            assert!(decode_vertex_gather(&b, 36));
        }
    }

    #[test]
    fn records_fit_in_a_block() {
        assert!(PATCHES_PER_BLOCK * PATCH_RECORD <= BLOCK_SIZE);
        assert!(ELEMENTS_PER_BLOCK * ELEMENT_RECORD <= BLOCK_SIZE);
        assert!(VERTICES_PER_BLOCK * VERTEX_RECORD <= BLOCK_SIZE);
        assert_eq!(SUBSPACE_IDS_PER_BLOCK, 510);
    }
}
