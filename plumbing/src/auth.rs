//! Who may join a cluster: a shared token that every process presents on every call
//! (gRPC metadata `x-magg-token`) and every server checks.
//!
//! A client wraps its channel with [`AddToken`] ([`Authed`] is the resulting channel
//! type); a server wraps each service with [`CheckToken`]. A call without the token, or
//! with another, is refused with `UNAUTHENTICATED` and a message saying what to set, and
//! the server logs the refusal. With no token configured a server accepts every call
//! (fine on 127.0.0.1, the default bind address, and on a private network;
//! [`exposure_warning`] says when a server can be reached from outside, see [`crate::reach`]).
//!
//! ```no_run
//! use magg_plumbing::auth::{AddToken, Token};
//! use magg_proto::v1::fork_client::ForkClient;
//! # async fn f() -> Result<(), Box<dyn std::error::Error>> {
//! let token = Token::new(Some("s3cret".into()));
//! let channel = tonic::transport::Endpoint::from_static("http://127.0.0.1:7100").connect().await?;
//! let fork = ForkClient::with_interceptor(channel, AddToken(token));
//! # Ok(()) }
//! ```

use std::net::{IpAddr, SocketAddr};
use std::sync::Arc;
use tonic::metadata::MetadataValue;
use tonic::service::interceptor::InterceptedService;
use tonic::{Request, Status};

/// The metadata key carrying the token.
pub const TOKEN_KEY: &str = "x-magg-token";

/// Environment variable every binary reads the token from when `--token` is not given.
pub const TOKEN_ENV: &str = "MAGG_TOKEN";

/// Longest token accepted (it travels on every call).
pub const MAX_TOKEN_LEN: usize = 256;

/// The cluster token, or none (no check). Cheap to clone.
#[derive(Clone, Default, PartialEq, Eq)]
pub struct Token(Option<Arc<str>>);

impl std::fmt::Debug for Token {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.0.is_some() { "Token(<set>)" } else { "Token(none)" })
    }
}

/// Why a token given on a command line is unusable.
#[derive(Debug, thiserror::Error)]
pub enum TokenError {
    /// Too long, or not printable ASCII (it must fit in a gRPC metadata value).
    #[error("the cluster token must be 1..={MAX_TOKEN_LEN} printable ASCII characters without spaces")]
    Malformed,
}

impl Token {
    /// A token from a flag or environment value; an empty string means none. Not checked:
    /// see [`Token::parse`].
    pub fn new(token: Option<String>) -> Token {
        Token(token.filter(|t| !t.is_empty()).map(Arc::from))
    }

    /// A token from a flag or environment value, refusing values that cannot travel in
    /// metadata.
    pub fn parse(token: Option<String>) -> Result<Token, TokenError> {
        let t = Token::new(token);
        match &t.0 {
            Some(s) if s.len() > MAX_TOKEN_LEN || !s.bytes().all(|b| b.is_ascii_graphic()) => {
                Err(TokenError::Malformed)
            }
            _ => Ok(t),
        }
    }

    /// True when a token is set.
    pub fn is_set(&self) -> bool {
        self.0.is_some()
    }

    /// The token's text, for handing on to processes started by this one.
    pub fn as_str(&self) -> Option<&str> {
        self.0.as_deref()
    }
}

/// Byte comparison whose time does not depend on where the inputs differ.
fn same(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// Client side: adds the token to every call.
#[derive(Clone, Debug, Default)]
pub struct AddToken(pub Token);

impl tonic::service::Interceptor for AddToken {
    fn call(&mut self, mut req: Request<()>) -> Result<Request<()>, Status> {
        if let Some(t) = &self.0 .0 {
            let v: MetadataValue<_> =
                t.parse().map_err(|_| Status::invalid_argument("the cluster token is not valid metadata"))?;
            req.metadata_mut().insert(TOKEN_KEY, v);
        }
        Ok(req)
    }
}

/// A connection (socket or in-process, see [`crate::transport`]) that adds the cluster
/// token to every call.
pub type Authed = InterceptedService<crate::transport::Transport, AddToken>;

/// Server side: refuses calls without the right token.
#[derive(Clone, Debug, Default)]
pub struct CheckToken {
    /// The expected token (none: every call passes).
    pub token: Token,
    /// Which server this is, for the log and the error ("fork", "host").
    pub server: &'static str,
}

impl tonic::service::Interceptor for CheckToken {
    fn call(&mut self, req: Request<()>) -> Result<Request<()>, Status> {
        let Some(want) = &self.token.0 else { return Ok(req) };
        let got = req.metadata().get(TOKEN_KEY).map(|v| v.as_bytes());
        if got.is_some_and(|g| same(g, want.as_bytes())) {
            return Ok(req);
        }
        let what = if got.is_some() { "a wrong" } else { "no" };
        let peer = req.remote_addr().map_or_else(|| "a client".to_string(), |a| a.to_string());
        tracing::warn!("{} refused a call from {peer}: {what} cluster token", self.server);
        Err(Status::unauthenticated(format!(
            "the {} refused the call: {what} cluster token (give every process the same --token or {TOKEN_ENV})",
            self.server
        )))
    }
}

/// The warning to print when a server without a token listens where it can be reached
/// from outside this machine's private networks ([`crate::reach`]), if it does: a fork
/// on a compose network or a pod network stays quiet.
pub fn exposure_warning(addr: SocketAddr, token: &Token) -> Option<String> {
    if token.is_set() || addr.ip().is_loopback() {
        return None;
    }
    let interfaces = if addr.ip().is_unspecified() { crate::reach::interface_addresses() } else { None };
    exposure_warning_on(addr, token, interfaces.as_deref())
}

/// [`exposure_warning`] on a machine with these interface addresses (`None`: unknown).
pub fn exposure_warning_on(addr: SocketAddr, token: &Token, interfaces: Option<&[IpAddr]>) -> Option<String> {
    (!token.is_set() && crate::reach::reachable_from_outside(addr, interfaces)).then(|| {
        format!(
            "listening on {addr} without a cluster token, reachable from outside this machine's private networks: \
             any host that can reach it may join or read the scene (set --token or {TOKEN_ENV} on every process)"
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use tonic::service::Interceptor;

    fn with(token: Option<&str>) -> Request<()> {
        let mut r = Request::new(());
        if let Some(t) = token {
            r.metadata_mut().insert(TOKEN_KEY, t.parse().unwrap());
        }
        r
    }

    #[test]
    fn the_right_token_passes_and_others_are_refused() {
        let mut check = CheckToken { token: Token::new(Some("abc".into())), server: "fork" };
        assert!(check.call(with(Some("abc"))).is_ok());
        for bad in [None, Some("abd"), Some("ab"), Some("abcd")] {
            let e = check.call(with(bad)).unwrap_err();
            assert_eq!(e.code(), tonic::Code::Unauthenticated, "{bad:?}");
            assert!(e.message().contains("--token"), "{e}");
        }
    }

    #[test]
    fn no_token_configured_lets_everything_through() {
        let mut check = CheckToken::default();
        assert!(check.call(with(None)).is_ok());
        assert!(check.call(with(Some("x"))).is_ok());
    }

    #[test]
    fn the_client_adds_what_the_server_wants() {
        let t = Token::new(Some("k3y".into()));
        let req = AddToken(t.clone()).call(Request::new(())).unwrap();
        assert!(CheckToken { token: t, server: "host" }.call(req).is_ok());
    }

    #[test]
    fn malformed_tokens_and_open_binds() {
        assert!(Token::parse(Some("has space".into())).is_err());
        assert!(Token::parse(Some("x".repeat(300))).is_err());
        assert!(!Token::parse(Some(String::new())).unwrap().is_set());
        let none = Token::default();
        assert!(exposure_warning("127.0.0.1:1".parse().unwrap(), &none).is_none());
        let public = ["10.0.0.1".parse().unwrap(), "203.0.113.4".parse().unwrap()];
        let private = ["10.0.0.1".parse().unwrap(), "fd00::1".parse().unwrap()];
        let any = "0.0.0.0:1".parse().unwrap();
        assert!(exposure_warning_on(any, &none, Some(&public)).is_some());
        assert!(exposure_warning_on(any, &none, Some(&private)).is_none(), "a private network is quiet");
        assert!(exposure_warning_on("172.20.0.3:1".parse().unwrap(), &none, None).is_none());
        assert!(exposure_warning_on("198.51.100.7:1".parse().unwrap(), &none, None).is_some());
        assert!(exposure_warning_on(any, &Token::new(Some("t".into())), Some(&public)).is_none());
    }
}

/// The key of one render's node secrets: node `i`'s secret is a keyed hash (HMAC-SHA256,
/// 64 bits of it) of `i`. The host makes the key, hands each node its own secret at
/// registration and every fork the key with its shard, so that a fork can check that a
/// request under node `i`'s id comes from node `i`, and no node can work out another's.
#[derive(Clone, Default, PartialEq, Eq)]
pub struct NodeKey(Vec<u8>);

impl std::fmt::Debug for NodeKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "NodeKey({} bytes)", self.0.len())
    }
}

impl NodeKey {
    /// A fresh key from the operating system's random source.
    pub fn random() -> NodeKey {
        use ring::rand::SecureRandom;
        let mut k = vec![0u8; 32];
        if ring::rand::SystemRandom::new().fill(&mut k).is_err() {
            // No random source: a key that still differs per process and per moment.
            let t = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
            k[..16].copy_from_slice(&t.as_nanos().to_le_bytes());
            k[16..20].copy_from_slice(&std::process::id().to_le_bytes());
        }
        NodeKey(k)
    }

    /// The key as sent to forks (empty: none, nothing is checked).
    pub fn from_bytes(b: &[u8]) -> NodeKey {
        NodeKey(b.to_vec())
    }

    /// The key's bytes.
    pub fn as_bytes(&self) -> &[u8] {
        &self.0
    }

    /// Whether there is a key (a render's forks get one; a bare test shard has none).
    pub fn is_set(&self) -> bool {
        !self.0.is_empty()
    }

    /// Node `node`'s secret.
    pub fn secret(&self, node: u32) -> u64 {
        let key = ring::hmac::Key::new(ring::hmac::HMAC_SHA256, &self.0);
        let tag = ring::hmac::sign(&key, &node.to_le_bytes());
        let mut b = [0u8; 8];
        b.copy_from_slice(&tag.as_ref()[..8]);
        u64::from_le_bytes(b)
    }

    /// Whether `secret` is node `node`'s (always, without a key).
    pub fn admits(&self, node: u32, secret: u64) -> bool {
        !self.is_set() || self.secret(node) == secret
    }
}

#[cfg(test)]
mod node_key_tests {
    use super::*;

    #[test]
    fn secrets_differ_per_node_and_per_key_and_only_the_right_one_is_admitted() {
        let (a, b) = (NodeKey::random(), NodeKey::random());
        assert_ne!(a.secret(0), a.secret(1));
        assert_ne!(a.secret(0), b.secret(0));
        assert_eq!(a.secret(7), NodeKey::from_bytes(a.as_bytes()).secret(7));
        assert!(a.admits(3, a.secret(3)) && !a.admits(3, a.secret(4)) && !a.admits(3, 0));
        assert!(NodeKey::default().admits(3, 0), "no key: nothing to check");
    }
}
