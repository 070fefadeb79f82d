//! Fuzzing what the host takes from nodes, with proptest (fixed seed, bounded cases):
//! `SubmitRows` contents (any subscreen id, row, length, values) and `NextWork` calls
//! from any node, interleaved with lease expiry, never panic the subscreen scheduler and
//! never count more pixels than the frame has; afterwards, once the leases of the
//! fuzzing nodes expire, a well-behaved node still finishes the frame (no row is lost).

use magg_cluster::schedule::{Next, Scheduler};
use magg_core::subscreen::Subscreen;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
use std::time::Duration;

#[derive(Clone, Debug)]
enum Call {
    Next(u32),
    Rows { id: u64, y: u32, len: usize, v: f32 },
    Expire,
}

fn call() -> impl Strategy<Value = Call> {
    prop_oneof![
        (0..4u32).prop_map(Call::Next),
        (0..12u64, 0..40u32, 0..80usize, any::<f32>()).prop_map(|(id, y, len, v)| Call::Rows { id, y, len, v }),
        Just(Call::Expire),
    ]
}

#[test]
fn any_sequence_of_node_calls_keeps_the_frame_consistent() {
    let config =
        Config { cases: 512, failure_persistence: None, rng_algorithm: RngAlgorithm::ChaCha, ..Config::default() };
    let mut runner = TestRunner::new_with_rng(config, TestRng::from_seed(RngAlgorithm::ChaCha, &[7; 32]));
    let (w, h) = (24u32, 20u32);
    runner
        .run(&proptest::collection::vec(call(), 0..80), |calls| {
            let tiles = magg_core::subscreen::tile(w, h, 8);
            // Half the cases let requests take runs of adjacent subscreens.
            let mut s = Scheduler::new(w, h, tiles);
            if calls.len() % 2 == 0 {
                s = s.merging(2);
            }
            let mut handed: Vec<(u64, Subscreen)> = Vec::new();
            for c in calls {
                match c {
                    Call::Next(node) => {
                        if let Next::Trace(id, t) = s.next(node) {
                            handed.push((id, t));
                        }
                    }
                    Call::Rows { id, y, len, v } => {
                        // Half the time, a well-formed row of a handed-out subscreen.
                        let (id, len) = match handed.iter().find(|(i, _)| *i == id) {
                            Some((i, t)) if len % 2 == 0 => (*i, 3 * t.w as usize),
                            _ => (id, len),
                        };
                        let _ = s.submit(id, &[(y, &magg_proto::convert::pixels_to_wire(vec![v; len]))]);
                    }
                    Call::Expire => {
                        s.expire(Duration::ZERO);
                    }
                }
                prop_assert!(s.pixels_done() <= w as u64 * h as u64, "more pixels than the frame has");
            }
            s.expire(Duration::ZERO);
            for _ in 0..1000 {
                match s.next(99) {
                    Next::Trace(id, t) => {
                        for y in t.y..t.y + t.h {
                            prop_assert!(s
                                .submit(id, &[(y, &magg_proto::convert::pixels_to_wire(vec![1.0; 3 * t.w as usize]))])
                                .is_ok());
                        }
                    }
                    Next::Wait => prop_assert!(false, "work left that nobody can get"),
                    Next::Done => break,
                }
            }
            prop_assert!(s.is_done());
            prop_assert_eq!(s.pixels_done(), w as u64 * h as u64);
            Ok(())
        })
        .unwrap();
}
