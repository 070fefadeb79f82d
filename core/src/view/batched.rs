//! Reads of many records at once through a bounded cache: what a stage of a kernel will
//! read next (a level of element records under a wave's hits, their vertex energies) is
//! known before it is read, so its blocks are fetched ahead in runs, a request per run
//! instead of a request per missed block ([`crate::blocks::BlockCache::prefetch`]).
//!
//! The records read, and every result computed from them, are those of reading the
//! items one by one: only when the blocks arrive changes. With every block resident
//! there is nothing to fetch and the items are read one by one.

use super::SceneView;
use crate::blocks::{BlockError, ElementRecord};
use crate::header::SceneHeader;
use crate::scene::MAX_REFINE_LEVELS;
use crate::subdivision::child_of;

/// No block (a slot of [`SceneView::in_prefetched_runs`]'s per-item blocks left unused).
pub const NO_BLOCK: u32 = u32::MAX;

/// A point on an element: the element, and the point's barycentric coordinates in it.
pub type ElementPoint = (u32, [f64; 3]);

/// The leaf element under a point ([`SceneView::leaf_element`]): its id, its record and
/// the point's coordinates in it.
pub type LeafPoint = (u32, ElementRecord, [f64; 3]);

/// The block of element record `id`, [`NO_BLOCK`] when there is no such element (its
/// read then reports the error).
pub fn element_block(header: &SceneHeader, id: u32) -> u32 {
    if id < header.counts.elements {
        header.layout.element_slot(id).0
    } else {
        NO_BLOCK
    }
}

/// The block of patch record `id`, [`NO_BLOCK`] when there is no such patch.
pub fn patch_block(header: &SceneHeader, id: u32) -> u32 {
    if id < header.counts.patches {
        header.layout.patch_slot(id).0
    } else {
        NO_BLOCK
    }
}

/// The block of vertex `id`'s energy record, [`NO_BLOCK`] when there is no such vertex.
pub fn vertex_block(header: &SceneHeader, id: u32) -> u32 {
    if id < header.counts.vertices {
        header.layout.vertex_slot(id).0
    } else {
        NO_BLOCK
    }
}

impl SceneView {
    /// Runs `each(view, ctx, i)` for `i` in `0..n`, in order. Through a bounded cache
    /// that fetches ahead ([`crate::blocks::BlockCache::prefetch_room`]) the items go in
    /// runs whose blocks (`blocks(ctx, i)`, up to three an item, [`NO_BLOCK`] for none)
    /// number at most that room, and each run's blocks are prefetched (one request)
    /// before its items are read.
    pub fn in_prefetched_runs<C>(
        &mut self,
        ctx: &mut C,
        n: usize,
        blocks: impl Fn(&C, usize) -> [u32; 3],
        mut each: impl FnMut(&mut SceneView, &mut C, usize) -> Result<(), BlockError>,
    ) -> Result<(), BlockError> {
        let Some(room) = self.cache.prefetch_room() else {
            for i in 0..n {
                each(self, ctx, i)?;
            }
            return Ok(());
        };
        let mut run: Vec<u32> = Vec::with_capacity(room + 3);
        let mut start = 0;
        // The blocks of the item before, all in the run (items in order of their
        // records mostly repeat them: nothing to look up).
        let mut last = [NO_BLOCK; 3];
        for i in 0..=n {
            let item = if i < n { blocks(ctx, i) } else { [NO_BLOCK; 3] };
            if i < n && item == last {
                continue;
            }
            last = item;
            let new = item.iter().filter(|&&b| b != NO_BLOCK && !run.contains(&b)).count();
            if i == n || (run.len() + new > room && i > start) {
                self.cache.prefetch(&run)?;
                for k in start..i {
                    each(self, ctx, k)?;
                }
                run.clear();
                start = i;
            }
            for b in item {
                if b != NO_BLOCK && !run.contains(&b) {
                    run.push(b);
                }
            }
        }
        Ok(())
    }

    /// The leaf elements under `points` (each an element of its patch's lattice and the
    /// point's coordinates in it), appended to `out` in their order: for each, what
    /// [`SceneView::element`] then [`SceneView::leaf_element`] give. The records are read
    /// a level of refinement at a time for all the points, each level's blocks
    /// prefetched in runs: points sorted by element read each block once a level.
    pub fn leaf_elements(&mut self, points: &[ElementPoint], out: &mut Vec<LeafPoint>) -> Result<(), BlockError> {
        if self.cache.prefetch_room().is_none() {
            for &(id, w) in points {
                let rec = self.element(id)?;
                out.push(self.leaf_element(id, rec, w)?);
            }
            return Ok(());
        }
        // Per point: the element whose record is read next, the coordinates in it, its
        // depth below the lattice, and its record once it is a leaf.
        struct Walk {
            at: Vec<(u32, [f64; 3], u32)>,
            leaf: Vec<Option<ElementRecord>>,
            todo: Vec<usize>,
            next: Vec<usize>,
        }
        let mut walk = Walk {
            at: points.iter().map(|&(id, w)| (id, w, 0)).collect(),
            leaf: vec![None; points.len()],
            todo: (0..points.len()).collect(),
            next: Vec::new(),
        };
        let header = self.header.clone();
        while !walk.todo.is_empty() {
            let n = walk.todo.len();
            self.in_prefetched_runs(
                &mut walk,
                n,
                |w, k| [element_block(&header, w.at[w.todo[k]].0), NO_BLOCK, NO_BLOCK],
                |view, w, k| {
                    let i = w.todo[k];
                    let (id, p, depth) = w.at[i];
                    let rec = view.element(id)?;
                    if rec.child == 0 {
                        w.leaf[i] = Some(rec);
                        return Ok(());
                    }
                    let (slot, inner) = child_of(p);
                    let Some(child) = rec.child.checked_add(slot as u32).filter(|_| depth < MAX_REFINE_LEVELS) else {
                        return Err(BlockError::Unavailable { id, reason: "corrupt element refinement".into() });
                    };
                    w.at[i] = (child, inner, depth + 1);
                    w.next.push(i);
                    Ok(())
                },
            )?;
            std::mem::swap(&mut walk.todo, &mut walk.next);
            walk.next.clear();
        }
        for (&(id, w, _), leaf) in walk.at.iter().zip(&walk.leaf) {
            let rec =
                leaf.ok_or_else(|| BlockError::Unavailable { id, reason: "element lookup did not end".into() })?;
            out.push((id, rec, w));
        }
        Ok(())
    }
}
