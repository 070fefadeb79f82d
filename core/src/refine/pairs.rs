//! The pilots' pairs of point lights, traced once and kept raw ([`PilotPairs`] while the
//! pilots run, [`KeptPairs`] for the render's light pass), in a table indexed by light
//! and element id: no hashing, and the table is split into [`SHARDS`] by element id so
//! that the node threads of a pilot seldom wait for one another.

use crate::blocks::BlockError;
use crate::lrt::{bin, trace_pair, trace_pair_raw, PairResult, RawDeposit, RawPair};
use crate::trace::TraceScratch;
use crate::view::SceneView;
use std::sync::{Arc, Mutex};

/// Parts of the table: element `e`'s pairs are in part `e % SHARDS`, at `e / SHARDS`.
const SHARDS: usize = 64;

/// One part of the table: by light, then by element id / [`SHARDS`].
type Shard = Vec<Vec<Option<Arc<RawPair>>>>;

/// Where pair (`light`, `element`) lies: its part, and its slot there.
fn slot(element: u32) -> (usize, usize) {
    (element as usize % SHARDS, element as usize / SHARDS)
}

fn get(shard: &Shard, light: u32, at: usize) -> Option<&Arc<RawPair>> {
    shard.get(light as usize)?.get(at)?.as_ref()
}

/// The pilots' pairs of point lights, traced once and kept raw: every level's pilot has
/// the same lights and, for every element not split since, the same element ids and
/// rays ([`crate::lrt::bin`] gives exactly the result a new trace would). A pair whose
/// deposits all fall on its own element keeps their sum (the same sum, in the same
/// order, as binning them would make), so the pairs of direct light carried by light
/// rays cost one entry each. Pairs of area lights are traced at every level.
pub(super) struct PilotPairs {
    shards: Vec<Mutex<Shard>>,
}

impl Default for PilotPairs {
    fn default() -> Self {
        PilotPairs { shards: (0..SHARDS).map(|_| Mutex::default()).collect() }
    }
}

impl PilotPairs {
    /// The pairs traced, read-only.
    pub(super) fn into_kept(self) -> KeptPairs {
        let shards: Vec<Shard> =
            self.shards.into_iter().map(|m| m.into_inner().unwrap_or_else(|e| e.into_inner())).collect();
        let len = shards.iter().flatten().flatten().filter(|s| s.is_some()).count();
        KeptPairs { shards, len }
    }

    /// The result of pair (`light`, `element`) on `view`'s scene: its kept raw deposits
    /// binned, traced (and kept) first if it was not yet.
    pub(super) fn trace(
        &self,
        view: &mut SceneView,
        scratch: &mut TraceScratch,
        light: u32,
        element: u32,
    ) -> Result<PairResult, BlockError> {
        if light as usize >= view.header.lights.len() {
            return trace_pair(view, scratch, light, element);
        }
        let (part, at) = slot(element);
        let lock = || self.shards[part].lock().unwrap_or_else(|e| e.into_inner());
        let kept = get(&lock(), light, at).cloned();
        let raw = match kept {
            Some(raw) => raw,
            None => {
                let raw = Arc::new(compact(trace_pair_raw(view, scratch, light, element)?));
                let mut shard = lock();
                if shard.len() <= light as usize {
                    shard.resize_with(light as usize + 1, Vec::new);
                }
                let lights = &mut shard[light as usize];
                if lights.len() <= at {
                    lights.resize(at + 1, None);
                }
                lights[at] = Some(raw.clone());
                raw
            }
        };
        bin(view, element, &raw)
    }
}

/// `raw` with its deposits summed into one when they all fall on the same element
/// itself, in generation order (as [`bin`] would sum them).
fn compact(raw: RawPair) -> RawPair {
    let Some(&RawDeposit::On(first, f0)) = raw.deposits.first() else { return raw };
    let mut sum = f0;
    for d in &raw.deposits[1..] {
        match *d {
            RawDeposit::On(e, f) if e == first => sum = sum.add(f),
            _ => return raw,
        }
    }
    RawPair { deposits: vec![RawDeposit::On(first, sum)], tally: raw.tally }
}

/// Refinement's pilot pairs of point lights, traced once and kept raw (see the module
/// doc of [`crate::refine`]), read-only: for the render's light pass when it carries
/// exactly the pilots' light. [`crate::lrt::bin`] of [`KeptPairs::raw`] gives a kept
/// pair's result on the render's scene, which is what tracing it there gives, bit for
/// bit (the pair's element is a leaf there, as it was when the pair was traced, and its
/// rays are the same).
pub struct KeptPairs {
    shards: Vec<Shard>,
    len: usize,
}

impl KeptPairs {
    /// Pairs kept.
    pub fn len(&self) -> usize {
        self.len
    }

    /// No pair kept.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The kept raw deposits of pair (`light`, `element`), `None` when it was not kept
    /// (a new element's pair, or an area light's): [`crate::lrt::bin`] gives its result
    /// on the render's scene.
    pub fn raw(&self, light: u32, element: u32) -> Option<&RawPair> {
        let (part, at) = slot(element);
        get(&self.shards[part], light, at).map(|raw| &**raw)
    }
}

impl std::fmt::Debug for KeptPairs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "KeptPairs({} pairs)", self.len)
    }
}

/// Where the prepared scene holds its [`KeptPairs`] until the first light pass takes
/// them ([`KeptSlot::take`]): the pairs are freed when that pass ends, not with the
/// scene. A later light pass of the same prepared scene traces every pair (the same
/// bits). Clones share the slot.
#[derive(Clone, Default)]
pub struct KeptSlot(Arc<Mutex<Option<Arc<KeptPairs>>>>);

impl KeptSlot {
    /// A slot holding `kept`.
    pub fn new(kept: Option<Arc<KeptPairs>>) -> KeptSlot {
        KeptSlot(Arc::new(Mutex::new(kept)))
    }

    /// The pairs, leaving the slot empty.
    pub fn take(&self) -> Option<Arc<KeptPairs>> {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).take()
    }

    /// Pairs held (0 once taken, or when none were kept).
    pub fn len(&self) -> usize {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).as_ref().map_or(0, |k| k.len())
    }

    /// No pair held.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

impl std::fmt::Debug for KeptSlot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "KeptSlot({} pairs)", self.len())
    }
}
