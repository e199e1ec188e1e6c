//! `repertoire replay RUN_OR_FILE -o out.html` and `repertoire export FILE --bvh/--npy`.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Args;
use repertoire_scenes::Recording;
use repertoire_scenes::replay::{WEB_DIR, three_build_dir, write_html};

#[derive(Debug, Args)]
pub struct ReplayArgs {
    /// A recording (`.rec`), or a folder holding some (an eval folder's `worst/` is searched too).
    pub input: PathBuf,
    /// The HTML page to write (default: beside the recording, `.html`); for a folder, a folder.
    #[arg(short, long)]
    pub out: Option<PathBuf>,
    /// The folder holding node_modules/three (default: scenes/web, installed by scripts/setup.sh).
    #[arg(long)]
    pub web: Option<PathBuf>,
}

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

/// The web folder: `--web`, else `$REPERTOIRE_WEB`, else `scenes/web` in the working
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
    for d in [dir.to_path_buf(), dir.join("worst")] {
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
    let out = args.out.unwrap_or_else(|| args.input.with_extension("html"));
    let size = replay_file(&args.input, &out, &web)?;
    println!("replay page written to {} ({:.1} MB); open it in a browser", out.display(), size as f64 / 1e6);
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
