//! AdamW (decoupled weight decay) whose state — both moments and the step count — can be saved
//! and restored, so an interrupted training run resumes exactly where it stopped.

use std::collections::HashMap;
use std::path::Path;

use candle_core::{backprop::GradStore, Result, Tensor, Var};

/// AdamW over named variables.
pub struct AdamW {
    vars: Vec<(String, Var)>,
    m: Vec<Tensor>,
    v: Vec<Tensor>,
    step: u64,
    /// Learning rate (set every step by the schedule).
    pub lr: f64,
    beta1: f64,
    beta2: f64,
    eps: f64,
    weight_decay: f64,
}

impl AdamW {
    /// Optimise `vars` (name, variable), sorted by name so saved state lines up.
    pub fn new(mut vars: Vec<(String, Var)>, lr: f64, weight_decay: f64) -> Result<AdamW> {
        vars.sort_by(|a, b| a.0.cmp(&b.0));
        let m = vars
            .iter()
            .map(|(_, v)| v.as_tensor().zeros_like())
            .collect::<Result<Vec<_>>>()?;
        let v = m.clone();
        Ok(AdamW {
            vars,
            m,
            v,
            step: 0,
            lr,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
            weight_decay,
        })
    }

    /// Optimise every variable of `vm`.
    pub fn from_varmap(vm: &candle_nn::VarMap, lr: f64, weight_decay: f64) -> Result<AdamW> {
        let vars = vm
            .data()
            .lock()
            .map_err(|_| candle_core::Error::Msg("poisoned weights".into()))?
            .iter()
            .map(|(k, v)| (k.clone(), v.clone()))
            .collect();
        AdamW::new(vars, lr, weight_decay)
    }

    /// Steps taken.
    pub fn steps(&self) -> u64 {
        self.step
    }

    /// Global L2 norm of the gradients.
    pub fn grad_norm(&self, grads: &GradStore) -> Result<f64> {
        let mut n2 = 0f64;
        for (_, var) in &self.vars {
            if let Some(g) = grads.get(var) {
                n2 += g.sqr()?.sum_all()?.to_scalar::<f32>()? as f64;
            }
        }
        Ok(n2.sqrt())
    }

    /// One update; gradients are scaled by `scale` first (gradient clipping).
    pub fn step(&mut self, grads: &GradStore, scale: f64) -> Result<()> {
        self.step += 1;
        let t = self.step as i32;
        let (b1, b2) = (self.beta1, self.beta2);
        let c1 = 1.0 - b1.powi(t);
        let c2 = 1.0 - b2.powi(t);
        for (i, (_, var)) in self.vars.iter().enumerate() {
            let Some(g) = grads.get(var) else { continue };
            let g = (g * scale)?;
            let m = ((&self.m[i] * b1)? + (&g * (1.0 - b1))?)?;
            let v = ((&self.v[i] * b2)? + (g.sqr()? * (1.0 - b2))?)?;
            let mhat = (&m / c1)?;
            let vhat = (&v / c2)?;
            let theta = (var.as_tensor() * (1.0 - self.lr * self.weight_decay))?;
            let upd = (mhat / (vhat.sqrt()? + self.eps)?)?;
            var.set(&(theta - (upd * self.lr)?)?)?;
            self.m[i] = m;
            self.v[i] = v;
        }
        Ok(())
    }

    /// Save the moments and step count (safetensors).
    pub fn save(&self, path: &Path) -> Result<()> {
        let mut map: HashMap<String, Tensor> = HashMap::new();
        for (i, (name, _)) in self.vars.iter().enumerate() {
            map.insert(format!("m.{name}"), self.m[i].clone());
            map.insert(format!("v.{name}"), self.v[i].clone());
        }
        map.insert(
            "step".into(),
            Tensor::new(
                &[self.step as f32],
                self.m
                    .first()
                    .map(|m| m.device())
                    .unwrap_or(&candle_core::Device::Cpu),
            )?,
        );
        candle_core::safetensors::save(&map, path)
    }

    /// Restore what [`AdamW::save`] wrote; every variable must be present with its shape.
    pub fn load(&mut self, path: &Path) -> Result<()> {
        let dev = self
            .m
            .first()
            .map(|m| m.device().clone())
            .unwrap_or(candle_core::Device::Cpu);
        let map = candle_core::safetensors::load(path, &dev)?;
        for (i, (name, var)) in self.vars.iter().enumerate() {
            for (key, slot) in [
                (format!("m.{name}"), &mut self.m[i]),
                (format!("v.{name}"), &mut self.v[i]),
            ] {
                let t = map.get(&key).ok_or_else(|| {
                    candle_core::Error::Msg(format!("{}: no {key}", path.display()))
                })?;
                if t.dims() != var.dims() {
                    candle_core::bail!(
                        "{}: {key} has shape {:?}, expected {:?}",
                        path.display(),
                        t.dims(),
                        var.dims()
                    );
                }
                *slot = t.clone();
            }
        }
        let step = map
            .get("step")
            .ok_or_else(|| candle_core::Error::Msg(format!("{}: no step", path.display())))?;
        self.step = step.to_vec1::<f32>()?.first().copied().unwrap_or(0.0) as u64;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::{DType, Device};

    #[test]
    fn minimises_a_quadratic_and_resumes_identically() {
        let dev = Device::Cpu;
        let target = Tensor::new(&[1.0f32, -2.0, 0.5], &dev).unwrap();
        let run = |steps: usize, split: Option<usize>| -> Vec<f32> {
            let x = Var::zeros(3, DType::F32, &dev).unwrap();
            let mut opt = AdamW::new(vec![("x".into(), x.clone())], 0.05, 0.0).unwrap();
            let scratch = tempfile::tempdir().unwrap();
            let dir = scratch.path().to_path_buf();
            for k in 0..steps {
                if Some(k) == split {
                    // Save, rebuild from scratch, load: the run must continue unchanged.
                    let p = dir.join("opt.safetensors");
                    opt.save(&p).unwrap();
                    let w = x.as_tensor().copy().unwrap();
                    let x2 = Var::from_tensor(&w).unwrap();
                    opt = AdamW::new(vec![("x".into(), x2.clone())], 0.05, 0.0).unwrap();
                    opt.load(&p).unwrap();
                    x.set(x2.as_tensor()).unwrap();
                    opt = AdamW {
                        vars: vec![("x".into(), x.clone())],
                        ..opt
                    };
                }
                let loss = x
                    .as_tensor()
                    .sub(&target)
                    .unwrap()
                    .sqr()
                    .unwrap()
                    .sum_all()
                    .unwrap();
                let g = loss.backward().unwrap();
                opt.step(&g, 1.0).unwrap();
            }
            x.as_tensor().to_vec1::<f32>().unwrap()
        };
        let straight = run(300, None);
        let resumed = run(300, Some(120));
        for (a, b) in straight.iter().zip(&resumed) {
            assert!((a - b).abs() < 1e-6, "{a} vs {b}");
        }
        for (a, b) in straight.iter().zip([1.0f32, -2.0, 0.5]) {
            assert!((a - b).abs() < 1e-2, "converged to {a}, want {b}");
        }
    }
}
