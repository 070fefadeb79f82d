//! The subcommands of `magg-host`.

pub mod info;
pub mod render;
