//! `echoctl export onnx`: write a forecaster checkpoint as an ONNX model (opset 17, dynamic
//! batch) for ONNX Runtime — e.g. with the CUDA or TensorRT execution provider on an edge box.

use std::path::PathBuf;

use anyhow::Result;

/// Options.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Format.
    #[arg(value_enum)]
    pub format: ExportFormat,
    /// Checkpoint stem.
    #[arg(long, default_value = "models/forecaster")]
    pub model: PathBuf,
    /// Output file (default: <model>.onnx).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Export formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ExportFormat {
    /// ONNX, opset 17, dynamic batch.
    Onnx,
}

/// Export.
pub fn run(args: Args) -> Result<()> {
    let ExportFormat::Onnx = args.format;
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| args.model.with_extension("onnx"));
    let m = echo_onnx::export_checkpoint(&args.model, &out)?;
    let g = m.graph.as_ref();
    println!(
        "wrote {} (opset {}, {} nodes, {} initializers)",
        out.display(),
        echo_onnx::export::OPSET,
        g.map(|g| g.node.len()).unwrap_or(0),
        g.map(|g| g.initializer.len()).unwrap_or(0)
    );
    Ok(())
}
