//! Conversions of the light pass's messages (`LoadShard`, `TakePairs`, `Deposit`,
//! `GetEnergies`, node reports) to and from the domain values of
//! [`magg_core::cluster`], which the fork's and the node's state work on.
//!
//! A batch of deposits is read through [`crate::deposits`], whose [`DepositBatch`]
//! borrows the request's decoded arrays.

use super::{block_bytes_from_wire, finite, invalid, require, rgb_from_wire, rgb_to_wire, ConvertError};
use crate::packed;
use crate::v1;
use magg_core::blocks::CacheStats;
use magg_core::cluster::{ForkReport, LedgerDigest, NodeReport, PairDigest, PairLease, ShardLoad};
use magg_core::header::SceneHeader;
use magg_core::lrt::LrtTally;
use magg_core::view::OpCounters;
use std::time::Duration;

/// A `LoadShard` request as a shard to load: the header converted, every block checked
/// to be 2 KB (kept as received, no copy), `lease_ms == 0` as the default lease. The
/// protocol version and the hardware profile are for the receiver to check first.
impl TryFrom<v1::LoadShardRequest> for ShardLoad<bytes::Bytes> {
    type Error = ConvertError;
    fn try_from(r: v1::LoadShardRequest) -> Result<Self, ConvertError> {
        let header = SceneHeader::try_from(require(r.header, "header")?)?;
        let blocks = r.blocks.into_iter().map(block_bytes_from_wire).collect::<Result<_, _>>()?;
        Ok(ShardLoad {
            fork_index: r.fork_index,
            fork_addrs: r.fork_addrs,
            header,
            blocks,
            nodes: r.nodes,
            lease: (r.lease_ms != 0).then(|| Duration::from_millis(r.lease_ms as u64)),
            epoch: r.epoch,
            node_key: r.node_key.to_vec(),
        })
    }
}

/// A stored block (id, payload as received) for the wire, without a copy.
impl From<(u32, bytes::Bytes)> for v1::Block {
    fn from((id, data): (u32, bytes::Bytes)) -> Self {
        v1::Block { id, data }
    }
}

impl From<PairLease> for v1::TakePairsReply {
    fn from(l: PairLease) -> Self {
        let pairs = packed::varint_bytes(l.pairs.iter().copied());
        v1::TakePairsReply { pairs, exhausted: l.exhausted, epoch: l.epoch, remaining: l.remaining }
    }
}

/// A `TakePairs` reply's pairs, read from their packed array.
impl TryFrom<v1::TakePairsReply> for PairLease {
    type Error = ConvertError;
    fn try_from(r: v1::TakePairsReply) -> Result<Self, ConvertError> {
        let pairs = packed::varints_u64(&r.pairs)
            .map_err(|e| invalid("TakePairsReply.pairs", format!("{} bytes", r.pairs.len()), e.to_string()))?;
        Ok(PairLease { pairs, exhausted: r.exhausted, epoch: r.epoch, remaining: r.remaining })
    }
}

/// A fork's report as a `GetEnergies` reply (the busy times of its emulated hardware
/// are the service's to fill in).
impl From<ForkReport> for v1::GetEnergiesReply {
    fn from(r: ForkReport) -> Self {
        v1::GetEnergiesReply {
            elements: packed::varint_bytes(r.elements.iter().map(|&e| e as u64)),
            energy: packed::i64_bytes(r.energy.iter().flatten().copied()),
            pairs_total: r.pairs_total,
            pairs_done: r.pairs_done,
            dma_bytes: r.dma_bytes,
            gbus_bytes: r.gbus_bytes,
            rpcs: r.rpcs,
            link_bytes: r.link_bytes,
            pairs_returned: r.pairs_returned,
            ledger_epoch: r.ledger.epoch,
            applied: digests_to_wire(&r.ledger.applied),
            recorded: digests_to_wire(&r.ledger.recorded),
            ..Default::default()
        }
    }
}

fn digests_to_wire(d: &[PairDigest]) -> Vec<u64> {
    d.iter().flat_map(|d| [d.count, d.sum]).collect()
}

fn digests_from_wire(v: &[u64], field: &str, forks: usize) -> Result<Vec<PairDigest>, ConvertError> {
    if v.len() != 2 * forks {
        return Err(invalid(field, v.len(), format!("2 values for each of {forks} forks")));
    }
    Ok(v.chunks_exact(2).map(|c| PairDigest { count: c[0], sum: c[1] }).collect())
}

/// The ledger digests of a fork's `GetEnergies` reply, checked to name each of `forks`
/// forks once.
pub fn ledger_digest(r: &v1::GetEnergiesReply, forks: usize) -> Result<LedgerDigest, ConvertError> {
    Ok(LedgerDigest {
        epoch: r.ledger_epoch,
        applied: digests_from_wire(&r.applied, "GetEnergiesReply.applied", forks)?,
        recorded: digests_from_wire(&r.recorded, "GetEnergiesReply.recorded", forks)?,
    })
}

impl From<&NodeReport> for v1::NodeReport {
    fn from(r: &NodeReport) -> Self {
        let rgb = |c| Some(rgb_to_wire(c));
        v1::NodeReport {
            cache_hits: r.cache.hits,
            cache_misses: r.cache.misses,
            cache_remote_misses: r.cache.remote_misses,
            cache_prefetched: r.cache.prefetched,
            grid_steps: r.ops.grid_steps,
            patch_tests: r.ops.patch_tests,
            light_rays: r.ops.light_rays,
            view_rays: r.ops.view_rays,
            shades: r.ops.shades,
            pairs: r.pairs,
            tiles: r.tiles,
            reached: rgb(r.tally.reached),
            occluded: rgb(r.tally.occluded),
            absorbed: rgb(r.tally.absorbed),
            diffuse_end: rgb(r.tally.diffuse_end),
            escaped: rgb(r.tally.escaped),
            cut: rgb(r.tally.cut),
            link_busy_s: r.link_busy_s,
            cpu_busy_s: r.cpu_busy_s,
        }
    }
}

/// A node's report as it came off the wire: every light tally finite and non-negative,
/// busy times finite and non-negative (a report the host sums and prints must not be NaN).
impl TryFrom<&v1::NodeReport> for NodeReport {
    type Error = ConvertError;
    fn try_from(r: &v1::NodeReport) -> Result<Self, ConvertError> {
        let rgb = |c: &Option<v1::Rgb>, field: &str| rgb_from_wire(*c, field, f64::MAX);
        let seconds = |s: f64, field: &str| {
            finite(s, field)?;
            if s < 0.0 {
                return Err(invalid(field, s, "not negative"));
            }
            Ok(s)
        };
        Ok(NodeReport {
            cache: CacheStats {
                hits: r.cache_hits,
                misses: r.cache_misses,
                remote_misses: r.cache_remote_misses,
                prefetched: r.cache_prefetched,
            },
            ops: OpCounters {
                grid_steps: r.grid_steps,
                patch_tests: r.patch_tests,
                light_rays: r.light_rays,
                view_rays: r.view_rays,
                shades: r.shades,
            },
            pairs: r.pairs,
            tiles: r.tiles,
            tally: LrtTally {
                reached: rgb(&r.reached, "reached")?,
                occluded: rgb(&r.occluded, "occluded")?,
                absorbed: rgb(&r.absorbed, "absorbed")?,
                diffuse_end: rgb(&r.diffuse_end, "diffuse_end")?,
                escaped: rgb(&r.escaped, "escaped")?,
                cut: rgb(&r.cut, "cut")?,
            },
            link_busy_s: seconds(r.link_busy_s, "link_busy_s")?,
            cpu_busy_s: seconds(r.cpu_busy_s, "cpu_busy_s")?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::deposits::DepositWriter;

    #[test]
    fn node_reports_round_trip_and_refuse_nan() {
        let mut r = NodeReport { pairs: 7, tiles: 2, cpu_busy_s: 0.5, ..Default::default() };
        r.tally.reached = magg_core::color::Rgb::new(1.0, 2.0, 3.0);
        r.cache.hits = 9;
        let wire = v1::NodeReport::from(&r);
        assert_eq!(NodeReport::try_from(&wire).unwrap(), r);
        let nan = v1::NodeReport { reached: Some(v1::Rgb { r: f64::NAN, g: 0.0, b: 0.0 }), ..wire.clone() };
        assert!(NodeReport::try_from(&nan).unwrap_err().to_string().contains("reached.r"));
        let negative = v1::NodeReport { link_busy_s: -1.0, ..wire };
        assert!(NodeReport::try_from(&negative).is_err());
    }

    #[test]
    fn pair_leases_round_trip() {
        let l = PairLease { pairs: vec![3, 9], epoch: 2, exhausted: false, remaining: 40 };
        assert_eq!(PairLease::try_from(v1::TakePairsReply::from(l.clone())).unwrap(), l);
        let cut = v1::TakePairsReply { pairs: vec![3, 0x89].into(), ..Default::default() };
        let e = PairLease::try_from(cut).unwrap_err();
        assert!(e.to_string().contains("TakePairsReply.pairs = 2 bytes: the last varint is cut short"), "{e}");
    }

    #[test]
    fn a_deposit_batch_is_the_requests_pairs() {
        let mut w = DepositWriter::new(true, 5);
        w.pair(4);
        w.deposit(1, [1, 2, 3]);
        w.deposit(2, [4, 5, 6]);
        let req = w.finish();
        let arrays = crate::deposits::read(&req).unwrap();
        let batch = arrays.batch();
        assert_eq!((batch.complete, batch.epoch, batch.deposits, batch.pairs.len()), (true, 5, 2, 1));
        let p = batch.pairs.clone().next().unwrap();
        assert_eq!((p.pair, p.elements, p.energy), (4, &[1, 2][..], &[1, 2, 3, 4, 5, 6][..]));
    }

    #[test]
    fn a_shard_load_needs_a_header_and_2_kb_blocks() {
        let missing = ShardLoad::try_from(v1::LoadShardRequest::default()).unwrap_err();
        assert_eq!(missing.to_string(), "header is missing");
    }

    #[test]
    fn fork_reports_flatten_the_energies() {
        let r = ForkReport { elements: vec![1, 4], energy: vec![[1, 2, 3], [4, 5, 6]], rpcs: 7, ..Default::default() };
        let w = v1::GetEnergiesReply::from(r);
        let got: Vec<_> = crate::convert::element_energies(&w).unwrap().collect();
        assert_eq!((got, w.rpcs), (vec![(1, [1, 2, 3]), (4, [4, 5, 6])], 7));
    }

    #[test]
    fn ledger_digests_round_trip_and_must_name_every_fork() {
        let d = |count, sum| PairDigest { count, sum };
        let ledger =
            LedgerDigest { epoch: 3, applied: vec![d(1, 2), d(3, 4)], recorded: vec![d(5, 6), d(7, u64::MAX)] };
        let w = v1::GetEnergiesReply::from(ForkReport { ledger: ledger.clone(), ..Default::default() });
        assert_eq!(ledger_digest(&w, 2).unwrap(), ledger);
        let e = ledger_digest(&w, 3).unwrap_err();
        assert!(e.to_string().contains("2 values for each of 3 forks"), "{e}");
    }
}
