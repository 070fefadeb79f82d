//! The fork's emulated hardware (the throttling layer of docs/ARCHITECTURE.md): its processor,
//! which serves one request at a time, the DMA engine of its GPU card, and its share of
//! the one usable G-bus.
//!
//! Under the `native` profile nothing here costs anything: the profile is `None` and
//! every method returns at once. Under a throttled profile (sent by the host with
//! `LoadShard`) each request pays the fork's service time, each block reply pays the DMA
//! engine, and each fork-to-fork transfer books the G-bus. The G-bus is shared by every
//! fork of the cluster: in one process the forks share one [`Resource`]; across
//! processes fork 0 arbitrates, and the others book through its `ReserveGbus` RPC.

use crate::locks::{read, write};
use crate::peers::Peers;
use magg_throttle::{Path, Profile, Resource};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, RwLock};
use std::time::{Duration, Instant};

/// A fork's processor, DMA engine and G-bus access.
#[derive(Debug)]
pub struct ForkHardware {
    profile: RwLock<Option<Profile>>,
    service: Resource,
    dma: Resource,
    /// This process's G-bus: the cluster's when shared in-process or when this is fork 0.
    gbus: Arc<Resource>,
    /// True when every fork of the cluster uses `gbus` directly (one process).
    gbus_shared: bool,
    /// G-bus time booked by this fork, real nanoseconds.
    gbus_booked_ns: AtomicU64,
    /// The profile this fork was started with (`--profile`): the host's must match.
    pinned: Option<String>,
}

impl Default for ForkHardware {
    fn default() -> Self {
        ForkHardware::new(Arc::new(Resource::new()), false)
    }
}

impl ForkHardware {
    /// Hardware whose G-bus is `gbus`; `shared` says every fork of the cluster books that
    /// same resource (forks in one process).
    pub fn new(gbus: Arc<Resource>, shared: bool) -> ForkHardware {
        ForkHardware {
            profile: RwLock::new(None),
            service: Resource::new(),
            dma: Resource::new(),
            gbus,
            gbus_shared: shared,
            gbus_booked_ns: AtomicU64::new(0),
            pinned: None,
        }
    }

    /// Refuses shards whose profile is not `name` (a fork started with `--profile`).
    pub fn pinned_to(mut self, name: &str) -> ForkHardware {
        self.pinned = Some(name.to_string());
        self
    }

    /// Checks the host's profile against the one this fork was started with.
    pub fn check_profile(&self, host: Option<&Profile>) -> Result<(), crate::ForkError> {
        let host_name = host.map_or("native", |p| p.name.as_str());
        match &self.pinned {
            Some(mine) if mine != host_name => {
                Err(crate::ForkError::ProfileMismatch { host: host_name.to_string(), fork: mine.clone() })
            }
            _ => Ok(()),
        }
    }

    /// Puts `profile` in force (`None` or native: nothing throttled).
    pub fn set_profile(&self, profile: Option<Profile>) {
        *write(&self.profile) = profile.filter(|p| !p.is_native());
        self.service.reset_counts();
        self.dma.reset_counts();
        self.gbus_booked_ns.store(0, Ordering::Relaxed);
    }

    fn profile(&self) -> Option<Profile> {
        read(&self.profile).clone()
    }

    /// The fork processor serves one request carrying `deposits` element deposits.
    pub async fn serve(&self, deposits: usize) {
        if let Some(p) = self.profile() {
            if let Some(f) = p.fork {
                let us = f.request_us + f.deposit_us * deposits as f64;
                self.service.pay(p.dilate(Duration::from_secs_f64(us * 1e-6))).await;
            }
        }
    }

    /// The DMA engine sends `bytes` to a node.
    pub async fn dma(&self, bytes: usize) {
        if let Some(p) = self.profile() {
            self.dma.pay(p.real_cost(Path::Dma, bytes as u64)).await;
        }
    }

    /// Books the G-bus for a transfer of `bytes` and waits until it has ended: on the
    /// shared resource, or through fork 0's arbiter.
    pub async fn gbus(&self, me: u32, peers: &Peers, bytes: usize) {
        let Some(p) = self.profile() else { return };
        let cost = p.real_cost(Path::Gbus, bytes as u64);
        if cost.is_zero() {
            return;
        }
        self.gbus_booked_ns.fetch_add(cost.as_nanos() as u64, Ordering::Relaxed);
        if self.gbus_shared || me == 0 {
            self.gbus.pay(cost).await;
            return;
        }
        match peers.reserve_gbus(cost).await {
            Ok(wait) => magg_throttle::wait(Instant::now() + wait).await,
            Err(e) => {
                // The arbiter is out of reach: pay the transfer alone rather than stall.
                tracing::warn!("G-bus arbiter (fork 0) unreachable, paying the G-bus locally: {e}");
                self.gbus.pay(cost).await;
            }
        }
    }

    /// The arbiter's side of `ReserveGbus`: books `cost` and says how long to wait.
    pub fn reserve_gbus(&self, cost: Duration) -> Duration {
        self.gbus.reserve(cost).saturating_duration_since(Instant::now())
    }

    /// Modelled seconds the processor, the DMA engine and this fork's G-bus bookings
    /// were busy.
    pub fn busy_s(&self) -> (f64, f64, f64) {
        let d = self.profile().map_or(1.0, |p| p.dilation);
        let gbus = Duration::from_nanos(self.gbus_booked_ns.load(Ordering::Relaxed));
        (self.service.busy().as_secs_f64() / d, self.dma.busy().as_secs_f64() / d, gbus.as_secs_f64() / d)
    }
}
