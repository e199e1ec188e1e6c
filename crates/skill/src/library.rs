//! The skill library: a folder per skill holding `manifest.ron` (what the skill was trained on
//! and how) beside `policy.safetensors` (the acting policy) and, once evaluated,
//! `end_poses.ron` (its successful end states, for transition fine-tuning) and `value.safetensors`
//! (the critic it was trained with, which the skill's next training stage continues). Loading a skill
//! into a world whose body, observation layout or rates differ is an error naming the difference.

use std::path::{Path, PathBuf};

use repertoire_learn::acting::{ActingCritic, ActingPolicy};
use repertoire_learn::checkpoint::fnv1a;
use repertoire_scenes::{ObservationLayout, WorldModel};
use serde::{Deserialize, Serialize};

use crate::error::{Result, SkillError};
use crate::spec::SkillSpec;

/// Format of the manifests this build writes and reads.
pub const LIBRARY_FORMAT: u32 = 1;

/// Training figures recorded with a skill.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TrainingFigures {
    /// PPO iterations.
    pub iterations: usize,
    /// Environment steps.
    pub samples: u64,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Mean episode return over the last iterations.
    pub mean_return: f32,
    /// Mean episode length (control steps) over the last iterations.
    pub mean_length: f32,
    /// Share of episodes ended by a fall over the last iterations.
    pub termination_rate: f32,
}

/// The clip a skill imitates.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClipRecord {
    /// Its name.
    pub name: String,
    /// Its content hash (of the retargeted clip, before resampling).
    pub hash: String,
    /// Where it came from.
    pub origin: String,
    /// Frames at the control rate.
    pub frames: usize,
    /// For a cycle (walk): its joint angles and velocities per control frame (`frames × dof`
    /// each), so a meta-controller can pick it up at the frame nearest the character's pose
    /// ([`crate::reference::nearest_pose`]). Empty for other clips and older manifests.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub cycle_joints: Vec<f32>,
    /// See `cycle_joints`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub cycle_joint_vel: Vec<f32>,
}

/// One earlier training stage of a skill (its stage one, or a fine-tune before the last): what
/// ran, on which code, and the policy it left, so a manifest tells the whole way its weights
/// were made and not only the last command.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Stage {
    /// The command.
    pub command: String,
    /// Git commit of the code that ran it.
    pub git_hash: Option<String>,
    /// Its training figures.
    pub training: TrainingFigures,
    /// FNV-1a of the policy it wrote.
    pub policy_fnv1a: u64,
}

/// `manifest.ron` of one skill.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SkillManifest {
    /// [`LIBRARY_FORMAT`].
    pub format: u32,
    /// The skill's name.
    pub name: String,
    /// Content hash of the body it drives.
    pub body_hash: String,
    /// Where that body came from.
    pub body_origin: String,
    /// The observation layout (then `extra_obs` task values).
    pub observation: ObservationLayout,
    /// Task values after the layout (phase, goal).
    pub extra_obs: usize,
    /// Action width.
    pub act_dim: usize,
    /// Control and physics rates (Hz).
    pub control_hz: u32,
    /// Physics rate (Hz).
    pub physics_hz: u32,
    /// MuJoCo's version string at training.
    pub mujoco: String,
    /// The clip.
    pub clip: ClipRecord,
    /// The spec it was trained from.
    pub spec: SkillSpec,
    /// Training figures.
    pub training: TrainingFigures,
    /// The command that trained it.
    pub command: String,
    /// Git commit of the code that trained it.
    pub git_hash: Option<String>,
    /// FNV-1a of `policy.safetensors` (checked on load).
    pub policy_fnv1a: u64,
    /// FNV-1a of `value.safetensors`, the critic trained with the policy (checked when a next
    /// stage loads it); `None` for skills saved before critics were kept.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub value_fnv1a: Option<u64>,
    /// The stages before this one, oldest first (a fine-tune appends the skill it started
    /// from); empty for a skill trained from scratch and for manifests older than the record.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub lineage: Vec<Stage>,
}

impl SkillManifest {
    /// This manifest's own stage (its last command), for the lineage of a fine-tune of it.
    pub fn stage(&self) -> Stage {
        Stage {
            command: self.command.clone(),
            git_hash: self.git_hash.clone(),
            training: self.training.clone(),
            policy_fnv1a: self.policy_fnv1a,
        }
    }
}

/// A loaded skill: its manifest and acting policy.
#[derive(Debug, Clone)]
pub struct LibrarySkill {
    /// Its folder.
    pub dir: PathBuf,
    /// The manifest.
    pub manifest: SkillManifest,
    /// The policy.
    pub policy: ActingPolicy,
}

/// Writes `bytes` to `path` through a temporary sibling and a rename ([`repertoire_files`]).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    repertoire_files::write_atomic(path, bytes).map_err(|e| SkillError::io(&e.path, e.action, e.source))
}

/// The critic's file in a skill folder.
pub const VALUE_FILE: &str = "value.safetensors";

/// The folder of skill `name` in `library`.
pub fn skill_dir(library: &Path, name: &str) -> PathBuf {
    library.join(name)
}

/// Saves a skill: the policy and its critic first, then the manifest that vouches for both.
pub fn save(
    library: &Path,
    manifest: &mut SkillManifest,
    policy: &ActingPolicy,
    critic: &ActingCritic,
) -> Result<PathBuf> {
    let dir = skill_dir(library, &manifest.name);
    std::fs::create_dir_all(&dir).map_err(|e| SkillError::io(&dir, "cannot create the skill folder", e))?;
    let checksum = |path: &Path| -> Result<u64> {
        let bytes = std::fs::read(path).map_err(|e| SkillError::io(path, "cannot read back", e))?;
        Ok(fnv1a(&bytes))
    };
    let policy_path = dir.join("policy.safetensors");
    policy.save(&policy_path)?;
    manifest.policy_fnv1a = checksum(&policy_path)?;
    let value_path = dir.join(VALUE_FILE);
    critic.save(&value_path)?;
    manifest.value_fnv1a = Some(checksum(&value_path)?);
    let text = ron::ser::to_string_pretty(manifest, ron::ser::PrettyConfig::new().depth_limit(3))
        .map_err(|e| SkillError::Invalid(format!("cannot serialise the manifest of `{}`: {e}", manifest.name)))?;
    write_atomic(&dir.join("manifest.ron"), text.as_bytes())?;
    Ok(dir)
}

/// Loads skill `name` from `library`, checking the policy file against the manifest.
pub fn load(library: &Path, name: &str) -> Result<LibrarySkill> {
    let dir = skill_dir(library, name);
    let path = dir.join("manifest.ron");
    let text =
        std::fs::read_to_string(&path).map_err(|e| SkillError::io(&path, "cannot read the skill manifest", e))?;
    let manifest: SkillManifest = ron::from_str(&text).map_err(|e| SkillError::ron(&path, e))?;
    if manifest.format != LIBRARY_FORMAT {
        return Err(SkillError::Mismatch {
            path,
            message: format!("library format {} (this build reads {LIBRARY_FORMAT})", manifest.format),
        });
    }
    let policy_path = dir.join("policy.safetensors");
    let bytes = std::fs::read(&policy_path).map_err(|e| SkillError::io(&policy_path, "cannot read the policy", e))?;
    if fnv1a(&bytes) != manifest.policy_fnv1a {
        return Err(SkillError::Mismatch {
            path: policy_path,
            message: "the policy file does not match its manifest's checksum (modified or truncated)".into(),
        });
    }
    let policy = ActingPolicy::load(&policy_path)?;
    if policy.obs_dim() != manifest.observation.size + manifest.extra_obs || policy.act_dim() != manifest.act_dim {
        return Err(SkillError::Mismatch {
            path,
            message: format!(
                "the policy maps {} → {} values, the manifest says {} → {}",
                policy.obs_dim(),
                policy.act_dim(),
                manifest.observation.size + manifest.extra_obs,
                manifest.act_dim
            ),
        });
    }
    Ok(LibrarySkill { dir, manifest, policy })
}

impl LibrarySkill {
    /// The critic saved with this skill's policy, checked against the manifest; `None` for a
    /// skill saved before critics were kept.
    pub fn load_critic(&self) -> Result<Option<ActingCritic>> {
        let Some(expected) = self.manifest.value_fnv1a else { return Ok(None) };
        let path = self.dir.join(VALUE_FILE);
        let bytes = std::fs::read(&path).map_err(|e| SkillError::io(&path, "cannot read the critic", e))?;
        if fnv1a(&bytes) != expected {
            return Err(SkillError::Mismatch {
                path,
                message: "the critic file does not match its manifest's checksum (modified or truncated)".into(),
            });
        }
        let critic = ActingCritic::parse(&path, &bytes)?;
        if critic.obs_dim() != self.policy.obs_dim() {
            return Err(SkillError::Mismatch {
                path,
                message: format!(
                    "the critic reads {} values, the policy beside it {}",
                    critic.obs_dim(),
                    self.policy.obs_dim()
                ),
            });
        }
        Ok(Some(critic))
    }

    /// Checks that this skill can drive the character of `model`: same body, same rates, and
    /// the observation layout it was trained on.
    pub fn check_fits(&self, model: &WorldModel) -> Result<()> {
        self.check_body_and_rates(model)?;
        let here = ObservationLayout::new(model, &self.manifest.observation.features)?;
        self.check_layout(&here)
    }

    /// Like [`LibrarySkill::check_fits`], with the observation laid out by the caller (its
    /// props bound to props of `model` with other names, see `Scenario::bind`).
    pub fn check_fits_layout(&self, model: &WorldModel, here: &ObservationLayout) -> Result<()> {
        self.check_body_and_rates(model)?;
        self.check_layout(here)
    }

    fn check_layout(&self, here: &ObservationLayout) -> Result<()> {
        let m = &self.manifest;
        here.ensure_same(&m.observation).map_err(|e| SkillError::Mismatch {
            path: self.dir.join("manifest.ron"),
            message: format!("skill `{}`: {e}", m.name),
        })
    }

    fn check_body_and_rates(&self, model: &WorldModel) -> Result<()> {
        let m = &self.manifest;
        let path = self.dir.join("manifest.ron");
        let mismatch = |message: String| Err(SkillError::Mismatch { path: path.clone(), message });
        let hash = model.body.content_hash();
        if hash != m.body_hash {
            return mismatch(format!(
                "skill `{}` was trained on body {} (hash {}), this scene's body is {} (hash {hash})",
                m.name,
                m.body_origin,
                m.body_hash,
                model.body.mjcf_path.display()
            ));
        }
        let rates = &model.scenario.scenario.rates;
        if rates.control_hz != m.control_hz || rates.physics_hz != m.physics_hz {
            return mismatch(format!(
                "skill `{}` runs at control {} Hz / physics {} Hz, this scene at {} / {}",
                m.name, m.control_hz, m.physics_hz, rates.control_hz, rates.physics_hz
            ));
        }
        Ok(())
    }
}
