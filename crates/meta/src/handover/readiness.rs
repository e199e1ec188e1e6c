//! Readiness: a learned answer to "would the terminal skill (sit) succeed if it started now?",
//! read from the meta-controller's own observation, and a controller that sits only when the
//! answer is yes.
//!
//! A terminal skill (one the graph leaves no way out of) decides the episode the moment it is
//! chosen. The planner ([`crate::search::planner`]) knows whether it will succeed because it plays it
//! out in a copy of the episode; a controller trained by PPO has to learn it from the rare
//! decisions on which it happened to sit. Here it is learned directly: the controller plays
//! seeded episodes without its terminal skills, and every decision at which one could have been
//! chosen is labelled with whether it would have succeeded (played out in a copy of the
//! episode), and a classifier ([`repertoire_learn::classify`]) is fitted to the labels. The result is a
//! folder (`readiness.ron` + `readiness.safetensors`) beside the controller; the gated
//! controller ([`crate::controller::Gated`]) then sits when the classifier says it is at
//! least `threshold` likely to succeed, and chooses among the other skills otherwise — the
//! options framework's initiation set, learned from counterfactual rollouts.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use rayon::prelude::*;
use repertoire_learn::acting::ActingHybrid;
use repertoire_learn::classify::{Classifier, ClassifierConfig, Separation, fit, separation};
use repertoire_learn::env::Env;
use serde::{Deserialize, Serialize};

use crate::env::terminal_skills;
use crate::env::trial_rng;
use crate::env::{MetaEnv, MetaSetup};
use crate::error::{MetaError, Result};
use crate::search::planner::{Planner, PlannerConfig, write_action};
use crate::train::check_skill_weights;
use repertoire_learn::run_dir::git_hash;

/// Whether `mask` offers a choice between a terminal skill and another: a terminal skill is
/// allowed, and so is some other (not the case once one is playing).
pub(crate) fn terminal_choice(mask: &[bool], terminal: &[bool]) -> bool {
    let allowed = |want: bool| mask.iter().zip(terminal).any(|(&m, &t)| m && t == want);
    allowed(true) && allowed(false)
}

/// Restricts `mask` to the terminal skills when `ready` and one is allowed, else to the
/// others when one is allowed (a mask with nothing else is left as it is: a terminal skill
/// already playing continues).
pub(crate) fn gate(mask: &mut [bool], terminal: &[bool], ready: bool) {
    let allowed = |want: bool| mask.iter().zip(terminal).any(|(&m, &t)| m && t == want);
    let keep_terminal = if ready && allowed(true) {
        true
    } else if allowed(false) {
        false
    } else {
        return;
    };
    for (m, &t) in mask.iter_mut().zip(terminal) {
        *m &= t == keep_terminal;
    }
}

/// How a readiness probability gates the controller's choice of a terminal skill.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gate {
    /// At or above this probability a terminal skill is taken (the controller picks which).
    pub sit_at: f32,
    /// Below this probability no terminal skill may be taken. Between the two the controller
    /// chooses as it would alone.
    pub veto_below: f32,
}

impl Gate {
    /// Applies the gate at readiness `p` to `mask` (`terminal`: which skills are terminal).
    pub fn apply(&self, p: f32, mask: &mut [bool], terminal: &[bool]) {
        if p >= self.sit_at {
            gate(mask, terminal, true);
        } else if p < self.veto_below {
            gate(mask, terminal, false);
        }
    }
}

/// One decision of the controller with its sits timed by the copy (`meta eval --oracle-sit`):
/// where a terminal skill could be chosen instead of another, one that succeeds from here (in
/// the copy, so in the episode) is taken, and otherwise `head` chooses among the other skills.
pub(crate) fn checked_act(
    head: &mut ActingHybrid,
    planner: &mut Planner,
    env: &MetaEnv,
    obs: &[f32],
    mask: &mut [bool],
    act: &mut [f32],
) {
    env.option_mask(mask);
    if terminal_choice(mask, planner.terminal()) {
        if let Some(c) = planner.terminal_that_succeeds(env) {
            write_action(planner.setup(), (c, 0), act);
            return;
        }
        gate(mask, planner.terminal(), false);
    }
    head.act(obs, mask, act);
}

/// A trained readiness classifier with what it was trained for.
#[derive(Clone)]
pub struct Readiness {
    /// Its manifest.
    pub manifest: ReadinessManifest,
    /// The classifier: meta observation → probability that the terminal skill succeeds.
    pub classifier: Classifier,
}

/// Options of [`learn`].
#[derive(Debug, Clone)]
pub struct ReadinessOptions {
    /// Where `readiness.ron` and `readiness.safetensors` go.
    pub out: PathBuf,
    /// Zones the labelling episodes start in.
    pub zones: Vec<String>,
    /// Labelling episodes per zone.
    pub trials: usize,
    /// Seed of the labelling episodes (keep it apart from evaluation's).
    pub seed: u64,
    /// The copy's horizon (the terminal skill is played for at most this many decisions).
    pub planner: PlannerConfig,
    /// Every `holdout`-th episode is held out of the fit and measures it (0: none held out).
    pub holdout: usize,
    /// The classifier and its fit.
    pub classifier: ClassifierConfig,
    /// The probability at or above which the gated controller sits.
    pub threshold: f32,
    /// The controller that played the episodes (recorded).
    pub controller: String,
    /// The command line.
    pub command: String,
}

/// How well the classifier separates one set of decisions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Fit {
    /// Decisions.
    pub decisions: usize,
    /// Decisions where it would have succeeded.
    pub ready: usize,
    /// Mean logistic loss.
    pub loss: f64,
    /// Area under the ROC curve.
    pub auc: f64,
    /// At the threshold: share of the decisions called ready that were.
    pub precision: f64,
    /// At the threshold: share of the ready decisions called ready.
    pub recall: f64,
}

impl From<Separation> for Fit {
    fn from(s: Separation) -> Self {
        Fit {
            decisions: s.rows,
            ready: s.positives,
            loss: s.loss,
            auc: s.auc,
            precision: s.precision,
            recall: s.recall,
        }
    }
}

/// What is recorded beside a readiness classifier (`readiness.ron`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReadinessManifest {
    /// The scenario.
    pub scenario: String,
    /// Skills in option order, with their policy checksums: the labels hold only for them.
    pub skills: Vec<String>,
    /// Each skill's `policy_fnv1a`, in option order.
    pub skill_weights: Vec<u64>,
    /// The terminal skills whose success it predicts.
    pub terminal: Vec<String>,
    /// Body content hash.
    pub body_hash: String,
    /// Observation width.
    pub obs_dim: usize,
    /// The probability at or above which the gated controller sits.
    pub threshold: f32,
    /// The controller whose episodes were labelled.
    pub controller: String,
    /// Zones labelled.
    pub zones: Vec<String>,
    /// Episodes per zone.
    pub trials: usize,
    /// Seed of the labelling episodes.
    pub seed: u64,
    /// The classifier's hidden widths.
    pub hidden: Vec<usize>,
    /// Passes over the data.
    pub epochs: usize,
    /// The decisions fitted.
    pub train: Fit,
    /// The held-out episodes' decisions (`None` when none were held out).
    pub holdout: Option<Fit>,
    /// Seconds labelling.
    pub labelling_s: f64,
    /// Seconds fitting.
    pub fitting_s: f64,
    /// The command that made it.
    pub command: String,
    /// Git commit.
    pub git_hash: Option<String>,
}

/// One labelling episode's decisions.
struct Labelled {
    obs: Vec<f32>,
    labels: Vec<f32>,
}

/// Plays one labelling episode: at every decision where a terminal skill could be chosen, the
/// copy says whether it would succeed (the label), and the controller then chooses among the
/// other skills anyway, so the episode walks on past the moments it was ready and labels the
/// states around them too, until it falls or runs out of time.
fn label_episode(
    setup: &Arc<MetaSetup>,
    head: &ActingHybrid,
    cfg: PlannerConfig,
    rng_of: (u64, usize, usize, usize),
) -> Labelled {
    let (seed, zi, trials, i) = rng_of;
    let mut env = MetaEnv::new(Arc::clone(setup));
    let mut planner = Planner::new(Arc::clone(setup), cfg);
    let terminal = terminal_skills(setup);
    let mut head = head.clone();
    let mut rng = trial_rng(seed, zi, trials, i);
    let mut obs = vec![0.0; env.obs_dim()];
    let mut act = vec![0.0; env.act_dim()];
    let mut mask = vec![false; setup.skills.len()];
    let mut out = Labelled { obs: Vec::new(), labels: Vec::new() };
    env.reset(&mut rng, &mut obs);
    loop {
        env.option_mask(&mut mask);
        if terminal_choice(&mask, &terminal) {
            let ready = planner.terminal_that_succeeds(&env).is_some();
            out.obs.extend_from_slice(&obs);
            out.labels.push(if ready { 1.0 } else { 0.0 });
            gate(&mut mask, &terminal, false);
        }
        head.act(&obs, &mask, &mut act);
        let step = env.step(&act, &mut obs);
        if step.terminated || step.truncated {
            return out;
        }
    }
}

/// Labels the decisions of `trials` episodes per zone played by `head` without its sits
/// ([`label_episode`]), fits the classifier to them and writes it to `opts.out`.
pub fn learn(setup: Arc<MetaSetup>, head: &ActingHybrid, opts: &ReadinessOptions) -> Result<ReadinessManifest> {
    setup.check_zones(&opts.zones)?;
    let terminal = terminal_skills(&setup);
    if !terminal.iter().any(|&t| t) {
        return Err(MetaError::Invalid(format!(
            "{}: no skill of the graph is terminal (one with no way out but itself, like sit): \
             there is nothing whose readiness to learn",
            setup.model.scenario.path.display()
        )));
    }
    let started = Instant::now();
    let (mut train, mut held) = ((Vec::new(), Vec::new()), (Vec::new(), Vec::new()));
    for (zi, zone) in opts.zones.iter().enumerate() {
        *setup.zones.write().expect("never poisoned") = vec![zone.clone()];
        let episodes: Vec<Labelled> = (0..opts.trials)
            .into_par_iter()
            .map(|i| label_episode(&setup, head, opts.planner, (opts.seed, zi, opts.trials, i)))
            .collect();
        let ready: usize = episodes.iter().map(|e| e.labels.iter().filter(|&&y| y > 0.5).count()).sum();
        tracing::info!(zone = %zone, episodes = episodes.len(), ready, "labelled");
        for (i, e) in episodes.into_iter().enumerate() {
            let into = if opts.holdout > 0 && i % opts.holdout == 0 { &mut held } else { &mut train };
            into.0.extend(e.obs);
            into.1.extend(e.labels);
        }
    }
    *setup.zones.write().expect("never poisoned") =
        setup.model.scenario.scenario.spawn.iter().map(|z| z.name.clone()).collect();
    let labelling_s = started.elapsed().as_secs_f64();
    if !train.1.iter().any(|&y| y > 0.5) {
        return Err(MetaError::Invalid(format!(
            "none of the {} labelled decisions was one where the terminal skill would succeed: \
             nothing to learn readiness from (label more episodes, or a better controller)",
            train.1.len() + held.1.len()
        )));
    }
    let fit_started = Instant::now();
    let (mut classifier, _) = fit(&train.0, &train.1, &opts.classifier).map_err(MetaError::Invalid)?;
    let fitting_s = fit_started.elapsed().as_secs_f64();
    let mut measure = |(x, y): &(Vec<f32>, Vec<f32>)| -> Fit {
        let mut probs = vec![0.0; y.len()];
        classifier.probabilities(x, &mut probs);
        separation(&probs, y, opts.threshold).into()
    };
    let train_fit = measure(&train);
    let holdout = (!held.1.is_empty()).then(|| measure(&held));
    let manifest = ReadinessManifest {
        scenario: setup.model.scenario.path.display().to_string(),
        skills: setup.skills.iter().map(|s| s.name.clone()).collect(),
        skill_weights: setup.skills.iter().map(|s| s.policy_fnv1a).collect(),
        terminal: setup.skills.iter().zip(&terminal).filter(|(_, t)| **t).map(|(s, _)| s.name.clone()).collect(),
        body_hash: setup.model.body.content_hash(),
        obs_dim: setup.obs_dim(),
        threshold: opts.threshold,
        controller: opts.controller.clone(),
        zones: opts.zones.clone(),
        trials: opts.trials,
        seed: opts.seed,
        hidden: opts.classifier.hidden.clone(),
        epochs: opts.classifier.epochs,
        train: train_fit,
        holdout,
        labelling_s,
        fitting_s,
        command: opts.command.clone(),
        git_hash: git_hash(),
    };
    let readiness = Readiness { manifest: manifest.clone(), classifier };
    readiness.save(&opts.out)?;
    Ok(manifest)
}

impl Readiness {
    /// Writes `readiness.safetensors` and `readiness.ron` into `dir` (each atomically).
    pub fn save(&self, dir: &Path) -> Result<()> {
        std::fs::create_dir_all(dir)
            .map_err(|e| MetaError::Invalid(format!("{}: cannot create: {e}", dir.display())))?;
        self.classifier.save(&dir.join("readiness.safetensors")).map_err(|e| MetaError::Invalid(e.to_string()))?;
        let text = ron::ser::to_string_pretty(&self.manifest, ron::ser::PrettyConfig::new().depth_limit(2))
            .map_err(|e| MetaError::Invalid(e.to_string()))?;
        repertoire_skill::library::write_atomic(&dir.join("readiness.ron"), text.as_bytes())?;
        Ok(())
    }

    /// Loads the readiness classifier in `dir` and checks it was made for `setup`'s skills (the
    /// same weights), body and observation.
    pub fn load(dir: &Path, setup: &MetaSetup) -> Result<Self> {
        let path = dir.join("readiness.ron");
        let text =
            std::fs::read_to_string(&path).map_err(|e| MetaError::Invalid(format!("{}: {e}", path.display())))?;
        let manifest: ReadinessManifest = ron::from_str(&text)
            .map_err(|e| MetaError::Invalid(format!("{}:{}: {}", path.display(), e.span.start.line, e.code)))?;
        let names: Vec<String> = setup.skills.iter().map(|s| s.name.clone()).collect();
        if manifest.skills != names || manifest.body_hash != setup.model.body.content_hash() {
            return Err(MetaError::Invalid(format!(
                "{}: made for skills {:?} on body {}; this scenario has {:?} on body {}",
                path.display(),
                manifest.skills,
                manifest.body_hash,
                names,
                setup.model.body.content_hash()
            )));
        }
        check_skill_weights(&path, &manifest.skill_weights, setup, "label again with `repertoire meta readiness`")?;
        let weights_path = dir.join("readiness.safetensors");
        let classifier = Classifier::load(&weights_path).map_err(|e| MetaError::Invalid(e.to_string()))?;
        if manifest.obs_dim != setup.obs_dim() || classifier.inputs() != setup.obs_dim() {
            return Err(MetaError::Invalid(format!(
                "{}: takes {} observations ({} in {}); this scenario's meta observation has {}",
                path.display(),
                manifest.obs_dim,
                classifier.inputs(),
                weights_path.display(),
                setup.obs_dim()
            )));
        }
        Ok(Readiness { manifest, classifier })
    }
}

impl ReadinessManifest {
    /// A Markdown table of the fit.
    pub fn markdown(&self) -> String {
        let row = |name: &str, f: &Fit| {
            format!(
                "| {name} | {} | {} | {:.3} | {:.3} | {:.1} % | {:.1} % |\n",
                f.decisions,
                f.ready,
                f.loss,
                f.auc,
                100.0 * f.precision,
                100.0 * f.recall
            )
        };
        let mut s = format!(
            "readiness of {} ({} episodes per zone from {}, labelled in {:.1} min, fitted in {:.1} s)\n\n\
             | decisions | count | would succeed | log loss | AUC | precision at {t} | recall at {t} |\n\
             |---|---:|---:|---:|---:|---:|---:|\n",
            self.terminal.join(", "),
            self.trials,
            self.zones.join(", "),
            self.labelling_s / 60.0,
            self.fitting_s,
            t = self.threshold
        );
        s.push_str(&row("fitted", &self.train));
        if let Some(h) = &self.holdout {
            s.push_str(&row("held out", h));
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TERMINAL: [bool; 3] = [false, false, true];

    #[test]
    fn the_gate_offers_the_terminal_skill_only_when_ready_and_lets_a_playing_one_continue() {
        let mut mask = [true, true, true];
        gate(&mut mask, &TERMINAL, true);
        assert_eq!(mask, [false, false, true]);
        let mut mask = [true, false, true];
        gate(&mut mask, &TERMINAL, false);
        assert_eq!(mask, [true, false, false]);
        // Ready, but the graph does not allow the terminal skill here: the others stay.
        let mut mask = [true, true, false];
        gate(&mut mask, &TERMINAL, true);
        assert_eq!(mask, [true, true, false]);
        // The terminal skill is playing and all there is: never masked to nothing.
        let mut mask = [false, false, true];
        gate(&mut mask, &TERMINAL, false);
        assert_eq!(mask, [false, false, true]);
    }

    #[test]
    fn between_veto_and_sit_the_controller_chooses_freely() {
        let g = Gate { sit_at: 0.6, veto_below: 0.1 };
        let cases = [
            (0.7, [false, false, true]),
            (0.6, [false, false, true]),
            (0.3, [true, true, true]),
            (0.05, [true, true, false]),
        ];
        for (p, want) in cases {
            let mut mask = [true, true, true];
            g.apply(p, &mut mask, &TERMINAL);
            assert_eq!(mask, want, "p = {p}");
        }
    }
}
