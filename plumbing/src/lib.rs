//! # magg-plumbing: what the three magg processes share around their services
//!
//! A fork, a node and a host are different machines of the paper, but the same kind of
//! process: each parses the cluster flags ([`flags`]), keeps the memory it frees
//! ([`allocator`]), starts logging ([`logging`]), loads its TLS files ([`tls`]),
//! presents and checks the cluster token ([`auth`]) and warns when it has none where
//! outsiders can reach it ([`reach`]), serves and dials gRPC with one set
//! of limits ([`net`]), reaches servers of its own process without a socket
//! ([`transport`]), retries what failed for a transient reason ([`retry`]), answers and
//! asks health checks ([`health`]) and stops on a signal ([`lifecycle`]). The protocol
//! itself (messages, services, conversions) is `magg-proto`'s; nothing here knows a
//! message.
//!
//! ```no_run
//! use magg_plumbing::{auth, lifecycle, logging, net, retry};
//! # async fn f() -> Result<(), Box<dyn std::error::Error>> {
//! logging::init("magg-example", 0); // warnings, one format, colour only on a terminal
//! // A server with the cluster's limits, serving health until Ctrl-C or SIGTERM:
//! let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await?;
//! let (_reporter, health) = magg_plumbing::health::health_service();
//! tokio::spawn(
//!     net::server()?.add_service(health).serve_with_incoming_shutdown(net::nodelay_incoming(listener), lifecycle::shutdown_signal()),
//! );
//! // A client: retried with backoff, the token added to every call.
//! let links = magg_plumbing::transport::InProcess::none(); // a process of its own: sockets
//! let channel = retry::connect_with_backoff(&links, "127.0.0.1:7100", retry::Backoff::default()).await?;
//! let _authed = tonic::service::interceptor::InterceptedService::new(channel, auth::AddToken(auth::Token::default()));
//! # Ok(()) }
//! ```

#![deny(missing_docs)]

pub mod allocator;
pub mod auth;
pub mod flags;
pub mod health;
pub mod lifecycle;
pub mod logging;
pub mod memory;
pub mod net;
pub mod reach;
pub mod retry;
pub mod tls;
pub mod transport;

/// `e` and its sources on one line, `: `-separated (a transport error says little by
/// itself: the reason, e.g. "connection refused", is in its sources).
pub fn error_chain(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        text.push_str(": ");
        text.push_str(&s.to_string());
        source = s.source();
    }
    text
}
