//! Random base commands: targets `(vx, vy, ωz)` in the body's heading frame, held for random
//! durations, followed through a first-order filter so that transitions are smooth.
//!
//! Linear ranges are given in **human-equivalent m/s** (the paper's −1.5…5 m/s) and multiplied by the
//! character's speed scale (see [`super::ScalingConfig`]); the yaw rate (−1…1 rad/s) is not scaled.

use rand::RngExt;
use serde::{Deserialize, Serialize};

use super::uniform;

/// Ranges and timing of the random commands. Linear speeds in human-equivalent m/s.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CommandConfig {
    /// Forward speed range (paper: −1.5…5 m/s).
    pub forward: [f32; 2],
    /// Sideways speed range.
    pub lateral: [f32; 2],
    /// Yaw rate range (rad/s; paper: −1…1).
    pub yaw_rate: [f32; 2],
    /// How long a target is held (s).
    pub hold_seconds: [f32; 2],
    /// Time constant of the first-order filter from target to followed command (s).
    pub time_constant: f32,
    /// Probability that a target is "stand still".
    pub p_stand: f32,
    /// Probability that a target is a pure turn on the spot.
    pub p_turn: f32,
    /// Probability that a target has a sideways component (else forward/backward plus turning).
    pub p_lateral: f32,
    /// Probability that the forward speed is drawn from the slow band `slow` rather than the full range
    /// (so that walking speeds, where gaits are most varied, are well covered).
    pub p_slow: f32,
    /// The slow band of forward speeds.
    pub slow: [f32; 2],
}

impl Default for CommandConfig {
    fn default() -> Self {
        CommandConfig {
            forward: [-1.5, 5.0],
            lateral: [-1.0, 1.0],
            yaw_rate: [-1.0, 1.0],
            hold_seconds: [1.0, 5.0],
            time_constant: 0.4,
            p_stand: 0.08,
            p_turn: 0.07,
            p_lateral: 0.3,
            p_slow: 0.4,
            slow: [-0.8, 1.8],
        }
    }
}

/// A base command: linear velocity `(vx, vy)` (m/s, heading frame) and yaw rate `wz` (rad/s).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Command {
    /// Forward velocity (m/s).
    pub vx: f32,
    /// Leftward velocity (m/s).
    pub vy: f32,
    /// Yaw rate (rad/s, counter-clockwise seen from above).
    pub wz: f32,
}

impl Command {
    /// As an array `[vx, vy, wz]`.
    pub fn to_array(self) -> [f32; 3] {
        [self.vx, self.vy, self.wz]
    }

    /// Linear speed.
    pub fn speed(&self) -> f32 {
        self.vx.hypot(self.vy)
    }

    /// `self + (target − self)·a`.
    pub fn lerp(&self, target: &Command, a: f32) -> Command {
        Command {
            vx: self.vx + (target.vx - self.vx) * a,
            vy: self.vy + (target.vy - self.vy) * a,
            wz: self.wz + (target.wz - self.wz) * a,
        }
    }
}

/// Draws random targets and filters them.
#[derive(Clone, Debug)]
pub struct CommandGenerator {
    cfg: CommandConfig,
    /// Multiplies human-equivalent linear speeds.
    scale: f32,
    /// Largest foot speed `|v| + |ω|·turn_radius` the character can follow cleanly (m/s, scaled).
    max_speed: f32,
    /// Radius at which turning adds to the foot speed (m).
    turn_radius: f32,
    /// Foot speeds forward and sideways the legs follow at a natural cadence (m/s), when limited so.
    cadence: Option<[f32; 2]>,
    target: Command,
    current: Command,
    remaining: f32,
}

impl CommandGenerator {
    /// A generator standing still, with linear speeds multiplied by `scale` and limited so that
    /// `|v| + |ω|·turn_radius ≤ max_speed`.
    pub fn new(cfg: CommandConfig, scale: f32, max_speed: f32, turn_radius: f32) -> Self {
        CommandGenerator {
            cfg,
            scale,
            max_speed,
            turn_radius,
            cadence: None,
            target: Command::default(),
            current: Command::default(),
            remaining: 0.0,
        }
    }

    /// Limits commands to what the legs follow at a natural cadence ([`super::Rig::cadence_speeds`]):
    /// `|v| / v_max(θ) + |ω|·turn_radius / side ≤ 1`, where `v_max(θ)` is the ellipse with semi-axes
    /// `fore` (along the body) and `side` in the direction `θ` of `v` (a turning foot moves across its
    /// leg's step region, as a sideways one does). A command beyond it is scaled down whole, turning
    /// included.
    pub fn with_cadence_speeds(mut self, speeds: Option<[f32; 2]>) -> Self {
        self.cadence = speeds;
        self
    }

    /// Back to standing still; the first target is "stand" for `stand_seconds`.
    pub fn reset(&mut self, stand_seconds: f32) {
        self.target = Command::default();
        self.current = Command::default();
        self.remaining = stand_seconds;
    }

    /// The current target (what the controller is asked to reach).
    pub fn target(&self) -> Command {
        self.target
    }

    /// The filtered command the base follows.
    pub fn current(&self) -> Command {
        self.current
    }

    /// Sets a fixed target (no random draws until `hold` seconds have passed).
    pub fn set_target(&mut self, target: Command, hold: f32) {
        self.target = self.limit(target);
        self.remaining = hold;
    }

    /// Advances by `dt`: draws a new target when the hold time is over, then filters.
    pub fn step<R: rand::Rng + ?Sized>(&mut self, dt: f32, rng: &mut R) -> Command {
        self.remaining -= dt;
        if self.remaining <= 0.0 {
            self.target = self.limit(self.draw(rng));
            self.remaining = uniform(rng, self.cfg.hold_seconds[0], self.cfg.hold_seconds[1]);
        }
        // Exact discretisation of the first-order lag.
        let a = 1.0 - (-dt / self.cfg.time_constant.max(1e-3)).exp();
        self.current = self.current.lerp(&self.target, a);
        self.current
    }

    fn draw<R: rand::Rng + ?Sized>(&self, rng: &mut R) -> Command {
        let c = &self.cfg;
        let u: f32 = rng.random();
        if u < c.p_stand {
            return Command::default();
        }
        let wz = uniform(rng, c.yaw_rate[0], c.yaw_rate[1]);
        if u < c.p_stand + c.p_turn {
            return Command { vx: 0.0, vy: 0.0, wz };
        }
        let band = if rng.random::<f32>() < c.p_slow {
            c.slow
        } else {
            c.forward
        };
        let vx = uniform(rng, band[0].max(c.forward[0]), band[1].min(c.forward[1]));
        let vy = if rng.random::<f32>() < c.p_lateral {
            uniform(rng, c.lateral[0], c.lateral[1])
        } else {
            0.0
        };
        // Turning while running fast is drawn smaller, as animals do.
        let wz = wz / (1.0 + 0.3 * vx.abs().max(0.0));
        Command {
            vx: vx * self.scale,
            vy: vy * self.scale,
            wz,
        }
    }

    /// Limits the command to what the character can follow: by the cadence ellipse when set
    /// ([`CommandGenerator::with_cadence_speeds`]), else its linear speed to what the legs follow while
    /// turning at `c.wz`.
    fn limit(&self, mut c: Command) -> Command {
        if let Some([fore, side]) = self.cadence {
            let (fore, side) = (fore.max(1e-6), side.max(1e-6));
            let load = (c.vx / fore).hypot(c.vy / side) + c.wz.abs() * self.turn_radius / side;
            if load > 1.0 {
                c.vx /= load;
                c.vy /= load;
                c.wz /= load;
            }
            return c;
        }
        // Turning alone may not exceed the top speed either (a wheeled base turning on the spot).
        if c.wz.abs() * self.turn_radius > self.max_speed {
            c.wz = c.wz.signum() * self.max_speed / self.turn_radius;
        }
        let s = c.speed();
        let allowed = (self.max_speed - c.wz.abs() * self.turn_radius).max(0.0);
        if s > allowed {
            let k = allowed / s;
            c.vx *= k;
            c.vy *= k;
        }
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn turning_alone_is_held_within_the_top_speed() {
        // Top speed 0.6 m/s at 0.3 m from the axis (a wheeled base's farthest wheel).
        let g = CommandGenerator::new(CommandConfig::default(), 1.0, 0.6, 0.3);
        let c = g.limit(Command { vx: 0.0, vy: 0.0, wz: -3.0 });
        assert!((c.wz + 2.0).abs() < 1e-6, "{c:?}");
        // Within it, the turn stays and the linear speed takes what is left.
        let c = g.limit(Command { vx: 1.0, vy: 0.0, wz: 1.0 });
        assert!((c.vx - 0.3).abs() < 1e-6 && c.wz == 1.0, "{c:?}");
    }

    #[test]
    fn filter_settles_on_the_target_and_draws_stay_in_range() {
        let mut g = CommandGenerator::new(CommandConfig::default(), 0.5, 10.0, 0.3);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        g.reset(0.0);
        g.set_target(
            Command {
                vx: 1.0,
                vy: 0.0,
                wz: 0.5,
            },
            100.0,
        );
        for _ in 0..300 {
            g.step(1.0 / 30.0, &mut rng);
        }
        assert!((g.current().vx - 1.0).abs() < 1e-3 && (g.current().wz - 0.5).abs() < 1e-3);
        for _ in 0..20_000 {
            g.step(1.0 / 30.0, &mut rng);
            let t = g.target();
            assert!((-0.75..=2.5).contains(&t.vx), "{t:?}");
            assert!((-0.5..=0.5).contains(&t.vy) && (-1.0..=1.0).contains(&t.wz));
        }
    }

    #[test]
    fn the_cadence_ellipse_scales_a_command_down_whole() {
        let g = CommandGenerator::new(CommandConfig::default(), 0.5, 10.0, 0.3).with_cadence_speeds(Some([2.0, 0.5]));
        let c = |vx, vy, wz| Command { vx, vy, wz };
        // Inside the ellipse: unchanged.
        let inside = g.limit(c(1.0, 0.2, 0.5));
        assert_eq!((inside.vx, inside.vy, inside.wz), (1.0, 0.2, 0.5));
        // Straight ahead at twice the forward cadence speed: halved.
        assert!((g.limit(c(4.0, 0.0, 0.0)).vx - 2.0).abs() < 1e-6);
        // Sideways, the shorter axis binds.
        assert!((g.limit(c(0.0, -1.0, 0.0)).vy + 0.5).abs() < 1e-6);
        // Diagonal plus turning: the load is 1 after scaling and the direction is kept.
        let l = g.limit(c(2.0, 0.5, 1.0));
        let load = (l.vx / 2.0).hypot(l.vy / 0.5) + l.wz.abs() * 0.3 / 0.5;
        assert!((load - 1.0).abs() < 1e-5, "{l:?}");
        assert!((l.vx / l.vy - 4.0).abs() < 1e-4 && (l.wz / l.vx - 0.5).abs() < 1e-4, "{l:?}");
        // Without a cadence limit only the maximum speed binds.
        let free = CommandGenerator::new(CommandConfig::default(), 0.5, 10.0, 0.3);
        assert_eq!(free.limit(c(4.0, 0.0, 0.0)).vx, 4.0);
    }
}
