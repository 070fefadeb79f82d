//! Which fork holds what, written once.
//!
//! Scene data is interleaved over the forks' shared memories: block `b` lives on fork
//! `b mod F`, so that every fork holds a like share of each kind of block and a node's
//! misses spread over all the links. A node processor sits on one fork's card, its home
//! fork: node `i` on fork `i mod F`. Every renderer (embedded or cluster) asks these two
//! functions rather than restating the rule.
//!
//! ```
//! use magg_core::blocks::{fork_of_block, home_fork_of_node};
//! assert_eq!(fork_of_block(7, 3), 1);
//! assert_eq!(home_fork_of_node(4, 2), 0);
//! ```

/// The fork, among `forks`, that holds block `block`: `block mod forks`. A fork count of
/// 0 is taken as 1 (everything on fork 0) rather than dividing by zero.
pub fn fork_of_block(block: u32, forks: u32) -> u32 {
    block % forks.max(1)
}

/// The home fork, among `forks`, of node `node` (the fork whose card its processor sits
/// on): `node mod forks`. A fork count of 0 is taken as 1.
pub fn home_fork_of_node(node: u32, forks: u32) -> u32 {
    node % forks.max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_are_dealt_round_robin_over_the_forks() {
        let owners: Vec<u32> = (0..7).map(|b| fork_of_block(b, 3)).collect();
        assert_eq!(owners, [0, 1, 2, 0, 1, 2, 0]);
        assert_eq!(fork_of_block(u32::MAX, 2), 1);
        assert!((0..100).all(|b| fork_of_block(b, 1) == 0));
    }

    #[test]
    fn nodes_share_their_home_forks_in_turn() {
        let homes: Vec<u32> = (0..5).map(|n| home_fork_of_node(n, 2)).collect();
        assert_eq!(homes, [0, 1, 0, 1, 0]);
        assert_eq!(home_fork_of_node(3, 8), 3);
    }

    #[test]
    fn zero_forks_is_one_fork_not_a_panic() {
        assert_eq!(fork_of_block(9, 0), 0);
        assert_eq!(home_fork_of_node(9, 0), 0);
    }
}
