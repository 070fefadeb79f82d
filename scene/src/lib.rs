//! # magg-scene: scenes, read and validated
//!
//! The scene model magg renders ([`Scene`]: camera, render settings, lights, materials,
//! triangle patches, textures, each entity remembering the file and line it came from),
//! the TOML front end, and the model formats its `[[mesh]]` entries read (OBJ with MTL,
//! PLY, glTF 2.0), with camera paths, smooth-shading normals and the crease angle.
//! Nothing here renders: preparation (`magg-prepare`) turns a [`Scene`] into blocks, and
//! the rendering core (`magg-core`, which re-exports this crate as `magg_core::scene`)
//! traces them.
//!
//! ```no_run
//! use magg_scene::{parse_scene_str, Scene};
//! let text = std::fs::read_to_string("scenes/cornell.toml").unwrap();
//! let scene: Scene = parse_scene_str("scenes/cornell.toml", &text, std::path::Path::new("scenes"),
//!     &|p: &std::path::Path| std::fs::read(p)).unwrap();
//! ```
//! The crate does no I/O itself: the files a scene names are read, as bytes, through the
//! `read` callback the caller passes.

pub mod color;
pub mod math;

mod chunks;
mod error;
mod field;
mod gltf;
mod load;
mod mesh;
mod model;
mod normals;
mod obj;
mod parse;
mod path;
mod ply;
mod shape;
mod texture;

pub use error::SceneError;
pub use gltf::{gltf_stage, GltfStage};
pub use mesh::{MeshFormat, ReadFile};
pub use model::*;
pub use parse::{parse_scene_str, parse_scene_with_path};
pub use texture::{bilinear_taps as texture_taps, srgb_to_linear, Texture, MAX_TEXTURE_SIDE};
