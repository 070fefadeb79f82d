//! Fingerprints of everything a light pass depends on, so that saved energies are reused
//! only for the scene and settings they were computed for.
//!
//! The element energies of LRT depend on the geometry after preprocessing (patches,
//! elements, welded vertices, subspace grid: every block except the vertex-energy blocks),
//! the materials, the lights and the light-pass settings (light rays, element size,
//! specular depth, diffuse bounces, seed). They do not depend on the camera, the image
//! size, the pixel samples, the viewing depth or the ambient term, which is what lets one
//! light pass serve many views (paper §3: the light pass is view-independent).
//!
//! The hash is 64-bit FNV-1a over a fixed little-endian encoding: stable across runs,
//! machines and builds, and enough to tell a stale file from a matching one (it is not a
//! defence against a forged file).
//!
//! ```
//! # use magg_core::fingerprint::Fnv64;
//! let mut h = Fnv64::new();
//! h.bytes(b"magg");
//! assert_ne!(h.finish(), Fnv64::new().finish());
//! ```

use crate::blocks::BlockKind;
use crate::color::Rgb;
use crate::prepared::PreparedScene;
use glam::DVec3;
use serde::{Deserialize, Serialize};

/// 64-bit FNV-1a, fed with explicit little-endian encodings.
#[derive(Clone, Copy, Debug)]
pub struct Fnv64(u64);

impl Default for Fnv64 {
    fn default() -> Self {
        Fnv64::new()
    }
}

impl Fnv64 {
    /// The empty hash (FNV offset basis).
    pub fn new() -> Self {
        Fnv64(0xcbf2_9ce4_8422_2325)
    }
    /// Feeds bytes.
    pub fn bytes(&mut self, b: &[u8]) {
        for &x in b {
            self.0 = (self.0 ^ x as u64).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    /// Feeds a u32.
    pub fn u32(&mut self, v: u32) {
        self.bytes(&v.to_le_bytes());
    }
    /// Feeds a u64.
    pub fn u64(&mut self, v: u64) {
        self.bytes(&v.to_le_bytes());
    }
    /// Feeds an f64 by its bits.
    pub fn f64(&mut self, v: f64) {
        self.u64(v.to_bits());
    }
    /// Feeds a point or direction.
    pub fn vec3(&mut self, v: DVec3) {
        for c in [v.x, v.y, v.z] {
            self.f64(c);
        }
    }
    /// Feeds a colour.
    pub fn rgb(&mut self, c: Rgb) {
        for x in c.0 {
            self.f64(x);
        }
    }
    /// Feeds a string (length first, so that concatenations differ).
    pub fn str(&mut self, s: &str) {
        self.u64(s.len() as u64);
        self.bytes(s.as_bytes());
    }
    /// The hash.
    pub fn finish(&self) -> u64 {
        self.0
    }
}

/// [`EnergyInputs::bounce_rays`] of files from before it: one bounce ray per light ray.
fn one() -> u32 {
    1
}

/// What the energies of a light pass depend on: component hashes and the settings in
/// clear, so that a mismatch can be explained field by field.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EnergyInputs {
    /// Hash of the prepared geometry: every non-vertex-energy block, the grid header,
    /// the element table.
    pub geometry: u64,
    /// Hash of the materials.
    pub materials: u64,
    /// Hash of the lights.
    pub lights: u64,
    /// Light rays per pair.
    pub light_rays: u32,
    /// Diffuse bounce rays per light ray of a bounce-only pair. Absent (1) in files from
    /// before the setting existed.
    #[serde(default = "one")]
    pub bounce_rays: u32,
    /// Target element edge length.
    pub element_size: f64,
    /// Specular bounces of light rays.
    pub lrt_depth: u32,
    /// Diffuse-to-diffuse bounces.
    pub diffuse_bounces: u32,
    /// Seed of the light rays.
    pub seed: u64,
    /// Element count.
    pub elements: u32,
    /// Welded vertex count.
    pub vertices: u32,
    /// Direct light is left to VRT: the energies hold only light via specular surfaces
    /// and diffuse bounces. Absent (false) in files from before the choice existed.
    #[serde(default)]
    pub direct_vrt: bool,
    /// Hash of all of the above: equal digests mean reusable energies.
    pub digest: u64,
}

impl EnergyInputs {
    /// The inputs of `prepared`'s light pass.
    pub fn of(prepared: &PreparedScene) -> EnergyInputs {
        let h = &prepared.header;
        let mut g = Fnv64::new();
        for (id, block) in prepared.blocks.iter().enumerate() {
            if h.layout.kind(id as u32) != Some(BlockKind::VertexEnergy) {
                g.bytes(&block[..]);
            }
        }
        g.vec3(h.grid.min);
        g.vec3(h.grid.max);
        for d in h.grid.dims {
            g.u32(d);
        }
        for &b in &h.grid.cell_first_block {
            g.u32(b);
        }
        for e in &prepared.elements {
            g.u32(e.patch);
            for v in e.vertices {
                g.u32(v);
            }
            g.f64(e.area);
        }
        let mut m = Fnv64::new();
        for mat in &h.materials {
            m.str(&mat.name);
            m.rgb(mat.diffuse);
            m.rgb(mat.mirror);
            m.rgb(mat.transmit);
            m.f64(mat.ior);
            if mat.one_sided {
                m.str("one-sided");
            }
            if mat.is_emitter() {
                // Only emitters hash it, so other scenes keep their fingerprints.
                m.str("emit");
                m.rgb(mat.emit);
            }
        }
        let mut l = Fnv64::new();
        for light in &h.lights {
            l.vec3(light.position);
            l.rgb(light.intensity);
            match &light.spot {
                None => l.u32(0),
                Some(s) => {
                    l.u32(1);
                    l.vec3(s.direction);
                    l.f64(s.half_angle_deg);
                    l.f64(s.falloff_deg);
                }
            }
        }
        let s = &h.settings;
        let inputs = EnergyInputs {
            geometry: g.finish(),
            materials: m.finish(),
            lights: l.finish(),
            light_rays: s.light_rays,
            // Only pairs traced for their bounce alone use it: elsewhere it changes nothing.
            bounce_rays: if h.plan.splits_bounces() { s.bounce_rays } else { 1 },
            element_size: s.element_size,
            lrt_depth: s.lrt_depth,
            diffuse_bounces: s.diffuse_bounces,
            seed: s.seed,
            elements: h.counts.elements,
            vertices: h.counts.vertices,
            direct_vrt: h.plan.direct_vrt,
            digest: 0,
        };
        inputs.sealed()
    }

    /// `self` with `digest` set from the other fields.
    pub fn sealed(mut self) -> EnergyInputs {
        self.digest = self.compute_digest();
        self
    }

    /// The hash of every field but `digest`.
    fn compute_digest(&self) -> u64 {
        let mut d = Fnv64::new();
        d.bytes(b"magg energy inputs v1");
        for v in [self.geometry, self.materials, self.lights, self.seed] {
            d.u64(v);
        }
        for v in [self.light_rays, self.lrt_depth, self.diffuse_bounces, self.elements, self.vertices] {
            d.u32(v);
        }
        d.f64(self.element_size);
        // Only when set, so that the digests of earlier files stay valid.
        if self.direct_vrt {
            d.bytes(b"direct light at VRT");
        }
        if self.bounce_rays != 1 {
            d.bytes(b"bounce rays");
            d.u32(self.bounce_rays);
        }
        d.finish()
    }

    /// True when `self` (from a file) says it holds its own digest and matches `now`.
    pub fn matches(&self, now: &EnergyInputs) -> bool {
        self.digest == now.digest && self.compute_digest() == self.digest
    }

    /// What differs between `self` (the saved inputs) and `now`, one phrase per field,
    /// e.g. `light_rays 16 (file) vs 32 (now)`; empty when nothing a person can name does.
    pub fn differences(&self, now: &EnergyInputs) -> Vec<String> {
        let mut out = Vec::new();
        let mut hashed = |name: &str, a: u64, b: u64| {
            if a != b {
                out.push(format!("{name} differ"));
            }
        };
        hashed("lights", self.lights, now.lights);
        hashed("materials", self.materials, now.materials);
        hashed("geometry (patches, elements or subspace grid)", self.geometry, now.geometry);
        let mut setting = |name: &str, a: String, b: String| {
            if a != b {
                out.push(format!("{name} {a} (file) vs {b} (now)"));
            }
        };
        setting("light_rays", self.light_rays.to_string(), now.light_rays.to_string());
        setting("bounce_rays", self.bounce_rays.to_string(), now.bounce_rays.to_string());
        setting("element_size", self.element_size.to_string(), now.element_size.to_string());
        setting("lrt_depth", self.lrt_depth.to_string(), now.lrt_depth.to_string());
        setting("diffuse_bounces", self.diffuse_bounces.to_string(), now.diffuse_bounces.to_string());
        setting("seed", self.seed.to_string(), now.seed.to_string());
        setting("elements", self.elements.to_string(), now.elements.to_string());
        setting("vertices", self.vertices.to_string(), now.vertices.to_string());
        let direct = |vrt: bool| if vrt { "vrt" } else { "lrt" }.to_string();
        setting("direct light", direct(self.direct_vrt), direct(now.direct_vrt));
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv_matches_the_reference_vectors() {
        // FNV-1a 64 test vectors (Fowler, Noll, Vo).
        let hash = |s: &[u8]| {
            let mut h = Fnv64::new();
            h.bytes(s);
            h.finish()
        };
        assert_eq!(hash(b""), 0xcbf29ce484222325);
        assert_eq!(hash(b"a"), 0xaf63dc4c8601ec8c);
        assert_eq!(hash(b"foobar"), 0x85944171f73967e8);
    }

    /// Inputs of a small made-up light pass.
    fn inputs() -> EnergyInputs {
        EnergyInputs {
            geometry: 1,
            materials: 2,
            lights: 3,
            light_rays: 16,
            bounce_rays: 1,
            element_size: 0.1,
            lrt_depth: 4,
            diffuse_bounces: 0,
            seed: 1,
            elements: 10,
            vertices: 12,
            direct_vrt: false,
            digest: 0,
        }
    }

    #[test]
    fn differences_name_the_setting() {
        let a = inputs();
        let mut b = a.clone();
        b.light_rays = 32;
        b.lights = 4;
        assert_eq!(a.differences(&b), ["lights differ", "light_rays 16 (file) vs 32 (now)"]);
        assert!(a.differences(&a).is_empty());
    }

    #[test]
    fn bounce_rays_change_the_digest_but_files_from_before_them_keep_theirs() {
        let a = EnergyInputs { diffuse_bounces: 1, direct_vrt: true, ..inputs() }.sealed();
        // A file written before the setting existed has no `bounce_rays`: it reads as 1,
        // and its digest is the one it was written with.
        let mut json = serde_json::to_value(&a).unwrap();
        json.as_object_mut().unwrap().remove("bounce_rays");
        let old: EnergyInputs = serde_json::from_value(json).unwrap();
        assert_eq!(old, a);
        let eight = EnergyInputs { bounce_rays: 8, ..a.clone() }.sealed();
        assert_ne!(eight.digest, a.digest);
        assert_eq!(a.differences(&eight), ["bounce_rays 1 (file) vs 8 (now)"]);
    }
}
