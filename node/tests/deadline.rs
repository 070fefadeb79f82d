//! A stalled peer does not hang a node: every call has a deadline, and a host that never
//! answers fails the node with `DEADLINE_EXCEEDED` in bounded time.

use magg_proto::v1::host_server::{Host, HostServer};
use magg_proto::v1::{
    NextWorkReply, NextWorkRequest, RegisterReply, RegisterRequest, SubmitRowsReply, SubmitRowsRequest,
};
use std::time::{Duration, Instant};
use tonic::{Request, Response, Status};

/// A host that accepts connections and never answers.
struct Stalled;

#[tonic::async_trait]
impl Host for Stalled {
    async fn register(&self, _: Request<RegisterRequest>) -> Result<Response<RegisterReply>, Status> {
        std::future::pending().await
    }
    async fn next_work(&self, _: Request<NextWorkRequest>) -> Result<Response<NextWorkReply>, Status> {
        std::future::pending().await
    }
    async fn submit_rows(&self, _: Request<SubmitRowsRequest>) -> Result<Response<SubmitRowsReply>, Status> {
        std::future::pending().await
    }
}

#[test]
fn a_host_that_never_answers_fails_the_node_at_the_call_deadline() {
    let rt = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap();
    let listener = rt.block_on(tokio::net::TcpListener::bind("127.0.0.1:0")).unwrap();
    let addr = listener.local_addr().unwrap();
    rt.spawn(
        tonic::transport::Server::builder()
            .add_service(HostServer::new(Stalled))
            .serve_with_incoming(tokio_stream::wrappers::TcpListenerStream::new(listener)),
    );
    let cfg = magg_node::NodeConfig {
        host: addr.to_string(),
        backoff: magg_plumbing::retry::Backoff { call_timeout: Duration::from_millis(300), ..Default::default() },
        ..Default::default()
    };
    let t = Instant::now();
    let err = magg_node::run_with_runtime(rt.handle().clone(), &cfg).unwrap_err();
    match &err {
        magg_node::NodeError::Rpc { what: "Register", status } => {
            assert!(
                matches!(status.code(), tonic::Code::DeadlineExceeded | tonic::Code::Cancelled),
                "expected a deadline error: {err}"
            );
        }
        other => panic!("expected Register to time out, got {other}"),
    }
    // Far below "hung"; generous for a loaded machine (no exact timing is asserted).
    assert!(t.elapsed() < Duration::from_secs(20), "the node waited {:?}", t.elapsed());
}
