//! One run of the sweep: a `magg-host render` child process (in-process cluster) or a
//! `deploy/local-cluster.sh` multi-process cluster, with its stats read back into a row.

use crate::error::{Result, StudyError};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Where one run happens; `host` is the `magg-host` binary (the application passes its
/// own path).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Runner {
    /// `host render` as a child process: forks and nodes in its process.
    InProcess {
        /// The `magg-host` binary.
        host: PathBuf,
    },
    /// `deploy/local-cluster.sh` at `script`: forks and nodes as separate processes, with
    /// the binaries next to `host` (`MAGG_BIN`).
    MultiProcess {
        /// The cluster script.
        script: PathBuf,
        /// The `magg-host` binary.
        host: PathBuf,
    },
}

/// The shape of one run.
#[derive(Clone, Debug, PartialEq)]
pub struct Shape {
    /// Schedule (`paper` or `magg`).
    pub scheme: String,
    /// Forks.
    pub forks: u32,
    /// Nodes.
    pub nodes: u32,
    /// Cache blocks per node.
    pub cache_blocks: u32,
    /// Dilation used.
    pub dilation: f64,
    /// Acceleration structure (`grid`, the paper's, or `bvh`).
    pub accel: String,
}

impl Shape {
    /// The run's schedule as the figures name it: the scheme, with the acceleration
    /// structure after it when that is not the paper's grid (`magg-bvh`).
    pub fn schedule(&self) -> String {
        if self.accel == "grid" {
            self.scheme.clone()
        } else {
            format!("{}-{}", self.scheme, self.accel)
        }
    }
}

/// The CSV columns, in order.
pub const COLUMNS: &[&str] = &[
    "scheme",
    "profile",
    "mode",
    "forks",
    "nodes",
    "cache_blocks",
    "dilation",
    "real_cpu_share",
    "preprocess_s",
    "lrt_s",
    "interp_s",
    "vrt_s",
    "total_s",
    "hits",
    "misses",
    "hit_ratio",
    "link_bytes",
    "dma_bytes",
    "gbus_bytes",
    "rpcs",
    "pairs",
    "tiles",
    "redivisions",
    "node_cpu_s",
    "link_busy_s",
    "dma_busy_s",
    "gbus_busy_s",
    "fork_busy_s",
    "accel",
    "light_rays",
    "view_rays",
    "prefetched",
];

/// One measured run: its shape and the values of [`COLUMNS`].
#[derive(Clone, Debug)]
pub struct Row {
    /// The shape.
    pub shape: Shape,
    /// Values by column name, as written to the CSV.
    pub values: Vec<(String, String)>,
}

impl Row {
    /// A numeric column.
    pub fn num(&self, column: &str) -> f64 {
        self.values.iter().find(|(k, _)| k == column).and_then(|(_, v)| v.parse().ok()).unwrap_or(f64::NAN)
    }

    /// Blocks fetched per cache read: the misses and the blocks fetched ahead of any
    /// read (our scheme; a read of one is a hit), over the reads. Unlike the miss ratio
    /// it counts every block a node fetched, so the two schemes compare.
    pub fn fetched_per_read(&self) -> f64 {
        let prefetched = self.num("prefetched");
        let prefetched = if prefetched.is_nan() { 0.0 } else { prefetched };
        (self.num("misses") + prefetched) / (self.num("hits") + self.num("misses"))
    }

    /// Bytes the forks sent the nodes (DMA) per ray traced, light and viewing rays.
    pub fn dma_bytes_per_ray(&self) -> f64 {
        self.num("dma_bytes") / (self.num("light_rays") + self.num("view_rays"))
    }

    /// Reads a row from a stats JSON file.
    pub fn from_stats(shape: Shape, stats: &Value) -> Row {
        let get = |path: &[&str]| -> String {
            let mut v = stats;
            for p in path {
                v = &v[*p];
            }
            match v {
                Value::Null => String::new(),
                Value::String(s) => s.clone(),
                other => other.to_string(),
            }
        };
        let values = COLUMNS
            .iter()
            .map(|&c| {
                let v = match c {
                    "scheme" => shape.scheme.clone(),
                    "forks" => shape.forks.to_string(),
                    "nodes" => get(&["nodes"]),
                    "cache_blocks" => shape.cache_blocks.to_string(),
                    "dilation" => shape.dilation.to_string(),
                    "real_cpu_share" => get(&["emulation", "real_cpu_share"]),
                    "preprocess_s" | "lrt_s" | "interp_s" | "vrt_s" | "total_s" => get(&["stages", c]),
                    "hits" | "misses" | "hit_ratio" | "prefetched" => get(&["cache", c]),
                    "link_bytes" | "dma_bytes" | "gbus_bytes" | "rpcs" => get(&["traffic", c]),
                    "pairs" | "tiles" | "redivisions" | "light_rays" | "view_rays" => get(&["work", c]),
                    "accel" => shape.accel.clone(),
                    "node_cpu_s" => get(&["emulation", "busy", "node_cpu_s"]),
                    "link_busy_s" => get(&["emulation", "busy", "link_s"]),
                    "dma_busy_s" => get(&["emulation", "busy", "dma_s"]),
                    "gbus_busy_s" => get(&["emulation", "busy", "gbus_s"]),
                    "fork_busy_s" => get(&["emulation", "busy", "fork_s"]),
                    other => get(&[other]),
                };
                (c.to_string(), v)
            })
            .collect();
        Row { shape, values }
    }
}

/// Writes `rows` to `path` as CSV: the header [`COLUMNS`], then one record per run.
pub fn write_csv(path: &Path, rows: &[Row]) -> Result<()> {
    let write = || -> csv::Result<()> {
        let mut out = csv::Writer::from_path(path)?;
        out.write_record(COLUMNS)?;
        for r in rows {
            out.write_record(r.values.iter().map(|(_, v)| v))?;
        }
        out.flush()?;
        Ok(())
    };
    write().map_err(|reason| StudyError::Csv { path: path.to_path_buf(), reason })
}

/// Runs one render of `scene` with `shape`, writing its stats to `stats` and its image
/// to `image`; `extra` are further `render` flags (e.g. `--width 200`).
pub fn run_one(
    runner: &Runner,
    scene: &Path,
    profile: &str,
    shape: &Shape,
    image: &Path,
    stats: &Path,
    extra: &[String],
) -> Result<Row> {
    let flags: Vec<String> = [
        "--stats".to_string(),
        stats.display().to_string(),
        "--cache-blocks".into(),
        shape.cache_blocks.to_string(),
        "--profile".into(),
        profile.to_string(),
        "--dilation".into(),
        shape.dilation.to_string(),
        "--scheme".into(),
        shape.scheme.clone(),
        // The paper's experiments trace through the paper's grid unless the sweep asks
        // for the BVH too.
        "--accel".into(),
        shape.accel.clone(),
        "-q".into(),
    ]
    .into_iter()
    .chain(extra.iter().cloned())
    .collect();
    let mut cmd = match runner {
        Runner::InProcess { host } => {
            let mut c = Command::new(host);
            c.arg("render").arg(scene).arg("--out").arg(image);
            c.args(["--nodes", &shape.nodes.to_string(), "--forks", &shape.forks.to_string()]);
            c.args(&flags);
            c
        }
        Runner::MultiProcess { script, host } => {
            let mut c = Command::new("bash");
            c.arg(script).arg(scene).arg(image);
            c.args(["--forks", &shape.forks.to_string(), "--nodes", &shape.nodes.to_string(), "--"]);
            c.args(&flags);
            if let Some(dir) = host.parent() {
                c.env("MAGG_BIN", dir);
            }
            c
        }
    };
    let failed = |reason: String| StudyError::Run { run: format!("{shape:?}"), reason };
    let out = cmd.output().map_err(|e| failed(format!("cannot start: {e}")))?;
    if !out.status.success() {
        let last = String::from_utf8_lossy(&out.stderr).lines().last().unwrap_or("").to_string();
        return Err(failed(format!("failed ({}): {last}", out.status)));
    }
    let text = std::fs::read_to_string(stats).map_err(StudyError::io("read", stats))?;
    let json: Value =
        serde_json::from_str(&text).map_err(|e| failed(format!("cannot parse {}: {e}", stats.display())))?;
    let mut row = Row::from_stats(shape.clone(), &json);
    let mode = if matches!(runner, Runner::InProcess { .. }) { "in-process" } else { "multi-process" };
    for (k, v) in row.values.iter_mut() {
        if k == "mode" {
            *v = mode.to_string();
        }
    }
    Ok(row)
}
