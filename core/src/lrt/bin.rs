//! A pair's deposits binned to the leaf elements under them, in fixed point: the raw
//! deposits a pair's rays made (on its own element, or at local coordinates within a
//! lattice element that refinement may have split) become one sum per leaf element,
//! each summed in the order the rays made them. Refinement's kept pairs are binned
//! again at every level, and a batch's pairs together through a bounded cache.

use super::result::{PairResult, RawDeposit, RawPair};
use crate::blocks::BlockError;
use crate::color::Rgb;
use crate::fixed::{to_fixed, Fixed};
use crate::pair::Pair;
use crate::view::{element_block, SceneView, NO_BLOCK};

/// The result of pair (`_`, `element`) from its raw deposits, binned to the leaves of
/// `view`'s elements: exactly what [`trace_pair`] returns on `view`'s scene, as long as
/// the pair's rays are the same (its element is a leaf there, as when it was traced).
pub fn bin(view: &mut SceneView, element: u32, raw: &RawPair) -> Result<PairResult, BlockError> {
    if view.element(element)?.child != 0 {
        return Ok(PairResult::default());
    }
    bin_leaf(view, raw)
}

/// [`bin`] of a pair whose element is known to be a leaf of `view`'s elements.
fn bin_leaf(view: &mut SceneView, raw: &RawPair) -> Result<PairResult, BlockError> {
    let deposits = binned(view, &raw.deposits)?;
    Ok(PairResult { deposits: merged(deposits, view.header.energy_quantum), tally: raw.tally })
}

/// A pair's deposits binned to leaf elements, in their order. Through a bounded cache
/// the leaves are looked up in the order of their lattice elements, a level of
/// refinement at a time, so that each element block the lookups read is read once a
/// level, fetched ahead with the level's others, however the pair's rays spread their
/// deposits.
pub(super) fn binned(view: &mut SceneView, raw: &[RawDeposit]) -> Result<Vec<(u32, Rgb)>, BlockError> {
    let leaf = |view: &mut SceneView, d: &RawDeposit| match *d {
        RawDeposit::On(e, f) => Ok((e, f)),
        RawDeposit::Under { element, w, flux } => Ok((leaf_under(view, element, w)?, flux)),
    };
    if view.header.settings.refine == 0 || !view.cache_is_bounded() {
        // Every lattice element is a leaf (nothing to look up), or every block is at
        // hand (the order of the lookups costs nothing).
        return raw.iter().map(|d| leaf(view, d)).collect();
    }
    let mut deposits = vec![(0, Rgb::BLACK); raw.len()];
    // (lattice element, deposit index) as one key, with the deposit's coordinates.
    let mut under: Vec<(u64, [f64; 3])> = Vec::with_capacity(raw.len());
    for (i, d) in raw.iter().enumerate() {
        match *d {
            RawDeposit::On(e, f) => deposits[i] = (e, f),
            RawDeposit::Under { element, w, flux } => {
                deposits[i].1 = flux;
                under.push(((element as u64) << 32 | i as u64, w));
            }
        }
    }
    under.sort_unstable_by_key(|u| u.0);
    // The leaves under the deposits a level of refinement at a time, each level's
    // blocks fetched ahead (SceneView::leaf_elements).
    let points: Vec<(u32, [f64; 3])> = under.iter().map(|&(k, w)| ((k >> 32) as u32, w)).collect();
    let mut leaves = Vec::with_capacity(points.len());
    view.leaf_elements(&points, &mut leaves)?;
    for (&(k, _), &(leaf, _, _)) in under.iter().zip(&leaves) {
        deposits[k as u32 as usize].0 = leaf;
    }
    Ok(deposits)
}

/// The leaf element under local coordinates `w` of lattice element `element`.
fn leaf_under(view: &mut SceneView, element: u32, w: [f64; 3]) -> Result<u32, BlockError> {
    if view.header.settings.refine == 0 {
        return Ok(element);
    }
    // Refinement may have split it: the deposit goes to the leaf under the hit.
    let rec = view.element(element)?;
    Ok(view.leaf_element(element, rec, w)?.0)
}

/// Whether refinement split the element of each of `pairs` that `wanted` names (a kept
/// pair's element split since its pilot: the pair then deposits nothing, as [`bin`]
/// says); false for the others. The elements' records are read first, a run of blocks
/// fetched ahead at a time, rather than one at a time between binnings.
fn split_elements(
    view: &mut SceneView,
    pairs: &[Pair],
    wanted: impl Fn(usize) -> bool,
) -> Result<Vec<bool>, BlockError> {
    let header = view.header.clone();
    let mut split = vec![false; pairs.len()];
    view.in_prefetched_runs(
        &mut split,
        pairs.len(),
        |_, i| [if wanted(i) { element_block(&header, pairs[i].element) } else { NO_BLOCK }, NO_BLOCK, NO_BLOCK],
        |view, split, i| {
            if wanted(i) {
                split[i] = view.element(pairs[i].element)?.child != 0;
            }
            Ok(())
        },
    )?;
    Ok(split)
}

/// [`bin`] of each of `raws` (the raw deposits of `pairs[i]`, `None` for a pair that has
/// none: its answer is `None` too). The same results, but the elements' records are read
/// first and the leaves under all the pairs' deposits are looked up together (through a
/// bounded cache a level of refinement at a time, each level's blocks fetched ahead), not
/// pair by pair.
pub fn bin_all(
    view: &mut SceneView,
    pairs: &[Pair],
    raws: &[Option<std::sync::Arc<RawPair>>],
) -> Result<Vec<Option<PairResult>>, BlockError> {
    let split = split_elements(view, pairs, |i| raws[i].is_some())?;
    let mut all = Vec::new();
    for (raw, &split) in raws.iter().zip(&split) {
        if let Some(raw) = raw.as_deref().filter(|_| !split) {
            all.extend_from_slice(&raw.deposits);
        }
    }
    let mut leaves = binned(view, &all)?.into_iter();
    let quantum = view.header.energy_quantum;
    Ok(raws
        .iter()
        .zip(split)
        .map(|(raw, split)| {
            raw.as_deref().map(|raw| match split {
                true => PairResult::default(),
                false => PairResult {
                    deposits: merged(leaves.by_ref().take(raw.deposits.len()).collect(), quantum),
                    tally: raw.tally,
                },
            })
        })
        .collect())
}

/// One entry per element, sorted by element, each summed in generation order
/// (deterministic), in fixed point. (The order is that of a stable sort by element,
/// found by sorting the deposits' (element, index) keys, 8 bytes each, rather than
/// moving the 32-byte deposits themselves.)
pub(super) fn merged(deposits: Vec<(u32, Rgb)>, quantum: f64) -> Vec<(u32, Fixed)> {
    let mut keys: Vec<u64> = deposits.iter().enumerate().map(|(i, d)| (d.0 as u64) << 32 | i as u64).collect();
    keys.sort_unstable();
    let mut merged: Vec<(u32, Rgb)> = Vec::new();
    for k in keys {
        let (e, f) = deposits[(k & 0xffff_ffff) as usize];
        match merged.last_mut() {
            Some(last) if last.0 == e => last.1 = last.1.add(f),
            _ => merged.push((e, f)),
        }
    }
    merged.into_iter().map(|(e, f)| (e, to_fixed(f, quantum))).collect()
}
