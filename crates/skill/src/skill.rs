//! [`SkillSetup`]: a spec made concrete: its scene compiled, its clip imported, retargeted and
//! laid out at the control rate, its pools loaded, ready to make environments.

use std::path::Path;
use std::sync::Arc;

use repertoire_clip::{Clip, ClipBody, ClipSource, LoadedKeyframes, RetargetOptions};
use repertoire_humanoid::HumanoidEnv;
use repertoire_scenes::{ObservationLayout, ScenarioFile, WorldModel};

use crate::error::{Result, SkillError};
use crate::imitation::{ImitationTask, ObjectSetup, TaskSettings};
use crate::library::ClipRecord;
use crate::pool::Pool;
use crate::reference::Reference;
use crate::spec::{Goal, Init, SpecFile};

/// The environment type of every skill.
pub type SkillEnv = HumanoidEnv<ImitationTask>;

/// Everything needed to make a skill's environments.
pub struct SkillSetup {
    /// The spec.
    pub spec: SpecFile,
    /// The compiled scene.
    pub model: Arc<WorldModel>,
    /// The body alone (clips, retargeting).
    pub body: ClipBody,
    /// The observation layout (before the task's phase and goal values).
    pub layout: Arc<ObservationLayout>,
    /// The task settings shared by all envs.
    pub settings: Arc<TaskSettings>,
    /// The clip as retargeted (before resampling).
    pub clip: Clip,
    /// Episode limit in control steps.
    pub max_steps: u32,
}

/// Imports any clip file the project reads onto `body`: a retargeted clip (`.clip.ron`,
/// `.npy` with its `.meta.ron`), a keyframe clip (`.ron`), or mocap (BVH, ASF/AMC, DeepMimic,
/// joint positions: `.npy`/`.npz` with a `.joints.ron`) retargeted with the shipped map (or `map`).
pub fn load_clip(path: &Path, map: Option<&Path>, body: &ClipBody) -> Result<Clip> {
    let name = path.file_name().map(|n| n.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    let positions = name.ends_with(".npy")
        && !repertoire_clip::io::sidecar(path).exists()
        && repertoire_clip::positions::declaration_path(path).exists();
    if name.ends_with(".clip.ron") || (name.ends_with(".npy") && !positions) {
        let clip = Clip::load(path)?;
        // A retargeted clip holds one body's joint angles: on another body they would land on
        // other joints (or past the end of its qpos).
        if clip.body_hash != body.hash() {
            let mjcf = repertoire_files::portable_path(&body.def.mjcf_path);
            let flag = if mjcf.starts_with("<built-in>") { "humanoid".to_string() } else { mjcf.clone() };
            return Err(SkillError::Invalid(format!(
                "{}: retargeted onto another body (body hash {}, {} qpos values a frame), not {} (hash {}, {} values); \
                 retarget its source onto this body: `repertoire clip check SOURCE --body {} --out CLIP`",
                path.display(),
                clip.body_hash,
                clip.nq,
                mjcf,
                body.hash(),
                body.nq(),
                flag,
            )));
        }
        return Ok(clip);
    }
    let source = ClipSource::from_path(path, None)?;
    if let ClipSource::Keyframes(p) = &source {
        return Ok(LoadedKeyframes::load(p)?.to_clip(body)?);
    }
    let map = map.map(repertoire_clip::map::LoadedMap::load).transpose()?;
    let report = repertoire_clip::check(&source, body, map, None, &RetargetOptions::default())?;
    Ok(report.clip)
}

/// The pool file a name in [`Init::Pools`] stands for: a name ending in `.ron` is a pool file
/// itself (states a meta-controller delivered, `repertoire meta deliver`); any other names a
/// skill, whose successful end poses are `library/<skill>/end_poses.ron`.
pub fn pool_path(library: &Path, name: &str) -> std::path::PathBuf {
    if name.ends_with(".ron") {
        std::path::PathBuf::from(name)
    } else {
        crate::library::skill_dir(library, name).join("end_poses.ron")
    }
}

impl SkillSetup {
    /// Builds the skill of `spec`; predecessor pools (for [`Init::Pools`]) are read from
    /// [`pool_path`].
    pub fn new(spec: SpecFile, library: &Path) -> Result<Self> {
        let s = &spec.spec;
        let scenario = match s.scene.as_str() {
            "builtin:sit" => ScenarioFile::builtin_default(),
            other => ScenarioFile::load(spec.resolve(other))?,
        };
        let model = Arc::new(WorldModel::build(scenario)?);
        let body = ClipBody::new(model.body.clone())?;
        let clip_path = spec.resolve(&s.clip.file);
        if !clip_path.exists() {
            let hint =
                if s.clip.file.starts_with("pack:") { " (run scripts/setup.sh to install the clip pack)" } else { "" };
            return Err(SkillError::Invalid(format!(
                "{}: clip file {} does not exist{hint}",
                spec.path.display(),
                clip_path.display()
            )));
        }
        let map = s.clip.map.as_deref().map(|m| spec.resolve(m));
        let mut clip = load_clip(&clip_path, map.as_deref(), &body)?;
        if let Some((a, b)) = s.clip.cut_s {
            let frame = |t: f64| ((t * clip.fps).round() as usize).min(clip.frame_count());
            clip = clip.cut(frame(a), frame(b))?;
        }
        if s.clip.mirror {
            clip = clip.mirrored(&body)?;
        }
        clip.looping = s.clip.looping;
        if s.clip.lead_s > 0.0 {
            clip = clip.with_lead((s.clip.lead_s * clip.fps).round() as usize);
        }
        hold_joints(&mut clip, &body, &s.clip.pose_deg)
            .map_err(|m| SkillError::Invalid(format!("{}: {m}", spec.path.display())))?;
        let control_hz = f64::from(model.scenario.scenario.rates.control_hz);
        let mut reference = Reference::new(&clip, &body, control_hz)?;
        reference.hold_steps = (s.clip.hold_s * control_hz).round() as usize;
        if s.clip.seat_lift_m != 0.0 {
            if !s.clip.seat_lift_m.is_finite() || s.clip.seat_lift_m.abs() > 0.5 {
                return Err(SkillError::Invalid(format!(
                    "{}: clip seat_lift_m = {} is outside ±0.5 m",
                    spec.path.display(),
                    s.clip.seat_lift_m
                )));
            }
            reference.lift_low(s.clip.seat_lift_m);
        }

        let seat = match &s.goal {
            Goal::Seat { prop, .. } => {
                let id = model.prop_id(prop).ok_or_else(|| {
                    SkillError::Invalid(format!(
                        "{}: goal Seat names prop `{prop}`, which the scene {} lacks",
                        spec.path.display(),
                        model.scenario.path.display()
                    ))
                })?;
                // The seat goes under the pelvis where the clip sits lowest, facing its heading.
                let (f, _) = reference
                    .height
                    .iter()
                    .enumerate()
                    .fold((0, f64::INFINITY), |best, (i, &h)| if h < best.1 { (i, h) } else { best });
                let p = reference.root_pos[f];
                let (h, forward) = (reference.heading[f], goal_forward(&s.goal));
                Some((id, [p[0] + forward * h.cos(), p[1] + forward * h.sin(), h]))
            }
            _ => None,
        };
        let object = object_setup(&spec, &model, &reference)?;
        let obstacle = match &s.obstacle {
            Some(o) => {
                let id = model.prop_id(&o.prop).filter(|&id| !model.scenario.scenario.props[id].is_free());
                let id = id.ok_or_else(|| {
                    SkillError::Invalid(format!(
                        "{}: obstacle `{}` is not a fixed prop of the scene {}",
                        spec.path.display(),
                        o.prop,
                        model.scenario.path.display()
                    ))
                })?;
                Some((id, o.clone()))
            }
            None => None,
        };
        let delivered_seat = match &s.delivered_seat {
            Some(name) => {
                let id = model.prop_id(name).filter(|&id| !model.scenario.scenario.props[id].is_free());
                let id = id.ok_or_else(|| {
                    SkillError::Invalid(format!(
                        "{}: delivered_seat `{name}` is not a fixed prop of the scene {}",
                        spec.path.display(),
                        model.scenario.path.display()
                    ))
                })?;
                if seat.is_some() {
                    return Err(SkillError::Invalid(format!(
                        "{}: delivered_seat is for skills without a seat goal (a seat goal's chair follows a \
                         delivered state already)",
                        spec.path.display()
                    )));
                }
                Some(id)
            }
            None => None,
        };
        let mut pools = Vec::new();
        if let Init::Pools { from, .. } = &s.init {
            for name in from {
                let path = pool_path(library, name);
                if !path.exists() {
                    let how = if name.ends_with(".ron") {
                        "write it with `repertoire meta deliver`".to_string()
                    } else {
                        format!("run `repertoire skill eval {name}` first")
                    };
                    return Err(SkillError::Invalid(format!(
                        "{}: init Pools needs {}; {how}",
                        spec.path.display(),
                        path.display()
                    )));
                }
                let pool = Pool::load(&path)?;
                if pool.body_hash != model.body.content_hash()
                    || pool.states.iter().any(|st| st.joints.len() != reference.dof)
                {
                    return Err(SkillError::Mismatch {
                        path,
                        message: format!("end poses of `{name}` were recorded on another body"),
                    });
                }
                pools.push(pool);
            }
        }
        let max_steps = if reference.looping {
            (s.episode_s * control_hz).round() as u32
        } else {
            ((reference.frames() - 1 + reference.hold_steps) as u32).min((s.episode_s * control_hz).round() as u32)
        };
        let layout = Arc::new(ObservationLayout::new(&model, &s.features)?);
        let settings = Arc::new(TaskSettings {
            reference,
            imitation: s.imitation,
            goal: s.goal.clone(),
            init: s.init.clone(),
            termination: s.termination,
            pools,
            seat,
            object,
            grip: s.grip,
            obstacle,
            delivered_seat,
        });
        Ok(SkillSetup { spec, model, body, layout, settings, clip, max_steps: max_steps.max(1) })
    }

    /// Where the seat stands, for a sit skill, when an episode starts from a pool state (at the
    /// clip's first frame), in the character's heading frame: metres ahead, metres to the left,
    /// yaw relative to the heading; `None` for skills without a seat goal. A meta-controller's
    /// deliveries ([`PoolState::seat`](crate::pool::PoolState::seat)) are measured against it.
    pub fn seat_at_start(&self) -> Option<[f64; 3]> {
        let (_, [sx, sy, syaw]) = self.settings.seat?;
        let r = &self.settings.reference;
        let (p, h) = (r.root_pos[0], r.heading[0]);
        let d = crate::reference::to_heading(h, [sx - p[0], sy - p[1], 0.0]);
        Some([d[0], d[1], repertoire_scenes::math::wrap_angle(syaw - h)])
    }

    /// One environment.
    pub fn env(&self) -> SkillEnv {
        let task = ImitationTask::new(Arc::clone(&self.settings));
        HumanoidEnv::with_layout(&self.model, Arc::clone(&self.layout), task, self.max_steps)
    }

    /// `n` environments.
    pub fn envs(&self, n: usize) -> Vec<SkillEnv> {
        (0..n).map(|_| self.env()).collect()
    }

    /// What the library records about the clip.
    pub fn clip_record(&self) -> ClipRecord {
        let r = &self.settings.reference;
        let table = |v: &[f64]| if r.looping { v.iter().map(|&x| x as f32).collect() } else { Vec::new() };
        ClipRecord {
            name: self.clip.name.clone(),
            hash: self.clip.content_hash(),
            origin: repertoire_files::portable(&self.clip.origin),
            frames: r.frames(),
            cycle_joints: table(&r.joints),
            cycle_joint_vel: table(&r.joint_vel),
        }
    }
}

/// The seat's offset in front of the clip's seated pelvis.
fn goal_forward(goal: &Goal) -> f64 {
    match goal {
        Goal::Seat { forward_m, .. } => *forward_m,
        _ => 0.0,
    }
}

/// Sets the joints named in `pose_deg` to those angles (degrees; metres for slides) in every
/// frame of `clip`.
fn hold_joints(
    clip: &mut Clip,
    body: &ClipBody,
    pose_deg: &std::collections::BTreeMap<String, f64>,
) -> Result<(), String> {
    for (name, &v) in pose_deg {
        let j = body.joint(name).ok_or_else(|| {
            use repertoire_clip::body::JointKind;
            let known: Vec<&str> = body
                .joints
                .iter()
                .filter(|j| matches!(j.kind, JointKind::Hinge | JointKind::Slide))
                .map(|j| j.name.as_str())
                .collect();
            format!("clip pose_deg names joint `{name}`, which the body lacks; it has: {}", known.join(", "))
        })?;
        let value = if j.kind == repertoire_clip::body::JointKind::Slide { v } else { v.to_radians() };
        let value = j.range.map_or(value, |[lo, hi]| value.clamp(lo, hi));
        let (nq, q) = (clip.nq, j.qpos);
        for frame in clip.qpos.chunks_exact_mut(nq) {
            frame[q] = value;
        }
    }
    Ok(())
}

/// Resolves an object goal's props and clip times: the box or ball must be a free prop of the
/// scene, the pedestal a fixed one, the times inside the clip.
fn object_setup(spec: &SpecFile, model: &WorldModel, r: &Reference) -> Result<Option<ObjectSetup>> {
    let goal = &spec.spec.goal;
    let Some((kind, name)) = goal.object() else { return Ok(None) };
    let invalid = |m: String| SkillError::Invalid(format!("{}: goal {kind}: {m}", spec.path.display()));
    let scene = model.scenario.path.display();
    let find = |name: &str, free: bool, what: &str| -> Result<usize> {
        let id = model
            .prop_id(name)
            .ok_or_else(|| invalid(format!("names prop `{name}`, which the scene {scene} lacks")))?;
        if model.scenario.scenario.props[id].is_free() != free {
            return Err(invalid(format!("prop `{name}` of {scene} is not {what}")));
        }
        Ok(id)
    };
    let prop = find(name, true, "a free box or ball")?;
    let pedestal = goal.pedestal().map(|p| find(p, false, "a fixed pedestal")).transpose()?;
    let duration = r.duration();
    let frame = |what: &str, t: f64| -> Result<usize> {
        if t > duration {
            return Err(invalid(format!("{what} = {t} s is past the clip's end ({duration:.2} s)")));
        }
        Ok(r.frame_at(t))
    };
    let n = r.frames();
    let (held, pedestal_frame) = match goal {
        Goal::Lift { grip_s, .. } => {
            let g = frame("grip_s", *grip_s)?;
            (g..n, Some(g))
        }
        Goal::PutDown { release_s, .. } => {
            let g = frame("release_s", *release_s)?;
            (0..g, Some(g))
        }
        Goal::Catch { catch_s, .. } => {
            let c = frame("catch_s", *catch_s)?;
            // A throw needs some flight time: starts closer to the catch than this hold the ball.
            let min_flight = (0.25 / r.dt).round() as usize;
            (c.saturating_sub(min_flight)..n, Some(c))
        }
        _ => (0..n, None),
    };
    let shape = &model.scenario.scenario.props[prop];
    let (half, width) = match shape {
        repertoire_scenes::Prop::Box(b) => (0.5 * b.size.2, b.size.1),
        repertoire_scenes::Prop::Ball(b) => (b.radius, 2.0 * b.radius),
        other => return Err(invalid(format!("prop `{name}` is a {}, not a box or ball", other.kind()))),
    };
    Ok(Some(ObjectSetup {
        prop,
        pedestal: pedestal.zip(pedestal_frame),
        catch_frame: if matches!(goal, Goal::Catch { .. }) { pedestal_frame } else { None },
        held,
        half,
        width,
    }))
}
