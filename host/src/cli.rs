//! Command-line interface of `magg-host` (clap derive), and its validation into a
//! [`RenderConfig`] before anything runs.

use anyhow::{bail, Context};
use clap::{Args, Parser, Subcommand};
use magg_core::blocks::CacheSize;
use std::path::PathBuf;

/// magg: a parallel bidirectional ray tracer after the MAGG transputer system (1993).
#[derive(Debug, Parser)]
#[command(name = "magg-host", version, about, long_about = None)]
pub struct Cli {
    /// More log output (-v: info, -vv: debug, -vvv: trace); RUST_LOG overrides.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    pub verbose: u8,
    /// Also read mesh files (OBJ, MTL) from this folder and below; by default only the
    /// scene's own folder is. Repeat for more folders.
    #[arg(long, global = true, value_name = "DIR", env = "MAGG_ALLOW_PATH", value_delimiter = ':')]
    pub allow_path: Vec<PathBuf>,
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Render a scene to an image (PNG tone-mapped; EXR or PFM linear, by extension).
    ///
    /// Runs the light pass (LRT), energy interpolation and the viewing pass (VRT) on the
    /// cluster: by default forks and nodes started inside this process, talking gRPC over
    /// 127.0.0.1 ports; `--forks-at` and `--external-nodes` use separate magg-fork and
    /// magg-node processes; `--embedded` drives the rendering core directly. The image is
    /// the same, bit for bit, in every case.
    Render(RenderArgs),
    /// Print a scene's counts (patches, elements, vertices, subspaces, blocks of each
    /// kind) and its effects plan, without rendering.
    Info(InfoArgs),
    /// Measure error against a converged reference versus render time over a grid of
    /// accuracy settings (docs/ACCURACY.md): writes accuracy.csv and prints the Pareto
    /// front as a markdown table.
    Accuracy(crate::commands::accuracy::AccuracyArgs),
    /// Redo the paper's experiments (its figures 4-11): render on the cluster under a
    /// hardware profile over nodes x cache blocks x forks x schedule; writes sweep.csv,
    /// one PNG per figure and a markdown table (docs/EXPERIMENTS.md).
    Sweep(crate::commands::sweep::SweepArgs),
    /// Compare image A with the reference B (.pfm, .exr, .hdr linear; .png, .jpg, .tif
    /// decoded from sRGB): print relMSE, MSE, the brightness ratio and the largest
    /// difference, optionally write a heat map of the error; exit 0 (2 with --fail-above X
    /// when relMSE > X).
    Diff(crate::commands::diff::DiffArgs),
    /// Write the scene for another renderer (`--mitsuba`: Mitsuba 3's scene.xml and PLY
    /// meshes), after --set, --quality and the knob flags, to make an independent
    /// reference image (docs/ACCURACY.md).
    Export(crate::commands::export::ExportArgs),
    /// Ask the gRPC health service at ADDR (HOST:PORT: a magg-fork, a magg-node with
    /// --health-listen, or a host while it renders) and exit 0 when it reports SERVING:
    /// the health check of a container image that has no shell.
    Probe(magg_plumbing::flags::ProbeArgs),
}

/// Arguments of `render`.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// Scene file (TOML), e.g. scenes/cornell.toml.
    pub scene: PathBuf,
    /// Output image, by extension: .png, .jpg, .tif (tone-mapped sRGB); .exr, .hdr, .pfm
    /// (linear radiance).
    #[arg(short, long)]
    pub out: PathBuf,
    /// Also write the linear image to this .exr, .hdr or .pfm file.
    #[arg(long)]
    pub linear: Option<PathBuf>,
    /// Nodes started in this process (0 = one per core); each is a thread.
    #[arg(long, visible_alias = "threads", default_value_t = 0)]
    pub nodes: u32,
    /// Forks started in this process; the 2 KB blocks are interleaved over them (block b
    /// on fork b mod F).
    #[arg(long, default_value_t = 5)]
    pub forks: u32,
    /// Fewest patches of a share: the scene is prepared in shares, one per fork at most,
    /// each of at least this many patches (a smaller scene is one share). The image is
    /// the same for every value; only who prepares what and the BVH's shape change.
    #[arg(long, default_value_t = magg_prepare::shares::MIN_SHARE_PATCHES)]
    pub share_patches: usize,
    /// LRU cache size per node, in 2 KB blocks, or "unlimited".
    // Text until `validate` makes it a `CacheSize`: a bad value is then one error line.
    #[arg(long, default_value = "unlimited")]
    pub cache_blocks: String,
    /// Hardware profile, the machine to emulate (docs/EXPERIMENTS.md): a built-in name,
    /// "native" (nothing throttled) or "magg1993" (the paper's transputers, links, DMA and
    /// G-bus), or a profile file
    /// (deploy/profiles/*.toml). Stage times of a throttled run are modelled seconds.
    #[arg(long, default_value = "native", env = "MAGG_PROFILE")]
    pub profile: String,
    /// Real seconds per modelled second, overriding the profile's: raise it when the
    /// stats' emulation.real_cpu_share passes 0.5.
    #[arg(long)]
    pub dilation: Option<f64>,
    /// Schedule: "magg" (ours: batched and guided pair hand-out, batched deposits,
    /// prefetched blocks, preprocessing over every fork) or "paper" (one pair per
    /// request, one block per request, preprocessing on one fork). Same image.
    #[arg(long, default_value = "magg")]
    pub scheme: String,
    /// Write run statistics (JSON) here.
    #[arg(long)]
    pub stats: Option<PathBuf>,
    /// Write element and vertex energies (CSV) here.
    #[arg(long)]
    pub energy: Option<PathBuf>,
    /// Save the light pass (element and vertex energies, exactly, with a fingerprint of the
    /// scene and light settings) to this file, for --load-energy.
    #[arg(long, value_name = "FILE")]
    pub save_energy: Option<PathBuf>,
    /// Skip the light pass: use the energies saved in this file by --save-energy. A file
    /// made for other geometry, materials, lights or light settings is refused; the
    /// camera, image size and pixel samples may differ.
    #[arg(long, value_name = "FILE")]
    pub load_energy: Option<PathBuf>,
    /// Force every optional effect on, whatever the scene needs (the image is identical;
    /// only the time differs).
    #[arg(long)]
    pub all_effects: bool,
    /// Subscreen edge in pixels (VRT work unit).
    #[arg(long, default_value_t = 16)]
    pub subscreen: u32,
    /// Drive the rendering core directly in this process (no gRPC): the reference the
    /// cluster is measured and tested against.
    #[arg(long, conflicts_with_all = ["forks_at", "external_nodes"])]
    pub embedded: bool,
    /// How the in-process forks, nodes and host call each other: in-process (gRPC
    /// without sockets, the default) or tcp (every call over 127.0.0.1, as between
    /// processes). The image is the same; see docs/PERFORMANCE.md.
    #[arg(long, value_enum, default_value = "in-process", env = "MAGG_TRANSPORT")]
    pub transport: magg_plumbing::transport::Mode,
    /// Use these running magg-fork processes (comma-separated HOST:PORT) instead of
    /// starting forks in this process.
    #[arg(long, value_delimiter = ',', env = "MAGG_FORKS_AT")]
    pub forks_at: Vec<String>,
    /// Address to serve nodes (and gRPC health) on (HOST:PORT; port 0 picks a free one).
    #[arg(long, default_value = "127.0.0.1:0", env = "MAGG_HOST_LISTEN")]
    pub listen: String,
    /// Start no node in this process: wait for magg-node processes to register.
    #[arg(long, env = "MAGG_EXTERNAL_NODES")]
    pub external_nodes: bool,
    /// With --external-nodes: start the light pass once this many nodes have registered
    /// (or after --stall-timeout with those that have), so that every node takes part.
    #[arg(long, default_value_t = 0, env = "MAGG_MIN_NODES")]
    pub min_nodes: u32,
    /// Abort when a phase makes no progress for this many seconds.
    #[arg(long, default_value_t = 60)]
    pub stall_timeout: u64,
    /// No progress bars or summary.
    #[arg(short, long)]
    pub quiet: bool,
    /// Accuracy preset, applied before the knob flags below (which override it).
    /// draft: elements x2 the scene's size (fixed subdivisions halved), a quarter of its
    /// light rays per pair, 1 pixel sample, the scene's refinement; good: the scene's own
    /// settings; final: the scene's elements, four times its light rays per pair, 16
    /// pixel samples, one more level of refinement. See docs/ACCURACY.md.
    #[arg(long, value_enum)]
    pub quality: Option<magg_study::accuracy::preset::Quality>,
    /// Serve a live view of the render on this address (HOST:PORT, port 0 picks a free
    /// one; the URL is printed): the frame filling in, the subscreens by node, the stage
    /// and a table per node, and the finished image as PNG and EXR.
    #[arg(long, value_name = "ADDR")]
    pub view: Option<String>,
    /// With --view: start rendering only once a page has opened the live view (waits at
    /// most 10 minutes).
    #[arg(long, requires = "view")]
    pub view_wait: bool,
    /// With --view: keep serving the page this many seconds after the render is done.
    #[arg(long, value_name = "SECS", default_value_t = 0, requires = "view")]
    pub view_linger: u64,
    /// Scene overrides: accuracy knobs and output size.
    #[command(flatten)]
    pub knobs: Knobs,
    /// Overrides of any scene value (`--set KEY=VALUE`).
    #[command(flatten)]
    pub set: crate::overrides::SetArgs,
    /// What part to render: a crop window, a range of frames.
    #[command(flatten)]
    pub framing: crate::framing::FramingArgs,
    /// Fault handling and access: node leases, fork timeout, cluster token.
    #[command(flatten)]
    pub faults: crate::faults::FaultArgs,
}

/// Overrides of the scene's `[render]` settings.
#[derive(Debug, Default, Args)]
pub struct Knobs {
    /// Image width in pixels.
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height in pixels.
    #[arg(long)]
    pub height: Option<u32>,
    /// Viewing rays per pixel.
    #[arg(long, visible_alias = "spp")]
    pub pixel_samples: Option<u32>,
    /// Light rays per (light, element) pair.
    #[arg(long)]
    pub light_rays: Option<u32>,
    /// Diffuse bounce rays per light ray of a pair traced only for its bounce (direct
    /// light at VRT, a diffuse target): it casts light-rays / bounce-rays light rays.
    #[arg(long)]
    pub bounce_rays: Option<u32>,
    /// Gather rays per viewing ray where the elements cannot hold the bounced light
    /// (beside elements that received none, e.g. where a box stands on the floor); 0
    /// interpolates everywhere.
    #[arg(long)]
    pub gather_rays: Option<u32>,
    /// Target element edge length (patches with fixed subdivisions keep theirs).
    #[arg(long)]
    pub element_size: Option<f64>,
    /// Specular bounces of light rays.
    #[arg(long)]
    pub lrt_depth: Option<u32>,
    /// Specular bounces of viewing rays.
    #[arg(long)]
    pub vrt_depth: Option<u32>,
    /// Diffuse-to-diffuse bounces of light rays (0 = ambient term).
    #[arg(long)]
    pub diffuse_bounces: Option<u32>,
    /// Seed of every random choice.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Acceleration structure: "bvh" (the default) or "grid" (the paper's uniform grid
    /// of subspaces; the default with --scheme paper). Same image, bit for bit.
    // Text until `apply`: a bad value is then one error line.
    #[arg(long)]
    pub accel: Option<String>,
    /// Where direct light is computed: "auto" (the effects plan decides), "vrt" (a shadow
    /// ray per light, and shadow rays to points sampled on the area lights, at each
    /// diffuse hit: pixel-sharp shadows) or "lrt" (light rays onto elements, the paper's
    /// way; the default with --scheme paper).
    #[arg(long)]
    pub direct: Option<String>,
}

/// Arguments of `info`.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Overrides of any scene value (`--set KEY=VALUE`).
    #[command(flatten)]
    pub set: crate::overrides::SetArgs,
    /// Print as JSON.
    #[arg(long)]
    pub json: bool,
    /// The scene as `render --quality` would render it.
    #[arg(long, value_enum)]
    pub quality: Option<magg_study::accuracy::preset::Quality>,
}

pub use crate::images::ImageFormat;

/// A validated render command.
#[derive(Debug)]
pub struct RenderConfig {
    /// How in-process forks, nodes and host call each other.
    pub transport: magg_plumbing::transport::Mode,
    /// Scene file.
    pub scene: PathBuf,
    /// Its values overridden (`--set`).
    pub overrides: Vec<crate::overrides::Override>,
    /// The crop window and the frames (checked against the scene once it is read).
    pub framing: crate::framing::FramingArgs,
    /// Main output and its format.
    pub out: (PathBuf, ImageFormat),
    /// Extra linear output.
    pub linear: Option<(PathBuf, ImageFormat)>,
    /// Node workers (0 = cores).
    pub nodes: u32,
    /// Forks.
    pub forks: u32,
    /// How the scene is split for preparation.
    pub shares: magg_prepare::Shares,
    /// Cache blocks per node.
    pub cache_blocks: CacheSize,
    /// Hardware profile.
    pub profile: magg_throttle::Profile,
    /// Schedule.
    pub scheme: magg_throttle::Scheme,
    /// Stats file.
    pub stats: Option<PathBuf>,
    /// Energy file.
    pub energy: Option<PathBuf>,
    /// Saved-energy file to write.
    pub save_energy: Option<PathBuf>,
    /// Saved-energy file to read instead of running LRT.
    pub load_energy: Option<PathBuf>,
    /// Force every effect on.
    pub all_effects: bool,
    /// Subscreen edge.
    pub subscreen: u32,
    /// No bars or summary.
    pub quiet: bool,
    /// Accuracy preset, applied before `knobs`.
    pub quality: Option<magg_study::accuracy::preset::Quality>,
    /// Scene overrides.
    pub knobs: Knobs,
    /// Live view: address, wait for a page, seconds to linger.
    pub view: Option<(String, bool, u64)>,
    /// Where the cluster runs.
    pub mode: Mode,
    /// Memory bound in MiB (refused up front above it).
    pub max_memory_mb: u64,
}

/// How the render is run.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Mode {
    /// The rendering core driven directly, no gRPC.
    Embedded,
    /// The cluster over gRPC: forks in this process unless `forks_at` is given, nodes in
    /// this process unless `external_nodes`.
    Cluster {
        /// External forks.
        forks_at: Vec<String>,
        /// Host address for nodes.
        listen: String,
        /// Wait for external nodes instead of starting them.
        external_nodes: bool,
        /// External nodes to wait for before the light pass.
        min_nodes: u32,
        /// Phase stall limit.
        stall_timeout: std::time::Duration,
        /// Node leases, fork timeout, cluster token.
        faults: magg_cluster::FaultPolicy,
    },
}

/// Parses `--cache-blocks` ([`CacheSize`]), naming the flag in the error: a user error
/// is one line with exit code 1, as for every flag value (clap would print its usage).
pub fn parse_cache_blocks(s: &str) -> anyhow::Result<CacheSize> {
    s.parse::<CacheSize>().map_err(|e| anyhow::anyhow!("--cache-blocks {e}"))
}

impl RenderArgs {
    /// Checks every flag before anything runs.
    pub fn validate(self) -> anyhow::Result<RenderConfig> {
        // Outputs are written during and after the render: a missing folder is an error
        // now, not after minutes of tracing.
        let outputs = [Some(&self.out), self.linear.as_ref(), self.stats.as_ref(), self.energy.as_ref()];
        for p in outputs.into_iter().chain([self.save_energy.as_ref()]).flatten() {
            let dir = p.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(std::path::Path::new("."));
            if !dir.is_dir() {
                bail!("{}: cannot write there: folder {} does not exist", p.display(), dir.display());
            }
        }
        let out_fmt = ImageFormat::of(&self.out)?;
        let linear = match self.linear {
            Some(p) => {
                let f = ImageFormat::of(&p)?;
                if !f.is_linear() {
                    bail!("--linear {}: must be .exr, .hdr or .pfm", p.display());
                }
                Some((p, f))
            }
            None => None,
        };
        if self.nodes > 4096 {
            bail!("--nodes {}: at most 4096", self.nodes);
        }
        if self.forks == 0 || self.forks > 256 {
            bail!("--forks {}: must be 1..=256", self.forks);
        }
        if self.subscreen == 0 || self.subscreen > 4096 {
            bail!("--subscreen {}: must be 1..=4096", self.subscreen);
        }
        if self.forks_at.iter().any(|a| a.trim().is_empty()) {
            bail!("--forks-at: empty address in the list");
        }
        if self.stall_timeout == 0 {
            bail!("--stall-timeout 0: must be at least 1 second");
        }
        if self.view_linger > 86_400 {
            bail!("--view-linger {}: at most 86400 seconds", self.view_linger);
        }
        let mut profile =
            magg_throttle::Profile::named(&self.profile).with_context(|| format!("--profile {}", self.profile))?;
        if let Some(d) = self.dilation {
            if !(d.is_finite() && d > 0.0) {
                bail!("--dilation {d}: must be a positive number");
            }
            profile = profile.with_dilation(d);
        }
        if self.embedded && !profile.is_native() {
            bail!("--profile {}: the embedded renderer runs natively; profiles apply to the cluster", profile.name);
        }
        let Some(scheme) = magg_throttle::Scheme::parse(&self.scheme) else {
            bail!("--scheme {:?}: expected \"magg\" or \"paper\"", self.scheme);
        };
        Ok(RenderConfig {
            overrides: self.set.overrides()?,
            framing: self.framing,
            transport: self.transport,
            max_memory_mb: self.faults.max_memory_mb,
            scene: self.scene,
            out: (self.out, out_fmt),
            linear,
            nodes: self.nodes,
            forks: self.forks,
            shares: magg_prepare::Shares {
                forks: match &self.forks_at {
                    at if !at.is_empty() && !self.embedded => at.len(),
                    _ => self.forks as usize,
                },
                min_patches: self.share_patches.max(1),
            },
            cache_blocks: parse_cache_blocks(&self.cache_blocks)?,
            profile,
            scheme,
            stats: self.stats,
            energy: self.energy,
            save_energy: self.save_energy,
            load_energy: self.load_energy,
            all_effects: self.all_effects,
            subscreen: self.subscreen,
            quiet: self.quiet,
            quality: self.quality,
            knobs: self.knobs,
            view: self.view.map(|a| (a, self.view_wait, self.view_linger)),
            mode: if self.embedded {
                Mode::Embedded
            } else {
                Mode::Cluster {
                    forks_at: self.forks_at.iter().map(|a| a.trim().to_string()).collect(),
                    listen: self.listen,
                    external_nodes: self.external_nodes,
                    min_nodes: self.min_nodes,
                    stall_timeout: std::time::Duration::from_secs(self.stall_timeout),
                    faults: self.faults.policy()?,
                }
            },
        })
    }
}

impl Knobs {
    /// Applies the overrides to `s`, refusing out-of-range values.
    pub fn apply(&self, s: &mut magg_core::scene::RenderSettings) -> anyhow::Result<()> {
        fn range(name: &str, v: u32, lo: u32, hi: u32) -> anyhow::Result<u32> {
            if v < lo || v > hi {
                bail!("--{name} {v}: must be {lo}..={hi}");
            }
            Ok(v)
        }
        if let Some(v) = self.width {
            s.width = range("width", v, 1, 16384)?;
        }
        if let Some(v) = self.height {
            s.height = range("height", v, 1, 16384)?;
        }
        if let Some(v) = self.pixel_samples {
            s.pixel_samples = range("pixel-samples", v, 1, 4096)?;
        }
        if let Some(v) = self.light_rays {
            s.light_rays = range("light-rays", v, 1, 1_000_000)?;
        }
        if let Some(v) = self.bounce_rays {
            s.bounce_rays = range("bounce-rays", v, 1, magg_core::scene::MAX_BOUNCE_RAYS)?;
        }
        if let Some(v) = self.gather_rays {
            s.gather_rays = range("gather-rays", v, 0, magg_core::scene::MAX_GATHER_RAYS)?;
        }
        if let Some(v) = self.lrt_depth {
            s.lrt_depth = range("lrt-depth", v, 0, 32)?;
        }
        if let Some(v) = self.vrt_depth {
            s.vrt_depth = range("vrt-depth", v, 0, 32)?;
        }
        if let Some(v) = self.diffuse_bounces {
            s.diffuse_bounces = range("diffuse-bounces", v, 0, 16)?;
        }
        if let Some(v) = self.element_size {
            if !(v.is_finite() && v > 0.0) {
                bail!("--element-size {v}: must be a positive finite length");
            }
            s.element_size = v;
        }
        if let Some(v) = self.seed {
            s.seed = v;
        }
        if let Some(v) = &self.accel {
            let Some(a) = magg_core::scene::Accel::parse(v) else {
                bail!("--accel {v:?}: expected \"bvh\" or \"grid\"");
            };
            s.accel = a;
        }
        if let Some(v) = &self.direct {
            let Some(d) = magg_core::scene::DirectLight::parse(v) else {
                bail!("--direct {v:?}: expected \"auto\", \"vrt\" or \"lrt\"");
            };
            s.direct = d;
        }
        Ok(())
    }

    /// [`Knobs::apply`] for a render under `scheme`: the paper's scheme traces through the
    /// paper's grid and deposits direct light with light rays, unless `--accel` or
    /// `--direct` says otherwise, and keeps one element for both faces of a patch.
    pub fn apply_for(
        &self,
        scheme: magg_throttle::Scheme,
        s: &mut magg_core::scene::RenderSettings,
    ) -> anyhow::Result<()> {
        if scheme == magg_throttle::Scheme::Paper && self.accel.is_none() {
            s.accel = magg_core::scene::Accel::Grid;
        }
        if scheme == magg_throttle::Scheme::Paper && self.direct.is_none() {
            s.direct = magg_core::scene::DirectLight::Lrt;
        }
        if scheme == magg_throttle::Scheme::Paper {
            // The paper's receiving: one element for both faces of a patch, on its
            // regular lattice (no adaptive refinement).
            s.shared_faces = true;
            s.refine = 0;
        }
        self.apply(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cache_blocks_parse() {
        assert_eq!(parse_cache_blocks("unlimited").unwrap(), CacheSize::Unlimited);
        assert_eq!(parse_cache_blocks("40").unwrap().blocks(), Some(40));
        assert!(parse_cache_blocks("0").is_err());
        assert!(parse_cache_blocks("-3").is_err());
    }

    #[test]
    fn formats_by_extension() {
        assert_eq!(ImageFormat::of("a/b.PNG".as_ref()).unwrap(), ImageFormat::Png);
        assert_eq!(ImageFormat::of("x.exr".as_ref()).unwrap(), ImageFormat::Exr);
        assert_eq!(ImageFormat::of("x.jpg".as_ref()).unwrap(), ImageFormat::Jpeg);
        assert!(ImageFormat::of("x.bmp".as_ref()).is_err());
    }

    #[test]
    fn explicit_knobs_override_the_preset() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell.toml");
        let mut s = crate::scene_file::SceneFiles::default().load(&path, &[]).unwrap();
        magg_study::accuracy::preset::Quality::Final.apply(&mut s);
        let knobs = Knobs { light_rays: Some(4), ..Default::default() };
        knobs.apply(&mut s.settings).unwrap();
        assert_eq!(s.settings.light_rays, 4);
        assert_eq!(s.settings.pixel_samples, 16);
    }

    #[test]
    fn accel_is_a_knob_and_the_paper_scheme_keeps_the_grid() {
        use magg_core::scene::{Accel, RenderSettings};
        use magg_throttle::Scheme;
        let mut s = RenderSettings::default();
        Knobs::default().apply_for(Scheme::Magg, &mut s).unwrap();
        assert_eq!(s.accel, Accel::Bvh);
        Knobs::default().apply_for(Scheme::Paper, &mut s).unwrap();
        assert_eq!(s.accel, Accel::Grid);
        let bvh = Knobs { accel: Some("bvh".into()), ..Default::default() };
        bvh.apply_for(Scheme::Paper, &mut s).unwrap();
        assert_eq!(s.accel, Accel::Bvh);
        let e = Knobs { accel: Some("octree".into()), ..Default::default() }.apply(&mut s).unwrap_err();
        assert_eq!(e.to_string(), "--accel \"octree\": expected \"bvh\" or \"grid\"");
    }

    #[test]
    fn the_paper_scheme_deposits_direct_light_with_light_rays() {
        use magg_core::scene::{DirectLight, RenderSettings};
        use magg_throttle::Scheme;
        let mut s = RenderSettings::default();
        Knobs::default().apply_for(Scheme::Magg, &mut s).unwrap();
        assert_eq!(s.direct, DirectLight::Auto);
        Knobs::default().apply_for(Scheme::Paper, &mut s).unwrap();
        assert_eq!(s.direct, DirectLight::Lrt);
        let vrt = Knobs { direct: Some("vrt".into()), ..Default::default() };
        vrt.apply_for(Scheme::Paper, &mut s).unwrap();
        assert_eq!(s.direct, DirectLight::Vrt);
        assert!(Knobs { direct: Some("both".into()), ..Default::default() }.apply(&mut s).is_err());
    }

    #[test]
    fn the_paper_scheme_shares_one_element_between_both_faces() {
        use magg_core::scene::RenderSettings;
        use magg_throttle::Scheme;
        let mut s = RenderSettings { refine: 2, ..RenderSettings::default() };
        Knobs::default().apply_for(Scheme::Magg, &mut s).unwrap();
        assert!(!s.shared_faces);
        assert_eq!(s.refine, 2);
        Knobs::default().apply_for(Scheme::Paper, &mut s).unwrap();
        assert!(s.shared_faces);
        assert_eq!(s.refine, 0, "the paper's regular lattice");
    }
}
