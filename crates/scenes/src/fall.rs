//! The fall test every task, skill and evaluation shares.
//!
//! A character has fallen when, for at least the rule's time,
//! - a part of the body not allowed on the floor touches it (the body map's
//!   `floor_contact_allowed` parts are, the feet on the built-in humanoid; the hands too where the
//!   scenario's `fall` says so): [`FallCause::Floor`];
//! - a part of the body touches a fixed prop that is not meant for it: the head on anything, and
//!   the pelvis or torso on a pedestal or a bucket (a chair is meant for sitting and leaning
//!   back, so only the head counts there; boxes and balls are handled, so no part counts):
//!   [`FallCause::Prop`];
//! - the pelvis is below a share of its standing height ([`FallCause::Low`]; at once by default,
//!   as the skills' own `min_height` termination);
//! - the head is below the pelvis: upside down or lying head-first ([`FallCause::Inverted`]).
//!
//! The test runs once per control tick inside [`crate::World::step`], so every user of a world
//! (skill training and evaluation, the meta-controller's tasks, the latent low level, the
//! recordings) gets the same answer; its timers travel in [`crate::World::snapshot`]. A fall
//! latches: it stays until the world is reset or its state set by hand.

use repertoire_files::FieldError;
use serde::{Deserialize, Serialize};

use crate::body::BodyIndex;

/// What counts as a fall in a scenario (its optional `fall: (...)` field; every value has a
/// default, so `fall: (hands_on_floor: true)` is enough to change one).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FallRule {
    /// Seconds a part not allowed on the floor may touch it before that is a fall (0: at once,
    /// the early termination every shipped skill was trained with).
    pub floor_s: f64,
    /// Whether the hands (and what hangs from them) may touch the floor: a task that picks
    /// things up from it, or a get-up.
    pub hands_on_floor: bool,
    /// Seconds a part may touch a prop not meant for it before that is a fall (brushing past a
    /// pedestal with a hip is not one; lying on it is).
    pub prop_s: f64,
    /// The pelvis below this share of its standing height (0.33: 0.32 m on the built-in
    /// humanoid, whose lowest seat puts it at about 0.4 m) ...
    pub pelvis_below: f64,
    /// ... for this many seconds is a fall (0: at once).
    pub pelvis_s: f64,
    /// The head below the pelvis for this many seconds is a fall.
    pub inverted_s: f64,
}

impl Default for FallRule {
    fn default() -> Self {
        Self { floor_s: 0.0, hands_on_floor: false, prop_s: 0.2, pelvis_below: 0.33, pelvis_s: 0.0, inverted_s: 0.3 }
    }
}

impl FallRule {
    /// Whether every value is the default (the scenario then leaves the field out).
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }

    /// Checks the values; `Err` names the first bad field.
    pub fn check(&self) -> std::result::Result<(), FieldError> {
        for (name, v) in [
            ("floor_s", self.floor_s),
            ("prop_s", self.prop_s),
            ("pelvis_s", self.pelvis_s),
            ("inverted_s", self.inverted_s),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(FieldError::new(format!("fall.{name}"), v, "it must be a number of seconds ≥ 0"));
            }
        }
        if !(self.pelvis_below.is_finite() && (0.0..1.0).contains(&self.pelvis_below)) {
            return Err(FieldError::new(
                "fall.pelvis_below",
                self.pelvis_below,
                "it must be a share of the standing pelvis height in [0, 1)",
            ));
        }
        Ok(())
    }
}

/// Why a character fell.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum FallCause {
    /// A part not allowed on the floor touched it.
    Floor,
    /// A part touched a prop not meant for it.
    Prop,
    /// The pelvis stayed low.
    Low,
    /// The head stayed below the pelvis.
    Inverted,
}

impl FallCause {
    /// Every cause, in code order.
    pub const ALL: [FallCause; 4] = [FallCause::Floor, FallCause::Prop, FallCause::Low, FallCause::Inverted];

    /// The cause's code in recordings (1–4; 0 is no fall).
    pub fn code(self) -> u8 {
        match self {
            FallCause::Floor => 1,
            FallCause::Prop => 2,
            FallCause::Low => 3,
            FallCause::Inverted => 4,
        }
    }

    /// The cause of recording code `code` (`None` for 0 or an unknown code).
    pub fn from_code(code: u8) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.code() == code)
    }

    /// A short name for tables and pages.
    pub fn name(self) -> &'static str {
        match self {
            FallCause::Floor => "floor",
            FallCause::Prop => "prop",
            FallCause::Low => "pelvis low",
            FallCause::Inverted => "upside down",
        }
    }
}

/// A fall: why, which body part (model body id; the pelvis for [`FallCause::Low`], the head for
/// [`FallCause::Inverted`]), on which prop (for [`FallCause::Prop`]) and when (simulated
/// seconds, when the rule's time ran out).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fall {
    /// Why.
    pub cause: FallCause,
    /// The body part.
    pub body: usize,
    /// The prop (scenario order) it lay on, for [`FallCause::Prop`].
    pub prop: Option<usize>,
    /// When it counted (s).
    pub time: f64,
}

/// How a model body is treated by the contact rules.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Part {
    /// Not the character.
    World,
    /// Allowed on the floor (the map's `floor_contact_allowed`: the feet).
    Foot,
    /// A hand (or what hangs from it).
    Hand,
    /// The head (or what hangs from it).
    Head,
    /// The pelvis or the torso body itself.
    Trunk,
    /// Any other part (thighs, shins, arms).
    Limb,
}

/// How a prop is treated by the contact rules.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PropUse {
    /// A seat: every part but the head may rest on it.
    Seat,
    /// Furniture to stand beside (a pedestal, a bucket): the head, pelvis and torso may not.
    Stand,
    /// A handled object (box, ball): any part may touch it.
    Handled,
}

impl PropUse {
    /// Whether `part` lying on a prop of this use is a fall.
    pub fn forbids(self, part: Part) -> bool {
        match self {
            PropUse::Seat => part == Part::Head,
            PropUse::Stand => matches!(part, Part::Head | Part::Trunk),
            PropUse::Handled => false,
        }
    }
}

/// Classifies every model body for the contact rules.
pub fn parts(index: &BodyIndex, parent: &[usize]) -> Vec<Part> {
    (0..index.is_character.len())
        .map(|b| {
            if !index.is_character[b] {
                Part::World
            } else if index.floor_ok[b] {
                Part::Foot
            } else if index.hand_of[b].is_some() {
                Part::Hand
            } else if crate::body::in_subtree(parent, b, index.head) {
                Part::Head
            } else if b == index.pelvis || b == index.pelvis_part || b == index.torso {
                Part::Trunk
            } else {
                Part::Limb
            }
        })
        .collect()
}

/// What one control tick showed, for [`FallMonitor::update`]: the first offending body for
/// each contact rule (`None` when none), the pelvis height and the head's height over the
/// pelvis.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FallSigns {
    /// A part not allowed on the floor touching it.
    pub floor: Option<usize>,
    /// A part on a prop not meant for it, and the prop.
    pub prop: Option<(usize, usize)>,
    /// Pelvis height (m).
    pub pelvis_z: f64,
    /// Head height minus pelvis height (m).
    pub head_over_pelvis: f64,
    /// The pelvis body (named by a [`FallCause::Low`] fall).
    pub pelvis: usize,
    /// The head body (named by a [`FallCause::Inverted`] fall).
    pub head: usize,
}

/// Numbers in a [`FallMonitor`]'s snapshot.
pub const FALL_STATE_LEN: usize = 8;

/// The fall test's running state: how long each sign has held, and the fall once one counted.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FallMonitor {
    floor_t: f64,
    prop_t: f64,
    low_t: f64,
    inverted_t: f64,
    fall: Option<Fall>,
}

impl FallMonitor {
    /// Forgets every sign and any fall (a new episode, a state set by hand).
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// The fall, once one counted.
    pub fn fall(&self) -> Option<Fall> {
        self.fall
    }

    /// Advances the timers by `dt` seconds of what `signs` shows (`dt` = 0 checks the rules
    /// that count at once) and latches a fall at `time` when one's time has come. `pelvis_min`:
    /// the pelvis height below which it is low (m).
    pub fn update(&mut self, rule: &FallRule, signs: &FallSigns, pelvis_min: f64, dt: f64, time: f64) -> Option<Fall> {
        if self.fall.is_some() {
            return self.fall;
        }
        let held = |t: &mut f64, on: bool, limit: f64| {
            *t = if on { *t + dt } else { 0.0 };
            on && *t >= limit - 1e-9
        };
        let fall = if held(&mut self.floor_t, signs.floor.is_some(), rule.floor_s) {
            signs.floor.map(|b| Fall { cause: FallCause::Floor, body: b, prop: None, time })
        } else {
            None
        };
        let prop_on = held(&mut self.prop_t, signs.prop.is_some(), rule.prop_s);
        let low = held(&mut self.low_t, signs.pelvis_z < pelvis_min, rule.pelvis_s);
        let inverted = held(&mut self.inverted_t, signs.head_over_pelvis < 0.0, rule.inverted_s);
        self.fall = fall
            .or_else(|| {
                prop_on
                    .then(|| signs.prop.map(|(b, p)| Fall { cause: FallCause::Prop, body: b, prop: Some(p), time }))?
            })
            .or_else(|| low.then_some(Fall { cause: FallCause::Low, body: signs.pelvis, prop: None, time }))
            .or_else(|| inverted.then_some(Fall { cause: FallCause::Inverted, body: signs.head, prop: None, time }));
        self.fall
    }

    /// The state as [`FALL_STATE_LEN`] numbers.
    pub fn snapshot(&self, out: &mut Vec<f64>) {
        out.extend_from_slice(&[self.floor_t, self.prop_t, self.low_t, self.inverted_t]);
        match self.fall {
            Some(f) => out.extend_from_slice(&[
                f64::from(f.cause.code()),
                f.body as f64,
                f.prop.map_or(-1.0, |p| p as f64),
                f.time,
            ]),
            None => out.extend_from_slice(&[0.0, 0.0, -1.0, 0.0]),
        }
    }

    /// Restores [`FallMonitor::snapshot`]'s numbers; `Err` says what is wrong with them.
    pub fn restore(&mut self, s: &[f64]) -> std::result::Result<(), FallStateError> {
        if s.len() != FALL_STATE_LEN {
            return Err(FallStateError::Length(s.len()));
        }
        let code = s[4];
        let fall = if code == 0.0 {
            None
        } else {
            let cause = (code.fract() == 0.0 && (1.0..=4.0).contains(&code))
                .then(|| FallCause::from_code(code as u8))
                .flatten()
                .ok_or(FallStateError::Cause(code))?;
            Some(Fall { cause, body: s[5].max(0.0) as usize, prop: (s[6] >= 0.0).then_some(s[6] as usize), time: s[7] })
        };
        *self = Self { floor_t: s[0], prop_t: s[1], low_t: s[2], inverted_t: s[3], fall };
        Ok(())
    }
}

/// What is wrong with the numbers given to [`FallMonitor::restore`].
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum FallStateError {
    /// Not [`FALL_STATE_LEN`] numbers.
    #[error("a fall state has {FALL_STATE_LEN} values, not {0}")]
    Length(usize),
    /// A fall whose cause code is none of the causes'.
    #[error("fall cause code {0} is not one of 1–4")]
    Cause(f64),
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f64 = 1.0 / 60.0;

    fn standing() -> FallSigns {
        FallSigns { floor: None, prop: None, pelvis_z: 0.95, head_over_pelvis: 0.5, pelvis: 1, head: 3 }
    }

    /// Feeds `signs` for `ticks` control ticks; the fall, if one counted.
    fn feed(m: &mut FallMonitor, rule: &FallRule, signs: FallSigns, ticks: usize) -> Option<Fall> {
        (0..ticks).fold(None, |_, k| m.update(rule, &signs, 0.32, DT, k as f64 * DT))
    }

    #[test]
    fn a_floor_touch_counts_at_once_and_latches() {
        let rule = FallRule::default();
        let mut m = FallMonitor::default();
        assert_eq!(feed(&mut m, &rule, standing(), 60), None);
        let fall = m.update(&rule, &FallSigns { floor: Some(7), ..standing() }, 0.32, 0.0, 1.0).expect("a fall");
        assert_eq!((fall.cause, fall.body, fall.prop), (FallCause::Floor, 7, None));
        // Getting up again does not undo it; only a reset does.
        assert_eq!(feed(&mut m, &rule, standing(), 10).map(|f| f.cause), Some(FallCause::Floor));
        m.reset();
        assert_eq!(m.fall(), None);
    }

    #[test]
    fn a_prop_under_a_forbidden_part_counts_only_when_it_lasts() {
        let rule = FallRule::default();
        let on_prop = FallSigns { prop: Some((2, 0)), ..standing() };
        let mut m = FallMonitor::default();
        // A brush of 0.15 s, then off: nothing; the timer starts again.
        assert_eq!(feed(&mut m, &rule, on_prop, 9), None);
        assert_eq!(feed(&mut m, &rule, standing(), 1), None);
        assert_eq!(feed(&mut m, &rule, on_prop, 11), None, "0.18 s is not 0.2 s");
        let fall = feed(&mut m, &rule, on_prop, 1).expect("0.2 s counts");
        assert_eq!((fall.cause, fall.body, fall.prop), (FallCause::Prop, 2, Some(0)));
    }

    #[test]
    fn a_low_pelvis_and_a_head_below_it_are_falls() {
        let rule = FallRule::default();
        let mut m = FallMonitor::default();
        let low = feed(&mut m, &rule, FallSigns { pelvis_z: 0.25, ..standing() }, 1).expect("low at once");
        assert_eq!((low.cause, low.body), (FallCause::Low, 1));
        let mut m = FallMonitor::default();
        let upside_down = FallSigns { head_over_pelvis: -0.2, ..standing() };
        assert_eq!(feed(&mut m, &rule, upside_down, 17), None, "0.28 s upside down");
        let fall = feed(&mut m, &rule, upside_down, 1).expect("0.3 s counts");
        assert_eq!((fall.cause, fall.body), (FallCause::Inverted, 3));
        // A rule that gives the pelvis time lets a short dip pass.
        let patient = FallRule { pelvis_s: 0.5, ..rule };
        let mut m = FallMonitor::default();
        assert_eq!(feed(&mut m, &patient, FallSigns { pelvis_z: 0.25, ..standing() }, 20), None);
    }

    #[test]
    fn the_snapshot_carries_the_timers_and_the_fall() {
        let rule = FallRule::default();
        let on_prop = FallSigns { prop: Some((4, 1)), ..standing() };
        let mut m = FallMonitor::default();
        feed(&mut m, &rule, on_prop, 8);
        let mut s = Vec::new();
        m.snapshot(&mut s);
        assert_eq!(s.len(), FALL_STATE_LEN);
        let mut copy = FallMonitor::default();
        copy.restore(&s).unwrap();
        assert_eq!(copy, m);
        // Both go on to the same fall at the same tick.
        assert_eq!(feed(&mut m, &rule, on_prop, 4), feed(&mut copy, &rule, on_prop, 4));
        assert!(m.fall().is_some());
        s.clear();
        m.snapshot(&mut s);
        let mut again = FallMonitor::default();
        again.restore(&s).unwrap();
        assert_eq!(again, m);
        s[4] = 9.0;
        assert_eq!(again.restore(&s), Err(FallStateError::Cause(9.0)));
        assert_eq!(again.restore(&s[1..]), Err(FallStateError::Length(FALL_STATE_LEN - 1)));
    }

    #[test]
    fn bad_rules_are_refused_by_name() {
        assert!(FallRule::default().check().is_ok());
        let e = FallRule { prop_s: -1.0, ..FallRule::default() }.check().unwrap_err();
        assert_eq!((e.field.as_str(), e.value.as_str()), ("fall.prop_s", "-1"));
        let e = FallRule { pelvis_below: 1.5, ..FallRule::default() }.check().unwrap_err();
        assert_eq!(e.field, "fall.pelvis_below");
        assert!(e.to_string().starts_with("`fall.pelvis_below` is 1.5; it must be a share"), "{e}");
    }

    #[test]
    fn a_seat_takes_any_part_but_the_head_and_furniture_takes_no_trunk() {
        assert!(!PropUse::Seat.forbids(Part::Trunk) && PropUse::Seat.forbids(Part::Head));
        assert!(PropUse::Stand.forbids(Part::Trunk) && !PropUse::Stand.forbids(Part::Hand));
        assert!(!PropUse::Stand.forbids(Part::Limb));
        assert!(!PropUse::Handled.forbids(Part::Head));
    }
}
