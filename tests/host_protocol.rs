//! The host's gRPC service refuses bad requests with gRPC errors and keeps serving.

use magg_proto::v1::host_client::HostClient;
use magg_proto::v1::{NextWorkRequest, RegisterRequest, Row, SubmitRowsRequest};
use magg_tests::*;
use std::process::{Command, Stdio};
use std::time::Duration;

#[test]
fn wrong_protocol_version_and_bad_requests_are_refused_and_the_render_goes_on() {
    let dir = tempfile::tempdir().unwrap();
    let host_addr = format!("127.0.0.1:{}", free_port());
    let out = dir.path().join("p.png");
    let host = magg_host()
        .arg("render")
        .arg(scene("magg-paper.toml"))
        .arg("--out")
        .arg(&out)
        .args(["--width", "32", "--height", "32", "--light-rays", "2", "--pixel-samples", "1", "--quiet"])
        .args(["--listen", &host_addr, "--external-nodes", "--forks", "2"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
    rt.block_on(async {
        let mut client = None;
        for _ in 0..200 {
            if let Ok(c) = HostClient::connect(format!("http://{host_addr}")).await {
                client = Some(c);
                break;
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        let mut c = client.expect("the host never listened");
        let e = c.register(RegisterRequest { protocol_version: 99, name: "old".into(), threads: 1 }).await.unwrap_err();
        assert_eq!(e.code(), tonic::Code::FailedPrecondition, "{e}");
        assert!(e.message().contains("99"), "{e}");
        let e = c.next_work(NextWorkRequest { node: 12345, report: None, node_secret: 0 }).await.unwrap_err();
        assert_eq!(e.code(), tonic::Code::InvalidArgument, "{e}");
        let e = c
            .submit_rows(SubmitRowsRequest {
                node: 0,
                subscreen: 7,
                rows: vec![Row { y: 0, rgb: vec![0u8; 12].into() }],
                last: false,
                node_secret: 0,
            })
            .await
            .unwrap_err();
        assert!(matches!(e.code(), tonic::Code::InvalidArgument | tonic::Code::FailedPrecondition), "{e}");
        let e = c
            .register(RegisterRequest {
                protocol_version: magg_proto::PROTOCOL_VERSION,
                name: "x".repeat(300),
                threads: 1,
            })
            .await
            .unwrap_err();
        assert_eq!(e.code(), tonic::Code::InvalidArgument);
        // A registered node's id is no use without its secret.
        let reg = c
            .register(RegisterRequest {
                protocol_version: magg_proto::PROTOCOL_VERSION,
                name: "victim".into(),
                threads: 1,
            })
            .await
            .unwrap()
            .into_inner();
        let forged = NextWorkRequest { node: reg.node, report: None, node_secret: reg.node_secret ^ 1 };
        let e = c.next_work(forged).await.unwrap_err();
        assert_eq!(e.code(), tonic::Code::PermissionDenied, "{e}");
        let forged = SubmitRowsRequest { node: reg.node, subscreen: 0, rows: vec![], last: true, node_secret: 0 };
        let e = c.submit_rows(forged).await.unwrap_err();
        assert_eq!(e.code(), tonic::Code::PermissionDenied, "{e}");
    });
    // A proper node still gets the render done.
    let mut node = Command::new(magg_bin("magg-node")).args(["--host", &host_addr]).spawn().unwrap();
    let done = host.wait_with_output().unwrap();
    let _ = node.wait();
    assert!(done.status.success(), "host failed after the bad requests: {}", String::from_utf8_lossy(&done.stderr));
    assert!(out.is_file());
}
