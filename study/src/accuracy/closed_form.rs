//! The closed-form reference of the accuracy study: where the only light is direct and
//! unoccluded (no mirror or glass, no diffuse bounce, no spot cone, no flux occluded in
//! the light pass), the irradiance at every point of a surface is E = I |cos(theta)| / r^2
//! per light, counting on each face of a patch only the lights on that face's side where
//! the patch keeps its faces apart (one-sided materials, back elements). The vertex irradiance that energy interpolation makes from the elements'
//! flux is measured against it: the bias that the element size leaves, which more light
//! rays cannot remove (each element's flux is exactly I x Omega whatever the ray count).

use glam::DVec3;
use magg_core::color::Rgb;
use magg_core::lrt::LrtTally;
use magg_core::math::Normalized;
use magg_core::prepared::{Face, PreparedScene};

/// True when the closed form holds for a render of `prepared` whose light pass reported
/// `tally`. Not when direct light is computed at VRT: the elements then hold none of it.
pub fn applies(prepared: &PreparedScene, tally: &LrtTally) -> bool {
    let h = &prepared.header;
    !h.plan.direct_vrt
        && h.plan.lrt_depth == 0
        && h.plan.diffuse_bounces == 0
        && h.lights.iter().all(|l| l.spot.is_none())
        && tally.occluded.0.iter().all(|&o| o == 0.0)
}

/// Closed-form irradiance at `p` on the face `face` of a surface with unit (front)
/// normal `n`.
pub fn irradiance_at(prepared: &PreparedScene, p: DVec3, n: DVec3, face: Face) -> Rgb {
    prepared.header.lights.iter().fold(Rgb::BLACK, |acc, l| {
        let d = l.position - p;
        let r2 = d.dot(d);
        if r2 <= 0.0 || !face.takes(d, n) {
            return acc;
        }
        let cos = (n.dot(d) / r2.sqrt()).abs();
        acc.add(l.intensity.scale(cos / r2))
    })
}

/// Unit (front) normal and face of every vertex: the area-weighted mean of its elements'
/// normals, and the face its elements hold (welding joins only elements of one face).
fn vertex_normals(prepared: &PreparedScene) -> Vec<(DVec3, Face)> {
    let p = &prepared.vertex_positions;
    let mut n = vec![(DVec3::ZERO, Face::Both); p.len()];
    for e in &prepared.elements {
        let [a, b, c] = e.vertices.map(|v| v as usize);
        if a >= p.len() || b >= p.len() || c >= p.len() {
            continue;
        }
        let w = (p[b] - p[a]).cross(p[c] - p[a]);
        for v in [a, b, c] {
            n[v] = (n[v].0 + w, e.face);
        }
    }
    n.into_iter().map(|(v, f)| (if v == DVec3::ZERO { v } else { v.normalized() }, f)).collect()
}

/// Relative RMSE of `vertex_irradiance` against the closed form: the RMSE over vertices
/// and channels divided by the mean closed-form irradiance. `None` where the closed
/// form does not hold (see [`applies`]).
pub fn vertex_rel_rmse(prepared: &PreparedScene, tally: &LrtTally, vertex_irradiance: &[Rgb]) -> Option<f64> {
    if !applies(prepared, tally) || vertex_irradiance.len() != prepared.vertex_positions.len() {
        return None;
    }
    let normals = vertex_normals(prepared);
    let (mut se, mut sum, mut n) = (0.0, 0.0, 0usize);
    for ((&p, &(nv, face)), got) in prepared.vertex_positions.iter().zip(&normals).zip(vertex_irradiance) {
        let want = irradiance_at(prepared, p, nv, face);
        for c in 0..3 {
            se += (got.0[c] - want.0[c]).powi(2);
            sum += want.0[c];
            n += 1;
        }
    }
    (n > 0 && sum > 0.0).then(|| (se / n as f64).sqrt() / (sum / n as f64))
}

#[cfg(test)]
mod tests {
    use super::*;
    use magg_core::progress::NoProgress;
    use magg_core::render;

    fn scene(name: &str) -> magg_core::scene::Scene {
        crate::test_scene(name)
    }

    fn vertex_error(mut s: magg_core::scene::Scene, element_size: f64, light_rays: u32) -> Option<f64> {
        s.settings.width = 16;
        s.settings.height = 16;
        s.settings.element_size = element_size;
        s.settings.light_rays = light_rays;
        s.settings.direct = magg_core::scene::DirectLight::Lrt;
        let prepared = magg_prepare::prepare(&s).unwrap();
        let out = render::render(&prepared, &Default::default(), &NoProgress).unwrap();
        vertex_rel_rmse(&prepared, &out.stats.light, &out.vertex_irradiance)
    }

    /// The interpolation bias shrinks with the element size (about 4x per halving) and
    /// does not move with the ray count.
    #[test]
    fn plane_vertex_error_is_set_by_the_element_size_not_the_rays() {
        let coarse = vertex_error(scene("plane.toml"), 0.5, 16).unwrap();
        let fine = vertex_error(scene("plane.toml"), 0.25, 16).unwrap();
        let fine_more_rays = vertex_error(scene("plane.toml"), 0.25, 64).unwrap();
        assert!(coarse > 2.5 * fine && fine > 0.0, "coarse {coarse} fine {fine}");
        assert!((fine - fine_more_rays).abs() <= 1e-9 * fine, "{fine} vs {fine_more_rays}");
    }

    #[test]
    fn no_vertex_closed_form_when_direct_light_is_computed_at_vrt() {
        let mut s = scene("plane.toml");
        s.settings.width = 16;
        s.settings.height = 16;
        let prepared = magg_prepare::prepare(&s).unwrap();
        assert!(prepared.header.plan.direct_vrt);
        let out = render::render(&prepared, &Default::default(), &NoProgress).unwrap();
        assert_eq!(vertex_rel_rmse(&prepared, &out.stats.light, &out.vertex_irradiance), None);
    }

    #[test]
    fn no_closed_form_with_a_mirror() {
        assert_eq!(vertex_error(scene("magg-paper.toml"), 0.25, 4), None);
    }
}
