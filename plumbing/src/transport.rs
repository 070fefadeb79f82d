//! What a client's calls travel over: a TCP (or TLS) channel to another process, or the
//! in-process transport to a server of this same process.
//!
//! The single-process harness behind `magg-host render` runs forks, nodes and the host in
//! one process. Their calls need not cross the kernel's loopback: the harness makes one
//! [`InProcess`] set, each server [`InProcess::register`]s its tonic service under the
//! address it also listens on, and a client given the same set that
//! [`InProcess::connect`]s to that address gets the service itself instead of a socket.
//! The set is passed to whoever needs it (no process-wide registry): a fork or node
//! process of its own holds [`InProcess::none`] and always opens sockets. The call is still
//! gRPC: the client encodes the request with prost, the server's interceptors (cluster
//! token) and codec (message size limits) run, the reply is decoded and statuses are the
//! same; only HTTP/2 framing, TCP and the hop between threads are skipped. This is
//! grpc-java's `InProcessChannel`, for tonic. A set made in [`Mode::Tcp`] registers
//! nothing, so every call goes over a socket again.
//!
//! ```no_run
//! # async fn f() -> Result<(), Box<dyn std::error::Error>> {
//! use magg_plumbing::transport::{InProcess, Mode};
//! let links = InProcess::new(Mode::InProcess);
//! let (_reporter, health) = tonic_health::server::health_reporter();
//! let _registered = links.register("127.0.0.1:7100", health); // until dropped
//! let endpoint = magg_plumbing::tls::endpoint("127.0.0.1:7100")?;
//! let channel = links.connect(endpoint, None).await?; // no socket
//! # Ok(()) }
//! ```

use std::collections::HashMap;
use std::convert::Infallible;
use std::sync::{Arc, Condvar, Mutex};
use std::task::{Context, Poll};
use std::time::Duration;
use tonic::body::Body;
use tonic::codegen::http::{Request, Response};
use tonic::transport::Endpoint;
use tower::util::BoxCloneSyncService;
use tower::{Service, ServiceExt};

/// A client's connection: boxed, so a `ForkClient<Transport>` is one type whatever it
/// runs over.
pub type Transport = BoxCloneSyncService<Request<Body>, Response<Body>, TransportError>;

/// Why a call failed below gRPC (a socket error, or an in-process deadline). A concrete
/// type rather than a bare box: tonic's client bounds then hold in every async context.
/// tonic turns it into a `Status` by looking through [`std::error::Error::source`]
/// (an expired deadline becomes `CANCELLED` "Timeout expired", as on a channel).
#[derive(Debug)]
pub struct TransportError(tower::BoxError);

impl std::fmt::Display for TransportError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.fmt(f)
    }
}

impl std::error::Error for TransportError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        Some(&*self.0)
    }
}

/// How the clients of one in-process cluster reach its servers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Mode {
    /// Through the in-process transport when the address is registered (the default).
    #[default]
    InProcess,
    /// Always over a socket, as between processes.
    Tcp,
}

/// The servers of one in-process cluster, by address (`HOST:PORT`, no scheme), shared by
/// its clients. Cloning shares the set.
#[derive(Clone, Debug, Default)]
pub struct InProcess {
    shared: Option<Arc<Shared>>,
}

#[derive(Default)]
struct Shared {
    services: Mutex<HashMap<String, Transport>>,
    /// Signalled whenever a service registers (for [`InProcess::wait_registered`]).
    registered: Condvar,
    /// Values handed between the servers and clients of this process by key
    /// ([`InProcess::share`]), and the last key given.
    values: Mutex<(u64, HashMap<u64, SharedValue>)>,
}

/// A value of [`InProcess::share`].
pub type SharedValue = Arc<dyn std::any::Any + Send + Sync>;

/// Keeps a value shared; dropping it withdraws the value.
#[must_use = "the value is withdrawn when this is dropped"]
pub struct Sharing {
    shared: Arc<Shared>,
    key: u64,
}

impl Sharing {
    /// The key the value is found under ([`InProcess::shared`]); never 0.
    pub fn key(&self) -> u64 {
        self.key
    }
}

impl std::fmt::Debug for Sharing {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Sharing").field("key", &self.key).finish()
    }
}

impl Drop for Sharing {
    fn drop(&mut self) {
        if let Ok(mut v) = self.shared.values.lock() {
            v.1.remove(&self.key);
        }
    }
}

impl std::fmt::Debug for Shared {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let addrs: Vec<String> = self.services.lock().map(|r| r.keys().cloned().collect()).unwrap_or_default();
        f.debug_struct("InProcess").field("addrs", &addrs).finish()
    }
}

/// `HOST:PORT` of an address given with or without a scheme.
fn key(addr: &str) -> String {
    let a = addr.trim();
    let a = a.strip_prefix("http://").or_else(|| a.strip_prefix("https://")).unwrap_or(a);
    a.trim_end_matches('/').to_string()
}

/// Keeps a service registered; dropping it unregisters the address (a client that
/// connects later gets a socket, as to any other process).
#[must_use = "the service is unregistered when this is dropped"]
#[derive(Debug)]
pub struct Registration {
    shared: Option<Arc<Shared>>,
    key: String,
}

impl Drop for Registration {
    fn drop(&mut self) {
        if let Some(mut r) = self.shared.as_ref().and_then(|s| s.services.lock().ok()) {
            r.remove(&self.key);
        }
    }
}

impl InProcess {
    /// A set for the servers of this process: in [`Mode::InProcess`] they register and
    /// are reached without sockets; in [`Mode::Tcp`] nothing registers ([`InProcess::none`]).
    pub fn new(mode: Mode) -> InProcess {
        match mode {
            Mode::InProcess => InProcess { shared: Some(Arc::default()) },
            Mode::Tcp => InProcess::none(),
        }
    }

    /// No in-process servers: every connection is a socket (a fork or node process of
    /// its own, or `--transport tcp`).
    pub fn none() -> InProcess {
        InProcess { shared: None }
    }

    /// Makes `service` (a tonic server with its interceptors, e.g. what `fork_server`
    /// builds) reachable in-process at `addr`, the address it also listens on.
    pub fn register<S, B>(&self, addr: &str, service: S) -> Registration
    where
        S: Service<Request<Body>, Response = Response<B>, Error = Infallible> + Clone + Send + Sync + 'static,
        S::Future: Send + 'static,
        B: http_body::Body<Data = tonic::codegen::Bytes> + Send + 'static,
        B::Error: Into<tower::BoxError>,
    {
        let k = key(addr);
        if let Some(shared) = &self.shared {
            let boxed = BoxCloneSyncService::new(
                service
                    .map_response(|r: Response<B>| r.map(Body::new))
                    .map_err(|e: Infallible| -> TransportError { match e {} }),
            );
            if let Ok(mut r) = shared.services.lock() {
                r.insert(k.clone(), boxed);
            }
            shared.registered.notify_all();
        }
        Registration { shared: self.shared.clone(), key: k }
    }

    /// Shares `value` with the servers of this set, which find it by the key of the
    /// guard returned ([`InProcess::shared`]) until the guard is dropped: large payloads
    /// (a fork's scene blocks) then pass between the host and its in-process forks by
    /// reference, where a call would encode them and decode a copy. `None` for
    /// [`InProcess::none`] (no server shares this process).
    pub fn share(&self, value: SharedValue) -> Option<Sharing> {
        let shared = self.shared.as_ref()?;
        let mut v = shared.values.lock().ok()?;
        v.0 += 1;
        let key = v.0;
        v.1.insert(key, value);
        Some(Sharing { shared: shared.clone(), key })
    }

    /// The value shared under `key` in this set, if it still is.
    pub fn shared(&self, key: u64) -> Option<SharedValue> {
        self.shared.as_ref()?.values.lock().ok()?.1.get(&key).cloned()
    }

    /// The registered service at `addr`, if any.
    pub fn get(&self, addr: &str) -> Option<Transport> {
        self.shared.as_ref()?.services.lock().ok()?.get(&key(addr)).cloned()
    }

    /// Waits up to `timeout` for a server of this set to register `addr` (a client
    /// started with its server should not race it onto a socket). False when the time
    /// ran out or the set is [`InProcess::none`].
    pub fn wait_registered(&self, addr: &str, timeout: Duration) -> bool {
        let Some(shared) = &self.shared else { return false };
        let (k, deadline) = (key(addr), std::time::Instant::now() + timeout);
        let Ok(mut r) = shared.services.lock() else { return false };
        loop {
            if r.contains_key(&k) {
                return true;
            }
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            if left.is_zero() {
                return false;
            }
            r = match shared.registered.wait_timeout(r, left) {
                Ok((r, _)) => r,
                Err(_) => return false,
            };
        }
    }

    /// Opens `endpoint`: the in-process service when its address is registered in this
    /// set, with `call_timeout` as the deadline of each call (what `Endpoint::timeout`
    /// does for a socket); otherwise a connection (TCP, or TLS when installed), as
    /// [`Endpoint::connect`].
    pub async fn connect(
        &self,
        endpoint: Endpoint,
        call_timeout: Option<Duration>,
    ) -> Result<Transport, tonic::transport::Error> {
        let authority = endpoint.uri().authority().map(|a| a.to_string()).unwrap_or_default();
        if let Some(service) = self.get(&authority) {
            return Ok(match call_timeout {
                Some(timeout) => BoxCloneSyncService::new(Deadline { inner: service, timeout }),
                None => service,
            });
        }
        let channel = endpoint.connect().await?;
        Ok(BoxCloneSyncService::new(channel.map_err(|e| TransportError(e.into()))))
    }
}

/// A deadline on every call of an in-process service: a call still running after
/// `timeout` fails as a socket call would (tonic's `TimeoutExpired`).
#[derive(Clone)]
struct Deadline {
    inner: Transport,
    timeout: Duration,
}

impl Service<Request<Body>> for Deadline {
    type Response = Response<Body>;
    type Error = TransportError;
    type Future = std::pin::Pin<Box<dyn std::future::Future<Output = Result<Response<Body>, TransportError>> + Send>>;

    fn poll_ready(&mut self, cx: &mut Context<'_>) -> Poll<Result<(), Self::Error>> {
        self.inner.poll_ready(cx)
    }

    fn call(&mut self, req: Request<Body>) -> Self::Future {
        let call = self.inner.call(req);
        let timeout = self.timeout;
        Box::pin(async move {
            match tokio::time::timeout(timeout, call).await {
                Ok(r) => r,
                Err(_) => Err(TransportError(Box::new(tonic::TimeoutExpired(())))),
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_shared_value_is_found_by_its_key_until_its_guard_drops() {
        let links = InProcess::new(Mode::InProcess);
        let guard = links.share(Arc::new(vec![1u8, 2, 3])).expect("an in-process set shares");
        let key = guard.key();
        assert_ne!(key, 0);
        let other = links.clone();
        let v = other.shared(key).and_then(|v| v.downcast::<Vec<u8>>().ok()).expect("shared");
        assert_eq!(*v, vec![1, 2, 3]);
        assert!(other.shared(key + 1).is_none());
        drop(guard);
        assert!(links.shared(key).is_none(), "withdrawn with its guard");
        // A process of its own shares nothing.
        assert!(InProcess::none().share(Arc::new(0u8)).is_none());
        assert!(InProcess::none().shared(key).is_none());
    }
}
