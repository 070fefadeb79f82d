//! Why a node stopped.

/// Errors of a node process.
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    /// A peer could not be reached, even after retries.
    #[error("cannot reach {addr}: {reason}")]
    Connect {
        /// Address tried.
        addr: String,
        /// Last error.
        reason: String,
    },
    /// A peer answered an RPC with an error.
    #[error("{what} failed: {} ({:?})", status.message(), status.code())]
    Rpc {
        /// Which call.
        what: &'static str,
        /// The gRPC status.
        status: tonic::Status,
    },
    /// The host sent something the node cannot use.
    #[error("bad data from the host: {0}")]
    Convert(String),
    /// A kernel could not read a block.
    #[error(transparent)]
    Block(#[from] magg_core::blocks::BlockError),
    /// A worker thread died.
    #[error("node worker failed: {0}")]
    Worker(String),
    /// The async runtime could not start.
    #[error("cannot start the async runtime: {0}")]
    Runtime(String),
}

impl NodeError {
    /// The host refused the registration because the render had ended: the node came too
    /// late to take part (its share was traced by the others).
    pub fn came_after_the_render(&self) -> bool {
        matches!(self, NodeError::Rpc { what: "Register", status }
            if status.code() == tonic::Code::Unavailable && status.message() == magg_proto::RENDER_OVER)
    }
}

impl NodeError {
    /// Wraps a status of call `what`.
    pub fn rpc(what: &'static str) -> impl FnOnce(tonic::Status) -> NodeError {
        move |status| NodeError::Rpc { what, status }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_hosts_render_over_answer_to_a_registration_counts_as_late() {
        let rpc = |what, status| NodeError::Rpc { what, status };
        assert!(rpc("Register", tonic::Status::unavailable(magg_proto::RENDER_OVER)).came_after_the_render());
        assert!(!rpc("NextWork", tonic::Status::unavailable(magg_proto::RENDER_OVER)).came_after_the_render());
        assert!(!rpc("Register", tonic::Status::unavailable("connection refused")).came_after_the_render());
        assert!(!rpc("Register", tonic::Status::failed_precondition(magg_proto::RENDER_OVER)).came_after_the_render());
    }
}
