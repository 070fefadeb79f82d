//! # magg-throttle: the 1993 machine on today's hardware
//!
//! A run with a hardware profile behaves like the MAGG system of Kawai et al. (1993):
//! every message pays for its bytes on the path it travels (the T800
//! serial **link** between a node and its fork or the host, the **DMA** bus inside a GPU
//! card from a fork to its nodes, the shared **G-bus** between forks), every fork pays a
//! service time per request, and every node pays for its computation through a
//! deterministic cost model (operations counted by the kernels times a per-operation
//! cost of a T800-20).
//!
//! Costs are imposed with *token-debt* accounting on [`Resource`]s: a user reserves the
//! resource for the message's modelled time and only sleeps once its debt exceeds a
//! timer tick, so that a stream of 24 µs G-bus transfers is paced correctly although the
//! timer cannot sleep for 24 µs. A resource shared by several users (a fork's DMA engine,
//! the one usable G-bus) serialises them.
//!
//! Every modelled cost is multiplied by the profile's **dilation** in real time, and
//! reported times are divided by it, so that the real costs of the emulating machine
//! (RPCs, scheduling 80 nodes on 2 cores) stay small beside the modelled ones.
//!
//! ```
//! use magg_throttle::{Path, Profile};
//! let p = Profile::named("magg1993").unwrap();
//! // A 2 KB block costs about 1.2 ms on a T800 link.
//! let t = p.path(Path::Link).unwrap().cost(2048);
//! assert!((t.as_secs_f64() - 1.2e-3).abs() < 0.1e-3);
//! // The native profile throttles nothing: the layer is out of the path.
//! assert!(Profile::named("native").unwrap().is_native());
//! ```

mod cost;
mod profile;
mod resource;

pub use cost::{preprocess_ops, CpuCost};
pub use profile::{CpuSpec, ForkSpec, Path, PathSpec, Profile, ProfileError, BUILTIN};
pub use resource::{wait, wait_blocking, Resource, BURST, SLACK};

/// How the cluster schedules its work (docs/ARCHITECTURE.md, the throttling layer): the paper's choices or ours.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Scheme {
    /// The paper's scheme: serial preprocessing on one fork, one request per block, one
    /// pair per request.
    Paper,
    /// Ours: parallel preprocessing, batched and prefetched block requests, guided
    /// batches of pairs and batched deposits.
    #[default]
    Magg,
}

impl Scheme {
    /// The name used on the command line and in stats.
    pub fn name(self) -> &'static str {
        match self {
            Scheme::Paper => "paper",
            Scheme::Magg => "magg",
        }
    }

    /// Parses `paper` or `magg`.
    pub fn parse(s: &str) -> Option<Scheme> {
        match s {
            "paper" => Some(Scheme::Paper),
            "magg" => Some(Scheme::Magg),
            _ => None,
        }
    }
}
