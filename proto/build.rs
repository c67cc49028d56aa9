//! Generates the ecat.v1 client and server code with a vendored protoc, so that a fresh
//! machine needs no protoc of its own.

use std::path::PathBuf;

const FILES: [&str; 5] = [
    "ecat/v1/common.proto",
    "ecat/v1/bus.proto",
    "ecat/v1/mailbox.proto",
    "ecat/v1/gateway.proto",
    "ecat/v1/process_data.proto",
];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // SAFETY: build scripts are single-threaded; nothing reads the environment concurrently.
    unsafe { std::env::set_var("PROTOC", protoc_bin_vendored::protoc_bin_path()?) };
    println!("cargo:rerun-if-changed=ecat");
    let out = PathBuf::from(std::env::var("OUT_DIR")?);
    tonic_prost_build::configure()
        // Malformed requests are INVALID_ARGUMENT (src/codec.rs).
        .codec_path("crate::codec::Codec")
        .file_descriptor_set_path(out.join("ecat_v1_descriptor.bin"))
        .compile_protos(&FILES, &["."])?;
    Ok(())
}
