//! [`Rig`]: everything the controllers need to know about a character, derived once from its kinematic
//! tree and morphology — leg chains with their nominal stance and reachable step radius, wheels, the DoF
//! groups that reach, the nominal body height and its safe range, the speed scale and the gaits.
//!
//! Nothing here depends on link names: legs are the chains to [`Morphology::feet`], arms the chains to
//! [`Morphology::manipulators`], wheels [`Morphology::wheels`]; every other DoF (a head, gripper
//! fingers) is moved by a "misc" reach group.
//!
//! How each leg's stance, step radius, sole and swing height, the body's height and tilt range and the
//! appendages' stowed configuration are found is described in [`super::calibrate`]; episodes start
//! with the appendages stowed ([`Rig::standing`]). The **speed scale** is the mean hip–foot distance at
//! the nominal stance / [`super::ScalingConfig::human_leg_length`] for legged characters, the standing
//! height / [`super::ScalingConfig::human_height`] otherwise. The **hip height** is
//! [`crate::dynamic_similarity::hip_height_at`] the nominal stance; gaits are chosen and timed by the Froude number it gives
//! ([`super::gait`]). The **top speed** is what the fastest gait can follow at its highest cadence with
//! stances within the step radii, and each faster gait takes over no later than where the slower one
//! runs out of stride.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector2, Vector3};

use super::chain::Chain;
use super::collide::{Obb, Proxies};
use super::gait::{Gait, build_gaits};
use super::joint_speed::{swing_foot_speed_limit, swing_speed_ratio};
use super::spine::SpineJoint;
use super::undulation::Undulation;
use super::{ControllerConfig, ControllerError, calibrate, reach, spine, wheels};
use crate::dynamic_similarity::{froude, hip_height_at, speed_at_froude, speed_for_stride, stride_frequency, stride_length};
use crate::kinematics::{CharacterPose, JointKind, KinematicTree};
use crate::morphology::Morphology;

/// How the base moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BaseMode {
    /// On legs: stepping gaits.
    Legged,
    /// On wheels: planar holonomic motion, wheels roll.
    Wheeled,
    /// A legless creature: crawls by undulating its body ([`super::undulation`]).
    Crawling,
    /// Neither legs nor wheels: the base stays put, only reaching moves.
    Fixed,
}

/// One leg.
#[derive(Clone, Debug)]
pub struct Leg {
    /// Chain from the root to the foot link.
    pub chain: Chain,
    /// The foot link ([`Morphology::feet`]).
    pub foot: usize,
    /// Links that move with the leg (the subtree of its first moving joint).
    pub links: Vec<usize>,
    /// First moving joint's position in the root frame at the nominal pose.
    pub hip: Vector3<f32>,
    /// Nominal foothold in the heading frame (x, y; the ground is z = 0).
    pub nominal: Vector2<f32>,
    /// Hip–foot distance at the nominal stance (m).
    pub length: f32,
    /// Largest safe horizontal distance of a stance foot from its nominal foothold in any direction
    /// (m): the step region's semi-axis across the body.
    pub r_max: f32,
    /// The step region's semi-axis along the body (forward and back, m; at least `r_max`): the region
    /// is the ellipse with these semi-axes around the nominal foothold (heading frame).
    pub r_fore: f32,
    /// Peak swing height (m).
    pub swing_height: f32,
    /// Height of the foot point above the ground in stance (m): 0 unless the foot's geometry would
    /// dip below the ground at the nominal stance with the foot point on it (a foot point found at a
    /// straight-legged neutral pose, say), then just enough to keep the geometry on the ground.
    pub sole: f32,
    /// Whether spine DoFs ([`Morphology::spine`]) lie between the root and the hip: bending the spine
    /// moves the hip (the chain's IK holds those DoFs).
    pub on_spine: bool,
}

impl Leg {
    /// Where offset `d` (heading frame, from the nominal foothold) lies in the step region: 1 on its
    /// boundary, less inside.
    pub fn reach_fraction(&self, d: Vector2<f32>) -> f32 {
        (d.x / self.r_fore.max(1e-6)).hypot(d.y / self.r_max.max(1e-6))
    }

    /// The step region's radius in the direction of `dir` (any length; `r_max` for a zero vector).
    pub fn radius_toward(&self, dir: Vector2<f32>) -> f32 {
        let n = dir.norm();
        if n < 1e-9 {
            self.r_max
        } else {
            n / self.reach_fraction(dir)
        }
    }

    /// The point of the step region's boundary at angle `a` (rad, from forward), scaled by `scale`.
    pub fn region_point(&self, a: f32, scale: f32) -> Vector2<f32> {
        self.nominal + Vector2::new(a.cos() * self.r_fore, a.sin() * self.r_max) * scale
    }
}

/// One wheel.
#[derive(Clone, Debug)]
pub struct Wheel {
    /// Its DoF.
    pub dof: usize,
    /// Spin axis in the root frame.
    pub axis: Vector3<f32>,
    /// Centre in the root frame.
    pub center: Vector3<f32>,
    /// Radius (height of the axle above the ground when standing, m).
    pub radius: f32,
}

/// What a reach group moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReachKind {
    /// A manipulator chain (its end-effector link).
    Arm(usize),
    /// DoFs no leg, arm or wheel owns (heads, fingers).
    Misc,
}

/// A set of DoFs that moves to random targets together.
#[derive(Clone, Debug)]
pub struct ReachGroup {
    /// What it is.
    pub kind: ReachKind,
    /// The DoFs it moves.
    pub dofs: Vec<usize>,
    /// Links that move when these DoFs move.
    pub links: Vec<usize>,
    /// Lowest z its links may reach with the body at the bottom of its range (m).
    pub floor: f32,
    /// For each of [`Rig::swept`]: whether the group already touches that obstacle in its stowed
    /// (nominal) configuration — coarse boxes of neighbouring parts often do — so that paths are not
    /// refused for it.
    pub tolerated: Vec<bool>,
    /// The range each DoF draws its targets from ([`ReachGroup::set_home_windows`]).
    pub windows: Vec<(f32, f32)>,
}

/// A collision box of a link that does not belong to some group, in the root frame.
#[derive(Clone, Debug)]
pub struct Obstacle {
    /// The link.
    pub link: usize,
    /// Its box.
    pub obb: Obb,
}

/// The controllers' model of a character (see the module docs).
#[derive(Clone, Debug)]
pub struct Rig {
    /// How the base moves.
    pub mode: BaseMode,
    /// The pose episodes start from: [`KinematicTree::standing_pose`] with the appendages stowed
    /// ([`calibrate::stow_appendages`]).
    pub standing: CharacterPose,
    /// Joint vector at the nominal stance.
    pub nominal_q: Vec<f32>,
    /// Root height at the nominal stance (m).
    pub nominal_height: f32,
    /// Root height range used for body height variation (m).
    pub height_range: [f32; 2],
    /// Largest body pitch and roll (rad).
    pub max_tilt: [f32; 2],
    /// Legs, in [`Morphology::feet`] order.
    pub legs: Vec<Leg>,
    /// Wheels.
    pub wheels: Vec<Wheel>,
    /// Spine DoFs a legged creature bends ([`super::spine`]; empty for a URDF).
    pub spine: Vec<SpineJoint>,
    /// The yaw rate at which the spine bends fully into a turn ([`spine::full_turn_rate`], rad/s).
    pub spine_turn_rate: f32,
    /// A legless creature's crawl ([`BaseMode::Crawling`]).
    pub crawl: Option<Undulation>,
    /// Reach groups: one per manipulator, then the misc group if any DoF is left.
    pub reach: Vec<ReachGroup>,
    /// Gaits, sorted by the speed from which they are used.
    pub gaits: Vec<Gait>,
    /// Mean leg length (m; 0 without legs).
    pub leg_length: f32,
    /// Hip height for the laws of [`crate::dynamic_similarity`] (m; 0 without legs).
    pub hip_height: f32,
    /// Multiplies human-equivalent speeds (m/s) into character speeds.
    pub speed_scale: f32,
    /// Largest foot speed `|v| + |ω|·foot_radius` the legs follow cleanly, or a wheeled base's wheels
    /// allow within their velocity limits (m/s): the top linear speed when not turning. Infinite
    /// without legs or limited wheels.
    pub max_speed: f32,
    /// The largest speed (m/s, relative to the root) at which every leg's joints let its swinging foot
    /// move in any horizontal direction within their velocity limits ([`super::joint_speed`]); it
    /// bounds each gait's speed (and [`Rig::max_speed`]) by [`super::joint_speed::swing_speed_ratio`].
    /// Infinite without legs, without limits or with [`super::ScalingConfig::leg_limits`] off.
    pub foot_speed_limit: f32,
    /// With [`super::LegConfig::cadence_limit`]: the largest foot speed forward or back and sideways
    /// (m/s) at which the legs keep their stances inside the step regions stepping at most that multiple
    /// of the law's stride frequency (and within the shortest swing); commands are limited to the
    /// ellipse with these semi-axes ([`super::CommandGenerator`]). `None` without the limit or legs.
    pub cadence_speeds: Option<[f32; 2]>,
    /// Mean distance of the feet (a wheeled base: the farthest wheel's) from the root axis (m), for
    /// turning.
    pub foot_radius: f32,
    /// Height a swinging foot rises before it moves horizontally (m; 0 without legs): the band within
    /// which UFR counts a foot as in contact ([`crate::metrics::UfrConfig::CONTACT_HEIGHT`] × the body
    /// length), so that a low swing (a long body on short legs: swing heights follow the leg length)
    /// does not scuff along the ground.
    pub clearance: f32,
    /// Collision proxies.
    pub proxies: Proxies,
    /// Boxes of every link at the nominal pose with legs moved over their workspace (root frame at the
    /// nominal height); reach groups check their paths against these.
    pub swept: Vec<Obstacle>,
    /// Link poses at the nominal pose in the root frame.
    pub nominal_links: Vec<Isometry3<f32>>,
}

/// Root pose with the base at height `h` tilted by `pitch` and `roll` (no yaw, at the origin).
pub fn tilted_root(h: f32, pitch: f32, roll: f32) -> Isometry3<f32> {
    Isometry3::from_parts(
        Translation3::new(0.0, 0.0, h),
        UnitQuaternion::from_euler_angles(roll, pitch, 0.0),
    )
}

/// The subtree of link `l` (itself included), in link order.
pub fn subtree(tree: &KinematicTree, l: usize) -> Vec<usize> {
    (0..tree.links.len()).filter(|&x| tree.is_descendant(x, l)).collect()
}

/// Froude number below which a gait transition hands over from a walking gait (walk → trot near
/// Fr 0.3–0.5, wave → ripple → tripod), as opposed to the trot → gallop one near Fr 2–3.
const WALKING_HANDOVER: f32 = 1.0;

impl Rig {
    /// Analyses a character for `cfg` at `fps` frames per second.
    pub fn new(
        tree: &KinematicTree,
        morph: &Morphology,
        cfg: &ControllerConfig,
        fps: f32,
    ) -> Result<Rig, ControllerError> {
        if tree.dof() == 0 {
            return Err(ControllerError::Rigid);
        }
        let mut standing = tree.standing_pose();
        let h_stand = standing.root.translation.vector.z;
        let mut proxies = Proxies::new(tree, &standing);

        let mut legs = calibrate::legs(tree, morph, &standing)?;
        let mode = if !legs.is_empty() {
            BaseMode::Legged
        } else if !morph.wheels.is_empty() {
            BaseMode::Wheeled
        } else if !morph.body_axis.is_empty() {
            BaseMode::Crawling
        } else {
            BaseMode::Fixed
        };
        let (h0, mut nominal_q) = calibrate::nominal_stance(tree, &mut legs, &standing, cfg.legs.max_extension)?;
        // The pairs tested at the standing pose, before those touching at the nominal stance are let go.
        let rest_proxies = proxies.clone();
        proxies.ignore_touching(&calibrate::fk_root(tree, &nominal_q));

        let (mut height_range, mut max_tilt) = ([h_stand, h_stand], [0.0, 0.0]);
        let on_leg: Vec<bool> = (0..tree.links.len())
            .map(|l| legs.iter().any(|g| g.links.contains(&l)))
            .collect();
        if mode == BaseMode::Legged {
            let p = &cfg.posture;
            height_range = [h0 * (1.0 + p.height[0]), h0 * (1.0 + p.height[1])];
            max_tilt = [p.pitch.abs(), p.roll.abs()];
            // Keep the body (everything not on a leg) 2 % of its height off the ground when lowest and
            // most tilted.
            let body: Vec<usize> = (0..tree.links.len()).filter(|&l| !on_leg[l]).collect();
            let low = calibrate::lowest_tilted(&proxies, &calibrate::fk_root(tree, &nominal_q), &body, max_tilt);
            height_range[0] = height_range[0].max(0.02 * h0.max(0.1) - low).min(h0);
            let dip_tol = calibrate::dip_tolerance(tree, &standing);
            // Appendages (a tail, a head, arms) are not obstacles for the step regions but are stowed
            // clear of the legs' workspace; where one cannot be, the legs step around it as it is.
            let mut wheel_dof = vec![false; tree.dof()];
            for w in wheels::find(tree, morph, &standing) {
                wheel_dof[w.dof] = true;
            }
            let appendage = calibrate::appendages(tree, &legs, &wheel_dof);
            let (legs0, q0) = (legs.clone(), nominal_q.clone());
            let mut ignore = appendage.clone();
            loop {
                let kept = calibrate::step_radii(
                    tree,
                    &proxies,
                    &mut legs,
                    &mut nominal_q,
                    h0,
                    height_range,
                    max_tilt,
                    dip_tol,
                    &ignore,
                )?;
                calibrate::swing_heights(tree, &mut legs, &nominal_q, kept.height[0], cfg.legs.swing_height);
                if !ignore.iter().any(|&i| i) {
                    (height_range, max_tilt) = (kept.height, kept.tilt);
                    break;
                }
                let obstacles = calibrate::obstacles(tree, &proxies, &legs, &nominal_q, h0, kept.height, |l| !ignore[l]);
                let floor = 0.02 * h0.max(0.1) - kept.height[0];
                let margin = cfg.reach.margin;
                let stuck =
                    calibrate::stow_appendages(tree, &rest_proxies, &ignore, &mut nominal_q, &obstacles, floor, margin);
                if stuck.is_empty() {
                    (height_range, max_tilt) = (kept.height, kept.tilt);
                    break;
                }
                // Calibrate again with the appendages that found no clear stowage as obstacles.
                for top in stuck {
                    for l in subtree(tree, top) {
                        ignore[l] = false;
                    }
                }
                (legs, nominal_q) = (legs0.clone(), q0.clone());
            }
            // Episodes start with the appendages stowed; pairs they touched at the nominal stance are
            // tested again where they no longer touch.
            let mut moved = vec![false; tree.links.len()];
            for d in 0..tree.dof() {
                if !appendage[tree.dof_link(d)] || standing.q[d] == nominal_q[d] {
                    continue;
                }
                standing.q[d] = nominal_q[d];
                for l in subtree(tree, tree.dof_link(d)) {
                    moved[l] = true;
                }
            }
            if moved.iter().any(|&m| m) {
                proxies.recheck(&rest_proxies, &calibrate::fk_root(tree, &nominal_q), &moved);
            }
        }
        let nominal_links = calibrate::fk_root(tree, &nominal_q);

        let mut claimed = vec![false; tree.dof()];
        for d in legs.iter().flat_map(|l| l.chain.active_dofs()) {
            claimed[d] = true;
        }
        // A legged creature's spine bends as a body; a legless one's axis crawls.
        let spine = if mode == BaseMode::Legged { spine::joints(tree, morph, &legs, &nominal_q) } else { Vec::new() };
        if mode == BaseMode::Legged {
            for &d in &morph.spine {
                claimed[d] = true;
            }
        }
        let crawl = if mode == BaseMode::Crawling {
            Some(Undulation::new(tree, morph, &nominal_q).map_err(ControllerError::Crawl)?)
        } else {
            None
        };
        if let Some(c) = &crawl {
            for d in c.segments.iter().chain(&c.lifts).map(|j| j.dof).chain(c.held.iter().copied()) {
                claimed[d] = true;
            }
        }
        let wheels = wheels::find(tree, morph, &standing);
        for w in &wheels {
            claimed[w.dof] = true;
        }
        let mut reach = reach::groups(tree, morph, &proxies, &standing, &claimed);

        // Obstacles for reaching: legs over their workspace, the rest of the body at the nominal pose
        // (reach groups check each other's actual paths instead).
        let in_reach: Vec<bool> = (0..tree.links.len())
            .map(|l| reach.iter().any(|g| g.links.contains(&l)))
            .collect();
        let mut swept = calibrate::obstacles(tree, &proxies, &legs, &nominal_q, h0, height_range, |l| !in_reach[l]);
        // And the body wherever the spine bends it.
        swept.extend(spine::swept(tree, &proxies, &spine, &nominal_q, |l| !in_reach[l] && !on_leg[l]));
        for g in &mut reach {
            g.tolerate(&proxies, &nominal_links, &swept, cfg.reach.margin);
            g.set_home_windows(tree, &nominal_q, cfg.reach.home_reach);
        }

        let mut rig = Rig {
            mode,
            standing,
            nominal_q,
            nominal_height: h0,
            height_range,
            max_tilt,
            legs,
            wheels,
            spine,
            spine_turn_rate: spine::TURN_RATE,
            crawl,
            reach,
            gaits: Vec::new(),
            leg_length: 0.0,
            hip_height: 0.0,
            speed_scale: 1.0,
            max_speed: f32::INFINITY,
            foot_speed_limit: f32::INFINITY,
            cadence_speeds: None,
            foot_radius: 0.0,
            clearance: 0.0,
            proxies,
            swept,
            nominal_links,
        };
        rig.set_speeds(tree, morph, cfg, fps);
        if let Some(c) = &rig.crawl {
            rig.max_speed = c.max_speed;
        }
        if rig.mode == BaseMode::Wheeled && cfg.scaling.wheel_limits {
            rig.limit_to_wheels(tree);
        }
        if let (None, Some(pace)) = (cfg.scaling.speed_scale, cfg.scaling.walking_pace) {
            rig.speed_scale = rig.speed_scale.min(rig.max_speed / pace);
        }
        rig.spine_turn_rate = spine::full_turn_rate(rig.max_speed, rig.cadence_speeds, rig.foot_radius);
        Ok(rig)
    }

    /// A wheeled base's top speed from its wheels' velocity limits: a wheel's contact point moves at
    /// most `|v| + |ω|·r` along its rolling direction (`r` its distance from the root axis), so
    /// `max_speed` is the slowest wheel's limit times its radius and `foot_radius` the farthest
    /// wheel's distance, and commands within `|v| + |ω|·foot_radius ≤ max_speed` spin no wheel past
    /// its limit. Wheels without a limit leave the speed free.
    fn limit_to_wheels(&mut self, tree: &KinematicTree) {
        self.max_speed = self
            .wheels
            .iter()
            .map(|w| tree.dof_joint(w.dof).limits.and_then(|l| l.velocity_bound()).unwrap_or(f32::INFINITY) * w.radius)
            .fold(f32::INFINITY, f32::min);
        self.foot_radius = self.wheels.iter().map(|w| w.center.xy().norm()).fold(0.0, f32::max);
    }

    /// Gaits, speed scale and top speed (module docs).
    fn set_speeds(&mut self, tree: &KinematicTree, morph: &Morphology, cfg: &ControllerConfig, fps: f32) {
        let feet_xy: Vec<[f32; 2]> = self.legs.iter().map(|l| [l.nominal.x, l.nominal.y]).collect();
        self.gaits = build_gaits(&feet_xy);
        let n = self.legs.len().max(1) as f32;
        self.leg_length = self.legs.iter().map(|l| l.length).sum::<f32>() / n;
        if !self.legs.is_empty() {
            let nominal = CharacterPose {
                root: tilted_root(self.nominal_height, 0.0, 0.0),
                q: self.nominal_q.clone(),
            };
            self.hip_height = hip_height_at(tree, morph, &nominal).unwrap_or(self.leg_length);
        }
        self.foot_radius = self.legs.iter().map(|l| l.nominal.norm()).sum::<f32>() / n;
        if !self.legs.is_empty() {
            self.clearance =
                crate::metrics::UfrConfig::CONTACT_HEIGHT * crate::features::character_body_length(tree, morph);
        }
        let height = {
            let b = tree.aabb(&tree.forward_kinematics(&self.standing));
            (b.max.z - b.min.z).max(1e-3)
        };
        self.speed_scale = cfg.scaling.speed_scale.unwrap_or(if self.mode == BaseMode::Legged {
            self.leg_length / cfg.scaling.human_leg_length
        } else {
            height / cfg.scaling.human_height
        });
        if self.mode != BaseMode::Legged {
            return;
        }
        // The highest foot speed (m/s) a gait follows with duty `duty` at Froude number `fr`: its
        // stance fits in the step radius at its highest cadence.
        // Top speeds are forward: the step regions' fore-and-aft semi-axes.
        let r_min = self.legs.iter().map(|l| l.r_fore).fold(f32::INFINITY, f32::min);
        let h = self.hip_height;
        // With leg limits, also no faster than the swinging feet can move with the leg joints within
        // their velocity limits at the gait's duty factor ([`super::joint_speed`]), taken with the
        // shortest horizontal share of a swing: the lowest lift the controller swings with
        // ([`super::legs::swing_lift`] at rest) has the longest rise and fall.
        if cfg.scaling.leg_limits {
            self.foot_speed_limit = self.slowest_swing_foot_speed(tree);
        }
        let foot_speed_limit = self.foot_speed_limit;
        let edge = self
            .legs
            .iter()
            .map(|l| super::legs::edge(self.clearance, super::legs::swing_lift(0.0) * l.swing_height))
            .fold(0.0, f32::max);
        // With a cadence limit `k` and `walking`, also no faster than where the law's stride, stepped k
        // times as often, fits the stance at the gait's smallest duty factor
        // (`λ(v) ≤ 2·STANCE_USE·r·k / duty`), so that a walk too short in the leg for the law's strides
        // hands over to the trot early. Only out of the walking gaits: the trot's hand-over to the gallop
        // stays at the Froude number animals gallop at (the commands' cadence limit slows the trot).
        // `duty_fr`: the Froude number the duty factor is taken at (the transition's own, as before
        // the cadence limit, so that datasets recorded without it regenerate unchanged).
        let capacity = |g: &Gait, duty_fr: f32, fr: f32, walking: bool| {
            let duty = g.duty_at(duty_fr);
            let c = frequency_cap(cfg, duty, fr, fps) * 2.0 * super::legs::STANCE_USE * r_min / duty;
            let c = c.min(foot_speed_limit / swing_speed_ratio(duty, edge));
            match cfg.legs.cadence_limit.filter(|_| walking) {
                Some(k) => {
                    let floor = g.duty[0].min(g.duty[1]);
                    c.min(speed_for_stride(2.0 * super::legs::STANCE_USE * r_min * k / floor, h))
                }
                None => c,
            }
        };
        for k in 1..self.gaits.len() {
            let (from, prev_from) = (self.gaits[k].from_froude, self.gaits[k - 1].from_froude);
            if from <= prev_from {
                continue;
            }
            let limit = self.gaits[..k]
                .iter()
                .filter(|g| g.from_froude == prev_from)
                .map(|g| capacity(g, from, 0.99 * from, from < WALKING_HANDOVER)) // still in the slower gait
                .fold(f32::INFINITY, f32::min)
                * 0.95;
            let limit = froude(limit, h) / (1.0 + super::gait::GaitSelector::BAND);
            if limit < from {
                for g in self.gaits.iter_mut().skip(k).filter(|g| g.from_froude == from) {
                    g.from_froude = limit.max(froude(0.05 * self.speed_scale, h));
                }
            }
        }
        let top = self.gaits.iter().map(|g| g.from_froude).fold(0.0, f32::max);
        // The top gait's capacity at the speed it reaches: iterate, as the duty and the frame cap
        // depend on the Froude number.
        let mut v = speed_at_froude(top, h).max(1e-3);
        for _ in 0..20 {
            let fr = froude(v, h);
            v = self
                .gaits
                .iter()
                .filter(|g| g.from_froude == top)
                .map(|g| capacity(g, fr, fr, false))
                .fold(f32::INFINITY, f32::min);
        }
        self.max_speed = v;
        self.cadence_speeds = cfg.legs.cadence_limit.map(|k| {
            let fore = self.legs.iter().map(|l| l.r_fore).fold(f32::INFINITY, f32::min);
            let side = self.legs.iter().map(|l| l.r_max).fold(f32::INFINITY, f32::min);
            [self.cadence_speed(fore, k), self.cadence_speed(side, k)]
        });
    }

    /// [`Rig::foot_speed_limit`]: the slowest leg's, each at the middle of its swing
    /// ([`super::joint_speed::swing_foot_speed_limit`]) from the nominal stance.
    fn slowest_swing_foot_speed(&self, tree: &KinematicTree) -> f32 {
        let root = tilted_root(self.nominal_height, 0.0, 0.0);
        let mut scratch = super::ChainScratch::default();
        self.legs
            .iter()
            .map(|l| {
                let foot = root.inverse_transform_point(&Point3::new(l.nominal.x, l.nominal.y, l.sole));
                swing_foot_speed_limit(tree, &l.chain, &self.nominal_q, foot, l.swing_height, &mut scratch)
            })
            .fold(f32::INFINITY, f32::min)
    }

    /// The largest foot speed (m/s, at most [`Rig::max_speed`], which keeps to the shortest swing) up to
    /// which stances fit in step radius `r` at a stride frequency of at most `k` times the law's, in every
    /// gait the selector may be in at that speed (the hysteresis band included), with the duty factor
    /// the controller steps with ([`Gait::duty_fitting`]).
    fn cadence_speed(&self, r: f32, k: f32) -> f32 {
        const STEPS: usize = 400;
        let h = self.hip_height;
        let band = super::gait::GaitSelector::BAND;
        // The next faster threshold above each gait's own.
        let next = |g: &Gait| {
            self.gaits
                .iter()
                .map(|o| o.from_froude)
                .filter(|&f| f > g.from_froude)
                .fold(f32::INFINITY, f32::min)
        };
        let mut ok = 0.0;
        for i in 1..=STEPS {
            let v = self.max_speed * i as f32 / STEPS as f32;
            let fr = froude(v, h);
            let fits = self
                .gaits
                .iter()
                .filter(|g| g.from_froude * (1.0 - band) <= fr && fr <= next(g) * (1.0 + band))
                .all(|g| {
                    let room = 2.0 * super::legs::STANCE_USE * r;
                    let duty = g.duty_fitting(fr, stride_length(v, h) / k, room);
                    let needed = v * duty / room;
                    needed <= k * stride_frequency(v, h) * 1.0001
                });
            if !fits {
                break;
            }
            ok = v;
        }
        ok
    }
}

/// Shortest swing (frames, lift-off to touchdown) at Froude number `fr`:
/// [`super::LegConfig::walking_min_swing_frames`] in the walks (below
/// [`crate::dynamic_similarity::WALK_TROT_FROUDE`], a margin over the gait measure's walking Froude
/// number), else [`super::LegConfig::min_swing_frames`].
pub fn min_swing_frames(cfg: &ControllerConfig, fr: f32) -> u32 {
    let frames = if fr < crate::dynamic_similarity::WALK_TROT_FROUDE {
        cfg.legs.walking_min_swing_frames.max(cfg.legs.min_swing_frames)
    } else {
        cfg.legs.min_swing_frames
    };
    frames.max(1)
}

/// Highest stepping frequency with duty factor `duty` at Froude number `fr` (Hz): swings last at least
/// [`min_swing_frames`].
pub fn frequency_cap(cfg: &ControllerConfig, duty: f32, fr: f32, fps: f32) -> f32 {
    (1.0 - duty) * fps / min_swing_frames(cfg, fr) as f32
}

/// Position limits of DoF `d`, with continuous joints limited to ±π around `centre`.
pub fn finite_limits(tree: &KinematicTree, d: usize, centre: f32) -> (f32, f32) {
    match tree.limits(d) {
        Some(l) if l.lower.is_finite() && l.upper.is_finite() => (l.lower, l.upper),
        _ => {
            let pi = if tree.dof_joint(d).kind == JointKind::Prismatic {
                0.1
            } else {
                std::f32::consts::PI
            };
            (centre - pi, centre + pi)
        }
    }
}
