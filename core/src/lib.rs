//! # magg-core: the rendering library of magg
//!
//! Two-pass bidirectional ray tracing after Kawai et al. (1993): light ray tracing (LRT)
//! from point lights onto triangle *elements*, energy interpolation to vertices, then
//! viewing ray tracing (VRT) from the eye. Scene data lives in 2 KB *blocks* (subspace,
//! patch, element and vertex-energy blocks) behind the [`blocks::BlockSource`] trait, and
//! every access of the kernels goes through an LRU [`blocks::BlockCache`], exactly as a
//! node processor of the MAGG system reads shared memory through its local cache.
//!
//! The crate does no I/O and knows nothing of networking. The phases are sequenced once
//! ([`phases::run`]) over a [`machine::Machine`]: the embedded renderer
//! ([`render::EmbeddedMachine`], [`render::render`]) and the cluster's host are its two
//! implementations, and both run the same kernels ([`lrt::trace_pair`],
//! [`vrt::shade_pixel`]).
//!
//! The scene model and its readers are the `magg-scene` crate, re-exported here as
//! [`scene`] (with [`color`] and [`math`]); preparation, which turns a scene into a
//! [`prepared::PreparedScene`], is the `magg-prepare` crate: nodes render a prepared
//! scene's blocks without it.
//!
//! ```no_run
//! use magg_core::{render, scene};
//! let text = std::fs::read_to_string("scenes/cornell.toml").unwrap();
//! let scene = scene::parse_scene_str("scenes/cornell.toml", &text, "scenes".as_ref(),
//!     &|p: &std::path::Path| std::fs::read(p)).unwrap();
//! let prepared = magg_prepare::prepare(&scene).unwrap();
//! let out = render::render(&prepared, &render::RenderOptions::default(), &magg_core::progress::NoProgress).unwrap();
//! println!("{} x {} pixels", out.frame.width, out.frame.height);
//! ```

pub mod blocks;
pub mod camera;
pub mod cluster;
pub mod direct;
pub mod energy;
pub mod fingerprint;
pub mod fixed;
pub mod frame;
pub mod geometry;
pub mod header;
pub mod idhash;
pub mod kept;
pub mod lights;
pub mod lrt;
pub mod machine;
pub mod pair;
pub mod phases;
pub mod placement;
pub mod plan;
pub mod prepared;
pub mod progress;
pub mod render;
pub mod rng;
pub mod scatter;
pub mod stats;
pub mod subdivision;
pub mod subscreen;
pub mod trace;
pub mod view;
pub mod vrt;

pub use magg_scene as scene;
pub use magg_scene::{color, math};
