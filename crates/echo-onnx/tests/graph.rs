//! The exported graph is well formed, as the ONNX checker demands: every initializer name is
//! unique (each stored tensor is one initializer, shared by the nodes that read it), every value
//! is produced once (SSA), and the nodes are in topological order — each input is a graph input,
//! an initializer, or the output of an earlier node. Checked for the shipped checkpoint and for
//! every architecture variant.

mod common;

use std::collections::{HashMap, HashSet};
use std::path::Path;

use candle_core::Device;
use echo_models::CheckpointMeta;
use echo_onnx::export::{build, build_checkpoint};
use echo_onnx::proto::ModelProto;

/// Every way `model` breaks the rules above, one line each (empty when well formed).
fn problems(model: &ModelProto) -> Vec<String> {
    let g = model.graph.as_ref().expect("the model has a graph");
    let mut out = vec![];
    let mut inits = HashSet::new();
    for t in &g.initializer {
        if !inits.insert(t.name.as_str()) {
            out.push(format!(
                "initializer '{}' is defined more than once",
                t.name
            ));
        }
    }
    let mut inputs = HashSet::new();
    for i in &g.input {
        if !inputs.insert(i.name.as_str()) {
            out.push(format!(
                "graph input '{}' is declared more than once",
                i.name
            ));
        }
        if inits.contains(i.name.as_str()) {
            out.push(format!(
                "'{}' is both a graph input and an initializer",
                i.name
            ));
        }
    }
    let mut produced: HashSet<&str> = HashSet::new();
    let mut used = HashSet::new();
    for (k, n) in g.node.iter().enumerate() {
        for i in &n.input {
            used.insert(i.as_str());
            let known = inputs.contains(i.as_str())
                || inits.contains(i.as_str())
                || produced.contains(i.as_str());
            if !known {
                out.push(format!(
                    "node {k} ({} '{}') reads '{i}' before anything defines it",
                    n.op_type, n.name
                ));
            }
        }
        for o in &n.output {
            if inputs.contains(o.as_str()) || inits.contains(o.as_str()) {
                out.push(format!(
                    "node {k} ({}) writes '{o}', a graph input or initializer",
                    n.op_type
                ));
            }
            if !produced.insert(o.as_str()) {
                out.push(format!("'{o}' is written by more than one node"));
            }
        }
    }
    for t in &g.initializer {
        if !used.contains(t.name.as_str()) {
            out.push(format!("initializer '{}' is never read", t.name));
        }
    }
    for o in &g.output {
        if !produced.contains(o.name.as_str()) {
            out.push(format!("graph output '{}' is never written", o.name));
        }
    }
    out
}

fn assert_well_formed(model: &ModelProto, what: &str) {
    let p = problems(model);
    assert!(
        p.is_empty(),
        "{what}: {} problems in the exported graph:\n  {}",
        p.len(),
        p.join("\n  ")
    );
}

#[test]
fn shipped_checkpoint_graph_is_well_formed() {
    let stem = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/forecaster");
    let meta: CheckpointMeta =
        serde_json::from_slice(&std::fs::read(stem.with_extension("json")).unwrap()).unwrap();
    let model = build_checkpoint(&stem, &meta.model).unwrap();
    assert_well_formed(&model, "models/forecaster");
    // One initializer per stored tensor at most: none is stored twice under another name.
    let g = model.graph.as_ref().unwrap();
    let weights =
        candle_core::safetensors::load(stem.with_extension("safetensors"), &Device::Cpu).unwrap();
    let mut seen: HashMap<(i32, &[i64], &[u8]), &str> = HashMap::new();
    for t in &g.initializer {
        if let Some(first) = seen.insert((t.data_type, &t.dims, &t.raw_data), &t.name) {
            // Only distinct stored tensors may happen to hold the same values.
            assert!(
                weights.contains_key(first) && weights.contains_key(&t.name),
                "'{}' and '{first}' are byte-identical copies",
                t.name
            );
        }
    }
}

#[test]
fn every_variant_graph_is_well_formed() {
    let variants = common::variants();
    for cfg in &variants {
        let weights = common::random_weights(cfg);
        assert_well_formed(&build(weights, cfg).unwrap(), &format!("{cfg:?}"));
    }
}
