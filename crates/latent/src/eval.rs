//! `latent eval`: one-shot imitation (MoCapAct Table 2). Each skill's clip is tracked from the
//! same random reference frames by the expert skill (its mean action) and by the latent model
//! (encoder on the coming reference frames → `z` → proprioceptive decoder); normalised episode
//! length and imitation return are reported side by side, as Markdown and CSV.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

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
    let mut rows = Vec::new();
    for spec in specs {
        let (setup, settings, expert_policy, _) = expert_setup(spec, library)?;
        policy.check_fits(&setup.model, model_path)?;
        let layout = proprio_layout(&setup)?;
        let opts =
            RolloutOptions { k: policy.manifest.k, batch, seed, noise_std: 0.0, budget: Budget::Episodes(episodes) };
        let best = best_imitation_reward(&settings.imitation);
        let run = |ctrl: &mut dyn Controller| {
            let mut ends = BTreeMap::new();
            rollout(&setup, &settings, &layout, ctrl, &opts, &mut |_| {}, &mut |e| {
                ends.insert(e.episode, *e);
            });
            ends
        };
        let expert = run(&mut Expert(expert_policy));
        let latent = run(policy);
        let name = setup.spec.spec.name.clone();
        tracing::info!(skill = %name, episodes = expert.len(), "one-shot imitation");
        rows.push(OneShotRow {
            skill: name,
            episodes: expert.len(),
            expert: summarize(&expert, best),
            latent: summarize(&latent, best),
        });
    }
    Ok(rows)
}

/// The table as Markdown, with a mean row.
pub fn markdown(rows: &[OneShotRow]) -> String {
    let mut s = String::from(
        "| clip | episodes | expert length | expert return | latent length | latent return | latent / expert return | latent falls |\n|---|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        s.push_str(&format!(
            "| {} | {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.1} % | {:.1} % |\n",
            r.skill,
            r.episodes,
            r.expert.normalized_length,
            r.expert.normalized_return,
            r.latent.normalized_length,
            r.latent.normalized_return,
            100.0 * r.relative_return(),
            100.0 * r.latent.fall_rate
        ));
    }
    if !rows.is_empty() {
        let n = rows.len() as f64;
        let mean = |f: &dyn Fn(&OneShotRow) -> f64| rows.iter().map(f).sum::<f64>() / n;
        s.push_str(&format!(
            "| mean | | {:.3} | {:.3} | {:.3} | {:.3} | {:.1} % | {:.1} % |\n",
            mean(&|r| r.expert.normalized_length),
            mean(&|r| r.expert.normalized_return),
            mean(&|r| r.latent.normalized_length),
            mean(&|r| r.latent.normalized_return),
            100.0 * mean(&|r| r.relative_return()),
            100.0 * mean(&|r| r.latent.fall_rate)
        ));
    }
    s
}

/// The table as CSV.
pub fn csv(rows: &[OneShotRow]) -> String {
    let mut s = String::from(
        "clip,episodes,expert_length,expert_return,expert_falls,latent_length,latent_return,latent_falls,relative_return,relative_length\n",
    );
    for r in rows {
        s.push_str(&format!(
            "{},{},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4}\n",
            r.skill,
            r.episodes,
            r.expert.normalized_length,
            r.expert.normalized_return,
            r.expert.fall_rate,
            r.latent.normalized_length,
            r.latent.normalized_return,
            r.latent.fall_rate,
            r.relative_return(),
            r.relative_length()
        ));
    }
    s
}
