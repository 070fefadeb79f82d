//! The prost codec of every magg service, with buffers sized for magg's messages.
//!
//! tonic's default codec starts each message's buffers at 8 KiB and lets them double as
//! they fill. A batch of blocks (up to 64 blocks of 2 KiB) or of pixel rows is tens of
//! kilobytes: encoding it reallocated its buffer three or four times, and decoding it
//! twice more (the received body is appended to an 8 KiB buffer, which then reserves
//! the message's length again once its header is read), each reallocation copying
//! what the buffer held. With a 40-block node cache, where a render fetches blocks by
//! the hundred thousand, those copies were about 5% of the render's instructions.
//! Buffers of [`BUFFER_SIZE`] take such a message without growing; memory taken and
//! not touched costs nothing, and freed buffers are reused (`magg_plumbing::allocator`).

use prost::Message;
use std::marker::PhantomData;
use tonic::codec::{BufferSettings, Codec};
use tonic_prost::{ProstCodec, ProstDecoder, ProstEncoder};

/// Initial size of an encoding or decoding buffer: twice the largest batch a bounded
/// node cache fetches ahead ([`magg_core::blocks::PREFETCH_RUN`] blocks, with their
/// framing), since a decoder reserves a received message's length once more after it
/// holds it. (An unlimited cache's batches are larger and grow their buffers as before.)
pub const BUFFER_SIZE: usize = 288 << 10;

/// When a streamed encoder hands a filled buffer on (tonic's default).
const YIELD_THRESHOLD: usize = 32 << 10;

/// [`ProstCodec`]'s encoder and decoder, with [`BUFFER_SIZE`] buffers; named by the
/// generated services. It holds nothing: the message types are its only parameters.
#[derive(Debug, Clone)]
pub struct MaggCodec<T, U>(PhantomData<fn() -> (T, U)>);

impl<T, U> Default for MaggCodec<T, U> {
    fn default() -> Self {
        MaggCodec(PhantomData)
    }
}

/// The buffer settings of every encoder and decoder.
fn settings() -> BufferSettings {
    BufferSettings::new(BUFFER_SIZE, YIELD_THRESHOLD)
}

impl<T, U> Codec for MaggCodec<T, U>
where
    T: Message + Send + 'static,
    U: Message + Default + Send + 'static,
{
    type Encode = T;
    type Decode = U;
    type Encoder = ProstEncoder<T>;
    type Decoder = ProstDecoder<U>;

    fn encoder(&mut self) -> Self::Encoder {
        ProstCodec::<T, U>::raw_encoder(settings())
    }

    fn decoder(&mut self) -> Self::Decoder {
        ProstCodec::<T, U>::raw_decoder(settings())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::v1::{Block, GetBlocksReply};
    use magg_core::blocks::{BLOCK_SIZE, PREFETCH_RUN};
    use tonic::codec::{Decoder, Encoder};

    /// The reply to a full prefetch run, as the fork sends it.
    fn full_run() -> GetBlocksReply {
        let blocks = (0..PREFETCH_RUN as u32).map(|id| Block { id, data: vec![id as u8; BLOCK_SIZE].into() }).collect();
        GetBlocksReply { blocks }
    }

    #[test]
    fn a_full_prefetch_run_fits_twice_in_a_buffer() {
        let len = full_run().encoded_len();
        assert!(len > PREFETCH_RUN * BLOCK_SIZE);
        // The frame's 5-byte header, the message, and the message's length reserved
        // again by the decoder.
        assert!(5 + 2 * len <= BUFFER_SIZE, "{len}-byte run, {BUFFER_SIZE}-byte buffers");
    }

    #[test]
    fn encoders_and_decoders_start_at_buffer_size() {
        let mut codec = MaggCodec::<GetBlocksReply, GetBlocksReply>::default();
        let want = format!("{:?}", settings());
        assert!(want.contains(&BUFFER_SIZE.to_string()), "{want}");
        assert_eq!(format!("{:?}", codec.encoder().buffer_settings()), want);
        assert_eq!(format!("{:?}", codec.decoder().buffer_settings()), want);
    }
}
