//! The subcommands of `magg-host`.

pub mod accuracy;
pub mod diff;
pub mod export;
pub mod info;
pub mod render;
pub mod sweep;
