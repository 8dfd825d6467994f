//! Reaching: each reach group (a manipulator chain, or the leftover DoFs such as a head) moves to random
//! reachable targets, holds, and moves on.
//!
//! Targets are joint configurations drawn within the limits (or the stowed nominal configuration, with
//! [`ReachConfig::stow_probability`]). A human's hand mostly makes small moves near where it is, at
//! speeds from a slow reach to a quick wave, and a motion prior can only offer what its dataset shows:
//! so with [`ReachConfig::local_probability`] a target is drawn near the current configuration
//! (each DoF within [`ReachConfig::local_fraction`] of its range), otherwise anywhere within the
//! limits, and each move's speed is drawn between [`ReachConfig::speed_fraction`] and
//! [`ReachConfig::max_speed_fraction`] of the velocity limits. The end-effector target is the
//! targets' forward kinematics, so it is
//! reachable by construction. A draw is accepted only if the whole path to it — a minimum-jerk
//! interpolation in joint space, sampled at [`PATH_SAMPLES`] points — keeps the group's links clear of
//! the body, of the legs anywhere in their workspace, of the paths the other groups are following, and
//! above the ground; otherwise up to [`ATTEMPTS`] draws are tried before the group heads back to its
//! stowed configuration. Joint-space interpolation between in-limit configurations never leaves the
//! limits, and the duration follows the URDF velocity limits so that reaches look deliberate.

use nalgebra::Isometry3;
use rand::RngExt;
use serde::{Deserialize, Serialize};

use super::chain::Chain;
use super::collide::{Obb, Proxies};
use super::legs::min_jerk;
use super::rig::{Obstacle, ReachGroup, ReachKind, Rig, finite_limits, subtree};
use super::uniform;
use crate::kinematics::{CharacterPose, JointKind, KinematicTree};
use crate::morphology::Morphology;

/// Clearance above the ground kept by reaching links (m), unless they stand lower.
const GROUND_MARGIN: f32 = 0.01;

/// The reach groups of a character: one per manipulator (the DoFs on its chain that no leg, wheel or
/// earlier manipulator owns), then one for every DoF left over. `claimed` marks DoFs already owned.
pub fn groups(
    tree: &KinematicTree,
    morph: &Morphology,
    proxies: &Proxies,
    standing: &CharacterPose,
    claimed: &[bool],
) -> Vec<ReachGroup> {
    let mut claimed = claimed.to_vec();
    let mut out = Vec::new();
    for &m in &morph.manipulators {
        let dofs: Vec<usize> = Chain::new(tree, morph, m)
            .active_dofs()
            .filter(|&d| !claimed[d])
            .collect();
        if let Some(&first) = dofs.first() {
            for &d in &dofs {
                claimed[d] = true;
            }
            out.push((ReachKind::Arm(m), subtree(tree, tree.dof_link(first)), dofs));
        }
    }
    let misc: Vec<usize> = (0..tree.dof()).filter(|&d| !claimed[d]).collect();
    if !misc.is_empty() {
        let mut links: Vec<usize> = misc.iter().flat_map(|&d| subtree(tree, tree.dof_link(d))).collect();
        links.sort_unstable();
        links.dedup();
        out.push((ReachKind::Misc, links, misc));
    }
    let world = tree.forward_kinematics(standing);
    out.into_iter()
        .map(|(kind, links, dofs)| {
            // Never required higher than at the standing pose (some robots stand with the arm low).
            let standing_low = links
                .iter()
                .flat_map(|&l| proxies.world(l, &world[l]))
                .map(|b| b.min_z())
                .fold(f32::INFINITY, f32::min);
            ReachGroup {
                kind,
                dofs,
                links,
                floor: GROUND_MARGIN.min(standing_low - 1e-3),
                tolerated: Vec::new(),
                windows: Vec::new(),
            }
        })
        .collect()
}

impl ReachGroup {
    /// Sets the range each DoF draws its targets from: its limits, narrowed for an arm by
    /// [`ReachConfig::home_reach`] to the values that move the tip at most that fraction of the arm's
    /// length from its stowed position (`nominal`, the whole joint vector) on their own (to first
    /// order: the DoF's lever arm at the stowed configuration).
    pub fn set_home_windows(&mut self, tree: &KinematicTree, nominal: &[f32], home_reach: Option<f32>) {
        let limits = self.dofs.iter().map(|&d| finite_limits(tree, d, nominal[d]));
        let (Some(fraction), ReachKind::Arm(tip)) = (home_reach, self.kind) else {
            self.windows = limits.collect();
            return;
        };
        let stowed = fk_root(tree, nominal);
        let first = tree.dof_link(self.dofs[0]);
        let tip_at = |poses: &[Isometry3<f32>]| poses[tip].translation.vector;
        let reach = fraction * (tip_at(&stowed) - stowed[first].translation.vector).norm();
        const STEP: f32 = 1e-3;
        let mut q = nominal.to_vec();
        self.windows = self
            .dofs
            .iter()
            .zip(limits)
            .map(|(&d, (lo, hi))| {
                q[d] += STEP;
                let lever = (tip_at(&fk_root(tree, &q)) - tip_at(&stowed)).norm() / STEP;
                q[d] = nominal[d];
                // A DoF that hardly moves the tip (a wrist roll) keeps its whole range.
                let half = reach / lever.max(1e-6);
                ((nominal[d] - half).max(lo), (nominal[d] + half).min(hi))
            })
            .collect();
    }

    /// Marks the obstacles the group already touches in its stowed configuration (`nominal`, root
    /// frame), grown by `margin`.
    pub fn tolerate(&mut self, proxies: &Proxies, nominal: &[Isometry3<f32>], obstacles: &[Obstacle], margin: f32) {
        let boxes: Vec<(usize, Obb)> = self
            .links
            .iter()
            .flat_map(|&l| proxies.world(l, &nominal[l]).map(move |b| (l, b)))
            .collect();
        self.tolerated = obstacles
            .iter()
            .map(|o| {
                boxes
                    .iter()
                    .any(|(l, b)| proxies.is_checked(*l, o.link) && b.overlaps(&o.obb, margin))
            })
            .collect();
    }
}

/// Points at which a candidate path is checked.
pub const PATH_SAMPLES: usize = 8;
/// Draws per new target before falling back to the stowed configuration.
pub const ATTEMPTS: usize = 24;

/// Reaching settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReachConfig {
    /// Probability that the next target is the stowed (nominal) configuration.
    pub stow_probability: f32,
    /// How long a target is held (s). A person's hands rest for seconds between gestures, and a
    /// prior learns to hold an arm still only from a dataset that does: with holds of 0.2–2 s, Spot's
    /// arm was on the move most of the time and its prior moved the gripper while the hand rested.
    pub hold_seconds: [f32; 2],
    /// Fraction of each joint's velocity limit used by the slowest-finishing joint on the slowest moves.
    pub speed_fraction: f32,
    /// The same on the fastest moves; each move draws its fraction uniformly between the two. A
    /// minimum-jerk move peaks at 1.875 times its mean speed, so fractions up to 0.53 keep every joint
    /// within its velocity limit.
    pub max_speed_fraction: f32,
    /// Probability that a target is drawn near the current configuration rather than anywhere.
    pub local_probability: f32,
    /// How far a near target may lie from the current configuration, per DoF, as a fraction of the
    /// DoF's range.
    pub local_fraction: f32,
    /// How far an arm's targets may take its tip from where it is stowed, as a fraction of the arm's
    /// length (its first moving joint to its tip, stowed); `None`: anywhere within the limits. Each
    /// DoF draws within the angle (or travel) that moves the tip that far on its own, so a shoulder
    /// turns a little and a wrist a lot. A person's hand moves within a few tenths of a body length of
    /// where it rests; an arm that roams its whole workspace in the dataset is what the
    /// discriminator then asks for, against the hand's motion that L_fea asks for. Other reach groups
    /// (heads, tails) are not limited.
    pub home_reach: Option<f32>,
    /// Velocity assumed for revolute joints without a limit (rad/s).
    pub default_angular_speed: f32,
    /// Velocity assumed for prismatic joints without a limit (m/s).
    pub default_linear_speed: f32,
    /// Shortest reach (s).
    pub min_duration: f32,
    /// Clearance kept between a reaching limb and everything else (m), on top of the collision proxies'
    /// own tolerance.
    pub margin: f32,
}

impl Default for ReachConfig {
    fn default() -> Self {
        ReachConfig {
            stow_probability: 0.2,
            hold_seconds: [0.5, 5.0],
            speed_fraction: 0.2,
            max_speed_fraction: 0.5,
            local_probability: 0.5,
            local_fraction: 0.15,
            home_reach: None,
            default_angular_speed: 2.0,
            default_linear_speed: 0.5,
            min_duration: 0.6,
            margin: 0.0,
        }
    }
}

/// The motion of one reach group.
#[derive(Clone, Debug)]
pub struct ReachState {
    /// Configuration at the start of the current move (group DoFs, in group order).
    pub from: Vec<f32>,
    /// Target configuration.
    pub to: Vec<f32>,
    /// Progress in `[0, 1]`.
    pub s: f32,
    /// Duration of the move (s).
    pub duration: f32,
    /// Hold time left after arriving (s).
    pub hold: f32,
}

impl ReachState {
    /// At rest in configuration `q` (group DoFs), holding for `hold` seconds.
    pub fn at(q: Vec<f32>, hold: f32) -> Self {
        ReachState {
            from: q.clone(),
            to: q,
            s: 1.0,
            duration: 1.0,
            hold,
        }
    }

    /// The configuration at progress `s`.
    pub fn config_at(&self, s: f32, out: &mut [f32]) {
        let u = min_jerk(s);
        for (o, (a, b)) in out.iter_mut().zip(self.from.iter().zip(&self.to)) {
            *o = a + (b - a) * u;
        }
    }

    /// The current configuration.
    pub fn current(&self, out: &mut [f32]) {
        self.config_at(self.s, out);
    }
}

/// What [`step_reach`] did this frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReachEvents {
    /// New targets drawn and accepted.
    pub targets: usize,
    /// Groups sent back to their stowed configuration because no draw had a clear path.
    pub fallbacks: usize,
}

/// Moves every reach group by one frame: advances moves, and draws new targets for groups whose hold
/// is over. `q` holds the whole joint vector (groups' DoFs are written).
pub fn step_reach<R: rand::Rng + ?Sized>(
    tree: &KinematicTree,
    rig: &Rig,
    cfg: &ReachConfig,
    states: &mut [ReachState],
    q: &mut [f32],
    dt: f32,
    rng: &mut R,
) -> ReachEvents {
    let mut events = ReachEvents::default();
    let mut cur = Vec::new();
    for g in 0..states.len() {
        let st = &mut states[g];
        if st.s < 1.0 {
            st.s = (st.s + dt / st.duration).min(1.0);
        } else {
            st.hold -= dt;
            if st.hold <= 0.0 {
                if plan(tree, rig, cfg, states, g, rng) {
                    events.targets += 1;
                } else {
                    events.fallbacks += 1;
                }
            }
        }
        let group = &rig.reach[g];
        cur.resize(group.dofs.len(), 0.0);
        states[g].current(&mut cur);
        for (&d, &x) in group.dofs.iter().zip(&cur) {
            q[d] = clamp_dof(tree, d, x);
        }
    }
    events
}

fn clamp_dof(tree: &KinematicTree, d: usize, x: f32) -> f32 {
    match tree.limits(d) {
        Some(l) => x.clamp(l.lower, l.upper),
        None => x,
    }
}

/// Draws the next target of group `g` and starts moving to it; false when no draw had a clear path and
/// the group heads back to its stowed configuration.
fn plan<R: rand::Rng + ?Sized>(
    tree: &KinematicTree,
    rig: &Rig,
    cfg: &ReachConfig,
    states: &mut [ReachState],
    g: usize,
    rng: &mut R,
) -> bool {
    let group = &rig.reach[g];
    let mut current = vec![0.0; group.dofs.len()];
    states[g].current(&mut current);
    // Paths the other groups are still following (from now to their target).
    let mut others: Vec<Obb> = Vec::new();
    let mut other_links: Vec<usize> = Vec::new();
    for (h, st) in states.iter().enumerate() {
        if h == g {
            continue;
        }
        let oh = &rig.reach[h];
        let mut cfgq = vec![0.0; oh.dofs.len()];
        let mut full = rig.nominal_q.clone();
        let samples = if st.s < 1.0 { PATH_SAMPLES } else { 1 };
        for k in 0..samples {
            let s = if samples == 1 {
                1.0
            } else {
                st.s + (1.0 - st.s) * k as f32 / (samples - 1) as f32
            };
            st.config_at(s, &mut cfgq);
            for (&d, &x) in oh.dofs.iter().zip(&cfgq) {
                full[d] = x;
            }
            let links = fk_root(tree, &full);
            for &l in oh.links.iter().filter(|l| !group.links.contains(l)) {
                for b in rig.proxies.world(l, &links[l]) {
                    others.push(b);
                    other_links.push(l);
                }
            }
        }
    }
    let mut full = rig.nominal_q.clone();
    for (h, st) in states.iter().enumerate() {
        if h != g {
            let mut c = vec![0.0; rig.reach[h].dofs.len()];
            st.current(&mut c);
            for (&d, &x) in rig.reach[h].dofs.iter().zip(&c) {
                full[d] = x;
            }
        }
    }
    let stowed: Vec<f32> = group.dofs.iter().map(|&d| rig.nominal_q[d]).collect();
    let mut chosen = None;
    let local = rng.random::<f32>() < cfg.local_probability;
    for attempt in 0..ATTEMPTS {
        let target: Vec<f32> = if attempt == 0 && !local && rng.random::<f32>() < cfg.stow_probability {
            stowed.clone()
        } else {
            current
                .iter()
                .zip(&group.windows)
                .map(|(&now, &(lo, hi))| {
                    if local {
                        let r = cfg.local_fraction * (hi - lo);
                        let now = now.clamp(lo, hi);
                        uniform(rng, (now - r).max(lo), (now + r).min(hi))
                    } else {
                        uniform(rng, lo, hi)
                    }
                })
                .collect()
        };
        if path_clear(
            tree,
            rig,
            cfg,
            group,
            &current,
            &target,
            &mut full,
            &others,
            &other_links,
        ) {
            chosen = Some(target);
            break;
        }
    }
    let found = chosen.is_some();
    let to = chosen.unwrap_or(stowed);
    let speed = uniform(rng, cfg.speed_fraction, cfg.max_speed_fraction.max(cfg.speed_fraction));
    let duration = group
        .dofs
        .iter()
        .zip(current.iter().zip(&to))
        .map(|(&d, (a, b))| {
            let j = tree.dof_joint(d);
            let default = if j.kind == JointKind::Prismatic {
                cfg.default_linear_speed
            } else {
                cfg.default_angular_speed
            };
            let v = j.limits.map_or(default, |l| l.velocity).min(default * 3.0);
            (b - a).abs() / (speed * v).max(1e-3)
        })
        .fold(cfg.min_duration, f32::max);
    states[g] = ReachState {
        from: current,
        to,
        s: 0.0,
        duration,
        hold: uniform(rng, cfg.hold_seconds[0], cfg.hold_seconds[1]),
    };
    found
}

/// Link poses in the root frame.
fn fk_root(tree: &KinematicTree, q: &[f32]) -> Vec<Isometry3<f32>> {
    tree.forward_kinematics(&CharacterPose {
        root: Isometry3::identity(),
        q: q.to_vec(),
    })
}

/// Whether the minimum-jerk path from `from` to `to` keeps the group clear (see the module docs).
#[allow(clippy::too_many_arguments)]
fn path_clear(
    tree: &KinematicTree,
    rig: &Rig,
    cfg: &ReachConfig,
    group: &ReachGroup,
    from: &[f32],
    to: &[f32],
    full: &mut [f32],
    others: &[Obb],
    other_links: &[usize],
) -> bool {
    let st = ReachState {
        from: from.to_vec(),
        to: to.to_vec(),
        s: 0.0,
        duration: 1.0,
        hold: 0.0,
    };
    let mut c = vec![0.0; group.dofs.len()];
    let low_root = rig.height_range[0];
    for k in 1..=PATH_SAMPLES {
        st.config_at(k as f32 / PATH_SAMPLES as f32, &mut c);
        for (&d, &x) in group.dofs.iter().zip(&c) {
            full[d] = x;
        }
        let links = fk_root(tree, full);
        for &a in &group.links {
            let boxes: Vec<Obb> = rig.proxies.world(a, &links[a]).collect();
            if boxes.is_empty() {
                continue;
            }
            // Ground: the lowest point with the body at its lowest and most tilted (a pitch p lowers a
            // point at distance x ahead of or behind the root by up to |x|·sin p).
            for b in &boxes {
                let r = b.radius();
                let drop =
                    (b.center.x.abs() + r) * rig.max_tilt[0].sin() + (b.center.y.abs() + r) * rig.max_tilt[1].sin();
                if b.min_z() + low_root - drop < group.floor {
                    return false;
                }
            }
            // Own links.
            for &b in &group.links {
                if b > a
                    && rig.proxies.is_checked(a, b)
                    && boxes
                        .iter()
                        .any(|x| rig.proxies.world(b, &links[b]).any(|y| x.overlaps(&y, cfg.margin)))
                {
                    return false;
                }
            }
            // Body and legs over their workspace.
            for (o, _) in rig.swept.iter().zip(&group.tolerated).filter(|(_, t)| !**t) {
                if !group.links.contains(&o.link)
                    && rig.proxies.is_checked(a, o.link)
                    && boxes.iter().any(|x| x.overlaps(&o.obb, cfg.margin))
                {
                    return false;
                }
            }
            // Other groups' paths.
            for (o, &l) in others.iter().zip(other_links) {
                if rig.proxies.is_checked(a, l) && boxes.iter().any(|x| x.overlaps(o, cfg.margin)) {
                    return false;
                }
            }
        }
    }
    true
}
