//! The fork service over real gRPC: three forks on 127.0.0.1:0 sharing the paper's test
//! scene (with a second light), driven as nodes and the host would drive them.

use magg_core::blocks::BLOCK_SIZE;
use magg_core::cluster::PairLease;
use magg_core::pair::Pair;
use magg_core::prepared::PreparedScene;
use magg_core::scene::parse_scene_str;
use magg_plumbing::auth::Authed;
use magg_prepare::prepare;
use magg_proto::deposits::DepositWriter;
use magg_proto::v1;
use magg_proto::v1::fork_client::ForkClient;
use std::collections::BTreeSet;
use tokio::sync::oneshot;
use tokio::task::JoinHandle;
use tonic::Code;

const FORKS: u32 = 3;

/// The paper's scene (1664 elements) with a second light: 3328 pairs.
fn paper_scene() -> PreparedScene {
    let text = include_str!("../../scenes/magg-paper.toml");
    let read = |p: &std::path::Path| std::fs::read(p);
    let mut scene = parse_scene_str("magg-paper.toml", text, "scenes".as_ref(), &read).unwrap();
    let mut second = scene.lights[0].clone();
    second.position.x += 1.0;
    scene.lights.push(second);
    prepare(&scene).unwrap()
}

struct Cluster {
    scene: PreparedScene,
    addrs: Vec<String>,
    clients: Vec<ForkClient<Authed>>,
    stops: Vec<oneshot::Sender<()>>,
    servers: Vec<JoinHandle<Result<(), tonic::transport::Error>>>,
}

impl Cluster {
    /// `FORKS` forks serving, nothing loaded.
    async fn start() -> Cluster {
        let (mut addrs, mut stops, mut servers, mut clients) = (vec![], vec![], vec![], vec![]);
        for _ in 0..FORKS {
            let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
            addrs.push(listener.local_addr().unwrap().to_string());
            let (stop, stopped) = oneshot::channel::<()>();
            stops.push(stop);
            servers.push(tokio::spawn(magg_fork::serve(listener, Default::default(), async {
                stopped.await.ok();
            })));
        }
        for a in &addrs {
            clients.push(magg_fork::connect(a, &Default::default()).await.unwrap());
        }
        Cluster { scene: paper_scene(), addrs, clients, stops, servers }
    }

    fn elements(&self) -> u32 {
        self.scene.header.counts.elements
    }

    fn pairs(&self) -> u64 {
        self.scene.header.lights.len() as u64 * self.elements() as u64
    }

    fn total_blocks(&self) -> u32 {
        self.scene.header.layout.total
    }

    fn element_owner(&self, e: u32) -> u32 {
        self.scene.header.layout.element_slot(e).0 % FORKS
    }

    /// The `LoadShard` request of fork `i`.
    fn load_request(&self, i: u32) -> v1::LoadShardRequest {
        let blocks = (0..self.total_blocks())
            .filter(|b| b % FORKS == i)
            .map(|b| magg_proto::convert::block_to_wire(b, &self.scene.blocks[b as usize]))
            .collect();
        v1::LoadShardRequest {
            protocol_version: magg_proto::PROTOCOL_VERSION,
            fork_index: i,
            fork_addrs: self.addrs.clone(),
            header: Some(v1::SceneHeader::from(&*self.scene.header)),
            blocks,
            ..Default::default()
        }
    }

    async fn load_all(&mut self) {
        for i in 0..FORKS {
            let req = self.load_request(i);
            let reply = self.clients[i as usize].load_shard(req).await.unwrap().into_inner();
            let owned = (0..self.total_blocks()).filter(|b| b % FORKS == i).count() as u32;
            assert_eq!(reply.blocks, owned);
        }
    }

    async fn energies(&mut self, i: u32) -> v1::GetEnergiesReply {
        let req = v1::GetEnergiesRequest { summary_only: false, monitor: false };
        self.clients[i as usize].get_energies(req).await.unwrap().into_inner()
    }

    async fn stop(self) {
        for s in self.stops {
            s.send(()).ok();
        }
        for h in self.servers {
            h.await.unwrap().unwrap();
        }
    }
}

/// A `TakePairs` reply's pairs.
fn lease(r: v1::TakePairsReply) -> PairLease {
    PairLease::try_from(r).expect("a malformed array of pairs")
}

/// A request of pairs (pair, element, r g b) with one deposit each, in epoch 0.
fn deposits(complete: bool, pairs: &[(u64, u32, [i64; 3])]) -> v1::DepositRequest {
    let mut w = DepositWriter::new(complete, 0);
    for &(pair, element, rgb) in pairs {
        w.pair(pair);
        w.deposit(element, rgb);
    }
    w.finish()
}

fn code<T: std::fmt::Debug>(r: Result<tonic::Response<T>, tonic::Status>) -> (Code, String) {
    let s = r.expect_err("a bad request was accepted");
    (s.code(), s.message().to_string())
}

#[tokio::test]
async fn get_blocks_serves_every_forks_blocks_in_request_order() {
    let mut c = Cluster::start().await;
    c.load_all().await;
    let last = c.total_blocks() - 1;
    let element_base = c.scene.header.layout.element_base;
    let ids = vec![last, 2, 0, 1, element_base + 1, 5, 4, 3, last, element_base];
    let reply = c.clients[0].get_blocks(v1::GetBlocksRequest { ids: ids.clone() }).await.unwrap().into_inner();
    assert_eq!(reply.blocks.iter().map(|b| b.id).collect::<Vec<_>>(), ids);
    for b in &reply.blocks {
        assert_eq!(&b.data[..], &c.scene.blocks[b.id as usize][..], "block {}", b.id);
    }
    let remote = ids.iter().filter(|&&id| id % FORKS != 0).count() as u64;
    let e = c.energies(0).await;
    assert_eq!(e.dma_bytes, ids.len() as u64 * BLOCK_SIZE as u64);
    assert_eq!(e.gbus_bytes, remote * BLOCK_SIZE as u64);
    assert!(e.rpcs >= 2, "LoadShard and GetBlocks were counted: {}", e.rpcs);
    let empty = c.clients[0].get_blocks(v1::GetBlocksRequest { ids: vec![] }).await.unwrap().into_inner();
    assert!(empty.blocks.is_empty());
    c.stop().await;
}

#[tokio::test]
async fn take_pairs_from_one_fork_drains_every_pair_exactly_once() {
    let mut c = Cluster::start().await;
    c.load_all().await;
    let mut totals = 0;
    for i in 0..FORKS {
        totals += c.energies(i).await.pairs_total;
    }
    assert_eq!(totals, c.pairs());
    let mut seen = BTreeSet::new();
    let mut stolen = 0;
    loop {
        let r = c.clients[1]
            .take_pairs(v1::TakePairsRequest { max: 100, node: 7, ..Default::default() })
            .await
            .unwrap()
            .into_inner();
        let r = lease(r);
        if r.exhausted {
            assert!(r.pairs.is_empty());
            break;
        }
        assert!(!r.pairs.is_empty() && r.pairs.len() <= 100);
        for p in r.pairs {
            assert!(p < c.pairs(), "pair {p} out of range");
            assert!(seen.insert(p), "pair {p} handed out twice");
            stolen += (c.element_owner((p % c.elements() as u64) as u32) != 1) as usize;
        }
    }
    assert_eq!(seen.len() as u64, c.pairs());
    assert!(stolen > 0, "fork 1 handed out only its own pairs");
    for i in 0..FORKS {
        let r = c.clients[i as usize]
            .take_pairs(v1::TakePairsRequest { max: 0, node: 0, ..Default::default() })
            .await
            .unwrap()
            .into_inner();
        assert!(r.exhausted && r.pairs.is_empty(), "fork {i} still had pairs");
    }
    c.stop().await;
}

#[tokio::test]
async fn own_pairs_come_first_in_ascending_order() {
    let mut c = Cluster::start().await;
    c.load_all().await;
    let own: Vec<u64> = (0..c.pairs()).filter(|p| c.element_owner((p % c.elements() as u64) as u32) == 2).collect();
    assert!(own.len() < 4096);
    // A max over the limit is clamped, not refused; the own queue is not empty, so
    // nothing is stolen.
    let r = c.clients[2]
        .take_pairs(v1::TakePairsRequest { max: 50_000, node: 0, ..Default::default() })
        .await
        .unwrap()
        .into_inner();
    let r = lease(r);
    assert_eq!(r.pairs, own);
    assert!(!r.exhausted);
    c.stop().await;
}

/// A take with `own_only` gets the answering fork's own pairs and never steals: once they
/// are gone its reply is empty (this fork has none), while a plain take steals. On the
/// completion of pairs a fork lent, such a take asks it for the next of its own.
#[tokio::test]
async fn an_own_only_take_never_steals() {
    let mut c = Cluster::start().await;
    c.load_all().await;
    let own_of = |f: u32| -> Vec<u64> {
        (0..c.pairs()).filter(|p| c.element_owner((p % c.elements() as u64) as u32) == f).collect()
    };
    let (own2, own1) = (own_of(2), own_of(1));
    let only = v1::TakePairsRequest { max: 4096, node: 3, own_only: true, ..Default::default() };
    let mut got = Vec::new();
    loop {
        let r = lease(c.clients[2].take_pairs(only).await.unwrap().into_inner());
        if r.pairs.is_empty() {
            assert!(r.exhausted, "an empty own-only reply says the fork has none");
            break;
        }
        got.extend(r.pairs);
    }
    assert_eq!(got, own2);
    let plain = v1::TakePairsRequest { max: 8, own_only: false, ..only };
    let stolen = lease(c.clients[2].take_pairs(plain).await.unwrap().into_inner());
    assert!(!stolen.pairs.is_empty() && stolen.pairs.iter().all(|p| !own2.contains(p)), "a plain take steals");

    // Fork 1 lends four pairs; their completion asks it for four more.
    let four = v1::TakePairsRequest { max: 4, ..only };
    let first = lease(c.clients[1].take_pairs(four).await.unwrap().into_inner()).pairs;
    assert!(own1.len() >= 16 && first.len() == 4 && first.iter().all(|p| own1.contains(p)));
    let mut w = DepositWriter::new(true, 0);
    for &p in &first {
        w.pair(p);
    }
    let mut req = w.finish();
    req.take = Some(four);
    let r = c.clients[1].deposit(req).await.unwrap().into_inner();
    let next = lease(r.taken.expect("no pairs came back with the completion"));
    assert_eq!(next.pairs.len(), 4);
    assert!(next.pairs.iter().all(|p| own1.contains(p) && !first.contains(p)), "{:?}", next.pairs);
    c.stop().await;
}

/// The completion of a batch may ask for the next one: the deposits are applied, then
/// the pairs taken, as a separate TakePairs would take them; a refused deposit takes
/// nothing.
#[tokio::test]
async fn a_completion_can_carry_the_next_take() {
    let mut c = Cluster::start().await;
    c.load_all().await;
    let take = v1::TakePairsRequest { max: 4, node: 3, ..Default::default() };
    let first = lease(c.clients[2].take_pairs(take).await.unwrap().into_inner());
    assert_eq!(first.pairs.len(), 4);
    let mut w = DepositWriter::new(true, first.epoch);
    for &p in &first.pairs {
        w.pair(p);
        w.deposit((p % c.elements() as u64) as u32, [1, 2, 3]);
    }
    let mut req = w.finish();
    req.take = Some(take);
    let mut torn = req.clone();
    torn.counts = torn.counts.slice(..torn.counts.len() - 1); // one count (a varint below 128) less
    assert_eq!(code(c.clients[2].deposit(torn).await).0, Code::InvalidArgument);
    let r = c.clients[2].deposit(req).await.unwrap().into_inner();
    assert_eq!((r.applied, r.duplicates), (4, 0));
    let next = lease(r.taken.expect("no pairs came back with the completion"));
    // The refused request took nothing: the next four follow the first four.
    let own: Vec<u64> = (0..c.pairs()).filter(|p| c.element_owner((p % c.elements() as u64) as u32) == 2).collect();
    assert_eq!([first.pairs, next.pairs].concat(), own[..8].to_vec());
    assert_eq!(c.energies(2).await.pairs_done, 4);
    // Without a take, no pairs come back.
    let plain = deposits(false, &[]);
    assert!(c.clients[2].deposit(plain).await.unwrap().into_inner().taken.is_none());
    c.stop().await;
}

#[tokio::test]
async fn deposits_apply_exactly_once_and_energies_sum() {
    let mut c = Cluster::start().await;
    c.load_all().await;
    let e = c.elements();
    let on = |f: u32| (0..e).filter(|&x| c.element_owner(x) == f).collect::<Vec<_>>();
    let (own0, own1) = (on(0), on(1));
    let (a, b) = (own1[0], own1[own1.len() - 1]);
    // Pair (light 1, a): complete on fork 1, which owns a.
    let p = Pair::new(1, a).id(e);
    let mut w = DepositWriter::new(true, 0);
    w.pair(p);
    w.deposit(a, [5, 6, 7]);
    w.deposit(b, [1, 1, 1]);
    w.deposit(a, [10, 0, 0]);
    let req = w.finish();
    let r1 = c.clients[1].deposit(req.clone()).await.unwrap().into_inner();
    assert_eq!((r1.applied, r1.duplicates), (1, 0));
    let r2 = c.clients[1].deposit(req).await.unwrap().into_inner();
    assert_eq!((r2.applied, r2.duplicates), (0, 1));
    // A pair of fork 0's element whose secondary rays reached fork 1's element b.
    let q = Pair::new(0, own0[3]).id(e);
    let r3 = c.clients[1].deposit(deposits(false, &[(q, b, [2, 3, 4])])).await.unwrap();
    assert_eq!(r3.into_inner().applied, 1);
    let r4 = c.clients[0].deposit(deposits(true, &[(q, own0[3], [100, 0, 0])])).await;
    assert_eq!(r4.unwrap().into_inner().applied, 1);

    let e1 = c.energies(1).await;
    assert_eq!(magg_proto::packed::varints_u32(&e1.elements).unwrap(), own1, "every owned element, ascending");
    let get = |r: &v1::GetEnergiesReply, el: u32| {
        magg_proto::convert::element_energies(r).unwrap().find(|x| x.0 == el).unwrap().1
    };
    assert_eq!(get(&e1, a), [15, 6, 7]);
    assert_eq!(get(&e1, b), [3, 4, 5]);
    assert_eq!(e1.pairs_done, 1);
    let req = v1::GetEnergiesRequest { summary_only: true, monitor: false };
    let summary = c.clients[1].get_energies(req).await.unwrap().into_inner();
    assert!(summary.elements.is_empty() && summary.energy.is_empty());
    assert_eq!((summary.pairs_done, summary.pairs_total), (1, e1.pairs_total));
    let e0 = c.energies(0).await;
    assert_eq!(get(&e0, own0[3]), [100, 0, 0]);
    assert_eq!(e0.pairs_done, 1);
    let mut sum = [0i64; 3];
    let mut count = 0;
    for i in 0..FORKS {
        let r = c.energies(i).await;
        for (_, x) in magg_proto::convert::element_energies(&r).unwrap() {
            sum = [sum[0] + x[0], sum[1] + x[1], sum[2] + x[2]];
            count += 1;
        }
    }
    assert_eq!(count, e, "the forks together report every element once");
    assert_eq!(sum, [118, 10, 12]);
    c.stop().await;
}

#[tokio::test]
async fn bad_requests_get_the_right_codes_and_the_server_keeps_serving() {
    let mut c = Cluster::start().await;
    // Before LoadShard.
    let (k, m) = code(c.clients[0].get_energies(v1::GetEnergiesRequest { summary_only: true, monitor: false }).await);
    assert_eq!((k, m.as_str()), (Code::Unavailable, "no scene loaded"));
    let (k, _) = code(c.clients[0].take_pairs(v1::TakePairsRequest { max: 1, node: 0, ..Default::default() }).await);
    assert_eq!(k, Code::Unavailable, "an empty fork is retried until the host loads it");
    // Wrong protocol version.
    let mut req = c.load_request(0);
    req.protocol_version = magg_proto::PROTOCOL_VERSION + 1;
    let (k, m) = code(c.clients[0].load_shard(req).await);
    assert_eq!(k, Code::FailedPrecondition);
    assert!(
        m.contains(&(magg_proto::PROTOCOL_VERSION + 1).to_string())
            && m.contains(&magg_proto::PROTOCOL_VERSION.to_string()),
        "{m}"
    );
    c.load_all().await;

    let total = c.total_blocks();
    let (k, m) = code(c.clients[0].get_blocks(v1::GetBlocksRequest { ids: vec![0, total + 5] }).await);
    assert_eq!(k, Code::InvalidArgument);
    assert!(m.contains(&(total + 5).to_string()), "{m}");
    let (k, _) = code(c.clients[0].get_blocks(v1::GetBlocksRequest { ids: vec![0; 4097] }).await);
    assert_eq!(k, Code::ResourceExhausted);
    let (k, _) = code(c.clients[0].peer_blocks(v1::GetBlocksRequest { ids: vec![1] }).await);
    assert_eq!(k, Code::InvalidArgument);

    // Deposits: element not owned, element out of range, pair out of range, complete on
    // another fork's pair.
    let e = c.elements();
    let own = |f: u32| (0..e).find(|&x| c.element_owner(x) == f).unwrap();
    let (a0, a1) = (own(0), own(1));
    let bad = [
        ((Pair::new(0, a0).id(e), a1, [1, 1, 1]), false),
        ((Pair::new(0, a0).id(e), e, [1, 1, 1]), false),
        ((c.pairs(), a0, [1, 1, 1]), false),
        ((Pair::new(0, a1).id(e), a0, [1, 1, 1]), true),
    ];
    for (i, (d, complete)) in bad.into_iter().enumerate() {
        // The good pair first: a refused request must apply nothing.
        let good = (Pair::new(1, a0).id(e), a0, [9, 9, 9]);
        let (k, m) = code(c.clients[0].deposit(deposits(complete, &[good, d])).await);
        assert_eq!(k, Code::InvalidArgument, "case {i}: {m}");
    }
    // Arrays that do not fit together.
    let mut torn = deposits(true, &[(Pair::new(1, a0).id(e), a0, [9, 9, 9])]);
    torn.energy = torn.energy.slice(..torn.energy.len() - 8);
    let (k, m) = code(c.clients[0].deposit(torn).await);
    assert_eq!(k, Code::InvalidArgument, "{m}");
    assert!(m.contains("energy values"), "{m}");
    let e0 = c.energies(0).await;
    assert!(e0.energy.iter().all(|&x| x == 0), "a refused deposit changed energies");
    assert_eq!(e0.pairs_done, 0);
    let good = deposits(true, &[(Pair::new(1, a0).id(e), a0, [9, 9, 9])]);
    let r = c.clients[0].deposit(good).await.unwrap().into_inner();
    assert_eq!((r.applied, r.duplicates), (1, 0), "the pair was not marked applied by the refused requests");

    // Bad shards: a block of another fork, a short block, a bad index, a bad header.
    let mut req = c.load_request(0);
    req.blocks.push(magg_proto::convert::block_to_wire(1, &c.scene.blocks[1]));
    assert_eq!(code(c.clients[0].load_shard(req).await).0, Code::InvalidArgument);
    let mut req = c.load_request(0);
    req.blocks[0].data.truncate(100);
    assert_eq!(code(c.clients[0].load_shard(req).await).0, Code::InvalidArgument);
    let mut req = c.load_request(0);
    req.fork_index = FORKS;
    assert_eq!(code(c.clients[0].load_shard(req).await).0, Code::InvalidArgument);
    let mut req = c.load_request(0);
    req.header.as_mut().unwrap().settings.as_mut().unwrap().width = 0;
    let (k, m) = code(c.clients[0].load_shard(req).await);
    assert_eq!(k, Code::InvalidArgument);
    assert!(m.contains("settings.width"), "{m}");
    let (k, _) = code(
        c.clients[0]
            .put_blocks(v1::PutBlocksRequest {
                blocks: vec![v1::Block { id: total, data: vec![0; BLOCK_SIZE].into() }],
            })
            .await,
    );
    assert_eq!(k, Code::InvalidArgument);

    // Still serving the shard loaded before the refused requests.
    let ids = vec![0, 1, 2];
    let reply = c.clients[0].get_blocks(v1::GetBlocksRequest { ids }).await.unwrap().into_inner();
    assert_eq!(&reply.blocks[2].data[..], &c.scene.blocks[2][..]);
    assert_eq!(c.energies(0).await.pairs_done, 1, "the earlier render was kept");
    c.stop().await;
}

#[tokio::test]
async fn put_blocks_replaces_owned_blocks() {
    let mut c = Cluster::start().await;
    c.load_all().await;
    let v = c.scene.header.layout.vertex_base;
    let id = (v..c.total_blocks()).find(|b| b % FORKS == 2).unwrap();
    let block = v1::Block { id, data: vec![0xAB; BLOCK_SIZE].into() };
    let r = c.clients[id as usize % FORKS as usize].put_blocks(v1::PutBlocksRequest { blocks: vec![block] }).await;
    assert_eq!(r.unwrap().into_inner().stored, 1);
    let got = c.clients[0].get_blocks(v1::GetBlocksRequest { ids: vec![id] }).await.unwrap().into_inner();
    assert_eq!(got.blocks[0].data, vec![0xAB; BLOCK_SIZE]);
    c.stop().await;
}

#[tokio::test]
async fn no_pairs_when_the_plan_turns_lrt_off() {
    let mut c = Cluster::start().await;
    for i in 0..FORKS {
        let mut req = c.load_request(i);
        req.header.as_mut().unwrap().plan.as_mut().unwrap().lrt = false;
        assert_eq!(c.clients[i as usize].load_shard(req).await.unwrap().into_inner().pairs, 0);
    }
    let r = c.clients[0]
        .take_pairs(v1::TakePairsRequest { max: 10, node: 0, ..Default::default() })
        .await
        .unwrap()
        .into_inner();
    assert!(r.exhausted && r.pairs.is_empty());
    c.stop().await;
}

#[tokio::test]
async fn an_unreachable_peer_is_unavailable_and_named() {
    let mut c = Cluster::start().await;
    // Fork 2's address points at a port nobody listens on.
    let dead = {
        let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        l.local_addr().unwrap().to_string()
    };
    c.addrs[2] = dead.clone();
    for i in 0..2 {
        let req = c.load_request(i);
        c.clients[i as usize].load_shard(req).await.unwrap();
    }
    let (k, m) = code(c.clients[0].get_blocks(v1::GetBlocksRequest { ids: vec![0, 2] }).await);
    assert_eq!(k, Code::Unavailable);
    assert!(m.contains(&dead), "{m}");
    // Fork 0 drains its own pairs and fork 1's, then cannot tell whether fork 2 is done.
    let last = loop {
        match c.clients[0].take_pairs(v1::TakePairsRequest { max: 4096, node: 0, ..Default::default() }).await {
            Ok(r) => assert!(!r.into_inner().exhausted, "exhausted although fork 2 was never asked"),
            Err(s) => break s,
        }
    };
    assert_eq!(last.code(), Code::Unavailable);
    c.stop().await;
}
