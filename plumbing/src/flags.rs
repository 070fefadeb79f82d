//! The clap flag groups every magg binary shares: the cluster flags of a fork and a
//! node ([`ClusterArgs`]), the TLS files ([`crate::tls::TlsFiles`], inside them) and the
//! `probe ADDR` subcommand ([`ProbeCommand`]).
//!
//! ```
//! use clap::Parser;
//! #[derive(Parser)]
//! struct Args {
//!     #[command(flatten)]
//!     cluster: magg_plumbing::flags::ClusterArgs,
//!     #[command(subcommand)]
//!     command: Option<magg_plumbing::flags::ProbeCommand>,
//! }
//! let args = Args::parse_from(["magg-fork", "--token", "s3cret"]);
//! assert_eq!(args.cluster.token.as_deref(), Some("s3cret"));
//! ```

/// Arguments of the `probe` subcommand of every binary.
#[derive(Clone, Debug, clap::Args)]
pub struct ProbeArgs {
    /// Address to probe (HOST:PORT): a magg-fork, a magg-node with --health-listen, or a
    /// magg-host while it renders.
    pub addr: String,
    /// PEM CA to verify a TLS server against (the cluster's --tls-ca): the probe then
    /// speaks TLS.
    #[arg(long = "tls-ca", env = "MAGG_TLS_CA", value_name = "FILE")]
    pub tls_ca: Option<std::path::PathBuf>,
}

/// The subcommands of a binary whose only one is `probe` (magg-fork, magg-node).
#[derive(Clone, Debug, clap::Subcommand)]
pub enum ProbeCommand {
    /// Ask the gRPC health service at ADDR and exit 0 when it reports SERVING: the health
    /// check of a container image that has no shell.
    Probe(ProbeArgs),
}

/// The flags every cluster process (magg-fork, magg-node) shares, flattened into each
/// binary's arguments.
#[derive(Clone, Debug, clap::Args)]
pub struct ClusterArgs {
    /// Hardware profile: a built-in name (native, magg1993) or a profile
    /// file. The host sends each render's profile; with this flag the process refuses a
    /// render that runs another one. Without it, it runs the host's.
    #[arg(long, env = "MAGG_PROFILE")]
    pub profile: Option<String>,
    /// Cluster token: presented on every call, and required on every call a fork serves
    /// (the same on every process of the cluster). Without one, any client is served:
    /// keep the default 127.0.0.1 addresses then.
    #[arg(long, env = "MAGG_TOKEN", hide_env_values = true)]
    pub token: Option<String>,
    /// TLS: the certificate and key of what this process serves, and the CA its peers'
    /// certificates chain to (every connection is then https).
    #[command(flatten)]
    pub tls: crate::tls::TlsFiles,
    /// More log output (-v: info, -vv: debug, -vvv: trace); RUST_LOG overrides.
    #[arg(short, long, action = clap::ArgAction::Count)]
    pub verbose: u8,
    /// Keep serving when the process that started this one ends. Without it, a fork or
    /// node whose parent is gone (a script killed with SIGKILL, a closed shell) exits
    /// within a second instead of serving forever; one started by init, systemd or as a
    /// container's first process has no such parent and serves on anyway.
    #[arg(long, env = "MAGG_SERVE_ON")]
    pub serve_on: bool,
}
