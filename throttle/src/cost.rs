//! The deterministic cost model: operations counted by the kernels times the profile's
//! cost per operation. The same work always costs the same modelled time, whatever
//! machine runs it and however loaded it is.

use crate::profile::CpuSpec;
use magg_core::prepared::PrepareOps;
use magg_core::view::OpCounters;
use std::time::Duration;

/// Compute costs of a node processor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CpuCost(pub CpuSpec);

impl CpuCost {
    /// Modelled time of the operations in `ops` (before dilation).
    pub fn of(&self, ops: &OpCounters) -> Duration {
        let c = &self.0;
        let us = ops.grid_steps as f64 * c.grid_step_us
            + ops.patch_tests as f64 * c.patch_test_us
            + ops.light_rays as f64 * c.light_ray_us
            + ops.view_rays as f64 * c.view_ray_us
            + ops.shades as f64 * c.shade_us;
        Duration::from_secs_f64(us * 1e-6)
    }
}

/// Modelled time of preprocessing spread over `processors` processors (before
/// dilation). The work is divided evenly: each patch's subdivision and grid insertion is
/// independent, which is what lets the paper's fork processors share it.
pub fn preprocess_ops(spec: &CpuSpec, ops: &PrepareOps, processors: u32) -> Duration {
    let us = ops.box_tests as f64 * spec.box_test_us
        + ops.elements as f64 * spec.element_us
        + ops.vertices as f64 * spec.vertex_us
        + ops.blocks as f64 * spec.block_us;
    Duration::from_secs_f64(us * 1e-6 / processors.max(1) as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn costs_add_up_per_operation() {
        let spec = CpuSpec { grid_step_us: 5.0, patch_test_us: 30.0, shade_us: 25.0, ..Default::default() };
        let ops = OpCounters { grid_steps: 1000, patch_tests: 100, shades: 40, ..Default::default() };
        let t = CpuCost(spec).of(&ops).as_secs_f64();
        assert!((t - (5e-3 + 3e-3 + 1e-3)).abs() < 1e-12, "{t}");
    }

    #[test]
    fn preprocessing_divides_over_processors() {
        let spec =
            CpuSpec { box_test_us: 90.0, element_us: 30.0, vertex_us: 6.0, block_us: 100.0, ..Default::default() };
        let ops = PrepareOps { box_tests: 100, elements: 1000, vertices: 500, blocks: 10 };
        let one = preprocess_ops(&spec, &ops, 1).as_secs_f64();
        let five = preprocess_ops(&spec, &ops, 5).as_secs_f64();
        assert!((one - (9e-3 + 30e-3 + 3e-3 + 1e-3)).abs() < 1e-12);
        assert!((one / five - 5.0).abs() < 1e-9);
    }
}
