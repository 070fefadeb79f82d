//! What can go wrong in a fork, and the one mapping from those errors to gRPC status
//! codes (`impl From<ForkError> for Status`).
//!
//! | error | code |
//! | --- | --- |
//! | [`ForkError::ProtocolVersion`], [`ForkError::ProfileMismatch`], [`ForkError::BlockNotLoaded`] | `FAILED_PRECONDITION` |
//! | [`ForkError::NotLoaded`] (a fork just started or restarted: callers retry until the host loads it) | `UNAVAILABLE` |
//! | [`ForkError::BadHeader`], [`ForkError::BadBlock`], [`ForkError::BadRequest`], [`ForkError::BlockOutOfRange`], [`ForkError::BlockNotOwned`], [`ForkError::PairOutOfRange`], [`ForkError::ElementOutOfRange`], [`ForkError::ElementNotOwned`] | `INVALID_ARGUMENT` |
//! | [`ForkError::TooMany`], [`ForkError::OverMemory`] | `RESOURCE_EXHAUSTED` |
//! | [`ForkError::NotThatNode`] (a `TakePairs` without the node's secret) | `PERMISSION_DENIED` |
//! | [`ForkError::PeerUnavailable`] | `UNAVAILABLE` |
//! | [`ForkError::Peer`] | the peer's own code |
//! | [`ForkError::PeerReply`], [`ForkError::Internal`] | `INTERNAL` |
//! | [`ForkError::Prepare`] of a share it does not hold ([`StepError::Unknown`]) | `ABORTED` |
//! | [`ForkError::Prepare`] of a request it cannot take ([`StepError::Bad`]) | `INVALID_ARGUMENT` |

use magg_prepare::shares::steps::StepError;
use magg_proto::convert::ConvertError;
use tonic::{Code, Status};

/// A request a fork cannot serve.
#[derive(Debug, thiserror::Error)]
pub enum ForkError {
    /// A request under node `n`'s id without its secret: another client acting for it.
    #[error("node {0}'s requests must carry its secret: one node may not act for another")]
    NotThatNode(u32),
    /// An RPC other than `LoadShard` arrived before any scene was loaded.
    #[error("{}", magg_proto::NOT_LOADED)]
    NotLoaded,
    /// `LoadShard` with another hardware profile than the one this fork was started with.
    #[error("the host runs hardware profile {host:?} but this fork was started with --profile {fork:?}")]
    ProfileMismatch {
        /// The host's profile.
        host: String,
        /// This fork's.
        fork: String,
    },
    /// `LoadShard` from a process speaking another protocol version.
    #[error("protocol version {got} is not this fork's version {want}")]
    ProtocolVersion {
        /// Version in the request.
        got: u32,
        /// [`magg_proto::PROTOCOL_VERSION`].
        want: u32,
    },
    /// The scene header does not convert.
    #[error("bad scene header: {0}")]
    BadHeader(ConvertError),
    /// A preparation step the fork cannot take.
    #[error("preparation: {0}")]
    Prepare(#[from] StepError),
    /// A block does not convert (wrong size).
    #[error("bad block: {0}")]
    BadBlock(ConvertError),
    /// A request field outside its range that has no more specific variant.
    #[error("{0}")]
    BadRequest(String),
    /// A block id past the scene's last block.
    #[error("block {id} does not exist (the scene has {total} blocks)")]
    BlockOutOfRange {
        /// Requested id.
        id: u32,
        /// Blocks in the scene.
        total: u32,
    },
    /// A block id this fork does not hold (block `b` lives on fork `b mod F`).
    #[error("block {id} lives on fork {owner}, not on fork {fork}")]
    BlockNotOwned {
        /// Requested id.
        id: u32,
        /// Fork that holds it.
        owner: u32,
        /// This fork.
        fork: u32,
    },
    /// An owned block that no `LoadShard` or `PutBlocks` has supplied yet.
    #[error("block {id} has not been loaded on fork {fork}")]
    BlockNotLoaded {
        /// Requested id.
        id: u32,
        /// This fork.
        fork: u32,
    },
    /// A pair id past `lights * elements`.
    #[error("pair {pair} does not exist (the scene has {pairs} pairs)")]
    PairOutOfRange {
        /// Pair id.
        pair: u64,
        /// `lights * elements`.
        pairs: u64,
    },
    /// An element id past the scene's last element.
    #[error("element {element} does not exist (the scene has {elements} elements)")]
    ElementOutOfRange {
        /// Element id.
        element: u32,
        /// Elements in the scene.
        elements: u32,
    },
    /// An element whose energy another fork accumulates.
    #[error("element {element} belongs to fork {owner}, not to fork {fork}")]
    ElementNotOwned {
        /// Element id.
        element: u32,
        /// Fork that owns it.
        owner: u32,
        /// This fork.
        fork: u32,
    },
    /// A request larger than a handler accepts.
    #[error("{what}: {got} is more than the limit of {max}")]
    TooMany {
        /// What was counted.
        what: &'static str,
        /// How many were sent.
        got: u64,
        /// The limit.
        max: u64,
    },
    /// A `LoadShard` whose pair bookkeeping would take more memory than this fork may
    /// use (refused before anything is allocated).
    #[error(
        "the shard's pair bookkeeping needs about {} MB ({pairs} pairs: {lights} lights x {elements} elements), \
         over this fork's --max-memory-mb {limit_mb}",
        need.div_ceil(1 << 20)
    )]
    OverMemory {
        /// Bytes the shard would take.
        need: u64,
        /// Pairs of the scene.
        pairs: u64,
        /// Its lights.
        lights: u64,
        /// Its elements.
        elements: u64,
        /// The fork's limit in MiB.
        limit_mb: u64,
    },
    /// A peer fork could not be reached.
    #[error("fork at {addr} is unreachable: {reason}")]
    PeerUnavailable {
        /// Its address.
        addr: String,
        /// What went wrong.
        reason: String,
    },
    /// A peer fork answered with an error.
    #[error("fork {fork} at {addr}: {}", status.message())]
    Peer {
        /// Its index.
        fork: u32,
        /// Its address.
        addr: String,
        /// Its answer.
        status: Status,
    },
    /// A peer fork answered with something other than what was asked for.
    #[error("fork {fork} at {addr} answered wrongly: {detail}")]
    PeerReply {
        /// Its index.
        fork: u32,
        /// Its address.
        addr: String,
        /// What was wrong.
        detail: String,
    },
    /// A fault of this fork (a task that did not finish).
    #[error("internal error: {0}")]
    Internal(String),
}

impl ForkError {
    /// The gRPC code of this error.
    pub fn code(&self) -> Code {
        match self {
            ForkError::ProtocolVersion { .. }
            | ForkError::ProfileMismatch { .. }
            | ForkError::BlockNotLoaded { .. } => Code::FailedPrecondition,
            ForkError::NotLoaded => Code::Unavailable,
            ForkError::NotThatNode(_) => Code::PermissionDenied,
            ForkError::BadHeader(_)
            | ForkError::BadBlock(_)
            | ForkError::BadRequest(_)
            | ForkError::BlockOutOfRange { .. }
            | ForkError::BlockNotOwned { .. }
            | ForkError::PairOutOfRange { .. }
            | ForkError::ElementOutOfRange { .. }
            | ForkError::ElementNotOwned { .. } => Code::InvalidArgument,
            ForkError::TooMany { .. } | ForkError::OverMemory { .. } => Code::ResourceExhausted,
            ForkError::PeerUnavailable { .. } => Code::Unavailable,
            ForkError::Peer { status, .. } => status.code(),
            ForkError::PeerReply { .. } | ForkError::Internal(_) => Code::Internal,
            ForkError::Prepare(StepError::Unknown { .. }) => Code::Aborted,
            ForkError::Prepare(StepError::Bad { .. }) => Code::InvalidArgument,
        }
    }
}

/// A message that does not convert: a block of the wrong size is a bad block, anything
/// else a bad scene header (the only other part of a request that converts).
impl From<ConvertError> for ForkError {
    fn from(e: ConvertError) -> ForkError {
        match e {
            ConvertError::BlockSize { .. } => ForkError::BadBlock(e),
            _ => ForkError::BadHeader(e),
        }
    }
}

impl From<ForkError> for Status {
    fn from(e: ForkError) -> Status {
        Status::new(e.code(), e.to_string())
    }
}
