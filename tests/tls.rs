//! TLS on the cluster's channels: with a throwaway CA and a server certificate for
//! 127.0.0.1 made at test time (rcgen), a fork, a node and the host render over TLS and
//! the image is bitwise the embedded one; a plaintext client of a TLS fork is refused
//! with one clear line, and nothing panics.

use magg_tests::*;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

const TINY: &[&str] = &["--width", "32", "--height", "32", "--light-rays", "2", "--pixel-samples", "1"];

/// PEM files of a test CA and of a certificate it signed for `localhost` and 127.0.0.1.
struct Pki {
    ca: PathBuf,
    cert: PathBuf,
    key: PathBuf,
}

impl Pki {
    fn new(dir: &Path) -> Pki {
        use rcgen::{BasicConstraints, CertificateParams, DnType, IsCa, KeyPair};
        let ca_key = KeyPair::generate().unwrap();
        let mut ca_params = CertificateParams::new(Vec::<String>::new()).unwrap();
        ca_params.is_ca = IsCa::Ca(BasicConstraints::Unconstrained);
        ca_params.distinguished_name.push(DnType::CommonName, "magg test CA");
        let ca = ca_params.self_signed(&ca_key).unwrap();
        let key = KeyPair::generate().unwrap();
        let mut params = CertificateParams::new(vec!["localhost".to_string(), "127.0.0.1".to_string()]).unwrap();
        params.distinguished_name.push(DnType::CommonName, "magg test server");
        let cert = params.signed_by(&key, &ca, &ca_key).unwrap();
        let pki = Pki { ca: dir.join("ca.pem"), cert: dir.join("server.pem"), key: dir.join("server.key") };
        std::fs::write(&pki.ca, ca.pem()).unwrap();
        std::fs::write(&pki.cert, cert.pem()).unwrap();
        std::fs::write(&pki.key, key.serialize_pem()).unwrap();
        pki
    }

    /// `--tls-cert C --tls-key K --tls-ca A`.
    fn all_flags(&self) -> Vec<String> {
        let s = |p: &Path| p.display().to_string();
        ["--tls-cert", &s(&self.cert), "--tls-key", &s(&self.key), "--tls-ca", &s(&self.ca)].map(String::from).to_vec()
    }
}

/// A command with no TLS or token settings inherited from the environment.
fn clean(mut c: Command) -> Command {
    for v in ["MAGG_TLS_CERT", "MAGG_TLS_KEY", "MAGG_TLS_CA", "MAGG_TOKEN"] {
        c.env_remove(v);
    }
    c
}

#[test]
fn a_render_over_tls_is_bitwise_the_embedded_one() {
    let dir = tempfile::tempdir().unwrap();
    let pki = Pki::new(dir.path());
    let tls = pki.all_flags();
    let tls: Vec<&str> = tls.iter().map(String::as_str).collect();
    let mut fork_args = tls.clone();
    fork_args.extend(["--token", "tls-token"]);
    let (fork, fork_addr) = spawn_fork(0, &fork_args, &dir.path().join("fork.log"));
    let mut procs = Procs(vec![fork]);

    let host_addr = format!("127.0.0.1:{}", free_port());
    let out = Rendered::at(dir.path(), "tls");
    let mut host = clean(out.command(&scene("magg-paper.toml")));
    host.args(TINY)
        .args(["--forks-at", &fork_addr, "--listen", &host_addr, "--external-nodes", "--min-nodes", "1"])
        .args(&tls)
        .env("MAGG_TOKEN", "tls-token")
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    procs.0.push(host.spawn().unwrap());

    // The node only needs the CA (it serves nothing); token and CA from the environment.
    let node = clean(Command::new(magg_bin("magg-node")))
        .args(["--host", &host_addr, "--connect-timeout", "30"])
        .env("MAGG_TOKEN", "tls-token")
        .env("MAGG_TLS_CA", &pki.ca)
        .output()
        .unwrap();
    let node_err = String::from_utf8_lossy(&node.stderr);
    assert!(node.status.success(), "node over TLS failed: {node_err}");

    let mut host = procs.0.pop().unwrap();
    let st = host.wait().unwrap();
    let mut log = String::new();
    std::io::Read::read_to_string(&mut host.stderr.take().unwrap(), &mut log).unwrap();
    assert!(st.success(), "host over TLS failed: {log}");

    let embedded = render(&scene("magg-paper.toml"), dir.path(), "embedded", &[TINY, &["--embedded"]].concat());
    let (w, h, tls_rgb) = read_png_rgb(&out.png);
    let (_, _, embedded_rgb) = read_png_rgb(&embedded.png);
    assert_eq!((w, h), (32, 32));
    assert!(not_all_black(&tls_rgb));
    assert!(tls_rgb == embedded_rgb, "the TLS render differs from the embedded one");
}

#[test]
fn a_plaintext_client_of_a_tls_fork_is_refused_with_one_clear_line() {
    let dir = tempfile::tempdir().unwrap();
    let pki = Pki::new(dir.path());
    let tls = pki.all_flags();
    let tls: Vec<&str> = tls.iter().map(String::as_str).collect();
    let (fork, fork_addr) = spawn_fork(0, &tls, &dir.path().join("fork.log"));
    let _procs = Procs(vec![fork]);

    // A probe without the CA speaks plaintext HTTP/2 to the TLS port.
    let probe = clean(Command::new(magg_bin("magg-fork"))).args(["probe", &fork_addr]).output().unwrap();
    let err = String::from_utf8_lossy(&probe.stderr);
    assert!(!probe.status.success(), "a plaintext probe of a TLS fork succeeded");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.starts_with(&format!("magg-fork: {fork_addr}: ")) && !err.contains("panicked"), "{err}");
    // With the CA from the environment it speaks TLS and is answered.
    let probe = clean(Command::new(magg_bin("magg-fork")))
        .args(["probe", &fork_addr])
        .env("MAGG_TLS_CA", &pki.ca)
        .output()
        .unwrap();
    assert!(probe.status.success(), "{}", String::from_utf8_lossy(&probe.stderr));
    // magg-host's probe (the host image's health check) takes the CA as a flag too.
    let probe = clean(magg_host()).args(["probe", "--tls-ca"]).arg(&pki.ca).arg(&fork_addr).output().unwrap();
    assert!(probe.status.success(), "{}", String::from_utf8_lossy(&probe.stderr));
    let probe = clean(magg_host()).args(["probe", &fork_addr]).output().unwrap();
    assert!(!probe.status.success(), "magg-host probed a TLS fork in plaintext");

    // A host without TLS flags stops with one line naming the fork.
    let o = clean(magg_host())
        .arg("render")
        .arg(scene("magg-paper.toml"))
        .arg("--out")
        .arg(dir.path().join("x.png"))
        .args(TINY)
        .args(["--quiet", "--forks-at", &fork_addr, "--nodes", "1", "--fork-timeout", "3"])
        .env("RUST_LOG", "error") // the retries' warnings aside
        .output()
        .unwrap();
    let line = assert_user_error(&o, "plaintext host against a TLS fork");
    assert!(line.contains(&fork_addr) && line.contains("is the peer serving TLS?"), "{line}");
}

#[test]
fn a_missing_certificate_file_is_named() {
    let o = clean(magg_host())
        .arg("render")
        .arg(scene("magg-paper.toml"))
        .args(["--out", "/tmp/never-written.png", "--quiet", "--forks-at", "127.0.0.1:1"])
        .args(["--tls-ca", "/nonexistent/ca.pem"])
        .output()
        .unwrap();
    let line = assert_user_error(&o, "missing CA file");
    assert!(line.contains("--tls-ca /nonexistent/ca.pem"), "{line}");
    let o = clean(Command::new(magg_bin("magg-fork"))).args(["--tls-cert", "/nonexistent/c.pem"]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("--tls-cert and --tls-key go together"), "{err}");
}
