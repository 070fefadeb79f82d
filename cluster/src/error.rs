//! What a node's request to the host can be refused for, and the one mapping from those
//! errors to gRPC status codes (`impl From<HostError> for Status`), as the fork has its own.
//!
//! | error | code |
//! | --- | --- |
//! | [`HostError::ProtocolVersion`], [`HostError::NoViewPass`] | `FAILED_PRECONDITION` |
//! | [`HostError::RenderOver`] (a node that came after the end: it exits quietly), [`HostError::NextScene`] (between two scenes of a render: it registers again) | `UNAVAILABLE` |
//! | [`HostError::NameTooLong`], [`HostError::UnknownNode`], [`HostError::Report`], [`HostError::Rows`] | `INVALID_ARGUMENT` |
//! | [`HostError::TooManyNodes`] | `RESOURCE_EXHAUSTED` |
//! | [`HostError::NotThatNode`] (a request without the node's secret) | `PERMISSION_DENIED` |

use crate::schedule::RowError;
use magg_proto::convert::ConvertError;
use magg_proto::PROTOCOL_VERSION;
use tonic::Status;

/// Longest node name the host keeps, in bytes.
pub const MAX_NODE_NAME: usize = 256;

/// Most nodes that may register with one host.
pub const MAX_NODES: usize = 65_536;

/// A node request the host refuses.
#[derive(Debug, thiserror::Error)]
pub enum HostError {
    /// `Register` from a process speaking another protocol version.
    #[error("protocol version {0} refused: this host speaks version {PROTOCOL_VERSION}")]
    ProtocolVersion(u32),
    /// `Register` with a name past [`MAX_NODE_NAME`] bytes.
    #[error("node name longer than {MAX_NODE_NAME} bytes")]
    NameTooLong,
    /// `Register` after the render ended.
    #[error("{}", magg_proto::RENDER_OVER)]
    RenderOver,
    /// `Register` between two scenes of one render (refinement's pilot levels, then the
    /// render), while the host prepares the next: the node asks again.
    #[error("{}", magg_proto::NEXT_SCENE)]
    NextScene,
    /// `Register` past [`MAX_NODES`].
    #[error("too many nodes registered")]
    TooManyNodes,
    /// A request under a node id that never registered.
    #[error("node {0} is not registered")]
    UnknownNode(u32),
    /// A request under node `n`'s id without its secret: another client acting for it.
    #[error("node {0}'s requests must carry its secret: one node may not act for another")]
    NotThatNode(u32),
    /// Rows sent while no viewing pass runs.
    #[error("no viewing ray tracing in progress")]
    NoViewPass,
    /// A node report that does not convert (a NaN or negative figure).
    #[error("bad node report: {0}")]
    Report(ConvertError),
    /// Rows the subscreen queue refuses.
    #[error(transparent)]
    Rows(#[from] RowError),
}

impl From<HostError> for Status {
    fn from(e: HostError) -> Status {
        let text = e.to_string();
        match e {
            HostError::ProtocolVersion(_) | HostError::NoViewPass => Status::failed_precondition(text),
            HostError::RenderOver | HostError::NextScene => Status::unavailable(text),
            HostError::NameTooLong | HostError::UnknownNode(_) | HostError::Report(_) | HostError::Rows(_) => {
                Status::invalid_argument(text)
            }
            HostError::NotThatNode(_) => Status::permission_denied(text),
            HostError::TooManyNodes => Status::resource_exhausted(text),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tonic::Code;

    #[test]
    fn every_error_has_its_code_and_names_the_value() {
        let cases = [
            (HostError::ProtocolVersion(2), Code::FailedPrecondition, "2"),
            (HostError::NoViewPass, Code::FailedPrecondition, "viewing"),
            (HostError::RenderOver, Code::Unavailable, "over"),
            (HostError::NextScene, Code::Unavailable, "next scene"),
            (HostError::NameTooLong, Code::InvalidArgument, "256"),
            (HostError::UnknownNode(7), Code::InvalidArgument, "node 7"),
            (HostError::Rows(RowError::UnknownSubscreen(9)), Code::InvalidArgument, "subscreen 9"),
            (HostError::TooManyNodes, Code::ResourceExhausted, "too many"),
        ];
        for (e, code, text) in cases {
            let s = Status::from(e);
            assert_eq!(s.code(), code, "{}", s.message());
            assert!(s.message().contains(text), "{:?} lacks {text:?}", s.message());
        }
    }
}
