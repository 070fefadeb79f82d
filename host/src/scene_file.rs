//! Loading a scene file from disk (the core parses; this reads the files it names), with
//! the limits of a renderer that may be handed any scene: only regular files, each
//! capped in size, and mesh files only from the scene's folder or a root the user allows
//! (`--allow-path DIR`). An error names the file and the limit; it never shows what the
//! file holds.

use crate::model_scene::{scene_text, View};
use crate::overrides::Override;
use anyhow::Context;
use magg_core::scene::{gltf_stage, parse_scene_with_path, CameraPath, MeshFormat, Scene};
use std::io::{self, Read};
use std::path::{Path, PathBuf};

/// Largest scene file (TOML) read, in bytes: a scene of a million explicit quads is
/// about 150 MB of TOML; meshes belong in OBJ files.
pub const MAX_SCENE_BYTES: u64 = 256 << 20;

/// Largest mesh file read (OBJ, MTL, PLY, glTF or one of its buffers), in bytes: about
/// 20 million triangles of OBJ, past the renderer's default memory bound.
pub const MAX_MESH_BYTES: u64 = 2 << 30;

/// Where a scene's meshes may come from besides its own folder.
#[derive(Clone, Debug, Default)]
pub struct SceneFiles {
    roots: Vec<PathBuf>,
}

impl SceneFiles {
    /// Mesh files from the scene's folder and below, and from the folders `allow`
    /// (each must exist).
    pub fn new(allow: &[PathBuf]) -> anyhow::Result<SceneFiles> {
        let roots = allow
            .iter()
            .map(|d| {
                let c = d.canonicalize().with_context(|| format!("--allow-path {}", d.display()))?;
                anyhow::ensure!(c.is_dir(), "--allow-path {}: not a folder", d.display());
                Ok(c)
            })
            .collect::<anyhow::Result<_>>()?;
        Ok(SceneFiles { roots })
    }

    /// Reads and parses the scene at `path`, with `overrides` applied.
    pub fn load(&self, path: &Path, overrides: &[Override]) -> anyhow::Result<Scene> {
        self.load_with_path(path, overrides).map(|(scene, _)| scene)
    }

    /// Reads and parses the scene at `path` with its camera path, if it has one, with
    /// `overrides` applied to its text first. An error that follows from them says so.
    /// The knobs its file leaves unset are chosen ([`crate::auto`]).
    pub fn load_with_path(&self, path: &Path, overrides: &[Override]) -> anyhow::Result<(Scene, Option<CameraPath>)> {
        self.load_explained(path, overrides).map(|(scene, camera_path, _)| (scene, camera_path))
    }

    /// [`SceneFiles::load_with_path`], with what was chosen for the knobs the file
    /// leaves unset, and why.
    pub fn load_explained(
        &self,
        path: &Path,
        overrides: &[Override],
    ) -> anyhow::Result<(Scene, Option<CameraPath>, crate::auto::Chosen)> {
        let text = if crate::model_scene::is_model(path) {
            self.model_scene(path)?
        } else {
            read_capped(path, MAX_SCENE_BYTES).with_context(|| format!("cannot read scene file {}", path.display()))?
        };
        let (text, parsed) = if !overrides.is_empty() {
            let text = crate::overrides::apply(&text, overrides).with_context(|| path.display().to_string())?;
            let with: Vec<String> = overrides.iter().map(|o| o.to_string()).collect();
            let parsed = self.parse(path, &text).with_context(|| format!("with {}", with.join(" ")));
            (text, parsed)
        } else {
            let parsed = self.parse(path, &text);
            (text, parsed)
        };
        let (mut scene, camera_path) = parsed?;
        let chosen = crate::auto::choose(&mut scene, &crate::auto::Given::of(&text));
        Ok((scene, camera_path, chosen))
    }

    /// The scene made up around the model file at `path` ([`crate::model_scene`]): parsed
    /// once to find its bounds (with the grey material when its faces have none), then
    /// written with the view that frames it.
    fn model_scene(&self, path: &Path) -> anyhow::Result<String> {
        let file = path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
        let text = |view: &View, grey| scene_text(&file, view, grey);
        let format = MeshFormat::of(path);
        let first = if format == Some(MeshFormat::Ply) {
            Err(anyhow::anyhow!("face has no material"))
        } else {
            self.parse(path, &text(&View::placeholder(), false))
        };
        let ((scene, _), grey) = match first {
            Ok(parsed) => (parsed, false),
            Err(e) if format!("{e:#}").contains("face has no material") => {
                (self.parse(path, &text(&View::placeholder(), true))?, true)
            }
            Err(e) => return Err(e),
        };
        let mut view = View::framing(&scene);
        if format == Some(MeshFormat::Gltf) {
            let label = path.display().to_string();
            let bytes = self.read_mesh(&self.home(path)?, path).with_context(|| format!("cannot read {label}"))?;
            view = view.with_stage(&gltf_stage(&label, &bytes)?);
        }
        Ok(text(&view, grey))
    }

    /// The canonical folder of the scene at `path`, where its meshes may come from.
    fn home(&self, path: &Path) -> anyhow::Result<PathBuf> {
        let base = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or_else(|| Path::new("."));
        base.canonicalize().with_context(|| format!("the scene's folder {}", base.display()))
    }

    fn parse(&self, path: &Path, text: &str) -> anyhow::Result<(Scene, Option<CameraPath>)> {
        let base = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or_else(|| Path::new("."));
        let home = self.home(path)?;
        let label = path.display().to_string();
        let read = |p: &Path| self.read_mesh(&home, p);
        Ok(parse_scene_with_path(&label, text, base, &read)?)
    }

    /// A mesh file (or a file a mesh names: an MTL, a glTF buffer), if it lies in the
    /// scene's folder `home` or an allowed root.
    fn read_mesh(&self, home: &Path, p: &Path) -> io::Result<Vec<u8>> {
        let c = p.canonicalize()?;
        if !c.starts_with(home) && !self.roots.iter().any(|r| c.starts_with(r)) {
            return Err(io::Error::new(
                io::ErrorKind::PermissionDenied,
                format!("it lies outside the scene's folder {}; allow its folder with --allow-path", home.display()),
            ));
        }
        read_capped_bytes(&c, MAX_MESH_BYTES)
    }
}

/// The text of the regular file at `path`, refused past `limit` bytes or when it is not
/// UTF-8 (the error then gives the line).
pub fn read_capped(path: &Path, limit: u64) -> io::Result<String> {
    let bytes = read_capped_bytes(path, limit)?;
    String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        let line = 1 + e.as_bytes()[..at].iter().filter(|&&b| b == b'\n').count();
        io::Error::new(io::ErrorKind::InvalidData, format!("line {line}: not UTF-8 text"))
    })
}

/// The bytes of the regular file at `path`, refused past `limit` bytes.
pub fn read_capped_bytes(path: &Path, limit: u64) -> io::Result<Vec<u8>> {
    let file = std::fs::File::open(path)?;
    if !file.metadata()?.is_file() {
        return Err(io::Error::new(io::ErrorKind::InvalidInput, "not a regular file"));
    }
    let mut bytes = Vec::new();
    file.take(limit + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!("larger than the limit of {} MiB", limit >> 20),
        ));
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir() -> tempfile::TempDir {
        tempfile::tempdir().unwrap()
    }

    #[test]
    fn only_regular_files_within_the_limit() {
        let d = dir();
        let f = d.path().join("a.txt");
        std::fs::write(&f, "0123456789").unwrap();
        assert_eq!(read_capped(&f, 10).unwrap(), "0123456789");
        let e = read_capped(&f, 9).unwrap_err().to_string();
        assert!(e.contains("larger than the limit"), "{e}");
        let e = read_capped(Path::new("/dev/zero"), 1 << 20).unwrap_err().to_string();
        assert_eq!(e, "not a regular file");
        assert!(read_capped(d.path(), 10).is_err(), "a folder");
    }

    #[test]
    fn non_utf8_names_its_line_and_not_its_bytes() {
        let d = dir();
        let f = d.path().join("s.toml");
        std::fs::write(&f, b"a = 1\nb = 2\nc = \"\xff\xfe secret\"\n").unwrap();
        let e = read_capped(&f, 1 << 20).unwrap_err().to_string();
        assert_eq!(e, "line 3: not UTF-8 text");
    }

    #[test]
    fn meshes_come_from_the_scene_folder_or_an_allowed_root() {
        let (scene_dir, other) = (dir(), dir());
        let inside = scene_dir.path().join("m.obj");
        let outside = other.path().join("m.obj");
        for f in [&inside, &outside] {
            std::fs::write(f, "v 0 0 0\n").unwrap();
        }
        let home = scene_dir.path().canonicalize().unwrap();
        let files = SceneFiles::default();
        assert!(files.read_mesh(&home, &inside).is_ok());
        let e = files.read_mesh(&home, &outside).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::PermissionDenied);
        assert!(e.to_string().contains("--allow-path"), "{e}");
        let sneaky = scene_dir.path().join("..").join(other.path().file_name().unwrap()).join("m.obj");
        assert!(files.read_mesh(&home, &sneaky).is_err(), "../ leaves the folder");
        let allowed = SceneFiles::new(&[other.path().to_path_buf()]).unwrap();
        assert!(allowed.read_mesh(&home, &outside).is_ok());
        assert!(SceneFiles::new(&[other.path().join("missing")]).is_err());
    }
}
