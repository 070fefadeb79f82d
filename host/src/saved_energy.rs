//! Saved energies (`--save-energy FILE`, `--load-energy FILE`): the element and vertex
//! energies of a light pass, with the fingerprint of everything they depend on, so that a
//! later render of the same scene and light settings skips LRT, whatever its camera.
//!
//! Layout (little-endian): the magic `MAGGNRG1`; a u32 length and that many bytes of JSON
//! (scene label, [`EnergyInputs`]); u32 element and vertex counts; the element fluxes as
//! 3 x i64 fixed-point sums per element; the vertex irradiances as 3 x f64 per vertex;
//! a u64 FNV-1a checksum of everything before it. Both tables are stored exactly, so a
//! render from a loaded file is bitwise identical to the render that saved it.

use anyhow::{bail, Context};
use magg_core::color::Rgb;
use magg_core::fingerprint::{EnergyInputs, Fnv64};
use magg_core::machine::Energies;
use serde::{Deserialize, Serialize};
use std::path::Path;

const MAGIC: &[u8; 8] = b"MAGGNRG1";
/// Longest JSON header accepted.
const MAX_HEADER: usize = 1 << 20;

/// The JSON header of the file.
#[derive(Debug, Serialize, Deserialize)]
struct FileHeader {
    /// Scene the energies were computed for (for people; the fingerprint decides).
    scene: String,
    /// What they depend on.
    inputs: EnergyInputs,
}

/// Encodes energies and their inputs.
pub fn encode(scene: &str, inputs: &EnergyInputs, e: &Energies) -> anyhow::Result<Vec<u8>> {
    let json = serde_json::to_vec(&FileHeader { scene: scene.to_string(), inputs: inputs.clone() })?;
    let mut out = Vec::with_capacity(32 + json.len() + e.element_flux.len() * 24 + e.vertex_irradiance.len() * 24);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&json);
    out.extend_from_slice(&(e.element_flux.len() as u32).to_le_bytes());
    out.extend_from_slice(&(e.vertex_irradiance.len() as u32).to_le_bytes());
    for f in &e.element_flux {
        for c in f {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    for v in &e.vertex_irradiance {
        for c in v.0 {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    let mut h = Fnv64::new();
    h.bytes(&out);
    out.extend_from_slice(&h.finish().to_le_bytes());
    Ok(out)
}

/// Reads little-endian fields off a byte slice, refusing to run past its end.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> anyhow::Result<&[u8]> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len());
        let Some(end) = end else { bail!("truncated at byte {} (wanted {n} more)", self.at) };
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn u32(&mut self) -> anyhow::Result<u32> {
        let b = self.take(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
    fn u64(&mut self) -> anyhow::Result<u64> {
        let b = self.take(8)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(u64::from_le_bytes(a))
    }
}

/// Decodes a file made by [`encode`] for a scene whose light pass has inputs `now`:
/// refuses, naming what differs, a file made for other inputs.
pub fn decode(path: &Path, bytes: &[u8], now: &EnergyInputs) -> anyhow::Result<Energies> {
    let name = path.display();
    if bytes.len() < MAGIC.len() + 8 || &bytes[..MAGIC.len()] != MAGIC {
        bail!("{name} is not a magg energy file (made by --save-energy)");
    }
    let (body, sum) = bytes.split_at(bytes.len() - 8);
    let mut h = Fnv64::new();
    h.bytes(body);
    let mut r = Reader { bytes: body, at: MAGIC.len() };
    let json_len = r.u32()? as usize;
    if json_len > MAX_HEADER {
        bail!("{name}: header of {json_len} bytes is too long");
    }
    let header: FileHeader =
        serde_json::from_slice(r.take(json_len)?).with_context(|| format!("{name}: unreadable header"))?;
    if !header.inputs.matches(now) {
        let diff = header.inputs.differences(now);
        let what = if diff.is_empty() { String::from("its fingerprint differs") } else { diff.join("; ") };
        bail!(
            "energy file {name} was made for a different scene or light settings ({}): {what}; \
             render without --load-energy (and --save-energy it again)",
            header.scene
        );
    }
    if u64::from_le_bytes(sum.try_into().unwrap_or([0; 8])) != h.finish() {
        bail!("{name} is damaged: its checksum does not match");
    }
    let (n_el, n_v) = (r.u32()? as usize, r.u32()? as usize);
    if n_el != now.elements as usize || n_v != now.vertices as usize {
        bail!("{name}: holds {n_el} elements and {n_v} vertices, the scene has {} and {}", now.elements, now.vertices);
    }
    let mut element_flux = Vec::with_capacity(n_el);
    for _ in 0..n_el {
        element_flux.push([r.u64()? as i64, r.u64()? as i64, r.u64()? as i64]);
    }
    let mut vertex_irradiance = Vec::with_capacity(n_v);
    for _ in 0..n_v {
        let c = [f64::from_bits(r.u64()?), f64::from_bits(r.u64()?), f64::from_bits(r.u64()?)];
        if c.iter().any(|x| !x.is_finite()) {
            bail!("{name}: vertex irradiance {c:?} is not finite");
        }
        vertex_irradiance.push(Rgb(c));
    }
    if r.at != body.len() {
        bail!("{name}: {} bytes after the energies", body.len() - r.at);
    }
    Ok(Energies { element_flux, vertex_irradiance })
}

/// Writes the file.
pub fn save(path: &Path, scene: &str, inputs: &EnergyInputs, e: &Energies) -> anyhow::Result<()> {
    let bytes = encode(scene, inputs, e)?;
    std::fs::write(path, bytes).with_context(|| format!("cannot write energy file {}", path.display()))
}

/// Reads the file, refusing one made for other inputs than `now`.
pub fn load(path: &Path, now: &EnergyInputs) -> anyhow::Result<Energies> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read energy file {}", path.display()))?;
    decode(path, &bytes, now)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn inputs(light_rays: u32) -> EnergyInputs {
        EnergyInputs {
            geometry: 1,
            materials: 2,
            lights: 3,
            light_rays,
            bounce_rays: 1,
            element_size: 0.1,
            lrt_depth: 4,
            diffuse_bounces: 0,
            seed: 1,
            elements: 2,
            vertices: 1,
            direct_vrt: false,
            digest: 0,
        }
        .sealed()
    }

    fn energies() -> Energies {
        Energies { element_flux: vec![[1, -2, i64::MAX], [4, 5, 6]], vertex_irradiance: vec![Rgb([0.5, 0.1, 1e-300])] }
    }

    #[test]
    fn round_trip_is_exact() {
        let bytes = encode("s", &inputs(16), &energies()).unwrap();
        assert_eq!(decode(Path::new("e.bin"), &bytes, &inputs(16)).unwrap(), energies());
    }

    #[test]
    fn stale_damaged_and_foreign_files_are_refused() {
        let p = Path::new("e.bin");
        let bytes = encode("s", &inputs(16), &energies()).unwrap();
        let e = decode(p, &bytes, &inputs(32)).unwrap_err().to_string();
        assert!(e.contains("energy file e.bin was made for a different scene"), "{e}");
        assert!(e.contains("light_rays 16 (file) vs 32 (now)"), "{e}");
        let mut damaged = bytes.clone();
        let n = damaged.len();
        damaged[n - 20] ^= 1;
        assert!(decode(p, &damaged, &inputs(16)).unwrap_err().to_string().contains("checksum"));
        assert!(decode(p, &bytes[..bytes.len() - 9], &inputs(16)).is_err());
        assert!(decode(p, b"not an energy file", &inputs(16)).unwrap_err().to_string().contains("not a magg energy"));
    }
}
