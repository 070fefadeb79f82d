//! A batch's deposits on one fork (`DepositRequest`), written and read as its packed
//! arrays.
//!
//! A node writes one request per fork and round ([`DepositWriter`]): for each pair of
//! the batch, [`DepositWriter::pair`] starts it and [`DepositWriter::deposit`] adds the
//! flux on one element. A fork reads a request through [`read`], which checks that the
//! arrays fit together before anything is applied and yields one [`PairDeposit`] (a
//! [`magg_core::cluster`] value) per pair, borrowing from the request (no copy, no allocation per pair).
//!
//! ```
//! use magg_proto::deposits::{read, DepositWriter};
//! let mut w = DepositWriter::new(true, 0);
//! w.pair(7);
//! w.deposit(3, [10, 20, 30]);
//! w.also_on(2);
//! let req = w.finish();
//! let pairs: Vec<_> = read(&req).unwrap().collect();
//! assert_eq!((pairs[0].pair, pairs[0].elements, pairs[0].also_on), (7, &[3][..], &[2][..]));
//! ```

use crate::v1::DepositRequest;
pub use magg_core::cluster::PairDeposit;

/// Builds a `DepositRequest` pair by pair.
#[derive(Clone, Debug, Default)]
pub struct DepositWriter {
    req: DepositRequest,
}

impl DepositWriter {
    /// An empty request: round 2 (`complete`, to the pairs' owner) or round 1, for pairs
    /// handed out in replay `epoch`.
    pub fn new(complete: bool, epoch: u64) -> Self {
        DepositWriter { req: DepositRequest { complete, epoch, ..Default::default() } }
    }

    /// Starts pair `pair`: the deposits and forks added next are its own.
    pub fn pair(&mut self, pair: u64) {
        self.req.pairs.push(pair);
        self.req.counts.push(0);
        if !self.req.also_on_counts.is_empty() {
            self.req.also_on_counts.push(0);
        }
    }

    /// Whether the last pair started is `pair`.
    pub fn last_pair_is(&self, pair: u64) -> bool {
        self.req.pairs.last() == Some(&pair)
    }

    /// Adds `energy` (r, g, b fixed point) on `element` to the current pair.
    pub fn deposit(&mut self, element: u32, energy: [i64; 3]) {
        if let Some(c) = self.req.counts.last_mut() {
            *c += 1;
            self.req.elements.push(element);
            self.req.energy.extend_from_slice(&energy);
        }
    }

    /// Notes that the current pair also deposited on fork `fork` (round 2 only).
    pub fn also_on(&mut self, fork: u32) {
        let n = self.req.pairs.len();
        if n == 0 {
            return;
        }
        // The counts are written only once some pair deposited elsewhere.
        self.req.also_on_counts.resize(n, 0);
        self.req.also_on_counts[n - 1] += 1;
        self.req.also_on.push(fork);
    }

    /// Pairs written so far.
    pub fn len(&self) -> usize {
        self.req.pairs.len()
    }

    /// True with no pair.
    pub fn is_empty(&self) -> bool {
        self.req.pairs.is_empty()
    }

    /// The request.
    pub fn finish(self) -> DepositRequest {
        self.req
    }
}

/// Why a request's arrays do not fit together.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum DepositError {
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

/// The pairs of `req`, once its arrays are checked to fit together (the values
/// themselves, pair and element ids, are for the fork to check).
pub fn read(req: &DepositRequest) -> Result<Pairs<'_>, DepositError> {
    let n = req.pairs.len();
    if req.counts.len() != n {
        return Err(DepositError::Counts { counts: req.counts.len(), pairs: n });
    }
    let sum: u64 = req.counts.iter().map(|&c| c as u64).sum();
    if sum != req.elements.len() as u64 {
        return Err(DepositError::Elements { sum, elements: req.elements.len() });
    }
    if req.energy.len() != 3 * req.elements.len() {
        return Err(DepositError::Energy { energy: req.energy.len(), elements: req.elements.len() });
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
    Ok(Pairs { req, k: 0, e: 0, a: 0 })
}

/// The pairs of a checked request ([`read`]), one [`PairDeposit`] each, borrowing its
/// arrays.
#[derive(Clone, Debug)]
pub struct Pairs<'a> {
    req: &'a DepositRequest,
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
        let (req, k, e, a) = (self.req, self.k, self.e, self.a);
        let pair = *req.pairs.get(k)?;
        let c = req.counts[k] as usize;
        let f = req.also_on_counts.get(k).map_or(0, |&f| f as usize);
        (self.k, self.e, self.a) = (k + 1, e + c, a + f);
        Some(PairDeposit {
            pair,
            elements: &req.elements[e..e + c],
            energy: &req.energy[3 * e..3 * (e + c)],
            also_on: &req.also_on[a..a + f],
        })
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let n = self.req.pairs.len() - self.k;
        (n, Some(n))
    }
}

impl ExactSizeIterator for Pairs<'_> {}

#[cfg(test)]
mod tests {
    use super::*;

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
        let got: Vec<_> = read(&req).unwrap().collect();
        let want = [
            PairDeposit { pair: 1, elements: &[10, 11], energy: &[1, 2, 3, 4, 5, 6], also_on: &[] },
            PairDeposit { pair: 2, elements: &[], energy: &[], also_on: &[] },
            PairDeposit { pair: 3, elements: &[12], energy: &[7, 8, 9], also_on: &[0, 2] },
        ];
        assert_eq!(got, want);
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
            (DepositRequest { counts: vec![], ..good.clone() }, "counts"),
            (DepositRequest { counts: vec![2], ..good.clone() }, "add up to 2"),
            (DepositRequest { energy: vec![1, 2], ..good.clone() }, "2 energy values"),
            (DepositRequest { also_on: vec![], ..good.clone() }, "also_on"),
            (DepositRequest { also_on_counts: vec![], ..good.clone() }, "also_on"),
            (DepositRequest { counts: vec![u32::MAX], ..good.clone() }, "add up to"),
        ];
        for (req, want) in cases {
            let e = read(&req).err().unwrap_or_else(|| panic!("accepted: {req:?}"));
            assert!(e.to_string().contains(want), "{e} lacks {want:?}");
        }
        assert!(read(&good).is_ok());
    }
}
