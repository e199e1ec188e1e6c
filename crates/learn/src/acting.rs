//! [`ActingPolicy`]: what a trained skill needs to act, and nothing else: the Gaussian policy's
//! mean network and log-std, and the observation normaliser frozen at the end of training. One
//! safetensors file, written atomically; loading refuses truncated, corrupt or ill-shaped files.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use dfdx::prelude::HasShape;
use safetensors::{Dtype, SafeTensors, tensor::TensorView};

use crate::checkpoint::CheckpointError;
use crate::env::Env;
use crate::nn::{Mlp, MlpInference};
use crate::normalize::RunningMeanStd;
use crate::ppo::{OBS_CLIP, Ppo};

pub use crate::nn::ShapeError;

/// A trained Gaussian policy with its frozen observation normaliser.
#[derive(Clone, Debug)]
pub struct ActingPolicy {
    /// Observation → action mean.
    pub mean: MlpInference,
    /// Log standard deviation per action dimension.
    pub log_std: Vec<f32>,
    /// Observation statistics (identity when training did not normalise).
    pub obs_rms: RunningMeanStd,
    /// Whether observations are normalised before the network.
    pub normalize_obs: bool,
    scratch: Vec<f32>,
}

pub(crate) fn corrupt(path: &Path, reason: impl Into<String>) -> CheckpointError {
    CheckpointError::Corrupt { path: path.to_path_buf(), reason: reason.into() }
}

fn f32s(path: &Path, st: &SafeTensors<'_>, name: &str) -> Result<(Vec<usize>, Vec<f32>), CheckpointError> {
    let t = st.tensor(name).map_err(|_| corrupt(path, format!("no tensor `{name}`")))?;
    if t.dtype() != Dtype::F32 {
        return Err(corrupt(path, format!("tensor `{name}` is {:?}, expected F32", t.dtype())));
    }
    let v = t.data().chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
    Ok((t.shape().to_vec(), v))
}

pub(crate) fn f64s(path: &Path, st: &SafeTensors<'_>, name: &str) -> Result<Vec<f64>, CheckpointError> {
    let t = st.tensor(name).map_err(|_| corrupt(path, format!("no tensor `{name}`")))?;
    if t.dtype() != Dtype::F64 {
        return Err(corrupt(path, format!("tensor `{name}` is {:?}, expected F64", t.dtype())));
    }
    Ok(t.data().chunks_exact(8).map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes"))).collect())
}

impl ActingPolicy {
    /// The current policy and normaliser of a PPO learner.
    pub fn from_ppo<E: Env>(ppo: &Ppo<E>) -> Self {
        let g = ppo.policy_inference();
        ActingPolicy {
            mean: g.mean_net().clone(),
            log_std: g.log_std.clone(),
            obs_rms: ppo.obs_rms.clone(),
            normalize_obs: ppo.cfg.normalize_obs,
            scratch: Vec::new(),
        }
    }

    /// Starts `ppo` from this policy (fine-tuning): the mean network, log-std and observation
    /// statistics are copied in (the value network keeps its initialisation). `Err` names the
    /// first shape that differs.
    pub fn load_into<E: Env>(&self, ppo: &mut Ppo<E>) -> Result<(), ShapeError> {
        let policy = &mut ppo.agent.policy;
        copy_mlp(&mut policy.mean, &self.mean, "policy")?;
        width("action", self.log_std.len(), policy.log_std.shape().0)?;
        width("observation", self.obs_rms.dim(), ppo.obs_rms.dim())?;
        policy.log_std.copy_from(&self.log_std);
        ppo.obs_rms = self.obs_rms.clone();
        if ppo.cfg.normalize_obs {
            ppo.obs_rms.normalize(&ppo.envs.obs, &mut ppo.next_obs, OBS_CLIP);
        }
        Ok(())
    }

    /// This policy taking `inputs` observation values, the new ones appended after its own:
    /// they enter the first layer with zero weights and identity statistics (mean 0,
    /// variance 1), so the widened policy acts exactly as this one until training gives them
    /// weight (a skill's next training stage observing more, such as walk's target). `Err`
    /// when `inputs` is fewer than it takes now.
    pub fn widened(&self, inputs: usize) -> Result<ActingPolicy, ShapeError> {
        let have = self.obs_dim();
        if inputs < have {
            return Err(ShapeError::Narrow { have, want: inputs });
        }
        self.with_inputs_at(have, inputs - have)
    }

    /// This policy with `count` new observation values inserted before its input `at` (`at`
    /// = its width appends them), entering as in [`ActingPolicy::widened`]: a skill started
    /// from another that observes less (carry from walk, which does not see the box).
    pub fn with_inputs_at(&self, at: usize, count: usize) -> Result<ActingPolicy, ShapeError> {
        let have = self.obs_dim();
        if at > have {
            return Err(ShapeError::InsertPast { at, inputs: have });
        }
        let mut obs_rms = self.obs_rms.clone();
        obs_rms.mean.splice(at..at, std::iter::repeat_n(0.0, count));
        obs_rms.var.splice(at..at, std::iter::repeat_n(1.0, count));
        Ok(ActingPolicy {
            mean: insert_zero_inputs(&self.mean, at, count)?,
            log_std: self.log_std.clone(),
            obs_rms,
            normalize_obs: self.normalize_obs,
            scratch: Vec::new(),
        })
    }

    /// Observation width.
    pub fn obs_dim(&self) -> usize {
        self.mean.inputs()
    }

    /// Action width.
    pub fn act_dim(&self) -> usize {
        self.mean.outputs()
    }

    /// Mean actions `[B × act_dim]` for raw observations `[B × obs_dim]` (normalised here).
    pub fn act(&mut self, obs: &[f32], actions: &mut [f32]) {
        if self.normalize_obs {
            self.scratch.resize(obs.len(), 0.0);
            self.obs_rms.normalize(obs, &mut self.scratch, OBS_CLIP);
            self.mean.forward(&self.scratch, actions);
        } else {
            self.mean.forward(obs, actions);
        }
    }

    /// Writes the policy to `path` (safetensors) via a temporary sibling and a rename.
    pub fn save(&self, path: &Path) -> Result<(), CheckpointError> {
        let mut entries: Vec<(String, Dtype, Vec<usize>, Vec<u8>)> = Vec::new();
        entries.extend(layer_entries("mean", &self.mean));
        entries.push(("log_std".into(), Dtype::F32, vec![self.log_std.len()], bytes32(&self.log_std)));
        let d = self.obs_rms.dim();
        entries.push(("obs.mean".into(), Dtype::F64, vec![d], bytes64(&self.obs_rms.mean)));
        entries.push(("obs.var".into(), Dtype::F64, vec![d], bytes64(&self.obs_rms.var)));
        entries.push(("obs.count".into(), Dtype::F64, vec![1], bytes64(&[self.obs_rms.count])));
        let flag = if self.normalize_obs { 1.0 } else { 0.0 };
        entries.push(("obs.normalize".into(), Dtype::F64, vec![1], bytes64(&[flag])));
        write_entries(path, &entries, "repertoire-acting-policy-1")
    }

    /// Reads a policy written by [`ActingPolicy::save`].
    pub fn load(path: &Path) -> Result<Self, CheckpointError> {
        let bytes = std::fs::read(path).map_err(|source| CheckpointError::Io { path: path.to_path_buf(), source })?;
        let st = SafeTensors::deserialize(&bytes).map_err(|e| corrupt(path, e.to_string()))?;
        let mean = read_mlp(path, &st, "mean")?;
        let (_, log_std) = f32s(path, &st, "log_std")?;
        if log_std.len() != mean.outputs() || log_std.iter().any(|v| !v.is_finite()) {
            return Err(corrupt(path, format!("log_std has {} values for {} actions", log_std.len(), mean.outputs())));
        }
        let obs_mean = f64s(path, &st, "obs.mean")?;
        let obs_var = f64s(path, &st, "obs.var")?;
        let count = f64s(path, &st, "obs.count")?;
        let flag = f64s(path, &st, "obs.normalize")?;
        if obs_mean.len() != mean.inputs() || obs_var.len() != mean.inputs() || count.len() != 1 || flag.len() != 1 {
            return Err(corrupt(path, format!("observation statistics do not fit {} inputs", mean.inputs())));
        }
        if obs_mean.iter().chain(&obs_var).any(|v| !v.is_finite()) || obs_var.iter().any(|&v| v < 0.0) {
            return Err(corrupt(path, "observation statistics hold a NaN, infinite or negative variance"));
        }
        Ok(ActingPolicy {
            mean,
            log_std,
            obs_rms: RunningMeanStd { mean: obs_mean, var: obs_var, count: count[0] },
            normalize_obs: flag[0] != 0.0,
            scratch: Vec::new(),
        })
    }
}

/// One tensor to write: name, type, shape, little-endian bytes.
pub(crate) type Entry = (String, Dtype, Vec<usize>, Vec<u8>);

fn bytes32(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

pub(crate) fn bytes64(v: &[f64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// The layers of `mlp` as `PREFIX.i.weight` / `PREFIX.i.bias` tensors.
pub(crate) fn layer_entries(prefix: &str, mlp: &MlpInference) -> Vec<Entry> {
    let mut entries = Vec::new();
    for (i, (inputs, outputs, w, b)) in mlp.layers().iter().enumerate() {
        entries.push((format!("{prefix}.{i}.weight"), Dtype::F32, vec![*inputs, *outputs], bytes32(w)));
        entries.push((format!("{prefix}.{i}.bias"), Dtype::F32, vec![*outputs], bytes32(b)));
    }
    entries
}

/// Reads the MLP stored under `prefix` (`PREFIX.i.weight` `[inputs, outputs]` and
/// `PREFIX.i.bias`, f32, for i = 0, 1, … until one is missing), as [`ActingPolicy::save`] and
/// [`ActingCritic::save`] write it. `Err` is [`CheckpointError::Corrupt`] naming `path` and the
/// tensor: a missing bias, another dtype, a shape that is not 2-D or does not chain, a NaN or an
/// infinity.
pub fn read_mlp(path: &Path, st: &SafeTensors<'_>, prefix: &str) -> Result<MlpInference, CheckpointError> {
    let mut layers = Vec::new();
    for i in 0.. {
        if st.tensor(&format!("{prefix}.{i}.weight")).is_err() {
            break;
        }
        let (shape, w) = f32s(path, st, &format!("{prefix}.{i}.weight"))?;
        let (_, b) = f32s(path, st, &format!("{prefix}.{i}.bias"))?;
        if shape.len() != 2 {
            return Err(corrupt(path, format!("{prefix}.{i}.weight has shape {shape:?}, expected 2-D")));
        }
        if w.iter().chain(&b).any(|v| !v.is_finite()) {
            return Err(corrupt(path, format!("layer {prefix}.{i} holds a NaN or infinite weight")));
        }
        layers.push((shape[0], shape[1], w, b));
    }
    MlpInference::from_layers(layers).map_err(|e| corrupt(path, e.to_string()))
}

/// Writes `entries` to `path` as safetensors (format tag `format`), atomically.
pub(crate) fn write_entries(path: &Path, entries: &[Entry], format: &str) -> Result<(), CheckpointError> {
    let views: Vec<(String, TensorView<'_>)> = entries
        .iter()
        .map(|(n, dt, shape, data)| (n.clone(), TensorView::new(*dt, shape.clone(), data).expect("sizes match")))
        .collect();
    let meta = HashMap::from([("format".to_string(), format.to_string())]);
    let bytes =
        safetensors::serialize(views, Some(meta)).map_err(|e| corrupt(path, format!("cannot serialise: {e}")))?;
    repertoire_files::write_atomic(path, &bytes).map_err(|e| CheckpointError::Io { path: e.path, source: e.source })
}

/// `Err` naming `what` when the saved width differs from the learner's.
fn width(what: &'static str, saved: usize, learner: usize) -> Result<(), ShapeError> {
    if saved == learner { Ok(()) } else { Err(ShapeError::Width { what, saved, learner }) }
}

/// Copies `src`'s weights into the trainable `dst` (`what` names it in the error); `Err` names
/// the first shape that differs.
fn copy_mlp(dst: &mut Mlp, src: &MlpInference, what: &'static str) -> Result<(), ShapeError> {
    if dst.layers.len() != src.layers().len() {
        return Err(ShapeError::Layers { what, saved: src.layers().len(), config: dst.layers.len() });
    }
    for (i, (layer, (inputs, outputs, w, b))) in dst.layers.iter_mut().zip(src.layers()).enumerate() {
        if (layer.inputs(), layer.outputs()) != (*inputs, *outputs) {
            return Err(ShapeError::Layer {
                what,
                layer: i,
                saved: (*inputs, *outputs),
                config: (layer.inputs(), layer.outputs()),
            });
        }
        layer.weight.copy_from(w);
        layer.bias.copy_from(b);
    }
    Ok(())
}

/// `mlp` with `count` inputs inserted before its input `at`, entering with zero weights.
fn insert_zero_inputs(mlp: &MlpInference, at: usize, count: usize) -> Result<MlpInference, ShapeError> {
    let mut layers = mlp.layers().to_vec();
    let (inputs, outputs, w, _) = &mut layers[0];
    if at > *inputs {
        return Err(ShapeError::InsertPast { at, inputs: *inputs });
    }
    // Row-major [in × out]: the new inputs are `count` zero rows from row `at`.
    let outputs = *outputs;
    w.splice(at * outputs..at * outputs, std::iter::repeat_n(0.0, count * outputs));
    layers[0].0 += count;
    MlpInference::from_layers(layers)
}

/// A trained skill's value network with the statistics of the returns its outputs are scaled
/// by (PPO's reward normaliser), saved beside the acting policy so that the next training stage
/// of the same skill (a fine-tune, a warm start) starts with a critic that already knows the
/// task instead of a fresh one whose first updates pull the policy about.
#[derive(Clone, Debug)]
pub struct ActingCritic {
    /// Normalised observation → value.
    pub value: MlpInference,
    /// The reward normaliser's statistics of discounted returns.
    pub returns: RunningMeanStd,
}

impl ActingCritic {
    /// The current value network and return statistics of a PPO learner.
    pub fn from_ppo<E: Env>(ppo: &Ppo<E>) -> Self {
        ActingCritic { value: ppo.agent.value.net.inference(), returns: ppo.reward_scaler.rms.clone() }
    }

    /// Starts `ppo`'s value network and reward normaliser from this critic. `Err` names the
    /// first shape that differs.
    pub fn load_into<E: Env>(&self, ppo: &mut Ppo<E>) -> Result<(), ShapeError> {
        width("value network's input", self.value.inputs(), ppo.envs.obs_dim())?;
        width("value network's output", self.value.outputs(), 1)?;
        copy_mlp(&mut ppo.agent.value.net, &self.value, "value")?;
        ppo.reward_scaler.rms = self.returns.clone();
        Ok(())
    }

    /// This critic with `count` observation values inserted before its input `at`, as
    /// [`ActingPolicy::with_inputs_at`] does for the policy it was saved with.
    pub fn with_inputs_at(&self, at: usize, count: usize) -> Result<ActingCritic, ShapeError> {
        Ok(ActingCritic { value: insert_zero_inputs(&self.value, at, count)?, returns: self.returns.clone() })
    }

    /// Observation width.
    pub fn obs_dim(&self) -> usize {
        self.value.inputs()
    }

    /// Writes the critic to `path` (safetensors) via a temporary sibling and a rename.
    pub fn save(&self, path: &Path) -> Result<(), CheckpointError> {
        let mut entries = layer_entries("value", &self.value);
        let r = &self.returns;
        entries.push(("returns.mean".into(), Dtype::F64, vec![1], bytes64(&r.mean)));
        entries.push(("returns.var".into(), Dtype::F64, vec![1], bytes64(&r.var)));
        entries.push(("returns.count".into(), Dtype::F64, vec![1], bytes64(&[r.count])));
        write_entries(path, &entries, "repertoire-critic-1")
    }

    /// Reads a critic written by [`ActingCritic::save`].
    pub fn load(path: &Path) -> Result<Self, CheckpointError> {
        let bytes = std::fs::read(path).map_err(|source| CheckpointError::Io { path: path.to_path_buf(), source })?;
        Self::parse(path, &bytes)
    }

    /// [`ActingCritic::load`] of bytes already read from `path` (named in errors).
    pub fn parse(path: &Path, bytes: &[u8]) -> Result<Self, CheckpointError> {
        let st = SafeTensors::deserialize(bytes).map_err(|e| corrupt(path, e.to_string()))?;
        let value = read_mlp(path, &st, "value")?;
        if value.outputs() != 1 {
            return Err(corrupt(path, format!("the value network has {} outputs, expected 1", value.outputs())));
        }
        let (mean, var, count) =
            (f64s(path, &st, "returns.mean")?, f64s(path, &st, "returns.var")?, f64s(path, &st, "returns.count")?);
        if mean.len() != 1 || var.len() != 1 || count.len() != 1 {
            return Err(corrupt(path, "the return statistics are not one value each"));
        }
        if !(mean[0].is_finite() && var[0].is_finite() && var[0] >= 0.0 && count[0].is_finite()) {
            return Err(corrupt(path, "the return statistics hold a NaN, infinite or negative variance"));
        }
        Ok(ActingCritic { value, returns: RunningMeanStd { mean, var, count: count[0] } })
    }
}

/// A trained hybrid head (a meta-controller) with its frozen observation normaliser.
#[derive(Clone, Debug)]
pub struct ActingHybrid {
    /// The head.
    pub head: crate::policy::HybridInference,
    /// Observation statistics.
    pub obs_rms: RunningMeanStd,
    /// Whether observations are normalised before the networks.
    pub normalize_obs: bool,
    scratch: Vec<f32>,
}

impl ActingHybrid {
    /// The current head and normaliser of a PPO learner over hybrid actions.
    pub fn from_ppo<E: Env>(ppo: &Ppo<E>) -> Option<Self> {
        Some(ActingHybrid {
            head: ppo.hybrid_inference()?,
            obs_rms: ppo.obs_rms.clone(),
            normalize_obs: ppo.cfg.normalize_obs,
            scratch: Vec::new(),
        })
    }

    /// The most likely allowed option and the mean continuous part for raw observations.
    pub fn act(&mut self, obs: &[f32], masks: &[bool], actions: &mut [f32]) {
        if self.normalize_obs {
            self.scratch.resize(obs.len(), 0.0);
            self.obs_rms.normalize(obs, &mut self.scratch, OBS_CLIP);
            self.head.mode(&self.scratch, masks, actions);
        } else {
            self.head.mode(obs, masks, actions);
        }
    }

    /// An allowed option and continuous part drawn from the head's distribution (the policy
    /// PPO trained, rather than its mode) for raw observations.
    pub fn sample(&mut self, obs: &[f32], masks: &[bool], rng: &mut impl rand::Rng, actions: &mut [f32]) {
        let batch = obs.len() / self.obs_rms.dim().max(1);
        let mut log_probs = vec![0.0; batch.max(1)];
        if self.normalize_obs {
            self.scratch.resize(obs.len(), 0.0);
            self.obs_rms.normalize(obs, &mut self.scratch, OBS_CLIP);
            self.head.sample(&self.scratch, masks, rng, actions, &mut log_probs);
        } else {
            self.head.sample(obs, masks, rng, actions, &mut log_probs);
        }
    }

    /// Starts `ppo`'s hybrid head and observation statistics from this controller (a warm
    /// start: the value network keeps its initialisation unless a critic is loaded as well).
    /// `Err` names the first thing that differs: no hybrid head, the options, the continuous
    /// width, a layer's shape or the observation width.
    pub fn load_into<E: Env>(&self, ppo: &mut Ppo<E>) -> Result<(), ShapeError> {
        width("observation", self.obs_rms.dim(), ppo.obs_rms.dim())?;
        let Some(hybrid) = ppo.agent.hybrid.as_mut() else {
            return Err(ShapeError::NotHybrid);
        };
        if hybrid.uses_continuous != self.head.uses_continuous {
            return Err(ShapeError::Options {
                saved: self.head.uses_continuous.clone(),
                learner: hybrid.uses_continuous.clone(),
            });
        }
        width("continuous action", self.head.log_std.len(), hybrid.log_std.shape().0)?;
        copy_mlp(&mut hybrid.logits, &self.head.logits, "option")?;
        copy_mlp(&mut hybrid.mean, &self.head.mean, "continuous")?;
        hybrid.log_std.copy_from(&self.head.log_std);
        ppo.obs_rms = self.obs_rms.clone();
        if ppo.cfg.normalize_obs {
            ppo.obs_rms.normalize(&ppo.envs.obs, &mut ppo.next_obs, OBS_CLIP);
        }
        Ok(())
    }

    /// Writes the head to `path` (safetensors, via temporary siblings and renames).
    pub fn save(&self, path: &Path) -> Result<(), CheckpointError> {
        let as_policy = |mean: &MlpInference, log_std: Vec<f32>| ActingPolicy {
            mean: mean.clone(),
            log_std,
            obs_rms: self.obs_rms.clone(),
            normalize_obs: self.normalize_obs,
            scratch: Vec::new(),
        };
        // Two acting-policy files side by side: the option logits and the continuous part.
        let k = self.head.uses_continuous.len();
        let uses: Vec<f32> = self.head.uses_continuous.iter().map(|&u| if u { 1.0 } else { 0.0 }).collect();
        as_policy(&self.head.logits, uses).save(&with_suffix(path, "logits"))?;
        debug_assert_eq!(k, self.head.logits.outputs());
        as_policy(&self.head.mean, self.head.log_std.clone()).save(path)
    }

    /// Reads a head written by [`ActingHybrid::save`].
    pub fn load(path: &Path) -> Result<Self, CheckpointError> {
        let logits = ActingPolicy::load(&with_suffix(path, "logits"))?;
        let mean = ActingPolicy::load(path)?;
        if logits.obs_dim() != mean.obs_dim() {
            return Err(corrupt(path, "the option and continuous networks read different observations"));
        }
        let uses = logits.log_std.iter().map(|&u| u > 0.5).collect();
        Ok(ActingHybrid {
            head: crate::policy::HybridInference::new(logits.mean, mean.mean, mean.log_std, uses),
            obs_rms: mean.obs_rms,
            normalize_obs: mean.normalize_obs,
            scratch: Vec::new(),
        })
    }
}

/// `dir/name.safetensors` → `dir/name.SUFFIX.safetensors`.
fn with_suffix(path: &Path, suffix: &str) -> PathBuf {
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    path.with_file_name(format!("{stem}.{suffix}.safetensors"))
}
