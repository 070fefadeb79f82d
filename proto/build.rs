//! Compiles `proto/magg/v1/magg.proto` with protox (a pure-Rust protobuf compiler, so no
//! system `protoc` is needed) and generates the tonic client and server code.

fn main() -> Result<(), Box<dyn std::error::Error>> {
    println!("cargo:rerun-if-changed=proto");
    let fds = protox::compile(["magg/v1/magg.proto"], ["proto"])?;
    tonic_prost_build::configure().compile_fds(fds)?;
    Ok(())
}
