//! Optional TLS (rustls) on every gRPC channel of a cluster, with certificates given by
//! path: `--tls-cert`, `--tls-key` (this process's server identity) and `--tls-ca` (the
//! CA that every peer's certificate must chain to), or `MAGG_TLS_CERT`/`KEY`/`CA`.
//!
//! The settings are process-wide, like the tracing subscriber: each binary reads its
//! flags into [`TlsFiles`], loads them once ([`TlsFiles::load`]) and [`install`]s the
//! result before it connects or serves anything. From then on every server the process
//! builds with [`server_builder`] serves TLS, and every channel it opens with [`endpoint`]
//! uses `https://` and verifies the peer against the CA (the certificate must name the
//! address dialled, a DNS name or an IP, in its subject alternative names). With nothing
//! installed both are plaintext, as before. The cluster token then travels encrypted.
//!
//! ```no_run
//! # fn f() -> Result<(), Box<dyn std::error::Error>> {
//! use magg_plumbing::tls::{self, TlsFiles};
//! let files = TlsFiles { cert: Some("fork.pem".into()), key: Some("fork.key".into()), ca: Some("ca.pem".into()) };
//! tls::install(files.load()?);
//! let endpoint = tls::endpoint("127.0.0.1:7100")?; // https://127.0.0.1:7100, CA-verified
//! # Ok(()) }
//! ```

use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use tonic::transport::{Certificate, ClientTlsConfig, Endpoint, Identity, Server, ServerTlsConfig};

/// The TLS flags every binary takes (flatten into a clap parser).
#[derive(Clone, Debug, Default, PartialEq, Eq, clap::Args)]
pub struct TlsFiles {
    /// PEM certificate (chain) this process serves with; with --tls-key, its servers speak
    /// TLS. It must name the address peers dial (DNS or IP subject alternative name).
    #[arg(long = "tls-cert", env = "MAGG_TLS_CERT", value_name = "FILE")]
    pub cert: Option<PathBuf>,
    /// PEM private key of --tls-cert.
    #[arg(long = "tls-key", env = "MAGG_TLS_KEY", value_name = "FILE")]
    pub key: Option<PathBuf>,
    /// PEM CA certificate that peers' certificates must chain to; when given, every
    /// connection this process makes is TLS (https) and verified against it.
    #[arg(long = "tls-ca", env = "MAGG_TLS_CA", value_name = "FILE")]
    pub ca: Option<PathBuf>,
}

/// Why the TLS files are unusable. Each names the file or flag at fault.
#[derive(Debug, thiserror::Error)]
pub enum TlsError {
    /// A file could not be read.
    #[error("{flag} {}: {reason}", path.display())]
    Read {
        /// The flag that named it.
        flag: &'static str,
        /// The file.
        path: PathBuf,
        /// The system's complaint.
        reason: String,
    },
    /// A file holds no PEM block of the expected kind.
    #[error("{flag} {}: no PEM {kind} in the file", path.display())]
    NotPem {
        /// The flag that named it.
        flag: &'static str,
        /// The file.
        path: PathBuf,
        /// What was expected ("CERTIFICATE", "PRIVATE KEY").
        kind: &'static str,
    },
    /// --tls-cert without --tls-key or the reverse.
    #[error("--tls-cert and --tls-key go together (only {given} was given)")]
    Unpaired {
        /// The one given.
        given: &'static str,
    },
}

/// Loaded TLS settings: what a process serves with and what it verifies peers against.
#[derive(Clone, Debug, Default)]
pub struct Tls {
    /// Server side, when a certificate and key were given.
    pub server: Option<ServerTlsConfig>,
    /// Client side, when a CA was given.
    pub client: Option<ClientTlsConfig>,
}

impl TlsFiles {
    /// True when no file is given (plaintext).
    pub fn is_empty(&self) -> bool {
        self.cert.is_none() && self.key.is_none() && self.ca.is_none()
    }

    /// Reads the files, checking that each holds PEM of its kind. The rustls handshake
    /// itself checks that key and certificate match when the first peer connects.
    pub fn load(&self) -> Result<Tls, TlsError> {
        let server = match (&self.cert, &self.key) {
            (Some(cert), Some(key)) => {
                let cert = read_pem("--tls-cert", cert, "CERTIFICATE")?;
                let key = read_pem("--tls-key", key, "PRIVATE KEY")?;
                Some(ServerTlsConfig::new().identity(Identity::from_pem(cert, key)))
            }
            (Some(_), None) => return Err(TlsError::Unpaired { given: "--tls-cert" }),
            (None, Some(_)) => return Err(TlsError::Unpaired { given: "--tls-key" }),
            (None, None) => None,
        };
        let client = match &self.ca {
            Some(ca) => {
                let ca = read_pem("--tls-ca", ca, "CERTIFICATE")?;
                Some(ClientTlsConfig::new().ca_certificate(Certificate::from_pem(ca)))
            }
            None => None,
        };
        Ok(Tls { server, client })
    }
}

/// Reads `path` and checks that it holds a PEM block whose label ends with `kind`
/// (`PRIVATE KEY` covers PKCS#8, RSA and EC keys).
fn read_pem(flag: &'static str, path: &Path, kind: &'static str) -> Result<Vec<u8>, TlsError> {
    let bytes =
        std::fs::read(path).map_err(|e| TlsError::Read { flag, path: path.to_path_buf(), reason: e.to_string() })?;
    let text = String::from_utf8_lossy(&bytes);
    let found = text
        .lines()
        .filter_map(|l| l.trim().strip_prefix("-----BEGIN ")?.strip_suffix("-----"))
        .any(|label| label.ends_with(kind));
    if found {
        Ok(bytes)
    } else {
        Err(TlsError::NotPem { flag, path: path.to_path_buf(), kind })
    }
}

static INSTALLED: OnceLock<Tls> = OnceLock::new();

/// Makes `tls` this process's settings. The first call wins (a process has one
/// identity); later calls are ignored and return false.
pub fn install(tls: Tls) -> bool {
    INSTALLED.set(tls).is_ok()
}

/// Loads `files` and [`install`]s them: what each binary does first. Nothing is
/// installed when no file is given.
pub fn install_files(files: &TlsFiles) -> Result<(), TlsError> {
    if !files.is_empty() {
        install(files.load()?);
    }
    Ok(())
}

/// The installed settings (plaintext when none).
fn installed() -> Option<&'static Tls> {
    INSTALLED.get()
}

/// True when this process connects with TLS.
pub fn client_enabled() -> bool {
    installed().is_some_and(|t| t.client.is_some())
}

/// The URI of a peer address: `HOST:PORT` becomes `https://HOST:PORT` when TLS is
/// installed for clients, else `http://HOST:PORT`; an address with a scheme is kept.
pub fn uri(addr: &str) -> String {
    if addr.contains("://") {
        addr.to_string()
    } else if client_enabled() {
        format!("https://{addr}")
    } else {
        format!("http://{addr}")
    }
}

/// A hint to add to a connection error whose text (`error`) looks like the two ends
/// disagree about TLS: a plaintext client of a TLS server sees HTTP/2 frame errors, a
/// TLS client of a plaintext server sees a corrupt TLS record. Empty otherwise.
pub fn mismatch_hint(error: &str) -> &'static str {
    if client_enabled() {
        if error.contains("corrupt message") || error.contains("InvalidContentType") {
            return " (is the peer serving plaintext? give it --tls-cert and --tls-key)";
        }
    } else if error.contains("frame with invalid size") || error.contains("h2 protocol error") {
        return " (is the peer serving TLS? give this process --tls-ca)";
    }
    ""
}

/// An endpoint to `addr` ([`uri`]), verifying the peer against the installed CA when
/// there is one. Callers add their timeouts and window sizes.
pub fn endpoint(addr: &str) -> Result<Endpoint, tonic::transport::Error> {
    let endpoint = Endpoint::from_shared(uri(addr))?;
    match installed().and_then(|t| t.client.clone()) {
        Some(client) => endpoint.tls_config(client),
        None => Ok(endpoint),
    }
}

/// A server builder that serves TLS with the installed identity when there is one.
pub fn server_builder() -> Result<Server, tonic::transport::Error> {
    let builder = Server::builder();
    match installed().and_then(|t| t.server.clone()) {
        Some(server) => builder.tls_config(server),
        None => Ok(builder),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_files_is_plaintext() {
        let tls = TlsFiles::default().load().unwrap();
        assert!(tls.server.is_none() && tls.client.is_none());
    }

    #[test]
    fn a_missing_file_is_named() {
        let files = TlsFiles { ca: Some("/nonexistent/ca.pem".into()), ..Default::default() };
        let e = files.load().unwrap_err().to_string();
        assert!(e.starts_with("--tls-ca /nonexistent/ca.pem:"), "{e}");
    }

    #[test]
    fn a_file_without_pem_is_named() {
        let dir = std::env::temp_dir().join(format!("magg-tls-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (cert, key) = (dir.join("cert.pem"), dir.join("key.pem"));
        std::fs::write(&cert, "-----BEGIN CERTIFICATE-----\nAAAA\n-----END CERTIFICATE-----\n").unwrap();
        std::fs::write(&key, "not a key").unwrap();
        let files = TlsFiles { cert: Some(cert), key: Some(key.clone()), ca: None };
        let e = files.load().unwrap_err().to_string();
        assert_eq!(e, format!("--tls-key {}: no PEM PRIVATE KEY in the file", key.display()));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn cert_without_key_is_refused() {
        let files = TlsFiles { cert: Some("c.pem".into()), ..Default::default() };
        assert!(matches!(files.load(), Err(TlsError::Unpaired { given: "--tls-cert" })));
    }

    #[test]
    fn plain_uri_without_tls() {
        assert_eq!(uri("a:1"), "http://a:1");
        assert_eq!(uri("https://a:1"), "https://a:1");
    }
}
