//! `magg-node`: a node processor. Registers with the host and traces what it is given.
//!
//! ```text
//! magg-node --host 127.0.0.1:7000 --threads 2
//! ```

use clap::Parser;
use std::process::ExitCode;

/// A magg node processor: pulls (light, element) pairs and subscreens and traces them.
#[derive(Debug, Parser)]
#[command(name = "magg-node", version, about)]
struct Args {
    /// Host address.
    #[arg(long, default_value = "127.0.0.1:7000", env = "MAGG_HOST")]
    host: String,
    /// Worker threads (cores this node uses).
    #[arg(long, default_value_t = 1)]
    threads: u32,
    /// Cache size in 2 KB blocks, or "unlimited" (default: what the host says).
    #[arg(long)]
    cache_blocks: Option<String>,
    /// Name in the host's logs.
    #[arg(long, default_value = "node")]
    name: String,
    /// Give up connecting, or retrying a call to an unreachable peer (with backoff and
    /// jitter), after this many seconds.
    #[arg(long, default_value_t = 30)]
    connect_timeout: u64,
    /// Extra milliseconds per pixel row: emulate a slow node (to watch adaptive
    /// redivision move its unstarted rows to others).
    #[arg(long, default_value_t = 0)]
    slow_row_ms: u64,
    /// Extra milliseconds per (light, element) pair: emulate a slow node in light ray
    /// tracing (fault tests kill such a node in the middle of its pairs).
    #[arg(long, default_value_t = 0)]
    slow_pair_ms: u64,
    /// Cluster token presented on every call (the host's and forks' --token).
    #[arg(long, env = "MAGG_TOKEN", hide_env_values = true)]
    token: Option<String>,
    /// More log output.
    #[arg(short, long, action = clap::ArgAction::Count)]
    verbose: u8,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let level = match args.verbose {
        0 => "warn",
        1 => "info",
        _ => "debug",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(level));
    let _ = tracing_subscriber::fmt().with_env_filter(filter).with_writer(std::io::stderr).try_init();
    match run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("magg-node: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(args: Args) -> anyhow::Result<()> {
    if args.threads == 0 || args.threads > 1024 {
        anyhow::bail!("--threads {}: must be 1..=1024", args.threads);
    }
    let cache_blocks = match args.cache_blocks.as_deref() {
        None => None,
        Some(s) if s.eq_ignore_ascii_case("unlimited") => Some(None),
        Some(s) => match s.parse::<u64>() {
            Ok(n) if n > 0 => Some(Some(n)),
            _ => anyhow::bail!("--cache-blocks {s:?}: expected a positive block count or \"unlimited\""),
        },
    };
    let token = magg_proto::auth::Token::parse(args.token).map_err(|e| anyhow::anyhow!("--token: {e}"))?;
    let cfg = magg_node::NodeConfig {
        host: args.host,
        threads: args.threads,
        cache_blocks,
        name: args.name,
        backoff: magg_node::Backoff {
            deadline: std::time::Duration::from_secs(args.connect_timeout),
            ..Default::default()
        },
        row_delay: std::time::Duration::from_millis(args.slow_row_ms),
        pair_delay: std::time::Duration::from_millis(args.slow_pair_ms),
        token,
    };
    let s = magg_node::run(&cfg)?;
    tracing::info!("node {} done: {} pairs, {} subscreens", s.node, s.pairs, s.tiles);
    Ok(())
}
