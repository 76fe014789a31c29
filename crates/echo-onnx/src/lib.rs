//! The forecaster as ONNX — the path to an edge GPU (ONNX Runtime with the CUDA or TensorRT
//! execution provider):
//!
//! - [`export`]: a checkpoint (safetensors + JSON) to an ONNX graph (opset 17, dynamic batch),
//!   written from Rust with the ONNX protobuf schema ([`proto`]);
//! - [`runtime`]: an [`echo_models::Backend`] on ONNX Runtime through `ort`, loading the
//!   library at run time (no download at build time).

pub mod export;
pub mod proto;
pub mod runtime;

pub use export::export_checkpoint;
pub use runtime::OrtBackend;
