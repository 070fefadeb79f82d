//! The node's block source: its home fork over gRPC (the paper's DMA path).

use crate::pace::NodePace;
use magg_core::blocks::{Block, BlockError, BlockSource, BLOCK_SIZE};
use magg_proto::v1::fork_client::ForkClient;
use magg_proto::v1::GetBlocksRequest;
use prost::Message;
use std::sync::Arc;
use tokio::runtime::Handle;
use tonic::transport::Channel;

/// Fetches blocks from the node's home fork. Called from the kernels' worker threads
/// (not from async code): each fetch blocks on the runtime. Under a throttled profile
/// the request pays the node's link (the paper's request packet); the blocks come back
/// over the fork's DMA engine, which the fork pays.
pub struct ForkBlocks {
    client: ForkClient<Channel>,
    rt: Handle,
    pace: Option<Arc<NodePace>>,
}

impl ForkBlocks {
    /// A source reading through `client` on runtime `rt`.
    pub fn new(client: ForkClient<Channel>, rt: Handle) -> Self {
        ForkBlocks { client, rt, pace: None }
    }

    /// The same, paying the link of `pace` for each request.
    pub fn paced(mut self, pace: Option<Arc<NodePace>>) -> Self {
        self.pace = pace;
        self
    }

    fn request(&self, req: &GetBlocksRequest) {
        if let Some(p) = &self.pace {
            p.send_blocking(req.encoded_len());
        }
    }
}

impl BlockSource for ForkBlocks {
    fn fetch_batch(&self, ids: &[u32], out: &mut [Box<Block>]) -> Result<(), BlockError> {
        let first = ids.first().copied().unwrap_or(0);
        let mut client = self.client.clone();
        let req = GetBlocksRequest { ids: ids.to_vec() };
        self.request(&req);
        let reply = self
            .rt
            .block_on(async move { client.get_blocks(req).await })
            .map_err(|s| BlockError::Unavailable { id: first, reason: s.message().to_string() })?
            .into_inner();
        if reply.blocks.len() != ids.len() {
            return Err(BlockError::Unavailable {
                id: first,
                reason: "the fork sent the wrong number of blocks".into(),
            });
        }
        for ((id, b), slot) in ids.iter().zip(reply.blocks).zip(out.iter_mut()) {
            if b.id != *id || b.data.len() != BLOCK_SIZE {
                return Err(BlockError::Unavailable { id: *id, reason: "the fork sent a malformed block".into() });
            }
            slot.copy_from_slice(&b.data);
        }
        Ok(())
    }

    fn fetch(&self, id: u32, out: &mut Block) -> Result<(), BlockError> {
        let mut client = self.client.clone();
        let req = GetBlocksRequest { ids: vec![id] };
        self.request(&req);
        let reply = self
            .rt
            .block_on(async move { client.get_blocks(req).await })
            .map_err(|s| BlockError::Unavailable { id, reason: s.message().to_string() })?
            .into_inner();
        match reply.blocks.into_iter().next() {
            Some(b) if b.id == id && b.data.len() == BLOCK_SIZE => {
                out.copy_from_slice(&b.data);
                Ok(())
            }
            _ => Err(BlockError::Unavailable { id, reason: "the fork sent no block or a malformed one".into() }),
        }
    }
}
