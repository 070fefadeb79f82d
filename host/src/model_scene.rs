//! A model file rendered on its own: `magg-host render model.obj --out m.png` (or `.ply`,
//! `.gltf`, `.glb`). The scene around it is made up as a user would write it: a camera
//! that frames the model's bounding sphere from the front, above and to the right (Y up,
//! the usual for OBJ and glTF), a point light beside the camera, elements sized to the
//! model, a grey diffuse material for a model whose faces have no material (every PLY).
//! A glTF file's own camera and point and spot lights replace the made-up ones. It is
//! written as a TOML scene and parsed like one, so `--set` reaches every value of it
//! (`--set camera.fov=30`).

use magg_core::scene::{GltfStage, Light, MeshFormat, Scene};
use std::fmt::Write;
use std::path::Path;

/// Whether `path` names a model file rather than a scene (by extension: `.obj`, `.ply`,
/// `.gltf`, `.glb`).
pub fn is_model(path: &Path) -> bool {
    MeshFormat::of(path).is_some()
}

/// The scene of model `file` (its name, beside the scene) seen as `view` says; `grey`:
/// give every face the grey material (for a model whose faces have no material).
pub fn scene_text(file: &str, view: &View, grey: bool) -> String {
    let v = |p: [f64; 3]| format!("[{:e}, {:e}, {:e}]", p[0], p[1], p[2]);
    let material = if grey { "material = \"grey\"\n" } else { "" };
    let mut out = format!(
        "# The scene magg-host makes up around {file:?}.\n\
         [camera]\neye = {}\nlook_at = {}\nup = {}\nfov = {}\n\n\
         [render]\nelement_size = {:e}\nambient = [0.05, 0.05, 0.05]\n",
        v(view.eye),
        v(view.look_at),
        v(view.up),
        view.fov,
        view.element_size,
    );
    if let Some(width) = view.width {
        let _ = writeln!(out, "width = {width}");
    }
    for light in &view.lights {
        let _ = write!(out, "\n[[light]]\nposition = {}\nintensity = {}\n", v(light.position), v(light.intensity));
        if let Some(spot) = &light.spot {
            let _ = write!(
                out,
                "direction = {}\ncone = {:e}\nfalloff = {:e}\n",
                v(spot.direction.to_array()),
                spot.half_angle_deg,
                spot.falloff_deg
            );
        }
    }
    let _ = write!(
        out,
        "\n[[material]]\nname = \"grey\"\ndiffuse = [0.7, 0.7, 0.7]\n\n[[mesh]]\nfile = {file:?}\n{material}"
    );
    out
}

/// A light of a model's scene, as its TOML gives it.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewLight {
    /// Position.
    pub position: [f64; 3],
    /// Intensity per channel, W/sr.
    pub intensity: [f64; 3],
    /// The spot cone, if any.
    pub spot: Option<magg_core::scene::Spot>,
}

impl From<&Light> for ViewLight {
    fn from(l: &Light) -> Self {
        ViewLight { position: l.position.to_array(), intensity: l.intensity.0, spot: l.spot.clone() }
    }
}

/// The camera, lights and element size of a model's scene.
#[derive(Clone, Debug, PartialEq)]
pub struct View {
    /// Camera position.
    pub eye: [f64; 3],
    /// The point the camera looks at (the model's centre, unless the model has a camera).
    pub look_at: [f64; 3],
    /// The camera's up direction.
    pub up: [f64; 3],
    /// Vertical field of view, degrees.
    pub fov: f64,
    /// Image width (for the model camera's aspect ratio at the default height), if set.
    pub width: Option<u32>,
    /// The lights: one beside and above the camera giving about 1 W/m^2 at the model,
    /// unless the model brings its own.
    pub lights: Vec<ViewLight>,
    /// Element edge: a fortieth of the model's size.
    pub element_size: f64,
}

impl View {
    /// A first guess that any model parses with (replaced once its bounds are known).
    pub fn placeholder() -> View {
        View {
            eye: [0.0, 0.0, 1.0],
            look_at: [0.0; 3],
            up: [0.0, 1.0, 0.0],
            fov: 40.0,
            width: None,
            lights: vec![ViewLight { position: [0.0, 0.0, 1.0], intensity: [1.0; 3], spot: None }],
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
        View {
            eye,
            look_at: centre,
            up: [0.0, 1.0, 0.0],
            fov,
            width: None,
            lights: vec![ViewLight { position: light, intensity: [distance * distance; 3], spot: None }],
            element_size: radius / 20.0,
        }
    }

    /// This view with the camera and lights a glTF file brings, where it brings them
    /// (its camera's aspect ratio sets the width at the default height of 400).
    pub fn with_stage(mut self, stage: &GltfStage) -> View {
        if let Some(c) = &stage.camera {
            (self.eye, self.look_at, self.up, self.fov) =
                (c.eye.to_array(), c.look_at.to_array(), c.up.to_array(), c.fov_y_deg);
            self.width = stage.aspect_ratio.map(|a| (400.0 * a).round().clamp(1.0, 16384.0) as u32);
        }
        if !stage.lights.is_empty() {
            self.lights = stage.lights.iter().map(ViewLight::from).collect();
        }
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_view_frames_the_bounding_sphere_from_the_front() {
        let text = scene_text("m.obj", &View::placeholder(), true);
        let obj = "v -1 0 -1\nv 1 0 -1\nv 1 2 1\nf 1 2 3\n";
        let read = |_: &Path| Ok(obj.as_bytes().to_vec());
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
