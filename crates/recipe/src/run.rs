//! Running a planned recipe: each stage's identity, which rounds run, what is done, and one
//! stage run with what the stages before it left (here, or inside a Slurm job).

use std::collections::{BTreeMap, HashMap};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use sha2::{Digest, Sha256};

use crate::store::{Record, Status, Store, files_under, hash_path, hex};
use crate::{Action, Keep, Plan, RecipeError, Result, io_err};

/// The environment variable a stage's command finds its recipe and stage in
/// (`recipes/sit.ron#handover/r2/finetune`); the command line a manifest records names it.
pub const STAGE_ENV: &str = "REPERTOIRE_RECIPE_STAGE";

/// Where a stage stands, as `recipe plan` shows it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Standing {
    /// Finished with its current identity.
    Done,
    /// Started with its current identity and not finished: goes on from its checkpoint.
    Resume,
    /// Handed to Slurm, the job still there.
    Queued(u64),
    /// Will run.
    Run,
    /// Its round will not run: the rounds before stopped the group.
    Stopped,
    /// Its round runs or not by what the round before gains, not known yet.
    Undecided,
}

/// A plan and its store, with what is known of each stage.
pub struct Runner<'a> {
    /// The plan.
    pub plan: &'a Plan,
    /// Its store.
    pub store: Store,
    /// The `repertoire` binary the stages run.
    pub exe: PathBuf,
    /// `Some(true)`: the stage's round runs (or it is in none); `Some(false)`: stopped; `None`:
    /// not known yet.
    active: Vec<Option<bool>>,
    /// Each stage's identity, once its inputs are known.
    identity: Vec<Option<String>>,
    /// Whether a group goes on after round K, once known.
    go_on: HashMap<(usize, usize), Option<bool>>,
    /// The round a group keeps (0: none of them), once its rounds are done.
    kept: HashMap<usize, usize>,
    hashes: HashMap<PathBuf, String>,
}

impl<'a> Runner<'a> {
    /// A runner of `plan` that runs `exe` for each command.
    pub fn new(plan: &'a Plan, exe: PathBuf) -> Runner<'a> {
        let n = plan.stages.len();
        Runner {
            plan,
            store: Store::new(plan.state_dir()),
            exe,
            active: vec![None; n],
            identity: vec![None; n],
            go_on: HashMap::new(),
            kept: HashMap::new(),
            hashes: HashMap::new(),
        }
    }

    /// Works out whether stage `i` runs and its identity (every stage before it settled first).
    pub fn settle(&mut self, i: usize) -> Result<()> {
        let stage = &self.plan.stages[i];
        let mut active = match stage.round {
            None | Some((_, 1)) => Some(true),
            Some((g, r)) => self.goes_on(g, r - 1)?,
        };
        // A stage after rounds not decided yet is not known either (its inputs depend on them),
        // nor one after a group that keeps its best round before every round is done.
        if active == Some(true) && stage.deps.iter().any(|&d| self.active[d].is_none()) {
            active = None;
        }
        if active == Some(true) {
            for d in self.plan.ancestors(i) {
                if let Some((g, _)) = self.plan.stages[d].round
                    && stage.round.is_none_or(|(h, _)| h != g)
                    && self.kept_round(g)?.is_none()
                {
                    active = None;
                }
            }
        }
        self.active[i] = active;
        if active == Some(true) {
            let id = self.compute_identity(i)?;
            self.identity[i] = Some(id);
        }
        Ok(())
    }

    /// Settles every stage.
    pub fn settle_all(&mut self) -> Result<()> {
        (0..self.plan.stages.len()).try_for_each(|i| self.settle(i))
    }

    /// Stage `i`'s identity (after [`Runner::settle`]).
    pub fn identity(&self, i: usize) -> Option<&str> {
        self.identity[i].as_deref()
    }

    /// Whether stage `i` runs: `Some(false)` when its round was stopped, `None` undecided.
    pub fn active(&self, i: usize) -> Option<bool> {
        self.active[i]
    }

    fn compute_identity(&mut self, i: usize) -> Result<String> {
        let stage = &self.plan.stages[i];
        let mut h = Sha256::new();
        h.update(b"repertoire recipe stage 1\n");
        h.update(stage.id.as_bytes());
        h.update([0]);
        for t in &stage.template {
            h.update(t.as_bytes());
            h.update([0]);
        }
        for src in &stage.sources {
            let hash = match self.hashes.get(src) {
                Some(x) => x.clone(),
                None => {
                    if !src.exists() {
                        return Err(RecipeError::Stage {
                            stage: stage.id.clone(),
                            message: format!("reads {}, which does not exist", src.display()),
                        });
                    }
                    let x = hash_path(src)?;
                    self.hashes.insert(src.clone(), x.clone());
                    x
                }
            };
            h.update(src.to_string_lossy().as_bytes());
            h.update([0]);
            h.update(hash.as_bytes());
            h.update([0]);
        }
        for &d in &stage.deps {
            if self.active[d] == Some(true) && !self.left_behind(d, i) {
                let id = self.identity[d].as_deref().expect("earlier stages are settled first");
                h.update(id.as_bytes());
            }
        }
        Ok(hex(&h.finalize())[..32].to_string())
    }

    /// Whether stage `i` finished with its current identity.
    pub fn done(&self, i: usize) -> Result<bool> {
        let Some(id) = &self.identity[i] else { return Ok(false) };
        Ok(
            matches!(self.store.record(&self.plan.stages[i].id)?, Some(r) if &r.identity == id && r.status == Status::Done),
        )
    }

    /// Whether group `g` goes on after its round `r`: `None` while that round is not done.
    fn goes_on(&mut self, g: usize, r: usize) -> Result<Option<bool>> {
        if let Some(&known @ Some(_)) = self.go_on.get(&(g, r)) {
            return Ok(known);
        }
        let group = &self.plan.groups[g];
        let range = group.rounds[r - 1].clone();
        let decided = if range.clone().any(|i| self.active[i] == Some(false)) {
            Some(false)
        } else if let Some(stop) = group.stop.clone().filter(|s| s.gain_below.is_some()) {
            let gain_below = stop.gain_below.expect("filtered");
            let mut all_done = true;
            for i in range.clone() {
                all_done &= self.done(i)?;
            }
            if !all_done {
                None
            } else {
                let now = metric(
                    &stop.report.replace("{round}", &r.to_string()).replace("{prev}", &(r - 1).to_string()),
                    &stop.zone,
                )?;
                let before = if r > 1 {
                    Some(metric(
                        &stop.report.replace("{round}", &(r - 1).to_string()).replace("{prev}", &(r - 2).to_string()),
                        &stop.zone,
                    )?)
                } else {
                    stop.baseline.as_deref().map(|b| metric(b, &stop.zone)).transpose()?
                };
                match before {
                    None => Some(true),
                    Some(b) => {
                        let gain = 100.0 * (now - b);
                        let go = gain >= gain_below;
                        tracing::info!(group = %group.name, round = r, gain, go_on = go, "stopping rule");
                        println!(
                            "{}: round {r} gained {gain:+.1} points ({:.1} → {:.1} % in zone {}); {}",
                            group.name,
                            100.0 * b,
                            100.0 * now,
                            stop.zone,
                            if go { "another round".to_string() } else { format!("stops (under {gain_below} points)") }
                        );
                        Some(go)
                    }
                }
            }
        } else {
            Some(true)
        };
        self.go_on.insert((g, r), decided);
        Ok(decided)
    }

    /// The round group `g` keeps for the stages after it (0: none, the baseline was better),
    /// once every round that runs is done; `None` before. A group that keeps its last round
    /// keeps every round (each overwrites the one before).
    pub fn kept_round(&mut self, g: usize) -> Result<Option<usize>> {
        let group = &self.plan.groups[g];
        let Some(stop) = group.stop.clone().filter(|s| s.keep == Keep::Best) else {
            return Ok(Some(group.rounds.len()));
        };
        if let Some(&k) = self.kept.get(&g) {
            return Ok(Some(k));
        }
        let mut best = (0, f64::NEG_INFINITY);
        if let Some(b) = &stop.baseline {
            best.1 = metric(b, &stop.zone)?;
        }
        for (r, range) in group.rounds.clone().into_iter().enumerate() {
            let mut ran = true;
            for i in range {
                match self.active[i] {
                    None => return Ok(None),
                    Some(false) => ran = false,
                    Some(true) if !self.done(i)? => return Ok(None),
                    Some(true) => {}
                }
            }
            if !ran {
                continue;
            }
            let round = r + 1;
            let rate = metric(
                &stop.report.replace("{round}", &round.to_string()).replace("{prev}", &r.to_string()),
                &stop.zone,
            )?;
            if rate > best.1 {
                best = (round, rate);
            }
        }
        tracing::info!(group = %group.name, round = best.0, rate = best.1, "keeps its best round");
        println!(
            "{}: keeps {} ({:.1} % in zone {})",
            group.name,
            if best.0 == 0 { "none of its rounds (the baseline)".to_string() } else { format!("round {}", best.0) },
            100.0 * best.1,
            stop.zone
        );
        self.kept.insert(g, best.0);
        Ok(Some(best.0))
    }

    /// Whether stage `a`, of a rounds group, is a round after the one its group keeps, so that
    /// stage `i` after the group neither restores what it wrote nor depends on it.
    fn left_behind(&self, a: usize, i: usize) -> bool {
        match (self.plan.stages[a].round, self.plan.stages[i].round) {
            (Some((g, _)), Some((h, _))) if g == h => false,
            (Some((g, r)), _) => self.kept.get(&g).is_some_and(|&k| r > k),
            _ => false,
        }
    }

    /// Keeps what stage `i` (settled) made for its current inputs (`recipe adopt`): a record
    /// that finished, or started (it goes on from its checkpoint), with another identity is given
    /// the current one, the old one kept in `adopted`. For a change that does not change what the
    /// stage makes (code tidied, a file moved), after checking it does. Returns the old identity
    /// where it changed it.
    pub fn adopt(&mut self, i: usize) -> Result<Option<String>> {
        let Some(id) = self.identity[i].clone() else { return Ok(None) };
        match self.store.record(&self.plan.stages[i].id)? {
            Some(mut r) if r.identity != id && matches!(r.status, Status::Done | Status::Started) => {
                let old = std::mem::replace(&mut r.identity, id);
                r.adopted.push(old.clone());
                self.store.put(&r)?;
                Ok(Some(old))
            }
            _ => Ok(None),
        }
    }

    /// Where stage `i` stands (after [`Runner::settle`]); `alive`: whether a Slurm job is still
    /// queued or running.
    pub fn standing(&self, i: usize, alive: &dyn Fn(u64) -> bool) -> Result<Standing> {
        match self.active[i] {
            Some(false) => return Ok(Standing::Stopped),
            None => return Ok(Standing::Undecided),
            Some(true) => {}
        }
        let id = self.identity[i].as_deref().expect("active stages have identities");
        Ok(match self.store.record(&self.plan.stages[i].id)? {
            Some(r) if r.identity == id => match r.status {
                Status::Done => Standing::Done,
                Status::Queued { job } if alive(job) => Standing::Queued(job),
                Status::Started if self.checkpoint(i).is_some() => Standing::Resume,
                _ => Standing::Run,
            },
            _ => Standing::Run,
        })
    }

    /// The last checkpoint stem in stage `i`'s run folder, if it resumes and has one.
    fn checkpoint(&self, i: usize) -> Option<PathBuf> {
        let dir = self.plan.stages[i].resume.as_ref()?.join("checkpoints");
        let mut stems: Vec<PathBuf> = std::fs::read_dir(&dir)
            .ok()?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "ron") && p.with_extension("safetensors").exists())
            .map(|p| p.with_extension(""))
            .collect();
        stems.sort();
        stems.pop()
    }

    /// The command line stage `i` runs, as a shell would take it.
    pub fn command(&self, i: usize) -> String {
        match &self.plan.stages[i].action {
            Action::Copy { from, to, only } if only.is_empty() => format!("copy {} {}", from.display(), to.display()),
            Action::Copy { from, to, only } => {
                format!("copy {}/{{{}}} {}", from.display(), only.join(","), to.display())
            }
            Action::Run { args } => {
                let mut s = String::from("repertoire");
                for a in args {
                    let _ = write!(s, " {}", shell_quote(a));
                }
                s
            }
        }
    }

    /// Runs stage `i` (settled, its round active): restores what the stages it follows left,
    /// clears what it writes of anything they did not leave (unless it resumes), runs it, keeps
    /// what it wrote and records it done. `ran`: `local` or `slurm job N`.
    pub fn run_stage(&mut self, i: usize, ran: &str) -> Result<()> {
        let stage = self.plan.stages[i].clone();
        let err = |message: String| RecipeError::Stage { stage: stage.id.clone(), message };
        if self.active[i] != Some(true) {
            return Err(err("its round does not run (the rounds before it stopped the group, or are not done)".into()));
        }
        let identity = self.identity[i].clone().expect("active stages have identities");
        let record = self.store.record(&stage.id)?;
        let resume = match &record {
            Some(r) if r.identity == identity && matches!(r.status, Status::Started | Status::Queued { .. }) => {
                self.checkpoint(i)
            }
            _ => None,
        };
        let mut expected = BTreeMap::new();
        for a in self.plan.ancestors(i) {
            if self.active[a] != Some(true) || self.left_behind(a, i) {
                continue;
            }
            let want = self.identity[a].as_deref().expect("settled");
            match self.store.record(&self.plan.stages[a].id)? {
                Some(r) if r.identity == want && r.status == Status::Done => {
                    // What it wrote replaces what was there before it: a file it dropped from a
                    // folder it writes is not brought back.
                    let roots = &self.plan.stages[a].writes;
                    expected.retain(|f: &String, _| !roots.iter().any(|w| Path::new(f).starts_with(w)));
                    expected.extend(r.outputs)
                }
                _ => {
                    return Err(err(format!(
                        "it follows `{}`, which has not finished with its current inputs (run the recipe, or that stage, first)",
                        self.plan.stages[a].id
                    )));
                }
            }
        }
        let restored = self.store.restore(&expected)?;
        if restored > 0 {
            tracing::info!(stage = %stage.id, files = restored, "restored what the stages before it left");
        }
        if resume.is_none() {
            // A stage that starts over starts from an empty run folder (no checkpoints or
            // metrics of a run with other inputs).
            if let Some(dir) = stage.resume.as_ref().filter(|d| d.exists()) {
                std::fs::remove_dir_all(dir).map_err(io_err(dir, "cannot clear the run folder"))?;
            }
            for w in &stage.writes {
                for (_, f) in files_under(w)? {
                    if !expected.contains_key(&f.to_string_lossy().replace('\\', "/")) {
                        std::fs::remove_file(&f).map_err(io_err(&f, "cannot clear"))?;
                    }
                }
            }
        }
        let command = self.command(i);
        let mut rec = Record {
            id: stage.id.clone(),
            identity: identity.clone(),
            status: Status::Started,
            outputs: BTreeMap::new(),
            command: command.clone(),
            seconds: 0.0,
            ran: ran.to_string(),
            adopted: Vec::new(),
        };
        self.store.put(&rec)?;
        let t = Instant::now();
        println!(
            "── {}: {}{}",
            stage.id,
            command,
            resume.as_ref().map_or(String::new(), |s| format!(" (resuming from {})", s.display()))
        );
        tracing::info!(stage = %stage.id, identity = %identity, command = %command, "stage starts");
        match &stage.action {
            Action::Copy { from, to, only } if only.is_empty() => copy_tree(from, to)?,
            Action::Copy { from, to, only } => {
                if to.exists() {
                    std::fs::remove_dir_all(to).map_err(io_err(to, "cannot replace"))?;
                }
                for o in only {
                    copy_tree(&from.join(o), &to.join(o))?;
                }
            }
            Action::Run { args } => {
                let mut args = args.clone();
                if let Some(stem) = &resume {
                    args = resume_args(&args, stem);
                }
                let mut cmd = Command::new(&self.exe);
                cmd.args(&args).env(STAGE_ENV, format!("{}#{}", self.plan.file.display(), stage.id));
                let threads = stage.cpus.map(|c| c.to_string()).or_else(|| std::env::var("SLURM_CPUS_PER_TASK").ok());
                if let (Some(t), None) = (threads, std::env::var_os("RAYON_NUM_THREADS")) {
                    cmd.env("RAYON_NUM_THREADS", t);
                }
                let status = match &stage.stdout {
                    None => cmd.status().map_err(|e| err(format!("cannot start {}: {e}", self.exe.display())))?,
                    Some(file) => {
                        // The output on the terminal as it comes, and into the file whole at the end.
                        use std::io::{BufRead, Write};
                        let mut child = cmd
                            .stdout(std::process::Stdio::piped())
                            .spawn()
                            .map_err(|e| err(format!("cannot start {}: {e}", self.exe.display())))?;
                        let mut text = String::new();
                        for line in std::io::BufReader::new(child.stdout.take().expect("piped")).lines() {
                            let line = line.map_err(|e| err(format!("reading its output: {e}")))?;
                            println!("{line}");
                            let _ = std::io::stdout().flush();
                            text.push_str(&line);
                            text.push('\n');
                        }
                        let status = child.wait().map_err(|e| err(format!("waiting for it: {e}")))?;
                        if status.success() {
                            if let Some(parent) = file.parent().filter(|p| !p.as_os_str().is_empty()) {
                                std::fs::create_dir_all(parent).map_err(io_err(parent, "cannot create"))?;
                            }
                            let head = format!("`{command}`\n\n");
                            repertoire_files::write_atomic(file, (head + &text).as_bytes()).map_err(|e| {
                                RecipeError::Io {
                                    path: e.path.display().to_string(),
                                    message: e.action,
                                    source: e.source,
                                }
                            })?;
                        }
                        status
                    }
                };
                if !status.success() {
                    return Err(err(format!(
                        "`{command}` failed ({status}); run the recipe again to {}",
                        if stage.resume.is_some() { "go on from its last checkpoint" } else { "retry it" }
                    )));
                }
            }
        }
        for w in &stage.writes {
            if !w.exists() {
                return Err(err(format!("it finished but did not write {} (its `writes` says it does)", w.display())));
            }
        }
        rec.outputs = self.store.keep(&stage.writes)?;
        rec.status = Status::Done;
        rec.seconds = t.elapsed().as_secs_f64();
        self.store.put(&rec)?;
        tracing::info!(stage = %stage.id, seconds = rec.seconds, files = rec.outputs.len(), "stage done");
        println!("── {}: done in {:.1} s", stage.id, rec.seconds);
        Ok(())
    }

    /// Runs every stage that is not done, in order, on this machine.
    pub fn run_local(&mut self) -> Result<Summary> {
        let mut s = Summary::default();
        for i in 0..self.plan.stages.len() {
            self.settle(i)?;
            match self.active[i] {
                Some(false) => s.stopped += 1,
                None => unreachable!("rounds are decided before the next one when run in order"),
                Some(true) if self.done(i)? => {
                    s.skipped += 1;
                    println!(
                        "── {}: done before (identity {})",
                        self.plan.stages[i].id,
                        self.identity[i].as_deref().unwrap_or("")
                    );
                }
                Some(true) => {
                    self.run_stage(i, "local")?;
                    s.ran += 1;
                }
            }
        }
        Ok(s)
    }
}

/// How many stages a run ran, found done, and left out (stopped rounds).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Summary {
    /// Stages run.
    pub ran: usize,
    /// Stages already done.
    pub skipped: usize,
    /// Stages of rounds that did not run.
    pub stopped: usize,
}

/// `args` to go on from checkpoint `stem`: `--resume STEM` added, and for `meta train` the
/// options a resumed run takes from its checkpoint (and refuses beside `--resume`) left out.
pub fn resume_args(args: &[String], stem: &Path) -> Vec<String> {
    let meta_train = args.len() >= 2 && args[0] == "meta" && args[1] == "train";
    let mut out = Vec::new();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let flag = a.split('=').next().unwrap_or(a);
        if meta_train && ["--warm-start", "--replace", "--learning-rate", "--critic-warmup"].contains(&flag) {
            if !a.contains('=') {
                it.next();
            }
            continue;
        }
        out.push(a.clone());
    }
    out.push("--resume".into());
    out.push(stem.display().to_string());
    out
}

/// The success rate of `zone` in a `meta eval` report (`report.json`).
fn metric(path: &str, zone: &str) -> Result<f64> {
    let p = Path::new(path);
    let text = std::fs::read_to_string(p).map_err(io_err(p, "cannot read the report the stopping rule compares"))?;
    let v: serde_json::Value = serde_json::from_str(&text).map_err(|e| RecipeError::Invalid {
        path: path.to_string(),
        message: format!("not a meta eval report: {e}"),
    })?;
    let zones = v.get("zones").and_then(|z| z.as_array()).ok_or_else(|| RecipeError::Invalid {
        path: path.to_string(),
        message: "not a meta eval report (no `zones`)".into(),
    })?;
    zones
        .iter()
        .find(|z| z.get("zone").and_then(|n| n.as_str()) == Some(zone))
        .and_then(|z| z.get("success_rate").and_then(|s| s.as_f64()))
        .ok_or_else(|| RecipeError::Invalid {
            path: path.to_string(),
            message: format!(
                "no success rate for zone `{zone}` (zones: {})",
                zones.iter().filter_map(|z| z.get("zone").and_then(|n| n.as_str())).collect::<Vec<_>>().join(", ")
            ),
        })
}

/// Copies a file or folder `from` onto `to` (a folder is replaced whole).
fn copy_tree(from: &Path, to: &Path) -> Result<()> {
    if from.is_file() {
        if let Some(parent) = to.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).map_err(io_err(parent, "cannot create"))?;
        }
        let tmp = repertoire_files::temp_sibling(to);
        std::fs::copy(from, &tmp).map_err(io_err(from, "cannot copy"))?;
        return repertoire_files::commit(&tmp, to).map_err(|e| RecipeError::Io {
            path: e.path.display().to_string(),
            message: e.action,
            source: e.source,
        });
    }
    if !from.is_dir() {
        return Err(RecipeError::Io {
            path: from.display().to_string(),
            message: "cannot copy",
            source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such file or folder"),
        });
    }
    if to.exists() {
        std::fs::remove_dir_all(to).map_err(io_err(to, "cannot replace"))?;
    }
    for (rel, file) in files_under(from)? {
        let dest = to.join(&rel);
        let parent = dest.parent().expect("inside `to`");
        std::fs::create_dir_all(parent).map_err(io_err(parent, "cannot create"))?;
        std::fs::copy(&file, &dest).map_err(io_err(&file, "cannot copy"))?;
    }
    std::fs::create_dir_all(to).map_err(io_err(to, "cannot create"))
}

/// `s` quoted for a POSIX shell where it needs it.
pub fn shell_quote(s: &str) -> String {
    if !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || "-_./,:=+@%".contains(c)) {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', "'\\''"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_resumed_meta_train_leaves_out_what_its_checkpoint_holds() {
        let args: Vec<String> =
            ["meta", "train", "s.ron", "--warm-start", "lib/meta", "--learning-rate=1e-4", "--seed", "2"]
                .map(String::from)
                .into();
        let got = resume_args(&args, Path::new("r/checkpoints/iter-000100"));
        assert_eq!(got, ["meta", "train", "s.ron", "--seed", "2", "--resume", "r/checkpoints/iter-000100"]);
        let args: Vec<String> = ["skill", "train", "x.ron", "--learning-rate", "1e-4"].map(String::from).into();
        assert_eq!(resume_args(&args, Path::new("c")).len(), 7, "skill train keeps its flags");
    }
}

#[cfg(test)]
mod round_tests {
    use super::*;

    /// A recipe whose commands are shell lines (the runner runs any program): a baseline report,
    /// then rounds that each write a report with the next success rate of `rates` and append
    /// to a file the next stage reads.
    fn recipe(dir: &Path, rates: &str, tag: &str) -> PathBuf {
        let work = dir.join("work");
        let text = format!(
            r#"(work: "{work}", vars: {{"rates": "{rates}", "tag": "{tag}"}}, stages: [
                Run(name: "base", args: ["-c", "mkdir -p {{work}}/ev-0 && echo '{{\"zones\":[{{\"zone\":\"all\",\"success_rate\":0.4}}]}}' > {{work}}/ev-0/report.json"],
                    writes: ["{{work}}/ev-0"]),
                Rounds(name: "loop", max: 4, stop: (report: "{{work}}/ev-{{round}}/report.json", gain_below: 1.0, baseline: "{{work}}/ev-0/report.json"), stages: [
                    Run(name: "grow", args: ["-c", "mkdir -p {{work}}/lib && echo {{round}}{{tag}} >> {{work}}/lib/log"], writes: ["{{work}}/lib"]),
                    Run(name: "eval", args: ["-c", "mkdir -p {{work}}/ev-{{round}} && r=$(echo {{rates}} | cut -d, -f{{round}}) && echo '{{\"zones\":[{{\"zone\":\"all\",\"success_rate\":'$r'}}]}}' > {{work}}/ev-{{round}}/report.json"],
                        writes: ["{{work}}/ev-{{round}}"], after: ["grow"]),
                ]),
            ])"#,
            work = work.display()
        );
        let path = dir.join("r.ron");
        std::fs::write(&path, text).unwrap();
        path
    }

    fn temp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("recipe-unit-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn rounds_stop_when_a_round_gains_under_the_rule_and_reruns_skip_what_is_done() {
        let dir = temp("stop");
        let run = |rates: &str, tag: &str| {
            let plan = Plan::load(&recipe(&dir, rates, tag), None).unwrap();
            Runner::new(&plan, PathBuf::from("/bin/sh")).run_local().unwrap()
        };
        let log = || std::fs::read_to_string(dir.join("work/lib/log")).unwrap();
        // base, rounds 1-3 (round 3 gains half a point: the group stops), round 4 left out.
        assert_eq!(run("0.5,0.6,0.605,0.9", "a"), Summary { ran: 1 + 3 * 2, skipped: 0, stopped: 2 });
        assert_eq!(log(), "1a\n2a\n3a\n");
        assert!(!dir.join("work/ev-4").exists());
        assert_eq!(run("0.5,0.6,0.605,0.9", "a"), Summary { ran: 0, skipped: 7, stopped: 2 });

        // A changed input of the rounds' first stage reruns every round from what the round
        // before left (the library as round 1 made it, not as the last run left it).
        assert_eq!(run("0.5,0.6,0.605,0.9", "b"), Summary { ran: 3 * 2, skipped: 1, stopped: 2 });
        assert_eq!(log(), "1b\n2b\n3b\n");

        // Other rates rerun only the evaluations; round 3 now gains 10 points, so round 4 runs,
        // from what round 3 left.
        assert_eq!(run("0.5,0.6,0.7,0.705", "b"), Summary { ran: 3 + 2, skipped: 1 + 3, stopped: 0 });
        assert_eq!(log(), "1b\n2b\n3b\n4b\n");
    }

    #[test]
    fn adopting_keeps_what_the_stages_made_for_their_changed_inputs() {
        let dir = temp("adopt");
        let run = |tag: &str| {
            let plan = Plan::load(&recipe(&dir, "0.5,0.6,0.605,0.9", tag), None).unwrap();
            Runner::new(&plan, PathBuf::from("/bin/sh")).run_local().unwrap()
        };
        assert_eq!(run("a").ran, 7);
        // The changed tag changes the rounds' identities; adopting them keeps what they made.
        let plan = Plan::load(&recipe(&dir, "0.5,0.6,0.605,0.9", "b"), None).unwrap();
        let mut r = Runner::new(&plan, PathBuf::from("/bin/sh"));
        let mut adopted = Vec::new();
        for i in 0..plan.stages.len() {
            r.settle(i).unwrap();
            if let Some(old) = r.adopt(i).unwrap() {
                adopted.push((plan.stages[i].id.clone(), old));
            }
        }
        let ids: Vec<_> = adopted.iter().map(|(s, _)| s.as_str()).collect();
        assert_eq!(
            ids,
            ["loop/r1/grow", "loop/r1/eval", "loop/r2/grow", "loop/r2/eval", "loop/r3/grow", "loop/r3/eval"]
        );
        let rec = r.store.record("loop/r2/grow").unwrap().unwrap();
        assert_eq!(rec.adopted, [adopted[2].1.clone()]);
        assert_eq!(Some(rec.identity.as_str()), r.identity(3));
        assert_eq!(run("b"), Summary { ran: 0, skipped: 7, stopped: 2 });
        assert_eq!(std::fs::read_to_string(dir.join("work/lib/log")).unwrap(), "1a\n2a\n3a\n");
        assert_eq!(run("c").ran, 6, "a stage not adopted runs again");
    }

    /// Seeds of one training as rounds (each writes `lib/seed` afresh), the best kept by its
    /// report, and a stage after the group that reads `lib/seed`.
    fn best_of(dir: &Path, rates: &str, baseline: &str) -> PathBuf {
        let work = dir.join("work");
        let text = format!(
            r#"(work: "{work}", vars: {{"rates": "{rates}"}}, stages: [
                Run(name: "base", args: ["-c", "mkdir -p {{work}}/ev-0 && echo '{{\"zones\":[{{\"zone\":\"all\",\"success_rate\":{baseline}}}]}}' > {{work}}/ev-0/report.json && mkdir -p {{work}}/lib && echo 0 > {{work}}/lib/seed"],
                    writes: ["{{work}}/ev-0", "{{work}}/lib"]),
                Rounds(name: "seeds", max: 3, stop: (report: "{{work}}/ev-{{round}}/report.json", keep: Best, baseline: "{{work}}/ev-0/report.json"), stages: [
                    Run(name: "train", args: ["-c", "echo {{round}} > {{work}}/lib/seed"], writes: ["{{work}}/lib"]),
                    Run(name: "eval", args: ["-c", "mkdir -p {{work}}/ev-{{round}} && r=$(echo {{rates}} | cut -d, -f{{round}}) && echo '{{\"zones\":[{{\"zone\":\"all\",\"success_rate\":'$r'}}]}}' > {{work}}/ev-{{round}}/report.json"],
                        writes: ["{{work}}/ev-{{round}}"], after: ["train"]),
                ]),
                Run(name: "after", args: ["-c", "cp $0 {{work}}/used", "{{work}}/lib/seed"], writes: ["{{work}}/used"]),
            ])"#,
            work = work.display()
        );
        let path = dir.join("r.ron");
        std::fs::write(&path, text).unwrap();
        path
    }

    #[test]
    fn a_group_that_keeps_its_best_round_runs_every_round_and_builds_on_the_best() {
        let dir = temp("best");
        let run = |rates: &str, baseline: &str| {
            let plan = Plan::load(&best_of(&dir, rates, baseline), None).unwrap();
            Runner::new(&plan, PathBuf::from("/bin/sh")).run_local().unwrap()
        };
        let used = || std::fs::read_to_string(dir.join("work/used")).unwrap();
        // Every round runs (no gain rule); round 2 is the best, so `after` reads its output,
        // though round 3 wrote the library last.
        assert_eq!(run("0.5,0.7,0.6", "0.4"), Summary { ran: 1 + 3 * 2 + 1, skipped: 0, stopped: 0 });
        assert_eq!(used(), "2\n");
        assert_eq!(run("0.5,0.7,0.6", "0.4"), Summary { ran: 0, skipped: 8, stopped: 0 });
        // Other evaluations (they run again) make round 3 the best: what comes after runs
        // again, over round 3's output; the trainings are not rerun.
        assert_eq!(run("0.5,0.7,0.8", "0.4"), Summary { ran: 3 + 1, skipped: 1 + 3, stopped: 0 });
        assert_eq!(used(), "3\n");
        // A baseline at least as good as every round (the first stage changes, so everything
        // runs again): what comes after sees what the group started from.
        assert_eq!(run("0.5,0.7,0.8", "0.8").ran, 8);
        assert_eq!(used(), "0\n");
    }

    #[test]
    fn a_rule_that_neither_stops_nor_keeps_the_best_is_refused() {
        let dir = temp("norule");
        let text = format!(
            r#"(work: "{}/w", stages: [Rounds(name: "g", max: 2, stop: (report: "{{work}}/r-{{round}}.json"), stages: [
                Run(name: "a", args: ["-c", "true"])])])"#,
            dir.display()
        );
        std::fs::write(dir.join("r.ron"), text).unwrap();
        let e = Plan::load(&dir.join("r.ron"), None).unwrap_err().to_string();
        assert!(e.contains("rounds `g`") && e.contains("gain_below") && e.contains("keep: Best"), "{e}");
    }

    #[test]
    fn a_failed_stage_is_recorded_started_and_later_stages_refuse_to_run_without_it() {
        let dir = temp("fail");
        let work = dir.join("work");
        let text = format!(
            r#"(work: "{}", stages: [
                Run(name: "a", args: ["-c", "mkdir -p {{work}}/a && echo x > {{work}}/a/f && exit 3"], writes: ["{{work}}/a"]),
                Run(name: "b", args: ["-c", "cat {{work}}/a/f > {{work}}/b"], writes: ["{{work}}/b"], after: ["a"]),
            ])"#,
            work.display()
        );
        let file = dir.join("r.ron");
        std::fs::write(&file, text).unwrap();
        let plan = Plan::load(&file, None).unwrap();
        let mut r = Runner::new(&plan, PathBuf::from("/bin/sh"));
        let e = r.run_local().unwrap_err().to_string();
        assert!(e.contains("stage `a`") && e.contains("failed"), "{e}");
        assert_eq!(r.store.record("a").unwrap().unwrap().status, Status::Started);
        let mut r = Runner::new(&plan, PathBuf::from("/bin/sh"));
        r.settle_all().unwrap();
        let e = r.run_stage(1, "local").unwrap_err().to_string();
        assert!(e.contains("follows `a`, which has not finished"), "{e}");
        assert!(!work.join("b").exists());
    }
}

#[cfg(test)]
mod copy_tests {
    use super::*;

    #[test]
    fn a_copy_of_some_entries_sees_only_them() {
        let dir = std::env::temp_dir().join(format!("recipe-unit-{}-only", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        for f in ["lib/a/x", "lib/b/y", "lib/meta/eval/report.json"] {
            std::fs::create_dir_all(dir.join(f).parent().unwrap()).unwrap();
            std::fs::write(dir.join(f), f).unwrap();
        }
        let text = format!(
            r#"(work: "{0}/work", stages: [Copy(name: "lib", from: "{0}/lib", to: "{{work}}/lib", only: ["a", "b"])])"#,
            dir.display()
        );
        std::fs::write(dir.join("r.ron"), text).unwrap();
        let plan = Plan::load(&dir.join("r.ron"), None).unwrap();
        let mut r = Runner::new(&plan, PathBuf::from("/bin/true"));
        assert_eq!(r.run_local().unwrap().ran, 1);
        assert!(dir.join("work/lib/a/x").exists() && dir.join("work/lib/b/y").exists());
        assert!(!dir.join("work/lib/meta").exists());
        // What else changes in the library does not change the copy's identity.
        std::fs::write(dir.join("lib/meta/eval/report.json"), "new").unwrap();
        assert_eq!(Runner::new(&plan, PathBuf::from("/bin/true")).run_local().unwrap().skipped, 1);
        std::fs::write(dir.join("lib/a/x"), "new").unwrap();
        assert_eq!(Runner::new(&plan, PathBuf::from("/bin/true")).run_local().unwrap().ran, 1);
        assert_eq!(std::fs::read_to_string(dir.join("work/lib/a/x")).unwrap(), "new");
    }
}
