//! A fork's state for one render, split by job (paper §4.3–4.4): the shard of blocks it
//! holds ([`store`]), its pairs, unassigned or lent to nodes ([`pairs`]), and the
//! exactly-once ledger of the deposits it applied and the pairs it counts as done
//! ([`ledger`]). [`crate::shard::Shard`] puts them together; each is synchronous, works
//! on domain values only and is tested beside its code.

pub mod ledger;
pub mod pairs;
pub mod store;
