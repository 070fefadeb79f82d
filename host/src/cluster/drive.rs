//! Running the phases against a set of forks, with nodes connecting to our Host service.

use super::emulation::{cpu_share, preprocess_time, process_cpu_s};
use super::events::EventSender;
use super::forks::ForkSet;
use super::schedule::Scheduler;
use super::service::{HostService, HostState, Phase};
use anyhow::{bail, Context};
use magg_core::energy::{interpolate, vertex_energy_blocks, Fixed};
use magg_core::lrt::LrtTally;
use magg_core::math::Rgb;
use magg_core::preprocess::PreparedScene;
use magg_core::progress::Progress;
use magg_core::render::{subscreens, FrameSink, RenderOutput, Sequence};
use magg_core::stats::*;
use magg_proto::auth::CheckToken;
use magg_proto::convert::{block_to_wire, element_energies};
use magg_proto::v1;
use magg_proto::v1::host_server::HostServer;
use magg_throttle::{Profile, Scheme};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::net::TcpListener;
use tonic::service::interceptor::InterceptedService;

/// Interval of the host's LRT progress polls.
const LRT_POLL: Duration = Duration::from_millis(25);
/// The same under a throttled profile, where the poll sets the resolution of the
/// modelled LRT time (the polls cost the forks nothing there).
const LRT_POLL_THROTTLED: Duration = Duration::from_millis(5);

/// Interval of the host's checks that every fork is alive during VRT.
const FORK_CHECK: Duration = Duration::from_millis(500);

/// How to drive a render.
#[derive(Clone, Debug)]
pub struct DriveOptions {
    /// Fork addresses, by index.
    pub forks: Vec<String>,
    /// Cache blocks per node (`None` = unlimited).
    pub cache_blocks: Option<u64>,
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
    /// Hardware profile (DESIGN.md §4), sent to every fork and node.
    pub profile: Profile,
    /// The paper's schedule or ours.
    pub scheme: Scheme,
    /// Energies to use instead of the light pass, and the cameras of the frames.
    pub sequence: Sequence,
    /// Where the host service sends events for a watcher (the live view).
    pub events: Option<EventSender>,
    /// Node leases, fork timeout, cluster token.
    pub faults: crate::faults::FaultPolicy,
    /// When the render began (before this process started its forks and nodes): the
    /// stats' total counts from here, so that it holds every cost of the cluster.
    pub started: Instant,
}

/// Accepted connections with Nagle's algorithm off: the protocol is many small
/// request/reply pairs, which Nagle plus delayed ACKs would stall for tens of ms each.
fn nodelay_incoming(listener: TcpListener) -> impl tokio_stream::Stream<Item = std::io::Result<tokio::net::TcpStream>> {
    use tokio_stream::StreamExt;
    tokio_stream::wrappers::TcpListenerStream::new(listener).map(|r| {
        r.inspect(|s| {
            let _ = s.set_nodelay(true);
        })
    })
}

/// Progress checks of the viewing pass (the end of the pass wakes the driver at once).
const VRT_POLL: Duration = Duration::from_millis(20);

/// Sleeps for `d`, or less when the service signals the driver.
async fn wait_for(service: &HostService, d: Duration) {
    tokio::select! {
        _ = tokio::time::sleep(d) => {}
        _ = service.changed.notified() => {}
    }
}

/// Sets the phase to [`Phase::Done`] when dropped: a render that fails still lets the
/// nodes go.
struct DoneOnDrop(HostService);

impl Drop for DoneOnDrop {
    fn drop(&mut self) {
        self.0.set_phase(Phase::Done);
    }
}

fn rgb(c: &Option<v1::Rgb>) -> Rgb {
    c.as_ref().map_or(Rgb::BLACK, |c| Rgb::new(c.r, c.g, c.b))
}

/// Runs the render: serves `Host` on `listener`, drives the forks, returns when every
/// node that registered has been told the render is done (or after a grace period).
/// The light pass runs once (not at all when `opts.sequence` brings energies), then one
/// viewing pass per camera, each frame handed to `sink`; the output's frame is the last.
pub async fn drive(
    prepared: &Arc<PreparedScene>,
    opts: &DriveOptions,
    listener: TcpListener,
    progress: &dyn Progress,
    sink: &mut FrameSink<'_>,
) -> anyhow::Result<RenderOutput> {
    let t_start = opts.started;
    let cpu0 = process_cpu_s();
    // The render's timeline at debug level (RUST_LOG=magg_host=debug): where the
    // cluster's fixed costs go.
    let mark =
        |what: &str| tracing::debug!(ms = format!("{:.2}", 1e3 * t_start.elapsed().as_secs_f64()), "timeline: {what}");
    mark("driving: forks and nodes started");
    let h = prepared.header.clone();
    let f = opts.forks.len();
    if f == 0 {
        bail!("no fork to render with");
    }
    let throttled = !opts.profile.is_native();
    let wire_profile = if throttled { opts.profile.to_wire() } else { String::new() };
    // Preprocessing as the emulated machine spends it (the real one took
    // `prepared.preprocess_s`, a thousandth of that or less).
    let preprocess_model =
        if throttled { preprocess_time(&opts.profile, opts.scheme, prepared, f as u32) } else { Duration::ZERO };
    // Not even a zero sleep natively: the timer would round it up to its next tick (1 ms).
    magg_throttle::wait(Instant::now() + opts.profile.dilate(preprocess_model)).await;
    let mut forks =
        ForkSet::connect(prepared, &opts.forks, &opts.faults).await?.for_render(wire_profile.clone(), opts.nodes);
    let wire_header = v1::SceneHeader::from(&*h);

    // Serve the host service.
    let loaded = opts.sequence.energies.clone();
    if let Some(e) = &loaded {
        e.check(&h)?;
    }
    let service = HostService::new(HostState {
        phase: Phase::Gather,
        nodes: Vec::new(),
        schedule: None,
        header: wire_header,
        fork_addrs: opts.forks.clone(),
        cache_blocks: opts.cache_blocks.unwrap_or(0),
        profile: wire_profile.clone(),
        scheme: opts.scheme.name().to_string(),
        link_bytes: 0,
        rpcs: 0,
        frame_camera: None,
        events: opts.events.clone(),
        pairs_epoch: 0,
    });
    let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
    let (health, health_service) = magg_proto::lifecycle::health_service();
    health.set_serving::<HostServer<HostService>>().await;
    let host_server = InterceptedService::new(
        HostServer::new(service.clone()).max_decoding_message_size(16 << 20),
        CheckToken { token: opts.faults.token.clone(), server: "host" },
    );
    // Nodes of this process reach the host without a socket (see magg_proto::transport).
    let host_addr = listener.local_addr().context("the host listener's address")?;
    let _in_process = magg_proto::transport::register(&host_addr.to_string(), host_server.clone());
    let server = magg_proto::tls::server_builder()
        .map_err(|e| anyhow::anyhow!("host server TLS: {e}"))?
        .initial_stream_window_size(Some(4 << 20))
        .initial_connection_window_size(Some(16 << 20))
        .add_service(health_service)
        .add_service(host_server.clone())
        .serve_with_incoming_shutdown(nodelay_incoming(listener), async {
            let _ = stop_rx.await;
        });
    let server = tokio::spawn(server);
    // However the render ends, nodes asking for work hear "done" and exit.
    let _done_on_exit = DoneOnDrop(service.clone());

    // The shards load while the nodes register (they wait for the light pass).
    forks.load_all().await?;
    mark("shards loaded");
    // Preprocessing ends when every shard is loaded.
    let preprocess_wall = t_start.elapsed().as_secs_f64();
    // The expected nodes register (connecting 80 nodes to 6 servers takes this machine a
    // moment that the emulated one, whose processors were wired, never spent).
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
        wait_for(&service, Duration::from_millis(2)).await;
    }
    let gather_s = t_gather.elapsed().as_secs_f64();
    mark(if opts.gather { "nodes registered" } else { "light pass open (nodes join as they register)" });
    // --- LRT: wait for every fork's pairs. The clock starts before the nodes hear of it
    // (this thread may lose its core to them at once).
    let t_lrt = Instant::now();
    // With loaded energies the nodes never trace pairs: they wait for subscreens.
    service.set_phase(if loaded.is_some() { Phase::Interp } else { Phase::Lrt });
    let poll = if throttled { LRT_POLL_THROTTLED } else { LRT_POLL };

    let total_pairs: u64 = if loaded.is_some() {
        0
    } else {
        let mut t = 0;
        for i in 0..f {
            t += forks.poll_until_up(i, true, true).await?.pairs_total;
        }
        t
    };
    let n_el = h.counts.elements as usize;
    let mut busy = EmulatedBusy { preprocess_s: preprocess_model.as_secs_f64(), ..Default::default() };
    let (lrt_s, t_interp, element_flux, vertex_irradiance) = match &loaded {
        Some(e) => {
            service.set_phase(Phase::Interp);
            (0.0, Instant::now(), e.element_flux.clone(), e.vertex_irradiance.clone())
        }
        None => {
            progress.begin("light ray tracing", total_pairs);
            let mut last = (0u64, Instant::now());
            let (mut returned_seen, mut epoch_seen) = (0, 0);
            let mut element_flux: Vec<Fixed> = vec![[0; 3]; n_el];
            // Until every pair is done and the energies are collected within one replay
            // epoch (a fork that restarts meanwhile starts a new one).
            let (lrt_s, t_interp) = loop {
                let (mut done, mut returned) = (0, 0);
                for i in 0..f {
                    let r = forks.poll_until_up(i, true, true).await?;
                    done += r.pairs_done;
                    returned += r.pairs_returned;
                }
                if returned > returned_seen || forks.epoch > epoch_seen {
                    // Pairs of a lost node are back on a queue, or a replay started: wake
                    // the nodes that ran out.
                    if forks.epoch > epoch_seen {
                        last = (done, Instant::now()); // the count starts again: not a stall
                    }
                    (returned_seen, epoch_seen) = (returned, forks.epoch);
                    {
                        let mut st = service.lock();
                        st.pairs_epoch += 1;
                        st.phase = Phase::Lrt;
                    }
                    service.bump();
                }
                tracing::debug!(done, total_pairs, "light pass: pairs done");
                if done > last.0 {
                    progress.advance(done - last.0);
                    last = (done, Instant::now());
                }
                if done >= total_pairs {
                    let lrt_s = t_lrt.elapsed().as_secs_f64();
                    // --- Interpolation.
                    service.set_phase(Phase::Interp);
                    let t_interp = Instant::now();
                    for i in 0..f {
                        let r = forks.poll_until_up(i, false, true).await?;
                        let energies = element_energies(&r).with_context(|| format!("the energies of fork {i}"))?;
                        for (element, e) in energies {
                            match element_flux.get_mut(element as usize) {
                                Some(slot) => *slot = e,
                                None => bail!("fork {i} sent energy for element {element} of {n_el}"),
                            }
                        }
                    }
                    if forks.epoch == epoch_seen {
                        break (lrt_s, t_interp);
                    }
                    continue;
                }
                if last.1.elapsed() > opts.stall_timeout {
                    bail!(
                        "light ray tracing stalled at {done} of {total_pairs} pairs for {:?} (are nodes connected?)",
                        opts.stall_timeout
                    );
                }
                // One RPC per fork per poll: keep it gentle, but look at once when a node
                // runs out of pairs (the pass may be over).
                wait_for(&service, poll).await;
            };
            progress.end();
            let v = interpolate(&prepared.elements, &element_flux, h.counts.vertices as usize, h.energy_quantum);
            (lrt_s, t_interp, element_flux, v)
        }
    };
    let (mut dma_bytes, mut gbus_bytes, mut fork_rpcs, mut fork_link) = (0, 0, 0, 0);
    let mut per_fork: Vec<Vec<v1::Block>> = vec![Vec::new(); f];
    for (id, block) in vertex_energy_blocks(&vertex_irradiance, &h.layout) {
        per_fork[id as usize % f].push(block_to_wire(id, &block));
    }
    mark("light pass done, energies gathered and interpolated");
    forks.put_vertex_blocks(per_fork).await?;
    let interp_s = t_interp.elapsed().as_secs_f64();
    mark("vertex energies on the forks");

    // --- VRT, one pass per camera; a camera path sends each frame's camera along with
    // its subscreens, and the nodes keep their caches from frame to frame.
    let s = &h.settings;
    let tiles = subscreens(s.width, s.height, opts.subscreen);
    let cameras = opts.sequence.frame_cameras(&h.camera);
    let n_tiles = tiles.len() as u64 * cameras.len() as u64;
    let (mut vrt_s, mut redivisions) = (0.0, 0);
    let mut frame = magg_core::frame::Frame::new(s.width, s.height);
    for (index, camera) in cameras.iter().enumerate() {
        progress.frame_begins(index, cameras.len());
        if let Some(tx) = &opts.events {
            let _ = tx.send(super::events::ClusterEvent::FrameBegins { index, count: cameras.len() });
        }
        let t_vrt = Instant::now();
        {
            let mut st = service.lock();
            let schedule = Scheduler::new(s.width, s.height, tiles.clone());
            let nodes = st.nodes.len() as u32;
            st.schedule = Some(if opts.scheme == Scheme::Magg { schedule.merging(nodes) } else { schedule });
            // Nodes hold the header's camera; another one rides on the subscreens.
            st.frame_camera = (*camera != h.camera).then(|| v1::Camera::from(camera));
            st.phase = Phase::Vrt;
        }
        service.bump();
        progress.begin("viewing ray tracing", s.width as u64 * s.height as u64);
        let mut last_rows = (0u64, Instant::now());
        let mut last_check = Instant::now();
        loop {
            // A fork that died is waited for (and loaded again when it is back) or named.
            if last_check.elapsed() > FORK_CHECK {
                for i in 0..f {
                    forks.poll(i, true, false).await?;
                }
                last_check = Instant::now();
            }
            let (done, px) = {
                let mut st = service.lock();
                if let Some(sc) = st.schedule.as_mut() {
                    let lost = sc.expire(opts.faults.lease);
                    if !lost.is_empty() {
                        tracing::warn!(
                            ?lost,
                            "nodes silent for over {:?}: their subscreens are back on the queue",
                            opts.faults.lease
                        );
                    }
                }
                let sc = st.schedule.as_ref();
                (sc.is_some_and(|s| s.is_done()), sc.map_or(0, |s| s.pixels_done()))
            };
            if px > last_rows.0 {
                progress.advance(px - last_rows.0);
                last_rows = (px, Instant::now());
            }
            if done {
                break;
            }
            if last_rows.1.elapsed() > opts.stall_timeout {
                bail!("viewing ray tracing stalled at {px} pixels for {:?}", opts.stall_timeout);
            }
            wait_for(&service, VRT_POLL).await;
        }
        progress.end();
        mark("viewing pass done");
        let frame_s = t_vrt.elapsed().as_secs_f64();
        vrt_s += frame_s;
        {
            let mut st = service.lock();
            if let Some(sc) = st.schedule.as_mut() {
                frame = sc.take_frame();
                redivisions += sc.redivisions;
            }
        }
        if index + 1 == cameras.len() {
            // The last frame is in: the nodes hear "done" and send their final reports
            // while the image is written.
            service.set_phase(Phase::Done);
        }
        sink(index, &frame, frame_s).map_err(|e| anyhow::anyhow!(e))?;
        mark("frame written");
    }

    // --- Done: every node hears it and sends its final report (bounded wait).
    service.set_phase(Phase::Done);
    let deadline = Instant::now() + Duration::from_secs(5);
    while Instant::now() < deadline {
        if service.lock().nodes.iter().all(|n| n.reported_or_gone(Duration::from_secs(2))) {
            break;
        }
        wait_for(&service, Duration::from_millis(5)).await;
    }
    mark("nodes done");
    for i in 0..f {
        let r = forks.poll_until_up(i, true, false).await?;
        dma_bytes += r.dma_bytes;
        gbus_bytes += r.gbus_bytes;
        fork_rpcs += r.rpcs;
        fork_link += r.link_bytes;
        busy.fork_s += r.service_busy_s;
        busy.dma_s += r.dma_busy_s;
        busy.gbus_s += r.gbus_busy_s;
    }
    let wall_s = t_start.elapsed().as_secs_f64();
    mark("fork figures collected");
    let cpu1 = process_cpu_s();
    // Graceful shutdown waits for clients to hang up; a client that never does (a stuck
    // or hostile peer) must not keep the host alive: give them a moment, then stop.
    let _ = stop_tx.send(());
    let abort = server.abort_handle();
    if tokio::time::timeout(Duration::from_secs(1), server).await.is_err() {
        abort.abort();
        tracing::warn!("a client kept its connection to the host open after the render: closed it");
    }

    let st = service.lock();
    let mut per_node = Vec::new();
    let mut cache = magg_core::blocks::CacheStats::default();
    let mut light = LrtTally::default();
    let (mut light_rays, mut view_rays) = (0, 0);
    for (i, n) in st.nodes.iter().enumerate() {
        let r = &n.report;
        let c = magg_core::blocks::CacheStats {
            hits: r.cache_hits,
            misses: r.cache_misses,
            remote_misses: r.cache_remote_misses,
            prefetched: 0,
        };
        cache = cache.add(c);
        light = light.add(LrtTally {
            reached: rgb(&r.reached),
            occluded: rgb(&r.occluded),
            absorbed: rgb(&r.absorbed),
            diffuse_end: rgb(&r.diffuse_end),
            escaped: rgb(&r.escaped),
            cut: rgb(&r.cut),
        });
        light_rays += r.light_rays;
        view_rays += r.view_rays;
        busy.node_cpu_s += r.cpu_busy_s;
        busy.link_s += r.link_busy_s;
        per_node.push(NodeStats {
            node: i as u32,
            home_fork: i as u32 % f as u32,
            pairs: r.pairs,
            tiles: r.tiles,
            cache: c.into(),
            ops: magg_core::view::OpCounters {
                grid_steps: r.grid_steps,
                patch_tests: r.patch_tests,
                light_rays: r.light_rays,
                view_rays: r.view_rays,
                shades: r.shades,
            },
            cpu_s: r.cpu_busy_s,
            link_s: r.link_busy_s,
        });
    }
    let stats = RenderStats {
        scene: prepared.name.clone(),
        mode: "cluster".into(),
        nodes: st.nodes.len() as u32,
        forks: f as u32,
        cache_blocks: opts.cache_blocks,
        profile: opts.profile.name.clone(),
        scheme: opts.scheme.name().into(),
        stages: if throttled {
            // Modelled seconds: every real duration divided by the dilation.
            let d = opts.profile.dilation;
            let pre = (prepared.preprocess_s + preprocess_wall) / d;
            Stages {
                preprocess_s: pre,
                lrt_s: lrt_s / d,
                interp_s: interp_s / d,
                vrt_s: vrt_s / d,
                total_s: (prepared.preprocess_s + wall_s - gather_s) / d,
            }
        } else {
            Stages::measured(prepared.preprocess_s, lrt_s, interp_s, vrt_s, t_start)
        },
        cache: cache.into(),
        traffic: Traffic { link_bytes: st.link_bytes + fork_link, dma_bytes, gbus_bytes, rpcs: st.rpcs + fork_rpcs },
        work: Work { pairs: total_pairs, tiles: n_tiles, redivisions, light_rays, view_rays },
        plan: (&h.plan).into(),
        counts: h.counts,
        light,
        per_node,
        emulation: throttled.then(|| Emulation {
            dilation: opts.profile.dilation,
            real_cpu_share: cpu_share(cpu0, cpu1, wall_s),
            busy,
        }),
    };
    Ok(RenderOutput { frame, element_flux, vertex_irradiance, stats })
}
