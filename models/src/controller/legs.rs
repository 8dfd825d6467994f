//! Stepping: a gait clock, one stance/swing state machine per leg, Raibert-style footholds and smooth
//! swing trajectories.
//!
//! - The clock's phase Φ advances at the stepping frequency `f`. Leg `i` is *due* to lift off when
//!   `(Φ − offset_i) mod 1` enters the first half of its swing window `[0, 1 − duty)`; it then swings for
//!   the rest of the window, rounded to whole frames. Because each leg keeps its own state, a gait change
//!   (new offsets and duty) only shifts when legs next lift off: no foot ever jumps. A leg that has
//!   stood its full stance time also lifts anywhere in its window (the window moved), or out of turn
//!   when it is far out (a gait starting or speeding up).
//! - `f = max(the stride frequency of dynamic similarity, the frequency at which a stance half-length
//!   stays within STANCE_USE of the step region's radius along the motion)`, capped so that swings last
//!   at least a few frames, and low-pass filtered (see [`super`]). The speed looked at is the larger of
//!   the current one and the one the command filter reaches shortly.
//! - Stance feet are fixed in the world. A stance foot that drifts out of its step region (an ellipse
//!   of semi-axes `r_fore` along the body and `r_max` across it), or that IK cannot hold, lifts off at
//!   once (counted in [`super::ControllerStats::early_liftoffs`]).
//! - Footholds (Raibert): the nominal foothold, rotated by `ω·T_st/2` and shifted by `v·T_st/2`
//!   (`T_st` = stance time, `v` and `ω` the mean predicted over that stance), in the heading frame
//!   predicted at touchdown, so that the foot passes under its nominal position mid-stance.
//! - Swing: the foot first rises with no horizontal motion (the first [`EDGE`] of the swing, longer
//!   until it is [`StepParams::clearance`] above the ground: [`edge`]), moves horizontally along a
//!   minimum-jerk profile, and comes straight down onto a landing point frozen for as long at the end
//!   (so a late command change cannot drag a low foot). Its height is `H·16 s²(1−s)²`:
//!   zero vertical speed at lift-off and touchdown, 41 % of `H` when horizontal motion starts.

use nalgebra::{Point3, Vector2};

use super::rig::Leg;

/// Fraction of the step region's radius a stance half-length uses at the chosen frequency.
pub const STANCE_USE: f32 = 0.9;
/// Fraction of the swing at each end without horizontal motion (at least).
pub const EDGE: f32 = 0.2;
/// Largest fraction of the swing at each end without horizontal motion.
pub const MAX_EDGE: f32 = 0.35;
/// Fraction of the step region within which a foothold is placed.
const FOOTHOLD_USE: f32 = 0.85;

/// Where a leg is in its cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LegPhase {
    /// On the ground, fixed in the world.
    Stance {
        /// Time since touchdown (s).
        time: f32,
    },
    /// In the air for a whole number of frames (so that touchdown falls on a frame and the foothold
    /// predicted for it is where the foot lands).
    Swing {
        /// Frames done.
        frame: u32,
        /// Frames in the swing.
        frames: u32,
        /// World position at lift-off.
        from: Point3<f32>,
        /// Where the foot comes down, fixed once the descent starts (so that a late change of
        /// command cannot drag a low foot sideways).
        landing: Option<Vector2<f32>>,
    },
}

/// A leg's state.
#[derive(Clone, Debug)]
pub struct LegState {
    /// Stance or swing.
    pub phase: LegPhase,
    /// The foot's target world position this frame.
    pub foot: Point3<f32>,
    /// The body's path (m) and time (s) since the foot last touched down: the stride's speed so far.
    stride: [f32; 2],
}

impl LegState {
    /// Standing at `foot`.
    pub fn standing(foot: Point3<f32>) -> Self {
        LegState {
            phase: LegPhase::Stance { time: 1.0 },
            foot,
            stride: [0.0; 2],
        }
    }

    /// True in stance.
    pub fn in_stance(&self) -> bool {
        matches!(self.phase, LegPhase::Stance { .. })
    }
}

/// The planar base motion the legs see: heading frame now, the command followed and where the
/// command filter is taking it (a first-order lag toward the target with time constant `tau`).
#[derive(Clone, Copy, Debug)]
pub struct BaseMotion {
    /// Heading-frame origin (world x, y).
    pub position: Vector2<f32>,
    /// Heading yaw (rad).
    pub yaw: f32,
    /// Linear velocity in the heading frame (m/s).
    pub v: Vector2<f32>,
    /// Yaw rate (rad/s).
    pub wz: f32,
    /// Target linear velocity (m/s).
    pub v_target: Vector2<f32>,
    /// Target yaw rate (rad/s).
    pub wz_target: f32,
    /// Filter time constant (s).
    pub tau: f32,
}

impl BaseMotion {
    /// Fraction of the way from the current to the target command after `t` seconds.
    fn approach(&self, t: f32) -> f32 {
        1.0 - (-t / self.tau.max(1e-3)).exp()
    }

    /// Mean fraction of the way over `[0, t]` (so that the displacement is `mean velocity · t`).
    fn mean_approach(&self, t: f32) -> f32 {
        if t <= 1e-6 {
            return 0.0;
        }
        let tau = self.tau.max(1e-3);
        1.0 - tau / t * (1.0 - (-t / tau).exp())
    }

    /// Predicted linear velocity and yaw rate `t` seconds ahead.
    pub fn velocity_at(&self, t: f32) -> (Vector2<f32>, f32) {
        let a = self.approach(t);
        (
            self.v + (self.v_target - self.v) * a,
            self.wz + (self.wz_target - self.wz) * a,
        )
    }

    /// Mean linear velocity and yaw rate over `[t0, t0 + t]`.
    pub fn mean_velocity(&self, t0: f32, t: f32) -> (Vector2<f32>, f32) {
        let (v0, w0) = self.velocity_at(t0);
        // The lag from there on is the same filter's (only `tau` matters).
        let a = self.mean_approach(t);
        (v0 + (self.v_target - v0) * a, w0 + (self.wz_target - w0) * a)
    }

    /// World (x, y) of heading-frame point `p` after the base moves on for `t` seconds.
    pub fn predict(&self, p: Vector2<f32>, t: f32) -> Vector2<f32> {
        let (v, wz) = self.mean_velocity(0.0, t);
        let origin = self.position + rot(self.yaw + 0.5 * wz * t) * v * t;
        origin + rot(self.yaw + wz * t) * p
    }

    /// Heading-frame (x, y) of world point `p`.
    pub fn to_local(&self, p: &Point3<f32>) -> Vector2<f32> {
        rot(-self.yaw) * (Vector2::new(p.x, p.y) - self.position)
    }
}

/// 2-D rotation.
pub fn rot(a: f32) -> nalgebra::Matrix2<f32> {
    let (s, c) = a.sin_cos();
    nalgebra::Matrix2::new(c, -s, s, c)
}

/// Stepping parameters of this frame.
#[derive(Clone, Copy, Debug)]
pub struct StepParams {
    /// Whether legs may start new swings.
    pub stepping: bool,
    /// Gait clock phase in `[0, 1)`.
    pub clock: f32,
    /// Stepping frequency (Hz).
    pub frequency: f32,
    /// Duty factor.
    pub duty: f32,
    /// Swing height scale (× the leg's swing height).
    pub lift: f32,
    /// Shortest swing (s), by the body's speed now.
    pub min_swing: f32,
    /// The walks' shortest swing by the stride, when set: see [`StrideWalk`].
    pub stride_walk: Option<StrideWalk>,
    /// Height above the sole a swinging foot reaches before it moves horizontally, and below which it
    /// comes straight down (m): at least the first and last [`EDGE`] of the swing, longer when the
    /// swing is low next to this (at most [`MAX_EDGE`]).
    pub clearance: f32,
}

/// A swing that ends a stride at a walk lasts at least the walks' shortest swing, judged by the
/// body's mean speed since the foot last touched down (the stride's speed, as the gait measure takes
/// it) as well as by its speed now, and also once the foot is in the air: a body that speeds up from a
/// walk, or slows to one, lands the foot with a walking swing.
#[derive(Clone, Copy, Debug)]
pub struct StrideWalk {
    /// Speeds below this are walks (m/s).
    pub below: f32,
    /// The walks' shortest swing (s).
    pub min_swing: f32,
}

/// Swing height scale at Froude number `fr` ([`StepParams::lift`]): 0.7 of the leg's swing height at
/// rest, rising to all of it by Fr 1. Its lowest, at rest, has the longest rise and fall
/// ([`edge`]).
pub fn swing_lift(fr: f32) -> f32 {
    0.7 + 0.3 * fr.min(1.0)
}

/// Minimum-jerk profile 10s³ − 15s⁴ + 6s⁵.
pub fn min_jerk(s: f32) -> f32 {
    let s = s.clamp(0.0, 1.0);
    s * s * s * (10.0 + s * (-15.0 + 6.0 * s))
}

impl LegState {
    /// Advances one frame of `dt`: decides lift-off and touchdown and sets `self.foot`. `centre` is the
    /// centre of the leg's step region (heading frame): its nominal foothold, or where a bent spine
    /// has moved it. `offset` is the leg's lift-off phase in the current gait; `force` lifts a stance
    /// foot now (IK could not hold it). Returns true when the leg lifted off early: forced, or drifted
    /// beyond its step radius.
    #[allow(clippy::too_many_arguments)]
    pub fn step(
        &mut self,
        leg: &Leg,
        centre: Vector2<f32>,
        offset: f32,
        base: &BaseMotion,
        p: &StepParams,
        dt: f32,
        force: bool,
    ) -> bool {
        self.stride[0] += base.v.norm() * dt;
        self.stride[1] += dt;
        let min_swing = match p.stride_walk {
            Some(w) if self.stride[0] < w.below * self.stride[1] => p.min_swing.max(w.min_swing),
            _ => p.min_swing,
        };
        let shortest = (min_swing / dt).round() as u32;
        let stance_time = p.duty / p.frequency;
        let window = 1.0 - p.duty;
        let phase = (p.clock - offset).rem_euclid(1.0);
        let mut emergency = false;
        if let LegPhase::Stance { time } = &mut self.phase {
            *time += dt;
            // Where the foot is in its step region (1 on the boundary).
            let drift = leg.reach_fraction(base.to_local(&self.foot) - centre);
            // Due: early in the leg's swing window, or anywhere in it once the stance has lasted its
            // full time (after a gait change moved the window), or out of turn when a foot that has
            // stood its time is far out (the gait is just starting or speeding up).
            let due = p.stepping
                && *time >= 0.4 * stance_time
                && (phase < 0.5 * window
                    || (phase < window && *time >= stance_time)
                    || (*time >= stance_time && drift > 0.8));
            emergency = !due && ((drift > 1.0 && *time > dt) || force);
            if due || emergency {
                let nominal = window / p.frequency;
                let duration = if due && phase < window {
                    (window - phase) / p.frequency
                } else {
                    nominal
                };
                let duration = duration.clamp(min_swing.max(0.5 * nominal).min(nominal), nominal);
                self.phase = LegPhase::Swing {
                    frame: 0,
                    frames: ((duration / dt).round() as u32)
                        .max(shortest)
                        .max(1),
                    from: self.foot,
                    landing: None,
                };
            }
        }
        if let LegPhase::Swing {
            frame,
            frames,
            from,
            landing,
        } = &mut self.phase
        {
            if p.stride_walk.is_some() && shortest > *frames {
                // Lengthened by at most as much as keeps `frame / frames` from falling next frame, so
                // that the foot never moves back along its arc; it reaches the shortest swing over the
                // next frames.
                *frames = shortest.min(*frames + *frames / (*frame).max(1));
            }
            *frame += 1;
            let s = (*frame as f32 / *frames as f32).min(1.0);
            let remaining = (*frames - (*frame).min(*frames)) as f32 * dt;
            let target = match landing {
                Some(l) => *l,
                None => foothold(leg, centre, base, remaining, stance_time),
            };
            let height = leg.swing_height * p.lift;
            let edge = edge(p.clearance, height);
            if s >= 1.0 - edge {
                *landing = Some(target);
            }
            if *frame >= *frames {
                self.foot = Point3::new(target.x, target.y, leg.sole);
                self.phase = LegPhase::Stance { time: 0.0 };
                self.stride = [0.0; 2];
            } else {
                let u = min_jerk((s - edge) / (1.0 - 2.0 * edge));
                let xy = Vector2::new(from.x, from.y) + (target - Vector2::new(from.x, from.y)) * u;
                let s2 = s * (1.0 - s);
                let z = height * 16.0 * s2 * s2;
                self.foot = Point3::new(xy.x, xy.y, leg.sole + z.max(0.0));
            }
        }
        emergency
    }
}

/// The fraction of a swing of peak height `height` at each end without horizontal motion: [`EDGE`], or
/// where the arc `16 s²(1−s)²·height` reaches `clearance` if that is later (at most [`MAX_EDGE`]).
pub fn edge(clearance: f32, height: f32) -> f32 {
    if clearance <= 0.41 * height {
        // 16·0.2²·0.8² ≈ 0.41: the arc is already clear at EDGE.
        return EDGE;
    }
    let k = (clearance / height.max(1e-9)).sqrt().min(1.0);
    (0.5 * (1.0 - (1.0 - k).sqrt())).clamp(EDGE, MAX_EDGE)
}

/// World (x, y) where the leg should touch down, `remaining` seconds from now, for stance time
/// `stance_time`: centred on the motion predicted over that stance, about the step region's `centre`
/// (heading frame).
pub fn foothold(leg: &Leg, centre: Vector2<f32>, base: &BaseMotion, remaining: f32, stance_time: f32) -> Vector2<f32> {
    let half = 0.5 * stance_time;
    let (v, wz) = base.mean_velocity(remaining, stance_time);
    let mut local = rot(wz * half) * centre + v * half;
    let d = local - centre;
    let k = leg.reach_fraction(d);
    if k > FOOTHOLD_USE {
        local = centre + d * (FOOTHOLD_USE / k);
    }
    base.predict(local, remaining)
}

#[cfg(test)]
mod tests {
    use super::super::chain::Chain;
    use super::*;
    use nalgebra::Vector3;

    /// A leg with a 0.1 m swing and a 0.6 m step region, with no chain (stepping does not need one).
    fn leg() -> Leg {
        Leg {
            chain: Chain {
                links: Vec::new(),
                dofs: Vec::new(),
                tip: 0,
                tip_offset: Vector3::zeros(),
                damping: 0.0,
            },
            foot: 0,
            links: Vec::new(),
            hip: Vector3::zeros(),
            nominal: Vector2::new(0.5, 0.2),
            length: 1.0,
            r_max: 0.6,
            r_fore: 0.6,
            swing_height: 0.1,
            sole: 0.0,
            on_spine: false,
        }
    }

    /// The largest horizontal move of the foot between two frames below `clearance` over one swing forward
    /// at 1 m/s, and how far the foot moved in all.
    fn low_horizontal_motion(clearance: f32) -> (f32, f32) {
        let leg = leg();
        let dt = 1.0 / 30.0;
        let mut base = BaseMotion {
            position: Vector2::zeros(),
            yaw: 0.0,
            v: Vector2::new(1.0, 0.0),
            wz: 0.0,
            v_target: Vector2::new(1.0, 0.0),
            wz_target: 0.0,
            tau: 0.3,
        };
        let p = StepParams {
            stepping: true,
            clock: 0.0,
            frequency: 1.0,
            duty: 0.5,
            lift: 1.0,
            min_swing: 0.1,
            stride_walk: None,
            clearance,
        };
        let mut state = LegState::standing(Point3::new(0.5, 0.2, 0.0));
        let start = state.foot;
        state.step(&leg, leg.nominal, 0.0, &base, &p, dt, true);
        let (mut worst, mut prev) = (0.0f32, state.foot);
        while !state.in_stance() {
            base.position += base.v * dt;
            state.step(&leg, leg.nominal, 0.0, &base, &p, dt, false);
            if state.foot.z.max(prev.z) < clearance {
                worst = worst.max((state.foot.xy() - prev.xy()).norm());
            }
            prev = state.foot;
        }
        (worst, (state.foot.xy() - start.xy()).norm())
    }

    /// Frames in the air of a swing forced at frame `liftoff`, the body moving forward at `speeds[k]`
    /// (m/s) in frame `k` (the last speed from then on), its speed now a walk from frame `walk_now`
    /// (then the shortest swing is `walk` frames, before it the trot's 4); with `stride_walk`, strides
    /// below 1 m/s are walks (5 frames). Also whether the swing's progress `frame / frames` ever fell
    /// (the foot moving back along its arc).
    fn air_frames(speeds: &[f32], liftoff: usize, walk_now: usize, walk: f32, stride_walk: bool) -> (usize, bool) {
        let (leg, dt) = (leg(), 1.0 / 30.0);
        let mut base = BaseMotion {
            position: Vector2::zeros(),
            yaw: 0.0,
            v: Vector2::zeros(),
            wz: 0.0,
            v_target: Vector2::zeros(),
            wz_target: 0.0,
            tau: 0.3,
        };
        let mut p = StepParams {
            stepping: false,
            clock: 0.0,
            frequency: 5.0,
            duty: 0.5,
            lift: 1.0,
            min_swing: 0.0,
            stride_walk: stride_walk.then_some(StrideWalk { below: 1.0, min_swing: 5.0 * dt }),
            clearance: 0.0,
        };
        let mut state = LegState::standing(Point3::new(0.5, 0.2, 0.0));
        let (mut air, mut back) = (0, false);
        for k in 0.. {
            let v = Vector2::new(speeds[k.min(speeds.len() - 1)], 0.0);
            (base.v, base.v_target) = (v, v);
            base.position += v * dt;
            p.min_swing = if k >= walk_now { walk } else { 4.0 } * dt;
            let progress = |state: &LegState| match state.phase {
                LegPhase::Swing { frame, frames, .. } => frame as f32 / frames as f32,
                LegPhase::Stance { .. } => 0.0,
            };
            let before = progress(&state);
            state.step(&leg, leg.nominal, 0.0, &base, &p, dt, k == liftoff);
            back |= !state.in_stance() && progress(&state) < before;
            if k >= liftoff {
                if state.in_stance() {
                    break;
                }
                air += 1;
            }
        }
        (air, back)
    }

    #[test]
    fn a_swing_ending_a_walking_stride_is_a_walking_swing() {
        // Speeding up from a walk: five frames at 0.5 m/s, lift-off at 2 m/s. The stride so far
        // averages 0.7 m/s, a walk, though the body's speed now is a trot's.
        let speeding = [0.5, 0.5, 0.5, 0.5, 0.5, 2.0];
        assert_eq!(air_frames(&speeding, 5, usize::MAX, 5.0, true), (4, false));
        assert_eq!(air_frames(&speeding, 5, usize::MAX, 5.0, false), (3, false));
        // Slowing to a walk in any frame of a trotting swing (3 frames in the air from lift-off at
        // frame 5): the swing under way lengthens by a frame, and its progress never falls.
        let slowing = [2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 0.3];
        for walk_now in 6..=8 {
            assert_eq!(air_frames(&slowing, 5, walk_now, 5.0, true), (4, false), "walk from {walk_now}");
            assert_eq!(air_frames(&slowing, 5, walk_now, 5.0, false), (3, false), "walk from {walk_now}");
        }
        // A much longer shortest swing, late in the air: the swing lengthens frame by frame to it,
        // never by so much at once that the foot would move back.
        assert_eq!(air_frames(&slowing, 5, 8, 8.0, true), (7, false));
        // Early in the air too: three times the swing, reached without the swing's progress falling.
        assert_eq!(air_frames(&slowing, 5, 6, 12.0, true), (11, false));
        // A trot all the way takes the trot's swing.
        assert_eq!(air_frames(&[2.0], 5, usize::MAX, 5.0, true), (3, false));
    }

    #[test]
    fn a_low_swing_moves_only_once_clear_of_the_ground() {
        // The swing is 0.1 m high; at EDGE it is 41 mm up. With a clearance of 80 mm it still rises
        // and lands straight, and still makes its step.
        let (low, step) = low_horizontal_motion(0.08);
        assert!(low < 1e-6, "moved {low} m horizontally below the clearance");
        assert!(step > 0.3, "{step}");
        // The edge is where the arc reaches the clearance, EDGE when it is clear there, MAX_EDGE at most.
        let e = edge(0.08, 0.1);
        assert!((16.0 * e * e * (1.0 - e) * (1.0 - e) * 0.1 - 0.08).abs() < 1e-4, "{e}");
        assert_eq!(edge(0.02, 0.1), EDGE);
        assert_eq!(edge(0.2, 0.1), MAX_EDGE);
    }
}
