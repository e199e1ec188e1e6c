//! [`SitJudge`]: the sitting task's success test and its per-trial figures.
//!
//! Success (Chao et al.): the character sits continuously for `hold_s` seconds; any control
//! tick not seated restarts the count. Seated is the pelvis on the seat, facing within the
//! scenario's `facing_deg` of the chair's front (`World::seated_on`; 180° is the paper's
//! literal pelvis–seat contact). The judge also keeps the trial's minimum
//! pelvis-to-seat-centre distance.

/// Judges one sitting trial, tick by tick.
#[derive(Debug, Clone, PartialEq)]
pub struct SitJudge {
    hold_ticks: u32,
    streak: u32,
    /// Whether the trial has succeeded (stays true once reached).
    pub succeeded: bool,
    /// The smallest pelvis-to-seat-centre distance seen (m).
    pub min_distance: f64,
}

impl SitJudge {
    /// A judge needing `hold_s` seconds of contact at `control_hz` ticks per second.
    pub fn new(hold_s: f64, control_hz: f64) -> Self {
        SitJudge {
            hold_ticks: (hold_s * control_hz).round().max(1.0) as u32,
            streak: 0,
            succeeded: false,
            min_distance: f64::INFINITY,
        }
    }

    /// Records one control tick: whether the character sat and the pelvis' distance to the
    /// seat centre. Returns whether the trial has succeeded.
    pub fn tick(&mut self, seated: bool, distance: f64) -> bool {
        self.min_distance = self.min_distance.min(distance);
        self.streak = if seated { self.streak + 1 } else { 0 };
        if self.streak >= self.hold_ticks {
            self.succeeded = true;
        }
        self.succeeded
    }

    /// Ticks of unbroken contact so far.
    pub fn streak(&self) -> u32 {
        self.streak
    }

    /// Restores a judge's running state (checkpoints).
    pub fn restore(&mut self, streak: u32, succeeded: bool, min_distance: f64) {
        self.streak = streak;
        self.succeeded = succeeded;
        self.min_distance = min_distance;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn success_needs_three_unbroken_seconds() {
        let hz = 60.0;
        let mut j = SitJudge::new(3.0, hz);
        // 2.9 s of contact, a break, 2.9 s more: no success.
        for _ in 0..174 {
            assert!(!j.tick(true, 0.1));
        }
        assert!(!j.tick(false, 0.1));
        for _ in 0..174 {
            assert!(!j.tick(true, 0.05));
        }
        assert!(!j.succeeded, "2.9 s twice is not 3 s");
        // Six more ticks reach exactly 3.0 s of unbroken contact.
        for k in 0..6 {
            assert_eq!(j.tick(true, 0.2), k == 5, "tick {k}");
        }
        assert!((j.min_distance - 0.05).abs() < 1e-12);
        // Success sticks.
        assert!(j.tick(false, 1.0));
    }
}
