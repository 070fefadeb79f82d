//! The steps of [`Share`] as requests and replies: what a fork serves when the host
//! prepares a scene in shares on the forks, and what [`super::LocalShareSet`] serves in
//! this process. Both call [`serve`], so there is one preparation code path.
//!
//! A preparation is a *session*: its first request, [`Request::Begin`], hands a share its
//! patches and the split of space; the steps follow in order; [`Request::End`] drops the
//! share. A request of another session, or for a share the server does not hold (it
//! restarted, or a later session replaced this one), is [`StepError::Unknown`]: the host
//! takes the share for lost and prepares again. A request the share cannot take (a step
//! out of order, an index out of range) is [`StepError::Bad`]; nothing a request holds
//! makes the server panic.

use super::share::{IdQuery, PatchCounts, Share, SharePatch, ShareVertices};
use super::space::SpaceSplit;
use super::weld::{WeldAnswer, WeldPoint};
use magg_core::blocks::bvh::{BvhChild, BvhNode};
use magg_core::blocks::{BlockLayout, BLOCK_SIZE, NO_BACK};
use magg_core::prepared::ElementInfo;
use magg_core::subdivision::{element_count, lattice_count};
use std::collections::BTreeMap;

/// A step asked of one share.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub enum Request {
    /// Step 0: the share's patches (ascending ids) and the split of space; more Begins
    /// of the same session hand it more patches (ascending after the last).
    Begin {
        /// The split: its share count and each point's home.
        split: SpaceSplit,
        /// The share's patches.
        patches: Vec<SharePatch>,
    },
    /// Step 1 ([`Share::lattice`]).
    Lattice,
    /// Step 2 ([`Share::resolve`]): the points whose home this share is.
    Resolve(Vec<WeldPoint>),
    /// Step 3 ([`Share::settle`]): the homes' answers about its points.
    Settle(Vec<WeldAnswer>),
    /// Step 4 ([`Share::number`]): each own patch's (front, back) base.
    Number(Vec<(u32, u32)>),
    /// Step 5 ([`Share::answer`]): per asking share, the ids it asks of this one.
    Answer(Vec<Vec<IdQuery>>),
    /// Step 6 ([`Share::elements`]): per share, its answers to this one's questions.
    Elements(Vec<Vec<u32>>),
    /// The BVH over the share's patches, every box padded by `pad`.
    Subtree {
        /// The padding.
        pad: f64,
    },
    /// The share's records, written where `layout` puts them.
    Pack {
        /// The scene's block layout.
        layout: BlockLayout,
    },
    /// The share is done: its server drops it.
    End,
}

/// What a share answers.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Reply {
    /// Begin and End.
    Done,
    /// Lattice: its boundary points, one list per home share.
    Points(Vec<Vec<WeldPoint>>),
    /// Resolve: the answers for other shares, one list per share.
    Answers(Vec<Vec<WeldAnswer>>),
    /// Settle: each own patch's counts.
    Counts(Vec<PatchCounts>),
    /// Number: the questions for each share.
    Asks(Vec<Vec<IdQuery>>),
    /// Answer: the ids asked, per asking share.
    Ids(Vec<Vec<u32>>),
    /// Elements: its elements (id, element) and its vertices (id, position).
    Made {
        /// Elements by id.
        elements: Vec<(u32, ElementInfo)>,
        /// Vertices by id.
        vertices: ShareVertices,
    },
    /// Subtree: the share's tree.
    Subtree(WireSubTree),
    /// Pack: the blocks it wrote records into (id, the block's bytes), ascending ids.
    Blocks(Vec<(u32, Vec<u8>)>),
}

/// A share's BVH ([`crate::bvh::SubTree`]) as it travels.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct WireSubTree {
    /// Node records.
    pub nodes: Vec<BvhNode>,
    /// Leaf triangle blocks, [`BLOCK_SIZE`] bytes each.
    pub triangle_blocks: Vec<Vec<u8>>,
    /// Leaf triangle records.
    pub triangles: u32,
    /// The tree as a child of a node.
    pub root: BvhChild,
    /// Primitive binnings made.
    pub binnings: u64,
}

impl WireSubTree {
    /// The wire form of `t`.
    pub fn from_tree(t: crate::bvh::SubTree) -> WireSubTree {
        WireSubTree {
            nodes: t.nodes,
            triangle_blocks: t.triangle_blocks.into_iter().map(|b| b.to_vec()).collect(),
            triangles: t.triangles,
            root: t.root,
            binnings: t.binnings,
        }
    }

    /// The tree again, `None` if a block is not [`BLOCK_SIZE`] bytes.
    pub fn into_tree(self) -> Option<crate::bvh::SubTree> {
        let blocks: Option<Vec<_>> = self.triangle_blocks.into_iter().map(|b| block(&b)).collect();
        Some(crate::bvh::SubTree {
            nodes: self.nodes,
            triangle_blocks: blocks?,
            triangles: self.triangles,
            root: self.root,
            binnings: self.binnings,
        })
    }
}

/// `bytes` as a block, `None` unless [`BLOCK_SIZE`] long.
pub fn block(bytes: &[u8]) -> Option<Box<magg_core::blocks::Block>> {
    let b: &magg_core::blocks::Block = bytes.try_into().ok()?;
    Some(Box::new(*b))
}

/// Why a share could not take a step.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum StepError {
    /// The server holds no such share in this session (it restarted, or a later session
    /// replaced it): the host prepares again.
    #[error("share {share} of session {session} is not held here (restarted or replaced)")]
    Unknown {
        /// The session asked for.
        session: u64,
        /// The share asked for.
        share: u32,
    },
    /// The request cannot be taken.
    #[error("share {share}: {why}")]
    Bad {
        /// The share asked for.
        share: u32,
        /// What is wrong.
        why: String,
    },
}

/// The shares a server holds, of one session.
#[derive(Default)]
pub struct Serving {
    session: u64,
    shares: BTreeMap<u32, Held>,
}

/// A share and the step it is at.
struct Held {
    share: Share,
    split: SpaceSplit,
    /// The next step it takes (1 after Begin, ... 7 after Elements).
    next: u8,
}

impl std::fmt::Debug for Serving {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Serving").field("session", &self.session).field("shares", &self.shares.len()).finish()
    }
}

impl Serving {
    /// Shares held now (of the current session).
    pub fn held(&self) -> usize {
        self.shares.len()
    }
}

/// Takes `request` for share `share` of session `session`.
pub fn serve(state: &mut Serving, session: u64, share: u32, request: Request) -> Result<Reply, StepError> {
    let bad = |why: String| StepError::Bad { share, why };
    if let Request::Begin { split, patches } = request {
        check_begin(share, &split, &patches).map_err(bad)?;
        if state.session != session {
            // A new preparation replaces whatever an older one left.
            *state = Serving { session, shares: BTreeMap::new() };
        }
        match state.shares.get_mut(&share) {
            // A share's patches come in several Begins when they are many.
            Some(held) if held.next == 1 && held.split == split => {
                let last = held.share.patches().last().map(|p| p.id);
                if patches.first().is_some_and(|p| last.is_some_and(|l| p.id <= l)) {
                    return Err(bad("patch ids not ascending across Begins".into()));
                }
                held.share.extend(patches);
            }
            Some(_) => return Err(bad("Begin after the share's first step".into())),
            None => {
                state.shares.insert(share, Held { share: Share::new(share, patches), split, next: 1 });
            }
        }
        return Ok(Reply::Done);
    }
    let unknown = StepError::Unknown { session, share };
    if state.session != session {
        return Err(unknown);
    }
    if let Request::End = request {
        state.shares.remove(&share);
        return Ok(Reply::Done);
    }
    let held = state.shares.get_mut(&share).ok_or(unknown)?;
    let shares = held.split.shares();
    // Steps 1 to 6 in order; the tree and the records once the elements are made.
    let (step, next) = match &request {
        Request::Lattice => (1, 2),
        Request::Resolve(_) => (2, 3),
        Request::Settle(_) => (3, 4),
        Request::Number(_) => (4, 5),
        Request::Answer(_) => (5, 6),
        Request::Elements(_) => (6, 7),
        _ => (7, 7),
    };
    if held.next != step {
        return Err(bad(format!("step {step} asked at step {}", held.next)));
    }
    held.next = next;
    let s = &mut held.share;
    Ok(match request {
        Request::Lattice => Reply::Points(s.lattice(&held.split)),
        Request::Resolve(points) => {
            if let Some(p) = points.iter().find(|p| p.share as usize >= shares) {
                return Err(bad(format!("a point of share {} of {shares}", p.share)));
            }
            Reply::Answers(s.resolve(shares, points))
        }
        Request::Settle(answers) => {
            let out = |a: &WeldAnswer| {
                a.root_share as usize >= shares || a.back_owner.is_some_and(|(_, o)| o as usize >= shares)
            };
            if answers.iter().any(out) {
                return Err(bad(format!("an answer names a share past {shares}")));
            }
            Reply::Counts(s.settle(answers))
        }
        Request::Number(bases) => {
            if bases.len() != s.patches().len() {
                return Err(bad(format!("{} bases for {} patches", bases.len(), s.patches().len())));
            }
            Reply::Asks(s.number(shares, &bases))
        }
        Request::Answer(asked) => Reply::Ids(asked.iter().map(|q| s.answer(q)).collect()),
        Request::Elements(answers) => {
            let vertices = s.elements(answers);
            Reply::Made { elements: s.made().map(|(id, e)| (id, *e)).collect(), vertices }
        }
        Request::Subtree { pad } => {
            let corners: Vec<(u32, [glam::DVec3; 3])> = s.patches().iter().map(|p| (p.id, p.v)).collect();
            Reply::Subtree(WireSubTree::from_tree(crate::bvh::build_subtree(&corners, pad)))
        }
        Request::Pack { layout } => {
            if !layout_holds(&layout, s) {
                return Err(bad("the layout does not hold the share's records".into()));
            }
            Reply::Blocks(s.pack(&layout).into_iter().map(|(id, b)| (id, b.to_vec())).collect())
        }
        Request::Begin { .. } | Request::End => unreachable!("taken above"),
    })
}

/// Most lattice points one server prepares (the host refuses scenes past this anyway).
const MAX_POINTS: u64 = u32::MAX as u64 / 2;

/// Whether a Begin can be taken: the share in the split, ascending patch ids, element
/// ids that fit, a lattice of bounded size.
fn check_begin(share: u32, split: &SpaceSplit, patches: &[SharePatch]) -> Result<(), String> {
    if share as usize >= split.shares() {
        return Err(format!("share {share} of a split into {}", split.shares()));
    }
    if !patches.windows(2).all(|w| w[0].id < w[1].id) {
        return Err("patch ids not ascending".into());
    }
    let mut points = 0u64;
    for p in patches {
        if p.n == 0 || p.n > 1 << 15 {
            return Err(format!("patch {}: {} subdivisions", p.id, p.n));
        }
        let elements = element_count(p.n);
        let fits = |first: u32| first as u64 + elements <= u32::MAX as u64;
        if !fits(p.first_element) || (p.back_element != NO_BACK && !fits(p.back_element)) {
            return Err(format!("patch {}: element ids past 2^32", p.id));
        }
        points += lattice_count(p.n);
    }
    if points > MAX_POINTS {
        return Err(format!("{points} lattice points"));
    }
    Ok(())
}

/// Whether every record of `s` falls in `layout`'s blocks.
fn layout_holds(layout: &BlockLayout, s: &Share) -> bool {
    let patches = s.patches();
    let last_patch = patches.last().map_or(0, |p| p.id);
    let last_element = s.made().map(|(id, _)| id).max().unwrap_or(0);
    let last_shading = patches.iter().map(|p| p.shading).filter(|&x| x != magg_core::blocks::NO_SHADING).max();
    let inside = |(b, off): (u32, usize)| b < layout.total && off < BLOCK_SIZE;
    // Bases below 2^31 keep the slots' sums from wrapping.
    let bases = [layout.patch_base, layout.shading_base, layout.element_base];
    layout.total < 1 << 31
        && bases.iter().all(|&b| b <= layout.total)
        && inside(layout.patch_slot(last_patch))
        && inside(layout.element_slot(last_element))
        && last_shading.is_none_or(|x| inside(layout.shading_slot(x)))
}
