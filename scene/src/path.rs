//! The `[camera_path]` table of a scene file: keyframes interpolated over N frames.
//!
//! ```toml
//! [camera_path]
//! frames = 24
//! [[camera_path.keys]]
//! eye = [0, 1, 3.5]
//! look_at = [0, 1, 0]
//! fov = 40
//! [[camera_path.keys]]
//! eye = [1, 1.2, 3.2]
//! look_at = [0, 1, 0]
//! fov = 40
//! ```
//! Each key is a camera table like `[camera]` (`eye`, `look_at`, optional `up`, `fov`);
//! errors name the key: `scene.toml:14: camera_path.keys[1].fov: ...`.

use serde::Deserialize;
use toml::Spanned;

use super::error::SceneError;
use super::model::CameraPath;
use super::parse::{Ctx, RawCamera};
use crate::math::Normalized;

/// Most frames a path may ask for.
const MAX_FRAMES: i64 = 100_000;

/// `[camera_path]` as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawCameraPath {
    frames: Spanned<i64>,
    #[serde(default)]
    keys: Vec<Spanned<RawCamera>>,
}

impl Ctx<'_> {
    /// Checks a camera path: the frame count, every key, and every interpolated frame
    /// (two keys can interpolate to a camera with no view direction or a degenerate up).
    pub(super) fn camera_path(&self, p: &Spanned<RawCameraPath>) -> Result<CameraPath, SceneError> {
        let raw = p.get_ref();
        let frames = self.int_in(&raw.frames, "camera_path.frames", 1, MAX_FRAMES)? as u32;
        if raw.keys.is_empty() {
            return Err(self.err(p, "camera_path.keys", "a camera path needs at least one [[camera_path.keys]]"));
        }
        let keys = raw
            .keys
            .iter()
            .enumerate()
            .map(|(i, k)| self.camera(k, &format!("camera_path.keys[{i}]")))
            .collect::<Result<Vec<_>, _>>()?;
        let path = CameraPath { keys, frames, loc: self.loc(p) };
        for f in 0..frames {
            let c = path.camera_at(f);
            let view = c.look_at - c.eye;
            let ok = view.length() > 1e-12 * (1.0 + c.eye.abs().max_element())
                && view.normalized().cross(c.up.normalized()).length() >= 1e-9
                && c.up.normalized().is_finite();
            if !ok {
                let msg = format!("frame {f} interpolates to a camera with no view direction or an up along it");
                return Err(self.err(&raw.frames, "camera_path", msg));
            }
        }
        Ok(path)
    }
}

#[cfg(test)]
mod tests {
    use crate::parse_scene_with_path;
    use glam::DVec3;

    const BASE: &str = "[[light]]\nposition = [0, 1.9, 0]\nintensity = [1, 1, 1]\n\n[[material]]\nname = \"w\"\n\
                        diffuse = [0.7, 0.7, 0.7]\n\n[[triangle]]\nvertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]\n\
                        material = \"w\"\n";

    fn parse(text: &str) -> Result<(crate::Scene, Option<crate::CameraPath>), String> {
        parse_scene_with_path("p.toml", text, "b".as_ref(), &|_: &std::path::Path| {
            Err(std::io::ErrorKind::NotFound.into())
        })
        .map_err(|e| e.to_string())
    }

    fn path(frames: &str, keys: &[&str]) -> String {
        let mut s = format!("{BASE}\n[camera_path]\nframes = {frames}\n");
        for k in keys {
            s.push_str(&format!("\n[[camera_path.keys]]\n{k}\n"));
        }
        s
    }

    #[test]
    fn keys_interpolate_and_frames_on_keys_are_exact() {
        let a = "eye = [0, 1, 4]\nlook_at = [0, 1, 0]\nfov = 40";
        let b = "eye = [2, 1, 4]\nlook_at = [0, 1, 0]\nfov = 60";
        let (scene, p) = parse(&path("3", &[a, b])).unwrap();
        let p = p.unwrap();
        let cams = p.cameras();
        assert_eq!(cams.len(), 3);
        assert_eq!(cams[0].eye, DVec3::new(0.0, 1.0, 4.0));
        assert_eq!(cams[1].eye, DVec3::new(1.0, 1.0, 4.0));
        assert_eq!(cams[1].fov_y_deg, 50.0);
        assert_eq!(cams[2].eye, DVec3::new(2.0, 1.0, 4.0));
        assert_eq!(scene.camera, cams[0], "no [camera]: the path's first frame");
        let (_, one) = parse(&path("5", &[a])).unwrap();
        assert!(one.unwrap().cameras().iter().all(|c| c.eye == DVec3::new(0.0, 1.0, 4.0)));
    }

    #[test]
    fn errors_name_line_and_field() {
        let a = "eye = [0, 1, 4]\nlook_at = [0, 1, 0]\nfov = 40";
        let e = parse(&path("0", &[a])).unwrap_err();
        assert!(e.starts_with("p.toml:14: camera_path.frames: 0 is out of range"), "{e}");
        let e = parse(&path("2", &[a, "eye = [0, 1, 4]\nlook_at = [0, 1, 0]\nfov = 200"])).unwrap_err();
        assert!(e.starts_with("p.toml:24: camera_path.keys[1].fov: 200 is out of range"), "{e}");
        let e = parse(&path("2", &[])).unwrap_err();
        assert!(e.contains("camera_path.keys: "), "{e}");
        let e = parse(&path("2", &[&format!("{a}\nspeed = 3")])).unwrap_err();
        assert!(e.contains("camera_path.keys") && e.contains("speed"), "{e}");
        // Two keys whose midpoint puts the eye on look_at.
        let back = "eye = [0, 1, -4]\nlook_at = [0, 1, -8]\nfov = 40";
        let e = parse(&path("3", &["eye = [0, 1, 4]\nlook_at = [0, 1, 8]\nfov = 40", back])).unwrap_err();
        assert!(e.contains("camera_path: frame 1 interpolates"), "{e}");
    }
}
