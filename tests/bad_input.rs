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

#[test]
fn a_refinement_over_the_memory_bound_is_refused_before_the_render() {
    // cornell.toml refines three times: the estimate up front cannot know how many elements
    // the pilot passes split, so the refined scene is checked again.
    let dir = tempfile::tempdir().unwrap();
    let args = ["--width", "16", "--height", "16", "--max-memory-mb", "100"];
    let out =
        run_host(
            [
                &[
                    "render",
                    scene("cornell.toml").to_str().unwrap(),
                    "--out",
                    dir.path().join("x.png").to_str().unwrap(),
                ][..],
                &args,
            ]
            .concat(),
        );
    let line = assert_user_error(&out, "a refinement over the memory bound");
    for part in ["cornell.toml", "after 3 levels of refinement", "elements", "--max-memory-mb 100"] {
        assert!(line.contains(part), "{part:?} missing from: {line}");
    }
    assert!(!dir.path().join("x.png").exists());
}

#[test]
fn a_scene_with_many_lights_is_refused_with_an_estimate_that_counts_pairs() {
    // The paper's scene (1664 elements) with 20,001 lights: 33 M (light, element) pairs,
    // about 40 MB of pair bookkeeping on 5 in-process forks, where elements and pixels
    // alone are about 1 MB.
    let dir = tempfile::tempdir().unwrap();
    let mut text = std::fs::read_to_string(scene("magg-paper.toml")).unwrap();
    for k in 0..20_000 {
        let x = -0.5 + (k % 100) as f64 * 0.001;
        text.push_str(&format!("\n[[light]]\nposition = [{x}, 2.6, 0.5]\nintensity = [0.01, 0.01, 0.01]\n"));
    }
    let many = dir.path().join("many-lights.toml");
    std::fs::write(&many, text).unwrap();
    let png = dir.path().join("x.png");
    let args = ["--width", "16", "--height", "16", "--forks", "5", "--max-memory-mb", "32"];
    let out = run_host(
        [&["render".as_ref(), many.as_os_str(), "--out".as_ref(), png.as_os_str()][..], &args.map(|a| a.as_ref())]
            .concat(),
    );
    let line = assert_user_error(&out, "over the memory bound");
    for part in
        ["many-lights.toml", "MB (1664 elements, 33281664 (light, element) pairs on 5 forks", "--max-memory-mb 32"]
    {
        assert!(line.contains(part), "{part:?} missing from: {line}");
    }
    assert!(!png.exists());
}
