//! Checkpoints: a safetensors file (network weights, Adam moments, normaliser statistics) beside
//! a RON manifest (config, sizes, counters, RNG and environment states, format version, and the
//! length and hash of the weights file). Both are written to temporary siblings and renamed into place,
//! and [`load`] refuses truncated, corrupt or mismatched checkpoints with a [`CheckpointError`].

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use rand_chacha::ChaCha8Rng;
use safetensors::{Dtype, SafeTensors, tensor::TensorView};
use serde::{Deserialize, Serialize};

use crate::env::{Env, VecEnvState};
use crate::nn::Parameters;
use crate::ppo::{Ppo, PpoConfig};

/// Version of the checkpoint layout this build writes and reads.
pub const FORMAT_VERSION: u32 = 1;

/// Why a checkpoint could not be written or read; every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    /// A file could not be read, written or renamed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The manifest is not valid RON for a checkpoint (includes line and column).
    #[error("{path} is not a valid checkpoint manifest: {source}")]
    Manifest {
        /// The manifest file.
        path: PathBuf,
        /// The parse error.
        source: Box<ron::error::SpannedError>,
    },
    /// The manifest could not be serialised.
    #[error("{path}: cannot serialise the manifest: {source}")]
    Serialize {
        /// The manifest file.
        path: PathBuf,
        /// The serialisation error.
        source: Box<ron::Error>,
    },
    /// The checkpoint was written by an incompatible version of this crate.
    #[error("{path} has checkpoint format {found}; this build reads format {expected}")]
    Version {
        /// The manifest file.
        path: PathBuf,
        /// Version in the file.
        found: u32,
        /// Version this build reads.
        expected: u32,
    },
    /// The weights file is truncated, corrupt, or not the one the manifest describes.
    #[error("{path} is corrupt or truncated: {reason}")]
    Corrupt {
        /// The weights file.
        path: PathBuf,
        /// What was wrong.
        reason: String,
    },
    /// The checkpoint does not fit the environments or networks it is loaded into.
    #[error("{path} does not fit: {what} is {saved} in the checkpoint but {here} here")]
    Mismatch {
        /// The checkpoint file.
        path: PathBuf,
        /// Which quantity differs (e.g. `observation size`).
        what: String,
        /// The value saved.
        saved: String,
        /// The value expected now.
        here: String,
    },
}

/// The RON half of a checkpoint.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// Layout version ([`FORMAT_VERSION`]).
    pub format_version: u32,
    /// The training configuration.
    pub config: PpoConfig,
    /// Observation size.
    pub obs_dim: usize,
    /// Action size.
    pub act_dim: usize,
    /// Number of environments.
    pub num_envs: usize,
    /// Iterations completed.
    pub iteration: usize,
    /// Environment steps taken.
    pub global_step: u64,
    /// Adam's step count.
    pub adam_steps: i32,
    /// The learner's RNG (actions, minibatches).
    pub rng: ChaCha8Rng,
    /// Environment states, RNGs and current observations.
    pub envs: VecEnvState,
    /// The normalised current observations.
    pub next_obs: Vec<f32>,
    /// File name of the weights, next to the manifest.
    pub weights_file: String,
    /// Byte length of the weights file.
    pub weights_len: u64,
    /// FNV-1a hash of the weights file.
    pub weights_fnv1a: u64,
    /// `git rev-parse HEAD` when saved, if available.
    pub git_hash: Option<String>,
}

/// 64-bit FNV-1a (enough to detect a torn or swapped file; not a cryptographic check).
pub fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

/// `path` with its extension set to `ext`.
fn with_ext(path: &Path, ext: &str) -> PathBuf {
    path.with_extension(ext)
}

/// The manifest of the checkpoint `stem` (`…/iter-000100` → `…/iter-000100.ron`), as [`save`]
/// writes and [`load`] reads it.
pub fn manifest_path(stem: &Path) -> PathBuf {
    with_ext(stem, "ron")
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> CheckpointError + '_ {
    move |source| CheckpointError::Io { path: path.to_path_buf(), source }
}

/// Write `bytes` to a temporary sibling of `path`, then rename it into place.
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), CheckpointError> {
    repertoire_files::write_atomic(path, bytes).map_err(|e| CheckpointError::Io { path: e.path, source: e.source })
}

/// A named tensor to be written: dtype, shape, little-endian bytes.
type Entry = (Dtype, Vec<usize>, Vec<u8>);

fn f32_entry(shape: Vec<usize>, v: &[f32]) -> Entry {
    (Dtype::F32, shape, v.iter().flat_map(|x| x.to_le_bytes()).collect())
}

fn f64_entry(v: &[f64]) -> Entry {
    (Dtype::F64, vec![v.len()], v.iter().flat_map(|x| x.to_le_bytes()).collect())
}

/// Save `ppo` as `<stem>.safetensors` + `<stem>.ron`; returns the manifest path.
pub fn save<E: Env>(ppo: &mut Ppo<E>, stem: &Path) -> Result<PathBuf, CheckpointError> {
    let weights_path = with_ext(stem, "safetensors");
    let manifest_path = with_ext(stem, "ron");

    let mut tensors: HashMap<String, Entry> = HashMap::new();
    let moments = ppo.optimizer.moments();
    for ((name, p), (m, v)) in ppo.agent.params_mut().into_iter().zip(&moments) {
        let dims = p.dims();
        tensors.insert(format!("adam.m.{name}"), f32_entry(dims.clone(), m));
        tensors.insert(format!("adam.v.{name}"), f32_entry(dims.clone(), v));
        tensors.insert(format!("agent.{name}"), f32_entry(dims, &p.values()));
    }
    let obs = &ppo.obs_rms;
    tensors.insert("obs_rms.mean".into(), f64_entry(&obs.mean));
    tensors.insert("obs_rms.var".into(), f64_entry(&obs.var));
    tensors.insert("obs_rms.count".into(), f64_entry(&[obs.count]));
    let rew = &ppo.reward_scaler;
    tensors.insert("reward_rms.mean".into(), f64_entry(&rew.rms.mean));
    tensors.insert("reward_rms.var".into(), f64_entry(&rew.rms.var));
    tensors.insert("reward_rms.count".into(), f64_entry(&[rew.rms.count]));
    tensors.insert("reward.returns".into(), f64_entry(&rew.returns));

    let views = tensors.iter().map(|(name, (dtype, shape, bytes))| {
        let view = TensorView::new(*dtype, shape.clone(), bytes).expect("shape and byte length agree by construction");
        (name.clone(), view)
    });
    let bytes = safetensors::serialize(views, None)
        .map_err(|e| CheckpointError::Corrupt { path: weights_path.clone(), reason: e.to_string() })?;

    let manifest = Manifest {
        format_version: FORMAT_VERSION,
        config: ppo.cfg.clone(),
        obs_dim: ppo.envs.obs_dim(),
        act_dim: ppo.envs.act_dim(),
        num_envs: ppo.envs.len(),
        iteration: ppo.iteration,
        global_step: ppo.global_step,
        adam_steps: ppo.optimizer.t,
        rng: ppo.rng.clone(),
        envs: ppo.envs.state(),
        next_obs: ppo.next_obs.clone(),
        weights_file: weights_path.file_name().map_or_else(String::new, |f| f.to_string_lossy().into_owned()),
        weights_len: bytes.len() as u64,
        weights_fnv1a: fnv1a(&bytes),
        git_hash: crate::run_dir::git_hash(),
    };
    let text = ron::ser::to_string_pretty(&manifest, ron::ser::PrettyConfig::default())
        .map_err(|source| CheckpointError::Serialize { path: manifest_path.clone(), source: Box::new(source) })?;
    // Weights first: a crash in between leaves the old manifest, whose hash then refuses the new
    // weights instead of silently mixing them.
    write_atomic(&weights_path, &bytes)?;
    write_atomic(&manifest_path, text.as_bytes())?;
    Ok(manifest_path)
}

/// Read and check a manifest (`<stem>.ron`).
pub fn read_manifest(path: &Path) -> Result<Manifest, CheckpointError> {
    let text = std::fs::read_to_string(path).map_err(io_err(path))?;
    let manifest: Manifest = ron::from_str(&text)
        .map_err(|source| CheckpointError::Manifest { path: path.to_path_buf(), source: Box::new(source) })?;
    if manifest.format_version != FORMAT_VERSION {
        return Err(CheckpointError::Version {
            path: path.to_path_buf(),
            found: manifest.format_version,
            expected: FORMAT_VERSION,
        });
    }
    Ok(manifest)
}

/// Rebuild a learner from the checkpoint at `<stem>.ron`/`.safetensors` over `envs`, so that
/// training continues exactly as if it had never stopped.
pub fn load<E: Env>(stem: &Path, envs: Vec<E>) -> Result<Ppo<E>, CheckpointError> {
    let manifest_path = with_ext(stem, "ron");
    let m = read_manifest(&manifest_path)?;
    let mismatch = |what: &str, saved: usize, here: usize| {
        (saved != here).then(|| CheckpointError::Mismatch {
            path: manifest_path.clone(),
            what: what.into(),
            saved: saved.to_string(),
            here: here.to_string(),
        })
    };
    let (od, ad) = envs.first().map_or((0, 0), |e| (e.obs_dim(), e.act_dim()));
    if let Some(e) = mismatch("observation size", m.obs_dim, od)
        .or_else(|| mismatch("action size", m.act_dim, ad))
        .or_else(|| mismatch("number of environments", m.num_envs, envs.len()))
    {
        return Err(e);
    }

    let weights_path = manifest_path.with_file_name(&m.weights_file);
    let bytes = std::fs::read(&weights_path).map_err(io_err(&weights_path))?;
    let corrupt = |reason: String| CheckpointError::Corrupt { path: weights_path.clone(), reason };
    if bytes.len() as u64 != m.weights_len {
        return Err(corrupt(format!("{} bytes, the manifest expects {}", bytes.len(), m.weights_len)));
    }
    if fnv1a(&bytes) != m.weights_fnv1a {
        return Err(corrupt("contents differ from the hash in the manifest".into()));
    }
    let st = SafeTensors::deserialize(&bytes).map_err(|e| corrupt(e.to_string()))?;
    let read = |name: &str, dtype: Dtype, shape: &[usize]| -> Result<Vec<u8>, CheckpointError> {
        let t = st.tensor(name).map_err(|_| corrupt(format!("tensor `{name}` is missing")))?;
        if t.dtype() != dtype || t.shape() != shape {
            return Err(CheckpointError::Mismatch {
                path: weights_path.clone(),
                what: format!("tensor `{name}`"),
                saved: format!("{:?} {:?}", t.dtype(), t.shape()),
                here: format!("{dtype:?} {shape:?}"),
            });
        }
        Ok(t.data().to_vec())
    };
    let f32s = |name: &str, shape: &[usize]| {
        read(name, Dtype::F32, shape)
            .map(|b| b.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect::<Vec<f32>>())
    };
    let f64s = |name: &str, len: usize| {
        read(name, Dtype::F64, &[len])
            .map(|b| b.chunks_exact(8).map(|c| f64::from_le_bytes(std::array::from_fn(|i| c[i]))).collect::<Vec<f64>>())
    };

    let mut ppo = Ppo::new(m.config.clone(), envs);
    let mut moments = Vec::new();
    for (name, mut p) in ppo.agent.params_mut() {
        let dims = p.dims();
        p.set_values(&f32s(&format!("agent.{name}"), &dims)?);
        moments.push((f32s(&format!("adam.m.{name}"), &dims)?, f32s(&format!("adam.v.{name}"), &dims)?));
    }
    if !ppo.optimizer.set_moments(m.adam_steps, &moments) {
        return Err(corrupt("Adam moments do not match the networks".into()));
    }
    ppo.obs_rms.mean = f64s("obs_rms.mean", od)?;
    ppo.obs_rms.var = f64s("obs_rms.var", od)?;
    ppo.obs_rms.count = f64s("obs_rms.count", 1)?[0];
    ppo.reward_scaler.rms.mean = f64s("reward_rms.mean", 1)?;
    ppo.reward_scaler.rms.var = f64s("reward_rms.var", 1)?;
    ppo.reward_scaler.rms.count = f64s("reward_rms.count", 1)?[0];
    ppo.reward_scaler.returns = f64s("reward.returns", m.num_envs)?;

    ppo.envs
        .set_state(&m.envs)
        .map_err(|e| CheckpointError::Corrupt { path: manifest_path.clone(), reason: e.to_string() })?;
    if m.next_obs.len() != ppo.next_obs.len() {
        return Err(CheckpointError::Corrupt {
            path: manifest_path.clone(),
            reason: "normalised observation batch has the wrong length".into(),
        });
    }
    ppo.next_obs = m.next_obs;
    ppo.rng = m.rng;
    ppo.iteration = m.iteration;
    ppo.global_step = m.global_step;
    Ok(ppo)
}
