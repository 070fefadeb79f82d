//! The node's block source: its home fork over gRPC (the paper's DMA path).

use crate::pace::NodePace;
use magg_core::blocks::{Block, BlockError, BlockSource, BLOCK_SIZE};
use magg_plumbing::auth::Authed;
use magg_plumbing::retry::retry;
use magg_plumbing::retry::Backoff;
use magg_proto::v1::fork_client::ForkClient;
use magg_proto::v1::GetBlocksRequest;
use prost::Message;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use tokio::runtime::Handle;

/// Fetches blocks from the node's home fork. Called from the kernels' worker threads
/// (not from async code): each fetch blocks on the runtime. Under a throttled profile
/// the request pays the node's link (the paper's request packet); the blocks come back
/// over the fork's DMA engine, which the fork pays.
pub struct ForkBlocks {
    client: ForkClient<Authed>,
    rt: Handle,
    backoff: Backoff,
    pace: Option<Arc<NodePace>>,
    /// Nanoseconds spent in fetches so far (for the worker's pass timing).
    fetching: Arc<AtomicU64>,
}

impl ForkBlocks {
    /// A source reading through `client` on runtime `rt`, retrying an unreachable fork
    /// per `backoff`.
    pub fn new(client: ForkClient<Authed>, rt: Handle, backoff: Backoff) -> Self {
        ForkBlocks { client, rt, backoff, pace: None, fetching: Arc::default() }
    }

    /// Time spent fetching so far is added to `counter` (in nanoseconds).
    pub fn timed(mut self, counter: Arc<AtomicU64>) -> Self {
        self.fetching = counter;
        self
    }

    /// The same, paying the link of `pace` for each request.
    pub fn paced(mut self, pace: Option<Arc<NodePace>>) -> Self {
        self.pace = pace;
        self
    }

    /// One `GetBlocks` call (a read: safe to retry); its request pays the link. The
    /// blocks as (id, payload), in the fork's order.
    fn get(&self, ids: &[u32]) -> Result<impl ExactSizeIterator<Item = (u32, prost::bytes::Bytes)>, tonic::Status> {
        let req = GetBlocksRequest { ids: ids.to_vec() };
        if let Some(p) = &self.pace {
            p.send_blocking(req.encoded_len());
        }
        let t = std::time::Instant::now();
        let reply = self.rt.block_on(retry("GetBlocks", self.backoff, || {
            let (mut client, req) = (self.client.clone(), req.clone());
            async move { client.get_blocks(req).await.map(|r| r.into_inner()) }
        }));
        self.fetching.fetch_add(t.elapsed().as_nanos() as u64, Ordering::Relaxed);
        Ok(reply?.blocks.into_iter().map(|b| (b.id, b.data)))
    }
}

impl BlockSource for ForkBlocks {
    fn fetch_batch(&self, ids: &[u32], out: &mut [Box<Block>]) -> Result<(), BlockError> {
        let first = ids.first().copied().unwrap_or(0);
        let blocks =
            self.get(ids).map_err(|s| BlockError::Unavailable { id: first, reason: s.message().to_string() })?;
        if blocks.len() != ids.len() {
            return Err(BlockError::Unavailable {
                id: first,
                reason: "the fork sent the wrong number of blocks".into(),
            });
        }
        for ((id, (got, data)), slot) in ids.iter().zip(blocks).zip(out.iter_mut()) {
            if got != *id || data.len() != BLOCK_SIZE {
                return Err(BlockError::Unavailable { id: *id, reason: "the fork sent a malformed block".into() });
            }
            slot.copy_from_slice(&data);
        }
        Ok(())
    }

    fn fetch(&self, id: u32, out: &mut Block) -> Result<(), BlockError> {
        let mut blocks =
            self.get(&[id]).map_err(|s| BlockError::Unavailable { id, reason: s.message().to_string() })?;
        match blocks.next() {
            Some((got, data)) if got == id && data.len() == BLOCK_SIZE => {
                out.copy_from_slice(&data);
                Ok(())
            }
            _ => Err(BlockError::Unavailable { id, reason: "the fork sent no block or a malformed one".into() }),
        }
    }
}
