//! The cluster's figures after the last pass: every node's final report, every fork's
//! traffic and busy times, and the stage times (modelled seconds on an emulated machine).

use super::emulation::{cpu_share, process_cpu_s};
use super::forks::EnergyPoll;
use super::machine::{mark, ClusterMachine};
use magg_core::blocks::{home_fork_of_node, CacheStats};
use magg_core::cluster::NodeReport;
use magg_core::lrt::LrtTally;
use magg_core::machine::{MachineFigures, PhaseTimes};
use magg_core::stats::{Emulation, NodeStats, Stages, Traffic};

/// A node's final report as the stats' per-node figures.
fn node_stats(node: u32, forks: u32, r: &NodeReport) -> NodeStats {
    NodeStats {
        node,
        home_fork: home_fork_of_node(node, forks),
        pairs: r.pairs,
        tiles: r.tiles,
        cache: r.cache.into(),
        ops: r.ops,
        cpu_s: r.cpu_busy_s,
        link_s: r.link_busy_s,
    }
}

impl ClusterMachine {
    /// Waits (bounded) for every node's final report, collects the forks' figures, stops
    /// the host server, and builds the machine's part of the stats.
    pub(super) async fn collect_figures(
        &mut self,
        times: PhaseTimes,
    ) -> Result<MachineFigures, crate::failure::ClusterError> {
        let t_start = self.opts.started;
        // --- Done: every node hears it and sends its final report (bounded wait).
        self.done().await;
        mark(t_start, "nodes done");
        let f = self.forks.len();
        let mut traffic = Traffic::default();
        let mut busy = self.busy;
        let mut fork_peak_bytes = Vec::with_capacity(f);
        for i in 0..f {
            let r = self.forks.poll_until_up(i, EnergyPoll::Summary, false).await?;
            let known = r.peak_rss_bytes > 0 && !self.forks.in_process(i);
            fork_peak_bytes.push(known.then_some(r.peak_rss_bytes));
            traffic.dma_bytes += r.dma_bytes;
            traffic.gbus_bytes += r.gbus_bytes;
            traffic.rpcs += r.rpcs;
            traffic.link_bytes += r.link_bytes;
            busy.fork_s += r.service_busy_s;
            busy.dma_s += r.dma_busy_s;
            busy.gbus_s += r.gbus_busy_s;
        }
        let wall_s = t_start.elapsed().as_secs_f64();
        mark(t_start, "fork figures collected");
        let cpu1 = process_cpu_s();
        self.endpoint.stop().await;

        let st = self.service().lock();
        traffic.link_bytes += st.link_bytes;
        traffic.rpcs += st.rpcs;
        let (mut per_node, mut cache, mut light) = (Vec::new(), CacheStats::default(), LrtTally::default());
        for (i, n) in st.nodes.iter().enumerate() {
            let stats = node_stats(i as u32, f as u32, &n.report);
            cache = cache.add(n.report.cache);
            light = light.add(n.report.tally);
            busy.node_cpu_s += stats.cpu_s;
            busy.link_s += stats.link_s;
            per_node.push(stats);
        }
        let pre = self.prepared.preprocess_s;
        let stages = if self.throttled() {
            // Modelled seconds: every real duration divided by the dilation.
            let d = self.opts.profile.dilation;
            Stages {
                preprocess_s: (pre + self.preprocess_wall) / d,
                lrt_s: times.lrt_s / d,
                interp_s: times.interp_s / d,
                vrt_s: times.vrt_s / d,
                total_s: (pre + wall_s - self.gather_s) / d,
            }
        } else {
            Stages::measured(pre, times.lrt_s, times.interp_s, times.vrt_s, t_start)
        };
        Ok(MachineFigures {
            mode: "cluster".into(),
            nodes: st.nodes.len() as u32,
            forks: f as u32,
            cache_blocks: self.opts.cache_blocks,
            profile: self.opts.profile.name.clone(),
            scheme: self.opts.scheme.name().into(),
            cache,
            traffic,
            light,
            per_node,
            emulation: self.throttled().then(|| Emulation {
                dilation: self.opts.profile.dilation,
                real_cpu_share: cpu_share(self.cpu0, cpu1, wall_s),
                busy,
            }),
            stages,
            fork_peak_bytes,
        })
    }
}
