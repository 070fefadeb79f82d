//! The cluster as a [`Machine`]: the host of the paper's machine, serving `Host` to the
//! nodes and driving the forks over gRPC. [`ClusterMachine::start`] connects the forks,
//! serves the host service, loads the shards and gathers the nodes; the phases themselves
//! are sequenced by [`magg_core::phases::run`], as for the embedded renderer.
//!
//! The passes are async (tonic); the machine runs each on its runtime with
//! [`tokio::runtime::Handle::block_on`], so it must be driven from a thread that is not
//! one of that runtime's workers (the harness drives it from the calling thread).

use super::emulation::{preprocess_time, process_cpu_s};
use super::events::EventSender;
use super::forks::ForkSet;
use super::service::{HostService, HostState, Phase, PilotPairs};
use crate::failure::ClusterError;
use magg_core::color::Rgb;
use magg_core::machine::{LightPass, Machine, MachineFigures, PhaseTimes, RenderError, ViewPass, ViewedFrame};
use magg_core::prepared::PreparedScene;
use magg_core::progress::Progress;
use magg_core::stats::EmulatedBusy;
use magg_core::subscreen::Subscreen;
use magg_plumbing::auth::CheckToken;
use magg_plumbing::with_message_limits;
use magg_proto::v1;
use magg_proto::v1::host_server::HostServer;
use magg_throttle::{Profile, Scheme};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::net::TcpListener;
use tonic::service::interceptor::InterceptedService;

/// How to drive a render.
#[derive(Clone, Debug)]
pub struct DriveOptions {
    /// Fork addresses, by index.
    pub forks: Vec<String>,
    /// Cache blocks per node.
    pub cache_blocks: magg_core::blocks::CacheSize,
    /// Subscreen edge in pixels.
    pub subscreen: u32,
    /// Nodes expected (sizes the forks' pair batches; see `gather`).
    pub nodes: u32,
    /// Whether the light pass waits for the expected nodes to register. An emulated run
    /// must (the paper's processors were wired: connecting is not part of its time), and
    /// so must a render that was told to wait for external nodes; native in-process
    /// nodes start on pairs as soon as they are in, and later ones join.
    pub gather: bool,
    /// Give up if a phase makes no progress for this long.
    pub stall_timeout: Duration,
    /// Hardware profile, sent to every fork and node.
    pub profile: Profile,
    /// The paper's schedule or ours.
    pub scheme: Scheme,
    /// Where the host service sends events for a watcher (the live view).
    pub events: Option<EventSender>,
    /// Node leases, fork timeout, cluster token.
    pub faults: crate::FaultPolicy,
    /// When the render began (before this process started its forks and nodes): the
    /// stats' total counts from here, so that it holds every cost of the cluster.
    pub started: Instant,
    /// The forks and nodes of this process, reached without sockets: the host's service
    /// registers here, and its fork clients look here first.
    pub links: magg_plumbing::transport::InProcess,
}

/// The host's gRPC server while the render runs.
struct HostServerTask {
    stop_tx: Option<tokio::sync::oneshot::Sender<()>>,
    task: Option<tokio::task::JoinHandle<Result<(), tonic::transport::Error>>>,
    _in_process: magg_plumbing::transport::Registration,
}

impl HostServerTask {
    /// Stops the server. Graceful shutdown waits for clients to hang up; a client that
    /// never does (a stuck or hostile peer) must not keep the host alive: give them a
    /// moment, then stop.
    async fn stop(&mut self) {
        if let Some(tx) = self.stop_tx.take() {
            let _ = tx.send(());
        }
        if let Some(task) = self.task.take() {
            let abort = task.abort_handle();
            if tokio::time::timeout(Duration::from_secs(1), task).await.is_err() {
                abort.abort();
                tracing::warn!("a client kept its connection to the host open after the render: closed it");
            }
        }
    }
}

/// Where the host serves its nodes: a listener not yet served (the render's first
/// scene), or the host service of the scene before, which the next one takes over (see
/// [`ClusterMachine::next_scene`]).
pub enum HostSocket {
    /// Serve `Host` here.
    Listen(TcpListener),
    /// Already serving: the next scene begins on this service.
    Serving(HostEndpoint),
}

/// The host service of a render, serving from its first scene to its last: refinement's
/// pilot levels, then the render itself, each a session of its own on the same address.
/// Dropped, it tells the nodes that the render is done, so that they stop whatever
/// happened to the host.
pub struct HostEndpoint {
    service: HostService,
    server: HostServerTask,
}

impl Drop for HostEndpoint {
    fn drop(&mut self) {
        self.service.lock().next_scene = false;
        self.service.set_phase(Phase::Done);
    }
}

impl HostEndpoint {
    /// Serves `Host` on `listener` with the first scene's `state`.
    async fn serve(state: HostState, opts: &DriveOptions, listener: TcpListener) -> Result<HostEndpoint, ClusterError> {
        let service = HostService::new(state);
        let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
        let (health, health_service) = magg_plumbing::health::health_service();
        health.set_serving::<HostServer<HostService>>().await;
        let host_server = InterceptedService::new(
            with_message_limits!(HostServer::new(service.clone())),
            CheckToken { token: opts.faults.token.clone(), server: "host" },
        );
        // Nodes of this process reach the host without a socket (see magg_plumbing::transport).
        let host_addr = listener.local_addr().map_err(ClusterError::Listener)?;
        let in_process = opts.links.register(&host_addr.to_string(), host_server.clone());
        let server = magg_plumbing::net::server()
            .map_err(ClusterError::ServerTls)?
            .add_service(health_service)
            .add_service(host_server)
            .serve_with_incoming_shutdown(magg_plumbing::net::nodelay_incoming(listener), async {
                let _ = stop_rx.await;
            });
        let server =
            HostServerTask { stop_tx: Some(stop_tx), task: Some(tokio::spawn(server)), _in_process: in_process };
        Ok(HostEndpoint { service, server })
    }

    /// Stops serving (see [`HostServerTask::stop`]).
    pub(super) async fn stop(&mut self) {
        self.server.stop().await;
    }
}

/// How a scene that another follows ended ([`ClusterMachine::next_scene`]).
#[derive(Clone, Debug, Default)]
pub struct SceneEnd {
    /// Pairs each node traced, by node id.
    pub pairs: Vec<u64>,
    /// Nodes that heard that the next scene follows: those the next scene gathers (a
    /// node lost in this one is not waited for again).
    pub followers: u32,
}

/// The cluster, started and ready for the light pass: see the module doc.
pub struct ClusterMachine {
    pub(super) rt: tokio::runtime::Handle,
    pub(super) prepared: Arc<PreparedScene>,
    pub(super) opts: DriveOptions,
    pub(super) forks: ForkSet,
    pub(super) endpoint: HostEndpoint,
    pub(super) tiles: Vec<Subscreen>,
    /// The process's CPU seconds when the render began (for the emulation's CPU share).
    pub(super) cpu0: Option<f64>,
    /// Real seconds from the start until every shard was loaded.
    pub(super) preprocess_wall: f64,
    /// Real seconds spent waiting for the expected nodes to register.
    pub(super) gather_s: f64,
    /// Modelled busy seconds, filled in as the passes report them.
    pub(super) busy: EmulatedBusy,
    /// Refinement's pilot pairs shared with the nodes of this process, until the light
    /// pass ends.
    pub(super) kept_pairs: Option<magg_plumbing::transport::Sharing>,
}

/// The render's timeline at debug level (RUST_LOG=magg_host=debug): where the cluster's
/// fixed costs go.
pub(super) fn mark(started: Instant, what: &str) {
    tracing::debug!(ms = format!("{:.2}", 1e3 * started.elapsed().as_secs_f64()), "timeline: {what}");
}

impl ClusterMachine {
    /// The host service of this scene.
    pub(super) fn service(&self) -> &HostService {
        &self.endpoint.service
    }

    /// Connects the forks, serves `Host` on `host` (or begins this scene on the service
    /// of the scene before), loads every fork's shard and waits for the expected nodes
    /// (when `opts.gather`). `rt` is the runtime this future runs on.
    pub async fn start(
        prepared: &Arc<PreparedScene>,
        opts: &DriveOptions,
        host: HostSocket,
        rt: tokio::runtime::Handle,
    ) -> Result<ClusterMachine, ClusterError> {
        Self::start_scene(prepared, opts, host, rt, None).await
    }

    /// [`ClusterMachine::start`] for one of refinement's pilot levels: its nodes trace
    /// the point lights' pairs through `pairs` (shared with the nodes of this process; a
    /// node of another process keeps its own over the render's levels). Run its light
    /// pass, then [`ClusterMachine::next_scene`].
    pub async fn start_pilot(
        prepared: &Arc<PreparedScene>,
        opts: &DriveOptions,
        host: HostSocket,
        rt: tokio::runtime::Handle,
        pairs: Arc<magg_core::kept::KeptPairs>,
    ) -> Result<ClusterMachine, ClusterError> {
        Self::start_scene(prepared, opts, host, rt, Some(pairs)).await
    }

    async fn start_scene(
        prepared: &Arc<PreparedScene>,
        opts: &DriveOptions,
        host: HostSocket,
        rt: tokio::runtime::Handle,
        pilot: Option<Arc<magg_core::kept::KeptPairs>>,
    ) -> Result<ClusterMachine, ClusterError> {
        let t_start = opts.started;
        let cpu0 = process_cpu_s();
        mark(t_start, "driving: forks and nodes started");
        let h = prepared.header.clone();
        let f = opts.forks.len();
        if f == 0 {
            return Err(ClusterError::NoForks);
        }
        let throttled = !opts.profile.is_native();
        let wire_profile = if throttled { opts.profile.to_wire() } else { String::new() };
        // Preprocessing as the emulated machine spends it (the real one took
        // `prepared.preprocess_s`, a thousandth of that or less).
        let preprocess_model =
            if throttled { preprocess_time(&opts.profile, opts.scheme, prepared, f as u32) } else { Duration::ZERO };
        // Not even a zero sleep natively: the timer would round it up to its next tick (1 ms).
        magg_throttle::wait(Instant::now() + opts.profile.dilate(preprocess_model)).await;
        // Each render's nodes get secrets under a key of its own, which the forks check too.
        let node_key = magg_plumbing::auth::NodeKey::random();
        let mut forks = ForkSet::connect(prepared, &opts.forks, &opts.faults, &opts.links).await?.for_render(
            wire_profile.clone(),
            opts.nodes,
            node_key.clone(),
        );

        // Refinement's pairs, for the nodes of this process (see
        // magg_core::kept::KeptPairs); shared until the light pass ends. A pilot level
        // traces them, the render's light pass bins those the pilots kept.
        let pilot_pairs = match (&pilot, prepared.refinement.kept) {
            (Some(_), _) => PilotPairs::Trace,
            (None, true) => PilotPairs::Bin,
            (None, false) => PilotPairs::None,
        };
        let kept_pairs = match pilot {
            Some(pairs) => opts.links.share(pairs),
            None => prepared.kept_pairs.take().and_then(|k| opts.links.share(k)),
        };
        let state = HostState {
            node_key,
            phase: Phase::Gather,
            nodes: Vec::new(),
            schedule: None,
            header: v1::SceneHeader::from(&*h),
            fork_addrs: opts.forks.clone(),
            cache_blocks: opts.cache_blocks,
            profile: wire_profile,
            scheme: opts.scheme.name().to_string(),
            link_bytes: 0,
            rpcs: 0,
            frame_camera: None,
            events: opts.events.clone(),
            pairs_epoch: 0,
            kept_pairs: kept_pairs.as_ref().map_or(0, |k| k.key()),
            pilot_pairs,
            next_scene: false,
            previous_key: None,
        };
        let endpoint = match host {
            HostSocket::Listen(listener) => HostEndpoint::serve(state, opts, listener).await?,
            HostSocket::Serving(endpoint) => {
                endpoint.service.begin(state);
                endpoint
            }
        };
        let service = &endpoint.service;
        mark(t_start, "host serving");
        // The shards load while the nodes register (they wait for the light pass).
        forks.load_all().await?;
        mark(t_start, "shards loaded");
        // Preprocessing ends when every shard is loaded.
        let preprocess_wall = t_start.elapsed().as_secs_f64();
        // The expected nodes register (connecting 80 nodes to 6 servers takes this machine
        // a moment that the emulated one, whose processors were wired, never spent).
        let t_gather = Instant::now();
        while opts.gather && service.lock().nodes.len() < opts.nodes as usize {
            if t_gather.elapsed() > opts.stall_timeout {
                tracing::warn!(
                    "only {} of {} nodes registered within {:?}: starting with them",
                    service.lock().nodes.len(),
                    opts.nodes,
                    opts.stall_timeout
                );
                break;
            }
            service.wait_for(Duration::from_millis(2)).await;
        }
        let gather_s = t_gather.elapsed().as_secs_f64();
        mark(t_start, if opts.gather { "nodes registered" } else { "light pass open (nodes join as they register)" });
        let s = &h.settings;
        Ok(ClusterMachine {
            rt,
            prepared: prepared.clone(),
            tiles: magg_core::subscreen::tile(s.width, s.height, opts.subscreen),
            opts: opts.clone(),
            forks,
            cpu0,
            preprocess_wall,
            gather_s,
            busy: EmulatedBusy { preprocess_s: preprocess_model.as_secs_f64(), ..Default::default() },
            kept_pairs,
            endpoint,
        })
    }

    /// Tells every node that this scene is done and waits (bounded) for their final
    /// reports; a node silent for 2 s is not waited for.
    pub(super) async fn done(&self) {
        self.service().set_phase(Phase::Done);
        let deadline = Instant::now() + Duration::from_secs(5);
        while Instant::now() < deadline {
            if self.service().lock().nodes.iter().all(|n| n.reported_or_gone(Duration::from_secs(2))) {
                break;
            }
            self.service().wait_for(Duration::from_millis(5)).await;
        }
    }

    /// Ends this scene with another of the render to follow (after a pilot level's light
    /// pass): the nodes hear that the next scene follows, send their final reports and
    /// register again with the next scene's [`ClusterMachine::start`], which takes the
    /// host service returned here.
    pub fn next_scene(self) -> (HostSocket, SceneEnd) {
        self.service().lock().next_scene = true;
        let rt = self.rt.clone();
        rt.block_on(self.done());
        let s = self.service().lock();
        let end = SceneEnd {
            pairs: s.nodes.iter().map(|n| n.report.pairs).collect(),
            followers: s.nodes.iter().filter(|n| n.finished()).count() as u32,
        };
        drop(s);
        (HostSocket::Serving(self.endpoint), end)
    }

    /// Whether the profile throttles (stage times are then modelled seconds).
    pub(super) fn throttled(&self) -> bool {
        !self.opts.profile.is_native()
    }
}

/// A cluster failure as the phase sequence's error.
fn failed(e: ClusterError) -> RenderError {
    RenderError::Machine(e.into())
}

impl Machine for ClusterMachine {
    fn light_pass(&mut self, progress: &dyn Progress) -> Result<LightPass, RenderError> {
        let rt = self.rt.clone();
        rt.block_on(self.trace_light(progress)).map_err(failed)
    }

    fn publish_vertex_energies(&mut self, vertex_irradiance: &[Rgb], gather: &[bool]) -> Result<(), RenderError> {
        let rt = self.rt.clone();
        rt.block_on(self.put_vertex_energies(vertex_irradiance, gather)).map_err(failed)
    }

    fn view_pass(&mut self, pass: ViewPass<'_>, progress: &dyn Progress) -> Result<ViewedFrame, RenderError> {
        let rt = self.rt.clone();
        rt.block_on(self.trace_view(pass, progress)).map_err(failed)
    }

    fn figures(&mut self, times: PhaseTimes) -> Result<MachineFigures, RenderError> {
        let rt = self.rt.clone();
        rt.block_on(self.collect_figures(times)).map_err(failed)
    }
}
