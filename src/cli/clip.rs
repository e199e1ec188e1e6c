//! `repertoire clip check FILE --body B [--map M] [--out OUT] [--fps F]`.

use anyhow::{Context, Result, bail};
use clap::Subcommand;
use repertoire_clip::{ClipBody, ClipSource, LoadedMap, RetargetOptions};
use std::path::PathBuf;

#[derive(Debug, Subcommand)]
pub enum ClipCommand {
    /// Import a clip, retarget it onto a body, report how well it fits, and write it.
    Check {
        /// The clip: .bvh, .amc (with --asf, or SUBJECT.asf beside it), .asf (with --amc),
        /// DeepMimic .txt/.json, or a keyframe .ron.
        file: PathBuf,
        /// The body: `humanoid` (built in), an MJCF file NAME.xml with NAME.map.ron beside it,
        /// or a body map NAME.map.ron with NAME.xml beside it.
        #[arg(long, default_value = "humanoid")]
        body: String,
        /// Retarget map (default: the shipped map whose joints the file has).
        #[arg(long)]
        map: Option<PathBuf>,
        /// The ASF skeleton of an AMC file.
        #[arg(long)]
        asf: Option<PathBuf>,
        /// The AMC motion of an ASF file.
        #[arg(long)]
        amc: Option<PathBuf>,
        /// Where to write the clip (.ron, or .npy + .meta.ron); default `<stem>.clip.ron` in
        /// the current directory.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Resample the written clip to this frame rate.
        #[arg(long)]
        fps: Option<f64>,
    },
}

pub fn run(cmd: ClipCommand) -> Result<()> {
    match cmd {
        ClipCommand::Check { file, body, map, asf, amc, out, fps } => check(file, &body, map, asf.or(amc), out, fps),
    }
}

fn check(
    file: PathBuf,
    body: &str,
    map: Option<PathBuf>,
    partner: Option<PathBuf>,
    out: Option<PathBuf>,
    fps: Option<f64>,
) -> Result<()> {
    let source = ClipSource::from_path(&file, partner.as_deref())?;
    let body = ClipBody::from_arg(body)?;
    let map = map.map(|m| LoadedMap::load(&m)).transpose()?;
    let report = repertoire_clip::check(&source, &body, map, fps, &RetargetOptions::default())
        .with_context(|| format!("{}: unusable clip", file.display()))?;
    let m = &report.motion;

    println!("clip      {}", report.source.display());
    println!("body      {} (hash {})", body.origin().display(), body.hash());
    match &report.map {
        Some(name) => println!("map       {name}"),
        None => println!("map       none (keyframes)"),
    }
    println!("frames    {} at {:.2} fps, duration {:.2} s", m.frames, m.fps, m.duration_s);
    if !report.points.is_empty() {
        println!("key point error (cm; vs the source pose re-proportioned to the body)");
        println!("  {:<16} {:<18} {:>7} {:>7}", "role", "body point", "mean", "max");
        for p in &report.points {
            println!("  {:<16} {:<18} {:>7.2} {:>7.2}", p.role.name(), p.target, p.mean_cm, p.max_cm);
        }
    }
    if let Some((mean, max)) = report.error_cm {
        println!("  {:<16} {:<18} {:>7.2} {:>7.2}", "all", "", mean, max);
    }
    println!("foot penetration   {:.2} cm (max below floor)", m.foot_penetration_cm);
    println!(
        "foot skate         {:.1} cm/s (feet within {:.1} cm of the floor)",
        m.foot_skate_cm_s,
        100.0 * repertoire_clip::check::CONTACT_HEIGHT
    );
    println!("root drift         {:.2} m", m.root_drift_m);
    println!("heading change     {:+.1}° (left turn positive)", m.heading_change_deg);
    if report.retarget_seconds > 0.0 {
        println!("retarget           {:.3} s, {:.0} frames/s", report.retarget_seconds, report.frames_per_second);
    }
    let out = match out {
        Some(p) => p,
        None => {
            let stem = file.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "clip".into());
            PathBuf::from(format!("{stem}.clip.ron"))
        }
    };
    if out.as_os_str().is_empty() {
        bail!("--out is empty");
    }
    report.clip.save(&out)?;
    println!("wrote     {} (hash {})", out.display(), report.clip.content_hash());
    Ok(())
}
