//! Export a forecaster checkpoint to ONNX (opset 17), op by op from the same weights the candle
//! model reads. Inputs: `obs` (b, 2, obs, 73) and, for text models, `text` (b, text_dim); output
//! `forecast` (b, 2, pred, 73). The batch dimension is dynamic.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use anyhow::{anyhow, Context, Result};
use candle_core::{Device, Tensor};
use echo_models::features::FEATURES;
use echo_models::model::{dct_matrix, ForecasterConfig};
use echo_models::CheckpointMeta;
use prost::Message;

use crate::proto::*;

/// ONNX opset the graph uses (LayerNormalization needs 17).
pub const OPSET: i64 = 17;

/// Key of a constant initializer: element type, shape and little-endian bytes.
type ConstKey = (i32, Vec<i64>, Vec<u8>);

/// The graph being written. Each stored tensor becomes one initializer (per orientation),
/// shared by every node that reads it — the self-attention and time-mixing layers run once per
/// agent with the same weights — and each distinct constant is stored once.
struct Graph {
    weights: HashMap<String, Tensor>,
    nodes: Vec<NodeProto>,
    inits: Vec<TensorProto>,
    /// Initializer names written so far.
    names: HashSet<String>,
    /// Stored tensor (name, transposed) → its initializer.
    params: HashMap<(String, bool), String>,
    /// Constant contents → its initializer.
    consts: HashMap<ConstKey, String>,
    next: usize,
}

fn ints(name: &str, v: &[i64]) -> AttributeProto {
    AttributeProto {
        name: name.into(),
        ints: v.to_vec(),
        r#type: attr_type::INTS,
        ..Default::default()
    }
}

fn int(name: &str, v: i64) -> AttributeProto {
    AttributeProto {
        name: name.into(),
        i: v,
        r#type: attr_type::INT,
        ..Default::default()
    }
}

fn float(name: &str, v: f32) -> AttributeProto {
    AttributeProto {
        name: name.into(),
        f: v,
        r#type: attr_type::FLOAT,
        ..Default::default()
    }
}

fn value_info(name: &str, dims: &[Result<i64, &str>]) -> ValueInfoProto {
    ValueInfoProto {
        name: name.into(),
        r#type: Some(TypeProto {
            tensor_type: Some(TensorTypeProto {
                elem_type: data_type::FLOAT,
                shape: Some(TensorShapeProto {
                    dim: dims
                        .iter()
                        .map(|d| match d {
                            Ok(v) => Dimension {
                                dim_value: Some(*v),
                                dim_param: None,
                            },
                            Err(p) => Dimension {
                                dim_value: None,
                                dim_param: Some(p.to_string()),
                            },
                        })
                        .collect(),
                }),
            }),
        }),
    }
}

impl Graph {
    fn fresh(&mut self, hint: &str) -> String {
        self.next += 1;
        format!("{hint}_{}", self.next)
    }

    fn weight(&self, name: &str) -> Result<&Tensor> {
        self.weights
            .get(name)
            .ok_or_else(|| anyhow!("checkpoint has no tensor '{name}'"))
    }

    /// A named initializer; the name must be new.
    fn init_f32(&mut self, name: &str, dims: &[usize], data: &[f32]) -> Result<String> {
        anyhow::ensure!(
            self.names.insert(name.to_string()),
            "initializer '{name}' written twice"
        );
        self.inits.push(TensorProto {
            dims: dims.iter().map(|d| *d as i64).collect(),
            data_type: data_type::FLOAT,
            name: name.into(),
            raw_data: data.iter().flat_map(|x| x.to_le_bytes()).collect(),
        });
        Ok(name.to_string())
    }

    /// A constant initializer, written once per distinct contents (named after the first
    /// `hint` that asks for it) and shared by every later node that needs the same values.
    fn constant(&mut self, hint: &str, data_type: i32, dims: Vec<i64>, raw: Vec<u8>) -> String {
        let key = (data_type, dims, raw);
        if let Some(name) = self.consts.get(&key) {
            return name.clone();
        }
        let mut name = self.fresh(hint);
        while self.names.contains(&name) {
            name = self.fresh(hint);
        }
        self.names.insert(name.clone());
        self.inits.push(TensorProto {
            dims: key.1.clone(),
            data_type,
            name: name.clone(),
            raw_data: key.2.clone(),
        });
        self.consts.insert(key, name.clone());
        name
    }

    fn init_i64(&mut self, hint: &str, data: &[i64]) -> String {
        let raw = data.iter().flat_map(|x| x.to_le_bytes()).collect();
        self.constant(hint, data_type::INT64, vec![data.len() as i64], raw)
    }

    fn constant_f32(&mut self, hint: &str, dims: &[i64], data: &[f32]) -> String {
        let raw = data.iter().flat_map(|x| x.to_le_bytes()).collect();
        self.constant(hint, data_type::FLOAT, dims.to_vec(), raw)
    }

    fn scalar(&mut self, hint: &str, v: f32) -> String {
        self.constant(hint, data_type::FLOAT, vec![], v.to_le_bytes().to_vec())
    }

    fn op(&mut self, op: &str, inputs: &[&str], attrs: Vec<AttributeProto>) -> String {
        let out = self.fresh(&op.to_lowercase());
        self.nodes.push(NodeProto {
            input: inputs.iter().map(|s| s.to_string()).collect(),
            output: vec![out.clone()],
            name: out.clone(),
            op_type: op.into(),
            attribute: attrs,
        });
        out
    }

    /// Stored tensor as an initializer (optionally transposed: Linear weights are (out, in)),
    /// written on first use and shared afterwards. It keeps the checkpoint's name unless the
    /// other orientation already has it.
    fn param(&mut self, name: &str, transpose: bool) -> Result<String> {
        let key = (name.to_string(), transpose);
        if let Some(init) = self.params.get(&key) {
            return Ok(init.clone());
        }
        let t = self.weight(name)?.clone();
        let t = if transpose { t.t()?.contiguous()? } else { t };
        let dims = t.dims().to_vec();
        let data = t.flatten_all()?.to_vec1::<f32>()?;
        let init = if self.names.contains(name) {
            let suffix = if transpose { "transposed" } else { "stored" };
            format!("{name}.{suffix}")
        } else {
            name.to_string()
        };
        let init = self.init_f32(&init, &dims, &data)?;
        self.params.insert(key, init.clone());
        Ok(init)
    }

    fn linear(&mut self, x: &str, prefix: &str) -> Result<String> {
        let w = self.param(&format!("{prefix}.weight"), true)?;
        let b = self.param(&format!("{prefix}.bias"), false)?;
        let y = self.op("MatMul", &[x, &w], vec![]);
        Ok(self.op("Add", &[&y, &b], vec![]))
    }

    /// candle's `gelu`: the tanh approximation.
    fn gelu(&mut self, x: &str) -> String {
        let c = self.scalar("c", 0.044715);
        let k = self.scalar("k", (2.0f32 / std::f32::consts::PI).sqrt());
        let one = self.scalar("one", 1.0);
        let half = self.scalar("half", 0.5);
        let x2 = self.op("Mul", &[x, x], vec![]);
        let cx2 = self.op("Mul", &[&x2, &c], vec![]);
        let inner = self.op("Add", &[&one, &cx2], vec![]);
        let kx = self.op("Mul", &[x, &k], vec![]);
        let arg = self.op("Mul", &[&kx, &inner], vec![]);
        let th = self.op("Tanh", &[&arg], vec![]);
        let s = self.op("Add", &[&one, &th], vec![]);
        let hx = self.op("Mul", &[x, &half], vec![]);
        self.op("Mul", &[&hx, &s], vec![])
    }

    fn mlp(&mut self, x: &str, prefix: &str) -> Result<String> {
        let h = self.linear(x, &format!("{prefix}.fc1"))?;
        let h = self.gelu(&h);
        self.linear(&h, &format!("{prefix}.fc2"))
    }

    fn layer_norm(&mut self, x: &str, prefix: &str) -> Result<String> {
        let w = self.param(&format!("{prefix}.weight"), false)?;
        let b = self.param(&format!("{prefix}.bias"), false)?;
        Ok(self.op(
            "LayerNormalization",
            &[x, &w, &b],
            vec![int("axis", -1), float("epsilon", 1e-5)],
        ))
    }

    fn attention(
        &mut self,
        x: &str,
        ctx: &str,
        prefix: &str,
        d: usize,
        heads: usize,
    ) -> Result<String> {
        let dh = (d / heads) as i64;
        let split = self.init_i64("split_shape", &[0, -1, heads as i64, dh]);
        let q = self.linear(x, &format!("{prefix}.q"))?;
        let k = self.linear(ctx, &format!("{prefix}.k"))?;
        let v = self.linear(ctx, &format!("{prefix}.v"))?;
        let q = self.op("Reshape", &[&q, &split], vec![]);
        let q = self.op("Transpose", &[&q], vec![ints("perm", &[0, 2, 1, 3])]);
        let k = self.op("Reshape", &[&k, &split], vec![]);
        let kt = self.op("Transpose", &[&k], vec![ints("perm", &[0, 2, 3, 1])]);
        let v = self.op("Reshape", &[&v, &split], vec![]);
        let v = self.op("Transpose", &[&v], vec![ints("perm", &[0, 2, 1, 3])]);
        let att = self.op("MatMul", &[&q, &kt], vec![]);
        let scale = self.scalar("scale", 1.0 / (dh as f32).sqrt());
        let att = self.op("Mul", &[&att, &scale], vec![]);
        let att = self.op("Softmax", &[&att], vec![int("axis", -1)]);
        let y = self.op("MatMul", &[&att, &v], vec![]);
        let y = self.op("Transpose", &[&y], vec![ints("perm", &[0, 2, 1, 3])]);
        let merge = self.init_i64("merge_shape", &[0, -1, d as i64]);
        let y = self.op("Reshape", &[&y, &merge], vec![]);
        self.linear(&y, &format!("{prefix}.o"))
    }

    fn block(
        &mut self,
        x: &str,
        ctx: &str,
        prefix: &str,
        d: usize,
        heads: usize,
    ) -> Result<String> {
        let q = self.layer_norm(x, &format!("{prefix}.ln_q"))?;
        let kv = self.layer_norm(ctx, &format!("{prefix}.ln_kv"))?;
        let a = self.attention(&q, &kv, &format!("{prefix}.att"), d, heads)?;
        let x = self.op("Add", &[x, &a], vec![]);
        let f = self.layer_norm(&x, &format!("{prefix}.ln_ff"))?;
        let f = self.mlp(&f, &format!("{prefix}.ff"))?;
        Ok(self.op("Add", &[&x, &f], vec![]))
    }

    fn temp_mlp(&mut self, x: &str, prefix: &str) -> Result<String> {
        let xt = self.op("Transpose", &[x], vec![ints("perm", &[0, 2, 1])]);
        let y = self.linear(&xt, &format!("{prefix}.time"))?;
        let y = self.op("Transpose", &[&y], vec![ints("perm", &[0, 2, 1])]);
        let y = self.layer_norm(&y, &format!("{prefix}.ln"))?;
        Ok(self.op("Add", &[x, &y], vec![]))
    }

    fn slice(&mut self, x: &str, axis: i64, start: i64, end: i64) -> String {
        let s = self.init_i64("starts", &[start]);
        let e = self.init_i64("ends", &[end]);
        let a = self.init_i64("axes", &[axis]);
        self.op("Slice", &[x, &s, &e, &a], vec![])
    }
}

/// Per-agent inputs of a model whose agents have different features: (batch, frames, F_a).
pub const AGENT_INPUTS: [&str; 2] = ["obs_a", "obs_b"];
/// Per-agent outputs of such a model: (batch, predicted frames, F_a).
pub const AGENT_OUTPUTS: [&str; 2] = ["forecast_a", "forecast_b"];

/// A node naming a value as a graph output.
fn identity(input: String, output: &str) -> NodeProto {
    NodeProto {
        input: vec![input],
        output: vec![output.into()],
        name: output.into(),
        op_type: "Identity".into(),
        attribute: vec![],
    }
}

/// The ONNX model of a checkpoint: weights by name and the architecture. Two-person models
/// read `obs` (batch, 2, frames, 73) and give `forecast` (batch, 2, predicted frames, 73);
/// models whose agents differ read [`AGENT_INPUTS`] and give [`AGENT_OUTPUTS`].
pub fn build(weights: HashMap<String, Tensor>, cfg: &ForecasterConfig) -> Result<ModelProto> {
    // Two people share one input and one output tensor (batch, 2, frames, 73); models whose
    // agents differ (the HRI model's robot agent) take and give one tensor per agent.
    let two_person = cfg.agent_features == [FEATURES, FEATURES];
    anyhow::ensure!(
        cfg.agent_features.iter().all(|f| *f > 0),
        "agent features {:?}",
        cfg.agent_features
    );
    let mut g = Graph {
        weights,
        nodes: vec![],
        inits: vec![],
        names: HashSet::new(),
        params: HashMap::new(),
        consts: HashMap::new(),
        next: 0,
    };
    let (d, heads) = (cfg.d_model, cfg.heads);
    let (n_obs, pred, t) = (cfg.obs as i64, cfg.pred as i64, cfg.frames() as i64);
    let text = cfg.text_dim > 0;
    let skip = i64::from(text);
    // Sinusoidal positions, exactly as the model computes them.
    let mut pe = vec![0f32; cfg.frames() * d];
    for p in 0..cfg.frames() {
        for i in 0..d / 2 {
            let w = 1.0 / 10000f64.powf(2.0 * i as f64 / d as f64);
            pe[p * d + 2 * i] = (p as f64 * w).sin() as f32;
            pe[p * d + 2 * i + 1] = (p as f64 * w).cos() as f32;
        }
    }
    let pe = g.init_f32("positional", &[1, cfg.frames(), d], &pe)?;
    let dct = if cfg.dct {
        let m = dct_matrix(cfg.frames(), &Device::Cpu)?;
        let dims = m.dims().to_vec();
        let data = m.flatten_all()?.to_vec1::<f32>()?;
        let fwd = g.init_f32("dct", &dims, &data)?;
        let inv = m.t()?.contiguous()?.flatten_all()?.to_vec1::<f32>()?;
        let inv = g.init_f32("idct", &dims, &inv)?;
        Some((fwd, inv))
    } else {
        None
    };
    let token = if text {
        let p = g.linear("text", "text")?;
        let ax = g.init_i64("axes", &[1]);
        Some(g.op("Unsqueeze", &[&p, &ax], vec![]))
    } else {
        None
    };
    let mut agents = vec![];
    let mut lasts = vec![];
    for (a, input) in AGENT_INPUTS.iter().enumerate() {
        let x = if two_person {
            let idx = g.init_i64("agent", &[a as i64]);
            let x = g.op("Gather", &["obs", &idx], vec![int("axis", 1)]);
            let ax = g.init_i64("axes", &[1]);
            g.op("Squeeze", &[&x, &ax], vec![])
        } else {
            input.to_string()
        };
        let last = g.slice(&x, 1, n_obs - 1, n_obs);
        let reps = g.init_i64("expand", &[1, t - n_obs, 1]);
        let rep = g.op("Expand", &[&last, &reps], vec![]);
        let mut padded = g.op("Concat", &[&x, &rep], vec![int("axis", 1)]);
        if let Some((fwd, _)) = &dct {
            padded = g.op("MatMul", &[fwd, &padded], vec![]);
        }
        let name = if a == 0 { "embed_a" } else { "embed_b" };
        let h = g.mlp(&padded, name)?;
        let mut h = g.op("Add", &[&h, &pe], vec![]);
        if let Some(tok) = &token {
            h = g.op("Concat", &[tok, &h], vec![int("axis", 1)]);
        }
        for i in 0..cfg.self_layers {
            h = g.block(&h, &h.clone(), &format!("self.{i}"), d, heads)?;
        }
        for i in 0..cfg.temp_mlp {
            h = g.temp_mlp(&h, &format!("temp.{i}"))?;
        }
        agents.push(h);
        // The base of the displacement: the last frame, plus the damped velocity prior.
        let base = if cfg.velocity_prior_s > 0.0 && cfg.displacement {
            let prev = g.slice(&x, 1, n_obs - 2, n_obs - 1);
            let v = g.op("Sub", &[&last, &prev], vec![]);
            let f = cfg.agent_features[a];
            let gains = cfg.prior_gain_matrix(f);
            let gk = g.constant_f32(&format!("prior_gains.{a}"), &[1, pred, f as i64], &gains);
            let dv = g.op("Mul", &[&v, &gk], vec![]);
            g.op("Add", &[&last, &dv], vec![])
        } else {
            last
        };
        lasts.push(base);
    }
    let (mut ha, mut hb) = (agents[0].clone(), agents[1].clone());
    if cfg.interleaved {
        for i in 0..cfg.rounds {
            ha = g.block(&ha, &hb, &format!("cross.{i}.a"), d, heads)?;
            hb = g.block(&hb, &ha, &format!("cross.{i}.b"), d, heads)?;
        }
    } else {
        for i in 0..cfg.rounds {
            ha = g.block(&ha, &hb, &format!("cross.{i}.a"), d, heads)?;
        }
        for i in 0..cfg.rounds {
            hb = g.block(&hb, &ha, &format!("cross.{i}.b"), d, heads)?;
        }
    }
    let mut outs = vec![];
    for (a, h) in [ha, hb].iter().enumerate() {
        let name = if a == 0 { "decode_a" } else { "decode_b" };
        let y = match &dct {
            Some((_, inv)) => {
                let all = g.slice(h, 1, skip, skip + t);
                let c = g.mlp(&all, name)?;
                let y = g.op("MatMul", &[inv, &c], vec![]);
                g.slice(&y, 1, n_obs, n_obs + pred)
            }
            None => {
                let fut = g.slice(h, 1, skip + n_obs, skip + n_obs + pred);
                g.mlp(&fut, name)?
            }
        };
        let y = if cfg.displacement {
            g.op("Add", &[&y, &lasts[a]], vec![])
        } else {
            y
        };
        if two_person {
            let ax = g.init_i64("axes", &[1]);
            outs.push(g.op("Unsqueeze", &[&y, &ax], vec![]));
        } else {
            outs.push(y);
        }
    }
    let f = FEATURES as i64;
    let (mut inputs, outputs) = if two_person {
        let out = g.op("Concat", &[&outs[0], &outs[1]], vec![int("axis", 1)]);
        g.nodes.push(identity(out, "forecast"));
        (
            vec![value_info("obs", &[Err("batch"), Ok(2), Ok(n_obs), Ok(f)])],
            vec![value_info(
                "forecast",
                &[Err("batch"), Ok(2), Ok(pred), Ok(f)],
            )],
        )
    } else {
        let mut inputs = vec![];
        let mut outputs = vec![];
        for (a, y) in outs.into_iter().enumerate() {
            let fa = cfg.agent_features[a] as i64;
            g.nodes.push(identity(y, AGENT_OUTPUTS[a]));
            inputs.push(value_info(
                AGENT_INPUTS[a],
                &[Err("batch"), Ok(n_obs), Ok(fa)],
            ));
            outputs.push(value_info(
                AGENT_OUTPUTS[a],
                &[Err("batch"), Ok(pred), Ok(fa)],
            ));
        }
        (inputs, outputs)
    };
    if text {
        inputs.push(value_info("text", &[Err("batch"), Ok(cfg.text_dim as i64)]));
    }
    check_order(&inputs, &g.inits, &g.nodes)?;
    Ok(ModelProto {
        ir_version: 8,
        producer_name: "echo".into(),
        producer_version: env!("CARGO_PKG_VERSION").into(),
        doc_string: "Echo dual-agent social forecaster".into(),
        graph: Some(GraphProto {
            node: g.nodes,
            name: "forecaster".into(),
            initializer: g.inits,
            input: inputs,
            output: outputs,
        }),
        opset_import: vec![OperatorSetIdProto {
            domain: String::new(),
            version: OPSET,
        }],
    })
}

/// The graph's values are defined once each, before they are read: initializer names are unique,
/// each node output is new (SSA), and each node input is a graph input, an initializer or an
/// earlier node's output.
fn check_order(
    inputs: &[ValueInfoProto],
    inits: &[TensorProto],
    nodes: &[NodeProto],
) -> Result<()> {
    let mut defined: HashSet<&str> = inputs.iter().map(|i| i.name.as_str()).collect();
    for t in inits {
        anyhow::ensure!(
            defined.insert(&t.name),
            "initializer '{}' defined twice",
            t.name
        );
    }
    for n in nodes {
        if let Some(i) = n.input.iter().find(|i| !defined.contains(i.as_str())) {
            anyhow::bail!(
                "{} '{}' reads '{i}' before it is defined",
                n.op_type,
                n.name
            );
        }
        for o in &n.output {
            anyhow::ensure!(defined.insert(o), "'{o}' defined twice");
        }
    }
    Ok(())
}

/// The ONNX model of `<stem>.safetensors` for architecture `cfg`.
pub fn build_checkpoint(stem: &Path, cfg: &ForecasterConfig) -> Result<ModelProto> {
    let wp = echo_assets::resolve_model(stem)?.with_extension("safetensors");
    let weights = candle_core::safetensors::load(&wp, &Device::Cpu)
        .with_context(|| format!("reading {}", wp.display()))?;
    build(weights, cfg)
}

/// Export `<stem>.safetensors` + `<stem>.json` to `out` (ONNX protobuf).
pub fn export_checkpoint(stem: &Path, out: &Path) -> Result<ModelProto> {
    let meta = CheckpointMeta::load(stem)?;
    let model = build_checkpoint(stem, &meta.model)?;
    std::fs::write(out, model.encode_to_vec())
        .with_context(|| format!("writing {}", out.display()))?;
    Ok(model)
}
