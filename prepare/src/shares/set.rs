//! Who runs the shares' steps: a [`ShareSet`] takes one request per share, runs them side
//! by side wherever its shares live, and gives back the replies. [`LocalShareSet`] holds
//! every share in this process; a cluster's set (in magg-cluster) sends each request to
//! the fork that holds the share. The driver functions here ([`weld`], [`subtrees`],
//! [`pack`], [`end`]) move the messages between the steps, the same for both.

use super::share::{PartialBlocks, PatchCounts};
use super::steps::{self, Reply, Request, Serving, StepError};
use super::{deliver, vertex_bases, SharePatch, SpaceSplit, UNMADE};
use glam::DVec3;
use magg_core::blocks::BlockLayout;
use magg_core::prepared::ElementInfo;
use rayon::prelude::*;
use std::sync::Mutex;

/// Why a step did not run on every share.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ShareError {
    /// A share's server was lost (unreachable, restarted, or it forgot the share): the
    /// preparation can run again.
    #[error("the fork at {at} was lost during preparation: {why}")]
    Lost {
        /// The server's address.
        at: String,
        /// What happened.
        why: String,
    },
    /// A share's server refused a step, or answered what no step answers.
    #[error("preparing share {share} failed: {why}")]
    Failed {
        /// The share.
        share: u32,
        /// What happened.
        why: String,
    },
}

/// Runs the shares' steps.
pub trait ShareSet: Send {
    /// A fresh session id for a preparation (every attempt has its own).
    fn begin_session(&mut self) -> u64;
    /// Runs each `(share, request)` of session `session` at its share, side by side: the
    /// replies in the order of the requests.
    fn run(&mut self, session: u64, requests: Vec<(u32, Request)>) -> Result<Vec<Reply>, ShareError>;
    /// Where the shares are, for messages ("in process", or the forks' addresses).
    fn place(&self) -> String;
}

/// Every share in this process, each served as a fork would serve it.
#[derive(Default)]
pub struct LocalShareSet {
    servings: Vec<Mutex<Serving>>,
    session: u64,
}

impl ShareSet for LocalShareSet {
    fn begin_session(&mut self) -> u64 {
        self.session += 1;
        self.session
    }

    fn run(&mut self, session: u64, requests: Vec<(u32, Request)>) -> Result<Vec<Reply>, ShareError> {
        let most = requests.iter().map(|r| r.0 as usize + 1).max().unwrap_or(0);
        while self.servings.len() < most {
            self.servings.push(Mutex::new(Serving::default()));
        }
        let servings = &self.servings;
        requests
            .into_par_iter()
            .map(|(share, request)| {
                let mut serving = servings[share as usize].lock().unwrap_or_else(|e| e.into_inner());
                steps::serve(&mut serving, session, share, request).map_err(|e| failed(share, e))
            })
            .collect()
    }

    fn place(&self) -> String {
        "in process".into()
    }
}

/// A step's error as the set reports it.
pub fn failed(share: u32, e: StepError) -> ShareError {
    ShareError::Failed { share, why: e.to_string() }
}

/// One request to each of `shares` shares, `make(share)`.
fn each(
    set: &mut dyn ShareSet,
    session: u64,
    shares: usize,
    mut make: impl FnMut(u32) -> Request,
) -> Result<Vec<Reply>, ShareError> {
    let requests: Vec<(u32, Request)> = (0..shares as u32).map(|s| (s, make(s))).collect();
    set.run(session, requests)
}

/// What no step answers at this point.
fn unexpected(share: usize, step: &str, got: &Reply) -> ShareError {
    let kind = format!("{got:?}");
    let kind = kind.split(['(', ' ', '{']).next().unwrap_or("?").to_string();
    ShareError::Failed { share: share as u32, why: format!("answered {kind} to {step}") }
}

/// Pulls `$variant`'s payload out of every reply, or fails naming the step.
macro_rules! take {
    ($replies:expr, $variant:ident, $step:literal) => {
        $replies
            .into_iter()
            .enumerate()
            .map(|(i, r)| match r {
                Reply::$variant(x) => Ok(x),
                other => Err(unexpected(i, $step, &other)),
            })
            .collect::<Result<Vec<_>, ShareError>>()
    };
}

/// Most patches in one Begin: about 230 MB at the largest (normals and texture
/// coordinates on every patch), under the cluster's 512 MB message limit.
pub const BEGIN_PATCHES: usize = 1 << 20;

/// Hands each share its patches (`by_share`, ascending ids each) and welds every
/// share's lattice points into vertices and elements (steps 0 to 6): every element
/// (`elements` of them) and welded vertex, by id.
pub fn weld(
    set: &mut dyn ShareSet,
    session: u64,
    split: &SpaceSplit,
    by_share: Vec<Vec<SharePatch>>,
    elements: usize,
) -> Result<(Vec<ElementInfo>, Vec<DVec3>), ShareError> {
    let n = by_share.len();
    // The patches in messages of at most BEGIN_PATCHES each (a message's limit).
    let rounds = by_share.iter().map(|p| p.len().div_ceil(BEGIN_PATCHES)).max().unwrap_or(0).max(1);
    let mut chunks: Vec<_> = by_share.into_iter().map(|p| p.into_iter()).collect();
    for _ in 0..rounds {
        let begun = each(set, session, n, |s| Request::Begin {
            split: split.clone(),
            patches: chunks[s as usize].by_ref().take(BEGIN_PATCHES).collect(),
        })?;
        for (i, r) in begun.iter().enumerate() {
            if *r != Reply::Done {
                return Err(unexpected(i, "Begin", r));
            }
        }
    }
    let points = deliver(take!(each(set, session, n, |_| Request::Lattice)?, Points, "Lattice")?, n);
    let mut points = points.into_iter();
    let answers = take!(
        each(set, session, n, |_| Request::Resolve(points.next().unwrap_or_default().into_iter().flatten().collect()))?,
        Answers,
        "Resolve"
    )?;
    let mut answers = deliver(answers, n).into_iter();
    let counts: Vec<Vec<PatchCounts>> = take!(
        each(set, session, n, |_| Request::Settle(answers.next().unwrap_or_default().into_iter().flatten().collect()))?,
        Counts,
        "Settle"
    )?;
    let (bases, _, vertices) = vertex_bases(&counts);
    let mut bases = bases.into_iter();
    let asks = take!(each(set, session, n, |_| Request::Number(bases.next().unwrap_or_default()))?, Asks, "Number")?;
    // asks[owner][asker]: answered by the owner, delivered back to the asker.
    let mut asks = deliver(asks, n).into_iter();
    let replies = take!(each(set, session, n, |_| Request::Answer(asks.next().unwrap_or_default()))?, Ids, "Answer")?;
    let mut replies = deliver(replies, n).into_iter();
    let made = each(set, session, n, |_| Request::Elements(replies.next().unwrap_or_default()))?;
    let mut out_elements = vec![UNMADE; elements];
    let mut out_vertices = vec![DVec3::ZERO; vertices as usize];
    for (i, r) in made.into_iter().enumerate() {
        let Reply::Made { elements, vertices } = r else {
            return Err(unexpected(i, "Elements", &r));
        };
        place(&mut out_elements, elements, i)?;
        place(&mut out_vertices, vertices, i)?;
    }
    Ok((out_elements, out_vertices))
}

/// Puts each `(id, value)` of share `share` in `out`; an id out of range fails.
fn place<T>(out: &mut [T], items: Vec<(u32, T)>, share: usize) -> Result<(), ShareError> {
    let len = out.len();
    for (id, value) in items {
        let slot = out
            .get_mut(id as usize)
            .ok_or_else(|| ShareError::Failed { share: share as u32, why: format!("made id {id} of {len}") })?;
        *slot = value;
    }
    Ok(())
}

/// Each share's BVH, every box padded by `pad`.
pub fn subtrees(
    set: &mut dyn ShareSet,
    session: u64,
    shares: usize,
    pad: f64,
) -> Result<Vec<crate::bvh::SubTree>, ShareError> {
    let trees = take!(each(set, session, shares, |_| Request::Subtree { pad })?, Subtree, "Subtree")?;
    trees
        .into_iter()
        .enumerate()
        .map(|(i, t)| {
            t.into_tree().ok_or(ShareError::Failed { share: i as u32, why: "a tree block of the wrong size".into() })
        })
        .collect()
}

/// Every share's records, written where `layout` puts them.
pub fn pack(
    set: &mut dyn ShareSet,
    session: u64,
    shares: usize,
    layout: &BlockLayout,
) -> Result<Vec<PartialBlocks>, ShareError> {
    let packed = take!(each(set, session, shares, |_| Request::Pack { layout: *layout })?, Blocks, "Pack")?;
    packed
        .into_iter()
        .enumerate()
        .map(|(i, blocks)| {
            blocks
                .into_iter()
                .map(|(id, b)| match steps::block(&b) {
                    Some(b) if id < layout.total => Ok((id, b)),
                    _ => Err(ShareError::Failed { share: i as u32, why: format!("a packed block {id} out of place") }),
                })
                .collect()
        })
        .collect()
}

/// Ends the session on every share: their servers drop them.
pub fn end(set: &mut dyn ShareSet, session: u64, shares: usize) -> Result<(), ShareError> {
    each(set, session, shares, |_| Request::End).map(|_| ())
}
