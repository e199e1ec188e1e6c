//! Where episodes start.
//!
//! [`ZoneCurriculum`]: training starts in the scenario's easiest spawn zone and moves to the next
//! when the success rate over the last `window` episodes reaches `advance_at` (the sitting
//! paper's front → sides → behind schedule); zones already passed stay open unless the scenario
//! says `keep_passed: false`. With `max_episodes` a zone also closes its turn once that many
//! episodes have been spent in it, whatever its success rate. Every switch is recorded with the episode count at
//! which it happened, so a run's schedule can be read back. Reference-state initialisation and
//! end-pose pools live with the skills (`repertoire_skill::imitation`, `repertoire_skill::pool`).

use std::collections::VecDeque;

use repertoire_scenes::scenario::Curriculum;
use serde::{Deserialize, Serialize};

/// One zone switch.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Advance {
    /// Episodes finished when it happened.
    pub episode: u64,
    /// The zone left.
    pub from: String,
    /// The zone entered.
    pub to: String,
    /// The success rate over the current window when it happened (over the episodes so far
    /// when a budget ran out before a full window).
    pub success_rate: f64,
    /// What moved training on.
    #[serde(default)]
    pub reason: AdvanceReason,
}

/// Why the curriculum moved to the next zone.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum AdvanceReason {
    /// The windowed success rate reached `advance_at`.
    #[default]
    Threshold,
    /// The zone's `max_episodes` were spent first.
    Budget,
}

impl AdvanceReason {
    /// For logs and tables: `threshold` or `budget`.
    pub fn as_str(self) -> &'static str {
        match self {
            AdvanceReason::Threshold => "threshold",
            AdvanceReason::Budget => "budget",
        }
    }
}

/// A spawn-zone curriculum over a scenario's zones.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ZoneCurriculum {
    zones: Vec<String>,
    advance_at: f64,
    window: usize,
    /// Index of the current (hardest unlocked) zone.
    current: usize,
    /// Outcomes of the last `window` episodes since the last switch (in every open zone).
    recent: VecDeque<bool>,
    episodes: u64,
    /// Episodes a zone may take before training moves on regardless of success.
    #[serde(default)]
    max_episodes: Option<u64>,
    /// Every switch so far.
    pub history: Vec<Advance>,
    /// When false, every zone is open from the start (the "no curriculum" ablation).
    pub enabled: bool,
    /// Whether passed zones stay open.
    keep_passed: bool,
}

impl ZoneCurriculum {
    /// A curriculum over `spec`'s zones, starting in the first; `enabled = false` opens every
    /// zone at once.
    pub fn new(spec: &Curriculum, enabled: bool) -> Self {
        ZoneCurriculum {
            zones: spec.zones.clone(),
            advance_at: spec.advance_at,
            window: spec.window.max(1),
            current: if enabled { 0 } else { spec.zones.len().saturating_sub(1) },
            recent: VecDeque::with_capacity(spec.window.max(1)),
            episodes: 0,
            max_episodes: spec.max_episodes,
            history: Vec::new(),
            enabled,
            keep_passed: spec.keep_passed,
        }
    }

    /// What in `spec` differs from the schedule this curriculum was made from (its zones,
    /// threshold, window, budget, whether passed zones stay open), or `None`: a saved
    /// curriculum (a resumed training run's) continues only under the schedule it began with.
    pub fn differs_from(&self, spec: &Curriculum) -> Option<String> {
        let fresh = ZoneCurriculum::new(spec, self.enabled);
        let fields: [(&str, String, String); 5] = [
            ("zones", format!("{:?}", self.zones), format!("{:?}", fresh.zones)),
            ("advance_at", self.advance_at.to_string(), fresh.advance_at.to_string()),
            ("window", self.window.to_string(), fresh.window.to_string()),
            ("max_episodes", format!("{:?}", self.max_episodes), format!("{:?}", fresh.max_episodes)),
            ("keep_passed", self.keep_passed.to_string(), fresh.keep_passed.to_string()),
        ];
        fields
            .into_iter()
            .find(|(_, saved, now)| saved != now)
            .map(|(what, saved, now)| format!("{what} {saved}, now {now}"))
    }

    /// The zones episodes may start in now: every zone up to the current one (only the current
    /// one with `keep_passed: false`) when enabled, else all of them.
    pub fn open_zones(&self) -> &[String] {
        match (self.enabled, self.keep_passed) {
            (false, _) => &self.zones,
            (true, true) => &self.zones[..=self.current],
            (true, false) => &self.zones[self.current..=self.current],
        }
    }

    /// The current zone's name.
    pub fn current(&self) -> &str {
        &self.zones[self.current]
    }

    /// Index of the current zone in the schedule.
    pub fn current_index(&self) -> usize {
        self.current
    }

    /// The schedule's zones, easiest first.
    pub fn zones(&self) -> &[String] {
        &self.zones
    }

    /// The windowed success rate that opens the next zone.
    pub fn advance_at(&self) -> f64 {
        self.advance_at
    }

    /// Episodes recorded so far.
    pub fn episodes(&self) -> u64 {
        self.episodes
    }

    /// The success rate over the episodes recorded in the current window so far (None before
    /// the first), for logs and plots; advancing waits for a full window.
    pub fn window_rate(&self) -> Option<f64> {
        (!self.recent.is_empty()).then(|| self.recent.iter().filter(|&&s| s).count() as f64 / self.recent.len() as f64)
    }

    /// Whether the last zone has been reached.
    pub fn finished(&self) -> bool {
        self.current + 1 >= self.zones.len()
    }

    /// The success rate over the current window (None until the window is full).
    pub fn success_rate(&self) -> Option<f64> {
        (self.recent.len() == self.window)
            .then(|| self.recent.iter().filter(|&&s| s).count() as f64 / self.window as f64)
    }

    /// Episodes a zone may take before training moves on regardless of its success rate.
    pub fn max_episodes(&self) -> Option<u64> {
        self.max_episodes
    }

    /// Episodes recorded since the current zone opened.
    pub fn episodes_in_zone(&self) -> u64 {
        self.episodes - self.history.last().map_or(0, |a| a.episode)
    }

    /// Records one finished episode; returns the switch when this episode completes a full
    /// window whose success rate is at least `advance_at`, or is the zone's `max_episodes`-th
    /// (the window then starts afresh in the next zone).
    pub fn record(&mut self, success: bool) -> Option<Advance> {
        self.episodes += 1;
        if !self.enabled || self.finished() {
            return None;
        }
        if self.recent.len() == self.window {
            self.recent.pop_front();
        }
        self.recent.push_back(success);
        let reason = match self.success_rate() {
            Some(rate) if rate >= self.advance_at => AdvanceReason::Threshold,
            _ if self.max_episodes.is_some_and(|m| self.episodes_in_zone() >= m) => AdvanceReason::Budget,
            _ => return None,
        };
        let advance = Advance {
            episode: self.episodes,
            from: self.zones[self.current].clone(),
            to: self.zones[self.current + 1].clone(),
            success_rate: self.window_rate().unwrap_or(0.0),
            reason,
        };
        self.current += 1;
        self.recent.clear();
        self.history.push(advance.clone());
        Some(advance)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> Curriculum {
        Curriculum {
            zones: vec!["front".into(), "sides".into(), "behind".into()],
            advance_at: 0.8,
            window: 10,
            keep_passed: true,
            max_episodes: None,
        }
    }

    #[test]
    fn advances_exactly_when_the_window_reaches_the_threshold() {
        let mut c = ZoneCurriculum::new(&spec(), true);
        assert_eq!(c.open_zones(), ["front"]);
        // 7 successes in a window of 10: 0.7 < 0.8, no switch.
        for k in 0..10 {
            assert_eq!(c.record(k < 7), None, "episode {k}");
        }
        assert_eq!(c.success_rate(), Some(0.7));
        // The window slides: each new success replaces an old outcome. After the 11th episode
        // (a success replacing a success) still 0.7; then a success replaces the first failure.
        assert_eq!(c.record(true), None); // window: episodes 2..11 → 7 successes (ep 1 success dropped)
        assert_eq!(c.success_rate(), Some(0.7));
        let mut switched = None;
        for _ in 0..10 {
            if let Some(a) = c.record(true) {
                switched = Some(a);
                break;
            }
            assert!(c.success_rate().unwrap() < 0.8, "a rate ≥ 0.8 must switch at once");
        }
        let a = switched.expect("switches once the rate reaches 0.8");
        assert_eq!((a.from.as_str(), a.to.as_str()), ("front", "sides"));
        assert!((a.success_rate - 0.8).abs() < 1e-12, "switches at exactly the threshold, not later");
        assert_eq!(c.current(), "sides");
        assert_eq!(c.open_zones(), ["front", "sides"], "the passed zone stays open");
        assert_eq!(c.success_rate(), None, "a new zone starts a new window");
        let mut only = ZoneCurriculum::new(&Curriculum { keep_passed: false, ..spec() }, true);
        for _ in 0..10 {
            only.record(true);
        }
        assert_eq!(only.open_zones(), ["sides"], "keep_passed: false opens the current zone only");
    }

    #[test]
    fn the_last_zone_stays_and_disabled_opens_all() {
        let mut c = ZoneCurriculum::new(&spec(), true);
        for _ in 0..25 {
            c.record(true);
        }
        assert_eq!(c.current(), "behind");
        assert_eq!(c.history.len(), 2);
        assert!(c.finished());
        assert_eq!(c.record(true), None);
        let off = ZoneCurriculum::new(&spec(), false);
        assert_eq!(off.open_zones(), ["front", "sides", "behind"]);
    }

    #[test]
    fn a_zone_budget_moves_on_at_its_last_episode_and_the_threshold_still_wins_earlier() {
        let mut c = ZoneCurriculum::new(&Curriculum { max_episodes: Some(25), ..spec() }, true);
        // Never a success: the threshold cannot open the sides; the 25th episode does.
        for k in 1..25 {
            assert_eq!(c.record(false), None, "episode {k} is inside the budget");
        }
        let a = c.record(false).expect("the 25th episode spends the front zone's budget");
        assert_eq!((a.from.as_str(), a.to.as_str(), a.episode), ("front", "sides", 25));
        assert_eq!(a.reason, AdvanceReason::Budget);
        assert_eq!(a.success_rate, 0.0);
        assert_eq!(c.open_zones(), ["front", "sides"]);
        // In the sides the threshold comes first: 8 successes in the first window of 10.
        let mut switched = None;
        for k in 0..10 {
            if let Some(a) = c.record(k >= 2) {
                switched = Some((k, a));
            }
        }
        let (k, a) = switched.expect("the threshold is reached inside the budget");
        assert_eq!(k, 9, "at the end of the first full window");
        assert_eq!((a.reason, a.episode), (AdvanceReason::Threshold, 35));
        assert!((a.success_rate - 0.8).abs() < 1e-12);
        assert!(c.finished());
        // Without a budget, 1000 failures never move on.
        let mut never = ZoneCurriculum::new(&spec(), true);
        assert!((0..1000).all(|_| never.record(false).is_none()));
        assert_eq!(never.current(), "front");
    }

    #[test]
    fn a_saved_curriculum_round_trips_and_names_what_a_changed_schedule_changed() {
        let mut c = ZoneCurriculum::new(&Curriculum { max_episodes: Some(25), ..spec() }, true);
        for k in 0..30 {
            c.record(k % 3 == 0);
        }
        let text = ron::to_string(&c).expect("serialise");
        let back: ZoneCurriculum = ron::from_str(&text).expect("parse");
        assert_eq!(back, c, "zone, window, episode count and history survive a checkpoint");
        let same = Curriculum { max_episodes: Some(25), ..spec() };
        assert_eq!(back.differs_from(&same), None);
        assert_eq!(back.differs_from(&spec()).as_deref(), Some("max_episodes Some(25), now None"));
        let moved = Curriculum { advance_at: 0.5, max_episodes: Some(25), ..spec() };
        assert_eq!(back.differs_from(&moved).as_deref(), Some("advance_at 0.8, now 0.5"));
        let renamed = Curriculum { zones: vec!["front".into(), "behind".into()], max_episodes: Some(25), ..spec() };
        assert!(back.differs_from(&renamed).unwrap().starts_with("zones [\"front\", \"sides\", \"behind\"]"));
    }
}
