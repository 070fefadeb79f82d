//! The host's gRPC service: node registration, work hand-out, pixel rows.

use super::error::{HostError, MAX_NODES, MAX_NODE_NAME};
use super::events::{ClusterEvent, EventSender};
use super::schedule::{Next, Scheduler};
use magg_core::blocks::home_fork_of_node;
use magg_core::cluster::NodeReport;
use magg_proto::v1::host_server::Host;
use magg_proto::v1::next_work_reply::Kind;
pub use magg_proto::v1::register_reply::PilotPairs;
use magg_proto::v1::{
    self, NextWorkReply, NextWorkRequest, RegisterReply, RegisterRequest, SubmitRowsReply, SubmitRowsRequest,
};
use magg_proto::PROTOCOL_VERSION;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};
use tokio::sync::{watch, Notify};
use tonic::{Request, Response, Status};

/// Render phase, as the host drives it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// Waiting for the expected nodes to register, so that the light pass starts on
    /// every processor at once (as the paper's machine did): nodes wait.
    Gather,
    /// Light ray tracing: nodes pull pairs from their forks.
    Lrt,
    /// Energy interpolation on the host: nodes wait.
    Interp,
    /// Viewing ray tracing: nodes pull subscreens.
    Vrt,
    /// Finished: nodes stop.
    Done,
}

/// A registered node.
#[derive(Clone, Debug, Default)]
pub struct NodeEntry {
    /// Name it gave.
    pub name: String,
    /// Its latest cumulative report.
    pub report: NodeReport,
    /// It was told to trace pairs already in this LRT phase.
    pub told_pairs: bool,
    /// The [`HostState::pairs_epoch`] it was last told to trace pairs in.
    pub pairs_epoch: u64,
    /// When it last called the host (NextWork, SubmitRows).
    pub last_seen: Option<Instant>,
    /// Worker threads it runs (each asks for work on its own).
    pub threads: u32,
    /// How many of its workers were told the render is done.
    pub told_done: u32,
    /// Bytes of its messages with the host (its share of the link path).
    pub link_bytes: u64,
}

impl NodeEntry {
    /// Every worker of the node has heard that the render is done.
    pub fn finished(&self) -> bool {
        self.told_done >= self.threads.max(1)
    }

    /// Every worker has heard "done" and sent its final report (a worker that hears
    /// "done" asks once more, carrying its last counters, and hears "done" again).
    pub fn reported_final(&self) -> bool {
        self.told_done >= 2 * self.threads.max(1)
    }

    /// Finished, or silent for longer than `grace` (a node that died: nobody waits for it).
    pub fn finished_or_gone(&self, grace: Duration) -> bool {
        self.finished() || self.gone(grace)
    }

    /// Final report in, or silent for longer than `grace`.
    pub fn reported_or_gone(&self, grace: Duration) -> bool {
        self.reported_final() || self.gone(grace)
    }

    fn gone(&self, grace: Duration) -> bool {
        self.last_seen.is_none_or(|t| t.elapsed() > grace)
    }
}

/// Shared state of the host service.
pub struct HostState {
    /// Current phase.
    pub phase: Phase,
    /// Registered nodes by id.
    pub nodes: Vec<NodeEntry>,
    /// Subscreens (set when VRT starts).
    pub schedule: Option<Scheduler>,
    /// Resident header sent at registration.
    pub header: v1::SceneHeader,
    /// Fork addresses.
    pub fork_addrs: Vec<String>,
    /// Hardware profile sent to nodes (`Profile::to_wire`; empty: native).
    pub profile: String,
    /// Schedule sent to nodes (`paper` or `magg`).
    pub scheme: String,
    /// The render's node key: node i's secret is its keyed hash of i (the forks get the
    /// key with their shards and check the secret too).
    pub node_key: magg_plumbing::auth::NodeKey,
    /// Cache blocks per node, told to nodes at registration.
    pub cache_blocks: magg_core::blocks::CacheSize,
    /// Bytes of node <-> host messages (the link path).
    pub link_bytes: u64,
    /// RPCs served.
    pub rpcs: u64,
    /// Camera of the frame being traced, sent with its subscreens (camera paths only).
    pub frame_camera: Option<v1::Camera>,
    /// Where to send events for watchers (the live view), if any.
    pub events: Option<EventSender>,
    /// Bumped when forks give back pairs of lost nodes during LRT: every node that has
    /// run out of pairs is told to trace pairs again.
    pub pairs_epoch: u64,
    /// The key refinement's pilot pairs are shared under in this process, told to nodes
    /// at registration (0: none; see `magg_core::kept::KeptPairs`).
    pub kept_pairs: u64,
    /// How this session's light pass treats the pilots' pairs, told to nodes at
    /// registration.
    pub pilot_pairs: PilotPairs,
    /// Another scene of the render follows this session's (refinement's next level, or
    /// the render after its pilots): DONE says so, and the nodes register again.
    pub next_scene: bool,
    /// The previous session's node key: a node of that session that asks for work late
    /// hears that the next scene has begun.
    pub previous_key: Option<magg_plumbing::auth::NodeKey>,
}

impl HostState {
    /// Counts a request of `len` encoded bytes from `node` (an RPC on the link path);
    /// returns the node's entry, or refuses a node that never registered or a request
    /// without that node's secret.
    fn count_request(&mut self, node: u32, secret: u64, len: usize) -> Result<&mut NodeEntry, Status> {
        self.rpcs += 1;
        self.link_bytes += len as u64;
        let entry = self.nodes.get_mut(node as usize).ok_or(HostError::UnknownNode(node))?;
        if !self.node_key.admits(node, secret) {
            return Err(HostError::NotThatNode(node).into());
        }
        entry.link_bytes += len as u64;
        Ok(entry)
    }

    /// Sends `e` to the watcher, if there is one.
    fn emit(&self, e: impl FnOnce() -> ClusterEvent) {
        if let Some(tx) = &self.events {
            let _ = tx.send(e());
        }
    }
}

/// The tonic service over [`HostState`].
///
/// Two signals keep phase changes quick without polling: a node that would be told to
/// wait is held (up to [`LONG_POLL`]) until [`HostService::bump`] says that something it
/// may be waiting for changed (phase, pairs epoch, subscreens); and the driver, which waits
/// on [`HostService::changed`], hears when a node ran out of pairs, when the last pixels
/// are in and when a node heard "done".
#[derive(Clone)]
pub struct HostService {
    state: Arc<Mutex<HostState>>,
    /// Signalled (one stored permit) for the driver: see the type's doc.
    pub changed: Arc<Notify>,
    /// Bumped when nodes told to wait may have work or news.
    version: Arc<watch::Sender<u64>>,
}

/// Longest time a NextWork call is held while there is nothing for the node: it returns
/// at once when the phase changes, and otherwise tells the node to ask again.
pub const LONG_POLL: Duration = Duration::from_millis(250);

impl HostService {
    /// A service over `state`.
    pub fn new(state: HostState) -> Self {
        HostService {
            state: Arc::new(Mutex::new(state)),
            changed: Arc::new(Notify::new()),
            version: Arc::new(watch::Sender::new(0)),
        }
    }

    /// Begins the next scene of the render on this service: `state` replaces the last
    /// scene's (its nodes register again; those of the last scene that ask for work late
    /// hear that it is over and the next has begun). Events go where `state` says.
    pub fn begin(&self, mut state: HostState) {
        {
            let mut s = self.lock();
            state.previous_key = Some(s.node_key.clone());
            *s = state;
        }
        self.bump();
    }

    /// Wakes the nodes held waiting, to ask for their work again.
    pub fn bump(&self) {
        self.version.send_modify(|v| *v += 1);
    }

    /// Sleeps for `d`, or less when a node signals the driver (a pass may be over).
    pub async fn wait_for(&self, d: std::time::Duration) {
        tokio::select! {
            _ = tokio::time::sleep(d) => {}
            _ = self.changed.notified() => {}
        }
    }
    /// Enters `phase` and wakes the waiting nodes.
    pub fn set_phase(&self, phase: Phase) {
        self.lock().phase = phase;
        self.bump();
    }
    /// Locks the state (a poisoned lock is recovered: the state stays consistent because
    /// every update is a single assignment or a checked scheduler call).
    pub fn lock(&self) -> MutexGuard<'_, HostState> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// Pause a node makes after a WAIT that the host already held for [`LONG_POLL`].
const WAIT_MS: u32 = 1;

impl HostService {
    /// The next work of `node` in `phase` (shared by NextWork and the reply to the rows
    /// that end a subscreen).
    fn assign(&self, s: &mut HostState, node: u32, phase: Phase) -> NextWorkReply {
        let epoch = s.pairs_epoch;
        let wait = NextWorkReply { kind: Kind::Wait as i32, wait_ms: WAIT_MS, ..Default::default() };
        match phase {
            Phase::Lrt => match s.nodes.get_mut(node as usize) {
                Some(e) if !e.told_pairs || e.pairs_epoch < epoch => {
                    e.told_pairs = true;
                    e.pairs_epoch = epoch;
                    NextWorkReply { kind: Kind::Pairs as i32, ..Default::default() }
                }
                _ => wait,
            },
            Phase::Interp | Phase::Gather => wait,
            Phase::Vrt => match s.schedule.as_mut().map(|sc| sc.next(node)) {
                Some(Next::Trace(id, t)) => {
                    s.emit(|| ClusterEvent::Assigned { node, id, rect: t });
                    let camera = s.frame_camera.clone();
                    NextWorkReply {
                        kind: Kind::Subscreen as i32,
                        subscreen: Some(v1::Subscreen { x: t.x, y: t.y, w: t.w, h: t.h, id, camera }),
                        ..Default::default()
                    }
                }
                Some(Next::Wait) | None => wait,
                Some(Next::Done) => {
                    self.changed.notify_one();
                    wait
                }
            },
            Phase::Done => {
                if let Some(e) = s.nodes.get_mut(node as usize) {
                    e.told_done += 1;
                }
                self.changed.notify_one();
                NextWorkReply { kind: Kind::Done as i32, subscreen: None, wait_ms: 0, next_scene: s.next_scene }
            }
        }
    }
}

#[tonic::async_trait]
impl Host for HostService {
    async fn register(&self, req: Request<RegisterRequest>) -> Result<Response<RegisterReply>, Status> {
        let r = req.into_inner();
        if r.protocol_version != PROTOCOL_VERSION {
            return Err(HostError::ProtocolVersion(r.protocol_version).into());
        }
        if r.name.len() > MAX_NODE_NAME {
            return Err(HostError::NameTooLong.into());
        }
        // Between two scenes of the render the call is held (up to LONG_POLL) until the
        // next one begins.
        let mut version = self.version.subscribe();
        let deadline = Instant::now() + LONG_POLL;
        loop {
            version.borrow_and_update();
            let between = {
                let s = self.lock();
                s.phase == Phase::Done && s.next_scene
            };
            let left = deadline.saturating_duration_since(Instant::now());
            if !between {
                break;
            }
            if left.is_zero() || !matches!(tokio::time::timeout(left, version.changed()).await, Ok(Ok(()))) {
                return Err(HostError::NextScene.into());
            }
        }
        let mut s = self.lock();
        if s.phase == Phase::Done {
            return Err(if s.next_scene { HostError::NextScene } else { HostError::RenderOver }.into());
        }
        if s.nodes.len() >= MAX_NODES {
            return Err(HostError::TooManyNodes.into());
        }
        let node = s.nodes.len() as u32;
        let secret = s.node_key.secret(node);
        s.nodes.push(NodeEntry {
            name: r.name.clone(),
            threads: r.threads.clamp(1, 1024),
            last_seen: Some(Instant::now()),
            ..Default::default()
        });
        s.rpcs += 1;
        s.emit(|| ClusterEvent::Registered { node, name: r.name.clone() });
        self.changed.notify_one();
        let forks = s.fork_addrs.len().max(1) as u32;
        tracing::info!(node, name = %r.name, "node registered");
        Ok(Response::new(RegisterReply {
            node,
            home_fork: home_fork_of_node(node, forks),
            fork_addrs: s.fork_addrs.clone(),
            header: Some(s.header.clone()),
            cache_blocks: magg_proto::convert::cache_size_to_wire(s.cache_blocks),
            profile: s.profile.clone(),
            scheme: s.scheme.clone(),
            node_secret: secret,
            kept_pairs: s.kept_pairs,
            pilot_pairs: s.pilot_pairs as i32,
        }))
    }

    async fn next_work(&self, req: Request<NextWorkRequest>) -> Result<Response<NextWorkReply>, Status> {
        let r = req.into_inner();
        let mut version = self.version.subscribe();
        let deadline = Instant::now() + LONG_POLL;
        {
            let mut s = self.lock();
            if !s.node_key.admits(r.node, r.node_secret)
                && s.previous_key.as_ref().is_some_and(|k| k.admits(r.node, r.node_secret))
            {
                // A node of the last scene that missed its end: that scene is over.
                s.rpcs += 1;
                return Ok(Response::new(NextWorkReply {
                    kind: Kind::Done as i32,
                    next_scene: true,
                    ..Default::default()
                }));
            }
            let entry = s.count_request(r.node, r.node_secret, prost::Message::encoded_len(&r))?;
            if let Some(rep) = &r.report {
                entry.report = NodeReport::try_from(rep).map_err(HostError::Report)?;
            }
        }
        let reported = r.report.is_some();
        // Held while there is nothing to do, until something changes or LONG_POLL ends.
        let reply = loop {
            version.borrow_and_update();
            let (reply, phase) = {
                let mut s = self.lock();
                let phase = s.phase;
                if let Some(entry) = s.nodes.get_mut(r.node as usize) {
                    entry.last_seen = Some(Instant::now());
                }
                (self.assign(&mut s, r.node, phase), phase)
            };
            if reply.kind != Kind::Wait as i32 {
                break reply;
            }
            if phase == Phase::Lrt {
                // The node is out of pairs: the driver checks the forks now.
                self.changed.notify_one();
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() || !matches!(tokio::time::timeout(left, version.changed()).await, Ok(Ok(()))) {
                break reply;
            }
        };
        let mut s = self.lock();
        let reply_len = prost::Message::encoded_len(&reply) as u64;
        s.link_bytes += reply_len;
        if let Some(entry) = s.nodes.get_mut(r.node as usize) {
            entry.link_bytes += reply_len;
            if reported {
                let (report, link_bytes) = (entry.report, entry.link_bytes);
                s.emit(|| ClusterEvent::Report { node: r.node, report, link_bytes });
            }
        }
        Ok(Response::new(reply))
    }

    async fn submit_rows(&self, req: Request<SubmitRowsRequest>) -> Result<Response<SubmitRowsReply>, Status> {
        let r = req.into_inner();
        let mut s = self.lock();
        s.count_request(r.node, r.node_secret, prost::Message::encoded_len(&r))?.last_seen = Some(Instant::now());
        let Some(schedule) = s.schedule.as_mut() else {
            return Err(HostError::NoViewPass.into());
        };
        let rows: Vec<(u32, &[u8])> = r.rows.iter().map(|row| (row.y, &row.rgb[..])).collect();
        let give_back = schedule.submit(r.subscreen, &rows).map_err(HostError::from)?;
        if schedule.is_done() {
            self.changed.notify_one();
        }
        s.emit(|| ClusterEvent::Rows { node: r.node, id: r.subscreen, rows: r.rows.clone() });
        if let Some(at) = give_back {
            s.emit(|| ClusterEvent::Redivided { id: r.subscreen, at });
        }
        // Rows that end the node's part come back with its next work, unless the host has
        // just taken rows back (then the node still has rows to trace).
        let next = if r.last && give_back.is_none() {
            let phase = s.phase;
            Some(self.assign(&mut s, r.node, phase))
        } else {
            None
        };
        let reply = SubmitRowsReply { give_back_from: give_back, next };
        let reply_len = prost::Message::encoded_len(&reply) as u64;
        s.link_bytes += reply_len;
        if let Some(entry) = s.nodes.get_mut(r.node as usize) {
            entry.link_bytes += reply_len;
        }
        Ok(Response::new(reply))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scene's state: no node yet, in `phase`.
    fn scene(phase: Phase) -> HostState {
        HostState {
            phase,
            nodes: Vec::new(),
            schedule: None,
            header: v1::SceneHeader::default(),
            fork_addrs: vec!["127.0.0.1:1".into()],
            profile: String::new(),
            scheme: "magg".into(),
            node_key: magg_plumbing::auth::NodeKey::random(),
            cache_blocks: magg_core::blocks::CacheSize::Unlimited,
            link_bytes: 0,
            rpcs: 0,
            frame_camera: None,
            events: None,
            pairs_epoch: 0,
            kept_pairs: 0,
            pilot_pairs: PilotPairs::Trace,
            next_scene: false,
            previous_key: None,
        }
    }

    fn register_request() -> Request<RegisterRequest> {
        Request::new(RegisterRequest { protocol_version: PROTOCOL_VERSION, name: "n".into(), threads: 1 })
    }

    fn work(node: u32, node_secret: u64) -> Request<NextWorkRequest> {
        Request::new(NextWorkRequest { node, report: None, node_secret })
    }

    #[tokio::test]
    async fn between_two_scenes_a_node_is_told_to_register_again_and_a_late_one_that_the_scene_is_over() {
        let host = HostService::new(scene(Phase::Lrt));
        let first = host.register(register_request()).await.unwrap().into_inner();
        assert_eq!(first.pilot_pairs, PilotPairs::Trace as i32);
        // The pilot level ends with another scene to follow: DONE says so.
        host.lock().next_scene = true;
        host.set_phase(Phase::Done);
        let done = host.next_work(work(first.node, first.node_secret)).await.unwrap().into_inner();
        assert_eq!((done.kind, done.next_scene), (Kind::Done as i32, true));
        // Registering before the next scene begins is held, then refused for a while.
        let e = host.register(register_request()).await.unwrap_err();
        assert_eq!(e.code(), tonic::Code::Unavailable);
        assert_eq!(e.message(), magg_proto::NEXT_SCENE);
        // A registration held while the next scene begins gets that scene.
        let held = {
            let host = host.clone();
            tokio::spawn(async move { host.register(register_request()).await })
        };
        tokio::time::sleep(Duration::from_millis(20)).await;
        let mut next = scene(Phase::Gather);
        next.pilot_pairs = PilotPairs::Bin;
        // The render's scene has a watcher (the live view); the pilot levels had none.
        let (events, mut watcher) = tokio::sync::mpsc::unbounded_channel();
        next.events = Some(events);
        host.begin(next);
        let again = held.await.unwrap().unwrap().into_inner();
        assert_eq!((again.node, again.pilot_pairs), (0, PilotPairs::Bin as i32));
        assert!(
            matches!(watcher.try_recv(), Ok(ClusterEvent::Registered { node: 0, .. })),
            "the watcher of the render's scene hears of its nodes"
        );
        assert_ne!(again.node_secret, first.node_secret, "each scene has a key of its own");
        // The first scene's node 0, asking late under its old secret, hears that its scene
        // is over, not an error; a secret of neither scene is refused.
        let late = host.next_work(work(first.node, first.node_secret)).await.unwrap().into_inner();
        assert_eq!((late.kind, late.next_scene), (Kind::Done as i32, true));
        let e = host.next_work(work(0, first.node_secret ^ 1)).await.unwrap_err();
        assert_eq!(e.code(), tonic::Code::PermissionDenied);
        // The render's last scene ends: DONE without another, and registering is over.
        host.set_phase(Phase::Done);
        let done = host.next_work(work(again.node, again.node_secret)).await.unwrap().into_inner();
        assert_eq!((done.kind, done.next_scene), (Kind::Done as i32, false));
        let e = host.register(register_request()).await.unwrap_err();
        assert_eq!(e.message(), magg_proto::RENDER_OVER);
    }
}
