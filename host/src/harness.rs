//! The single-process harness: F forks, N nodes and the host in this process, so that
//! `magg-host render` needs no set-up and exercises exactly the services of a
//! multi-process run. Each server listens on a 127.0.0.1 port and registers for the
//! in-process transport ([`magg_plumbing::transport`]): calls between them are gRPC
//! (encoded, intercepted, size-checked) without sockets, unless `--transport tcp`.

use anyhow::Context;
use magg_cluster::{ClusterMachine, DriveOptions, FaultPolicy, HostSocket};
use magg_core::kept::KeptPairs;
use magg_core::machine::{FrameSink, RenderOutput, Sequence};
use magg_core::machine::{LightPass, Machine, RenderError};
use magg_core::prepared::PreparedScene;
use magg_core::progress::Progress;
use magg_plumbing::transport::{InProcess, Mode as TransportMode};
use magg_prepare::refine::Pilots;
use std::sync::Arc;
use std::time::Duration;
use tokio::net::TcpListener;

/// How a started in-process (or partly external) cluster renders; where its forks and
/// host listen is its [`ClusterShape`].
#[derive(Clone, Debug)]
pub struct InProcessOptions {
    /// Nodes to run in this process.
    pub nodes: u32,
    /// Nodes of other processes to wait for before the light pass.
    pub external_nodes: u32,
    /// Cache blocks per node.
    pub cache_blocks: magg_core::blocks::CacheSize,
    /// Subscreen edge.
    pub subscreen: u32,
    /// Abort a phase that makes no progress for this long.
    pub stall_timeout: Duration,
    /// Hardware profile (the emulated 1993 machine, docs/EXPERIMENTS.md).
    pub profile: magg_throttle::Profile,
    /// The paper's schedule or ours.
    pub scheme: magg_throttle::Scheme,
    /// Energies to use instead of the light pass, and the cameras of the frames.
    pub sequence: Sequence,
    /// Where the host service sends events for a watcher (the live view).
    pub events: Option<magg_cluster::events::EventSender>,
    /// Node leases, fork timeout, and the cluster token of every process.
    pub faults: FaultPolicy,
}

/// Where the harness's forks and host listen: what it can start before the scene is
/// ready.
#[derive(Clone, Debug)]
pub struct ClusterShape {
    /// Forks to run in this process (ignored when `forks_at` is given).
    pub forks: u32,
    /// External forks to use instead.
    pub forks_at: Vec<String>,
    /// Address the host serves nodes on (`127.0.0.1:0` picks a free port).
    pub listen: String,
    /// The cluster token of every process.
    pub token: magg_plumbing::auth::Token,
    /// How the forks, nodes and host of this process call each other.
    pub transport: TransportMode,
}

/// A harness started ahead of its render: the async runtime, the forks of this process
/// (serving, empty), the host's bound listener. `magg-host render` starts it first: the
/// forks prepare the scene, and refinement's pilot passes run on its nodes
/// ([`StartedCluster::prepare`]). Dropped, it stops its forks, and its nodes hear that
/// the render is done.
pub struct StartedCluster {
    /// Taken only when dropped (see `Drop`): the node threads' calls run on it.
    rt: Option<tokio::runtime::Runtime>,
    stop_tx: tokio::sync::broadcast::Sender<()>,
    fork_addrs: Vec<String>,
    fork_tasks: Vec<tokio::task::JoinHandle<Result<(), tonic::transport::Error>>>,
    _registrations: Vec<magg_plumbing::transport::Registration>,
    links: InProcess,
    /// The listener, until the first scene serves on it; then that scene's host service.
    host: Option<HostSocket>,
    host_addr: String,
    /// The nodes of this process, each on a thread of its own, once started (the first
    /// scene, a pilot level or the render, starts them; they stay for the render's scenes).
    node_threads: Vec<std::thread::JoinHandle<Result<magg_node::NodeSummary, magg_node::NodeError>>>,
    /// Whether the nodes of this process are pinned to cores.
    pinned: bool,
    /// The nodes that went on from the last scene to the next (a pilot level's
    /// [`magg_cluster::SceneEnd::followers`]): the next scene gathers those, not the
    /// nodes the render asked for, some of which may have been lost.
    followers: Option<u32>,
}

impl StartedCluster {
    /// Starts the runtime, the forks (unless `shape` names external ones) and binds the
    /// host's address.
    pub fn start(shape: &ClusterShape) -> anyhow::Result<StartedCluster> {
        let rt =
            tokio::runtime::Builder::new_multi_thread().enable_all().build().context("starting the async runtime")?;
        let (stop_tx, _) = tokio::sync::broadcast::channel::<()>(1);
        let mut fork_addrs = shape.forks_at.clone();
        let mut fork_tasks = Vec::new();
        let mut registrations = Vec::new();
        // The forks, nodes and host of this process reach each other here, without
        // sockets (unless `--transport tcp`); forks elsewhere are always sockets.
        let links = InProcess::new(shape.transport);
        if fork_addrs.is_empty() {
            // The forks of this process share one G-bus, as the paper's shared one.
            let gbus = std::sync::Arc::new(magg_throttle::Resource::new());
            for _ in 0..shape.forks.max(1) {
                let listener =
                    rt.block_on(TcpListener::bind("127.0.0.1:0")).context("binding a fork port on 127.0.0.1")?;
                fork_addrs.push(listener.local_addr()?.to_string());
                let mut stop = stop_tx.subscribe();
                let service = std::sync::Arc::new(
                    magg_fork::ForkService::with_token(shape.token.clone())
                        .on_hardware(magg_fork::ForkHardware::new(gbus.clone(), true))
                        .with_links(links.clone()),
                );
                // Calls from this process skip the socket (see magg_plumbing::transport).
                registrations.push(links.register(
                    fork_addrs.last().expect("just pushed"),
                    magg_fork::fork_server(service.clone(), shape.token.clone()),
                ));
                fork_tasks.push(rt.spawn(magg_fork::serve_service(
                    service,
                    shape.token.clone(),
                    listener,
                    async move {
                        let _ = stop.recv().await;
                    },
                )));
            }
        }
        let listener = rt
            .block_on(TcpListener::bind(&shape.listen))
            .with_context(|| format!("binding the host address {}", shape.listen))?;
        let host_addr = listener.local_addr()?.to_string();
        if let Some(w) = magg_plumbing::auth::exposure_warning(listener.local_addr()?, &shape.token) {
            tracing::warn!("{w}");
        }
        tracing::info!("host serving nodes on {host_addr}, forks at {}", fork_addrs.join(","));
        Ok(StartedCluster {
            rt: Some(rt),
            stop_tx,
            fork_addrs,
            fork_tasks,
            _registrations: registrations,
            links,
            host: Some(HostSocket::Listen(listener)),
            host_addr,
            node_threads: Vec::new(),
            pinned: false,
            followers: None,
        })
    }

    fn rt(&self) -> &tokio::runtime::Runtime {
        self.rt.as_ref().expect("the runtime lives until the harness is dropped")
    }

    /// Starts the nodes of this process, unless they run already.
    fn start_nodes(&mut self, opts: &InProcessOptions) -> anyhow::Result<()> {
        if !self.node_threads.is_empty() || opts.nodes == 0 {
            return Ok(());
        }
        // When the nodes are as many as the cores, node i is pinned to core i (see
        // magg_core::placement).
        let cores = magg_core::placement::worker_cores(opts.nodes as usize);
        self.pinned = !cores.is_empty();
        for i in 0..opts.nodes {
            let cfg = magg_node::NodeConfig {
                host: self.host_addr.clone(),
                threads: 1,
                cache_blocks: Some(opts.cache_blocks),
                name: format!("in-process-{i}"),
                backoff: magg_plumbing::retry::Backoff::default(),
                row_delay: Duration::ZERO,
                profile: None,
                pair_delay: Duration::ZERO,
                token: opts.faults.token.clone(),
                cores: cores.get(i as usize).map(|&c| vec![c]).unwrap_or_default(),
                links: self.links.clone(),
            };
            let handle = self.rt().handle().clone();
            let thread = std::thread::Builder::new()
                .name(format!("magg-node-{i}"))
                .spawn(move || {
                    // The host service registers for in-process calls when the first
                    // scene starts serving: connect after that, not over the socket
                    // before it.
                    cfg.links.wait_registered(&cfg.host, Duration::from_secs(10));
                    magg_node::run_with_runtime(handle, &cfg)
                })
                .context("starting node threads")?;
            self.node_threads.push(thread);
        }
        Ok(())
    }

    /// How a scene of this render is driven: `events` go to a watcher (none for a
    /// pilot level), the stats' total counts from `started`.
    fn drive_options(
        &self,
        opts: &InProcessOptions,
        events: Option<magg_cluster::events::EventSender>,
        started: std::time::Instant,
    ) -> DriveOptions {
        DriveOptions {
            forks: self.fork_addrs.clone(),
            cache_blocks: opts.cache_blocks,
            subscreen: opts.subscreen,
            nodes: self.followers.filter(|&n| n > 0).unwrap_or(opts.nodes + opts.external_nodes),
            // With a core each, nodes register within a fraction of a millisecond: the light
            // pass need not wait for them (one that arrives late joins it). Many nodes on few
            // cores are all waited for, so that they all take part.
            gather: !opts.profile.is_native() || opts.external_nodes > 0 || !self.pinned,
            stall_timeout: opts.stall_timeout,
            profile: opts.profile.clone(),
            scheme: opts.scheme,
            events,
            faults: opts.faults.clone(),
            started,
            links: self.links.clone(),
        }
    }

    /// Prepares `scene` with `plan` ([`magg_prepare::refine::prepare_with`]) on this
    /// cluster's forks, each its shares of space ([`magg_cluster::preparing`]);
    /// refinement's pilot light passes run on this cluster's nodes: each level a scene
    /// of its own on the forks and the host service, the nodes registering for each.
    /// `progress` hears of each level.
    pub fn prepare(
        &mut self,
        scene: &magg_core::scene::Scene,
        plan: magg_core::plan::EffectsPlan,
        opts: &InProcessOptions,
        progress: &dyn Progress,
        shares: magg_prepare::Shares,
    ) -> anyhow::Result<PreparedScene> {
        let mut forks = magg_cluster::preparing::ForkShares::new(
            self.rt().handle().clone(),
            self.links.clone(),
            self.fork_addrs.clone(),
            opts.faults.token.clone(),
            opts.faults.fork_timeout,
        );
        let mut pilots = ClusterPilots { cluster: self, opts, nodes: 0 };
        Ok(magg_prepare::refine::prepare_with(scene, plan, &mut pilots, progress, shares, &mut forks)?)
    }
}

/// Refinement's pilot light passes on the harness's nodes.
struct ClusterPilots<'a> {
    cluster: &'a mut StartedCluster,
    opts: &'a InProcessOptions,
    /// Nodes that traced pairs of the last level.
    nodes: u32,
}

impl Pilots for ClusterPilots<'_> {
    fn light_pass(
        &mut self,
        pilot: &Arc<PreparedScene>,
        pairs: &Arc<KeptPairs>,
        progress: &dyn Progress,
    ) -> Result<LightPass, RenderError> {
        let mut level = || -> anyhow::Result<LightPass> {
            let c = &mut *self.cluster;
            c.start_nodes(self.opts)?;
            let host = c.host.take().context("the host service was lost to an earlier failure")?;
            let drive = c.drive_options(self.opts, None, std::time::Instant::now());
            let rt = c.rt().handle().clone();
            let mut machine =
                rt.block_on(ClusterMachine::start_pilot(pilot, &drive, host, rt.clone(), pairs.clone()))?;
            let light = machine.light_pass(progress)?;
            let (host, end) = machine.next_scene();
            tracing::debug!(pairs = ?end.pairs, "pilot level: pairs traced per node");
            c.host = Some(host);
            c.followers = Some(end.followers);
            self.nodes = end.pairs.iter().filter(|&&p| p > 0).count() as u32;
            Ok(light)
        };
        level().map_err(|e| RenderError::Machine(e.into()))
    }

    fn place(&self) -> &'static str {
        "nodes"
    }

    fn nodes(&self) -> u32 {
        self.nodes
    }
}

impl Drop for StartedCluster {
    fn drop(&mut self) {
        // The host service goes first: its nodes hear that the render is done.
        drop(self.host.take());
        let _ = self.stop_tx.send(());
        let threads = std::mem::take(&mut self.node_threads);
        if threads.is_empty() {
            return;
        }
        // Nodes may still be starting, or retrying a host that is gone; they end on their
        // own (retry deadline). The runtime they run on must outlive them (a timer made on
        // a runtime being shut down panics), so it is dropped on a thread of its own once
        // they have ended.
        let rt = self.rt.take();
        let _ = std::thread::Builder::new().name("magg-host-cleanup".into()).spawn(move || {
            for t in threads {
                let _ = t.join();
            }
            drop(rt);
        });
    }
}

impl StartedCluster {
    /// Runs the render on this cluster: starts the nodes (unless its pilot levels did),
    /// drives the phases, stops everything. The stats' total counts from `started` (the
    /// end of preprocessing, or earlier).
    pub fn render(
        mut self,
        prepared: &std::sync::Arc<PreparedScene>,
        opts: &InProcessOptions,
        started: std::time::Instant,
        progress: &dyn Progress,
        sink: &mut FrameSink<'_>,
    ) -> anyhow::Result<RenderOutput> {
        self.start_nodes(opts)?;
        let host = self.host.take().context("the host service was lost to an earlier failure")?;
        let drive_opts = self.drive_options(opts, opts.events.clone(), started);
        // The phases run on this thread; the machine's passes run on the runtime.
        let rt = self.rt().handle().clone();
        let out = rt
            .block_on(ClusterMachine::start(prepared, &drive_opts, host, rt.clone()))
            .map_err(anyhow::Error::from)
            .and_then(|mut machine| {
                magg_core::phases::run(&mut machine, prepared, &opts.sequence, progress, sink)
                    .map_err(anyhow::Error::from)
            })?;
        // (A failed render returned above: dropping the harness stops its forks and
        // lets its nodes go.)
        let mut node_err = None;
        for t in std::mem::take(&mut self.node_threads) {
            match t.join() {
                Ok(Ok(_)) => {}
                // Nodes join as they register: one that came after the end had nothing to do.
                Ok(Err(e)) if e.came_after_the_render() => {}
                Ok(Err(e)) => node_err = node_err.or(Some(anyhow::anyhow!(e))),
                Err(_) => node_err = node_err.or(Some(anyhow::anyhow!("a node thread panicked"))),
            }
        }
        let _ = self.stop_tx.send(());
        for t in std::mem::take(&mut self.fork_tasks) {
            let abort = t.abort_handle();
            if rt.block_on(async { tokio::time::timeout(Duration::from_secs(1), t).await }).is_err() {
                abort.abort();
            }
        }
        if let Some(e) = node_err {
            return Err(e.context("a node failed"));
        }
        Ok(out)
    }
}
