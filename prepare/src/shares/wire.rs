//! The bytes of a step's request and reply between the host and a fork: bincode, with a
//! bound on what a decode may allocate, so that a malformed or hostile payload is an
//! error, never a panic or an allocation of its claimed length.

use super::steps::{Reply, Request};
use bincode::Options;

/// Largest payload decoded (the biggest reply, a share's packed blocks or its points, is
/// well under it for shares of up to 2^31 lattice points in 2 KB blocks: gRPC's message
/// limit bounds it first).
const LIMIT: u64 = 1 << 34;

fn options() -> impl Options {
    bincode::DefaultOptions::new().with_fixint_encoding().with_little_endian().with_limit(LIMIT)
}

/// Why a payload could not be read.
#[derive(Debug, thiserror::Error)]
#[error("malformed {what}: {source}")]
pub struct WireError {
    what: &'static str,
    #[source]
    source: bincode::Error,
}

/// A request's bytes.
pub fn encode_request(r: &Request) -> Vec<u8> {
    options().serialize(r).unwrap_or_default()
}

/// A request from its bytes.
pub fn decode_request(bytes: &[u8]) -> Result<Request, WireError> {
    options().deserialize(bytes).map_err(|source| WireError { what: "preparation request", source })
}

/// A reply's bytes.
pub fn encode_reply(r: &Reply) -> Vec<u8> {
    options().serialize(r).unwrap_or_default()
}

/// A reply from its bytes.
pub fn decode_reply(bytes: &[u8]) -> Result<Reply, WireError> {
    options().deserialize(bytes).map_err(|source| WireError { what: "preparation reply", source })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shares::{SharePatch, SpaceSplit};
    use glam::DVec3;
    use magg_core::prepared::Face;

    fn patch() -> SharePatch {
        SharePatch {
            id: 7,
            v: [DVec3::ZERO, DVec3::X, DVec3::Y],
            n: 3,
            first_element: 9,
            back_element: 99,
            front_face: Face::Front,
            material: 1,
            shading: 0,
            normals: Some([DVec3::Z; 3]),
            uv: None,
        }
    }

    #[test]
    fn a_request_and_a_reply_come_back_as_they_were_sent() {
        let r = Request::Begin { split: SpaceSplit::single(), patches: vec![patch(), SharePatch { id: 8, ..patch() }] };
        let back = decode_request(&encode_request(&r)).unwrap();
        assert_eq!(format!("{back:?}"), format!("{r:?}"));
        let reply = Reply::Ids(vec![vec![1, 2, 3], vec![], vec![u32::MAX]]);
        assert_eq!(decode_reply(&encode_reply(&reply)).unwrap(), reply);
    }

    #[test]
    fn a_cut_or_hostile_payload_is_an_error_not_a_panic() {
        let bytes = encode_request(&Request::Begin { split: SpaceSplit::single(), patches: vec![patch(); 3] });
        for cut in 0..bytes.len() {
            assert!(decode_request(&bytes[..cut]).is_err(), "cut at {cut}");
        }
        // A variant past the last, and a list that claims 2^60 entries.
        assert!(decode_request(&[200, 0, 0, 0]).is_err());
        let mut huge = vec![2u8, 0, 0, 0];
        huge.extend_from_slice(&(1u64 << 60).to_le_bytes());
        assert!(decode_request(&huge).is_err());
    }
}
