//! A model file rendered on its own: `magg-host render model.obj --out m.png`. The scene
//! around it is made up as a user would write it: a camera that frames the model's
//! bounding sphere from the front, above and to the right (Y up, the usual for OBJ), a
//! point light beside the camera, elements sized to the model, a grey diffuse material
//! for faces the model's MTL does not colour. It is written as a TOML scene and parsed
//! like one, so `--set` reaches every value of it (`--set camera.fov=30`).

use magg_core::scene::Scene;
use std::path::Path;

/// Whether `path` names a model file rather than a scene (by extension: `.obj`).
pub fn is_model(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("obj"))
}

/// The scene of model `file` (its name, beside the scene) seen as `view` says; `grey`:
/// give every face the grey material (for a model whose faces have no `usemtl`).
pub fn scene_text(file: &str, view: &View, grey: bool) -> String {
    let v = |p: [f64; 3]| format!("[{:e}, {:e}, {:e}]", p[0], p[1], p[2]);
    let material = if grey { "material = \"grey\"\n" } else { "" };
    format!(
        "# The scene magg-host makes up around {file:?}.\n\
         [camera]\neye = {}\nlook_at = {}\nfov = {}\n\n\
         [render]\nelement_size = {:e}\nambient = [0.05, 0.05, 0.05]\n\n\
         [[light]]\nposition = {}\nintensity = {}\n\n\
         [[material]]\nname = \"grey\"\ndiffuse = [0.7, 0.7, 0.7]\n\n\
         [[mesh]]\nobj = {file:?}\n{material}",
        v(view.eye),
        v(view.look_at),
        view.fov,
        view.element_size,
        v(view.light),
        v([view.intensity; 3]),
    )
}

/// The camera, light and element size of a model's scene.
#[derive(Clone, Debug, PartialEq)]
pub struct View {
    /// Camera position.
    pub eye: [f64; 3],
    /// The model's centre.
    pub look_at: [f64; 3],
    /// Vertical field of view, degrees.
    pub fov: f64,
    /// Light position (beside and above the camera).
    pub light: [f64; 3],
    /// Light intensity (W/sr): about 1 W/m^2 at the model.
    pub intensity: f64,
    /// Element edge: a fortieth of the model's size.
    pub element_size: f64,
}

impl View {
    /// A first guess that any model parses with (replaced once its bounds are known).
    pub fn placeholder() -> View {
        View {
            eye: [0.0, 0.0, 1.0],
            look_at: [0.0; 3],
            fov: 40.0,
            light: [0.0, 0.0, 1.0],
            intensity: 1.0,
            element_size: 1e30,
        }
    }

    /// The view that frames every patch of `scene`.
    pub fn framing(scene: &Scene) -> View {
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for v in scene.patches.iter().flat_map(|p| p.vertices) {
            for k in 0..3 {
                lo[k] = lo[k].min(v[k]);
                hi[k] = hi[k].max(v[k]);
            }
        }
        let centre: [f64; 3] = std::array::from_fn(|k| 0.5 * (lo[k] + hi[k]));
        let radius = (0..3).map(|k| (hi[k] - lo[k]).powi(2)).sum::<f64>().sqrt().max(1e-9) * 0.5;
        let fov = 40.0f64;
        let distance = 1.15 * radius / (0.5 * fov.to_radians()).sin();
        let dir = [0.4, 0.35, 1.0];
        let len = dir.iter().map(|d| d * d).sum::<f64>().sqrt();
        let eye = std::array::from_fn(|k| centre[k] + dir[k] / len * distance);
        let light = std::array::from_fn(|k| eye[k] + if k == 1 { 0.5 * radius } else { 0.0 });
        View { eye, look_at: centre, fov, light, intensity: distance * distance, element_size: radius / 20.0 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_view_frames_the_bounding_sphere_from_the_front() {
        let text = scene_text("m.obj", &View::placeholder(), true);
        let obj = "v -1 0 -1\nv 1 0 -1\nv 1 2 1\nf 1 2 3\n";
        let read = |_: &Path| Ok(obj.to_string());
        let scene = magg_core::scene::parse_scene_str("m.obj", &text, Path::new("."), &read).unwrap();
        let view = View::framing(&scene);
        assert_eq!(view.look_at, [0.0, 1.0, 0.0]);
        let d: f64 = (0..3).map(|k| (view.eye[k] - view.look_at[k]).powi(2)).sum::<f64>().sqrt();
        let radius = 3f64.sqrt() * 2.0 * 0.5;
        assert!(d > radius / (20f64.to_radians()).sin(), "the model does not fit the view");
        assert!(view.eye[2] > 0.0 && view.eye[1] > 1.0, "not from the front and above");
        // The framed scene parses and keeps its one patch.
        let framed = scene_text("m.obj", &view, true);
        let again = magg_core::scene::parse_scene_str("m.obj", &framed, Path::new("."), &read).unwrap();
        assert_eq!(again.patches.len(), 1);
    }
}
