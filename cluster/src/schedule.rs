//! The host's subscreen scheduler (paper §4.6): many more subscreens than nodes, handed
//! out on request; when the queue is empty while nodes are still busy, a busy node is
//! asked to give back the rows it has not started, and those become a new subscreen for
//! an idle node (adaptive redivision).
//!
//! A subscreen is leased: when its node sends no rows for longer than the lease (it died
//! or stalled), the rows not received yet go back to the queue and the subscreen is
//! revoked. Rows already received are kept, and every row is written exactly once: rows
//! of a revoked subscreen are dropped, and the node sending them is told to stop.

use magg_core::frame::Frame;
use magg_core::subscreen::Subscreen;
use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::time::{Duration, Instant};

/// What an idle node should do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Next {
    /// Trace this subscreen (with its id).
    Trace(u64, Subscreen),
    /// Nothing to hand out now; ask again soon.
    Wait,
    /// Every pixel is in.
    Done,
}

/// Why a row was refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RowError {
    /// Unknown or finished subscreen.
    #[error("subscreen {0} is not being traced")]
    UnknownSubscreen(u64),
    /// Row outside the subscreen or out of order.
    #[error("row {y} is not the next row of subscreen {id} (expected {expected})")]
    BadRow {
        /// Subscreen.
        id: u64,
        /// Row sent.
        y: u32,
        /// Row expected.
        expected: u32,
    },
    /// Wrong number of bytes.
    #[error("row {y} has {got} bytes of pixels, expected {expected} (12 a pixel)")]
    BadLength {
        /// Row.
        y: u32,
        /// Bytes sent.
        got: usize,
        /// Bytes expected (three little-endian f32 per pixel).
        expected: usize,
    },
    /// A pixel that is not a finite non-negative radiance: the subscreen was taken back
    /// and goes to the queue again, for another node (or the same) to trace.
    #[error(
        "row {y} of subscreen {id}: pixel {x} has {value}, not a finite radiance >= 0; the subscreen is taken back"
    )]
    BadPixel {
        /// Subscreen.
        id: u64,
        /// Row.
        y: u32,
        /// Pixel within the row.
        x: u32,
        /// The channel value sent.
        value: f32,
    },
}

#[derive(Clone, Copy, Debug)]
struct Active {
    rect: Subscreen,
    next_row: u32,
    end: u32,
    node: u32,
    split_wanted: bool,
    /// When it was handed out or last sent rows.
    seen: Instant,
}

/// Subscreen queue, work in progress and the frame being assembled.
pub struct Scheduler {
    queue: VecDeque<Subscreen>,
    active: BTreeMap<u64, Active>,
    /// Subscreens whose lease expired: their late rows are dropped.
    revoked: BTreeSet<u64>,
    next_id: u64,
    /// Subscreens revoked because their node went silent.
    pub revocations: u64,
    /// Adaptive redivisions so far.
    pub redivisions: u64,
    /// Subscreens handed out (redivided parts included).
    pub handed_out: u64,
    frame: Frame,
    pixels_done: u64,
    /// Pixels of the subscreens (the frame's, or a crop window's).
    pixels_total: u64,
    /// Nodes sharing the queue, when a request may get a run of adjacent subscreens (see
    /// [`Scheduler::merging`]); `None`: one subscreen per request, as in the paper.
    merge_for: Option<u32>,
}

impl Scheduler {
    /// A scheduler over `tiles` for a `width` x `height` frame.
    pub fn new(width: u32, height: u32, tiles: Vec<Subscreen>) -> Self {
        Scheduler {
            pixels_total: magg_core::subscreen::pixels(&tiles),
            queue: tiles.into(),
            active: BTreeMap::new(),
            revoked: BTreeSet::new(),
            next_id: 0,
            revocations: 0,
            redivisions: 0,
            handed_out: 0,
            frame: Frame::new(width, height),
            pixels_done: 0,
            merge_for: None,
        }
    }

    /// Lets a request take a run of subscreens that lie side by side in the queue (same
    /// band of rows), traced as one rectangle: half of each of `nodes` nodes' share of the
    /// queue, so that a node asks once per band while much is left and for single
    /// subscreens at the end (guided self-scheduling, as for pairs). Each request and
    /// its rows cost a round trip; a 16x16 subscreen of a simple scene traces in about
    /// 70 us, so one request each costs the cluster a tenth of the viewing pass. Adaptive
    /// redivision splits a run by rows like any subscreen.
    pub fn merging(mut self, nodes: u32) -> Self {
        self.merge_for = Some(nodes.max(1));
        self
    }

    /// True when every pixel of the subscreens has arrived.
    pub fn is_done(&self) -> bool {
        self.pixels_done >= self.pixels_total
    }

    /// Work for `node`.
    pub fn next(&mut self, node: u32) -> Next {
        if let Some(mut rect) = self.queue.pop_front() {
            if let Some(nodes) = self.merge_for {
                let run = (self.queue.len() as u64 + 1) / (2 * nodes as u64);
                for _ in 1..run {
                    match self.queue.front() {
                        Some(t) if t.y == rect.y && t.h == rect.h && t.x == rect.x + rect.w => {
                            rect.w += t.w;
                            self.queue.pop_front();
                        }
                        _ => break,
                    }
                }
            }
            let id = self.next_id;
            self.next_id += 1;
            self.handed_out += 1;
            self.active.insert(
                id,
                Active {
                    rect,
                    next_row: rect.y,
                    end: rect.y + rect.h,
                    node,
                    split_wanted: false,
                    seen: Instant::now(),
                },
            );
            return Next::Trace(id, rect);
        }
        if self.is_done() {
            return Next::Done;
        }
        // Ask the busy node with the most unstarted rows to give half of them back.
        let pending = self.active.values().any(|a| a.split_wanted);
        if !pending {
            if let Some(a) = self
                .active
                .values_mut()
                .filter(|a| a.node != node && a.end - a.next_row >= 3)
                .max_by_key(|a| a.end - a.next_row)
            {
                a.split_wanted = true;
            }
        }
        Next::Wait
    }

    /// Stores rows of subscreen `id` (in order, starting at its next row); returns the
    /// row from which the node must stop (its unstarted rows were redivided), if any. A
    /// revoked subscreen's rows are dropped and the answer is row 0: stop now.
    pub fn submit(&mut self, id: u64, rows: &[(u32, &[u8])]) -> Result<Option<u32>, RowError> {
        if self.revoked.contains(&id) {
            return Ok(Some(0));
        }
        if let Some(a) = self.active.get_mut(&id) {
            a.seen = Instant::now();
        }
        for &(y, rgb) in rows {
            if let Err(e) = self.store_row(id, y, rgb) {
                if matches!(e, RowError::BadPixel { .. }) {
                    self.take_back(id);
                }
                return Err(e);
            }
        }
        Ok(self.split_if_wanted(id))
    }

    /// Stores row `y` of subscreen `id`; `rgb` holds its pixels as on the wire (see
    /// [`magg_proto::convert::pixels_to_wire`]).
    fn store_row(&mut self, id: u64, y: u32, rgb: &[u8]) -> Result<(), RowError> {
        let a = self.active.get_mut(&id).ok_or(RowError::UnknownSubscreen(id))?;
        if y < a.next_row && y >= a.rect.y {
            return Ok(()); // a repeated row: already stored
        }
        if y != a.next_row || y >= a.end {
            return Err(RowError::BadRow { id, y, expected: a.next_row });
        }
        let expected = 12 * a.rect.w as usize;
        if rgb.len() != expected {
            return Err(RowError::BadLength { y, got: rgb.len(), expected });
        }
        if !all_finite_non_negative(rgb) {
            let bad =
                magg_proto::convert::pixels_from_wire(rgb).enumerate().find(|(_, v)| !(v.is_finite() && *v >= 0.0));
            if let Some((k, value)) = bad {
                return Err(RowError::BadPixel { id, y, x: (k / 3) as u32, value });
            }
        }
        // The frame holds f32 pixels, as the wire does: the row is copied as it came.
        if let Some(row) = self.frame.row_mut(a.rect.x, y, a.rect.w) {
            magg_proto::convert::pixels_into(rgb, row);
        }
        self.pixels_done += a.rect.w as u64;
        a.next_row = y + 1;
        Ok(())
    }

    /// After rows arrived: hands half of the unstarted rows to the queue if an idle node
    /// asked for work, and retires a finished subscreen.
    fn split_if_wanted(&mut self, id: u64) -> Option<u32> {
        let a = self.active.get_mut(&id)?;
        let mut give_back = None;
        let remaining = a.end - a.next_row;
        if a.split_wanted && remaining >= 2 {
            let split = a.next_row + remaining.div_ceil(2);
            let rest = Subscreen { x: a.rect.x, y: split, w: a.rect.w, h: a.end - split };
            a.end = split;
            self.queue.push_back(rest);
            self.redivisions += 1;
            give_back = Some(split);
        }
        a.split_wanted = false;
        if a.next_row >= a.end {
            self.active.remove(&id);
        }
        give_back
    }

    /// Revokes every subscreen whose node sent nothing for longer than `lease`: its rows
    /// not received yet go to the front of the queue. Returns the nodes that lost one.
    pub fn expire(&mut self, lease: Duration) -> Vec<u32> {
        let expired: Vec<u64> =
            self.active.iter().filter(|(_, a)| a.seen.elapsed() > lease).map(|(&id, _)| id).collect();
        expired.into_iter().filter_map(|id| self.take_back(id)).collect()
    }

    /// Revokes subscreen `id`: its rows not received yet go to the front of the queue and
    /// its late rows are dropped. Returns the node that had it.
    fn take_back(&mut self, id: u64) -> Option<u32> {
        let a = self.active.remove(&id)?;
        if a.next_row < a.end {
            self.queue.push_front(Subscreen { x: a.rect.x, y: a.next_row, w: a.rect.w, h: a.end - a.next_row });
        }
        self.revoked.insert(id);
        self.revocations += 1;
        Some(a.node)
    }

    /// Pixels received so far.
    pub fn pixels_done(&self) -> u64 {
        self.pixels_done
    }

    /// The assembled frame.
    pub fn frame(&self) -> &Frame {
        &self.frame
    }

    /// Takes the assembled frame out (no copy of its pixels). The schedule keeps
    /// answering as before, but stores no more pixels: for when the frame is done.
    pub fn take_frame(&mut self) -> Frame {
        let empty = Frame { width: self.frame.width, height: self.frame.height, pixels: Vec::new() };
        std::mem::replace(&mut self.frame, empty)
    }
}

/// Whether every f32 of a row on the wire (little-endian) is finite and `>= 0.0`, read
/// off the bits in one branch-free pass that the compiler vectorises: a non-negative
/// finite value has a clear sign bit and an exponent below all ones; -0.0 passes too.
fn all_finite_non_negative(rgb: &[u8]) -> bool {
    // (Whole 4-byte arrays and non-short-circuit tests: `chunks_exact` and `||` kept
    // the loop scalar, 5.6 times slower in a micro-benchmark.)
    let (words, _) = rgb.as_chunks::<4>();
    words.iter().fold(true, |ok, w| {
        let bits = u32::from_le_bytes(*w);
        ok & ((bits < 0x7f80_0000) | (bits == 0x8000_0000))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(w: u32, v: f32) -> Vec<u8> {
        magg_proto::convert::pixels_to_wire(vec![v; 3 * w as usize]).to_vec()
    }

    /// The bit test says what `v.is_finite() && v >= 0.0` says, value by value.
    #[test]
    fn the_bit_test_agrees_with_the_float_test() {
        let specials = [
            0.0,
            -0.0,
            f32::MIN_POSITIVE,
            1.0e-45, // subnormal
            -1.0e-45,
            1.0,
            -1.0,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -f32::NAN,
            f32::from_bits(0x7f80_0001), // a signalling NaN
            f32::from_bits(0xffff_ffff),
        ];
        for v in specials {
            let want = v.is_finite() && v >= 0.0;
            let row = magg_proto::convert::pixels_to_wire([1.0, v, 2.0]);
            assert_eq!(all_finite_non_negative(&row), want, "{v} ({:#x})", v.to_bits());
        }
    }

    #[test]
    fn a_request_takes_a_run_of_adjacent_subscreens_while_many_are_left() {
        // 4 bands of 4 subscreens 2x2, shared by 1 node: half the queue, within a band.
        let tiles = magg_core::subscreen::tile(8, 8, 2);
        let mut s = Scheduler::new(8, 8, tiles).merging(1);
        let mut got = Vec::new();
        loop {
            match s.next(0) {
                Next::Trace(id, t) => {
                    for y in t.y..t.y + t.h {
                        s.submit(id, &[(y, &row(t.w, 1.0))]).unwrap();
                    }
                    got.push((t.x, t.y, t.w, t.h));
                }
                Next::Done => break,
                Next::Wait => panic!("one node never waits"),
            }
        }
        // 16 queued: a whole band (4, capped by the band); 12: 4; 8: 4; 4: 2, then 1, 1.
        assert_eq!(got, vec![(0, 0, 8, 2), (0, 2, 8, 2), (0, 4, 8, 2), (0, 6, 4, 2), (4, 6, 2, 2), (6, 6, 2, 2)]);
        assert!(s.is_done());
        assert_eq!(s.handed_out, 6);
    }

    #[test]
    fn without_merging_each_request_gets_one_subscreen() {
        let tiles = magg_core::subscreen::tile(8, 8, 2);
        let mut s = Scheduler::new(8, 8, tiles);
        let Next::Trace(_, t) = s.next(0) else { panic!("expected work") };
        assert_eq!((t.w, t.h), (2, 2));
    }

    #[test]
    fn redivision_hands_unstarted_rows_to_an_idle_node() {
        let mut s = Scheduler::new(4, 8, vec![Subscreen { x: 0, y: 0, w: 4, h: 8 }]);
        let Next::Trace(id, t) = s.next(0) else { panic!("expected work") };
        assert_eq!(t.h, 8);
        // Node 1 is idle: the queue is empty, so node 0 is asked to split.
        assert_eq!(s.next(1), Next::Wait);
        // Node 0 sends row 0; the host takes rows 5..8 back (half of the 7 unstarted).
        assert_eq!(s.submit(id, &[(0, &row(4, 1.0))]).unwrap(), Some(5));
        assert_eq!(s.redivisions, 1);
        let Next::Trace(id2, t2) = s.next(1) else { panic!("expected the redivided part") };
        assert_eq!((t2.y, t2.h), (5, 3));
        for y in 1..5 {
            assert_eq!(s.submit(id, &[(y, &row(4, 1.0))]).unwrap(), None);
        }
        for y in 5..8 {
            s.submit(id2, &[(y, &row(4, 2.0))]).unwrap();
        }
        assert!(s.is_done());
        assert_eq!(s.next(0), Next::Done);
        assert_eq!(s.frame().get(0, 7), [2.0; 3]);
    }

    #[test]
    fn a_taken_frame_keeps_its_pixels_and_the_schedule_still_answers() {
        let mut s = Scheduler::new(4, 2, vec![Subscreen { x: 0, y: 0, w: 4, h: 2 }]);
        let Next::Trace(id, _) = s.next(0) else { panic!("expected work") };
        s.submit(id, &[(0, &row(4, 1.0)), (1, &row(4, 3.0))]).unwrap();
        assert!(s.is_done());
        let f = s.take_frame();
        assert_eq!((f.width, f.height, f.pixels.len()), (4, 2, 8));
        assert_eq!((f.get(3, 0), f.get(0, 1)), ([1.0; 3], [3.0; 3]));
        // The schedule answers as before the take: done, and a row of a retired
        // subscreen is refused the same way.
        assert!(s.is_done());
        assert_eq!(s.pixels_done(), 8);
        assert_eq!(s.next(1), Next::Done);
        assert!(matches!(s.submit(id, &[(1, &row(4, 3.0))]), Err(RowError::UnknownSubscreen(_))));
    }

    #[test]
    fn a_silent_node_loses_its_unsent_rows_and_its_late_rows_are_dropped() {
        let mut s = Scheduler::new(4, 4, vec![Subscreen { x: 0, y: 0, w: 4, h: 4 }]);
        let Next::Trace(id, _) = s.next(0) else { panic!() };
        s.submit(id, &[(0, &row(4, 1.0))]).unwrap();
        assert!(s.expire(Duration::from_secs(60)).is_empty(), "a fresh lease does not expire");
        std::thread::sleep(Duration::from_millis(5));
        assert_eq!(s.expire(Duration::from_millis(1)), vec![0]);
        // The late node is told to stop; its rows are not written.
        assert_eq!(s.submit(id, &[(1, &row(4, 9.0))]).unwrap(), Some(0));
        let Next::Trace(id2, t) = s.next(1) else { panic!("rows 1..4 are back on the queue") };
        assert_eq!((t.y, t.h), (1, 3));
        for y in 1..4 {
            s.submit(id2, &[(y, &row(4, 2.0))]).unwrap();
        }
        assert!(s.is_done());
        assert_eq!((s.frame().get(0, 0), s.frame().get(0, 1)), ([1.0; 3], [2.0; 3]));
        assert_eq!(s.revocations, 1);
    }

    #[test]
    fn bad_rows_are_refused() {
        let mut s = Scheduler::new(4, 4, vec![Subscreen { x: 0, y: 0, w: 4, h: 4 }]);
        let Next::Trace(id, _) = s.next(0) else { panic!() };
        assert!(matches!(s.submit(id, &[(2, &row(4, 0.0))]), Err(RowError::BadRow { .. })));
        assert!(matches!(s.submit(id, &[(0, &row(3, 0.0))]), Err(RowError::BadLength { .. })));
        assert!(matches!(s.submit(99, &[(0, &row(4, 0.0))]), Err(RowError::UnknownSubscreen(99))));
        s.submit(id, &[(0, &row(4, 0.0)), (1, &row(4, 0.0))]).unwrap();
        assert_eq!(s.submit(id, &[(1, &row(4, 0.0))]).unwrap(), None, "a repeated row is ignored");
    }

    #[test]
    fn a_row_with_nan_or_negative_radiance_sends_the_subscreen_back_to_the_queue() {
        for poison in [f32::NAN, f32::INFINITY, -1.0] {
            let mut s = Scheduler::new(4, 2, vec![Subscreen { x: 0, y: 0, w: 4, h: 2 }]);
            let Next::Trace(id, _) = s.next(0) else { panic!() };
            s.submit(id, &[(0, &row(4, 0.5))]).unwrap();
            let mut bad = row(4, 0.5);
            bad[12 * 2 + 4..12 * 2 + 8].copy_from_slice(&poison.to_le_bytes());
            let e = s.submit(id, &[(1, &bad)]).unwrap_err();
            assert!(matches!(e, RowError::BadPixel { y: 1, x: 2, .. }), "{e}");
            assert_eq!(s.revocations, 1);
            // The row not received is traced again, by whoever asks next.
            let Next::Trace(again, rect) = s.next(1) else { panic!("the subscreen is not back on the queue") };
            assert_eq!((rect.y, rect.h), (1, 1));
            assert_eq!(s.submit(id, &[(1, &row(4, 0.5))]).unwrap(), Some(0), "the first node's late rows are dropped");
            s.submit(again, &[(1, &row(4, 0.25))]).unwrap();
            assert!(s.is_done());
            assert_eq!(s.frame().get(2, 1), [0.25; 3]);
        }
    }
}
