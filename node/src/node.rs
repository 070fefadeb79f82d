//! A node's life: connect, register, run workers until the host says done.

use crate::connect::connect_with_backoff;
use crate::fork_blocks::ForkBlocks;
use crate::pace::{NodePace, Processor};
use crate::report::{Totals, WorkerTotals};
use crate::work::Worker;
use crate::NodeError;
use magg_core::blocks::{BlockCache, BlockSource, CacheSize};
use magg_core::header::SceneHeader;
use magg_core::kept::KeptPairs;
use magg_core::view::SceneView;
use magg_plumbing::auth::{AddToken, Authed, Token};
use magg_plumbing::retry::Backoff;
use magg_plumbing::transport::InProcess;
use magg_proto::convert::cache_size_from_wire;
use magg_proto::v1::fork_client::ForkClient;
use magg_proto::v1::host_client::HostClient;
use magg_proto::v1::register_reply::PilotPairs;
use magg_proto::v1::{RegisterReply, RegisterRequest};
use magg_proto::PROTOCOL_VERSION;
use magg_throttle::{Profile, Scheme};
use prost::Message;
use std::sync::Arc;
use tokio::runtime::Handle;

/// Blocks fetched per cache miss when the cache is unlimited: the missed one and the
/// uncached ones after it on the same fork, scene blocks (subspaces, patches, elements)
/// and vertex-energy blocks apart (up to 8 MiB per request).
pub const PREFETCH_BLOCKS: u32 = 4096;

/// How to run a node.
#[derive(Clone, Debug)]
pub struct NodeConfig {
    /// Host address (`HOST:PORT`).
    pub host: String,
    /// Worker threads (each with its own share of the cache).
    pub threads: u32,
    /// Cache blocks per node, overriding the host's choice (`None`: the host's).
    pub cache_blocks: Option<CacheSize>,
    /// Name shown in the host's logs.
    pub name: String,
    /// Connection retries.
    pub backoff: Backoff,
    /// Extra time spent per pixel row: emulates a slow or overloaded node (to watch
    /// adaptive redivision and straggler handling).
    pub row_delay: std::time::Duration,
    /// The hardware profile this node was started with (`--profile`): a render with
    /// another one is refused. `None`: run whatever the host sends.
    pub profile: Option<String>,
    /// Extra time spent per (light, element) pair: emulates a slow node in LRT (to
    /// watch pair leases expire and move to others).
    pub pair_delay: std::time::Duration,
    /// Cluster token presented on every call (none: the cluster checks none).
    pub token: Token,
    /// Cores to pin the workers to (worker j on `cores[j % len]`, see
    /// [`magg_core::placement`]); empty (the default): the kernel places them.
    pub cores: Vec<usize>,
    /// The host and forks of this process, reached without sockets (the in-process
    /// harness); a node process of its own has none.
    pub links: InProcess,
}

impl Default for NodeConfig {
    fn default() -> Self {
        NodeConfig {
            host: "127.0.0.1:7000".into(),
            threads: 1,
            cache_blocks: None,
            name: "node".into(),
            backoff: Backoff::default(),
            row_delay: std::time::Duration::ZERO,
            profile: None,
            pair_delay: std::time::Duration::ZERO,
            token: Token::default(),
            cores: Vec::new(),
            links: InProcess::none(),
        }
    }
}

/// What a node did.
#[derive(Clone, Debug, Default)]
pub struct NodeSummary {
    /// Its id.
    pub node: u32,
    /// Pairs traced.
    pub pairs: u64,
    /// Subscreens traced.
    pub tiles: u64,
}

/// Runs a node on a runtime of its own (the `magg-node` binary).
pub fn run(cfg: &NodeConfig) -> Result<NodeSummary, NodeError> {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(|e| NodeError::Runtime(e.to_string()))?;
    run_with_runtime(rt.handle().clone(), cfg)
}

/// Runs a node whose RPCs go through `rt`. Must be called from a thread that is not one
/// of the runtime's (the kernels block on it).
///
/// A render may be several scenes on one host (refinement's pilot levels, then the
/// render): the node registers for each, until the host's DONE says no other follows.
/// The pairs it traced for the pilots are kept over those scenes (where its process
/// shares none: see [`magg_core::kept::KeptPairs`]).
pub fn run_with_runtime(rt: Handle, cfg: &NodeConfig) -> Result<NodeSummary, NodeError> {
    let channel = rt.block_on(connect_with_backoff(&cfg.links, &cfg.host, cfg.backoff))?;
    let auth = AddToken(cfg.token.clone());
    let host = magg_plumbing::with_message_limits!(HostClient::with_interceptor(channel, auth.clone()));
    let own_pairs = Arc::new(KeptPairs::default());
    let mut summary = NodeSummary::default();
    loop {
        let reg = register(&rt, host.clone(), cfg)?;
        let scene = run_scene(&rt, cfg, host.clone(), &auth, reg, &own_pairs)?;
        summary.node = scene.node;
        summary.pairs += scene.pairs;
        summary.tiles += scene.tiles;
        if !scene.next_scene {
            return Ok(summary);
        }
        tracing::debug!(node = scene.node, "the render goes on with another scene: registering again");
    }
}

/// Registers with the host, asking again (with backoff) while it prepares the next
/// scene of its render.
fn register(rt: &Handle, mut host: HostClient<Authed>, cfg: &NodeConfig) -> Result<RegisterReply, NodeError> {
    let req =
        RegisterRequest { protocol_version: PROTOCOL_VERSION, name: cfg.name.clone(), threads: cfg.threads.max(1) };
    let t0 = std::time::Instant::now();
    let mut delay = cfg.backoff.initial;
    loop {
        // A listener that accepts and never answers (not a magg-host) is given up on at
        // the connection deadline, naming it.
        let reply = rt
            .block_on(async { tokio::time::timeout(cfg.backoff.deadline, host.register(req.clone())).await })
            .map_err(|_| NodeError::Connect {
                addr: cfg.host.clone(),
                reason: format!("no answer to Register within {:?} (is it a magg-host?)", cfg.backoff.deadline),
            })?;
        match reply {
            Ok(r) => return Ok(r.into_inner()),
            Err(status)
                if status.code() == tonic::Code::Unavailable
                    && status.message() == magg_proto::NEXT_SCENE
                    && t0.elapsed() < cfg.backoff.deadline =>
            {
                std::thread::sleep(delay);
                delay = (delay * 2).min(cfg.backoff.max);
            }
            Err(status) => return Err(NodeError::rpc("Register")(status)),
        }
    }
}

/// What a node did in one scene.
struct SceneSummary {
    node: u32,
    pairs: u64,
    tiles: u64,
    /// The host said that another scene of the render follows.
    next_scene: bool,
}

/// Runs the workers on the scene of registration `reg` until the host says done.
fn run_scene(
    rt: &Handle,
    cfg: &NodeConfig,
    host: HostClient<Authed>,
    auth: &AddToken,
    reg: RegisterReply,
    own_pairs: &Arc<KeptPairs>,
) -> Result<SceneSummary, NodeError> {
    let rt = rt.clone();
    let profile = if reg.profile.is_empty() {
        Profile::native()
    } else {
        Profile::from_wire(&reg.profile).map_err(|e| NodeError::Convert(e.to_string()))?
    };
    if let Some(mine) = &cfg.profile {
        if *mine != profile.name {
            return Err(NodeError::Convert(format!(
                "the host runs hardware profile {:?} but this node was started with --profile {mine:?}",
                profile.name
            )));
        }
    }
    let scheme = Scheme::parse(&reg.scheme).unwrap_or_default();
    let pace = NodePace::new(profile).map(Arc::new);
    if let Some(p) = &pace {
        // The scene header came down the link.
        p.recv_blocking(reg.encoded_len());
    }
    let wire_header = reg.header.ok_or_else(|| NodeError::Convert("registration without a scene header".into()))?;
    let header: Arc<SceneHeader> =
        Arc::new(SceneHeader::try_from(wire_header).map_err(|e| NodeError::Convert(e.to_string()))?);
    if reg.fork_addrs.is_empty() || reg.home_fork as usize >= reg.fork_addrs.len() {
        return Err(NodeError::Convert(format!("home fork {} of {} forks", reg.home_fork, reg.fork_addrs.len())));
    }
    let mut forks = Vec::with_capacity(reg.fork_addrs.len());
    for addr in &reg.fork_addrs {
        let ch = rt.block_on(connect_with_backoff(&cfg.links, addr, cfg.backoff))?;
        forks.push(magg_plumbing::with_message_limits!(ForkClient::with_interceptor(ch, auth.clone())));
    }
    let home = reg.home_fork as usize;
    let cache_blocks = cfg.cache_blocks.unwrap_or(cache_size_from_wire(reg.cache_blocks)).blocks();
    let threads = cfg.threads.max(1) as usize;
    // The node's cache is split evenly over its workers.
    let per_worker = cache_blocks.map(|c| (c as usize / threads).max(1));
    let totals = Arc::new(Totals::new(threads).paced(pace.clone()));
    tracing::info!(node = reg.node, home, threads, ?cache_blocks, "registered with {}", cfg.host);
    let overlap = crate::work::overlap_pays(pace.is_some(), &cfg.links, &reg.fork_addrs);
    // Refinement's pairs: those the host of this process shares, or else this node's own.
    let pilot_pairs = PilotPairs::try_from(reg.pilot_pairs).unwrap_or(PilotPairs::None);
    let shared = (reg.kept_pairs != 0)
        .then(|| cfg.links.shared(reg.kept_pairs))
        .flatten()
        .and_then(|v| v.downcast::<KeptPairs>().ok());
    let kept_pairs = match pilot_pairs {
        PilotPairs::None => None,
        PilotPairs::Trace => Some(shared.unwrap_or_else(|| own_pairs.clone())),
        // Nothing to bin where this node traced no pilot pair.
        PilotPairs::Bin => shared.or_else(|| (!own_pairs.is_empty()).then(|| own_pairs.clone())),
    };
    let pilot = pilot_pairs == PilotPairs::Trace;

    let handles: Vec<_> = (0..threads)
        .map(|index| {
            let fetching = Arc::new(std::sync::atomic::AtomicU64::new(0));
            let source: Arc<dyn BlockSource> = Arc::new(
                ForkBlocks::new(forks[home].clone(), rt.clone(), cfg.backoff)
                    .paced(pace.clone())
                    .timed(fetching.clone()),
            );
            let l = header.layout;
            let mut cache = BlockCache::new(source, per_worker).with_home(home as u32, forks.len() as u32);
            // The paper's scheme asks for one block per request.
            if scheme == Scheme::Magg {
                cache = cache.with_prefetch(
                    PREFETCH_BLOCKS,
                    forks.len() as u32,
                    // Scene blocks (subspaces, patches, elements) in one run, the vertex
                    // energies (new for each viewing pass) in another.
                    vec![0, l.vertex_base, l.total],
                );
            }
            let worker = Worker {
                index,
                node: reg.node,
                secret: reg.node_secret,
                view: SceneView::new(header.clone(), cache),
                rt: rt.clone(),
                host: host.clone(),
                forks: forks.clone(),
                home,
                totals: totals.clone(),
                mine: WorkerTotals::default(),
                row_delay: cfg.row_delay,
                pace: pace.clone(),
                cpu: Processor::default(),
                scheme,
                pair_delay: cfg.pair_delay,
                backoff: cfg.backoff,
                overlap,
                vrt: Default::default(),
                fetching,
                kept_pairs: kept_pairs.clone(),
                pilot,
            };
            let cores = cfg.cores.clone();
            std::thread::Builder::new()
                .name(format!("magg-node-{}-{index}", reg.node))
                .spawn(move || {
                    if !magg_core::placement::pin_worker(&cores, index) {
                        tracing::debug!(?cores, "could not pin the worker: the kernel places it");
                    }
                    worker.run()
                })
                .map_err(|e| NodeError::Worker(e.to_string()))
        })
        .collect::<Result<_, _>>()?;
    let (mut first_err, mut next_scene) = (None, false);
    for h in handles {
        match h.join().unwrap_or_else(|_| Err(NodeError::Worker("a worker panicked".into()))) {
            Ok(next) => next_scene |= next,
            Err(e) => first_err = first_err.or(Some(e)),
        }
    }
    if let Some(e) = first_err {
        return Err(e);
    }
    let s = totals.sum();
    Ok(SceneSummary { node: reg.node, pairs: s.pairs, tiles: s.tiles, next_scene })
}
