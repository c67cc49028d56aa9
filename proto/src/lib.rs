//! The `ecat.v1` gRPC contract (`proto/ecat/v1/*.proto`).
//!
//! Code generation (tonic-prost-build with a vendored protoc) arrives with the server issue;
//! until then this crate only carries the contract files.
