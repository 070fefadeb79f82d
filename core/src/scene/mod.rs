//! Scenes: the validated in-memory model, the TOML front end, and the model formats its
//! `[[mesh]]` entries read (OBJ with MTL, PLY, glTF 2.0).
//!
//! ```no_run
//! use magg_core::scene::{parse_scene_str, Scene};
//! let text = std::fs::read_to_string("scenes/cornell.toml").unwrap();
//! let scene: Scene = parse_scene_str("scenes/cornell.toml", &text, std::path::Path::new("scenes"),
//!     &|p: &std::path::Path| std::fs::read(p)).unwrap();
//! ```
//! The core does no I/O itself: the files a scene names are read, as bytes, through the
//! `read` callback the caller passes.

mod error;
mod field;
mod gltf;
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
