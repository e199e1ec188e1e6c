//! Recipes: the stages that make a skill library and its controllers, written down as data.
//!
//! A recipe (RON, `recipes/*.ron`) lists stages: copy a committed library into the recipe's work
//! folder, run a `repertoire` command (train, fine-tune, evaluate, deliver handovers, train or
//! re-pin a controller), or repeat a group of stages in rounds until a round gains less than a
//! set number of points. Which stage follows which is read off the paths they name: a stage
//! follows every earlier stage that writes a path it names (or one inside it, or one around
//! it), so a fine-tune that writes `{work}/library/sit` follows the copy that made
//! `{work}/library` and comes before the controller that reads `{work}/library`.
//!
//! Each stage's identity is the hash of what makes its output: its arguments as written, the
//! content of every input outside the work folder it names (spec, scenario, committed pools,
//! the library it copies), and the identities of the stages it follows. A stage whose record
//! says it finished with that identity is skipped; one that started and did not finish resumes
//! from the last checkpoint of its run folder; a changed input changes the identity of that
//! stage and of every stage after it, which then run again. What each stage wrote is kept by
//! content hash (`{work}/.recipe/objects`), so a stage that runs again starts from exactly what
//! the stages before it left, even where later stages rewrote the same library in place.
//!
//! [`run::run_local`] runs a recipe on this machine; [`slurm::submit`] hands each stage to Slurm
//! as a batch job with `--dependency=afterok` edges from the same graph.

pub mod run;
pub mod slurm;
pub mod store;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use petgraph::graph::DiGraph;
use serde::{Deserialize, Serialize};

/// Errors of loading, planning and running a recipe: each names the file or stage it concerns.
#[derive(Debug, thiserror::Error)]
pub enum RecipeError {
    /// The recipe file does not parse.
    #[error("{path}:{line}:{col}: {message}")]
    Parse { path: String, line: usize, col: usize, message: String },
    /// The recipe parses but says something impossible.
    #[error("{path}: {message}")]
    Invalid { path: String, message: String },
    /// A file could not be read or written.
    #[error("{path}: {message}: {source}")]
    Io {
        path: String,
        message: &'static str,
        #[source]
        source: std::io::Error,
    },
    /// A stage failed or cannot run.
    #[error("stage `{stage}`: {message}")]
    Stage { stage: String, message: String },
}

/// Results of this crate.
pub type Result<T> = std::result::Result<T, RecipeError>;

pub(crate) fn io_err(path: &Path, message: &'static str) -> impl FnOnce(std::io::Error) -> RecipeError {
    let path = path.display().to_string();
    move |source| RecipeError::Io { path, message, source }
}

/// A recipe as written.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Recipe {
    /// What the recipe makes, in a line.
    #[serde(default)]
    pub about: String,
    /// The folder every stage writes under, relative to the folder the recipe runs in (the
    /// repository root); `{work}` in a stage stands for it.
    pub work: String,
    /// Named values: `{name}` in a stage's arguments stands for the value.
    #[serde(default)]
    pub vars: BTreeMap<String, String>,
    /// The stages, in the order they run.
    pub stages: Vec<Item>,
}

/// One entry of a recipe's stage list.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub enum Item {
    /// Copy a file or folder (a committed library to start from) into the work folder.
    Copy(CopyItem),
    /// One `repertoire` command.
    Run(RunItem),
    /// Stages repeated in rounds, `{round}` (1, 2, …) and `{prev}` (the round before) in their
    /// arguments, until a round gains less than its stopping rule asks.
    Rounds(RoundsItem),
}

/// [`Item::Copy`].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CopyItem {
    /// The stage's name.
    pub name: String,
    /// What is copied (outside the work folder: its content is part of the identity).
    pub from: String,
    /// Where it goes (inside the work folder).
    pub to: String,
    /// Only these entries of the folder `from` (skill folders of a library: `["walk_to",
    /// "stand", "sit"]`); default: all of it. Only they are part of the identity, so what else
    /// changes in `from` (an evaluation written into the library) does not rerun the recipe.
    #[serde(default)]
    pub only: Vec<String>,
}

/// [`Item::Run`].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunItem {
    /// The stage's name.
    pub name: String,
    /// The arguments of `repertoire` (`["skill", "train", …]`).
    pub args: Vec<String>,
    /// What the command writes, inside the work folder (files or folders): kept by content hash
    /// when the stage ends, restored when a stage after it runs again.
    #[serde(default)]
    pub writes: Vec<String>,
    /// A file (inside the work folder) that gets the command's standard output as well as the
    /// terminal: an evaluation's table. It counts as written.
    #[serde(default)]
    pub stdout: Option<String>,
    /// Inputs the arguments do not name (the clip a spec reads), part of the identity.
    #[serde(default)]
    pub reads: Vec<String>,
    /// The command's run folder (its `--run-dir`): an interrupted stage goes on from the last
    /// checkpoint there (`--resume …/checkpoints/iter-N`).
    #[serde(default)]
    pub resume: Option<String>,
    /// Stages it follows besides those that write what it names.
    #[serde(default)]
    pub after: Vec<String>,
    /// Threads for the command (`RAYON_NUM_THREADS`; Slurm's `--cpus-per-task`); default: all
    /// (Slurm: the profile's).
    #[serde(default)]
    pub cpus: Option<usize>,
}

/// [`Item::Rounds`].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RoundsItem {
    /// The group's name (its stages are `NAME/rK/STAGE`).
    pub name: String,
    /// At most this many rounds.
    pub max: usize,
    /// When to stop before `max` (default: never) and which round to keep.
    #[serde(default)]
    pub stop: Option<Stop>,
    /// Values that change from round to round: `{name}` in a round's stages stands for the
    /// round's entry (`"seed": ["7", "17", "27"]`: 7 in round 1), one entry per round.
    #[serde(default)]
    pub each: BTreeMap<String, Vec<String>>,
    /// The stages of one round (copies and commands; rounds do not nest).
    pub stages: Vec<Item>,
}

/// A rounds group's rule, read from the `meta eval` report each round writes: stop once a round
/// raises its success rate by less than `gain_below` points over the round before (or over
/// `baseline` for the first round), and keep the last round's outputs or the best round's.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Stop {
    /// The `report.json` of a `meta eval --out` each round writes (`{round}` in it).
    pub report: String,
    /// The zone whose success rate counts (default: `all`, every zone together).
    #[serde(default = "all_zones")]
    pub zone: String,
    /// Points (percent) a round must gain to go on (default: every round runs).
    #[serde(default)]
    pub gain_below: Option<f64>,
    /// The report before the first round (a stage before the group writes it); without one
    /// the first round always runs and the second is the first that may stop the group.
    #[serde(default)]
    pub baseline: Option<String>,
    /// Whose outputs the stages after the group see (default: the last round's).
    #[serde(default)]
    pub keep: Keep,
}

/// Which round of a group the stages after it build on.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Keep {
    /// The last round that ran.
    #[default]
    Last,
    /// The round whose report has the highest success rate (the earliest of equals), or none of
    /// them when the baseline is at least as high: the stages after the group see what the
    /// group started from. Seeds of one training as rounds, the best kept.
    Best,
}

fn all_zones() -> String {
    "all".into()
}

/// What a stage does.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub enum Action {
    /// Copy `from` to `to` (only the entries `only` of the folder, when given).
    Copy { from: PathBuf, to: PathBuf, only: Vec<String> },
    /// Run `repertoire ARGS`.
    Run { args: Vec<String> },
}

/// One stage of a planned recipe.
#[derive(Debug, Clone)]
pub struct Stage {
    /// `name`, or `group/rK/name` inside rounds.
    pub id: String,
    /// What it does, placeholders filled in.
    pub action: Action,
    /// The arguments as written (`{work}` unfilled): part of the identity, so moving the work
    /// folder keeps what is done.
    pub template: Vec<String>,
    /// What it writes (files or folders inside the work folder).
    pub writes: Vec<PathBuf>,
    /// Inputs outside the work folder: named by its arguments, or declared (`reads`).
    pub sources: Vec<PathBuf>,
    /// Paths inside the work folder it names (what it reads there, and its own outputs).
    pub names: Vec<PathBuf>,
    /// Its run folder, for resuming.
    pub resume: Option<PathBuf>,
    /// The file its standard output goes to as well.
    pub stdout: Option<PathBuf>,
    /// Threads.
    pub cpus: Option<usize>,
    /// The rounds group and round (from 1) it belongs to.
    pub round: Option<(usize, usize)>,
    /// The stages it follows (indices, all earlier).
    pub deps: Vec<usize>,
}

/// A rounds group of a planned recipe.
#[derive(Debug, Clone)]
pub struct Group {
    /// Its name.
    pub name: String,
    /// The stopping rule, placeholders other than `{round}` filled in.
    pub stop: Option<Stop>,
    /// The stage indices of each round (round K at K-1).
    pub rounds: Vec<std::ops::Range<usize>>,
}

/// A recipe expanded into stages, with the graph of which follows which.
#[derive(Debug, Clone)]
pub struct Plan {
    /// The recipe file (as given).
    pub file: PathBuf,
    /// The work folder.
    pub work: PathBuf,
    /// What the recipe makes.
    pub about: String,
    /// Every stage (every round of every group), in order.
    pub stages: Vec<Stage>,
    /// The rounds groups.
    pub groups: Vec<Group>,
}

impl Plan {
    /// Loads and expands the recipe at `file`; `work` overrides its work folder.
    pub fn load(file: &Path, work: Option<&Path>) -> Result<Plan> {
        Plan::load_with(file, work, &[])
    }

    /// [`Plan::load`] with `vars` set over the recipe's (`--var NAME=VALUE`).
    pub fn load_with(file: &Path, work: Option<&Path>, vars: &[(String, String)]) -> Result<Plan> {
        let text = std::fs::read_to_string(file).map_err(io_err(file, "cannot read the recipe"))?;
        let recipe: Recipe = ron::Options::default()
            .with_default_extension(
                ron::extensions::Extensions::IMPLICIT_SOME | ron::extensions::Extensions::UNWRAP_VARIANT_NEWTYPES,
            )
            .from_str(&text)
            .map_err(|e| RecipeError::Parse {
                path: file.display().to_string(),
                line: e.span.start.line,
                col: e.span.start.col,
                message: e.code.to_string(),
            })?;
        let mut recipe = recipe;
        for (k, v) in vars {
            recipe.vars.insert(k.clone(), v.clone());
        }
        Plan::expand(file, &recipe, work)
    }

    /// Expands `recipe` (read from `file`) into stages.
    pub fn expand(file: &Path, recipe: &Recipe, work: Option<&Path>) -> Result<Plan> {
        let invalid = |message: String| RecipeError::Invalid { path: file.display().to_string(), message };
        let work = normal(work.map(Path::to_path_buf).unwrap_or_else(|| PathBuf::from(&recipe.work)));
        if work.as_os_str().is_empty() || work == Path::new(".") {
            return Err(invalid("`work` must name a folder of its own (everything under it is the recipe's)".into()));
        }
        let mut vars = recipe.vars.clone();
        for reserved in ["work", "round", "prev"] {
            if vars.contains_key(reserved) {
                return Err(invalid(format!("`vars` may not define `{reserved}`: the recipe fills it in")));
            }
        }
        vars.insert("work".into(), work.display().to_string());
        let mut plan = Plan {
            file: file.to_path_buf(),
            work: work.clone(),
            about: recipe.about.clone(),
            stages: vec![],
            groups: vec![],
        };
        let mut after: Vec<Vec<String>> = Vec::new();
        for item in &recipe.stages {
            match item {
                Item::Rounds(g) => {
                    if g.max == 0 {
                        return Err(invalid(format!("rounds `{}`: `max` must be at least 1", g.name)));
                    }
                    let gi = plan.groups.len();
                    let mut group = Group { name: g.name.clone(), stop: None, rounds: vec![] };
                    if let Some(s) = &g.stop {
                        if s.gain_below.is_some_and(|x| !x.is_finite()) {
                            return Err(invalid(format!("rounds `{}`: `gain_below` must be a number", g.name)));
                        }
                        if s.gain_below.is_none() && s.keep == Keep::Last {
                            return Err(invalid(format!(
                                "rounds `{}`: `stop` needs `gain_below` (when to stop) or `keep: Best` (which round to keep)",
                                g.name
                            )));
                        }
                        let keep = |t: &str| {
                            fill(t, &vars, None, true).map_err(|m| invalid(format!("rounds `{}`: {m}", g.name)))
                        };
                        group.stop = Some(Stop {
                            report: keep(&s.report)?,
                            zone: s.zone.clone(),
                            gain_below: s.gain_below,
                            baseline: s.baseline.as_deref().map(keep).transpose()?,
                            keep: s.keep,
                        });
                    }
                    for (k, values) in &g.each {
                        if ["work", "round", "prev"].contains(&k.as_str()) || vars.contains_key(k) {
                            return Err(invalid(format!(
                                "rounds `{}`: `each` may not set `{k}`, which {}",
                                g.name,
                                if vars.contains_key(k) { "`vars` sets" } else { "the recipe fills in" }
                            )));
                        }
                        if values.len() < g.max {
                            return Err(invalid(format!(
                                "rounds `{}`: `each` gives `{k}` {} values for {} rounds",
                                g.name,
                                values.len(),
                                g.max
                            )));
                        }
                    }
                    for r in 1..=g.max {
                        let start = plan.stages.len();
                        let mut round_vars = vars.clone();
                        round_vars.extend(g.each.iter().map(|(k, v)| (k.clone(), v[r - 1].clone())));
                        for inner in &g.stages {
                            if matches!(inner, Item::Rounds(_)) {
                                return Err(invalid(format!("rounds `{}`: rounds do not nest", g.name)));
                            }
                            let (stage, a) =
                                stage_of(inner, &round_vars, Some((gi, r)), &g.name, &work).map_err(invalid)?;
                            plan.stages.push(stage);
                            after.push(a);
                        }
                        group.rounds.push(start..plan.stages.len());
                    }
                    plan.groups.push(group);
                }
                _ => {
                    let (stage, a) = stage_of(item, &vars, None, "", &work).map_err(invalid)?;
                    plan.stages.push(stage);
                    after.push(a);
                }
            }
        }
        for (i, s) in plan.stages.iter().enumerate() {
            if plan.stages[..i].iter().any(|t| t.id == s.id) {
                return Err(invalid(format!("two stages are called `{}`", s.id)));
            }
        }
        // Which stage follows which: an earlier writer of a path it names, or an `after`.
        for (i, after_i) in after.iter().enumerate() {
            let mut deps = Vec::new();
            for j in 0..i {
                let writes = &plan.stages[j].writes;
                if plan.stages[i].names.iter().any(|n| writes.iter().any(|w| overlaps(n, w))) {
                    deps.push(j);
                }
            }
            for name in after_i {
                let scope = plan.stages[i].id.rsplit_once('/').map(|(p, _)| format!("{p}/{name}"));
                let found = (0..i).rev().find(|&j| Some(&plan.stages[j].id) == scope.as_ref()).or_else(|| {
                    (0..i)
                        .rev()
                        .find(|&j| &plan.stages[j].id == name || plan.stages[j].id.ends_with(&format!("/{name}")))
                });
                match found {
                    Some(j) => deps.push(j),
                    None => {
                        return Err(invalid(format!(
                            "stage `{}` comes after `{name}`, which is not a stage before it",
                            plan.stages[i].id
                        )));
                    }
                }
            }
            deps.sort_unstable();
            deps.dedup();
            plan.stages[i].deps = deps;
        }
        Ok(plan)
    }

    /// The graph of the stages: an edge from each stage to each that follows it directly
    /// ([`Plan::direct`]).
    pub fn graph(&self) -> DiGraph<String, ()> {
        let mut g = DiGraph::new();
        let nodes: Vec<_> = self.stages.iter().map(|s| g.add_node(s.id.clone())).collect();
        for i in 0..self.stages.len() {
            for d in self.direct(i) {
                g.add_edge(nodes[d], nodes[i], ());
            }
        }
        g
    }

    /// The stage called `id`.
    pub fn find(&self, id: &str) -> Result<usize> {
        self.stages.iter().position(|s| s.id == id).ok_or_else(|| RecipeError::Invalid {
            path: self.file.display().to_string(),
            message: format!(
                "no stage `{id}` (stages: {})",
                self.stages.iter().map(|s| s.id.as_str()).collect::<Vec<_>>().join(", ")
            ),
        })
    }

    /// The stages `i` follows that no other stage it follows comes after (what a graph drawing
    /// shows).
    pub fn direct(&self, i: usize) -> Vec<usize> {
        let deps = &self.stages[i].deps;
        deps.iter().copied().filter(|&d| !deps.iter().any(|&e| e != d && self.ancestors(e).contains(&d))).collect()
    }

    /// Every stage `i` follows, directly or through others, in order.
    pub fn ancestors(&self, i: usize) -> Vec<usize> {
        let mut seen = vec![false; self.stages.len()];
        let mut todo = self.stages[i].deps.clone();
        while let Some(j) = todo.pop() {
            if !seen[j] {
                seen[j] = true;
                todo.extend(self.stages[j].deps.iter().copied());
            }
        }
        (0..self.stages.len()).filter(|&j| seen[j]).collect()
    }

    /// The folder of the recipe's own records (`{work}/.recipe`).
    pub fn state_dir(&self) -> PathBuf {
        self.work.join(".recipe")
    }
}

/// The stage of `item` and the names it comes `after`.
fn stage_of(
    item: &Item,
    vars: &BTreeMap<String, String>,
    round: Option<(usize, usize)>,
    group: &str,
    work: &Path,
) -> std::result::Result<(Stage, Vec<String>), String> {
    let r = round.map(|(_, r)| r);
    let name = match item {
        Item::Copy(c) => &c.name,
        Item::Run(c) => &c.name,
        Item::Rounds(g) => &g.name,
    };
    if name.is_empty() || name.contains(['/', ' ', '#']) {
        return Err(format!("stage name `{name}`: use letters, digits, `-` and `_`"));
    }
    let id = match r {
        Some(r) => format!("{group}/r{r}/{name}"),
        None => name.clone(),
    };
    let at = |m: String| format!("stage `{id}`: {m}");
    let f = |t: &str| fill(t, vars, r, false).map_err(at);
    // The identity sees the arguments with `{work}` left as written, so that moving the work
    // folder keeps what is done.
    let mut written = vars.clone();
    written.insert("work".into(), "{work}".into());
    let tf = |t: &str| fill(t, &written, r, false).map_err(at);
    let inside = |p: PathBuf, what: &str| -> std::result::Result<PathBuf, String> {
        if p.starts_with(work) {
            Ok(p)
        } else {
            Err(at(format!("{what} `{}` lies outside the work folder `{}`", p.display(), work.display())))
        }
    };
    let mut stage = Stage {
        id: id.clone(),
        action: Action::Run { args: vec![] },
        template: vec![],
        writes: vec![],
        sources: vec![],
        names: vec![],
        resume: None,
        stdout: None,
        cpus: None,
        round,
        deps: vec![],
    };
    let mut after = Vec::new();
    match item {
        Item::Copy(c) => {
            let from = normal(PathBuf::from(f(&c.from)?));
            let to = inside(normal(PathBuf::from(f(&c.to)?)), "`to`")?;
            if c.only.iter().any(|o| o.is_empty() || o.contains("..") || Path::new(o).is_absolute()) {
                return Err(at("`only` names entries of the folder `from` (no `..`, no absolute paths)".into()));
            }
            let parts: Vec<PathBuf> =
                if c.only.is_empty() { vec![from.clone()] } else { c.only.iter().map(|o| from.join(o)).collect() };
            for p in parts {
                if from.starts_with(work) {
                    stage.names.push(p);
                } else {
                    stage.sources.push(p);
                }
            }
            stage.template = vec![tf(&c.from)?, tf(&c.to)?];
            stage.template.extend(c.only.iter().map(|o| format!("only:{o}")));
            stage.writes.push(to.clone());
            stage.names.push(to.clone());
            stage.action = Action::Copy { from, to, only: c.only.clone() };
        }
        Item::Run(c) => {
            if c.args.is_empty() {
                return Err(at("`args` is empty".into()));
            }
            if c.writes.is_empty() && c.stdout.is_none() {
                return Err(at(
                    "it writes nothing: name what the command makes (`writes`, or `stdout` for a table it prints), so later stages can follow it"
                        .into(),
                ));
            }
            let args = c.args.iter().map(|a| f(a)).collect::<std::result::Result<Vec<_>, _>>()?;
            // The command's words (`meta train`) name no input, even where a folder of the same
            // name lies beside the recipe (the `meta` crate of this repository).
            let words = args.iter().take_while(|a| is_command_word(a)).count();
            for a in &args[words..] {
                for p in path_parts(a) {
                    if p.starts_with(work) {
                        stage.names.push(p);
                    } else if p.exists() {
                        stage.sources.push(p);
                    }
                }
            }
            for w in &c.writes {
                let p = inside(normal(PathBuf::from(f(w)?)), "`writes`")?;
                stage.names.push(p.clone());
                stage.writes.push(p);
            }
            for rd in &c.reads {
                let p = normal(PathBuf::from(f(rd)?));
                if p.starts_with(work) {
                    stage.names.push(p);
                } else {
                    stage.sources.push(p);
                }
            }
            if let Some(d) = &c.resume {
                let p = inside(normal(PathBuf::from(f(d)?)), "`resume`")?;
                stage.resume = Some(p);
            }
            if let Some(o) = &c.stdout {
                let p = inside(normal(PathBuf::from(f(o)?)), "`stdout`")?;
                stage.names.push(p.clone());
                stage.writes.push(p.clone());
                stage.stdout = Some(p);
            }
            if c.cpus == Some(0) {
                return Err(at("`cpus` must be at least 1".into()));
            }
            stage.cpus = c.cpus;
            let mut template = Vec::new();
            for a in &c.args {
                template.push(tf(a)?);
            }
            for w in &c.writes {
                template.push(format!("writes:{}", tf(w)?));
            }
            for w in &c.reads {
                template.push(format!("reads:{}", tf(w)?));
            }
            if let Some(w) = &c.resume {
                template.push(format!("resume:{}", tf(w)?));
            }
            if let Some(w) = &c.stdout {
                template.push(format!("stdout:{}", tf(w)?));
            }
            stage.template = template;
            stage.action = Action::Run { args };
            after = c.after.clone();
        }
        Item::Rounds(_) => unreachable!("rounds are expanded by the caller"),
    }
    stage.sources.sort();
    stage.sources.dedup();
    stage.names.sort();
    stage.names.dedup();
    Ok((stage, after))
}

/// `text` with `{name}` placeholders filled from `vars`, `{round}` and `{prev}` from `round`;
/// `keep_round`: leave `{round}` and `{prev}` as they are (stopping rules fill them per round).
pub(crate) fn fill(
    text: &str,
    vars: &BTreeMap<String, String>,
    round: Option<usize>,
    keep_round: bool,
) -> std::result::Result<String, String> {
    let mut out = String::new();
    let mut rest = text;
    while let Some(open) = rest.find('{') {
        out.push_str(&rest[..open]);
        // `{name}` is a placeholder; a brace around anything else (JSON in a shell line) is text.
        let close = rest[open..].find('}').map(|c| c + open);
        let key = close
            .map(|c| &rest[open + 1..c])
            .filter(|k| !k.is_empty() && k.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-'));
        let (Some(close), Some(key)) = (close, key) else {
            out.push('{');
            rest = &rest[open + 1..];
            continue;
        };
        match (key, round) {
            ("round" | "prev", _) if keep_round => out.push_str(&rest[open..=close]),
            ("round", Some(r)) => out.push_str(&r.to_string()),
            ("prev", Some(r)) => out.push_str(&(r - 1).to_string()),
            ("round" | "prev", None) => {
                return Err(format!("`{text}`: `{{{key}}}` only means something inside rounds"));
            }
            _ => match vars.get(key) {
                Some(v) => out.push_str(v),
                None => {
                    let known = vars.keys().map(|k| format!("{{{k}}}")).collect::<Vec<_>>().join(", ");
                    return Err(format!("`{text}`: no value for `{{{key}}}` (known: {known}, {{round}}, {{prev}})"));
                }
            },
        }
        rest = &rest[close + 1..];
    }
    out.push_str(rest);
    Ok(out)
}

/// The paths an argument may name: itself, its comma-separated parts, and the value of a
/// `--flag=value`.
/// A subcommand's name (`meta`, `finetune`): lowercase letters and `-`, not a flag.
fn is_command_word(arg: &str) -> bool {
    !arg.is_empty() && !arg.starts_with('-') && arg.chars().all(|c| c.is_ascii_lowercase() || c == '-')
}

fn path_parts(arg: &str) -> Vec<PathBuf> {
    let value = match arg.strip_prefix("--") {
        Some(flag) => match flag.split_once('=') {
            Some((_, v)) => v,
            None => return vec![],
        },
        None => arg,
    };
    value.split(',').filter(|p| !p.is_empty()).map(|p| normal(PathBuf::from(p))).collect()
}

pub use repertoire_files::normal;

/// Whether one of the paths lies inside the other (or they are the same).
fn overlaps(a: &Path, b: &Path) -> bool {
    a.starts_with(b) || b.starts_with(a)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plan(text: &str) -> Result<Plan> {
        let recipe: Recipe = ron::Options::default()
            .with_default_extension(
                ron::extensions::Extensions::IMPLICIT_SOME | ron::extensions::Extensions::UNWRAP_VARIANT_NEWTYPES,
            )
            .from_str(text)
            .expect("parses");
        Plan::expand(Path::new("t.ron"), &recipe, None)
    }

    #[test]
    fn stages_follow_the_writers_of_what_they_name_and_rounds_expand() {
        let p = plan(
            r#"(work: "w", stages: [
                Copy(name: "lib", from: "no/such/library", to: "{work}/lib"),
                Run(name: "a", args: ["skill", "train", "x.ron", "--library", "{work}/lib"], writes: ["{work}/lib/a"]),
                Run(name: "b", args: ["meta", "eval", "--out", "{work}/eval"], writes: ["{work}/eval"]),
                Rounds(name: "loop", max: 2, stages: [
                    Run(name: "ft", args: ["skill", "finetune", "--library", "{work}/lib", "--run-dir", "{work}/runs/ft-{round}"],
                        writes: ["{work}/lib/sit"], resume: "{work}/runs/ft-{round}"),
                    Run(name: "ev", args: ["meta", "eval", "--out", "{work}/ev-{round}"], writes: ["{work}/ev-{round}"], after: ["ft"]),
                ]),
            ])"#,
        )
        .unwrap();
        let ids: Vec<_> = p.stages.iter().map(|s| s.id.as_str()).collect();
        assert_eq!(ids, ["lib", "a", "b", "loop/r1/ft", "loop/r1/ev", "loop/r2/ft", "loop/r2/ev"]);
        assert_eq!(p.stages[1].deps, [0], "a reads the copied library");
        assert!(p.stages[2].deps.is_empty(), "b names nothing the others write");
        assert_eq!(p.stages[3].deps, [0, 1], "round 1's fine-tune reads the library a wrote into");
        assert_eq!(p.stages[4].deps, [3], "`after` inside a round means that round's stage");
        assert_eq!(p.stages[5].deps, [0, 1, 3], "round 2 follows round 1's writer of the sit");
        assert_eq!(p.stages[6].deps, [5]);
        assert_eq!(p.stages[5].resume.as_deref(), Some(Path::new("w/runs/ft-2")));
        assert_eq!(p.ancestors(6), [0, 1, 3, 5]);
        assert_eq!(p.direct(5), [3], "drawn: round 2 after round 1, which comes after the rest");
        assert_eq!(p.graph().edge_count(), 5);
    }

    #[test]
    fn the_command_words_are_not_inputs_even_where_a_folder_has_their_name() {
        // Tests run in the crate's folder, which has `src` and `Cargo.toml`.
        let p = plan(
            r#"(work: "w", stages: [Run(name: "a", args: ["src", "eval", "Cargo.toml", "--out", "{work}/a"], writes: ["{work}/a"])])"#,
        )
        .unwrap();
        assert_eq!(p.stages[0].sources, [PathBuf::from("Cargo.toml")]);
        let p =
            plan(r#"(work: "w", stages: [Run(name: "a", args: ["x", "--in", "src"], writes: ["{work}/a"])])"#).unwrap();
        assert_eq!(p.stages[0].sources, [PathBuf::from("src")], "after the command's words, a folder is an input");
    }

    #[test]
    fn bad_recipes_name_the_stage_and_what_is_wrong() {
        let e =
            plan(r#"(work: "w", stages: [Run(name: "a", args: ["x", "{nope}"], writes: ["{work}/a"])])"#).unwrap_err();
        assert!(e.to_string().contains("stage `a`") && e.to_string().contains("{nope}"), "{e}");
        let e = plan(r#"(work: "w", stages: [Run(name: "a", args: ["x"], writes: ["elsewhere"])])"#).unwrap_err();
        assert!(e.to_string().contains("outside the work folder"), "{e}");
        let e =
            plan(r#"(work: "w", stages: [Run(name: "a", args: ["x", "{round}"], writes: ["{work}/a"])])"#).unwrap_err();
        assert!(e.to_string().contains("inside rounds"), "{e}");
        let e = plan(r#"(work: "w", stages: [Run(name: "a", args: ["x"], writes: ["{work}/a"], after: ["b"])])"#)
            .unwrap_err();
        assert!(e.to_string().contains("not a stage before it"), "{e}");
        let e = plan(
            r#"(work: "w", stages: [Run(name: "a", args: ["x"], writes: ["{work}/a"]), Run(name: "a", args: ["y"], writes: ["{work}/b"])])"#,
        )
        .unwrap_err();
        assert!(e.to_string().contains("two stages are called `a`"), "{e}");
        let e = plan(r#"(work: ".", stages: [])"#).unwrap_err();
        assert!(e.to_string().contains("folder of its own"), "{e}");
        let e = plan(
            r#"(work: "w", stages: [Rounds(name: "g", max: 3, each: {"seed": ["1", "2"]}, stages: [Run(name: "a", args: ["x", "{seed}"])])])"#,
        )
        .unwrap_err();
        assert!(e.to_string().contains("`seed` 2 values for 3 rounds"), "{e}");
    }

    #[test]
    fn each_round_reads_its_own_values() {
        let p = plan(
            r#"(work: "w", stages: [Rounds(name: "g", max: 2, each: {"seed": ["7", "17"]}, stages: [
                Run(name: "a", args: ["x", "--seed", "{seed}", "--out", "{work}/o-{round}"], writes: ["{work}/o-{round}"])])])"#,
        )
        .unwrap();
        let args: Vec<_> = p.stages.iter().map(|s| s.template.join(" ")).collect();
        assert_eq!(
            args,
            ["x --seed 7 --out {work}/o-1 writes:{work}/o-1", "x --seed 17 --out {work}/o-2 writes:{work}/o-2"]
        );
    }
}
