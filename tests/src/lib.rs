//! Support for magg's end-to-end tests: they run the real `magg-host` binary, as a user
//! or a script would, and read back what it wrote.
//!
//! `magg-host` lives in another package of the workspace, so [`magg_host`] builds it
//! once per test process (`cargo build -p magg-host`, same profile and target directory
//! as the tests) and returns a [`Command`] for it. Set `MAGG_HOST=/path/to/magg-host` to
//! test a binary built elsewhere instead.
//!
//! ```no_run
//! let dir = tempfile::tempdir().unwrap();
//! let out = magg_tests::render(
//!     &magg_tests::scene("magg-paper.toml"),
//!     dir.path(),
//!     "run",
//!     &["--width", "64", "--height", "64"],
//! );
//! let (w, h, rgb) = magg_tests::read_png_rgb(&out.png);
//! assert_eq!((w, h, rgb.len()), (64, 64, 64 * 64 * 3));
//! ```

pub mod docker;

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output};
use std::sync::OnceLock;

/// The workspace root (the parent of this package).
pub fn workspace_root() -> PathBuf {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    here.parent().expect("the tests package sits inside the workspace").to_path_buf()
}

/// The path of `scenes/<name>` in the workspace.
pub fn scene(name: &str) -> PathBuf {
    workspace_root().join("scenes").join(name)
}

/// The cargo target directory the tests were built into: `CARGO_TARGET_DIR` (relative
/// paths taken from the workspace root), else `<workspace>/target`.
pub fn target_dir() -> PathBuf {
    match std::env::var_os("CARGO_TARGET_DIR") {
        Some(d) if !d.is_empty() => {
            let d = PathBuf::from(d);
            if d.is_absolute() {
                d
            } else {
                workspace_root().join(d)
            }
        }
        _ => workspace_root().join("target"),
    }
}

/// Builds `magg-host` (once per process) with the tests' profile and returns its path.
fn host_binary() -> &'static Path {
    static BIN: OnceLock<PathBuf> = OnceLock::new();
    BIN.get_or_init(|| {
        if let Some(p) = std::env::var_os("MAGG_HOST") {
            return PathBuf::from(p);
        }
        let release = !cfg!(debug_assertions);
        let target = target_dir();
        let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
        let mut cmd = Command::new(cargo);
        cmd.current_dir(workspace_root())
            .args(["build", "--quiet", "-p", "magg-host", "-p", "magg-fork", "-p", "magg-node"])
            .arg("--target-dir")
            .arg(&target);
        if release {
            cmd.arg("--release");
        }
        let out = cmd.output().unwrap_or_else(|e| panic!("cannot run cargo to build magg-host: {e}"));
        assert!(
            out.status.success(),
            "cargo build -p magg-host failed ({}):\n{}",
            out.status,
            String::from_utf8_lossy(&out.stderr)
        );
        let profile = if release { "release" } else { "debug" };
        let bin = target.join(profile).join(format!("magg-host{}", std::env::consts::EXE_SUFFIX));
        assert!(bin.is_file(), "built magg-host but {} is missing", bin.display());
        bin
    })
}

/// Path of a cluster binary (`magg-fork`, `magg-node`) built beside `magg-host`.
pub fn magg_bin(name: &str) -> PathBuf {
    let host = host_binary();
    host.with_file_name(format!("{name}{}", std::env::consts::EXE_SUFFIX))
}

/// A [`Command`] for the `magg-host` binary, built if needed, run from the workspace
/// root with logging quiet.
pub fn magg_host() -> Command {
    let mut cmd = Command::new(host_binary());
    cmd.current_dir(workspace_root()).env_remove("RUST_LOG");
    cmd
}

/// Runs `magg-host` with `args` and returns what it did.
pub fn run_host<I, S>(args: I) -> Output
where
    I: IntoIterator<Item = S>,
    S: AsRef<OsStr>,
{
    magg_host().args(args).output().expect("cannot start magg-host")
}

/// Panics with the command's output unless it exited with status 0.
pub fn assert_success(out: &Output, what: &str) {
    assert!(
        out.status.success(),
        "{what} failed with {}:\nstdout:\n{}\nstderr:\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The files of one render.
#[derive(Clone, Debug)]
pub struct Rendered {
    /// Tone-mapped PNG (`--out`).
    pub png: PathBuf,
    /// Linear PFM (`--linear`).
    pub pfm: PathBuf,
    /// Energy CSV (`--energy`).
    pub energy: PathBuf,
    /// Stats JSON (`--stats`).
    pub stats: PathBuf,
}

impl Rendered {
    /// The files `<stem>.png`, `<stem>.pfm`, `<stem>.csv` and `<stem>.json` in `dir`.
    pub fn at(dir: &Path, stem: &str) -> Rendered {
        Rendered {
            png: dir.join(format!("{stem}.png")),
            pfm: dir.join(format!("{stem}.pfm")),
            energy: dir.join(format!("{stem}.csv")),
            stats: dir.join(format!("{stem}.json")),
        }
    }

    /// A `magg-host render SCENE` command writing these files, quiet.
    pub fn command(&self, scene: &Path) -> Command {
        let mut c = magg_host();
        c.arg("render").arg(scene).arg("--out").arg(&self.png).arg("--linear").arg(&self.pfm);
        c.arg("--energy").arg(&self.energy).arg("--stats").arg(&self.stats).arg("--quiet");
        c
    }
}

/// Children killed and reaped on drop, so that a failing test leaves no process behind.
#[derive(Debug, Default)]
pub struct Procs(pub Vec<Child>);

impl Drop for Procs {
    fn drop(&mut self) {
        for c in &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// Starts `magg-fork --listen 127.0.0.1:PORT` (port 0: the fork picks one, which no other
/// process can take meanwhile) with `extra` flags, its log copied to `log`; returns the
/// process and the address it listens on, once it does.
pub fn spawn_fork(port: u16, extra: &[&str], log: &Path) -> (Child, String) {
    use std::io::{BufRead, Write};
    let mut child = Command::new(magg_bin("magg-fork"))
        .args(["--listen", &format!("127.0.0.1:{port}")])
        .args(extra)
        .env("NO_COLOR", "1")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("cannot start magg-fork");
    let stderr = child.stderr.take().expect("piped stderr");
    let mut file = std::fs::File::create(log).expect("cannot create the fork's log");
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in std::io::BufReader::new(stderr).lines().map_while(Result::ok) {
            let _ = writeln!(file, "{line}");
            if let Some(at) = line.find("listening").and_then(|i| line[i..].find("127.0.0.1:").map(|j| i + j)) {
                let port: String = line[at + 10..].chars().take_while(char::is_ascii_digit).collect();
                let _ = tx.send(format!("127.0.0.1:{port}"));
            }
        }
    });
    match rx.recv_timeout(std::time::Duration::from_secs(60)) {
        Ok(addr) => (child, addr),
        Err(e) => {
            let _ = child.kill();
            panic!("magg-fork did not start listening: {e}; log in {}", log.display())
        }
    }
}

/// A TCP port on 127.0.0.1 that was free a moment ago.
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("cannot bind a port on 127.0.0.1")
}

/// Renders `scene` into `dir` as `<stem>.png`, `<stem>.pfm`, `<stem>.csv` and
/// `<stem>.json`, with `extra` flags (overrides, cluster shape), and checks it succeeded.
pub fn render(scene: &Path, dir: &Path, stem: &str, extra: &[&str]) -> Rendered {
    let r = Rendered::at(dir, stem);
    let out = r.command(scene).args(extra).output().expect("cannot start magg-host");
    assert_success(&out, &format!("magg-host render {} {}", scene.display(), extra.join(" ")));
    r
}

/// Decodes an 8-bit RGB PNG: (width, height, rows of RGB bytes). Panics on anything else.
pub fn read_png_rgb(path: &Path) -> (u32, u32, Vec<u8>) {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("cannot open {}: {e}", path.display()));
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .unwrap_or_else(|e| panic!("{} is not a PNG: {e}", path.display()));
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap_or_else(|e| panic!("cannot decode {}: {e}", path.display()));
    assert_eq!(
        (info.color_type, info.bit_depth),
        (png::ColorType::Rgb, png::BitDepth::Eight),
        "{}: expected 8-bit RGB",
        path.display()
    );
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

/// The header every PFM of `width` x `height` that magg writes starts with.
pub fn pfm_header(width: u32, height: u32) -> String {
    format!("PF\n{width} {height}\n-1.0\n")
}

/// Reads a little-endian RGB PFM as magg writes it: (width, height, f32 samples).
pub fn read_pfm(path: &Path) -> (u32, u32, Vec<f32>) {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    // Three header lines: "PF", "W H", "-1.0".
    let mut lines = 0;
    let mut end = 0;
    for (i, &b) in bytes.iter().enumerate() {
        if b == b'\n' {
            lines += 1;
            if lines == 3 {
                end = i + 1;
                break;
            }
        }
    }
    assert_eq!(lines, 3, "{}: PFM header incomplete", path.display());
    let header = std::str::from_utf8(&bytes[..end]).expect("PFM header is ASCII");
    let mut it = header.lines();
    assert_eq!(it.next(), Some("PF"), "{}: not an RGB PFM", path.display());
    let dims: Vec<u32> =
        it.next().unwrap().split_whitespace().map(|s| s.parse().expect("PFM dimensions are integers")).collect();
    assert_eq!(dims.len(), 2, "{}: bad PFM dimensions", path.display());
    assert_eq!(it.next(), Some("-1.0"), "{}: expected little-endian scale -1.0", path.display());
    let data = &bytes[end..];
    let n = dims[0] as usize * dims[1] as usize * 3;
    assert_eq!(data.len(), n * 4, "{}: PFM data size does not match {}x{}", path.display(), dims[0], dims[1]);
    let samples = data.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    (dims[0], dims[1], samples)
}

/// One row of an energy CSV.
#[derive(Clone, Debug, PartialEq)]
pub struct EnergyRow {
    /// `element` or `vertex`.
    pub kind: String,
    /// The other nine fields, `None` where empty (a vertex's patch and area).
    pub values: Vec<Option<f64>>,
}

/// The header line of the energy CSV.
pub const ENERGY_HEADER: &str = "kind,id,patch,x,y,z,area,r,g,b";

/// Reads an energy CSV, checking its header, the field count of every row and that every
/// non-empty field parses as a number.
pub fn read_energy(path: &Path) -> Vec<EnergyRow> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some(ENERGY_HEADER), "{}: header", path.display());
    lines
        .enumerate()
        .map(|(i, line)| {
            let f: Vec<&str> = line.split(',').collect();
            assert_eq!(f.len(), 10, "{}:{}: {line:?}", path.display(), i + 2);
            let values = f[1..]
                .iter()
                .map(|s| {
                    if s.is_empty() {
                        None
                    } else {
                        Some(
                            s.parse::<f64>()
                                .unwrap_or_else(|e| panic!("{}:{}: {s:?} is not a number: {e}", path.display(), i + 2)),
                        )
                    }
                })
                .collect();
            EnergyRow { kind: f[0].to_string(), values }
        })
        .collect()
}

/// Reads a JSON file.
pub fn read_json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{} is not JSON: {e}", path.display()))
}

/// Checks that `out` is a clean user error: exit code 1, no output on stdout, exactly one
/// line on stderr, starting `magg-host: error:`, and no panic. Returns that line.
pub fn assert_user_error(out: &Output, what: &str) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!stderr.contains("panicked"), "{what}: magg-host panicked:\n{stderr}");
    assert_eq!(out.status.code(), Some(1), "{what}: expected exit code 1, got {}; stderr:\n{stderr}", out.status);
    assert!(out.stdout.is_empty(), "{what}: unexpected stdout:\n{}", String::from_utf8_lossy(&out.stdout));
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "{what}: expected one line on stderr, got:\n{stderr}");
    assert!(
        lines[0].starts_with("magg-host: error: "),
        "{what}: stderr does not start with 'magg-host: error: ':\n{stderr}"
    );
    lines[0].to_string()
}

/// True when some byte of an 8-bit image is not zero.
pub fn not_all_black(rgb: &[u8]) -> bool {
    rgb.iter().any(|&b| b != 0)
}
