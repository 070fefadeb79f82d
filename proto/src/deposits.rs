//! A batch's deposits on one fork (`DepositRequest`), written and read as its packed
//! arrays.
//!
//! A node writes one request per fork and round ([`DepositWriter`]): for each pair of
//! the batch, [`DepositWriter::pair`] starts it and [`DepositWriter::deposit`] adds the
//! flux on one element; the arrays are written as the bytes of their packed fields as
//! they grow ([`crate::packed`]). A fork reads a request through [`read`], which decodes
//! the arrays whole and checks that they fit together before anything is applied, and
//! yields one [`PairDeposit`] (a [`magg_core::cluster`] value) per pair, borrowing from
//! the decoded arrays (no allocation per pair).
//!
//! ```
//! use magg_proto::deposits::{read, DepositWriter};
//! let mut w = DepositWriter::new(true, 0);
//! w.pair(7);
//! w.deposit(3, [10, 20, 30]);
//! w.also_on(2);
//! let req = w.finish();
//! let arrays = read(&req).unwrap();
//! let pairs: Vec<_> = arrays.pairs().collect();
//! assert_eq!((pairs[0].pair, pairs[0].elements, pairs[0].also_on), (7, &[3][..], &[2][..]));
//! ```

use crate::packed::{self, PackedError};
use crate::v1::DepositRequest;
use magg_core::cluster::DepositBatch;
pub use magg_core::cluster::PairDeposit;

/// Builds a `DepositRequest` pair by pair.
#[derive(Clone, Debug, Default)]
pub struct DepositWriter {
    complete: bool,
    epoch: u64,
    /// Varints of the pair ids.
    pairs: Vec<u8>,
    /// The last pair started.
    last: Option<u64>,
    /// Deposits of each pair (written as varints at the end).
    counts: Vec<u32>,
    /// Varints of the element ids.
    elements: Vec<u8>,
    /// Little-endian energies, three per element.
    energy: Vec<u8>,
    also_on_counts: Vec<u32>,
    also_on: Vec<u32>,
}

impl DepositWriter {
    /// An empty request: round 2 (`complete`, to the pairs' owner) or round 1, for pairs
    /// handed out in replay `epoch`.
    pub fn new(complete: bool, epoch: u64) -> Self {
        DepositWriter { complete, epoch, ..Default::default() }
    }

    /// Starts pair `pair`: the deposits and forks added next are its own.
    pub fn pair(&mut self, pair: u64) {
        packed::put_varint(&mut self.pairs, pair);
        self.last = Some(pair);
        self.counts.push(0);
        if !self.also_on_counts.is_empty() {
            self.also_on_counts.push(0);
        }
    }

    /// Whether the last pair started is `pair`.
    pub fn last_pair_is(&self, pair: u64) -> bool {
        self.last == Some(pair)
    }

    /// Adds `energy` (r, g, b fixed point) on `element` to the current pair.
    pub fn deposit(&mut self, element: u32, energy: [i64; 3]) {
        if let Some(c) = self.counts.last_mut() {
            *c += 1;
            packed::put_varint(&mut self.elements, element as u64);
            for v in energy {
                packed::put_i64(&mut self.energy, v);
            }
        }
    }

    /// Notes that the current pair also deposited on fork `fork` (round 2 only).
    pub fn also_on(&mut self, fork: u32) {
        let n = self.counts.len();
        if n == 0 {
            return;
        }
        // The counts are written only once some pair deposited elsewhere.
        self.also_on_counts.resize(n, 0);
        self.also_on_counts[n - 1] += 1;
        self.also_on.push(fork);
    }

    /// Pairs written so far.
    pub fn len(&self) -> usize {
        self.counts.len()
    }

    /// True with no pair.
    pub fn is_empty(&self) -> bool {
        self.counts.is_empty()
    }

    /// The request.
    pub fn finish(self) -> DepositRequest {
        DepositRequest {
            pairs: self.pairs.into(),
            counts: packed::varint_bytes(self.counts.iter().map(|&c| c as u64)),
            elements: self.elements.into(),
            energy: self.energy.into(),
            complete: self.complete,
            epoch: self.epoch,
            also_on_counts: self.also_on_counts,
            also_on: self.also_on,
            take: None,
        }
    }
}

/// Why a request's arrays do not fit together.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum DepositError {
    /// An array is not a well-formed packed field.
    #[error("DepositRequest.{field}: {source}")]
    Packed {
        /// The field.
        field: &'static str,
        /// What is wrong with its bytes.
        source: PackedError,
    },
    /// `counts` and `pairs` differ in length.
    #[error("{counts} element counts for {pairs} pairs")]
    Counts {
        /// Entries of `counts`.
        counts: usize,
        /// Entries of `pairs`.
        pairs: usize,
    },
    /// The counts do not add up to the elements sent.
    #[error("the element counts add up to {sum}, {elements} elements were sent")]
    Elements {
        /// Sum of `counts`.
        sum: u64,
        /// Entries of `elements`.
        elements: usize,
    },
    /// Not three energy values per element.
    #[error("{energy} energy values for {elements} elements (3 each)")]
    Energy {
        /// Entries of `energy`.
        energy: usize,
        /// Entries of `elements`.
        elements: usize,
    },
    /// `also_on_counts` is neither empty nor one per pair, or does not add up.
    #[error("{counts} also_on counts adding up to {sum} for {pairs} pairs and {forks} forks")]
    AlsoOn {
        /// Entries of `also_on_counts`.
        counts: usize,
        /// Their sum.
        sum: u64,
        /// Entries of `pairs`.
        pairs: usize,
        /// Entries of `also_on`.
        forks: usize,
    },
}

/// A request's arrays, decoded and checked to fit together ([`read`]).
#[derive(Clone, Debug)]
pub struct Deposits<'a> {
    req: &'a DepositRequest,
    pairs: Vec<u64>,
    counts: Vec<u32>,
    elements: Vec<u32>,
    energy: Vec<i64>,
}

/// The arrays of `req`, decoded and checked to fit together (the values themselves,
/// pair and element ids, are for the fork to check).
pub fn read(req: &DepositRequest) -> Result<Deposits<'_>, DepositError> {
    let bad = |field| move |source| DepositError::Packed { field, source };
    let pairs = packed::varints_u64(&req.pairs).map_err(bad("pairs"))?;
    let counts = packed::varints_u32(&req.counts).map_err(bad("counts"))?;
    let elements = packed::varints_u32(&req.elements).map_err(bad("elements"))?;
    let energy = packed::fixed_i64(&req.energy).map_err(bad("energy"))?;
    let n = pairs.len();
    if counts.len() != n {
        return Err(DepositError::Counts { counts: counts.len(), pairs: n });
    }
    let sum: u64 = counts.iter().map(|&c| c as u64).sum();
    if sum != elements.len() as u64 {
        return Err(DepositError::Elements { sum, elements: elements.len() });
    }
    if energy.len() != 3 * elements.len() {
        return Err(DepositError::Energy { energy: energy.len(), elements: elements.len() });
    }
    let also_sum: u64 = req.also_on_counts.iter().map(|&c| c as u64).sum();
    let also_fits = if req.also_on_counts.is_empty() {
        req.also_on.is_empty()
    } else {
        req.also_on_counts.len() == n && also_sum == req.also_on.len() as u64
    };
    if !also_fits {
        return Err(DepositError::AlsoOn {
            counts: req.also_on_counts.len(),
            sum: also_sum,
            pairs: n,
            forks: req.also_on.len(),
        });
    }
    Ok(Deposits { req, pairs, counts, elements, energy })
}

impl<'a> Deposits<'a> {
    /// Pairs in the request.
    pub fn len(&self) -> usize {
        self.pairs.len()
    }

    /// True with no pair.
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// Element deposits in all.
    pub fn deposits(&self) -> usize {
        self.elements.len()
    }

    /// The pairs, one [`PairDeposit`] each, borrowing the arrays.
    pub fn pairs(&self) -> Pairs<'_> {
        Pairs { d: self, k: 0, e: 0, a: 0 }
    }

    /// The request's pairs as the batch a fork applies.
    pub fn batch(&self) -> DepositBatch<Pairs<'_>> {
        DepositBatch {
            complete: self.req.complete,
            epoch: self.req.epoch,
            deposits: self.deposits(),
            pairs: self.pairs(),
        }
    }
}

/// The pairs of a read request ([`Deposits::pairs`]), one [`PairDeposit`] each.
#[derive(Clone, Debug)]
pub struct Pairs<'a> {
    d: &'a Deposits<'a>,
    /// Next pair.
    k: usize,
    /// Its first element.
    e: usize,
    /// Its first entry of `also_on`.
    a: usize,
}

impl<'a> Iterator for Pairs<'a> {
    type Item = PairDeposit<'a>;

    fn next(&mut self) -> Option<PairDeposit<'a>> {
        let (d, k, e, a) = (self.d, self.k, self.e, self.a);
        let pair = *d.pairs.get(k)?;
        let c = d.counts[k] as usize;
        let f = d.req.also_on_counts.get(k).map_or(0, |&f| f as usize);
        (self.k, self.e, self.a) = (k + 1, e + c, a + f);
        Some(PairDeposit {
            pair,
            elements: &d.elements[e..e + c],
            energy: &d.energy[3 * e..3 * (e + c)],
            also_on: &d.req.also_on[a..a + f],
        })
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let n = self.d.pairs.len() - self.k;
        (n, Some(n))
    }
}

impl ExactSizeIterator for Pairs<'_> {}

#[cfg(test)]
mod tests {
    use super::*;
    use prost::Message;

    #[test]
    fn written_pairs_read_back_in_order() {
        let mut w = DepositWriter::new(true, 4);
        w.pair(1);
        w.deposit(10, [1, 2, 3]);
        w.deposit(11, [4, 5, 6]);
        w.pair(2); // deposited nothing here
        w.pair(3);
        w.deposit(12, [7, 8, 9]);
        w.also_on(0);
        w.also_on(2);
        assert!(w.last_pair_is(3) && !w.last_pair_is(2));
        let req = w.finish();
        assert_eq!((req.complete, req.epoch), (true, 4));
        let arrays = read(&req).unwrap();
        assert_eq!((arrays.len(), arrays.deposits()), (3, 3));
        let got: Vec<_> = arrays.pairs().collect();
        let want = [
            PairDeposit { pair: 1, elements: &[10, 11], energy: &[1, 2, 3, 4, 5, 6], also_on: &[] },
            PairDeposit { pair: 2, elements: &[], energy: &[], also_on: &[] },
            PairDeposit { pair: 3, elements: &[12], energy: &[7, 8, 9], also_on: &[0, 2] },
        ];
        assert_eq!(got, want);
    }

    /// The request is, byte for byte, the message with packed repeated fields that the
    /// `.proto` file's comments name (what protocol 3 to 14 sent).
    #[test]
    fn the_wire_format_is_that_of_the_packed_fields() {
        let mut w = DepositWriter::new(true, 9);
        w.pair(1 << 40);
        w.deposit(300, [1, -2, i64::MAX]);
        w.deposit(u32::MAX, [0, 0, 7]);
        w.pair(5);
        w.also_on(3);
        let ours = w.finish().encode_to_vec();
        let mut theirs = Vec::new();
        prost::encoding::uint64::encode_packed(2, &[1 << 40, 5], &mut theirs);
        prost::encoding::uint32::encode_packed(3, &[2, 0], &mut theirs);
        prost::encoding::uint32::encode_packed(4, &[300, u32::MAX], &mut theirs);
        prost::encoding::sfixed64::encode_packed(5, &[1, -2, i64::MAX, 0, 0, 7], &mut theirs);
        prost::encoding::bool::encode(6, &true, &mut theirs);
        prost::encoding::uint64::encode(7, &9, &mut theirs);
        prost::encoding::uint32::encode_packed(8, &[0, 1], &mut theirs);
        prost::encoding::uint32::encode_packed(9, &[3], &mut theirs);
        assert_eq!(ours, theirs);
    }

    #[test]
    fn round_one_requests_carry_no_fork_lists() {
        let mut w = DepositWriter::new(false, 0);
        w.pair(5);
        w.deposit(1, [1, 1, 1]);
        let req = w.finish();
        assert!(req.also_on_counts.is_empty() && req.also_on.is_empty());
        assert_eq!(read(&req).unwrap().len(), 1);
    }

    #[test]
    fn arrays_that_do_not_fit_together_are_refused() {
        let mut w = DepositWriter::new(true, 0);
        w.pair(1);
        w.deposit(10, [1, 2, 3]);
        w.also_on(1);
        let good = w.finish();
        let cases: Vec<(DepositRequest, &str)> = vec![
            (DepositRequest { counts: packed::varint_bytes([]), ..good.clone() }, "counts"),
            (DepositRequest { counts: packed::varint_bytes([2]), ..good.clone() }, "add up to 2"),
            (DepositRequest { energy: vec![0; 16].into(), ..good.clone() }, "2 energy values"),
            (DepositRequest { energy: vec![0; 20].into(), ..good.clone() }, "DepositRequest.energy: 20 bytes"),
            (DepositRequest { also_on: vec![], ..good.clone() }, "also_on"),
            (DepositRequest { also_on_counts: vec![], ..good.clone() }, "also_on"),
            (DepositRequest { counts: packed::varint_bytes([u32::MAX as u64]), ..good.clone() }, "add up to"),
            (
                DepositRequest { counts: packed::varint_bytes([1 << 32]), ..good.clone() },
                "DepositRequest.counts: a varint",
            ),
            (DepositRequest { pairs: vec![0x81].into(), ..good.clone() }, "DepositRequest.pairs: the last varint"),
            (DepositRequest { elements: vec![0xff; 11].into(), ..good.clone() }, "DepositRequest.elements"),
        ];
        for (req, want) in cases {
            let e = read(&req).err().unwrap_or_else(|| panic!("accepted: {req:?}"));
            assert!(e.to_string().contains(want), "{e} lacks {want:?}");
        }
        assert!(read(&good).is_ok());
    }
}
