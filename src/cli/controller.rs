//! The argument groups `meta eval` and `run` share: the scenario and library, and the
//! controller (`--controller learned|planner|oracle-sit|lookahead:K|gated[:DIR]` with its
//! settings), resolved into a loaded [`Controller`] and its default report folder.

use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::sync::Arc;

use anyhow::{Result, bail};
use repertoire_learn::acting::ActingHybrid;
use repertoire_meta::controller::{Controller, Gated, LookingAhead, OracleSit};
use repertoire_meta::handover::readiness::{Gate, Readiness};
use repertoire_meta::search::lookahead::LookaheadConfig;
use repertoire_meta::train::MetaManifest;
use repertoire_meta::{MetaSetup, TaskSpec};

use super::meta::{DEFAULT_LIBRARY, PlannerArgs};

/// The scenario, the skill library and the skill graph a command runs over.
#[derive(Debug, Clone, clap::Args)]
pub struct ScenarioArgs {
    /// Scenario RON file (default: the built-in scenarios/sit.ron).
    pub file: Option<PathBuf>,
    /// Skill library.
    #[arg(long, default_value = DEFAULT_LIBRARY)]
    pub library: PathBuf,
}

/// The skill graph's restrictions (`meta train`, `meta eval`): the same at evaluation as at
/// training.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct GraphArgs {
    /// Replace the scenario's skill graph by this fixed-order chain (e.g. walk,turn_left,sit).
    #[arg(long, value_delimiter = ',')]
    pub chain: Vec<String>,
    /// Restrict the scenario's graph to these skills (e.g. walk,turn_left,sit).
    #[arg(long, value_delimiter = ',')]
    pub skills: Vec<String>,
}

/// What decides which skill plays.
#[derive(Debug, Clone, PartialEq)]
pub enum Choice {
    /// The trained controller alone, acting by its mode.
    Learned,
    /// The search-based reference: at each decision it simulates skill plans in a copy of the
    /// episode and plays out one that succeeds (sitting).
    Planner,
    /// The trained controller with its sit timed by the planner's copy (sitting).
    OracleSit,
    /// The trained controller checked in a copy of the episode, K candidates a search
    /// (sitting).
    Lookahead(u32),
    /// The trained controller's sit gated by a learned readiness (`meta readiness`; default
    /// folder CONTROLLER/readiness) (sitting).
    Gated(Option<PathBuf>),
}

impl FromStr for Choice {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let (name, arg) = match s.split_once(':') {
            Some((name, arg)) => (name, Some(arg)),
            None => (s, None),
        };
        match (name, arg) {
            ("learned", None) => Ok(Choice::Learned),
            ("planner", None) => Ok(Choice::Planner),
            ("oracle-sit", None) => Ok(Choice::OracleSit),
            ("lookahead", Some(k)) => match k.parse::<u32>() {
                Ok(k) if k >= 1 => Ok(Choice::Lookahead(k)),
                _ => Err(format!("`{s}`: lookahead:K takes K candidates a search, a whole number from 1")),
            },
            ("gated", None) => Ok(Choice::Gated(None)),
            ("gated", Some(dir)) if !dir.is_empty() => Ok(Choice::Gated(Some(PathBuf::from(dir)))),
            _ => Err(format!(
                "`{s}`: expected learned, planner, oracle-sit, lookahead:K (K candidates a search) or gated[:DIR] \
                 (a `meta readiness` folder)"
            )),
        }
    }
}

impl Choice {
    /// Its name in messages and report folders.
    fn name(&self) -> &'static str {
        match self {
            Choice::Learned => "learned",
            Choice::Planner => "planner",
            Choice::OracleSit => "oracle-sit",
            Choice::Lookahead(_) => "lookahead",
            Choice::Gated(_) => "gated",
        }
    }
}

/// `--controller` and its settings.
#[derive(Debug, Clone, clap::Args)]
pub struct ControllerArgs {
    /// What decides: `learned` (the trained controller), `planner` (the search-based
    /// reference), `oracle-sit` (the controller, its sit timed by the planner's copy),
    /// `lookahead:K` (the controller checked in a copy of the episode, K candidates a search;
    /// never seats fewer, costs K simulated episodes a search) or `gated[:DIR]` (its sit gated
    /// by a `meta readiness` folder, default CONTROLLER/readiness). All but `learned` are for
    /// sitting scenarios.
    #[arg(long, default_value = "learned")]
    pub controller: Choice,
    /// The trained controller (default: as `meta train` writes it).
    #[arg(long)]
    pub meta: Option<PathBuf>,
    /// lookahead: most searches per episode (then the controller acts alone).
    #[arg(long, default_value_t = LookaheadConfig::default().searches)]
    pub lookahead_searches: u32,
    /// lookahead: simulate every candidate, also those whose copy a search can tell without
    /// playing it: the same decisions at more cost, to check that.
    #[arg(long)]
    pub lookahead_every_candidate: bool,
    /// gated: the readiness at or above which the controller sits (default: the one recorded
    /// with it).
    #[arg(long, value_parser = super::meta::probability)]
    pub ready_at: Option<f32>,
    /// gated: the readiness below which the controller may not sit (default: --ready-at, so the
    /// gate alone decides; between the two the controller decides).
    #[arg(long, value_parser = super::meta::probability)]
    pub veto_below: Option<f32>,
    #[command(flatten)]
    pub plan: PlannerArgs,
    /// Same as `--controller planner` (kept for older command lines).
    #[arg(long, hide = true)]
    pub planner: bool,
    /// Same as `--controller oracle-sit` (kept for older command lines).
    #[arg(long, hide = true)]
    pub oracle_sit: bool,
    /// Same as `--controller lookahead:K` (kept for older command lines).
    #[arg(long, hide = true, value_parser = clap::value_parser!(u32).range(1..))]
    pub lookahead: Option<u32>,
    /// Same as `--controller gated:DIR` (kept for older command lines).
    #[arg(long, hide = true)]
    pub readiness: Option<PathBuf>,
}

impl ControllerArgs {
    /// The choice, from `--controller` or one of the older flags (two at once are refused), and
    /// its settings checked against it.
    pub fn choice(&self) -> Result<Choice> {
        let older: Vec<Choice> = [
            self.planner.then_some(Choice::Planner),
            self.oracle_sit.then_some(Choice::OracleSit),
            self.lookahead.map(Choice::Lookahead),
            self.readiness.clone().map(|d| Choice::Gated(Some(d))),
        ]
        .into_iter()
        .flatten()
        .collect();
        let choice = match (older.as_slice(), &self.controller) {
            ([], c) => c.clone(),
            ([one], Choice::Learned) => one.clone(),
            _ => bail!(
                "more than one controller asked for: --controller and --planner, --oracle-sit, --lookahead and \
                 --readiness each choose one"
            ),
        };
        let not_lookahead = !matches!(choice, Choice::Lookahead(_));
        if not_lookahead
            && (self.lookahead_every_candidate || self.lookahead_searches != LookaheadConfig::default().searches)
        {
            bail!("--lookahead-searches and --lookahead-every-candidate are settings of --controller lookahead:K");
        }
        if !matches!(choice, Choice::Gated(_)) && (self.ready_at.is_some() || self.veto_below.is_some()) {
            bail!("--ready-at and --veto-below set a readiness gate, and there is none (--controller gated[:DIR])");
        }
        if choice == Choice::Planner && self.meta.is_some() {
            bail!("--controller planner chooses the skills itself: it takes no --meta");
        }
        Ok(choice)
    }
}

/// A controller loaded from its files, ready to decide.
pub struct Loaded {
    /// What was chosen.
    pub choice: Choice,
    /// The trained controller's folder and manifest (`None` for the planner).
    pub meta: Option<(PathBuf, MetaManifest)>,
    head: Option<ActingHybrid>,
    readiness: Option<(Readiness, Gate, PathBuf)>,
    args: ControllerArgs,
    seed: u64,
}

impl Loaded {
    /// Loads what `args` chooses over `setup` (the trained controller from `--meta` or the
    /// library's default for the scenario); a search-based choice outside sitting is refused.
    /// `seed` seeds the lookahead's draws.
    pub fn load(args: &ControllerArgs, setup: &Arc<MetaSetup>, library: &Path, seed: u64) -> Result<Self> {
        let choice = args.choice()?;
        if choice != Choice::Learned && !matches!(setup.task, TaskSpec::Sit { .. }) {
            bail!(
                "{}: --controller {} decides in sitting scenarios only (this one is {})",
                setup.model.scenario.path.display(),
                choice.name(),
                setup.task.name()
            );
        }
        let (meta, head) = if choice == Choice::Planner {
            (None, None)
        } else {
            let dir = args.meta.clone().unwrap_or_else(|| super::meta::setup_meta(library, setup));
            let (manifest, head) = repertoire_meta::train::load(&dir, setup)?;
            (Some((dir, manifest)), Some(head))
        };
        let readiness = match (&choice, &meta) {
            (Choice::Gated(dir), Some((m, _))) => {
                let dir = dir.clone().unwrap_or_else(|| m.join("readiness"));
                let r = Readiness::load(&dir, setup)?;
                let sit_at = args.ready_at.unwrap_or(r.manifest.threshold);
                let gate = Gate { sit_at, veto_below: args.veto_below.unwrap_or(sit_at) };
                if gate.veto_below > gate.sit_at {
                    bail!("--veto-below {} is above the readiness the controller sits at ({sit_at})", gate.veto_below);
                }
                Some((r, gate, dir))
            }
            _ => None,
        };
        Ok(Loaded { choice, meta, head, readiness, args: args.clone(), seed })
    }

    /// The decision maker.
    pub fn controller(&self) -> Result<Box<dyn Controller + '_>> {
        let head = || self.head.as_ref().expect("loaded for every choice but the planner");
        Ok(match &self.choice {
            Choice::Learned => Box::new(head().clone()),
            Choice::Planner => Box::new(self.args.plan.config()?),
            Choice::OracleSit => Box::new(OracleSit { head: head(), planner: self.args.plan.config()? }),
            Choice::Lookahead(k) => Box::new(LookingAhead { head: head(), lookahead: self.lookahead(*k) }),
            Choice::Gated(_) => {
                let (readiness, gate, _) = self.readiness.as_ref().expect("loaded with the gated choice");
                Box::new(Gated { head: head(), readiness, gate: *gate })
            }
        })
    }

    fn lookahead(&self, k: u32) -> LookaheadConfig {
        LookaheadConfig {
            candidates: k as usize,
            searches: self.args.lookahead_searches,
            seed: self.seed,
            skip_known: !self.args.lookahead_every_candidate,
        }
    }

    /// Where its evaluation goes when no folder is given: CONTROLLER/eval for the trained
    /// controller, CONTROLLER/eval-<choice> for one that searches or is gated,
    /// runs/planner-<scenario> for the planner.
    pub fn default_out(&self, setup: &MetaSetup) -> PathBuf {
        match (&self.choice, &self.meta) {
            (Choice::Learned, Some((dir, _))) => dir.join("eval"),
            (choice, Some((dir, _))) => dir.join(format!("eval-{}", choice.name())),
            (_, None) => PathBuf::from("runs").join(format!("planner-{}", setup.model.scenario.scenario.name)),
        }
    }

    /// One line saying what decides, for the report's heading on the terminal.
    pub fn describe(&self) -> Result<String> {
        let controller = |extra: String| match &self.meta {
            Some((dir, m)) => format!("meta-controller {} ({}{extra})", dir.display(), m.iterations_label()),
            None => String::new(),
        };
        Ok(match &self.choice {
            Choice::Learned => controller(String::new()),
            Choice::Planner => {
                let cfg = self.args.plan.config()?;
                format!("planner (horizon {}, repeats {})", cfg.horizon, cfg.repeats)
            }
            Choice::OracleSit => controller(", the sit timed by the planner's copy".into()),
            Choice::Lookahead(k) => controller(format!(
                ", looking ahead {k} candidates a search, at most {} searches an episode",
                self.args.lookahead_searches
            )),
            Choice::Gated(_) => {
                let (_, gate, dir) = self.readiness.as_ref().expect("loaded with the gated choice");
                controller(format!(
                    ", the sit gated by the readiness in {}: sits at p ≥ {}, never at p < {}",
                    dir.display(),
                    gate.sit_at,
                    gate.veto_below
                ))
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn controller_choices_parse_with_their_arguments() {
        assert_eq!("learned".parse::<Choice>(), Ok(Choice::Learned));
        assert_eq!("planner".parse::<Choice>(), Ok(Choice::Planner));
        assert_eq!("oracle-sit".parse::<Choice>(), Ok(Choice::OracleSit));
        assert_eq!("lookahead:8".parse::<Choice>(), Ok(Choice::Lookahead(8)));
        assert_eq!("gated".parse::<Choice>(), Ok(Choice::Gated(None)));
        assert_eq!("gated:runs/ready".parse::<Choice>(), Ok(Choice::Gated(Some(PathBuf::from("runs/ready")))));
        for bad in ["lookahead", "lookahead:0", "lookahead:two", "learned:x", "gated:", "Planner", ""] {
            let err = bad.parse::<Choice>().expect_err(bad);
            assert!(err.contains("expected learned") || err.contains("lookahead:K"), "{bad}: {err}");
        }
    }

    #[derive(clap::Parser)]
    struct Probe {
        #[command(flatten)]
        controller: ControllerArgs,
    }

    fn choice(args: &[&str]) -> Result<Choice> {
        use clap::Parser as _;
        Probe::try_parse_from([&["probe"][..], args].concat())?.controller.choice()
    }

    #[test]
    fn one_controller_is_chosen_by_the_flag_or_an_older_one() {
        assert_eq!(choice(&[]).unwrap(), Choice::Learned);
        assert_eq!(choice(&["--lookahead", "3"]).unwrap(), Choice::Lookahead(3));
        assert_eq!(choice(&["--planner"]).unwrap(), Choice::Planner);
        assert_eq!(choice(&["--readiness", "r"]).unwrap(), Choice::Gated(Some(PathBuf::from("r"))));
        assert_eq!(
            choice(&["--controller", "lookahead:2", "--lookahead-searches", "1"]).unwrap(),
            Choice::Lookahead(2)
        );
        for bad in [
            &["--controller", "planner", "--lookahead", "2"][..],
            &["--planner", "--oracle-sit"],
            &["--lookahead-searches", "1"],
            &["--controller", "oracle-sit", "--ready-at", "0.4"],
            &["--controller", "planner", "--meta", "m"],
        ] {
            assert!(choice(bad).is_err(), "{bad:?} was accepted");
        }
    }
}
