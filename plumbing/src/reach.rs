//! Whether a listen address can be reached from outside this machine's private networks,
//! which is when a server without a cluster token deserves a warning
//! ([`crate::auth::exposure_warning`]).
//!
//! The rule: an address is *public* unless it is loopback, unspecified, private
//! (RFC 1918: 10/8, 172.16/12, 192.168/16), shared (CGNAT, RFC 6598: 100.64/10),
//! link-local (169.254/16, fe80::/10), a unique local IPv6 address (RFC 4193: fc00::/7),
//! multicast or broadcast; an IPv4-mapped IPv6 address counts as its IPv4 address.
//! A server bound to a public address is reachable from outside. One bound to the
//! unspecified address (`0.0.0.0`, `::`) listens on every interface, so it is reachable
//! from outside when the machine has a public interface address (IPv4 ones for
//! `0.0.0.0`, any for `::`); when the interfaces cannot be listed it counts as reachable.
//! So a container on a compose network or a pod on a cluster's private range is quiet,
//! and a server on a machine with a public address is not.
//!
//! ```
//! use magg_plumbing::reach::{is_public, reachable_from_outside};
//! assert!(!is_public("10.0.0.7".parse().unwrap()));
//! let private_machine = ["127.0.0.1".parse().unwrap(), "172.18.0.5".parse().unwrap()];
//! assert!(!reachable_from_outside("0.0.0.0:7100".parse().unwrap(), Some(&private_machine)));
//! ```

use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr};

/// True for an address that may be reached from beyond this machine's private networks
/// (see the module doc for the rule).
pub fn is_public(ip: IpAddr) -> bool {
    match ip {
        IpAddr::V4(v4) => is_public_v4(v4),
        IpAddr::V6(v6) => match v6.to_ipv4_mapped() {
            Some(v4) => is_public_v4(v4),
            None => is_public_v6(v6),
        },
    }
}

fn is_public_v4(ip: Ipv4Addr) -> bool {
    let [a, b, ..] = ip.octets();
    let shared = a == 100 && (64..128).contains(&b);
    !(ip.is_loopback()
        || ip.is_unspecified()
        || ip.is_private()
        || ip.is_link_local()
        || ip.is_multicast()
        || ip.is_broadcast()
        || shared)
}

fn is_public_v6(ip: Ipv6Addr) -> bool {
    let first = ip.segments()[0];
    let unique_local = first & 0xfe00 == 0xfc00;
    let link_local = first & 0xffc0 == 0xfe80;
    !(ip.is_loopback() || ip.is_unspecified() || ip.is_multicast() || unique_local || link_local)
}

/// True when a server listening on `listen` can be reached from outside: a public
/// address, or the unspecified address on a machine that has a public interface address
/// among `interfaces` (`None`: they could not be listed, which counts as yes).
pub fn reachable_from_outside(listen: SocketAddr, interfaces: Option<&[IpAddr]>) -> bool {
    let ip = listen.ip();
    if !ip.is_unspecified() {
        return is_public(ip);
    }
    let Some(interfaces) = interfaces else { return true };
    // `0.0.0.0` takes IPv4 only; `::` is dual-stack on Linux, so it takes both.
    interfaces.iter().filter(|a| ip.is_ipv6() || a.is_ipv4()).any(|a| is_public(*a))
}

/// The addresses of this machine's network interfaces, or `None` if they cannot be
/// listed.
pub fn interface_addresses() -> Option<Vec<IpAddr>> {
    match if_addrs::get_if_addrs() {
        Ok(list) => Some(list.into_iter().map(|i| i.ip()).collect()),
        Err(e) => {
            tracing::debug!("cannot list the network interfaces: {e}");
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ip(s: &str) -> IpAddr {
        s.parse().unwrap()
    }

    #[test]
    fn private_shared_link_local_and_loopback_addresses_are_not_public() {
        for a in [
            "127.0.0.1",
            "10.1.2.3",
            "172.16.0.1",
            "172.31.255.254",
            "192.168.1.1",
            "100.64.0.1",
            "100.127.255.254",
            "169.254.3.4",
            "0.0.0.0",
            "255.255.255.255",
            "224.0.0.1",
            "::1",
            "::",
            "fd12:3456::1",
            "fc00::1",
            "fe80::1",
            "ff02::1",
            "::ffff:10.0.0.1",
        ] {
            assert!(!is_public(ip(a)), "{a} is not public");
        }
    }

    #[test]
    fn the_neighbours_of_private_ranges_are_public() {
        for a in ["8.8.8.8", "172.15.255.255", "172.32.0.0", "100.63.255.255", "100.128.0.0", "11.0.0.1"] {
            assert!(is_public(ip(a)), "{a} is public");
        }
        for a in ["2001:db8::1", "2a00:1450::1", "fbff::1", "::ffff:8.8.8.8"] {
            assert!(is_public(ip(a)), "{a} is public");
        }
    }

    #[test]
    fn a_specific_address_decides_by_itself() {
        let public = [ip("203.0.113.9")];
        assert!(!reachable_from_outside("127.0.0.1:7100".parse().unwrap(), Some(&public)));
        assert!(!reachable_from_outside("10.0.0.2:7100".parse().unwrap(), Some(&public)));
        assert!(reachable_from_outside("198.51.100.1:7100".parse().unwrap(), Some(&[])));
    }

    #[test]
    fn the_unspecified_address_is_reachable_only_through_a_public_interface() {
        let container = [ip("127.0.0.1"), ip("::1"), ip("172.18.0.5"), ip("fe80::42:acff:fe12:5")];
        let server = [ip("127.0.0.1"), ip("192.168.0.2"), ip("203.0.113.9")];
        let v6_only = [ip("127.0.0.1"), ip("10.0.0.2"), ip("2001:db8::7")];
        let any4: SocketAddr = "0.0.0.0:7100".parse().unwrap();
        let any6: SocketAddr = "[::]:7100".parse().unwrap();
        assert!(!reachable_from_outside(any4, Some(&container)));
        assert!(!reachable_from_outside(any6, Some(&container)));
        assert!(reachable_from_outside(any4, Some(&server)));
        assert!(reachable_from_outside(any6, Some(&server)));
        assert!(!reachable_from_outside(any4, Some(&v6_only)), "0.0.0.0 does not listen on IPv6");
        assert!(reachable_from_outside(any6, Some(&v6_only)));
        assert!(reachable_from_outside(any4, None), "interfaces unknown: warn");
    }
}
