//! The live view end to end in a real headless browser: `magg-host render --view` on the
//! in-process cluster, Debian's chromium driven through chromedriver (WebDriver, via
//! fantoccini). The page is opened before the render starts (`--view-wait`), and the test
//! checks that it shows a preview during the light pass (with elapsed time and pairs per
//! second, and a placeholder, not a broken image, where the final image will be), then
//! the final image (the same PNG the host wrote), one map colour per node that traced,
//! and a row per node; that the pictures fit the window and zoom to 1:1 pixels; it saves
//! a screenshot as target/live-view.png.
//!
//! Without chromium and chromedriver on PATH (`.ci/run` installs them) the test prints a
//! SKIPPED line and passes.

use magg_tests::{magg_host, read_json, read_png_rgb, scene, target_dir};
use serde_json::{json, Value};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The first of `names` found on PATH.
fn on_path(names: &[&str]) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path).flat_map(|d| names.iter().map(move |n| d.join(n))).find(|p| p.is_file())
}

/// Kills a child process when dropped (the test may fail half-way).
struct Reaper(Child);
impl Drop for Reaper {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A plain HTTP/1.1 GET on 127.0.0.1: (status, body).
fn http_get(url: &str) -> (u32, Vec<u8>) {
    let rest = url.strip_prefix("http://").expect("http URL");
    let (host, path) = rest.split_once('/').map(|(h, p)| (h, format!("/{p}"))).unwrap_or((rest, "/".into()));
    let mut s = TcpStream::connect(host).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    write!(s, "GET {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n").unwrap();
    let mut raw = Vec::new();
    s.read_to_end(&mut raw).unwrap();
    let split = raw.windows(4).position(|w| w == b"\r\n\r\n").expect("HTTP header end");
    let head = String::from_utf8_lossy(&raw[..split]).into_owned();
    let status = head.split_whitespace().nth(1).and_then(|c| c.parse().ok()).unwrap_or(0);
    assert!(!head.to_ascii_lowercase().contains("transfer-encoding: chunked"), "unexpected chunked reply:\n{head}");
    (status, raw[split + 4..].to_vec())
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

async fn js(c: &fantoccini::Client, script: &str) -> Value {
    c.execute(script, vec![]).await.unwrap_or_else(|e| panic!("script {script:?} failed: {e}"))
}

/// Polls `script` until it returns something other than null/false, at most `limit`.
async fn wait_for(c: &fantoccini::Client, script: &str, limit: Duration) -> Value {
    let end = Instant::now() + limit;
    loop {
        let v = js(c, script).await;
        if !(v.is_null() || v == Value::Bool(false)) {
            return v;
        }
        assert!(Instant::now() < end, "timed out after {limit:?} waiting for {script:?}");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

/// Starts `host` (a `magg-host render ... --view ...` command) with its stderr read here;
/// returns it and the live view's URL, once printed. The rest of its log goes to `log`.
fn start_with_view(mut host: Command, log: impl Fn(String) + Send + 'static) -> (Reaper, String) {
    host.stdout(Stdio::null()).stderr(Stdio::piped());
    let mut host = Reaper(host.spawn().expect("cannot start magg-host"));
    let mut lines = BufReader::new(host.0.stderr.take().unwrap()).lines();
    let url = loop {
        let line = lines.next().expect("magg-host ended before printing the live view address").unwrap();
        if let Some(u) = line.strip_prefix("live view: ") {
            break u.trim().to_string();
        }
    };
    std::thread::spawn(move || lines.for_each(|l| log(l.unwrap_or_default())));
    (host, url)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn live_view_shows_the_render_in_a_headless_browser() {
    let (Some(chromium), Some(driver)) =
        (on_path(&["chromium", "chromium-browser", "google-chrome"]), on_path(&["chromedriver"]))
    else {
        eprintln!("\n*** SKIPPED live_view: chromium and chromedriver are not installed (apt-get install chromium chromium-driver; .ci/run does) ***\n");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (png, stats) = (dir.path().join("live.png"), dir.path().join("live.json"));

    // The host: waits for the page, then renders, then keeps serving for a minute. Many
    // light rays per pair: a light pass of a second or more, long enough for previews.
    let mut host = magg_host();
    host.arg("render")
        .arg(scene("cornell.toml"))
        .args(["--width", "96", "--height", "72", "--light-rays", "256", "--pixel-samples", "1"])
        .args(["--nodes", "2", "--forks", "2", "--subscreen", "8", "--quiet"])
        .args(["--view", "127.0.0.1:0", "--view-wait", "--view-linger", "60"])
        .arg("--out")
        .arg(&png)
        .arg("--stats")
        .arg(&stats);
    let (_host, url) = start_with_view(host, |l| eprintln!("magg-host: {l}"));

    // The browser.
    let port = free_port();
    let _driver = Reaper(
        Command::new(&driver)
            .arg(format!("--port={port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("cannot start chromedriver"),
    );
    let end = Instant::now() + Duration::from_secs(20);
    while TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(Instant::now() < end, "chromedriver did not listen on port {port}");
        std::thread::sleep(Duration::from_millis(50));
    }
    let caps = json!({"goog:chromeOptions": {
        "binary": chromium,
        "args": ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--window-size=1400,1000"],
    }});
    let caps = match caps {
        Value::Object(m) => m,
        _ => unreachable!(),
    };
    let client = fantoccini::ClientBuilder::new(hyper_util::client::legacy::connect::HttpConnector::new())
        .capabilities(caps)
        .connect(&format!("http://127.0.0.1:{port}"))
        .await
        .expect("cannot open a WebDriver session with chromium");

    let t0 = Instant::now();
    eprintln!("browser session open; opening {url}");
    client.goto(&url).await.unwrap();
    // The render starts once the page's event stream is open. During the light pass the
    // page shows a preview, the clock and the pairs per second; the final image is a
    // placeholder, not a broken image.
    let during = wait_for(
        &client,
        "const s = document.getElementById('status').textContent;
         if (window.magg.previews() === 0 || !s.startsWith('light ray tracing')) return false;
         return [document.getElementById('timing').textContent,
                 getComputedStyle(document.getElementById('final')).display,
                 getComputedStyle(document.getElementById('final-wait')).display]",
        Duration::from_secs(60),
    )
    .await;
    eprintln!("during the light pass: {during}");
    let timing = during[0].as_str().unwrap();
    assert!(timing.contains("elapsed") && timing.contains("pairs/s"), "timing line {timing:?}");
    assert_eq!(during[1], json!("none"), "the final image's element shows before there is an image");
    assert_ne!(during[2], json!("none"), "no placeholder where the final image will be");
    wait_for(&client, "return document.body.dataset.state === 'done'", Duration::from_secs(90)).await;
    eprintln!("render shown done after {:.1} s", t0.elapsed().as_secs_f64());
    let size = js(&client, "return window.magg.size()").await;
    let (w, h) = (size[0].as_u64().unwrap(), size[1].as_u64().unwrap());
    assert_eq!((w, h), (96, 72), "the page's frame size");

    // The final image is shown, at the frame's size.
    let natural =
        js(&client, "const i = document.getElementById('final'); return [i.complete, i.naturalWidth, i.naturalHeight]")
            .await;
    assert_eq!(natural, json!([true, 96, 72]), "the final image is not displayed");

    // One map colour per node that traced, each that node's colour. The map canvas is
    // redrawn on the next animation frame: poll until it holds no pending colour.
    let want = wait_for(
        &client,
        "const want = window.magg.tracedBy().map(n => window.magg.nodeColour(n).join(',')).sort();
         const got = window.magg.mapColours();
         return JSON.stringify(want) === JSON.stringify(got) ? want : false",
        Duration::from_secs(10),
    )
    .await;
    let st = read_json(&stats);
    let traced: Vec<u64> = st["per_node"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|n| n["tiles"].as_u64().unwrap_or(0) > 0)
        .map(|n| n["node"].as_u64().unwrap())
        .collect();
    assert!(!traced.is_empty());
    assert_eq!(want.as_array().unwrap().len(), traced.len(), "map colours {want} vs nodes that traced {traced:?}");
    assert_eq!(js(&client, "return window.magg.tracedBy()").await, json!(traced), "nodes on the map vs the stats");
    // The frame canvas shows the final frame, tone-mapped as the host's PNG (to within
    // one step of rounding: the page computes in JavaScript).
    let canvas = js(&client, "return window.magg.framePixels()").await;
    let canvas: Vec<u64> = canvas.as_array().unwrap().iter().map(|v| v.as_u64().unwrap()).collect();
    let (pw, ph, rgb) = read_png_rgb(&png);
    assert_eq!((pw, ph), (96, 72));
    let worst = rgb
        .chunks_exact(3)
        .zip(canvas.chunks_exact(4))
        .flat_map(|(p, c)| (0..3).map(move |k| (p[k] as i64 - c[k] as i64).abs()))
        .max()
        .unwrap();
    assert!(worst <= 1, "the page's frame differs from the PNG by up to {worst} steps");
    // Every preview came during the light pass, and the last one shows lit pixels.
    let stages = js(&client, "return window.magg.previewStages()").await;
    assert_eq!(stages, json!(["light ray tracing"]), "previews arrived during {stages}");
    let lit = js(&client, "return window.magg.previewLit()").await.as_u64().unwrap();
    assert!(lit > 0, "the light pass preview is black");
    assert_eq!(
        js(&client, "return window.magg.previewShown()").await,
        json!(false),
        "the preview outlives the light pass"
    );
    // The pictures fit the window (wider than the frame here); 1:1 shows the frame's pixels.
    let shown_width = "return document.getElementById('frame').getBoundingClientRect().width";
    let fitted = js(&client, shown_width).await.as_f64().unwrap();
    assert!(fitted > 96.0, "the frame is shown {fitted} px wide in a 1400 px window");
    client.find(fantoccini::Locator::Id("zoom")).await.unwrap().click().await.unwrap();
    assert_eq!(js(&client, shown_width).await.as_f64().unwrap(), 96.0, "1:1 pixels");
    let rows = js(&client, "return document.querySelectorAll('#nodes tbody tr').length").await;
    assert_eq!(rows, json!(2), "the node table has a row per node");
    let status = js(&client, "return document.getElementById('status').textContent").await;
    assert_eq!(status, json!("done"));

    // Screenshot for CI, then the downloads: the PNG is the file the host wrote.
    let shot = client.screenshot().await.unwrap();
    let shot_path: PathBuf = target_dir().join("live-view.png");
    std::fs::write(&shot_path, &shot).unwrap();
    eprintln!("live view screenshot: {}", shot_path.display());
    assert!(shot.starts_with(b"\x89PNG"), "the screenshot is not a PNG");
    client.close().await.unwrap();

    let (code, body) = http_get(&format!("{url}image.png"));
    assert_eq!(code, 200);
    assert_eq!(body, std::fs::read(Path::new(&png)).unwrap(), "the page's PNG differs from the --out file");
    let (code, body) = http_get(&format!("{url}image.exr"));
    assert_eq!(code, 200);
    assert!(body.starts_with(&[0x76, 0x2f, 0x31, 0x01]), "image.exr is not OpenEXR");
}

/// `--view-wait` holds the render until a page opens the live view; that wait is not the
/// render's: the stats' total leaves it out, on the cluster and embedded. A page comes 3 s
/// late to a render of a few milliseconds; the host waited at least that long after it
/// printed the address, so a total that counted the wait would exceed the sum of the
/// stages by more than it.
#[test]
fn the_stats_total_leaves_out_the_wait_for_a_viewer() {
    for mode in [None, Some("--embedded")] {
        let dir = tempfile::tempdir().unwrap();
        let stats = dir.path().join("s.json");
        let mut host = magg_host();
        host.arg("render")
            .arg(scene("magg-paper.toml"))
            .args(["--width", "16", "--height", "16", "--light-rays", "2", "--pixel-samples", "1", "--quiet"])
            .args(["--view", "127.0.0.1:0", "--view-wait"])
            .args(mode)
            .arg("--out")
            .arg(dir.path().join("p.png"))
            .arg("--stats")
            .arg(&stats);
        let (mut host, url) = start_with_view(host, drop);
        let t_address = Instant::now();
        std::thread::sleep(Duration::from_secs(3));
        // A page opens the event stream (and keeps it open while the render runs).
        let addr = url.trim_start_matches("http://").trim_end_matches('/').to_string();
        let mut stream = TcpStream::connect(&addr).unwrap();
        let waited = t_address.elapsed().as_secs_f64();
        write!(stream, "GET /events HTTP/1.1\r\nHost: {addr}\r\n\r\n").unwrap();
        let status = host.0.wait().unwrap();
        assert!(status.success(), "the render ({mode:?}) failed: {status}");
        let st = &read_json(&stats)["stages"];
        let total = st["total_s"].as_f64().unwrap();
        let stages: f64 = ["preprocess_s", "lrt_s", "interp_s", "vrt_s"].iter().map(|k| st[k].as_f64().unwrap()).sum();
        assert!(total >= stages, "total_s {total} is less than the stages' sum {stages} ({mode:?})");
        assert!(
            total - stages < waited,
            "total_s {total} exceeds the stages' sum {stages} by the {waited:.1} s spent waiting for a viewer ({mode:?})"
        );
    }
}
