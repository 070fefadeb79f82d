//! The work loops of one node worker: pairs from the home fork, subscreens from the host.
//!
//! The loops work on domain values: pairs arrive as a [`PairLease`] and deposits are
//! split by fork in [`crate::route`]; the messages are converted at each gRPC call.

use crate::pace::{NodePace, Processor};
use crate::report::{Totals, WorkerTotals};
use crate::route::{element_owner, Rounds};
use crate::timing::PassTimes;
use crate::NodeError;
use magg_core::camera::CameraRig;
use magg_core::cluster::PairLease;
use magg_core::kept::trace_pairs_kept;
use magg_core::lrt::PairResult;
use magg_core::pair::Pair;
use magg_core::subscreen::Subscreen;
use magg_core::trace::TraceScratch;
use magg_core::view::SceneView;
use magg_core::vrt::shade_pixels;
use magg_plumbing::auth::Authed;
use magg_plumbing::retry::retry;
use magg_plumbing::retry::Backoff;
use magg_proto::deposits::DepositWriter;
use magg_proto::v1::fork_client::ForkClient;
use magg_proto::v1::host_client::HostClient;
use magg_proto::v1::next_work_reply::Kind;
use magg_proto::v1::{self, NextWorkRequest, Row, SubmitRowsRequest, TakePairsRequest};
use magg_throttle::Scheme;
use prost::Message;
use std::collections::VecDeque;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::runtime::Handle;
use tokio::task::JoinHandle;

/// Longest pause between work requests of an idle node (the host's `wait_ms` is capped
/// to it).
pub const MAX_WAIT_MS: u32 = 1000;

/// Rows of a subscreen traced together ([`shade_pixels`]): neighbouring rows' rays read
/// the same blocks, so a bounded cache misses less the more rows go together; the host
/// can take back a subscreen's unstarted rows only between bands.
pub const BAND_ROWS: u32 = 4;

/// Longest time a node keeps finished rows before sending them to the host.
pub const ROW_REPORT: Duration = Duration::from_millis(5);

/// Pairs asked for in the first request (batched hand-out, `--scheme magg` in
/// docs/ARCHITECTURE.md; the fork may hand out fewer, see
/// `magg_fork::state::pairs::guided_batch`). Later requests ask for
/// [`next_pair_batch`] pairs. The paper's scheme asks for one pair per request.
pub const PAIR_BATCH: u32 = 64;

/// Most pairs asked for in one request: cheap pairs (a target that neither mirrors nor
/// bounces light has nothing to trace when direct light is computed at VRT) come in
/// batches this large, so that a request and a deposit per fork are not paid every 64.
pub const MAX_PAIR_BATCH: u32 = 1024;

/// Element deposits a batch's pairs are expected to make, at most (a quarter of what a
/// fork accepts in one deposit request, `magg_fork::shard::MAX_DEPOSITS`).
pub const BATCH_DEPOSITS: u64 = 1 << 18;

/// Pairs to ask for next, from the deposits the node's pairs have made so far (`pairs`
/// traced, `deposits` made): as many as keep a batch's expected deposits within
/// [`BATCH_DEPOSITS`], between [`PAIR_BATCH`] and [`MAX_PAIR_BATCH`]. The batch size
/// changes when pairs are handed out and deposited, never what they deposit.
pub fn next_pair_batch(pairs: u64, deposits: u64) -> u32 {
    if pairs == 0 {
        return PAIR_BATCH;
    }
    let per_pair = deposits.div_ceil(pairs).max(1);
    (BATCH_DEPOSITS / per_pair).clamp(PAIR_BATCH as u64, MAX_PAIR_BATCH as u64) as u32
}

/// Batches whose deposits may still be on their way while the next batch is traced.
pub const DEPOSITS_IN_FLIGHT: usize = 2;

/// Everything a worker needs.
pub struct Worker {
    /// Index among the node's workers.
    pub index: usize,
    /// Node id given by the host.
    pub node: u32,
    /// The node's secret for this render, carried by its host requests.
    pub secret: u64,
    /// The scene as this worker sees it (its own block cache).
    pub view: SceneView,
    /// Runtime the RPCs run on.
    pub rt: Handle,
    /// The host.
    pub host: HostClient<Authed>,
    /// Every fork, by index (deposits go to the owning fork).
    pub forks: Vec<ForkClient<Authed>>,
    /// The home fork's index.
    pub home: usize,
    /// Node-wide totals.
    pub totals: Arc<Totals>,
    /// This worker's counts so far.
    pub mine: WorkerTotals,
    /// Emulated extra time per pixel row.
    pub row_delay: Duration,
    /// The throttling layer's link and cost model (`None`: native profile).
    pub pace: Option<Arc<NodePace>>,
    /// This worker's emulated processor.
    pub cpu: Processor,
    /// The paper's schedule or ours.
    pub scheme: Scheme,
    /// Emulated extra time per (light, element) pair.
    pub pair_delay: Duration,
    /// Retries of calls that failed for a transient reason.
    pub backoff: Backoff,
    /// Overlap communication with tracing (next pairs requested, deposits sent in the
    /// background). Pointless when every fork is in this process and no link is
    /// emulated: a call is then only CPU work, and a background task only adds a hop to
    /// another thread; see [`overlap_pays`].
    pub overlap: bool,
    /// Where this worker's time went in the viewing pass so far.
    pub vrt: PassTimes,
    /// Nanoseconds its block cache has spent fetching blocks so far.
    pub fetching: Arc<std::sync::atomic::AtomicU64>,
    /// Refinement's pairs of point lights ([`magg_core::kept::KeptPairs`]): traced
    /// through it in a pilot level (`pilot`), binned from it where kept in the render's
    /// light pass; dropped when the viewing pass begins.
    pub kept_pairs: Option<Arc<magg_core::kept::KeptPairs>>,
    /// This scene is one of refinement's pilot levels: pairs go through `kept_pairs`.
    pub pilot: bool,
}

/// Whether a node gains by overlapping communication with tracing: when a link is
/// emulated (its transfer time is slept, not computed) or some fork is reached over a
/// socket (a round trip waits on the network).
pub fn overlap_pays(paced: bool, links: &magg_plumbing::transport::InProcess, fork_addrs: &[String]) -> bool {
    paced || fork_addrs.iter().any(|a| links.get(a).is_none())
}

impl Worker {
    /// Pays the emulated processor for the operations done since the last payment.
    fn compute(&mut self) {
        if let Some(p) = &self.pace {
            self.cpu.pay(p, self.view.counters);
        }
    }

    /// Pays the link for a message sent and its reply, from the worker thread.
    fn link_blocking(&self, sent: usize, received: usize) {
        if let Some(p) = &self.pace {
            p.send_blocking(sent);
            p.recv_blocking(received);
        }
    }

    fn publish(&mut self) {
        self.mine.cache = self.view.cache_stats();
        self.mine.ops = self.view.counters;
        self.totals.set(self.index, self.mine);
    }

    /// Asks the host for work until it says done; returns whether the host said that
    /// another scene of the render follows.
    pub fn run(mut self) -> Result<bool, NodeError> {
        let mut handed: Option<v1::NextWorkReply> = None;
        loop {
            self.publish();
            // Work handed with the reply to the last rows was not held by the host: a
            // WAIT there is followed at once by a NextWork, which the host holds.
            let from_rows = handed.is_some();
            let asked = Instant::now();
            let reply = match handed.take() {
                Some(r) => r,
                None => {
                    let req = NextWorkRequest {
                        node: self.node,
                        report: Some((&self.totals.report()).into()),
                        node_secret: self.secret,
                    };
                    let sent = req.encoded_len();
                    // A lost answer is harmless: a subscreen handed out and never traced
                    // goes back to the queue when its lease expires.
                    let call = retry("NextWork", self.backoff, || {
                        let mut host = self.host.clone();
                        async move { host.next_work(req).await.map(|r| r.into_inner()) }
                    });
                    let reply = self.rt.block_on(call).map_err(NodeError::rpc("NextWork"))?;
                    self.link_blocking(sent, reply.encoded_len());
                    reply
                }
            };
            let kind = Kind::try_from(reply.kind).unwrap_or(Kind::Wait);
            match kind {
                Kind::Wait => {
                    if from_rows {
                        continue;
                    }
                    // The host held the call while there was nothing to do (and answers
                    // at once when the phase changes): pause as it says, then ask again.
                    std::thread::sleep(Duration::from_millis(reply.wait_ms.clamp(1, MAX_WAIT_MS) as u64));
                    continue;
                }
                Kind::Pairs => self.pairs()?,
                Kind::Subscreen => match reply.subscreen {
                    Some(s) => {
                        self.kept_pairs = None;
                        PassTimes::lap(&mut self.vrt.asking, asked);
                        self.vrt.unit(asked);
                        handed = self.subscreen(s)?
                    }
                    None => return Err(NodeError::Convert("SUBSCREEN work without a subscreen".into())),
                },
                Kind::Done => {
                    self.vrt.log(self.node, "viewing pass", &self.fetching);
                    self.publish();
                    let mut host = self.host.clone();
                    // Final report, so the host's stats include everything.
                    let req = NextWorkRequest {
                        node: self.node,
                        report: Some((&self.totals.report()).into()),
                        node_secret: self.secret,
                    };
                    let _ = self.rt.block_on(host.next_work(req));
                    return Ok(reply.next_scene);
                }
            }
        }
    }

    /// Pulls pairs from the home fork until no fork has any left. Communication overlaps
    /// computation, as the paper's higher-priority communication process did: the next
    /// batch of pairs is requested while this one is traced, and a batch's deposits are
    /// sent in the background (at most [`DEPOSITS_IN_FLIGHT`] batches behind).
    fn pairs(&mut self) -> Result<(), NodeError> {
        let h = self.view.header.clone();
        let elements = h.counts.elements;
        let total = h.pair_count();
        let mut scratch = TraceScratch::default();
        let paper = self.scheme == Scheme::Paper;
        // Pairs traced and deposits made so far, for the size of the next request.
        let (mut traced, mut deposited) = (0u64, 0u64);
        let pace = self.pace.clone();
        // Lost answers are harmless: pairs handed out and never traced go back to the
        // queue when their lease expires.
        let (backoff, secret) = (self.backoff, self.secret);
        let take = move |home: ForkClient<Authed>, node: u32, max: u32| {
            let pace = pace.clone();
            async move {
                let req = TakePairsRequest { max, node, node_secret: secret, own_only: false };
                if let Some(p) = &pace {
                    p.send(req.encoded_len()).await;
                }
                let reply = retry("TakePairs", backoff, move || {
                    let mut home = home.clone();
                    async move { home.take_pairs(req).await.map(|r| r.into_inner()) }
                })
                .await
                .map_err(NodeError::rpc("TakePairs"))?;
                if let Some(p) = &pace {
                    p.recv(reply.encoded_len()).await;
                }
                lease_from_wire(reply)
            }
        };
        let mut in_flight: VecDeque<JoinHandle<Result<(), NodeError>>> = VecDeque::new();
        // The next batch's request: already on its way when overlapping, else made when
        // this batch is done.
        let batch = |traced: u64, deposited: u64| if paper { 1 } else { next_pair_batch(traced, deposited) };
        let ask = |w: &Self, max: u32| w.overlap.then(|| w.rt.spawn(take(w.forks[w.home].clone(), w.node, max)));
        let mut next = ask(self, batch(0, 0));
        let mut times = PassTimes::default();
        // Without overlap, the next batch is asked for in the call that completes this
        // one on the home fork, and arrives with its reply.
        let mut piggybacked: Option<PairLease> = None;
        loop {
            let t = Instant::now();
            let got = match (piggybacked.take(), next.take()) {
                (Some(r), _) => r,
                (None, Some(t)) => self.rt.block_on(t).map_err(|e| NodeError::Worker(e.to_string()))??,
                (None, None) => {
                    self.rt.block_on(take(self.forks[self.home].clone(), self.node, batch(traced, deposited)))?
                }
            };
            let asked = PassTimes::lap(&mut times.asking, t);
            if got.pairs.is_empty() {
                if got.exhausted {
                    break;
                }
                std::thread::sleep(Duration::from_millis(2));
                next = ask(self, batch(traced, deposited));
                continue;
            }
            next = ask(self, batch(traced, deposited));
            times.unit(t);
            let t = asked;
            tracing::debug!(node = self.node, pairs = got.pairs.len(), "tracing a batch of pairs");
            // Split by fork in two rounds (see crate::route).
            let mut rounds = Rounds::new(self.forks.len(), got.epoch);
            let mut leased = Vec::with_capacity(got.pairs.len());
            for &pair in &got.pairs {
                if pair >= total || elements == 0 {
                    return Err(NodeError::Convert(format!("pair {pair} out of range ({total} pairs)")));
                }
                leased.push(Pair::from_id(pair, elements));
            }
            // Each pair's deposits are routed as it comes back (while they are hot).
            let (layout, forks) = (self.view.header.layout, self.forks.len());
            let owner_of = |e: u32| element_owner(&layout, forks, e);
            let (delay, mine) = (self.pair_delay, &mut self.mine);
            let each = |i: usize, r: PairResult| {
                let (pair, element) = (got.pairs[i], leased[i].element);
                if !delay.is_zero() {
                    std::thread::sleep(delay);
                }
                mine.pairs += 1;
                mine.tally = mine.tally.add(r.tally);
                (traced, deposited) = (traced + 1, deposited + r.deposits.len() as u64);
                rounds.add(pair, owner_of(element), r.deposits, owner_of);
            };
            match (&self.kept_pairs, self.pilot) {
                (Some(store), true) => store.trace_each(&mut self.view, &mut scratch, &leased, each)?,
                (kept, _) => trace_pairs_kept(&mut self.view, &mut scratch, &leased, kept.as_deref(), each)?,
            }
            self.compute();
            let (round1, round2) = rounds.into_writers();
            let t = PassTimes::lap(&mut times.tracing, t);
            let max = batch(traced, deposited);
            let home_take = (!self.overlap).then_some((
                self.home,
                TakePairsRequest { max, node: self.node, node_secret: self.secret, own_only: false },
            ));
            let send = send_deposits(self.forks.clone(), self.pace.clone(), round1, round2, self.backoff, home_take);
            if !self.overlap {
                piggybacked = self.rt.block_on(send)?;
                PassTimes::lap(&mut times.sending, t);
                self.publish();
                continue;
            }
            while in_flight.len() >= DEPOSITS_IN_FLIGHT {
                if let Some(t) = in_flight.pop_front() {
                    self.rt.block_on(t).map_err(|e| NodeError::Worker(e.to_string()))??;
                }
            }
            in_flight.push_back(self.rt.spawn(async move { send.await.map(|_| ()) }));
            PassTimes::lap(&mut times.sending, t);
            self.publish();
        }
        let t = Instant::now();
        for t in in_flight {
            self.rt.block_on(t).map_err(|e| NodeError::Worker(e.to_string()))??;
        }
        PassTimes::lap(&mut times.sending, t);
        times.log(self.node, "light pass", &self.fetching);
        Ok(())
    }

    /// Traces a subscreen row by row, sending rows as it goes; stops early when the host
    /// asks for the unstarted rows back. Returns the next work if the host sent it with
    /// the reply to the last rows.
    fn subscreen(&mut self, s: v1::Subscreen) -> Result<Option<v1::NextWorkReply>, NodeError> {
        let h = self.view.header.clone();
        let (w, hgt) = (h.settings.width, h.settings.height);
        if s.w == 0 || s.h == 0 || s.x.saturating_add(s.w) > w || s.y.saturating_add(s.h) > hgt {
            return Err(NodeError::Convert(format!(
                "subscreen {}x{}+{}+{} outside the {w}x{hgt} image",
                s.w, s.h, s.x, s.y
            )));
        }
        tracing::debug!(node = self.node, id = s.id, "tracing a subscreen {}x{}+{}+{}", s.w, s.h, s.x, s.y);
        // A camera path sends each frame's camera with its subscreens.
        let camera = match s.camera {
            Some(c) => magg_core::scene::Camera::try_from(c).map_err(|e| NodeError::Convert(e.to_string()))?,
            None => h.camera.clone(),
        };
        let rig = CameraRig::new(&camera, w, hgt);
        let mut scratch = TraceScratch::default();
        let mut pixels = Vec::with_capacity((s.w * BAND_ROWS) as usize);
        let mut end = s.y + s.h;
        let mut y = s.y;
        // Rows go to the host in batches: at least every ROW_REPORT of work, so that the
        // host can redivide a long subscreen, and never one RPC per row on fast tiles.
        let mut rows = Vec::new();
        let mut since = Instant::now();
        let mut t = since;
        while y < end {
            // A band of rows at a time: its pixels' rays are traced together.
            let band = Subscreen { x: s.x, y, w: s.w, h: BAND_ROWS.min(end - y) };
            pixels.clear();
            shade_pixels(&mut self.view, &mut scratch, &rig, band, &mut pixels)?;
            for row in pixels.chunks(s.w as usize) {
                let mut rgb = Vec::with_capacity(12 * s.w as usize);
                for c in row {
                    for v in c.0 {
                        rgb.extend_from_slice(&(v as f32).to_le_bytes());
                    }
                }
                self.compute();
                if !self.row_delay.is_zero() {
                    std::thread::sleep(self.row_delay);
                }
                rows.push(Row { y, rgb: rgb.into() });
                y += 1;
            }
            if y < end && since.elapsed() < ROW_REPORT {
                continue;
            }
            let last = y >= end;
            if last {
                self.mine.tiles += 1;
                self.publish();
            }
            t = PassTimes::lap(&mut self.vrt.tracing, t);
            let req = SubmitRowsRequest {
                node: self.node,
                subscreen: s.id,
                rows: std::mem::take(&mut rows),
                last,
                node_secret: self.secret,
            };
            let sent = req.encoded_len();
            // Repeated rows are acknowledged and ignored: safe to retry.
            let call = retry("SubmitRows", self.backoff, || {
                let (mut host, req) = (self.host.clone(), req.clone());
                async move { host.submit_rows(req).await.map(|r| r.into_inner()) }
            });
            let reply = self.rt.block_on(call).map_err(NodeError::rpc("SubmitRows"))?;
            self.link_blocking(sent, reply.encoded_len());
            t = PassTimes::lap(&mut self.vrt.sending, t);
            since = t;
            // Stop before row `from`: rows not started were redivided; a `from` at or
            // before `y` means the subscreen was revoked (this node was taken for lost).
            if let Some(from) = reply.give_back_from {
                if from < end {
                    end = from.max(y);
                }
            }
            if last {
                return Ok(reply.next);
            }
        }
        self.mine.tiles += 1;
        Ok(None)
    }
}

/// The pairs of a `TakePairs` reply (alone or riding on a `Deposit` reply).
fn lease_from_wire(r: v1::TakePairsReply) -> Result<PairLease, NodeError> {
    PairLease::try_from(r).map_err(|e| NodeError::Convert(e.to_string()))
}

/// Sends a batch's deposits: every round-1 message, then every round-2 message. Deposits
/// are keyed by pair: a retried one is applied once. `take` (the home fork's index and a
/// request) rides on a round-2 message, and its answer is returned (`None`: ask the home
/// fork separately): on the one to the home fork, or else (pairs the home fork stole)
/// on the one with the most pairs, as a take of that fork's own pairs only
/// ([`carrier`]).
async fn send_deposits(
    forks: Vec<ForkClient<Authed>>,
    pace: Option<Arc<NodePace>>,
    round1: Vec<DepositWriter>,
    round2: Vec<DepositWriter>,
    backoff: Backoff,
    take: Option<(usize, TakePairsRequest)>,
) -> Result<Option<PairLease>, NodeError> {
    let mut taken = None;
    let take = take.and_then(|(home, t)| carrier(&round2, home, t));
    for round in [round1, round2] {
        for (fork, pairs) in round.into_iter().enumerate() {
            if pairs.is_empty() {
                continue;
            }
            let Some(client) = forks.get(fork) else {
                return Err(NodeError::Convert(format!("fork {fork} of {}", forks.len())));
            };
            let mut req = pairs.finish();
            if let Some((on, t)) = &take {
                if req.complete && *on == fork {
                    req.take = Some(*t);
                }
            }
            if let Some(p) = &pace {
                p.send(req.encoded_len()).await;
            }
            let reply = retry("Deposit", backoff, || {
                let (mut c, req) = (client.clone(), req.clone());
                async move { c.deposit(req).await }
            })
            .await
            .map_err(NodeError::rpc("Deposit"))?
            .into_inner();
            if let Some(p) = &pace {
                p.recv(reply.encoded_len()).await;
            }
            if let Some(t) = &req.take {
                taken = reply.taken.map(lease_from_wire).transpose()?;
                // The lender has none left: the home fork is asked (and steals elsewhere).
                if t.own_only && taken.as_ref().is_some_and(|l| l.pairs.is_empty()) {
                    taken = None;
                }
            }
        }
    }
    Ok(taken)
}

/// Which round-2 message carries the node's take `t` (its home fork `home`): the one to
/// the home fork; or, when the batch holds none of the home fork's pairs (it stole them
/// all), the one with the most pairs, asking that fork, which lent them, for more of its
/// own. `None` when no round-2 message is sent.
fn carrier(round2: &[DepositWriter], home: usize, t: TakePairsRequest) -> Option<(usize, TakePairsRequest)> {
    if round2.get(home).is_some_and(|w| !w.is_empty()) {
        return Some((home, t));
    }
    let (lender, w) = round2.iter().enumerate().max_by_key(|(k, w)| (w.len(), std::cmp::Reverse(*k)))?;
    (!w.is_empty()).then_some((lender, TakePairsRequest { own_only: true, ..t }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The take rides to the home fork when the batch completes pairs there, else to the
    /// fork completing the most pairs, for its own pairs only.
    #[test]
    fn a_take_rides_home_or_to_the_lender() {
        let t = TakePairsRequest { max: 9, node: 1, node_secret: 5, own_only: false };
        let writers = |pairs: &[usize]| -> Vec<DepositWriter> {
            pairs
                .iter()
                .map(|&n| {
                    let mut w = DepositWriter::new(true, 0);
                    (0..n as u64).for_each(|p| w.pair(p));
                    w
                })
                .collect()
        };
        assert_eq!(carrier(&writers(&[0, 1, 7]), 1, t), Some((1, t)));
        assert_eq!(carrier(&writers(&[0, 0, 7, 3]), 1, t), Some((2, TakePairsRequest { own_only: true, ..t })));
        // A tie goes to the lower fork.
        assert_eq!(carrier(&writers(&[2, 0, 2]), 1, t).map(|c| c.0), Some(0));
        assert_eq!(carrier(&writers(&[0, 0, 0]), 1, t), None);
    }

    #[test]
    fn pair_batches_grow_for_cheap_pairs_and_keep_deposits_bounded() {
        // Nothing traced yet: the first batch.
        assert_eq!(next_pair_batch(0, 0), PAIR_BATCH);
        // Pairs that deposit nothing (direct light at VRT, a diffuse target): the largest.
        assert_eq!(next_pair_batch(500, 0), MAX_PAIR_BATCH);
        // Pairs with many deposits: as many as keep a batch within the budget...
        assert_eq!(next_pair_batch(100, 100 * 1024), (BATCH_DEPOSITS / 1024) as u32);
        // ... but never fewer than the first batch.
        assert_eq!(next_pair_batch(10, 10 * 100_000), PAIR_BATCH);
        // A batch's expected deposits stay within a quarter of what a fork accepts.
        for per_pair in [1u64, 7, 100, 300, 5000] {
            let n = next_pair_batch(64, 64 * per_pair) as u64;
            assert!(n * per_pair <= BATCH_DEPOSITS.max(PAIR_BATCH as u64 * per_pair), "{per_pair}: {n}");
        }
    }
}
