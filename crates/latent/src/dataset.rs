//! Expert rollouts as a compact dataset: library skills act from random clip frames with
//! Gaussian action noise, and every step's decoder input (proprioception), encoder input (the
//! next `k` reference frames), mean and noisy actions, imitation reward and ids are kept in one
//! f32 safetensors file beside a RON manifest (shapes, `k`, sources, seed, body hash, layouts,
//! checksum). Damaged or mismatched files are refused naming the file.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use indicatif::{ProgressBar, ProgressStyle};
use repertoire_learn::acting::ActingPolicy;
use repertoire_learn::checkpoint::fnv1a;
use repertoire_scenes::obs::LayoutEntry;
use repertoire_scenes::{Feature, ObservationLayout};
use repertoire_skill::imitation::TaskSettings;
use repertoire_skill::spec::Init;
use repertoire_skill::{SkillSetup, SpecFile, library};
use safetensors::{Dtype, SafeTensors, tensor::TensorView};
use serde::{Deserialize, Serialize};

use crate::error::{LatentError, Result, write_atomic};
use crate::reference::{reference_layout, reference_size};
use crate::rollout::{Budget, Controller, RolloutOptions, rollout};

/// Format of the dataset manifests this build writes and reads.
pub const DATASET_FORMAT: u32 = 1;
/// The manifest's file name in a dataset folder.
pub const MANIFEST_FILE: &str = "dataset.ron";
/// The data's file name in a dataset folder.
pub const DATA_FILE: &str = "dataset.safetensors";

/// A skill whose rollouts are in the dataset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SourceSkill {
    /// The skill's name (its index in [`DatasetManifest::skills`] is its id in the data).
    pub name: String,
    /// The spec its environment was built from.
    pub spec: String,
    /// FNV-1a of the policy file that acted.
    pub policy_fnv1a: u64,
    /// Content hash of its clip.
    pub clip_hash: String,
    /// Reference frames of its clip at the control rate.
    pub frames: usize,
    /// Transitions recorded.
    pub steps: u64,
    /// Episodes begun.
    pub episodes: u64,
    /// Episodes that ended in a fall.
    pub falls: u64,
}

/// `dataset.ron`: what the data file holds and where it came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DatasetManifest {
    /// [`DATASET_FORMAT`].
    pub format: u32,
    /// Transitions.
    pub steps: usize,
    /// Episodes.
    pub episodes: u64,
    /// Reference frames ahead in the encoder's input.
    pub k: usize,
    /// Standard deviation of the action noise.
    pub noise_std: f32,
    /// Seed of the rollouts.
    pub seed: u64,
    /// Content hash of the body.
    pub body_hash: String,
    /// Control rate (Hz).
    pub control_hz: u32,
    /// Action width.
    pub act_dim: usize,
    /// The decoder's input: proprioception only.
    pub proprio: ObservationLayout,
    /// The encoder's input: the reference features.
    pub reference: Vec<LayoutEntry>,
    /// Values in `reference`.
    pub reference_size: usize,
    /// The skills that acted, in id order.
    pub skills: Vec<SourceSkill>,
    /// FNV-1a of the data file.
    pub data_fnv1a: u64,
    /// Size of the data file (bytes).
    pub data_bytes: u64,
    /// The command that made it.
    pub command: String,
    /// Git commit of the code that made it.
    pub git_hash: Option<String>,
}

/// A dataset in memory: per transition, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    /// The manifest.
    pub manifest: DatasetManifest,
    /// Proprioception `[N × S]`.
    pub proprio: Vec<f32>,
    /// Reference features `[N × F]`.
    pub reference: Vec<f32>,
    /// The expert's mean action `[N × A]`.
    pub mean_action: Vec<f32>,
    /// The action taken (mean plus noise) `[N × A]`.
    pub noisy_action: Vec<f32>,
    /// Imitation reward `[N]`.
    pub reward: Vec<f32>,
    /// Episode id `[N]` (unique over the dataset; an episode's steps are contiguous).
    pub episode: Vec<u32>,
    /// Skill id `[N]` (index into the manifest's skills).
    pub skill: Vec<u32>,
    /// Step within the episode `[N]`.
    pub step: Vec<u32>,
    /// Reference frame `[N]`.
    pub frame: Vec<u32>,
}

/// Settings of `latent collect`.
#[derive(Debug, Clone)]
pub struct CollectOptions {
    /// The skill library.
    pub library: PathBuf,
    /// The skills' specs (their environments; the library entry of the same name acts).
    pub specs: Vec<PathBuf>,
    /// Transitions per skill.
    pub steps_per_skill: u64,
    /// Reference frames ahead.
    pub k: usize,
    /// Action noise (MoCapAct: 0.1).
    pub noise_std: f32,
    /// Environments stepped together.
    pub batch: usize,
    /// Seed.
    pub seed: u64,
    /// Show a progress bar.
    pub progress: bool,
    /// The command line, recorded in the manifest.
    pub command: String,
}

/// A library skill acting with its mean action.
struct Expert(ActingPolicy);

impl Controller for Expert {
    fn begin(&mut self, _i: usize) {}
    fn act(&mut self, obs: &[f32], _proprio: &[f32], _reference: &[f32], actions: &mut [f32]) {
        self.0.act(obs, actions);
    }
}

/// The skill of `spec` built with reference-state initialisation, and its library entry,
/// checked to fit.
pub fn expert_setup(spec: &Path, library_dir: &Path) -> Result<(SkillSetup, Arc<TaskSettings>, ActingPolicy, u64)> {
    let mut spec = SpecFile::load(spec)?;
    spec.spec.init = Init::Reference;
    let setup = SkillSetup::new(spec, library_dir)?;
    let skill = library::load(library_dir, &setup.spec.spec.name)?;
    skill.check_fits(&setup.model)?;
    let mut settings: TaskSettings = (*setup.settings).clone();
    settings.init = Init::Reference;
    let fnv = skill.manifest.policy_fnv1a;
    Ok((setup, Arc::new(settings), skill.policy, fnv))
}

/// The decoder's layout for `setup`'s world: proprioception only.
pub fn proprio_layout(setup: &SkillSetup) -> Result<Arc<ObservationLayout>> {
    Ok(Arc::new(ObservationLayout::new(&setup.model, &Feature::proprioception())?))
}

/// Runs the experts with action noise and gathers their transitions (`latent collect`).
pub fn collect(opts: &CollectOptions) -> Result<Dataset> {
    if opts.specs.is_empty() || opts.k == 0 || opts.steps_per_skill == 0 {
        return Err(LatentError::Invalid("collect needs at least one skill, k ≥ 1 and steps ≥ 1".into()));
    }
    if !(opts.noise_std.is_finite() && opts.noise_std >= 0.0) {
        return Err(LatentError::Invalid(format!("noise std must be ≥ 0, got {}", opts.noise_std)));
    }
    let bar = if opts.progress {
        ProgressBar::new(opts.steps_per_skill * opts.specs.len() as u64)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template("{msg:>10} [{bar:30}] {pos}/{len} steps ({per_sec}, ETA {eta})")
            .expect("valid template")
            .progress_chars("=> "),
    );
    let mut data: Option<Dataset> = None;
    let mut episode_base = 0u64;
    for (id, spec_path) in opts.specs.iter().enumerate() {
        let (setup, settings, policy, policy_fnv1a) = expert_setup(spec_path, &opts.library)?;
        let name = setup.spec.spec.name.clone();
        bar.set_message(name.clone());
        let layout = proprio_layout(&setup)?;
        let dof = settings.reference.dof;
        let act_dim = setup.model.index.dof();
        let d = data.get_or_insert_with(|| Dataset {
            manifest: DatasetManifest {
                format: DATASET_FORMAT,
                steps: 0,
                episodes: 0,
                k: opts.k,
                noise_std: opts.noise_std,
                seed: opts.seed,
                body_hash: setup.model.body.content_hash(),
                control_hz: setup.model.scenario.scenario.rates.control_hz,
                act_dim,
                proprio: (*layout).clone(),
                reference: reference_layout(opts.k, dof),
                reference_size: reference_size(opts.k, dof),
                skills: Vec::new(),
                data_fnv1a: 0,
                data_bytes: 0,
                command: opts.command.clone(),
                git_hash: repertoire_learn::run_dir::git_hash(),
            },
            proprio: Vec::new(),
            reference: Vec::new(),
            mean_action: Vec::new(),
            noisy_action: Vec::new(),
            reward: Vec::new(),
            episode: Vec::new(),
            skill: Vec::new(),
            step: Vec::new(),
            frame: Vec::new(),
        });
        let m = &d.manifest;
        let here = setup.model.body.content_hash();
        if here != m.body_hash || act_dim != m.act_dim || reference_size(opts.k, dof) != m.reference_size {
            return Err(LatentError::Mismatch {
                path: spec_path.clone(),
                message: format!("skill `{name}` drives body {here}, the dataset's first skill body {}", m.body_hash),
            });
        }
        if setup.model.scenario.scenario.rates.control_hz != m.control_hz {
            return Err(LatentError::Mismatch {
                path: spec_path.clone(),
                message: format!(
                    "skill `{name}` runs at {} Hz, the dataset at {} Hz",
                    setup.model.scenario.scenario.rates.control_hz, m.control_hz
                ),
            });
        }
        layout
            .ensure_same(&m.proprio)
            .map_err(|e| LatentError::Mismatch { path: spec_path.clone(), message: e.to_string() })?;
        let mut expert = Expert(policy);
        let rollout_opts = RolloutOptions {
            k: opts.k,
            batch: opts.batch,
            seed: opts.seed.wrapping_add(id as u64 * 1_000_003),
            noise_std: opts.noise_std,
            budget: Budget::Steps(opts.steps_per_skill),
        };
        let (mut steps, mut episodes, mut falls) = (0u64, 0u64, 0u64);
        rollout(
            &setup,
            &settings,
            &layout,
            &mut expert,
            &rollout_opts,
            &mut |t| {
                d.proprio.extend_from_slice(t.proprio);
                d.reference.extend_from_slice(t.reference);
                d.mean_action.extend_from_slice(t.mean);
                d.noisy_action.extend_from_slice(t.taken);
                d.reward.push(t.reward);
                d.episode.push((episode_base + t.episode) as u32);
                d.skill.push(id as u32);
                d.step.push(t.step);
                d.frame.push(t.frame);
                steps += 1;
                episodes = episodes.max(t.episode + 1);
                bar.inc(1);
            },
            &mut |end| falls += u64::from(end.fell),
        );
        episode_base += episodes;
        tracing::info!(skill = %name, steps, episodes, falls, "collected");
        d.manifest.skills.push(SourceSkill {
            name,
            spec: spec_path.display().to_string(),
            policy_fnv1a,
            clip_hash: settings.reference.clip_hash.clone(),
            frames: settings.reference.frames(),
            steps,
            episodes,
            falls,
        });
    }
    bar.finish_and_clear();
    let mut d = data.expect("at least one skill");
    // Episodes interleave across environment slots; make each one's steps contiguous.
    d.sort_by_episode();
    d.manifest.steps = d.reward.len();
    d.manifest.episodes = episode_base;
    Ok(d)
}

fn bytes32(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn bytes_u32(v: &[u32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

impl Dataset {
    /// Transitions.
    pub fn len(&self) -> usize {
        self.reward.len()
    }

    /// Whether it holds no transition.
    pub fn is_empty(&self) -> bool {
        self.reward.is_empty()
    }

    /// Proprioception width.
    pub fn proprio_dim(&self) -> usize {
        self.manifest.proprio.size
    }

    /// Reference-feature width.
    pub fn reference_dim(&self) -> usize {
        self.manifest.reference_size
    }

    /// Action width.
    pub fn act_dim(&self) -> usize {
        self.manifest.act_dim
    }

    /// Reorders transitions so each episode's steps are contiguous and in step order.
    fn sort_by_episode(&mut self) {
        let mut order: Vec<usize> = (0..self.len()).collect();
        order.sort_by_key(|&i| (self.episode[i], self.step[i]));
        let (s, f, a) = (self.proprio_dim(), self.reference_dim(), self.act_dim());
        let rows = |v: &[f32], w: usize| -> Vec<f32> {
            order.iter().flat_map(|&i| v[i * w..(i + 1) * w].iter().copied()).collect()
        };
        let ids = |v: &[u32]| -> Vec<u32> { order.iter().map(|&i| v[i]).collect() };
        self.proprio = rows(&self.proprio, s);
        self.reference = rows(&self.reference, f);
        self.mean_action = rows(&self.mean_action, a);
        self.noisy_action = rows(&self.noisy_action, a);
        self.reward = rows(&self.reward, 1);
        self.episode = ids(&self.episode);
        self.skill = ids(&self.skill);
        self.step = ids(&self.step);
        self.frame = ids(&self.frame);
    }

    /// Writes `dir/dataset.safetensors` and then `dir/dataset.ron` (which vouches for it), each
    /// atomically; returns the data file's size.
    pub fn save(&mut self, dir: &Path) -> Result<u64> {
        std::fs::create_dir_all(dir).map_err(|e| LatentError::io(dir, "cannot create the dataset folder", e))?;
        let n = self.len();
        let (s, f, a) = (self.proprio_dim(), self.reference_dim(), self.act_dim());
        let entries: Vec<(&str, Dtype, Vec<usize>, Vec<u8>)> = vec![
            ("proprio", Dtype::F32, vec![n, s], bytes32(&self.proprio)),
            ("reference", Dtype::F32, vec![n, f], bytes32(&self.reference)),
            ("mean_action", Dtype::F32, vec![n, a], bytes32(&self.mean_action)),
            ("noisy_action", Dtype::F32, vec![n, a], bytes32(&self.noisy_action)),
            ("reward", Dtype::F32, vec![n], bytes32(&self.reward)),
            ("episode", Dtype::U32, vec![n], bytes_u32(&self.episode)),
            ("skill", Dtype::U32, vec![n], bytes_u32(&self.skill)),
            ("step", Dtype::U32, vec![n], bytes_u32(&self.step)),
            ("frame", Dtype::U32, vec![n], bytes_u32(&self.frame)),
        ];
        let path = dir.join(DATA_FILE);
        let views: Vec<(String, TensorView<'_>)> = entries
            .iter()
            .map(|(name, dt, shape, data)| {
                (name.to_string(), TensorView::new(*dt, shape.clone(), data).expect("sizes match the shapes"))
            })
            .collect();
        let meta = HashMap::from([("format".to_string(), format!("repertoire-latent-dataset-{DATASET_FORMAT}"))]);
        let bytes = safetensors::serialize(views, Some(meta))
            .map_err(|e| LatentError::corrupt(&path, format!("cannot serialise: {e}")))?;
        write_atomic(&path, &bytes)?;
        self.manifest.steps = n;
        self.manifest.data_fnv1a = fnv1a(&bytes);
        self.manifest.data_bytes = bytes.len() as u64;
        let text = ron::ser::to_string_pretty(&self.manifest, ron::ser::PrettyConfig::new().depth_limit(3))
            .map_err(|e| LatentError::Invalid(format!("cannot serialise the dataset manifest: {e}")))?;
        write_atomic(&dir.join(MANIFEST_FILE), text.as_bytes())?;
        Ok(bytes.len() as u64)
    }

    /// Reads the manifest of the dataset in folder `path` (or at `path` itself when it names a
    /// `.ron` file).
    pub fn read_manifest(path: &Path) -> Result<(PathBuf, DatasetManifest)> {
        let is_ron = path.extension().is_some_and(|e| e == "ron");
        let manifest_path = if path.is_dir() || !is_ron { path.join(MANIFEST_FILE) } else { path.to_path_buf() };
        let text = std::fs::read_to_string(&manifest_path)
            .map_err(|e| LatentError::io(&manifest_path, "cannot read the dataset manifest", e))?;
        let manifest: DatasetManifest = ron::from_str(&text).map_err(|e| LatentError::ron(&manifest_path, e))?;
        if manifest.format != DATASET_FORMAT {
            return Err(LatentError::Mismatch {
                path: manifest_path,
                message: format!("dataset format {} (this build reads {DATASET_FORMAT})", manifest.format),
            });
        }
        if let Some(f) = manifest.proprio.features.iter().find(|f| matches!(f, Feature::PropPose(_))) {
            return Err(LatentError::Mismatch {
                path: manifest_path,
                message: format!("the proprioceptive layout holds the prop feature {}", f.name()),
            });
        }
        Ok((manifest_path, manifest))
    }

    /// Loads the dataset in `dir` (or at a `dataset.ron` path), checking the data file against
    /// the manifest's checksum and shapes.
    pub fn load(path: &Path) -> Result<Self> {
        let (manifest_path, manifest) = Self::read_manifest(path)?;
        let dir = manifest_path.parent().unwrap_or(Path::new("."));
        let data_path = dir.join(DATA_FILE);
        let bytes = std::fs::read(&data_path).map_err(|e| LatentError::io(&data_path, "cannot read the dataset", e))?;
        if fnv1a(&bytes) != manifest.data_fnv1a {
            return Err(LatentError::corrupt(
                &data_path,
                "the data file does not match its manifest's checksum (modified or truncated)",
            ));
        }
        let st = SafeTensors::deserialize(&bytes).map_err(|e| LatentError::corrupt(&data_path, e.to_string()))?;
        let n = manifest.steps;
        let (s, f, a) = (manifest.proprio.size, manifest.reference_size, manifest.act_dim);
        let get = |name: &str, dtype: Dtype, shape: &[usize]| -> Result<&[u8]> {
            let t = st.tensor(name).map_err(|_| LatentError::corrupt(&data_path, format!("no tensor `{name}`")))?;
            if t.dtype() != dtype || t.shape() != shape {
                return Err(LatentError::corrupt(
                    &data_path,
                    format!(
                        "tensor `{name}` is {:?} {:?}, the manifest says {dtype:?} {shape:?}",
                        t.dtype(),
                        t.shape()
                    ),
                ));
            }
            Ok(t.data())
        };
        let f32s = |name: &str, shape: &[usize]| -> Result<Vec<f32>> {
            let v: Vec<f32> = get(name, Dtype::F32, shape)?
                .chunks_exact(4)
                .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .collect();
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return Err(LatentError::corrupt(
                    &data_path,
                    format!("tensor `{name}` holds a non-finite value at {i}"),
                ));
            }
            Ok(v)
        };
        let u32s = |name: &str| -> Result<Vec<u32>> {
            Ok(get(name, Dtype::U32, &[n])?
                .chunks_exact(4)
                .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .collect())
        };
        let d = Dataset {
            proprio: f32s("proprio", &[n, s])?,
            reference: f32s("reference", &[n, f])?,
            mean_action: f32s("mean_action", &[n, a])?,
            noisy_action: f32s("noisy_action", &[n, a])?,
            reward: f32s("reward", &[n])?,
            episode: u32s("episode")?,
            skill: u32s("skill")?,
            step: u32s("step")?,
            frame: u32s("frame")?,
            manifest,
        };
        if let Some(i) = d.skill.iter().position(|&k| k as usize >= d.manifest.skills.len()) {
            return Err(LatentError::corrupt(
                &data_path,
                format!("transition {i} names skill {} of {}", d.skill[i], d.manifest.skills.len()),
            ));
        }
        if let Some(i) = (1..n).find(|&i| d.episode[i] < d.episode[i - 1]) {
            return Err(LatentError::corrupt(&data_path, format!("episodes are not contiguous at transition {i}")));
        }
        Ok(d)
    }
}
