//! The node's side of the throttling layer (docs/ARCHITECTURE.md, the throttling layer): its serial link to the fork
//! and host, and its processor, priced by the hardware profile the host sent.
//!
//! Every message a node sends or receives pays for its encoded bytes on the link, one
//! resource per direction; block replies arrive over the DMA bus instead, which their
//! fork pays. Computation pays the cost model's price for the operations the kernels
//! counted. Under the `native` profile there is no [`NodePace`] at all: the layer is out
//! of the path.

use magg_core::view::OpCounters;
use magg_throttle::{CpuCost, Path, Profile, Resource};
use std::time::Duration;

/// A node's emulated link and the cost model of its processors.
#[derive(Debug)]
pub struct NodePace {
    profile: Profile,
    cpu: Option<CpuCost>,
    link_out: Resource,
    link_in: Resource,
}

impl NodePace {
    /// The pace for `profile`, or `None` when it throttles nothing.
    pub fn new(profile: Profile) -> Option<NodePace> {
        if profile.is_native() {
            return None;
        }
        let cpu = profile.cpu.map(CpuCost);
        Some(NodePace { profile, cpu, link_out: Resource::new(), link_in: Resource::new() })
    }

    /// The profile in force.
    pub fn profile(&self) -> &Profile {
        &self.profile
    }

    fn link(&self, bytes: usize) -> Duration {
        self.profile.real_cost(Path::Link, bytes as u64)
    }

    /// Sends `bytes` on the link, blocking the thread while the link is busy.
    pub fn send_blocking(&self, bytes: usize) {
        self.link_out.pay_blocking(self.link(bytes));
    }

    /// Receives `bytes` on the link, blocking the thread while the link is busy.
    pub fn recv_blocking(&self, bytes: usize) {
        self.link_in.pay_blocking(self.link(bytes));
    }

    /// Sends `bytes` on the link from an async task.
    pub async fn send(&self, bytes: usize) {
        self.link_out.pay(self.link(bytes)).await;
    }

    /// Receives `bytes` on the link from an async task.
    pub async fn recv(&self, bytes: usize) {
        self.link_in.pay(self.link(bytes)).await;
    }

    /// Modelled time of the operations in `ops` on one processor.
    pub fn compute_cost(&self, ops: &OpCounters) -> Duration {
        self.cpu.map_or(Duration::ZERO, |c| c.of(ops))
    }

    /// Modelled seconds the link was busy, both directions.
    pub fn link_busy_s(&self) -> f64 {
        (self.link_out.busy() + self.link_in.busy()).as_secs_f64() / self.profile.dilation
    }
}

/// One worker's processor: pays, in real time, the modelled cost of the operations it
/// did since it last paid.
#[derive(Debug, Default)]
pub struct Processor {
    cpu: Resource,
    paid: OpCounters,
}

impl Processor {
    /// Pays for the operations counted in `now` beyond those already paid for, blocking
    /// the thread while the processor is "busy".
    pub fn pay(&mut self, pace: &NodePace, now: OpCounters) {
        let delta = now.since(self.paid);
        self.paid = now;
        self.cpu.pay_blocking(pace.profile.dilate(pace.compute_cost(&delta)));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn native_profile_has_no_pace() {
        assert!(NodePace::new(Profile::native()).is_none());
        assert!(NodePace::new(Profile::named("magg1993").unwrap()).is_some());
    }

    #[test]
    fn processor_pays_only_new_operations() {
        let pace = NodePace::new(Profile::named("magg1993").unwrap().with_dilation(1e-6)).unwrap();
        let mut cpu = Processor::default();
        let ops = OpCounters { grid_steps: 1000, ..Default::default() };
        cpu.pay(&pace, ops);
        let first = cpu.cpu.busy();
        cpu.pay(&pace, ops);
        assert_eq!(cpu.cpu.busy(), first, "the same counts were paid twice");
        assert!(first > Duration::ZERO);
    }
}
