//! The in-process transport: a registered service is reached without a socket (nothing
//! listens on its address), with the server's interceptors and status codes; a call that
//! outlives its deadline fails as on a channel; an unregistered address, another set's
//! address, or the tcp mode, goes to the network.

use magg_plumbing::auth::{AddToken, CheckToken, Token};
use magg_plumbing::transport::{InProcess, Mode};
use magg_proto::v1::host_client::HostClient;
use magg_proto::v1::host_server::{Host, HostServer};
use magg_proto::v1::{
    NextWorkReply, NextWorkRequest, RegisterReply, RegisterRequest, SubmitRowsReply, SubmitRowsRequest,
};
use std::time::Duration;
use tonic::service::interceptor::InterceptedService;
use tonic::{Code, Request, Response, Status};

/// A host that answers Register with the caller's name as the node id's length, and
/// holds NextWork for a second.
struct Echo;

#[tonic::async_trait]
impl Host for Echo {
    async fn register(&self, req: Request<RegisterRequest>) -> Result<Response<RegisterReply>, Status> {
        Ok(Response::new(RegisterReply { node: req.into_inner().name.len() as u32, ..Default::default() }))
    }
    async fn next_work(&self, _: Request<NextWorkRequest>) -> Result<Response<NextWorkReply>, Status> {
        tokio::time::sleep(Duration::from_secs(1)).await;
        Ok(Response::new(NextWorkReply::default()))
    }
    async fn submit_rows(&self, _: Request<SubmitRowsRequest>) -> Result<Response<SubmitRowsReply>, Status> {
        Err(Status::invalid_argument("no rows wanted"))
    }
}

/// An address no process listens on (a port taken and dropped).
fn unused_addr() -> String {
    let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    l.local_addr().unwrap().to_string()
}

fn token(t: &str) -> Token {
    Token::new(Some(t.into()))
}

async fn client(
    links: &InProcess,
    addr: &str,
    timeout: Option<Duration>,
    t: &str,
) -> HostClient<magg_plumbing::auth::Authed> {
    let endpoint = magg_plumbing::tls::endpoint(addr).unwrap().connect_timeout(Duration::from_millis(300));
    let ch = links.connect(endpoint, timeout).await.unwrap();
    HostClient::with_interceptor(ch, AddToken(token(t)))
}

#[tokio::test]
async fn a_registered_service_answers_without_a_socket_with_its_interceptors_and_deadlines() {
    let addr = unused_addr();
    let server = InterceptedService::new(HostServer::new(Echo), CheckToken { token: token("s3cret"), server: "host" });
    let links = InProcess::new(Mode::InProcess);
    let registered = links.register(&addr, server);
    assert!(links.get(&format!("http://{addr}")).is_some(), "the scheme is ignored");

    let mut host = client(&links, &addr, Some(Duration::from_millis(100)), "s3cret").await;
    let reply = host.register(RegisterRequest { name: "abcd".into(), ..Default::default() }).await.unwrap();
    assert_eq!(reply.into_inner().node, 4, "the call went through encoding and the service");
    let e = host.submit_rows(SubmitRowsRequest::default()).await.unwrap_err();
    assert_eq!((e.code(), e.message()), (Code::InvalidArgument, "no rows wanted"));
    // As on a channel with `Endpoint::timeout`: tonic reports the expired call as
    // CANCELLED, "Timeout expired" (which callers retry).
    let e = host.next_work(NextWorkRequest::default()).await.unwrap_err();
    assert_eq!((e.code(), e.message()), (Code::Cancelled, "Timeout expired"), "{e:?}");

    let mut intruder = client(&links, &addr, None, "wrong").await;
    let e = intruder.register(RegisterRequest::default()).await.unwrap_err();
    assert_eq!(e.code(), Code::Unauthenticated, "the server's token check runs in-process too");

    drop(registered);
    assert!(links.get(&addr).is_none());
    let endpoint = magg_plumbing::tls::endpoint(&addr).unwrap().connect_timeout(Duration::from_millis(300));
    assert!(links.connect(endpoint, None).await.is_err(), "unregistered: a socket, and nobody listens");
}

#[tokio::test]
async fn a_service_is_reached_only_through_the_set_it_registered_in() {
    let addr = unused_addr();
    let (_reporter, health) = tonic_health::server::health_reporter();
    let (ours, theirs) = (InProcess::new(Mode::InProcess), InProcess::new(Mode::InProcess));
    let _registered = ours.register(&addr, health);
    assert!(ours.wait_registered(&addr, Duration::from_millis(10)));
    assert!(ours.clone().get(&addr).is_some(), "a clone shares the set");
    assert!(theirs.get(&addr).is_none(), "no process-wide registry: another set does not see it");
    assert!(!theirs.wait_registered(&addr, Duration::from_millis(50)));
    let endpoint = magg_plumbing::tls::endpoint(&addr).unwrap().connect_timeout(Duration::from_millis(300));
    assert!(theirs.connect(endpoint, None).await.is_err(), "another set opens a socket, and nobody listens");
}

#[test]
fn the_tcp_mode_and_a_process_of_its_own_register_nothing() {
    let addr = unused_addr();
    for links in [InProcess::new(Mode::Tcp), InProcess::none()] {
        let (_reporter, health) = tonic_health::server::health_reporter();
        let _registered = links.register(&addr, health);
        assert!(links.get(&addr).is_none(), "{links:?} found an in-process service");
        assert!(!links.wait_registered(&addr, Duration::from_millis(50)), "{links:?} waited for a registration");
    }
}
