//! Ray casting through the subspace grid: 3D-DDA traversal (Amanatides and Woo 1987).
//!
//! A hit found in one subspace may lie beyond it (the patch spans several subspaces);
//! it is kept as a candidate and only accepted once traversal has passed its distance,
//! so a nearer patch in a later subspace still wins.

use super::query::{Hit, Query, TraceScratch};
use crate::blocks::BlockError;
use crate::view::SceneView;

/// [`super::cast`] through the grid.
pub(super) fn cast(view: &mut SceneView, scratch: &mut TraceScratch, q: &Query) -> Result<Option<Hit>, BlockError> {
    let (ray, tmin, tmax, exclude) = (q.ray, q.tmin, q.tmax, q.exclude);
    let (o, d) = (ray.origin, ray.direction);
    let (gmin, gmax, dims, cs) = {
        let g = &view.header.grid;
        (g.min, g.max, g.dims, g.cell_size())
    };
    // Clip to the grid box.
    let (mut t0, mut t1) = (tmin.max(0.0), tmax);
    for a in 0..3 {
        if d[a] == 0.0 {
            if o[a] < gmin[a] || o[a] > gmax[a] {
                return Ok(None);
            }
            continue;
        }
        let inv = 1.0 / d[a];
        let (mut ta, mut tb) = ((gmin[a] - o[a]) * inv, (gmax[a] - o[a]) * inv);
        if ta > tb {
            std::mem::swap(&mut ta, &mut tb);
        }
        t0 = t0.max(ta);
        t1 = t1.min(tb);
    }
    if !(t0 <= t1) {
        return Ok(None);
    }
    let p = ray.at(t0);
    let mut cell = [0i64; 3];
    let mut step = [0i64; 3];
    let mut next_t = [f64::INFINITY; 3];
    let mut delta = [f64::INFINITY; 3];
    for a in 0..3 {
        let c = ((p[a] - gmin[a]) / cs[a]).floor();
        let c = if c.is_finite() { c.clamp(0.0, (dims[a] - 1) as f64) as i64 } else { 0 };
        cell[a] = c;
        if d[a] > 0.0 {
            step[a] = 1;
            next_t[a] = (gmin[a] + (c + 1) as f64 * cs[a] - o[a]) / d[a];
            delta[a] = cs[a] / d[a];
        } else if d[a] < 0.0 {
            step[a] = -1;
            next_t[a] = (gmin[a] + c as f64 * cs[a] - o[a]) / d[a];
            delta[a] = -cs[a] / d[a];
        }
    }
    scratch.reset();
    let mut best: Option<Hit> = None;
    let mut ids = std::mem::take(&mut scratch.ids);
    let result = loop {
        view.counters.grid_steps += 1;
        let idx = (cell[2] as usize * dims[1] as usize + cell[1] as usize) * dims[0] as usize + cell[0] as usize;
        if let Err(e) = view.subspace(idx, &mut ids) {
            break Err(e);
        }
        let limit = best.map_or(t1, |b| b.t);
        let mut failed = None;
        for &pid in &ids {
            if pid == exclude || scratch.seen(pid) {
                continue;
            }
            view.counters.patch_tests += 1;
            let rec = match view.patch(pid) {
                Ok(r) => r,
                Err(e) => {
                    failed = Some(e);
                    break;
                }
            };
            if q.test(&rec.v, pid, limit, &mut best) && q.any {
                break;
            }
        }
        if let Some(e) = failed {
            break Err(e);
        }
        if q.any && best.is_some() {
            break Ok(best);
        }
        let exit = next_t[0].min(next_t[1]).min(next_t[2]);
        if let Some(b) = best {
            if b.t <= exit {
                break Ok(best);
            }
        }
        if exit > t1 {
            break Ok(best);
        }
        let axis = if next_t[0] <= next_t[1] && next_t[0] <= next_t[2] {
            0
        } else if next_t[1] <= next_t[2] {
            1
        } else {
            2
        };
        cell[axis] += step[axis];
        if cell[axis] < 0 || cell[axis] >= dims[axis] as i64 {
            break Ok(best);
        }
        next_t[axis] += delta[axis];
    };
    scratch.ids = ids;
    result
}
