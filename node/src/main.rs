//! `magg-node`: a node processor. Registers with the host and traces what it is given.
//!
//! ```text
//! magg-node --host 127.0.0.1:7000 --threads 2
//! magg-node --host host:7000 --repeat --health-listen 0.0.0.0:7200   # a long-lived service
//! magg-node probe 127.0.0.1:7200     # exit 0 when that node's health service says SERVING
//! ```

use anyhow::Context;
use clap::Parser;
use std::net::SocketAddr;
use std::process::ExitCode;
use std::time::Duration;

/// A magg node processor: pulls (light, element) pairs and subscreens and traces them.
/// Every flag can also be set by the environment variable named in its help.
#[derive(Debug, Parser)]
#[command(name = "magg-node", version, about, args_conflicts_with_subcommands = true)]
struct Args {
    /// Host address.
    #[arg(long, default_value = "127.0.0.1:7000", env = "MAGG_HOST")]
    host: String,
    /// Worker threads (cores this node uses).
    #[arg(long, default_value_t = 1, env = "MAGG_THREADS")]
    threads: u32,
    /// Cache size in 2 KB blocks, or "unlimited" (default: what the host says).
    #[arg(long, env = "MAGG_CACHE_BLOCKS")]
    cache_blocks: Option<magg_core::blocks::CacheSize>,
    /// Name in the host's logs.
    #[arg(long, default_value = "node", env = "MAGG_NODE_NAME")]
    name: String,
    /// Give up connecting, or retrying a call to an unreachable peer (with backoff and
    /// jitter), after this many seconds (with --repeat: try again, forever).
    #[arg(long, default_value_t = 30, env = "MAGG_CONNECT_TIMEOUT")]
    connect_timeout: u64,
    /// Extra milliseconds per pixel row: emulate a slow node (to watch adaptive
    /// redivision move its unstarted rows to others).
    #[arg(long, default_value_t = 0)]
    slow_row_ms: u64,
    /// After a render, wait for the next host and render again, until stopped (Ctrl-C,
    /// SIGTERM): a node as a long-lived service (docker compose, a Kubernetes Deployment).
    /// Without it the node exits when its render is done.
    #[arg(long, env = "MAGG_REPEAT")]
    repeat: bool,
    /// Serve the standard gRPC health service on this address (HOST:PORT), so that the
    /// node can be health-checked (`magg-node probe ADDR`); a node serves nothing else.
    #[arg(long, env = "MAGG_HEALTH_LISTEN")]
    health_listen: Option<SocketAddr>,
    /// Extra milliseconds per (light, element) pair: emulate a slow node in light ray
    /// tracing (fault tests kill such a node in the middle of its pairs).
    #[arg(long, default_value_t = 0)]
    slow_pair_ms: u64,
    /// Profile, token, TLS and log level: the flags every cluster process shares.
    #[command(flatten)]
    cluster: magg_plumbing::flags::ClusterArgs,
    /// Instead of serving: probe a process.
    #[command(subcommand)]
    command: Option<magg_plumbing::flags::ProbeCommand>,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let (cluster, command) = (args.cluster.clone(), args.command.clone());
    magg_plumbing::lifecycle::main("magg-node", &cluster, &command, || run(args))
}

fn run(args: Args) -> anyhow::Result<()> {
    if args.threads == 0 || args.threads > 1024 {
        anyhow::bail!("--threads {}: must be 1..=1024", args.threads);
    }
    let token = magg_plumbing::auth::Token::parse(args.cluster.token).map_err(|e| anyhow::anyhow!("--token: {e}"))?;
    let mut cfg = magg_node::NodeConfig {
        host: args.host,
        threads: args.threads,
        cache_blocks: args.cache_blocks,
        name: args.name,
        backoff: magg_plumbing::retry::Backoff {
            deadline: Duration::from_secs(args.connect_timeout),
            ..Default::default()
        },
        row_delay: Duration::from_millis(args.slow_row_ms),
        profile: match &args.cluster.profile {
            Some(p) => Some(magg_throttle::Profile::named(p)?.name),
            None => None,
        },
        pair_delay: Duration::from_millis(args.slow_pair_ms),
        token,
        // A node process of its own runs where the kernel puts it: its machine may run
        // other nodes and other work.
        cores: Vec::new(),
        // Its host and forks are other processes: sockets.
        links: magg_plumbing::transport::InProcess::none(),
    };
    // A node keeps no state of its own: on Ctrl-C or SIGTERM it just exits (cleanly: in
    // a container it is PID 1, which has no default action for SIGTERM).
    magg_plumbing::lifecycle::exit_on_signal("magg-node", 0).context("watching for signals")?;
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the runtime")?;
    if let Some(addr) = args.health_listen {
        let listener = rt
            .block_on(tokio::net::TcpListener::bind(addr))
            .with_context(|| format!("--health-listen {addr}: cannot listen"))?;
        rt.spawn(async move {
            if let Err(e) = magg_plumbing::health::serve_health(listener, std::future::pending()).await {
                tracing::warn!("health service on {addr} stopped: {e}");
            }
        });
    }
    // A long-lived node (--repeat) expects its host to come and go: connection attempts
    // are not warnings, and only a node that has never found a host says so (once). After
    // a render the host exits: its absence is the normal wait for the next one.
    cfg.backoff.expect_absence = args.repeat;
    let mut quiet_absence = false;
    loop {
        match magg_node::run_with_runtime(rt.handle().clone(), &cfg) {
            Ok(s) => {
                tracing::info!("node {} done: {} pairs, {} subscreens", s.node, s.pairs, s.tiles);
                quiet_absence = true;
            }
            // Between renders, a host that is not there yet (or is just ending) is normal.
            Err(e) if args.repeat && e.came_after_the_render() => {
                tracing::info!("no render yet: {e}");
                quiet_absence = true;
            }
            Err(e @ magg_node::NodeError::Connect { .. }) if args.repeat => {
                if quiet_absence {
                    tracing::info!("no host yet: {e}");
                } else {
                    tracing::warn!("no host yet: {e}; waiting on (--repeat)");
                    quiet_absence = true;
                }
            }
            Err(e) if args.repeat => tracing::warn!("render ended with an error: {e}"),
            Err(e) => return Err(e.into()),
        }
        if !args.repeat {
            return Ok(());
        }
        // The host that just finished refuses new registrations until it exits.
        std::thread::sleep(Duration::from_secs(1));
        tracing::info!("waiting for the next render from {}", cfg.host);
    }
}
