//! Hardware profiles: what each path and operation costs on the emulated machine.
//!
//! A profile is a TOML file (`deploy/profiles/*.toml`, format in `magg1993.toml`); the
//! profiles shipped with magg are also built in, so `--profile magg1993` works anywhere.

use serde::Deserialize;
use std::time::Duration;
use thiserror::Error;

/// The profiles built into every binary: (name, TOML text).
pub const BUILTIN: &[(&str, &str)] = &[
    ("native", include_str!("../../deploy/profiles/native.toml")),
    ("magg1993", include_str!("../../deploy/profiles/magg1993.toml")),
];

/// A profile could not be found or read.
#[derive(Debug, Error)]
pub enum ProfileError {
    /// Neither a built-in name nor a readable file.
    #[error("profile {name:?}: not a built-in profile ({builtins}) and not a readable file: {reason}")]
    NotFound {
        /// What was asked for.
        name: String,
        /// The built-in names.
        builtins: String,
        /// Why the file could not be read.
        reason: String,
    },
    /// The TOML is malformed or a value is out of range.
    #[error("profile {source_name}: {message}")]
    Invalid {
        /// File or built-in name.
        source_name: String,
        /// What is wrong (with the field).
        message: String,
    },
}

/// The paths a byte travels on the 1993 machine (docs/ARCHITECTURE.md, the throttling layer).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Path {
    /// T800 serial link: node <-> fork/host messages.
    Link,
    /// DMA bus inside a GPU card: blocks from a fork to its nodes.
    Dma,
    /// G-bus: fork <-> fork block fetches, pair stealing, the host's uploads.
    Gbus,
}

impl Path {
    /// Lower-case name, as in stats and profiles.
    pub fn name(self) -> &'static str {
        match self {
            Path::Link => "link",
            Path::Dma => "dma",
            Path::Gbus => "gbus",
        }
    }
}

/// Bandwidth and per-message costs of one path.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PathSpec {
    /// Megabytes (10^6 bytes) per second.
    pub bandwidth_mb_s: f64,
    /// Fixed cost per message, microseconds.
    #[serde(default)]
    pub latency_us: f64,
    /// Packet size in bytes (0: messages are not split into packets).
    #[serde(default)]
    pub packet_bytes: u64,
    /// Extra cost per packet, microseconds.
    #[serde(default)]
    pub packet_us: f64,
}

impl PathSpec {
    /// Modelled time of one message of `bytes` bytes (before dilation).
    pub fn cost(&self, bytes: u64) -> Duration {
        let packets = if self.packet_bytes == 0 { 0 } else { bytes.div_ceil(self.packet_bytes).max(1) };
        let s = self.latency_us * 1e-6
            + bytes as f64 / (self.bandwidth_mb_s * 1e6)
            + packets as f64 * self.packet_us * 1e-6;
        Duration::from_secs_f64(s)
    }

    fn check(&self, name: &str) -> Result<(), String> {
        if !(self.bandwidth_mb_s.is_finite() && self.bandwidth_mb_s > 0.0) {
            return Err(format!("{name}.bandwidth_mb_s = {}: must be a positive number", self.bandwidth_mb_s));
        }
        for (f, v) in [("latency_us", self.latency_us), ("packet_us", self.packet_us)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("{name}.{f} = {v}: must be a number >= 0"));
            }
        }
        Ok(())
    }
}

/// Per-operation compute costs of a node and of preprocessing, microseconds.
#[derive(Clone, Copy, Debug, PartialEq, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CpuSpec {
    /// One 3D-DDA step into a subspace.
    #[serde(default)]
    pub grid_step_us: f64,
    /// One ray/patch intersection test.
    #[serde(default)]
    pub patch_test_us: f64,
    /// One light ray generated.
    #[serde(default)]
    pub light_ray_us: f64,
    /// One viewing ray generated.
    #[serde(default)]
    pub view_ray_us: f64,
    /// One shading evaluation.
    #[serde(default)]
    pub shade_us: f64,
    /// One triangle/subspace overlap test in preprocessing.
    #[serde(default)]
    pub box_test_us: f64,
    /// One element made in preprocessing.
    #[serde(default)]
    pub element_us: f64,
    /// One vertex welded in preprocessing.
    #[serde(default)]
    pub vertex_us: f64,
    /// One 2 KB block packed in preprocessing.
    #[serde(default)]
    pub block_us: f64,
}

/// A fork processor's own costs, microseconds.
#[derive(Clone, Copy, Debug, PartialEq, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ForkSpec {
    /// Serving one request (any RPC).
    #[serde(default)]
    pub request_us: f64,
    /// Accumulating one element deposit.
    #[serde(default)]
    pub deposit_us: f64,
}

/// A hardware profile: the measured speeds of the machine's processors, links, DMA and G-bus.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Profile {
    /// Its name (stats, logs).
    pub name: String,
    /// Real seconds per modelled second.
    #[serde(default = "one")]
    pub dilation: f64,
    /// The serial link, if throttled.
    #[serde(default)]
    pub link: Option<PathSpec>,
    /// The DMA bus, if throttled.
    #[serde(default)]
    pub dma: Option<PathSpec>,
    /// The G-bus, if throttled.
    #[serde(default)]
    pub gbus: Option<PathSpec>,
    /// Node compute costs, if emulated.
    #[serde(default)]
    pub cpu: Option<CpuSpec>,
    /// Fork service costs, if emulated.
    #[serde(default)]
    pub fork: Option<ForkSpec>,
    /// The TOML text it was read from (sent to forks and nodes so that every process of
    /// a cluster runs the same profile).
    #[serde(skip)]
    pub source: String,
}

fn one() -> f64 {
    1.0
}

impl Profile {
    /// The native profile: nothing throttled.
    pub fn native() -> Profile {
        Profile::named("native").unwrap_or_else(|_| Profile {
            name: "native".into(),
            dilation: 1.0,
            link: None,
            dma: None,
            gbus: None,
            cpu: None,
            fork: None,
            source: String::new(),
        })
    }

    /// A built-in profile by name, or a profile file by path.
    pub fn named(name_or_file: &str) -> Result<Profile, ProfileError> {
        if let Some((n, text)) = BUILTIN.iter().find(|(n, _)| *n == name_or_file) {
            return Profile::from_toml(n, text);
        }
        match std::fs::read_to_string(name_or_file) {
            Ok(text) => Profile::from_toml(name_or_file, &text),
            Err(e) => Err(ProfileError::NotFound {
                name: name_or_file.into(),
                builtins: BUILTIN.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", "),
                reason: e.to_string(),
            }),
        }
    }

    /// Parses a profile; `source_name` names it in errors.
    pub fn from_toml(source_name: &str, text: &str) -> Result<Profile, ProfileError> {
        let invalid = |message: String| ProfileError::Invalid { source_name: source_name.into(), message };
        let mut p: Profile = toml::from_str(text).map_err(|e| invalid(e.to_string()))?;
        if !(p.dilation.is_finite() && p.dilation > 0.0) {
            return Err(invalid(format!("dilation = {}: must be a positive number", p.dilation)));
        }
        for (name, spec) in [("link", p.link), ("dma", p.dma), ("gbus", p.gbus)] {
            if let Some(s) = spec {
                s.check(name).map_err(invalid)?;
            }
        }
        let costs = [p.cpu.map(|c| c.all()), p.fork.map(|f| vec![f.request_us, f.deposit_us])];
        if costs.iter().flatten().flatten().any(|v| !(v.is_finite() && *v >= 0.0)) {
            return Err(invalid("cpu and fork costs must be numbers >= 0".into()));
        }
        p.source = text.to_string();
        Ok(p)
    }

    /// The same profile with another dilation.
    pub fn with_dilation(mut self, dilation: f64) -> Profile {
        self.dilation = dilation;
        self
    }

    /// True when nothing is throttled: the layer is taken out of the path.
    pub fn is_native(&self) -> bool {
        self.link.is_none() && self.dma.is_none() && self.gbus.is_none() && self.cpu.is_none() && self.fork.is_none()
    }

    /// The spec of `path`, if it is throttled.
    pub fn path(&self, path: Path) -> Option<&PathSpec> {
        match path {
            Path::Link => self.link.as_ref(),
            Path::Dma => self.dma.as_ref(),
            Path::Gbus => self.gbus.as_ref(),
        }
    }

    /// Real time to impose for a modelled time.
    pub fn dilate(&self, modelled: Duration) -> Duration {
        modelled.mul_f64(self.dilation)
    }

    /// Real time to impose for a message of `bytes` on `path` (zero if not throttled).
    pub fn real_cost(&self, path: Path, bytes: u64) -> Duration {
        self.path(path).map_or(Duration::ZERO, |s| self.dilate(s.cost(bytes)))
    }

    /// The text to send to other processes: the source, with the dilation in force.
    pub fn to_wire(&self) -> String {
        format!("{}\n# in force\n__dilation = {}\n", self.source, self.dilation)
    }

    /// Reads what [`Profile::to_wire`] wrote.
    pub fn from_wire(text: &str) -> Result<Profile, ProfileError> {
        let (source, dilation) = match text.rsplit_once("\n# in force\n__dilation = ") {
            Some((s, d)) => (s, d.trim().parse::<f64>().ok()),
            None => (text, None),
        };
        let p = Profile::from_toml("(sent by the host)", source)?;
        Ok(match dilation {
            Some(d) if d.is_finite() && d > 0.0 => p.with_dilation(d),
            _ => p,
        })
    }
}

impl CpuSpec {
    fn all(&self) -> Vec<f64> {
        vec![
            self.grid_step_us,
            self.patch_test_us,
            self.light_ray_us,
            self.view_ray_us,
            self.shade_us,
            self.box_test_us,
            self.element_us,
            self.vertex_us,
            self.block_us,
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtins_parse_and_native_is_native() {
        for (n, _) in BUILTIN {
            Profile::named(n).unwrap();
        }
        assert!(Profile::named("native").unwrap().is_native());
        assert!(!Profile::named("magg1993").unwrap().is_native());
    }

    #[test]
    fn design_figures_hold() {
        // The paper's measurements: a 2 KB block costs about 1.2 ms on a link and 24 us on the G-bus.
        let p = Profile::named("magg1993").unwrap();
        let link = p.path(Path::Link).unwrap().cost(2048).as_secs_f64();
        let gbus = p.path(Path::Gbus).unwrap().cost(2048).as_secs_f64();
        assert!((link - 1.2e-3).abs() < 0.1e-3, "link {link}");
        assert!((gbus - 24e-6).abs() < 6e-6, "gbus {gbus}");
    }

    #[test]
    fn unknown_name_lists_builtins() {
        let e = Profile::named("no-such-profile").unwrap_err().to_string();
        assert!(e.contains("native") && e.contains("magg1993"), "{e}");
    }

    #[test]
    fn bad_values_are_refused_with_the_field() {
        let e = Profile::from_toml("x.toml", "name = \"x\"\n[link]\nbandwidth_mb_s = 0\n").unwrap_err().to_string();
        assert!(e.contains("x.toml") && e.contains("link.bandwidth_mb_s"), "{e}");
        let e = Profile::from_toml("x.toml", "name = \"x\"\ndilation = -1\n").unwrap_err().to_string();
        assert!(e.contains("dilation"), "{e}");
        let e = Profile::from_toml("x.toml", "name = \"x\"\n[cpu]\nshade_us = -3\n").unwrap_err().to_string();
        assert!(e.contains("cpu"), "{e}");
    }

    #[test]
    fn wire_round_trip_keeps_dilation() {
        let p = Profile::named("magg1993").unwrap().with_dilation(7.5);
        let q = Profile::from_wire(&p.to_wire()).unwrap();
        assert_eq!(q.dilation, 7.5);
        assert_eq!(q.link, p.link);
        assert_eq!(q.cpu, p.cpu);
    }
}
