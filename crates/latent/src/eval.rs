//! `latent eval`: one-shot imitation (MoCapAct Table 2). Each skill's clip is tracked from the
//! same random reference frames by the expert skill (its mean action) and by the latent model
//! (encoder on the coming reference frames → `z` → proprioceptive decoder); normalised episode
//! length and imitation return are reported side by side, as Markdown and CSV.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::{Deserialize, Serialize};

use repertoire_scenes::ObservationLayout;
use repertoire_skill::imitation::TaskSettings;
use repertoire_skill::spec::{ClipRef, Init};
use repertoire_skill::{SkillSetup, SpecFile};

use crate::dataset::{expert_setup, proprio_layout};
use crate::error::Result;
use crate::model::LatentPolicy;
use crate::rollout::{Budget, Controller, EpisodeEnd, RolloutOptions, best_imitation_reward, rollout};

/// The figures of one controller on one skill's clip.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Tracking {
    /// Mean normalised episode length.
    pub normalized_length: f64,
    /// Mean normalised imitation return.
    pub normalized_return: f64,
    /// Share of episodes that ended in a fall.
    pub fall_rate: f64,
}

/// One row of the one-shot table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OneShotRow {
    /// The skill (its clip).
    pub skill: String,
    /// Episodes per controller.
    pub episodes: usize,
    /// The expert skill.
    pub expert: Tracking,
    /// The latent model.
    pub latent: Tracking,
    /// Whether the clip's skill was left out of the latent model's dataset (a held-out clip).
    #[serde(default)]
    pub held_out: bool,
}

impl OneShotRow {
    /// Latent over expert normalised return.
    pub fn relative_return(&self) -> f64 {
        self.latent.normalized_return / self.expert.normalized_return.max(1e-9)
    }

    /// Latent over expert normalised length.
    pub fn relative_length(&self) -> f64 {
        self.latent.normalized_length / self.expert.normalized_length.max(1e-9)
    }
}

fn summarize(ends: &BTreeMap<u64, EpisodeEnd>, best: f64) -> Tracking {
    let n = ends.len().max(1) as f64;
    Tracking {
        normalized_length: ends.values().map(EpisodeEnd::normalized_length).sum::<f64>() / n,
        normalized_return: ends.values().map(|e| e.normalized_return(best)).sum::<f64>() / n,
        fall_rate: ends.values().filter(|e| e.fell).count() as f64 / n,
    }
}

/// The random reference frames (seeded) a clip is tracked from, the same for every controller.
#[derive(Debug, Clone, Copy)]
struct Starts {
    episodes: usize,
    batch: usize,
    seed: u64,
}

impl Starts {
    /// `ctrl` tracking `setup`'s clip (reading `k` reference frames ahead): the episodes run and
    /// their figures.
    fn track(
        self,
        setup: &SkillSetup,
        settings: &Arc<TaskSettings>,
        layout: &Arc<ObservationLayout>,
        ctrl: &mut dyn Controller,
        k: usize,
    ) -> (usize, Tracking) {
        let opts = RolloutOptions {
            k,
            batch: self.batch,
            seed: self.seed,
            noise_std: 0.0,
            budget: Budget::Episodes(self.episodes),
        };
        let mut ends = BTreeMap::new();
        rollout(setup, settings, layout, ctrl, &opts, &mut |_| {}, &mut |e| {
            ends.insert(e.episode, *e);
        });
        (ends.len(), summarize(&ends, best_imitation_reward(&settings.imitation)))
    }
}

struct Expert(repertoire_learn::acting::ActingPolicy);

impl Controller for Expert {
    fn begin(&mut self, _i: usize) {}
    fn act(&mut self, obs: &[f32], _p: &[f32], _r: &[f32], actions: &mut [f32]) {
        self.0.act(obs, actions);
    }
}

/// Tracks each skill's clip (`specs`, library entries in `library`) from `episodes` random
/// reference frames with the expert and with `policy` (loaded from `model_path`).
pub fn one_shot(
    policy: &mut LatentPolicy,
    model_path: &Path,
    library: &Path,
    specs: &[PathBuf],
    episodes: usize,
    batch: usize,
    seed: u64,
) -> Result<Vec<OneShotRow>> {
    let models = std::slice::from_mut(policy);
    let mut rows = one_shot_many(models, &[model_path.to_path_buf()], library, specs, episodes, batch, seed)?;
    Ok(rows.remove(0))
}

/// [`one_shot`] for several latent models on the same starts: the expert runs once per clip.
/// One row list per model, in the order given.
pub fn one_shot_many(
    policies: &mut [LatentPolicy],
    model_paths: &[PathBuf],
    library: &Path,
    specs: &[PathBuf],
    episodes: usize,
    batch: usize,
    seed: u64,
) -> Result<Vec<Vec<OneShotRow>>> {
    let mut rows = vec![Vec::new(); policies.len()];
    for spec in specs {
        let (setup, settings, expert_policy, _) = expert_setup(spec, library)?;
        for (policy, path) in policies.iter().zip(model_paths) {
            policy.check_fits(&setup.model, path)?;
        }
        let layout = proprio_layout(&setup)?;
        let starts = Starts { episodes, batch, seed };
        // The expert reads no reference features: k only shapes the rollout's bookkeeping.
        let k = policies.first().map_or(1, |p| p.manifest.k);
        let (_, expert) = starts.track(&setup, &settings, &layout, &mut Expert(expert_policy), k);
        let name = setup.spec.spec.name.clone();
        for (policy, out) in policies.iter_mut().zip(&mut rows) {
            let held_out = !policy.manifest.dataset.skills.contains(&name);
            let k = policy.manifest.k;
            let (episodes, latent) = starts.track(&setup, &settings, &layout, policy, k);
            tracing::info!(skill = %name, episodes, held_out, "one-shot imitation");
            out.push(OneShotRow { skill: name.clone(), episodes, expert, latent, held_out });
        }
    }
    Ok(rows)
}

/// A clip tracked by a latent model alone: no expert was trained on it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClipRow {
    /// The clip (its file name).
    pub clip: String,
    /// Episodes.
    pub episodes: usize,
    /// The latent model.
    pub latent: Tracking,
}

/// Tracks each of `clips` (any clip file a skill spec takes: BVH, ASF/AMC, DeepMimic, keyframes,
/// joint positions; retargeted by the best-fitting shipped map) through each latent model from
/// `episodes` random reference frames, in the environment of the skill spec `template` (its body,
/// rates and imitation terms; its clip replaced, neither looped nor mirrored nor cut). No expert
/// exists for such a clip, so the figures are the latent model's own normalised length and return
/// (MoCapAct's measures before the division by the expert's). One row list per model.
#[allow(clippy::too_many_arguments)]
pub fn track_clips(
    policies: &mut [LatentPolicy],
    model_paths: &[PathBuf],
    template: &Path,
    library: &Path,
    clips: &[PathBuf],
    episodes: usize,
    batch: usize,
    seed: u64,
) -> Result<Vec<Vec<ClipRow>>> {
    let mut rows = vec![Vec::new(); policies.len()];
    for clip in clips {
        let mut spec = SpecFile::load(template)?;
        let file = std::path::absolute(clip).unwrap_or_else(|_| clip.clone());
        spec.spec.clip = ClipRef {
            file: file.display().to_string(),
            map: None,
            cut_s: None,
            mirror: false,
            looping: false,
            hold_s: 0.0,
            lead_s: 0.0,
            seat_lift_m: 0.0,
            pose_deg: BTreeMap::new(),
        };
        spec.spec.init = Init::Reference;
        let name = clip.file_name().map_or_else(|| clip.display().to_string(), |n| n.to_string_lossy().into_owned());
        spec.spec.name = name.clone();
        let setup = SkillSetup::new(spec, library)?;
        let mut settings: TaskSettings = (*setup.settings).clone();
        settings.init = Init::Reference;
        let settings = Arc::new(settings);
        let layout = proprio_layout(&setup)?;
        let starts = Starts { episodes, batch, seed };
        for ((policy, path), out) in policies.iter_mut().zip(model_paths).zip(&mut rows) {
            policy.check_fits(&setup.model, path)?;
            let k = policy.manifest.k;
            let (episodes, latent) = starts.track(&setup, &settings, &layout, policy, k);
            tracing::info!(clip = %name, episodes, "clip tracked through the latent model");
            out.push(ClipRow { clip: name.clone(), episodes, latent });
        }
    }
    Ok(rows)
}

/// The clips tracked without an expert, one row per model and clip.
pub fn clips_markdown(models: &[(String, Vec<ClipRow>)]) -> String {
    let mut s = String::from(
        "| model | clip (no expert) | episodes | latent length | latent return | latent falls |\n|---|---|---:|---:|---:|---:|\n",
    );
    for (label, rows) in models {
        for r in rows {
            s.push_str(&format!(
                "| {label} | {} | {} | {:.3} | {:.3} | {:.1} % |\n",
                r.clip,
                r.episodes,
                r.latent.normalized_length,
                r.latent.normalized_return,
                100.0 * r.latent.fall_rate
            ));
        }
    }
    s
}

/// Means over `rows` of the expert's and the latent model's figures and of their ratio.
fn means(rows: &[&OneShotRow]) -> [f64; 6] {
    let n = rows.len().max(1) as f64;
    let mean = |f: &dyn Fn(&OneShotRow) -> f64| rows.iter().map(|r| f(r)).sum::<f64>() / n;
    [
        mean(&|r| r.expert.normalized_length),
        mean(&|r| r.expert.normalized_return),
        mean(&|r| r.latent.normalized_length),
        mean(&|r| r.latent.normalized_return),
        mean(&|r| r.relative_return()),
        mean(&|r| r.latent.fall_rate),
    ]
}

/// The rows' clips split into the ones the model was trained on and the held-out ones.
fn split(rows: &[OneShotRow]) -> (Vec<&OneShotRow>, Vec<&OneShotRow>) {
    rows.iter().partition(|r| !r.held_out)
}

/// A comparison of several models over the same clips and starts: per clip the latent model's
/// return as a share of the expert's, then the means over trained and held-out clips and the
/// latent falls. `models` are (label, weighting, updates, rows).
pub fn comparison_markdown(models: &[(String, String, usize, Vec<OneShotRow>)]) -> String {
    let Some((_, _, _, first)) = models.first() else { return String::new() };
    let clip = |r: &OneShotRow| if r.held_out { format!("{} (held out)", r.skill) } else { r.skill.clone() };
    let mut s = String::from("| model | weighting | updates |");
    let mut rule = String::from("|---|---|---:|");
    for r in first {
        s.push_str(&format!(" {} |", clip(r)));
        rule.push_str("---:|");
    }
    let any_held_out = first.iter().any(|r| r.held_out);
    s.push_str(" mean, trained clips |");
    rule.push_str("---:|");
    if any_held_out {
        s.push_str(" mean, held-out clips |");
        rule.push_str("---:|");
    }
    s.push_str(" latent falls |\n");
    rule.push_str("---:|\n");
    s.push_str(&rule);
    for (label, weighting, updates, rows) in models {
        s.push_str(&format!("| {label} | {weighting} | {updates} |"));
        for r in rows {
            s.push_str(&format!(" {:.1} % |", 100.0 * r.relative_return()));
        }
        let (trained, held) = split(rows);
        s.push_str(&format!(" {:.1} % |", 100.0 * means(&trained)[4]));
        if any_held_out {
            s.push_str(&format!(" {:.1} % |", 100.0 * means(&held)[4]));
        }
        let all: Vec<&OneShotRow> = rows.iter().collect();
        s.push_str(&format!(" {:.1} % |\n", 100.0 * means(&all)[5]));
    }
    s
}

/// The table as Markdown, with a mean row.
pub fn markdown(rows: &[OneShotRow]) -> String {
    let mut s = String::from(
        "| clip | episodes | expert length | expert return | latent length | latent return | latent / expert return | latent falls |\n|---|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        s.push_str(&format!(
            "| {}{} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.1} % | {:.1} % |\n",
            r.skill,
            if r.held_out { " (held out)" } else { "" },
            r.episodes,
            r.expert.normalized_length,
            r.expert.normalized_return,
            r.latent.normalized_length,
            r.latent.normalized_return,
            100.0 * r.relative_return(),
            100.0 * r.latent.fall_rate
        ));
    }
    let (trained, held) = split(rows);
    let mut mean_row = |label: &str, rows: &[&OneShotRow]| {
        if rows.is_empty() {
            return;
        }
        let [el, er, ll, lr, rel, falls] = means(rows);
        s.push_str(&format!(
            "| {label} | | {el:.3} | {er:.3} | {ll:.3} | {lr:.3} | {:.1} % | {:.1} % |\n",
            100.0 * rel,
            100.0 * falls
        ));
    };
    if held.is_empty() {
        mean_row("mean", &trained);
    } else {
        mean_row("mean, trained clips", &trained);
        mean_row("mean, held-out clips", &held);
    }
    s
}

/// The table as CSV.
pub fn csv(rows: &[OneShotRow]) -> String {
    let mut s = String::from(
        "clip,episodes,expert_length,expert_return,expert_falls,latent_length,latent_return,latent_falls,relative_return,relative_length,held_out\n",
    );
    for r in rows {
        s.push_str(&format!(
            "{},{},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{}\n",
            r.skill,
            r.episodes,
            r.expert.normalized_length,
            r.expert.normalized_return,
            r.expert.fall_rate,
            r.latent.normalized_length,
            r.latent.normalized_return,
            r.latent.fall_rate,
            r.relative_return(),
            r.relative_length(),
            r.held_out
        ));
    }
    s
}
