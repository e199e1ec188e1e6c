//! `repertoire clip check FILE --body B [--map M] [--out OUT] [--fps F]` and
//! `repertoire clip play FILE --record OUT.rec [--html OUT.html]`.

use anyhow::{Context, Result, bail};
use clap::Subcommand;
use repertoire_clip::{ClipBody, ClipSource, LoadedMap, RetargetOptions};
use repertoire_scenes::{Annotation, RecordOptions, Recorder, WorldModel};
use std::path::{Path, PathBuf};
use std::sync::Arc;

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
    /// Play a clip kinematically on the scenario's body (no physics) and record it, for
    /// `repertoire replay` and `repertoire export`.
    Play {
        /// Any clip the project reads: mocap (BVH, ASF/AMC, DeepMimic), a keyframe .ron, or a
        /// retargeted .clip.ron / .npy.
        file: PathBuf,
        /// Retarget map for mocap (default: the shipped map whose joints the file has).
        #[arg(long)]
        map: Option<PathBuf>,
        /// Scenario whose body it plays on (default: the built-in scenarios/sit.ron).
        #[arg(long)]
        scene: Option<PathBuf>,
        /// Keep the scenario's props at their nominal places (by default the clip plays alone).
        #[arg(long)]
        props: bool,
        /// Where the recording goes.
        #[arg(long)]
        record: PathBuf,
        /// Also write the replay page here.
        #[arg(long)]
        html: Option<PathBuf>,
    },
}

pub fn run(cmd: ClipCommand) -> Result<()> {
    match cmd {
        ClipCommand::Check { file, body, map, asf, amc, out, fps } => check(file, &body, map, asf.or(amc), out, fps),
        ClipCommand::Play { file, map, scene, props, record, html } => {
            play(&file, map.as_deref(), scene.as_ref(), props, &record, html)
        }
    }
}

/// Mean key-point retarget error (cm) above which `clip check` warns that the map fits the
/// skeleton poorly (the shipped clips retarget at 1–4 cm).
const POOR_FIT_CM: f64 = 5.0;
/// Mean error of one key point over which `clip check` names it (cm).
const POOR_POINT_CM: f64 = 8.0;

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
    if !report.fits.is_empty() {
        let each: Vec<String> = report.fits.iter().map(|(name, cm)| format!("{name} {cm:.2} cm")).collect();
        println!(
            "          chosen by fit: mean key-point error over the first {:.0} s with each shipped map that takes this skeleton: {}",
            repertoire_clip::check::FIT_SECONDS,
            each.join(", ")
        );
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
        let off: Vec<String> = report
            .points
            .iter()
            .filter(|p| p.mean_cm > POOR_POINT_CM)
            .map(|p| format!("{} {:.1} cm", p.role.name(), p.mean_cm))
            .collect();
        if !off.is_empty() && mean <= POOR_FIT_CM {
            println!(
                "warning   {} land{} over {POOR_POINT_CM:.0} cm from where the source puts {}: {} (check the map's source joints and offsets for {})",
                if off.len() == 1 { "one key point" } else { "key points" },
                if off.len() == 1 { "s" } else { "" },
                if off.len() == 1 { "it" } else { "them" },
                off.join(", "),
                if off.len() == 1 { "it" } else { "them" },
            );
        }
        if mean > POOR_FIT_CM {
            let others: Vec<&str> =
                report.fitting.iter().map(String::as_str).filter(|n| Some(*n) != report.map.as_deref()).collect();
            println!(
                "warning   the map fits this skeleton poorly (mean key-point error {mean:.1} cm, over {POOR_FIT_CM:.0} cm): \
                 poses land off where the source put them; {}",
                if others.is_empty() {
                    "no other shipped map takes this skeleton: write a map for it (--map, docs/cli.md)".to_string()
                } else {
                    format!("other shipped maps that take it: {} (--map)", others.join(", "))
                }
            );
        }
    }
    println!("foot penetration   {:.2} cm (max below floor)", m.foot_penetration_cm);
    println!(
        "foot skate         {:.1} cm/s (feet within {:.1} cm of the floor)",
        m.foot_skate_cm_s,
        100.0 * repertoire_clip::check::CONTACT_HEIGHT
    );
    println!("root drift         {:.2} m", m.root_drift_m);
    println!("heading change     {:+.1}° (left turn positive)", m.heading_change_deg);
    let (pitch, low, high) = m.pelvis_pitch_deg;
    println!("pelvis pitch       {pitch:+.1}° mean, {low:+.1}° to {high:+.1}° (forward positive)");
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

fn play(
    file: &Path,
    map: Option<&Path>,
    scene: Option<&PathBuf>,
    props: bool,
    record: &Path,
    html: Option<PathBuf>,
) -> Result<()> {
    let mut scenario = super::load_scenario(scene)?;
    if !props {
        scenario.scenario.props.clear();
        scenario.scenario.spawn.clear();
    }
    let model = Arc::new(WorldModel::build(scenario)?);
    let body = ClipBody::new(model.body.clone())?;
    let clip =
        repertoire_skill::load_clip(file, map, &body).with_context(|| format!("{}: unusable clip", file.display()))?;
    let hz = 1.0 / model.control_dt();
    let clip = clip.resampled(hz)?;
    let mut world = model.new_world();
    let options = RecordOptions {
        title: format!("clip {} (kinematic playback of {})", clip.name, file.display()),
        phase: "clip frame".into(),
        capacity: clip.frame_count(),
        ..Default::default()
    };
    let mut rec = Recorder::new(&model, options);
    let idx = &body.index;
    let mut joints = vec![0.0; idx.joints.len()];
    for f in 0..clip.frame_count() {
        let q = clip.frame(f).expect("a frame in range");
        let r = idx.root_qpos;
        for (a, j) in joints.iter_mut().zip(&idx.joints) {
            *a = q[j.qpos];
        }
        world.set_motion(
            [q[r], q[r + 1], q[r + 2]],
            [q[r + 3], q[r + 4], q[r + 5], q[r + 6]],
            &joints,
            [0.0; 6],
            None,
        )?;
        world.set_time(f as f64 / hz);
        rec.record(&world, &Annotation { phase: f as f64, ..Default::default() });
    }
    let rec = rec.finish();
    rec.save(record)?;
    println!("{}: {} frames at {hz} Hz recorded to {}", clip.name, rec.frames(), record.display());
    if let Some(out) = html {
        let size = super::replay::replay_file(record, &out, &super::replay::web_dir(None))?;
        println!("replay page written to {} ({:.1} MB)", out.display(), size as f64 / 1e6);
    }
    Ok(())
}
