//! The energy file: one row per element (id, patch, centroid, area, irradiance RGB) and
//! one per vertex (id, position, irradiance RGB), written with the `csv` crate. Values
//! print in Rust's shortest round-trip form, so equal energies give byte-identical files.

use magg_core::color::Rgb;
use magg_core::energy::element_irradiance;
use magg_core::prepared::PreparedScene;

/// The header row; a vertex leaves `patch` and `area` empty.
pub const HEADER: [&str; 10] = ["kind", "id", "patch", "x", "y", "z", "area", "r", "g", "b"];

/// Writes the energy CSV.
pub fn write(
    path: &std::path::Path,
    prepared: &PreparedScene,
    flux: &[[i64; 3]],
    vertex_irradiance: &[Rgb],
) -> anyhow::Result<()> {
    let mut out = csv::Writer::from_path(path)?;
    out.write_record(HEADER)?;
    let q = prepared.header.energy_quantum;
    for (i, (e, irr)) in prepared.elements.iter().zip(element_irradiance(&prepared.elements, flux, q)).enumerate() {
        let c = e.centroid;
        let [r, g, b] = irr.0.map(|v| v.to_string());
        let (x, y, z) = (c.x.to_string(), c.y.to_string(), c.z.to_string());
        out.write_record([
            "element",
            &i.to_string(),
            &e.patch.to_string(),
            &x,
            &y,
            &z,
            &e.area.to_string(),
            &r,
            &g,
            &b,
        ])?;
    }
    for (i, (p, irr)) in prepared.vertex_positions.iter().zip(vertex_irradiance).enumerate() {
        let [r, g, b] = irr.0.map(|v| v.to_string());
        let (x, y, z) = (p.x.to_string(), p.y.to_string(), p.z.to_string());
        out.write_record(["vertex", &i.to_string(), "", &x, &y, &z, "", &r, &g, &b])?;
    }
    out.flush()?;
    Ok(())
}
