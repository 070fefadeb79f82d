//! The cluster's passes: the light pass (wait until every fork's pairs are done, then
//! collect the energies), the vertex energies sent to the forks, and one viewing pass
//! (subscreens handed to the nodes until every pixel row is in).

use super::events::ClusterEvent;
use super::forks::EnergyPoll;
use super::machine::{mark, ClusterMachine};
use super::schedule::Scheduler;
use super::service::Phase;
use crate::failure::ClusterError;
use magg_core::blocks::fork_of_block;
use magg_core::cluster::check_ledgers;
use magg_core::color::Rgb;
use magg_core::energy::vertex_energy_blocks;
use magg_core::fixed::Fixed;
use magg_core::machine::{LightPass, ViewPass, ViewedFrame};
use magg_core::progress::Progress;
use magg_proto::convert::{block_to_wire, element_energies, ledger_digest};
use magg_proto::v1;
use magg_throttle::Scheme;
use std::time::{Duration, Instant};

/// Interval of the host's LRT progress polls.
const LRT_POLL: Duration = Duration::from_millis(25);
/// The same under a throttled profile, where the poll sets the resolution of the
/// modelled LRT time (the polls cost the forks nothing there).
const LRT_POLL_THROTTLED: Duration = Duration::from_millis(5);
/// Times the forks whose ledgers fail the check at the end of the light pass are
/// rebuilt before the render gives up (each rebuild traces their pairs again).
const MAX_LEDGER_REBUILDS: u32 = 3;
/// Interval of the host's checks that every fork is alive during VRT.
const FORK_CHECK: Duration = Duration::from_millis(500);
/// Progress checks of the viewing pass (the end of the pass wakes the driver at once).
const VRT_POLL: Duration = Duration::from_millis(20);

/// Writes fork `fork`'s element energies in `r` into `flux` (by element id).
fn fill_flux(flux: &mut [Fixed], fork: usize, r: &v1::GetEnergiesReply) -> Result<(), ClusterError> {
    let elements = flux.len();
    for (element, e) in element_energies(r).map_err(|source| ClusterError::Energies { fork, source })? {
        match flux.get_mut(element as usize) {
            Some(slot) => *slot = e,
            None => return Err(ClusterError::NoSuchElement { fork, element, elements }),
        }
    }
    Ok(())
}

impl ClusterMachine {
    /// LRT: the nodes pull pairs from their home forks; the host waits until every fork
    /// reports all of its pairs done, then collects the energies, all within one replay
    /// epoch (a fork that restarts meanwhile starts a new one, and the wait goes on),
    /// and checks the forks' ledgers against each other before it keeps them (a fork
    /// that fails is rebuilt and the wait goes on; see [`crate::forks`]).
    pub(super) async fn trace_light(&mut self, progress: &dyn Progress) -> Result<LightPass, ClusterError> {
        let f = self.forks.len();
        let n_el = self.prepared.header.counts.elements as usize;
        // The clock (in the phase sequence) started before the nodes hear of the pass
        // (this thread may lose its core to them at once).
        self.service().set_phase(Phase::Lrt);
        let poll = if self.throttled() { LRT_POLL_THROTTLED } else { LRT_POLL };
        let mut total_pairs = 0;
        for i in 0..f {
            total_pairs += self.forks.poll_until_up(i, EnergyPoll::Summary, true).await?.pairs_total;
        }
        progress.begin(magg_core::progress::LIGHT_PASS, total_pairs);
        let mut last = (0u64, Instant::now());
        let (mut returned_seen, mut epoch_seen) = (0, 0);
        let mut rebuilds = 0;
        let mut element_flux: Vec<Fixed> = vec![[0; 3]; n_el];
        let collect_s = loop {
            let (mut done, mut returned) = (0, 0);
            // A watcher's snapshot rides on this round's progress polls (no extra RPC).
            let snapshot = progress.light_snapshot_due();
            let what = if snapshot { EnergyPoll::Snapshot } else { EnergyPoll::Summary };
            let mut so_far: Vec<Fixed> = if snapshot { vec![[0; 3]; n_el] } else { Vec::new() };
            for i in 0..f {
                let r = self.forks.poll_until_up(i, what, true).await?;
                done += r.pairs_done;
                returned += r.pairs_returned;
                if snapshot {
                    fill_flux(&mut so_far, i, &r)?;
                }
            }
            if snapshot {
                progress.light_snapshot(so_far);
            }
            if returned > returned_seen || self.forks.epoch > epoch_seen {
                // Pairs of a lost node are back on a queue, or a replay started: wake the
                // nodes that ran out.
                if self.forks.epoch > epoch_seen {
                    last = (done, Instant::now()); // the count starts again: not a stall
                }
                (returned_seen, epoch_seen) = (returned, self.forks.epoch);
                {
                    let mut st = self.service().lock();
                    st.pairs_epoch += 1;
                    st.phase = Phase::Lrt;
                }
                self.service().bump();
            }
            tracing::debug!(done, total_pairs, "light pass: pairs done");
            if done > last.0 {
                progress.advance(done - last.0);
                last = (done, Instant::now());
            }
            if done >= total_pairs {
                // Collect the energies (interpolation time, as the paper's host spends it).
                self.service().set_phase(Phase::Interp);
                let t_collect = Instant::now();
                let mut ledgers = Vec::with_capacity(f);
                let mut complete = true;
                for i in 0..f {
                    let r = self.forks.poll_until_up(i, EnergyPoll::Collect, true).await?;
                    complete &= r.pairs_done >= r.pairs_total;
                    ledgers.push(ledger_digest(&r, f).map_err(|source| ClusterError::Energies { fork: i, source })?);
                    fill_flux(&mut element_flux, i, &r)?;
                }
                if self.forks.epoch != epoch_seen || !complete {
                    continue;
                }
                // Every deposit applied exactly once on every fork, or the forks in doubt
                // are rebuilt (see crate::forks).
                let mismatches = check_ledgers(&ledgers, self.forks.epoch);
                if mismatches.is_empty() {
                    break t_collect.elapsed().as_secs_f64();
                }
                rebuilds += 1;
                if rebuilds > MAX_LEDGER_REBUILDS {
                    let fork = self.forks.name(mismatches[0].fork());
                    return Err(ClusterError::Unverified {
                        fork,
                        mismatch: mismatches[0].clone(),
                        rebuilds: MAX_LEDGER_REBUILDS,
                    });
                }
                let mut doubtful: Vec<usize> = mismatches.iter().map(|m| m.fork()).collect();
                doubtful.sort_unstable();
                doubtful.dedup();
                for m in &mismatches {
                    tracing::warn!("the ledgers disagree: {m}");
                }
                for j in doubtful {
                    self.forks.rebuild(j).await?;
                }
                continue;
            }
            if last.1.elapsed() > self.opts.stall_timeout {
                return Err(ClusterError::LightStalled { done, total: total_pairs, after: self.opts.stall_timeout });
            }
            // One RPC per fork per poll: keep it gentle, but look at once when a node runs
            // out of pairs (the pass may be over).
            self.service().wait_for(poll).await;
        };
        progress.end();
        // Nodes that register from now on trace no pairs: the pilot pairs are withdrawn
        // (those that hold them drop them when the viewing pass begins).
        self.service().lock().kept_pairs = 0;
        self.kept_pairs = None;
        Ok(LightPass { element_flux, pairs: total_pairs, collect_s })
    }

    /// Sends every fork the vertex-energy blocks it owns.
    pub(super) async fn put_vertex_energies(
        &mut self,
        vertex_irradiance: &[Rgb],
        gather: &[bool],
    ) -> Result<(), ClusterError> {
        // Given energies skip the light pass: the nodes wait meanwhile.
        self.service().set_phase(Phase::Interp);
        let f = self.forks.len();
        let mut per_fork: Vec<Vec<v1::Block>> = vec![Vec::new(); f];
        for (id, block) in vertex_energy_blocks(vertex_irradiance, gather, &self.prepared.header.layout) {
            per_fork[fork_of_block(id, f as u32) as usize].push(block_to_wire(id, &block));
        }
        mark(self.opts.started, "light pass done, energies gathered and interpolated");
        self.forks.put_vertex_blocks(per_fork).await?;
        mark(self.opts.started, "vertex energies on the forks");
        Ok(())
    }

    /// VRT of one frame: a camera path sends each frame's camera along with its
    /// subscreens, and the nodes keep their caches from frame to frame.
    pub(super) async fn trace_view(
        &mut self,
        pass: ViewPass<'_>,
        progress: &dyn Progress,
    ) -> Result<ViewedFrame, ClusterError> {
        let h = self.prepared.header.clone();
        let s = &h.settings;
        let f = self.forks.len();
        let tiles = pass.tiles(&self.tiles);
        if let Some(tx) = &self.opts.events {
            let _ = tx.send(ClusterEvent::FrameBegins { index: pass.index, count: pass.count });
        }
        {
            let mut st = self.service().lock();
            let schedule = Scheduler::new(s.width, s.height, tiles.clone());
            let nodes = st.nodes.len() as u32;
            st.schedule = Some(if self.opts.scheme == Scheme::Magg { schedule.merging(nodes) } else { schedule });
            // Nodes hold the header's camera; another one rides on the subscreens.
            st.frame_camera = (*pass.camera != h.camera).then(|| v1::Camera::from(pass.camera));
            st.phase = Phase::Vrt;
        }
        self.service().bump();
        progress.begin(magg_core::progress::VIEW_PASS, magg_core::subscreen::pixels(&tiles));
        let mut last_rows = (0u64, Instant::now());
        let mut last_check = Instant::now();
        loop {
            // A fork that died is waited for (and loaded again when it is back) or named.
            if last_check.elapsed() > FORK_CHECK {
                for i in 0..f {
                    self.forks.poll(i, EnergyPoll::Summary, false).await?;
                }
                last_check = Instant::now();
            }
            let (done, px) = {
                let mut st = self.service().lock();
                if let Some(sc) = st.schedule.as_mut() {
                    let lost = sc.expire(self.opts.faults.lease);
                    if !lost.is_empty() {
                        tracing::warn!(
                            ?lost,
                            "nodes silent for over {:?}: their subscreens are back on the queue",
                            self.opts.faults.lease
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
            if last_rows.1.elapsed() > self.opts.stall_timeout {
                return Err(ClusterError::ViewStalled { pixels: px, after: self.opts.stall_timeout });
            }
            self.service().wait_for(VRT_POLL).await;
        }
        progress.end();
        mark(self.opts.started, "viewing pass done");
        let (frame, redivisions) = {
            let mut st = self.service().lock();
            match st.schedule.as_mut() {
                Some(sc) => (sc.take_frame(), sc.redivisions),
                None => return Err(ClusterError::LostSchedule),
            }
        };
        if pass.is_last() {
            // The last frame is in: the nodes hear "done" and send their final reports
            // while the image is written.
            self.service().set_phase(Phase::Done);
        }
        Ok(ViewedFrame { frame, tiles: tiles.len() as u64, redivisions })
    }
}
