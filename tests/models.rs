//! A model file renders on its own, in a scene made up around it (camera framing it, a
//! light beside the camera, grey where its MTL gives no colour); `--set` reaches that
//! scene's values as a file's.

use magg_tests::*;

#[test]
fn a_bare_obj_renders_framed_and_lit() {
    let dir = tempfile::tempdir().unwrap();
    let model = workspace_root().join("scenes/meshes/sphere.obj");
    let a =
        render(&model, dir.path(), "sphere", &["--width", "48", "--height", "40", "--light-rays", "2", "--spp", "1"]);
    let (w, h, rgb) = read_png_rgb(&a.png);
    assert_eq!((w, h), (48, 40));
    assert!(not_all_black(&rgb), "the model is not lit");
    // The model is in view: its centre pixel is lit, a corner is background.
    let px = |x: u32, y: u32| rgb[3 * (y * w + x) as usize..][..3].iter().map(|&c| c as u32).sum::<u32>();
    assert!(px(24, 20) > 0 && px(0, 0) == 0, "the model is not framed in the middle");
    let zoomed = render(
        &model,
        dir.path(),
        "zoom",
        &["--width", "48", "--height", "40", "--light-rays", "2", "--spp", "1", "--set", "camera.fov=10"],
    );
    let (_, _, z) = read_png_rgb(&zoomed.png);
    assert!(z[..3].iter().any(|&c| c > 0), "--set camera.fov=10 did not bring the model closer");
    let info = magg_host().arg("info").arg(&model).output().unwrap();
    assert_success(&info, "info on a model");
    assert!(String::from_utf8_lossy(&info.stdout).contains("1280"), "the sphere's 1280 patches");
}
