//! The forks prepare the scene: a [`ShareSet`] whose shares live on the forks, share `s`
//! on fork `s mod F`, each step a `Prepare` call carrying the step's bytes
//! ([`magg_prepare::shares::wire`]). The host's driver ([`magg_prepare::shares::weld`]
//! and the steps after it) is the one the embedded renderer runs with its shares in
//! process, so the prepared scene is the same, bit for bit.
//!
//! A fork that cannot be reached within the fork timeout, or that answers `ABORTED` (it
//! restarted and no longer holds its share), is [`ShareError::Lost`]: the host prepares
//! again in a new session ([`magg_prepare::ATTEMPTS`] times), every share on the forks
//! as they are then. A fork that accepts a connection and does not answer a `Begin`
//! (which only stores patches) within the fork timeout is silent, as a `LoadShard` would
//! find it: the render stops naming it. The other steps compute, and may take longer:
//! their deadline is [`STEP_TIMEOUT_FACTOR`] fork timeouts, two minutes at least.

use magg_plumbing::auth::{AddToken, Authed, Token};
use magg_plumbing::retry::{self, Backoff};
use magg_plumbing::transport::InProcess;
use magg_plumbing::with_message_limits;
use magg_prepare::shares::steps::{Reply, Request};
use magg_prepare::shares::{wire, ShareError, ShareSet};
use magg_proto::v1::fork_client::ForkClient;
use magg_proto::v1::PrepareRequest;
use std::time::Duration;
use tonic::Code;

/// A computing step's deadline, in fork timeouts.
pub const STEP_TIMEOUT_FACTOR: u32 = 8;

/// The shares of a scene on the forks at `addrs`.
pub struct ForkShares {
    rt: tokio::runtime::Handle,
    links: InProcess,
    addrs: Vec<String>,
    token: Token,
    timeout: Duration,
    clients: Vec<Option<ForkClient<Authed>>>,
    /// This host's sessions: a random start (another host's sessions on the same forks
    /// do not collide), counted up.
    session: u64,
}

impl ForkShares {
    /// The forks at `addrs` (those of this process through `links`), reached with
    /// `token`, each call retried until `timeout`; calls run on `rt`.
    pub fn new(
        rt: tokio::runtime::Handle,
        links: InProcess,
        addrs: Vec<String>,
        token: Token,
        timeout: Duration,
    ) -> Self {
        let seed = magg_plumbing::auth::NodeKey::random();
        let session = u64::from_le_bytes(seed.as_bytes()[..8].try_into().unwrap_or([1; 8])) >> 1;
        let clients = vec![None; addrs.len()];
        ForkShares { rt, links, addrs, token, timeout, clients, session }
    }

    /// The client of fork `f`, connected on first use.
    fn client(&mut self, f: usize) -> Result<ForkClient<Authed>, ShareError> {
        if let Some(c) = &self.clients[f] {
            return Ok(c.clone());
        }
        let backoff = Backoff { deadline: self.timeout, ..Default::default() };
        let ch = self
            .rt
            .block_on(retry::connect_with_backoff(&self.links, &self.addrs[f], backoff))
            .map_err(|e| ShareError::Lost { at: self.addrs[f].clone(), why: e.reason })?;
        let c = with_message_limits!(ForkClient::with_interceptor(ch, AddToken(self.token.clone())));
        self.clients[f] = Some(c.clone());
        Ok(c)
    }
}

impl ShareSet for ForkShares {
    fn begin_session(&mut self) -> u64 {
        self.session = self.session.wrapping_add(1);
        self.session
    }

    fn run(&mut self, session: u64, requests: Vec<(u32, Request)>) -> Result<Vec<Reply>, ShareError> {
        if self.addrs.is_empty() {
            return Err(ShareError::Failed { share: 0, why: "no fork to prepare the scene on".into() });
        }
        // A Begin only stores patches: a fork that does not answer it in time is silent.
        let begin = matches!(requests.first(), Some((_, Request::Begin { .. })));
        let mut calls = Vec::with_capacity(requests.len());
        for (share, request) in requests {
            let f = share as usize % self.addrs.len();
            let client = self.client(f)?;
            let req = PrepareRequest {
                protocol_version: magg_proto::PROTOCOL_VERSION,
                session,
                share,
                payload: wire::encode_request(&request),
            };
            calls.push((share, f, client, req));
        }
        let timeout = self.timeout;
        let step_timeout = (timeout * STEP_TIMEOUT_FACTOR).max(Duration::from_secs(120));
        let backoff = Backoff { deadline: timeout, call_timeout: step_timeout, ..Default::default() };
        let answers = self.rt.block_on(futures_util::future::join_all(calls.into_iter().map(
            |(share, f, client, req)| async move {
                let call = retry::retry("Prepare", backoff, || {
                    let (mut c, req) = (client.clone(), req.clone());
                    async move { c.prepare(req).await }
                });
                let reply = match begin {
                    true => tokio::time::timeout(timeout, call).await.map_err(|_| ()),
                    false => Ok(call.await),
                };
                (share, f, reply)
            },
        )));
        let mut replies = Vec::with_capacity(answers.len());
        for (share, f, answer) in answers {
            let at = &self.addrs[f];
            let Ok(answer) = answer else {
                let why =
                    format!("the fork at {at} has not answered for {timeout:?} (--fork-timeout): no answer to Prepare");
                return Err(ShareError::Failed { share, why });
            };
            match answer {
                Ok(r) => replies.push(
                    wire::decode_reply(&r.into_inner().payload)
                        .map_err(|e| ShareError::Failed { share, why: format!("the fork at {at}: {e}") })?,
                ),
                Err(status) => {
                    let hint = magg_plumbing::tls::mismatch_hint(&status.to_string());
                    let why = format!("{:?}: {}{hint}", status.code(), status.message());
                    // A connection that broke, or a fork that restarted since: try again.
                    self.clients[f] = None;
                    return Err(match status.code() {
                        Code::Aborted
                        | Code::Unavailable
                        | Code::Unknown
                        | Code::Cancelled
                        | Code::DeadlineExceeded => ShareError::Lost { at: at.clone(), why },
                        _ => ShareError::Failed { share, why: format!("the fork at {at}: {why}") },
                    });
                }
            }
        }
        Ok(replies)
    }

    fn place(&self) -> String {
        format!("on the forks at {}", self.addrs.join(", "))
    }
}
