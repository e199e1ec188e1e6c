//! Adam with saveable state (on dfdx's Adam kernel) and global gradient-norm clipping.
//!
//! dfdx 0.13's `optim::Adam` keeps its step count and moments in private fields (`t`, `moment1`,
//! `moment2`), so they cannot be checkpointed, and it walks models through `TensorCollection`,
//! which cannot hold run-time-shaped tensors. [`Adam`] here owns its moments (one pair per tensor,
//! in [`Parameters`] order) and calls dfdx's own update kernel, `AdamConfig::try_update`.

use dfdx::prelude::{Cpu, Gradients, Storage};
use dfdx::tensor_ops::AdamConfig;

use crate::nn::{ParamMut, Parameters};

/// dfdx's CPU buffer type (derefs to `Vec<f32>`).
type CpuVec = <Cpu as Storage<f32>>::Vec;

/// The gradient buffer of one parameter (allocated as zeros when the loss did not touch it).
fn grad_of<'g>(p: &ParamMut<'_>, grads: &'g mut Gradients<f32, Cpu>) -> &'g mut CpuVec {
    let g = match p {
        ParamMut::Matrix(t) => grads.get_or_alloc_mut(&**t),
        ParamMut::Vector(t) => grads.get_or_alloc_mut(&**t),
    };
    g.expect("the CPU device cannot fail to allocate")
}

/// Adam over every tensor a model lists; its state is plain data for checkpoints.
#[derive(Clone, Debug)]
pub struct Adam {
    /// Learning rate, betas, epsilon (dfdx's config type).
    pub cfg: AdamConfig,
    /// Steps taken so far (Adam's `t`, for bias correction).
    pub t: i32,
    /// First and second moments, one pair per tensor in [`Parameters`] order.
    moments: Vec<(CpuVec, CpuVec)>,
    dev: Cpu,
}

impl Adam {
    /// A fresh optimiser for `model` with learning rate `lr` and PyTorch's default betas and eps.
    pub fn new(model: &mut impl Parameters, lr: f64) -> Self {
        let dev = Cpu::default();
        let moments = model
            .params_mut()
            .iter()
            .map(|(_, p)| {
                let n = p.values().len();
                (zeros(&dev, n), zeros(&dev, n))
            })
            .collect();
        Adam { cfg: AdamConfig { lr, betas: [0.9, 0.999], eps: 1e-8, weight_decay: None }, t: 0, moments, dev }
    }

    /// One Adam step on every tensor of `model` with the gradients in `grads`.
    pub fn update(&mut self, model: &mut impl Parameters, grads: &mut Gradients<f32, Cpu>) {
        self.t += 1;
        for ((_, p), (m, v)) in model.params_mut().into_iter().zip(&mut self.moments) {
            let g = grad_of(&p, grads);
            let done = match p {
                ParamMut::Matrix(t) => self.cfg.try_update(self.t, t, m, v, g),
                ParamMut::Vector(t) => self.cfg.try_update(self.t, t, m, v, g),
            };
            done.expect("the CPU Adam kernel cannot fail");
        }
    }

    /// Forget every step taken: moments zeroed and the step count back to 0, as [`Adam::new`]
    /// leaves them (the learning rate and betas stay).
    pub fn reset(&mut self) {
        self.t = 0;
        for (m, v) in &mut self.moments {
            m.iter_mut().for_each(|x| *x = 0.0);
            v.iter_mut().for_each(|x| *x = 0.0);
        }
    }

    /// The moments as `(first, second)` plain vectors, in [`Parameters`] order.
    pub fn moments(&self) -> Vec<(Vec<f32>, Vec<f32>)> {
        self.moments.iter().map(|(m, v)| (m.to_vec(), v.to_vec())).collect()
    }

    /// Restore moments saved by [`Adam::moments`]; `false` if the count or a length differs.
    pub fn set_moments(&mut self, t: i32, saved: &[(Vec<f32>, Vec<f32>)]) -> bool {
        if saved.len() != self.moments.len()
            || saved.iter().zip(&self.moments).any(|((a, b), (m, v))| a.len() != m.len() || b.len() != v.len())
        {
            return false;
        }
        for ((a, b), (m, v)) in saved.iter().zip(&mut self.moments) {
            m.copy_from_slice(a);
            v.copy_from_slice(b);
        }
        self.t = t;
        true
    }

    /// The device the moments live on.
    pub fn device(&self) -> &Cpu {
        &self.dev
    }
}

fn zeros(dev: &Cpu, n: usize) -> CpuVec {
    dev.try_alloc_len(n).expect("the CPU device cannot fail to allocate")
}

/// Scale all of `model`'s gradients so their joint L2 norm is at most `max_norm`; returns the
/// norm before clipping (PyTorch's `clip_grad_norm_`).
pub fn clip_grad_norm(model: &mut impl Parameters, grads: &mut Gradients<f32, Cpu>, max_norm: f32) -> f32 {
    let params = model.params_mut();
    let sum_sq: f64 =
        params.iter().map(|(_, p)| grad_of(p, grads).iter().map(|&g| f64::from(g) * f64::from(g)).sum::<f64>()).sum();
    let norm = sum_sq.sqrt() as f32;
    if norm > max_norm {
        let scale = max_norm / (norm + 1e-6);
        for (_, p) in &params {
            grad_of(p, grads).iter_mut().for_each(|g| *g *= scale);
        }
    }
    norm
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nn::{Linear, Vector};
    use dfdx::prelude::*;
    use rand::SeedableRng;

    fn loss_grads(layer: &Linear) -> Gradients<f32, Cpu> {
        let dev = Cpu::default();
        let x = dev.tensor_from_vec(vec![1.0, -2.0, 0.5, 3.0, 0.0, 1.0], (2, 3));
        (layer.forward(x.leaky_trace()) * 3.0).square().mean().backward()
    }

    #[test]
    fn clipping_scales_the_global_norm() {
        let dev = Cpu::default();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
        let mut layer = Linear::new(&dev, 3, 2, 1.0, &mut rng);
        let mut grads = loss_grads(&layer);
        let w = grads.get(&layer.weight).as_vec();
        let b = grads.get(&layer.bias).as_vec();
        let expected: f32 = w.iter().chain(&b).map(|g| g * g).sum::<f32>().sqrt();
        assert!(expected > 0.5, "test needs a norm above the threshold");
        let norm = clip_grad_norm(&mut layer, &mut grads, 0.5);
        assert!((norm - expected).abs() < 1e-4 * expected);
        let w2 = grads.get(&layer.weight).as_vec();
        let b2 = grads.get(&layer.bias).as_vec();
        let after: f32 = w2.iter().chain(&b2).map(|g| g * g).sum::<f32>().sqrt();
        assert!((after - 0.5).abs() < 1e-4, "clipped norm {after}");
        // Direction is kept.
        let ratio = w2[0] / w[0];
        for (x, y) in w.iter().chain(&b).zip(w2.iter().chain(&b2)) {
            assert!((y - x * ratio).abs() < 1e-5);
        }
        // Below the threshold nothing changes.
        let norm2 = clip_grad_norm(&mut layer, &mut grads, 10.0);
        assert!((norm2 - 0.5).abs() < 1e-4);
        assert_eq!(grads.get(&layer.weight).as_vec(), w2);
    }

    #[test]
    fn adam_matches_dfdx_adam_bit_for_bit() {
        // dfdx's optimiser on a const-shape tensor vs ours on a run-time-shaped copy of it.
        use dfdx::optim::{Adam as DfdxAdam, Optimizer};
        let dev = Cpu::default();
        let init = [0.3f32, -1.0, 2.0, 0.0, 5.0];
        let rate = dev.tensor([0.1f32, 1.0, -2.0, 0.5, 3.0]);
        let mut theirs: Tensor<Rank1<5>, f32, Cpu> = dev.tensor(init);
        let mut opt_theirs = DfdxAdam::new(&theirs, AdamConfig::default());
        struct One(Vector);
        impl Parameters for One {
            fn params_mut(&mut self) -> Vec<(String, ParamMut<'_>)> {
                vec![("x".into(), ParamMut::Vector(&mut self.0))]
            }
        }
        let mut ours = One(dev.tensor_from_vec(init.to_vec(), (5,)));
        let mut opt_ours = Adam::new(&mut ours, 1e-3);
        let rate_rt = dev.tensor_from_vec(rate.as_vec(), (5,));
        for _ in 0..10 {
            let g = (theirs.leaky_trace() * rate.clone()).square().mean().backward();
            opt_theirs.update(&mut theirs, &g).expect("update");
            let mut g = (ours.0.leaky_trace() * rate_rt.clone()).square().mean().backward();
            opt_ours.update(&mut ours, &mut g);
        }
        assert_eq!(theirs.as_vec(), ours.0.as_vec());
    }
}
