//! # magg-fork: the fork processor of magg
//!
//! A fork (the paper's FP, §4.2–4.4) holds one shard of the scene's 2 KB blocks (block
//! `b` on fork `b mod F`), serves blocks to its nodes (the DMA path) and fetches the ones
//! it does not own from their fork on the node's behalf (the G-bus path), hands out the
//! (light, element) pairs of the elements it owns and, when its queue runs dry, takes
//! unassigned pairs from the other forks; and it accumulates, exactly once per pair, the
//! fixed-point energy that nodes deposit on its elements.
//!
//! Rules the callers follow:
//! - element `e` belongs to the fork holding its element block,
//!   `layout.element_slot(e).0 % F`; its deposits go there;
//! - a node sends all of one pair's deposits for one fork in one `Deposit` request (a
//!   batch's pairs as packed arrays, [`magg_proto::deposits`]; a repeated pair id is
//!   acknowledged and ignored), and sets `complete` on the one it sends to the owner of
//!   the pairs' elements (`pair % elements`), with the `epoch` of the `TakePairs` reply
//!   that handed them out (a completion from before a `Replay` is not counted); that
//!   request may carry the node's next `TakePairs`, answered once the deposits are in
//!   (with `own_only`, from this fork's own queue alone: the node asks the fork that
//!   lent its home fork the pairs, and its home fork again when the answer is empty);
//! - pairs are leased: a node that has not asked a fork for pairs for the lease
//!   (`LoadShard.lease_ms`) loses its pairs there to the queue;
//! - every call carries the cluster token when one is set ([`magg_plumbing::auth`]);
//! - clients of a fork use the cluster's message size limits ([`connect`] does,
//!   [`magg_plumbing::net`]): a `GetBlocks` reply of 4096 blocks is 8 MiB.
//!
//! ```no_run
//! # async fn f() -> Result<(), Box<dyn std::error::Error>> {
//! let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await?;
//! let addr = listener.local_addr()?;
//! let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
//! let token = magg_plumbing::auth::Token::default(); // none: fine on 127.0.0.1
//! let server = tokio::spawn(magg_fork::serve(listener, token.clone(), async { stopped.await.ok(); }));
//! let mut fork = magg_fork::connect(&addr.to_string(), &magg_fork::PeerAccess::with_token(token)).await?;
//! // fork.load_shard(...), fork.get_blocks(...), fork.take_pairs(...), ...
//! stop.send(()).ok();
//! server.await??;
//! # Ok(()) }
//! ```

pub mod bits;
pub mod error;
pub mod hardware;
mod locks;
pub mod state;
pub use state::pairs;
pub mod peers;
pub mod prepare;
pub mod server;
pub mod service;
pub mod shard;

pub use error::ForkError;
pub use hardware::ForkHardware;
pub use peers::{connect, PeerAccess};
pub use server::{fork_server, serve, serve_service};
pub use service::ForkService;
pub use shard::Shard;
