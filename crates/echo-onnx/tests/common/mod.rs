//! What the export tests share: every architecture variant the exporter must cover.

use echo_models::model::ForecasterConfig;

/// Small models of every switch the exporter handles: text token or not, DCT, sequential
/// refinement, no displacement, no temporal MLP, no social rounds, the velocity prior, and a
/// deeper combination.
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
            self_layers: 2,
            dct: true,
            text_dim: 0,
            ..base
        },
    ]
}
