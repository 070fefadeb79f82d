//! `magg-fork`: a fork process of a magg cluster. It waits for the host to load a shard,
//! then serves blocks, pairs and energy to nodes and to the other forks.
//!
//! ```text
//! magg-fork --listen 0.0.0.0:7100 -v
//! magg-fork probe 127.0.0.1:7100     # exit 0 when that fork's health service says SERVING
//! ```

use anyhow::Context;
use clap::Parser;
use std::net::SocketAddr;
use std::process::ExitCode;

/// A fork of a magg cluster: holds a shard of the scene's 2 KB blocks, serves them to
/// nodes (DMA path) and other forks (G-bus path), hands out (light, element) pairs and
/// accumulates the energy deposited on its elements. The host loads the shard
/// (`magg-host render --forks-at ADDR,...`); until then every request but LoadShard is
/// refused. Stops on Ctrl-C or SIGTERM, finishing the requests in flight.
#[derive(Debug, Parser)]
#[command(name = "magg-fork", version, args_conflicts_with_subcommands = true)]
struct Args {
    /// Address to listen on for gRPC (HOST:PORT; port 0 picks a free port). The fork's
    /// services and the standard gRPC health service are served there.
    #[arg(long, default_value = "127.0.0.1:7100", env = "MAGG_FORK_LISTEN")]
    listen: SocketAddr,
    /// Memory the pair bookkeeping of one shard may take, in MiB: a `LoadShard` that
    /// would need more (many lights times many elements) is refused with
    /// RESOURCE_EXHAUSTED and the estimate, before anything is allocated.
    #[arg(long, default_value_t = magg_fork::shard::DEFAULT_MAX_MEMORY_MB, value_name = "MB")]
    max_memory_mb: u64,
    /// Waits this long before each step of preparing the scene (tests strike a fork in
    /// the middle of preparation with it).
    #[arg(long, default_value_t = 0, value_name = "MS", hide = true)]
    slow_step_ms: u64,
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
    magg_plumbing::lifecycle::main("magg-fork", &cluster, &command, || run(args))
}

fn run(args: Args) -> anyhow::Result<()> {
    let token = magg_plumbing::auth::Token::parse(args.cluster.token).context("--token")?;
    if let Some(w) = magg_plumbing::auth::exposure_warning(args.listen, &token) {
        tracing::warn!("{w}");
    }
    let runtime = tokio::runtime::Builder::new_multi_thread().enable_all().build().context("starting the runtime")?;
    runtime.block_on(async {
        let listener = tokio::net::TcpListener::bind(args.listen)
            .await
            .with_context(|| format!("cannot listen on {}", args.listen))?;
        let local = listener.local_addr().context("reading the bound address")?;
        // Not a log line: whoever started the fork (port 0 picks a free port) needs its
        // address at every log level.
        eprintln!("magg-fork: fork listening on {local}");
        let mut hw = magg_fork::ForkHardware::default();
        if let Some(p) = &args.cluster.profile {
            let profile = magg_throttle::Profile::named(p)?;
            hw = hw.pinned_to(&profile.name);
        }
        let service = magg_fork::ForkService::with_token(token.clone())
            .on_hardware(hw)
            .with_memory_limit(args.max_memory_mb)
            .with_slow_steps(std::time::Duration::from_millis(args.slow_step_ms));
        magg_fork::serve_service(service, token, listener, magg_plumbing::lifecycle::shutdown_signal())
            .await
            .context("serving")?;
        tracing::info!("fork stopped");
        Ok(())
    })
}
