//! The tcp mode hides this process's registered services (a test binary of its own: the
//! mode is process-wide).

use magg_plumbing::transport::{self, Mode};
use std::time::Duration;

#[test]
fn the_tcp_mode_ignores_registrations() {
    let addr = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().to_string();
    let (_reporter, health) = tonic_health::server::health_reporter();
    let _registered = transport::register(&addr, health);
    assert!(transport::wait_registered(&addr, Duration::from_millis(10)));
    transport::set_mode(Mode::Tcp);
    assert!(transport::in_process(&addr).is_none(), "tcp mode found the in-process service");
    assert!(!transport::wait_registered(&addr, Duration::from_secs(5)), "tcp mode waited for a registration");
    transport::set_mode(Mode::InProcess);
    assert!(transport::in_process(&addr).is_some());
}
