//! A fork's part in preparing the scene: it holds the shares of space the host hands it
//! and takes their steps ([`magg_prepare::shares::steps`]) as the host asks, so the forks
//! prepare the scene side by side (the paper's first conclusion: "preprocessing should
//! be executed in parallel ... 5 FPs should be used").
//!
//! Each step runs on the blocking pool: a step is seconds of computing on a large share,
//! and the fork keeps serving its other calls meanwhile. Steps of one fork's shares run
//! one at a time (one lock): the host's steps are a barrier across shares anyway.

use crate::error::ForkError;
use magg_prepare::shares::steps::{self, Serving};
use magg_prepare::shares::wire;
use magg_proto::v1;
use std::sync::{Arc, Mutex};

/// Takes the step `req` asks for on the shares in `serving`: the reply's payload.
pub async fn step(serving: Arc<Mutex<Serving>>, req: v1::PrepareRequest) -> Result<Vec<u8>, ForkError> {
    if req.protocol_version != magg_proto::PROTOCOL_VERSION {
        return Err(ForkError::ProtocolVersion { got: req.protocol_version, want: magg_proto::PROTOCOL_VERSION });
    }
    let work = move || {
        let request = wire::decode_request(&req.payload).map_err(|e| ForkError::BadRequest(e.to_string()))?;
        if let steps::Request::Begin { patches, .. } = &request {
            tracing::info!(session = req.session, share = req.share, patches = patches.len(), "preparing a share");
        }
        let mut serving = serving.lock().unwrap_or_else(|e| e.into_inner());
        let reply = steps::serve(&mut serving, req.session, req.share, request)?;
        Ok(wire::encode_reply(&reply))
    };
    tokio::task::spawn_blocking(work)
        .await
        .map_err(|e| ForkError::Internal(format!("a preparation step failed: {e}")))?
}
