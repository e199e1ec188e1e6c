//! `repertoire replay RUN_OR_FILE -o out.html`, `repertoire export FILE --bvh/--npy` and
//! `repertoire fall-check FILE --scenario S`.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;
use repertoire_scenes::replay::{WEB_DIR, three_build_dir, write_html};
use repertoire_scenes::{Recording, World, WorldModel};
use std::sync::Arc;

#[derive(Debug, Args)]
pub struct ReplayArgs {
    /// A recording (`.rec`), or a folder holding some (an eval folder's `worst/`, `successes/`
    /// and `random/` are searched too).
    pub input: PathBuf,
    /// The HTML page to write (default: beside the recording, `.html`); for a folder, a folder.
    #[arg(short, long)]
    pub out: Option<PathBuf>,
    /// The folder holding node_modules/three (default: crates/scenes/web, installed by scripts/setup.sh).
    #[arg(long)]
    pub web: Option<PathBuf>,
    /// Also render a contact sheet of the recording into this PNG: --frames evenly spaced
    /// frames from --view, captioned with time and skill (headless Chromium on the replay page).
    #[arg(long)]
    pub filmstrip: Option<PathBuf>,
    /// Frames in the filmstrip.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(1..=64), requires = "filmstrip")]
    pub frames: u32,
    /// Where the filmstrip looks from, around the pelvis of each frame: the character's right
    /// side, its front or from above (set from its heading at the first frame).
    #[arg(long, value_enum, default_value_t = View::Side, requires = "filmstrip")]
    pub view: View,
    /// Frames per row of the filmstrip.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..), requires = "filmstrip")]
    pub columns: u32,
}

/// A filmstrip's camera.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum View {
    /// The character's right side.
    Side,
    /// Its front.
    Front,
    /// From above.
    Top,
}

/// Width and height of one filmstrip frame (pixels).
const TILE: (u32, u32) = (480, 360);

#[derive(Debug, Args)]
pub struct ExportArgs {
    /// A recording (`.rec`).
    pub input: PathBuf,
    /// Write the character's motion as BVH (y-up, metres, frame time 1/control rate).
    #[arg(long)]
    pub bvh: Option<PathBuf>,
    /// Write qpos per frame as NumPy float64 `frames × nq`.
    #[arg(long)]
    pub npy: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct FallCheckArgs {
    /// Recordings (`.rec`), or folders holding some (an eval folder's `worst/` is searched too).
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// The scenario the recordings were made in (default: the built-in scenarios/sit.ron; a skill's
    /// recordings: its spec's `scene`, e.g. specs/arena.ron).
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// With one recording: write its last S seconds to --cut-out (a test fixture of a fall).
    #[arg(long, requires = "cut_out")]
    pub last_s: Option<f64>,
    /// Where --last-s writes the cut recording.
    #[arg(long, requires = "last_s")]
    pub cut_out: Option<PathBuf>,
}

/// The web folder: `--web`, else `$REPERTOIRE_WEB`, else `crates/scenes/web` in the working
/// directory, else the one in the source tree this binary was built from.
pub fn web_dir(arg: Option<&Path>) -> PathBuf {
    if let Some(p) = arg {
        return p.to_path_buf();
    }
    if let Some(p) = std::env::var_os("REPERTOIRE_WEB") {
        return PathBuf::from(p);
    }
    let local = PathBuf::from(WEB_DIR);
    if three_build_dir(&local).exists() {
        return local;
    }
    Path::new(env!("CARGO_MANIFEST_DIR")).join(WEB_DIR)
}

/// Writes the replay page of the recording at `input` to `out`; returns its size in bytes.
pub fn replay_file(input: &Path, out: &Path, web: &Path) -> Result<u64> {
    let rec = Recording::load(input)?;
    write_html(&rec, &three_build_dir(web), out)?;
    Ok(std::fs::metadata(out).with_context(|| format!("{}: cannot read back", out.display()))?.len())
}

fn recordings_in(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut found = Vec::new();
    for d in [dir.to_path_buf(), dir.join("worst"), dir.join("successes"), dir.join("random")] {
        let Ok(entries) = std::fs::read_dir(&d) else { continue };
        for e in entries {
            let p = e.with_context(|| format!("{}: cannot list", d.display()))?.path();
            if p.extension().is_some_and(|x| x == "rec") {
                found.push(p);
            }
        }
    }
    found.sort();
    Ok(found)
}

pub fn replay(args: ReplayArgs) -> Result<()> {
    let web = web_dir(args.web.as_deref());
    if args.input.is_dir() {
        let recs = recordings_in(&args.input)?;
        if recs.is_empty() {
            bail!("{}: no recordings (.rec) in it or in its worst/ folder", args.input.display());
        }
        if let Some(out) = &args.out {
            std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
        }
        for rec in recs {
            let out = match &args.out {
                Some(dir) => dir.join(rec.with_extension("html").file_name().expect("a file")),
                None => rec.with_extension("html"),
            };
            let size = replay_file(&rec, &out, &web)?;
            println!("{} → {} ({:.1} MB)", rec.display(), out.display(), size as f64 / 1e6);
        }
        return Ok(());
    }
    let out = args.out.clone().unwrap_or_else(|| args.input.with_extension("html"));
    let size = replay_file(&args.input, &out, &web)?;
    println!("replay page written to {} ({:.1} MB); open it in a browser", out.display(), size as f64 / 1e6);
    if let Some(png) = &args.filmstrip {
        filmstrip(&out, png, &web, &args)?;
        println!("filmstrip of {} frames ({:?} view) written to {}", args.frames, args.view, png.display());
    }
    Ok(())
}

/// Renders the contact sheet of the replay page `page` into `png` through
/// `<web>/filmstrip.mjs` (node, playwright-core and Chromium, as the browser test uses).
fn filmstrip(page: &Path, png: &Path, web: &Path, args: &ReplayArgs) -> Result<()> {
    let script = web.join("filmstrip.mjs");
    if !script.exists() {
        bail!("{} is missing: the filmstrip is drawn by it (crates/scenes/web/filmstrip.mjs)", script.display());
    }
    if let Some(dir) = png.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    }
    let view = format!("{:?}", args.view).to_lowercase();
    let numbers = |ns: &[u32]| ns.iter().map(u32::to_string).collect::<Vec<_>>();
    let out = std::process::Command::new("node")
        .arg(&script)
        .args([page, png])
        .args(numbers(&[args.frames]))
        .arg(&view)
        .args(numbers(&[args.columns, TILE.0, TILE.1]))
        .output();
    let out = out.with_context(|| "running node (Node 18 or newer; scripts/setup.sh installs the rest)")?;
    if !out.status.success() {
        bail!(
            "the filmstrip of {} could not be drawn: {}",
            page.display(),
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    Ok(())
}

pub fn export(args: ExportArgs) -> Result<()> {
    if args.bvh.is_none() && args.npy.is_none() {
        bail!("nothing to export: give --bvh FILE and/or --npy FILE");
    }
    let rec = Recording::load(&args.input)?;
    if let Some(path) = &args.bvh {
        let notes = repertoire_clip::export::write_bvh(&rec, path)?;
        for n in notes {
            println!("note: {n}");
        }
        println!("{}: {} frames at {} Hz as BVH", path.display(), rec.frames(), rec.header.control_hz);
    }
    if let Some(path) = &args.npy {
        repertoire_clip::export::write_npy(&rec, path)?;
        println!("{}: qpos, float64 [{}, {}]", path.display(), rec.frames(), rec.header.nq);
    }
    Ok(())
}

/// Writes a replay page beside each recording when three.js is installed; otherwise says how
/// to get one. Returns the pages written.
pub fn pages_beside(recs: &[PathBuf]) -> Vec<PathBuf> {
    let web = web_dir(None);
    if !three_build_dir(&web).exists() {
        if !recs.is_empty() {
            println!(
                "(no replay pages: three.js is not installed in {}; run scripts/setup.sh, then `repertoire replay`)",
                web.display()
            );
        }
        return Vec::new();
    }
    let mut pages = Vec::new();
    for rec in recs {
        let page = rec.with_extension("html");
        match replay_file(rec, &page, &web) {
            Ok(_) => pages.push(page),
            Err(e) => println!("no replay page for {}: {e:#}", rec.display()),
        }
    }
    pages
}

/// The recordings named: files as given, folders searched (with their `worst/`).
fn recordings_of(inputs: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut recs = Vec::new();
    for input in inputs {
        if input.is_dir() {
            let found = recordings_in(input)?;
            if found.is_empty() {
                bail!("{}: no recordings (.rec) in it or in its worst/ folder", input.display());
            }
            recs.extend(found);
        } else {
            recs.push(input.clone());
        }
    }
    Ok(recs)
}

/// `repertoire fall-check`: each recording judged again by the scenario's fall test, beside
/// what was recorded when it was made.
pub fn fall_check(args: FallCheckArgs) -> Result<()> {
    let scenario = super::load_scenario(args.scenario.as_ref())?;
    let name = scenario.path.display().to_string();
    let model = Arc::new(WorldModel::build(scenario)?);
    let mut world = World::new(Arc::clone(&model));
    let recs = recordings_of(&args.inputs)?;
    if args.last_s.is_some() && recs.len() != 1 {
        bail!("--last-s cuts one recording; {} were named", recs.len());
    }
    let body = |b: usize| model.mj_model().id_to_name(mujoco_rs::prelude::MjtObjBase::mjOBJ_BODY, b).unwrap_or("?");
    println!("fall test of {name}: {:?}", model.fall_rule());
    println!("| recording | frames | recorded | fall test now | cause | part | prop |");
    println!("|---|---:|---|---|---|---|---|");
    let (mut recorded_falls, mut falls) = (0, 0);
    for path in &recs {
        let rec = Recording::load(path)?;
        let verdicts = world.judge(&rec).with_context(|| format!("{}: cannot judge it", path.display()))?;
        let at = |f: usize| format!("frame {f} ({:.2} s)", rec.time[f]);
        let recorded = rec.first_fall().map_or("no fall".to_string(), |(f, c)| format!("{}, {}", at(f), c.name()));
        let now = verdicts.iter().position(Option::is_some);
        recorded_falls += usize::from(rec.first_fall().is_some());
        falls += usize::from(now.is_some());
        match now.and_then(|f| verdicts[f].map(|v| (f, v))) {
            Some((f, v)) => println!(
                "| {} | {} | {recorded} | {} | {} | {} | {} |",
                path.display(),
                rec.frames(),
                at(f),
                v.cause.name(),
                body(v.body),
                v.prop.map_or("—".to_string(), |p| model.props[p].name.clone())
            ),
            None => println!("| {} | {} | {recorded} | no fall | — | — | — |", path.display(), rec.frames()),
        }
        if let (Some(s), Some(out)) = (args.last_s, &args.cut_out) {
            if !(s.is_finite() && s > 0.0) {
                bail!("--last-s must be a positive number of seconds (got {s})");
            }
            let keep = ((s * rec.header.control_hz).round() as usize).clamp(1, rec.frames());
            let cut = rec.frames_from(rec.frames() - keep);
            cut.save(out)?;
            println!("the last {keep} frames written to {}", out.display());
        }
    }
    println!("{falls} of {} recordings fall by the fall test now ({recorded_falls} as recorded)", recs.len());
    Ok(())
}
