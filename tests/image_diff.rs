//! `magg-host diff A B`: a render against itself is identical with zero error, against one
//! with another seed it differs (relMSE > 0), its JSON parses and its heat map is a PNG of
//! the images' size; a mask keeps the pixels above its threshold; bad input is one error
//! line and `--fail-above` exits 2.

use magg_tests::*;

const TINY: &[&str] = &["--width", "32", "--height", "32", "--light-rays", "2", "--spp", "1", "--embedded"];
/// [`TINY`] half as wide.
const NARROW: &[&str] = &["--width", "16", "--height", "32", "--light-rays", "2", "--spp", "1", "--embedded"];

#[test]
fn a_render_diffs_to_zero_against_itself_and_not_against_another_seed() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene("magg-paper.toml");
    let a = render(&scene, dir.path(), "a", TINY);
    let b = render(&scene, dir.path(), "b", &[TINY, &["--seed", "7"]].concat());

    let same = run_host([std::ffi::OsStr::new("diff"), a.pfm.as_os_str(), a.pfm.as_os_str()]);
    assert_success(&same, "diff a a");
    let table = String::from_utf8_lossy(&same.stdout);
    assert!(table.contains("identical         yes"), "{table}");
    assert!(table.contains("relMSE            0.000000e0"), "{table}");

    let heat = dir.path().join("heat.png");
    let out =
        magg_host().arg("diff").arg(&a.pfm).arg(&b.pfm).arg("--json").arg("--heatmap").arg(&heat).output().unwrap();
    assert_success(&out, "diff a b --json");
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).expect("diff --json prints one JSON object");
    let rel = json["rel_mse"].as_f64().unwrap();
    assert!(rel > 0.0 && rel < 1.0, "relMSE {rel} of two seeds: {json}");
    assert_eq!(json["identical"], false);
    assert_eq!((json["width"].as_u64(), json["pixels"].as_u64()), (Some(32), Some(1024)));
    assert!((json["mean_ratio"].as_f64().unwrap() - 1.0).abs() < 0.05, "same scene, same brightness: {json}");
    let (w, h, rgb) = read_png_rgb(&heat);
    assert_eq!((w, h), (32, 32), "the heat map has the images' size");
    assert!(not_all_black(&rgb), "some error shows");

    // A PNG reads as sRGB decoded to linear, against itself identical.
    let png = run_host([std::ffi::OsStr::new("diff"), a.png.as_os_str(), a.png.as_os_str(), "--json".as_ref()]);
    assert_success(&png, "diff a.png a.png");
    assert_eq!(serde_json::from_slice::<serde_json::Value>(&png.stdout).unwrap()["identical"], true);

    let strict = magg_host().arg("diff").arg(&a.pfm).arg(&b.pfm).args(["--fail-above", "0"]).output().unwrap();
    assert_eq!(strict.status.code(), Some(2), "--fail-above 0 with relMSE {rel}");
    assert!(String::from_utf8_lossy(&strict.stderr).contains("above --fail-above 0"));
}

#[test]
fn images_that_cannot_be_compared_are_one_error_line_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene("magg-paper.toml");
    let a = render(&scene, dir.path(), "a", TINY);
    let narrow = render(&scene, dir.path(), "narrow", NARROW);
    let out = magg_host().arg("diff").arg(&a.pfm).arg(&narrow.pfm).output().unwrap();
    let line = assert_user_error(&out, "different sizes");
    assert!(line.contains("narrow.pfm") && line.contains("32 x 32 against 16 x 32"), "{line}");

    let nan = dir.path().join("nan.pfm");
    let mut bytes = b"PF\n1 1\n-1.0\n".to_vec();
    bytes.extend([f32::NAN, 0.0, 0.0].iter().flat_map(|v| v.to_le_bytes()));
    std::fs::write(&nan, bytes).unwrap();
    let line = assert_user_error(&magg_host().arg("diff").arg(&nan).arg(&nan).output().unwrap(), "a NaN pixel");
    assert!(line.contains("nan.pfm") && line.contains("NaN"), "{line}");

    let missing = dir.path().join("missing.exr");
    let line = assert_user_error(&magg_host().arg("diff").arg(&a.pfm).arg(&missing).output().unwrap(), "no such file");
    assert!(line.contains("missing.exr"), "{line}");
}

#[test]
fn a_mask_keeps_the_pixels_above_its_threshold() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene("magg-paper.toml");
    let a = render(&scene, dir.path(), "a", TINY);
    let b = render(&scene, dir.path(), "b", &[TINY, &["--seed", "7"]].concat());
    // Rows 0-15 wholly inside (1.0), rows 16-23 partly (0.7), the rest outside.
    let mask = dir.path().join("mask.pfm");
    let mut bytes = b"PF\n32 32\n-1.0\n".to_vec();
    for row in 0..32 {
        let v: f32 = if row < 16 {
            1.0
        } else if row < 24 {
            0.7
        } else {
            0.0
        };
        bytes.extend(std::iter::repeat_n(v, 32 * 3).flat_map(|c| c.to_le_bytes()));
    }
    std::fs::write(&mask, bytes).unwrap();
    let masked = |extra: &[&str]| {
        magg_host().arg("diff").arg(&a.pfm).arg(&b.pfm).arg("--mask").arg(&mask).args(extra).output().unwrap()
    };
    let pixels = |extra: &[&str]| {
        let out = masked(&[extra, &["--json"]].concat());
        assert_success(&out, "diff --mask");
        serde_json::from_slice::<serde_json::Value>(&out.stdout).unwrap()["pixels"].as_u64().unwrap()
    };
    assert_eq!(pixels(&[]), 24 * 32, "above one half by default");
    assert_eq!(pixels(&["--mask-above", "0.999"]), 16 * 32, "wholly inside");
    let none = assert_user_error(&masked(&["--mask-above", "1"]), "a mask that keeps nothing");
    assert!(none.contains("the mask keeps no pixel"), "{none}");
    let nan = assert_user_error(&masked(&["--mask-above", "NaN"]), "--mask-above NaN");
    assert!(nan.contains("expected a finite number"), "{nan}");
}
