//! What the export tests share: every architecture variant the exporter must cover, and their
//! untrained weights.

use std::collections::HashMap;

use candle_core::{DType, Device, Tensor};
use candle_nn::{VarBuilder, VarMap};
use echo_models::model::{Forecaster, ForecasterConfig};

/// A forecaster with `cfg` whose every weight is random (the decoders and time mixers of a
/// fresh one start at zero), and those weights by name.
#[allow(dead_code)] // not every test binary that includes this module uses it
pub fn random_model(cfg: &ForecasterConfig) -> (Forecaster, HashMap<String, Tensor>) {
    let dev = Device::Cpu;
    let vm = VarMap::new();
    let model = Forecaster::new(cfg.clone(), VarBuilder::from_varmap(&vm, DType::F32, &dev))
        .expect("a forecaster of this configuration");
    let mut weights = HashMap::new();
    for (name, var) in vm.data().lock().expect("weights").iter() {
        let r = Tensor::randn(0f32, 0.3, var.dims(), &dev).expect("random values");
        var.set(&r).expect("same shape");
        weights.insert(name.clone(), r);
    }
    (model, weights)
}

/// The freshly initialised weights of a forecaster with `cfg`, by name.
pub fn random_weights(cfg: &ForecasterConfig) -> HashMap<String, Tensor> {
    let vm = VarMap::new();
    Forecaster::new(
        cfg.clone(),
        VarBuilder::from_varmap(&vm, DType::F32, &Device::Cpu),
    )
    .expect("a forecaster of this configuration");
    let data = vm.data().lock().expect("weights");
    data.iter()
        .map(|(k, v)| (k.clone(), v.as_tensor().clone()))
        .collect()
}

/// Small models of every switch the exporter handles: text token or not, DCT, sequential
/// refinement, no displacement, no temporal MLP, no social rounds, the velocity prior (on every
/// value, or on the root only), and a deeper combination.
pub fn variants() -> Vec<ForecasterConfig> {
    let base = ForecasterConfig {
        d_model: 32,
        heads: 4,
        text_dim: 8,
        ..Default::default()
    };
    vec![
        base.clone(),
        ForecasterConfig {
            text_dim: 0,
            ..base.clone()
        },
        ForecasterConfig {
            dct: true,
            ..base.clone()
        },
        ForecasterConfig {
            interleaved: false,
            ..base.clone()
        },
        ForecasterConfig {
            displacement: false,
            ..base.clone()
        },
        ForecasterConfig {
            temp_mlp: 0,
            ..base.clone()
        },
        ForecasterConfig {
            rounds: 0,
            ..base.clone()
        },
        ForecasterConfig {
            velocity_prior_s: 0.4,
            ..base.clone()
        },
        ForecasterConfig {
            velocity_prior_s: 0.4,
            velocity_prior_root_only: true,
            ..base.clone()
        },
        ForecasterConfig {
            self_layers: 2,
            dct: true,
            text_dim: 0,
            ..base
        },
    ]
}
