//! Standing hold: the cleanup step that keeps a character's root in place while the person stands.
//!
//! Where the person stands still, the shipped networks keep their characters moving about: Stretch
//! drives 1.5 m backwards while the person waves on the bundled `wave` clip, and over the held-out
//! clips the characters' roots travel 0.05–0.11 body lengths per second while the person's stays
//! within 5 cm (docs/following.md, "Standing where the human stands"). The hold scales the horizontal
//! root motion of each frame (the state's displacement and linear velocity, so wheels roll with what is
//! shown) by a factor that follows the person's pelvis speed, read from x^h and smoothed over
//! `seconds`: 0 below `still`, 1 above `moving`, linear between. The legs do what the networks say;
//! the foot lock keeps the planted feet where they stand. Like the other cleanups it is causal.

use serde::{Deserialize, Serialize};

use crate::character_state::CharacterLayout;
use crate::human::layout as human_layout;

/// When and how the cleanup holds a character's root while the person stands.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StandingHold {
    /// The person's smoothed pelvis speed (m/s) at and below which the root holds still.
    pub still: f32,
    /// The speed (m/s) at and above which the root moves as the networks say.
    pub moving: f32,
    /// Time constant (s) of the smoothing of the person's speed.
    pub seconds: f32,
}

impl Default for StandingHold {
    fn default() -> Self {
        StandingHold { still: 0.1, moving: 0.25, seconds: 0.5 }
    }
}

impl StandingHold {
    /// The share of the networks' root travel kept at a smoothed person's speed of `speed` m/s.
    pub fn share(&self, speed: f32) -> f32 {
        ramp(self.still, self.moving, speed)
    }
}

/// The share (0–1) of a motion a hold keeps at a smoothed speed `speed`: 0 at and below `still`, 1
/// at and above `moving`, linear between (a step at `still` when `moving` is not above it).
pub(crate) fn ramp(still: f32, moving: f32, speed: f32) -> f32 {
    if moving <= still {
        return if speed > still { 1.0 } else { 0.0 };
    }
    ((speed - still) / (moving - still)).clamp(0.0, 1.0)
}

/// The fraction of the way to a new value that an exponential smoothing with time constant `seconds`
/// goes in one frame at `fps` frames per second (a time constant below a frame counts as one frame).
pub(crate) fn smoothing(seconds: f32, fps: f32) -> f32 {
    1.0 - (-1.0 / (fps * seconds.max(1.0 / fps))).exp()
}

/// One character's memory of the person's smoothed speed.
#[derive(Clone, Debug, Default)]
pub struct HoldState {
    /// The person's smoothed pelvis speed (m/s); `None` before the first frame.
    speed: Option<f32>,
}

impl HoldState {
    /// Scales the horizontal root motion of the next frame's denormalised state `state` by the share
    /// the person's speed so far allows (none before the first frame is seen: a stream starts moving
    /// freely).
    pub fn hold(&self, hold: &StandingHold, layout: &CharacterLayout, state: &mut [f32]) {
        let share = self.speed.map_or(1.0, |s| hold.share(s));
        if share == 1.0 {
            return;
        }
        for v in &mut state[layout.root_displacement()] {
            *v *= share;
        }
        let lin = layout.root_linear_velocity().start;
        for v in &mut state[lin..lin + 2] {
            *v *= share;
        }
    }

    /// Records a frame of the person, x^h row `x_h`, at `fps` frames per second.
    pub fn observe(&mut self, hold: &StandingHold, x_h: &[f32], fps: f32) {
        let v = &x_h[human_layout::ROOT_LINEAR_VELOCITY];
        let now = v[0].hypot(v[1]);
        let a = smoothing(hold.seconds, fps);
        self.speed = Some(self.speed.map_or(now, |s| s + a * (now - s)));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_share_of_travel_follows_the_persons_speed() {
        let h = StandingHold::default();
        assert_eq!((h.share(0.0), h.share(0.1), h.share(0.25), h.share(2.0)), (0.0, 0.0, 1.0, 1.0));
        assert!((h.share(0.175) - 0.5).abs() < 1e-6);
        // A threshold without a ramp.
        let step = StandingHold { still: 0.2, moving: 0.2, ..h };
        assert_eq!((step.share(0.2), step.share(0.21)), (0.0, 1.0));
    }

    #[test]
    fn a_person_standing_holds_the_root_and_a_person_walking_releases_it() {
        let layout = CharacterLayout { dof: 0, end_effectors: 0 };
        let hold = StandingHold::default();
        let fps = 30.0;
        let moving = || {
            let mut s = vec![0.0; layout.dim()];
            s[layout.root_displacement()].copy_from_slice(&[0.02, -0.01]);
            s[layout.root_linear_velocity()].copy_from_slice(&[0.6, -0.3, 0.05]);
            s
        };
        let person = |speed: f32| {
            let mut x = vec![0.0; human_layout::DIM];
            x[human_layout::ROOT_LINEAR_VELOCITY][1] = speed;
            // Vertical motion (a squat) is no travel.
            x[human_layout::ROOT_LINEAR_VELOCITY][2] = 0.8;
            x
        };
        let mut memory = HoldState::default();
        // Nothing seen yet: the stream moves as the networks say.
        let mut s = moving();
        memory.hold(&hold, &layout, &mut s);
        assert_eq!(s, moving());
        // The person stands: the root holds, its vertical velocity and everything else kept.
        memory.observe(&hold, &person(0.01), fps);
        let mut s = moving();
        memory.hold(&hold, &layout, &mut s);
        assert_eq!(&s[layout.root_displacement()], &[0.0, 0.0]);
        assert_eq!(&s[layout.root_linear_velocity()], &[0.0, 0.0, 0.05]);
        // The person walks off at 1 m/s: within about half a second (the smoothing) the root moves
        // freely again, not at once.
        let released = (1..=60).find(|_| {
            memory.observe(&hold, &person(-1.0), fps);
            let mut s = moving();
            memory.hold(&hold, &layout, &mut s);
            assert!((0.0..=0.02).contains(&s[layout.root_displacement()][0]), "a share of the travel");
            s == moving()
        });
        // Exponential smoothing over half a second: 1 − e^(−1/15) of the way each frame, from 0.01 m/s
        // to 1 m/s, passes 0.25 m/s on the fifth frame.
        assert_eq!(released, Some(5));
        let mut fresh = HoldState::default();
        fresh.observe(&hold, &person(0.0), fps);
        fresh.observe(&hold, &person(1.0), fps);
        let want = 1.0 - (-1.0f32 / 15.0).exp();
        assert!((fresh.speed.unwrap() - want).abs() < 1e-6, "{:?} against {want}", fresh.speed);
        fresh.observe(&hold, &person(0.0), fps);
        assert!((fresh.speed.unwrap() - want * (-1.0f32 / 15.0).exp()).abs() < 1e-6, "{:?}", fresh.speed);
        // A time constant below a frame counts as one frame.
        let mut instant = HoldState::default();
        let at_once = StandingHold { seconds: 0.0, ..hold };
        instant.observe(&at_once, &person(0.0), fps);
        instant.observe(&at_once, &person(1.0), fps);
        assert!((instant.speed.unwrap() - (1.0 - (-1.0f32).exp())).abs() < 1e-6, "{:?}", instant.speed);
    }
}
