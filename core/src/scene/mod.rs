//! Scenes: the validated in-memory model, and the TOML / OBJ+MTL front ends.
//!
//! ```no_run
//! use magg_core::scene::{parse_scene_str, Scene};
//! let text = std::fs::read_to_string("scenes/cornell.toml").unwrap();
//! let scene: Scene = parse_scene_str("scenes/cornell.toml", &text, std::path::Path::new("scenes"),
//!     &|p: &std::path::Path| std::fs::read_to_string(p)).unwrap();
//! ```
//! The core does no I/O itself: OBJ/MTL files named by a scene are read through the
//! `read` callback the caller passes.

mod error;
mod field;
mod model;
mod obj;
mod parse;
mod path;
mod shape;

pub use error::SceneError;
pub use model::*;
pub use parse::{parse_scene_str, parse_scene_with_path};
