//! Compiles `proto/magg/v1/magg.proto` with protox (a pure-Rust protobuf compiler, so no
//! system `protoc` is needed) and generates the tonic client and server code.

fn main() -> Result<(), Box<dyn std::error::Error>> {
    println!("cargo:rerun-if-changed=proto");
    let fds = protox::compile(["magg/v1/magg.proto"], ["proto"])?;
    // Block payloads are `bytes::Bytes`: decoding slices them out of the received
    // buffer instead of copying each 2 KB block, and a fork serves its stored blocks
    // without copying them either.
    // Pixel rows likewise: their floats are copied once, not encoded one by one.
    // The large packed arrays of deposits, energies and pair leases likewise: declared as `bytes`
    // (the same wire format), they are written and read whole by `crate::packed`.
    // Every service encodes with `crate::codec::MaggCodec`: prost, with buffers sized
    // for block batches.
    tonic_prost_build::configure()
        .bytes(".magg.v1.Block.data")
        .bytes(".magg.v1.Row.rgb")
        .bytes(".magg.v1.DepositRequest")
        .bytes(".magg.v1.GetEnergiesReply")
        .bytes(".magg.v1.TakePairsReply")
        .codec_path("crate::codec::MaggCodec")
        .compile_fds(fds)?;
    Ok(())
}
