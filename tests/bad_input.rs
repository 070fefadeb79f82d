//! Bad input the fault issue names and the other CLI tests do not cover: a scene whose
//! render would exceed the memory bound is refused up front with the estimate.

use magg_tests::*;

#[test]
fn a_scene_over_the_memory_bound_is_refused_up_front_with_the_estimate() {
    let dir = tempfile::tempdir().unwrap();
    let out = run_host([
        "render".as_ref(),
        scene("cornell.toml").as_os_str(),
        "--out".as_ref(),
        dir.path().join("x.png").as_os_str(),
        "--element-size".as_ref(),
        "0.004".as_ref(),
        "--max-memory-mb".as_ref(),
        "256".as_ref(),
    ]);
    let line = assert_user_error(&out, "over the memory bound");
    for part in ["cornell.toml", "MB (", "elements", "--max-memory-mb 256"] {
        assert!(line.contains(part), "{part:?} missing from: {line}");
    }
    assert!(!dir.path().join("x.png").exists());
}

#[test]
fn the_same_scene_under_the_bound_renders() {
    let dir = tempfile::tempdir().unwrap();
    let r = render(
        &scene("cornell.toml"),
        dir.path(),
        "ok",
        &["--embedded", "--width", "16", "--height", "16", "--light-rays", "1", "--max-memory-mb", "256"],
    );
    assert!(r.png.is_file());
}
