//! What part of a render to make, from the command line: a crop window has exactly the
//! whole image's pixels there, in the embedded renderer and on the cluster; `--frames`
//! renders a range of a camera path under the frames' own numbers; `--set` overrides any
//! scene value and is checked like the file; `--spp` and `--threads` are aliases.

use magg_tests::*;

const SMALL: &[&str] = &["--width", "40", "--height", "30", "--light-rays", "4", "--spp", "1", "--threads", "2"];

#[test]
fn a_crop_window_has_the_whole_images_pixels_there() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene("cornell.toml");
    let whole = render(&scene, dir.path(), "whole", &[SMALL, &["--embedded"]].concat());
    let (w, _, full) = read_pfm(&whole.pfm);
    for (stem, mode) in [("crop-core", "--embedded"), ("crop-cluster", "--forks=3")] {
        let crop = render(&scene, dir.path(), stem, &[SMALL, &[mode, "--crop", "7,5,33,21"]].concat());
        let (cw, ch, px) = read_pfm(&crop.pfm);
        assert_eq!((cw, ch), (26, 16), "{stem}: the image is the window");
        // PFM rows run bottom-up: compare pixel by pixel through both files' row order.
        let (_, fh, _) = read_pfm(&whole.pfm);
        for y in 0..ch {
            for x in 0..cw {
                let (fy, cy) = (fh - 1 - (y + 5), ch - 1 - y);
                let a = &full[3 * (fy * w + x + 7) as usize..][..3];
                let b = &px[3 * (cy * cw + x) as usize..][..3];
                assert_eq!(a, b, "{stem}: pixel ({x}, {y}) of the window differs");
            }
        }
        let (pw, ph, _) = read_png_rgb(&crop.png);
        assert_eq!((pw, ph), (26, 16));
    }
    let out = magg_host()
        .arg("render")
        .arg(&scene)
        .args(["--out", "x.png", "--crop", "0,0,41,3"])
        .args(SMALL)
        .output()
        .unwrap();
    let line = assert_user_error(&out, "a window past the image");
    assert!(line.contains("--crop 0,0,41,3") && line.contains("40 x 30"), "{line}");
}

#[test]
fn a_frame_range_renders_those_frames_under_their_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene("paths/diffuse-orbit.toml");
    let out = dir.path().join("orbit.png");
    let run = magg_host()
        .arg("render")
        .arg(&scene)
        .arg("--out")
        .arg(&out)
        .args(["--width", "16", "--height", "12", "--light-rays", "2", "--spp", "1", "--frames", "5..7", "--quiet"])
        .output()
        .unwrap();
    assert_success(&run, "--frames 5..7");
    let mut names: Vec<String> =
        std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    assert_eq!(names, ["orbit_0005.png", "orbit_0006.png"]);
    let bad = magg_host().arg("render").arg(&scene).args(["--out", "x.png", "--frames", "20..30"]).output().unwrap();
    assert!(assert_user_error(&bad, "frames past the path").contains("24 frames"));
}

#[test]
fn set_overrides_any_scene_value_and_is_checked_like_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene("magg-paper.toml");
    let plain = render(&scene, dir.path(), "plain", &[SMALL, &["--embedded"]].concat());
    let moved = render(&scene, dir.path(), "moved", &[SMALL, &["--embedded", "--set", "camera.fov=20"]].concat());
    assert_ne!(read_pfm(&plain.pfm).2, read_pfm(&moved.pfm).2, "the camera did not change");
    let same = render(&scene, dir.path(), "same", &[SMALL, &["--embedded", "--set", "render.seed=1"]].concat());
    assert_eq!(read_pfm(&plain.pfm).2, read_pfm(&same.pfm).2, "an override of a value to itself changed the image");
    let out =
        magg_host().arg("render").arg(&scene).args(["--out", "x.png", "--set", "render.width=0"]).output().unwrap();
    let line = assert_user_error(&out, "an out-of-range override");
    assert!(line.contains("render.width") && line.contains("--set render.width=0"), "{line}");
    let info = magg_host().arg("info").arg(&scene).args(["--set", "render.element_size=0.5"]).output().unwrap();
    assert_success(&info, "info --set");
}
