//! Fuzzing the scene parser with proptest (fixed seed, bounded cases, seconds in CI):
//! arbitrary bytes and mutated copies of a real scene never make `parse_scene_str` or
//! `prepare` panic; every refusal is a `SceneError` naming the file and a field.

use magg_core::scene::parse_scene_str;
use magg_prepare::prepare;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
use std::path::Path;

const LABEL: &str = "fuzz.toml";

fn runner(seed: u8, cases: u32) -> TestRunner {
    let config = Config { cases, failure_persistence: None, rng_algorithm: RngAlgorithm::ChaCha, ..Config::default() };
    TestRunner::new_with_rng(config, TestRng::from_seed(RngAlgorithm::ChaCha, &[seed; 32]))
}

fn paper_scene() -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/magg-paper.toml");
    std::fs::read_to_string(path).unwrap()
}

/// Parses `text` (OBJ files are missing), then prepares what parses with a small element
/// cap; checks that refusals name the file and a field.
fn check(text: &str) -> Result<(), TestCaseError> {
    let no_files = |p: &Path| Err(std::io::Error::new(std::io::ErrorKind::NotFound, p.display().to_string()));
    match parse_scene_str(LABEL, text, Path::new("."), &no_files) {
        Ok(mut scene) => {
            scene.settings.max_elements = scene.settings.max_elements.min(50_000);
            let _ = prepare(&scene);
        }
        Err(e) => {
            prop_assert!(e.to_string().starts_with(LABEL), "{e}");
            prop_assert!(!e.field.is_empty(), "{e}");
        }
    }
    Ok(())
}

#[test]
fn arbitrary_bytes_never_panic_the_parser() {
    let bytes = proptest::collection::vec(any::<u8>(), 0..400);
    runner(1, 512).run(&bytes, |b| check(&String::from_utf8_lossy(&b))).unwrap();
    runner(2, 256).run(&"[ -~\n]{0,300}", |s| check(&s)).unwrap();
}

/// Values that break things: NaN, infinities, huge, negative, wrong types, unclosed.
const BAD_VALUES: &[&str] = &[
    "nan",
    "inf",
    "-inf",
    "1e309",
    "-1",
    "0",
    "4294967297",
    "99999999999999999999",
    "\"x\"",
    "[",
    "[1, 2]",
    "[nan, 0, 0]",
    "[1e308, 1e308, 1e308]",
    "[0, 0, 0]",
    "true",
    "{}",
    "",
];

#[test]
fn mutated_real_scenes_never_panic_and_errors_name_a_field() {
    let base = paper_scene();
    let lines: Vec<String> = base.lines().map(String::from).collect();
    let n = lines.len();
    let mutation = proptest::collection::vec((0..n, 0..BAD_VALUES.len(), 0..4u8), 1..4);
    runner(3, 512)
        .run(&mutation, |edits| {
            let mut l = lines.clone();
            for (line, value, kind) in edits {
                let line = line.min(l.len().saturating_sub(1));
                if l.is_empty() {
                    break;
                }
                match kind {
                    // Replace the value of a `key = value` line.
                    0 => {
                        if let Some((k, _)) = l[line].split_once('=') {
                            l[line] = format!("{k}= {}", BAD_VALUES[value]);
                        }
                    }
                    1 => {
                        l.remove(line);
                    }
                    2 => {
                        let dup = l[line].clone();
                        l.insert(line, dup);
                    }
                    _ => l[line].truncate(value % 12),
                }
            }
            check(&l.join("\n"))
        })
        .unwrap();
}
