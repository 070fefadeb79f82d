//! The energy file: one row per element (id, patch, centroid, area, irradiance RGB) and
//! one per vertex (id, position, irradiance RGB). Values print in Rust's shortest
//! round-trip form, so equal energies give byte-identical files.

use magg_core::energy::element_irradiance;
use magg_core::math::Rgb;
use magg_core::preprocess::PreparedScene;
use std::io::Write;

/// Writes the energy CSV.
pub fn write(
    path: &std::path::Path,
    prepared: &PreparedScene,
    flux: &[[i64; 3]],
    vertex_irradiance: &[Rgb],
) -> anyhow::Result<()> {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(out, "kind,id,patch,x,y,z,area,r,g,b")?;
    let q = prepared.header.energy_quantum;
    for (i, (e, irr)) in prepared.elements.iter().zip(element_irradiance(&prepared.elements, flux, q)).enumerate() {
        let c = e.centroid;
        writeln!(
            out,
            "element,{i},{},{},{},{},{},{},{},{}",
            e.patch, c.x, c.y, c.z, e.area, irr.0[0], irr.0[1], irr.0[2]
        )?;
    }
    for (i, (p, irr)) in prepared.vertex_positions.iter().zip(vertex_irradiance).enumerate() {
        writeln!(out, "vertex,{i},,{},{},{},,{},{},{}", p.x, p.y, p.z, irr.0[0], irr.0[1], irr.0[2])?;
    }
    out.flush()?;
    Ok(())
}
