//! Refinement's pairs of point lights, traced once and kept raw ([`KeptPairs`]), in a
//! table indexed by light and element id: no hashing, and the table is split into
//! [`SHARDS`] by element id so that the threads tracing pairs seldom wait for one another.
//!
//! Refinement itself (choosing the elements to split, driving the pilot light passes)
//! is preparation's (`magg_prepare::refine`); the table lives here because the machines
//! and nodes that trace the pairs read and fill it.

use crate::blocks::BlockError;
use crate::lrt::{bin, bin_all, trace_pair, trace_pair_raw, trace_pairs_each, PairResult, RawDeposit, RawPair};
use crate::pair::Pair;
use crate::trace::TraceScratch;
use crate::view::SceneView;
use std::sync::{Arc, Mutex, MutexGuard};

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

/// Refinement's pairs of point lights, traced once and kept raw (see the module doc of
/// `magg_prepare::refine`).
///
/// While the pilots run, [`KeptPairs::trace`] gives a pair's result on the level's
/// scene, tracing (and keeping) it the first time only: every level's pilot has the same
/// lights and, for every element not split since, the same element ids and rays, so
/// [`crate::lrt::bin`] of the kept deposits is exactly what a new trace would give. A
/// pair whose deposits all fall on its own element keeps their sum (the same sum, in the
/// same order, as binning them would make), so the pairs of direct light carried by
/// light rays cost one entry each. Pairs of area lights are traced every time.
///
/// When the render's light pass carries exactly the pilots' light, it reads the kept
/// pairs ([`KeptPairs::raw`], through [`trace_pairs_kept`]): the pair's
/// element is a leaf there, as it was when the pair was traced, or split (the pair then
/// deposits nothing), so binning gives what tracing it there gives, bit for bit.
///
/// The pilots' workers share one table in a process (the embedded machine's threads,
/// the nodes of the host's process); a node of a process of its own keeps its own, with
/// the pairs it traced.
pub struct KeptPairs {
    shards: Vec<Mutex<Shard>>,
}

impl Default for KeptPairs {
    fn default() -> Self {
        KeptPairs { shards: (0..SHARDS).map(|_| Mutex::default()).collect() }
    }
}

impl KeptPairs {
    fn lock(&self, part: usize) -> MutexGuard<'_, Shard> {
        self.shards[part].lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The result of pair (`light`, `element`) on `view`'s scene: its kept raw deposits
    /// binned, traced (and kept) first if it was not yet.
    pub fn trace(
        &self,
        view: &mut SceneView,
        scratch: &mut TraceScratch,
        light: u32,
        element: u32,
    ) -> Result<PairResult, BlockError> {
        if light as usize >= view.header.lights.len() {
            return trace_pair(view, scratch, light, element);
        }
        let raw = self.kept_or_traced(view, scratch, light, element)?;
        bin(view, element, &raw)
    }

    /// The kept raw deposits of point light `light`'s pair with `element`, traced and
    /// kept first if it was not yet.
    fn kept_or_traced(
        &self,
        view: &mut SceneView,
        scratch: &mut TraceScratch,
        light: u32,
        element: u32,
    ) -> Result<Arc<RawPair>, BlockError> {
        if let Some(raw) = self.raw(light, element) {
            return Ok(raw);
        }
        let raw = Arc::new(compact(trace_pair_raw(view, scratch, light, element)?));
        let (part, at) = slot(element);
        let mut shard = self.lock(part);
        if shard.len() <= light as usize {
            shard.resize_with(light as usize + 1, Vec::new);
        }
        let lights = &mut shard[light as usize];
        if lights.len() <= at {
            lights.resize(at + 1, None);
        }
        lights[at] = Some(raw.clone());
        Ok(raw)
    }

    /// [`KeptPairs::trace`] of each of `pairs`, handed to `each` in
    /// order (a pilot level's batch): the same results. With a bounded cache the batch's
    /// raw deposits are gathered first and binned together ([`crate::lrt::bin_all`]:
    /// the elements' records and the leaves under the deposits read in runs of blocks
    /// fetched ahead, not pair by pair).
    pub fn trace_each(
        &self,
        view: &mut SceneView,
        scratch: &mut TraceScratch,
        pairs: &[Pair],
        mut each: impl FnMut(usize, PairResult),
    ) -> Result<(), BlockError> {
        if !view.cache_is_bounded() {
            for (i, &Pair { light, element }) in pairs.iter().enumerate() {
                each(i, self.trace(view, scratch, light, element)?);
            }
            return Ok(());
        }
        let points = view.header.lights.len();
        let mut raws = Vec::with_capacity(pairs.len());
        for &Pair { light, element } in pairs {
            let point = (light as usize) < points;
            raws.push(if point { Some(self.kept_or_traced(view, scratch, light, element)?) } else { None });
        }
        let results = bin_all(view, pairs, &raws)?;
        for (i, (result, &Pair { light, element })) in results.into_iter().zip(pairs).enumerate() {
            // (An area light's pair is traced, as `trace` does.)
            let result = match result {
                Some(r) => r,
                None => trace_pair(view, scratch, light, element)?,
            };
            each(i, result);
        }
        Ok(())
    }

    /// The kept raw deposits of pair (`light`, `element`), `None` when it was not kept
    /// (not traced yet, or an area light's): [`crate::lrt::bin`] gives its result on a
    /// later level's scene or the render's.
    pub fn raw(&self, light: u32, element: u32) -> Option<Arc<RawPair>> {
        let (part, at) = slot(element);
        get(&self.lock(part), light, at).cloned()
    }

    /// Pairs kept.
    pub fn len(&self) -> usize {
        (0..SHARDS).map(|p| self.lock(p).iter().flatten().filter(|s| s.is_some()).count()).sum()
    }

    /// No pair kept.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
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

impl std::fmt::Debug for KeptPairs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "KeptPairs({} pairs)", self.len())
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

/// [`trace_pairs_each`], where the pairs of `kept` (refinement's pilot pairs, see
/// [`KeptPairs`]) are binned from their kept deposits rather than traced:
/// the same results, handed to `each` in the batch's order.
pub fn trace_pairs_kept(
    view: &mut SceneView,
    scratch: &mut TraceScratch,
    pairs: &[Pair],
    kept: Option<&KeptPairs>,
    mut each: impl FnMut(usize, PairResult),
) -> Result<(), BlockError> {
    let Some(kept) = kept else {
        return trace_pairs_each(view, scratch, pairs, each);
    };
    let raws: Vec<Option<Arc<RawPair>>> = pairs.iter().map(|p| kept.raw(p.light, p.element)).collect();
    let mut kept_results = bin_all(view, pairs, &raws)?.into_iter();
    // Runs of pairs not kept are traced together (as trace_pairs_each would).
    let mut run = 0;
    for i in 0..=pairs.len() {
        let binned = kept_results.next().flatten();
        if binned.is_some() || i == pairs.len() {
            trace_pairs_each(view, scratch, &pairs[run..i], |k, r| each(run + k, r))?;
            run = i + 1;
        }
        if let Some(r) = binned {
            each(i, r);
        }
    }
    Ok(())
}
