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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::controller::ControllerConfig;
    use crate::test_data::close;
    use nalgebra::{Matrix3, Point3, Vector3};
    use rand::SeedableRng;
    use rand_pcg::Pcg64 as StdRng;

    /// A three-joint arm on a box lying on the ground (its root 0.1 m up): a yaw at the box's top, a
    /// shoulder and an elbow pitching forward (+x) for positive angles, a 0.1 m upper post, a 0.4 m
    /// upper arm and a 0.4 m forearm, standing straight up at 0.
    const ARM: &str = r#"<robot name="arm">
      <link name="base"><collision><geometry><box size="0.4 0.4 0.2"/></geometry></collision></link>
      <joint name="yaw" type="revolute"><parent link="base"/><child link="post"/><origin xyz="0 0 0.1"/><axis xyz="0 0 1"/><limit lower="-2" upper="2" velocity="2" effort="1"/></joint>
      <link name="post"><collision><origin xyz="0 0 0.05"/><geometry><cylinder radius="0.03" length="0.1"/></geometry></collision></link>
      <joint name="shoulder" type="revolute"><parent link="post"/><child link="upper"/><origin xyz="0 0 0.1"/><axis xyz="0 1 0"/><limit lower="-1.6" upper="1.6" velocity="1" effort="1"/></joint>
      <link name="upper"><collision><origin xyz="0 0 0.2"/><geometry><cylinder radius="0.025" length="0.4"/></geometry></collision></link>
      <joint name="elbow" type="revolute"><parent link="upper"/><child link="fore"/><origin xyz="0 0 0.4"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" velocity="10" effort="1"/></joint>
      <link name="fore"><collision><origin xyz="0 0 0.2"/><geometry><cylinder radius="0.02" length="0.4"/></geometry></collision></link>
    </robot>"#;

    fn arm() -> (KinematicTree, Morphology, Rig) {
        let tree = KinematicTree::from_urdf_str(ARM).unwrap();
        let morph = Morphology::analyze(&tree);
        let rig = Rig::new(&tree, &morph, &ControllerConfig::default(), 30.0).unwrap();
        assert_eq!(rig.reach.len(), 1, "one arm, no leftover DoF");
        assert_eq!(rig.reach[0].dofs, [0, 1, 2]);
        assert!(rig.nominal_q.iter().all(|&x| x == 0.0), "stowed straight up: {:?}", rig.nominal_q);
        (tree, morph, rig)
    }

    fn link(tree: &KinematicTree, name: &str) -> usize {
        tree.link_index(name).unwrap()
    }

    /// The smallest and largest of `v`.
    fn span(v: &[f32]) -> (f32, f32) {
        v.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &x| (lo.min(x), hi.max(x)))
    }

    /// Targets drawn anywhere within the windows, never the stowed configuration.
    fn anywhere() -> ReachConfig {
        ReachConfig {
            stow_probability: 0.0,
            local_probability: 0.0,
            ..ReachConfig::default()
        }
    }

    /// An axis-aligned box in the root frame.
    fn cube(center: [f32; 3], half: f32) -> Obb {
        Obb {
            center: Point3::from(center),
            axes: Matrix3::identity(),
            half: Vector3::repeat(half),
        }
    }

    /// Whether the path from straight up to `to` is clear, with `others` (and their links) in the way.
    fn clear(tree: &KinematicTree, rig: &Rig, cfg: &ReachConfig, to: [f32; 3], others: &[(Obb, usize)]) -> bool {
        let (boxes, links): (Vec<Obb>, Vec<usize>) = others.iter().copied().unzip();
        let mut full = rig.nominal_q.clone();
        path_clear(tree, rig, cfg, &rig.reach[0], &[0.0; 3], &to, &mut full, &boxes, &links)
    }

    #[test]
    fn a_move_follows_a_minimum_jerk_curve_from_its_start_to_its_target() {
        let st = ReachState {
            from: vec![1.0, -2.0],
            to: vec![3.0, 2.0],
            s: 0.25,
            duration: 1.0,
            hold: 0.0,
        };
        let mut out = [0.0; 2];
        st.config_at(0.0, &mut out);
        assert_eq!(out, [1.0, -2.0]);
        st.config_at(1.0, &mut out);
        assert_eq!(out, [3.0, 2.0]);
        st.config_at(0.5, &mut out);
        assert_eq!(out, [2.0, 0.0]);
        // At a quarter of the way in time, 10·s³ − 15·s⁴ + 6·s⁵ = 0.103515625 of the way in space.
        st.current(&mut out);
        assert!(close(&out, &[1.0 + 2.0 * 0.103515625, -2.0 + 4.0 * 0.103515625], 1e-6), "{out:?}");
        let rest = ReachState::at(vec![0.5], 2.0);
        assert_eq!((rest.from, rest.to, rest.s, rest.hold), (vec![0.5], vec![0.5], 1.0, 2.0));
    }

    #[test]
    fn a_group_moves_for_its_duration_holds_then_draws_its_next_target() {
        let (tree, _, rig) = arm();
        let cfg = ReachConfig::default();
        let mut rng = StdRng::seed_from_u64(1);
        let mut q = rig.nominal_q.clone();
        let mut states = vec![ReachState {
            from: vec![0.0; 3],
            to: vec![0.5, 0.5, 0.5],
            s: 0.0,
            duration: 2.0,
            hold: 0.5,
        }];
        let mut step = |states: &mut Vec<ReachState>, q: &mut Vec<f32>, dt: f32| {
            step_reach(&tree, &rig, &cfg, states, q, dt, &mut rng)
        };
        // Half a second of a two-second move: a quarter of the way, written to the group's DoFs.
        assert_eq!(step(&mut states, &mut q, 0.5), ReachEvents::default());
        assert_eq!((states[0].s, states[0].hold), (0.25, 0.5));
        assert!(close(&q, &[0.5 * 0.103515625; 3], 1e-6), "{q:?}");
        // A long frame ends the move at the target; the hold has not started.
        step(&mut states, &mut q, 10.0);
        assert_eq!((states[0].s, states[0].hold), (1.0, 0.5));
        assert_eq!(q, [0.5; 3]);
        // Holding counts down, and nothing new is drawn while time is left.
        assert_eq!(step(&mut states, &mut q, 0.25), ReachEvents::default());
        assert_eq!((states[0].hold, states[0].to.clone()), (0.25, vec![0.5; 3]));
        // The hold ends at exactly zero: a new move starts from where the group stands.
        let ev = step(&mut states, &mut q, 0.25);
        assert_eq!(ev.targets + ev.fallbacks, 1, "{ev:?}");
        assert_eq!((states[0].s, states[0].from.clone()), (0.0, vec![0.5; 3]));
        assert_eq!(q, [0.5; 3]);
    }

    #[test]
    fn a_target_beyond_the_limits_is_clamped_to_them() {
        let (tree, _, rig) = arm();
        let mut q = rig.nominal_q.clone();
        let mut states = vec![ReachState::at(vec![5.0, -5.0, 5.0], 10.0)];
        let mut rng = StdRng::seed_from_u64(1);
        step_reach(&tree, &rig, &ReachConfig::default(), &mut states, &mut q, 0.1, &mut rng);
        assert_eq!(q, [2.0, -1.6, 3.0]);
    }

    /// Plans group 0 once from `current` (holding, due) and returns the new state and whether a clear
    /// target was found.
    fn plan_from(tree: &KinematicTree, rig: &Rig, cfg: &ReachConfig, current: [f32; 3], seed: u64) -> (ReachState, bool) {
        let mut states = vec![ReachState::at(current.to_vec(), 0.0)];
        let found = plan(tree, rig, cfg, &mut states, 0, &mut StdRng::seed_from_u64(seed));
        (states.remove(0), found)
    }

    #[test]
    fn a_move_lasts_as_long_as_its_slowest_joint_needs_at_the_drawn_speed() {
        let (tree, _, rig) = arm();
        // Always back to the stowed configuration, at a quarter of the velocity limits, holding 1.5 s.
        let cfg = ReachConfig {
            stow_probability: 1.0,
            local_probability: 0.0,
            speed_fraction: 0.25,
            max_speed_fraction: 0.25,
            hold_seconds: [1.5, 1.5],
            ..ReachConfig::default()
        };
        let (st, found) = plan_from(&tree, &rig, &cfg, [0.5, 0.5, 0.5], 3);
        assert!(found);
        assert_eq!((st.from.clone(), st.to.clone(), st.s, st.hold), (vec![0.5; 3], vec![0.0; 3], 0.0, 1.5));
        // The yaw needs 0.5 / (0.25 · 2) = 1 s, the shoulder 0.5 / (0.25 · 1) = 2 s, the elbow less.
        assert!((st.duration - 2.0).abs() < 1e-5, "{}", st.duration);
        // The elbow's 10 rad/s counts as at most three times the default 2 rad/s: 3 / (0.25 · 6) = 2 s.
        let (st, _) = plan_from(&tree, &rig, &cfg, [0.0, 0.0, 3.0], 3);
        assert!((st.duration - 2.0).abs() < 1e-5, "{}", st.duration);
        // To a target other than the stowed one (the windows pinned at 0.4): the shoulder's 0.9 rad
        // take 3.6 s.
        let mut pinned = rig.clone();
        pinned.reach[0].windows = vec![(0.4, 0.4); 3];
        let unstowed = ReachConfig { stow_probability: 0.0, ..cfg.clone() };
        let (st, found) = plan_from(&tree, &pinned, &unstowed, [-0.5; 3], 3);
        assert!(found);
        assert_eq!(st.to, [0.4; 3]);
        assert!((st.duration - 3.6).abs() < 1e-4, "{}", st.duration);
        // A small move takes the shortest duration.
        let (st, _) = plan_from(&tree, &rig, &cfg, [0.01, 0.0, 0.0], 3);
        assert_eq!(st.duration, cfg.min_duration);
        // Each move draws its speed between the two fractions.
        let between = ReachConfig {
            speed_fraction: 0.25,
            max_speed_fraction: 0.5,
            ..cfg.clone()
        };
        let durations: Vec<f32> = (0..40).map(|seed| plan_from(&tree, &rig, &between, [0.0, 1.0, 0.0], seed).0.duration).collect();
        let (lo, hi) = span(&durations);
        assert!(lo >= 2.0 - 1e-4 && hi <= 4.0 + 1e-4 && hi - lo > 1.0, "{lo} {hi}");
    }

    #[test]
    fn near_targets_stay_within_their_fraction_of_each_range_and_far_ones_span_it() {
        let (tree, _, rig) = arm();
        let windows = rig.reach[0].windows.clone();
        assert_eq!(windows, [(-2.0, 2.0), (-1.6, 1.6), (-3.0, 3.0)]);
        let near = ReachConfig {
            local_probability: 1.0,
            stow_probability: 1.0,
            local_fraction: 0.1,
            ..ReachConfig::default()
        };
        // From the yaw's upper limit: up to 0.4 rad back, never past it; never the stowed configuration.
        // The shoulder and elbow, away from their limits, move either way.
        let current = [2.0, 0.3, 0.0];
        let (mut below, mut above) = ([0.0f32; 3], [0.0f32; 3]);
        for seed in 0..60 {
            let (st, found) = plan_from(&tree, &rig, &near, current, seed);
            assert!(found);
            for (k, ((x, c), (lo, hi))) in st.to.iter().zip(current).zip(&windows).enumerate() {
                let r = 0.1 * (hi - lo);
                assert!((x - c).abs() <= r + 1e-5 && *x >= *lo && *x <= *hi, "DoF {k}: {x} from {c}");
                below[k] = below[k].max((c - x) / r);
                above[k] = above[k].max((x - c) / r);
            }
        }
        assert!(below.iter().all(|&f| f > 0.8), "near targets hardly move: {below:?}");
        assert!(above[0] == 0.0 && above[1] > 0.8 && above[2] > 0.8, "near targets move one way: {above:?}");
        // Anywhere within the limits: the yaw spans its range.
        let yaws: Vec<f32> = (0..60).map(|seed| plan_from(&tree, &rig, &anywhere(), [0.0; 3], seed).0.to[0]).collect();
        let (lo, hi) = span(&yaws);
        assert!(lo < -1.6 && hi > 1.6, "far targets span {lo}..{hi} of -2..2");
    }

    /// Two 0.9 m poles on a 1.6 m box, 1.2 m apart, each on a pitch joint at its foot: the left one
    /// tilts towards the right one for positive angles, the right one towards the left for negative
    /// ones.
    const POLES: &str = r#"<robot name="poles">
      <link name="base"><collision><geometry><box size="1.6 0.3 0.2"/></geometry></collision></link>
      <joint name="left" type="revolute"><parent link="base"/><child link="lpole"/><origin xyz="-0.6 0 0.1"/><axis xyz="0 1 0"/><limit lower="-1.6" upper="1.6" velocity="2" effort="1"/></joint>
      <link name="lpole"><collision><origin xyz="0 0 0.45"/><geometry><cylinder radius="0.02" length="0.9"/></geometry></collision></link>
      <joint name="right" type="revolute"><parent link="base"/><child link="rpole"/><origin xyz="0.6 0 0.1"/><axis xyz="0 1 0"/><limit lower="-1.6" upper="1.6" velocity="2" effort="1"/></joint>
      <link name="rpole"><collision><origin xyz="0 0 0.45"/><geometry><cylinder radius="0.02" length="0.9"/></geometry></collision></link>
    </robot>"#;

    /// Whether the left pole, upright, finds a clear path to its one target `to` (its window pinned
    /// there) while the right pole follows `right` (ground and body let go).
    fn left_pole_plans(to: f32, right: ReachState) -> bool {
        let tree = KinematicTree::from_urdf_str(POLES).unwrap();
        let mut rig = Rig::new(&tree, &Morphology::analyze(&tree), &ControllerConfig::default(), 30.0).unwrap();
        let pole = |name: &str, window: (f32, f32)| {
            let l = link(&tree, name);
            ReachGroup {
                kind: ReachKind::Misc,
                dofs: vec![tree.links[l].joint.as_ref().and_then(|j| j.dof).unwrap()],
                links: vec![l],
                floor: -1.0,
                tolerated: vec![true; rig.swept.len()],
                windows: vec![window],
            }
        };
        rig.reach = vec![pole("lpole", (to, to)), pole("rpole", (-1.6, 1.6))];
        let mut states = vec![ReachState::at(vec![0.0], 0.0), right];
        plan(&tree, &rig, &anywhere(), &mut states, 0, &mut StdRng::seed_from_u64(5))
    }

    #[test]
    fn a_path_is_refused_where_another_group_is_still_going() {
        let moving = |s: f32| ReachState { from: vec![0.0], to: vec![-1.5], s, duration: 1.0, hold: 1.0 };
        // The left pole tilted 0.9 rad, its tip 0.15 m short of the right pole's foot. The right pole
        // lying down towards it (−1.5 rad) passes under it; on its way down (about −0.7 to −1.3 rad)
        // it crosses it.
        assert!(left_pole_plans(0.9, ReachState::at(vec![0.0], 1.0)));
        assert!(left_pole_plans(0.9, ReachState::at(vec![-1.5], 1.0)));
        assert!(!left_pole_plans(0.9, ReachState::at(vec![-0.94], 1.0)));
        // Going down from upright, or from 0.3 of the way (−0.25 rad): the rest of its path crosses.
        assert!(!left_pole_plans(0.9, moving(0.0)));
        assert!(!left_pole_plans(0.9, moving(0.3)));
        // Nine tenths of the way (−1.49 rad), the crossing is behind it.
        assert!(left_pole_plans(0.9, moving(0.9)));
        // A smaller tilt keeps clear of its whole path.
        assert!(left_pole_plans(0.3, moving(0.0)));
    }

    #[test]
    fn a_group_below_another_is_placed_where_that_one_stands_now() {
        // The arm split in two: the yaw and shoulder, then the elbow alone.
        let (tree, _, mut rig) = arm();
        let whole = rig.reach.remove(0);
        let (post, upper, fore) = (link(&tree, "post"), link(&tree, "upper"), link(&tree, "fore"));
        let part = |dofs: Vec<usize>, links: Vec<usize>, windows: Vec<(f32, f32)>| ReachGroup {
            dofs,
            links,
            windows,
            ..whole.clone()
        };
        rig.reach = vec![
            part(vec![0, 1], vec![post, upper, fore], vec![(-2.0, 2.0), (-1.6, 1.6)]),
            part(vec![2], vec![fore], vec![(1.5, 1.5)]),
        ];
        // The forearm 1.5 rad down: from the upright upper arm, level and clear; from the upper arm held
        // level forward, it goes into the ground.
        let elbow_plans = |shoulder: f32| {
            let mut states = vec![ReachState::at(vec![0.0, shoulder], 1.0), ReachState::at(vec![0.0], 0.0)];
            plan(&tree, &rig, &anywhere(), &mut states, 1, &mut StdRng::seed_from_u64(5))
        };
        assert!(elbow_plans(0.0));
        assert!(!elbow_plans(1.5));
    }

    #[test]
    fn with_no_clear_path_the_group_heads_back_to_its_stowed_configuration() {
        let (tree, _, mut rig) = arm();
        // A floor above the whole arm: every draw is refused.
        rig.reach[0].floor = 10.0;
        let cfg = ReachConfig {
            stow_probability: 0.0,
            ..ReachConfig::default()
        };
        let mut states = vec![ReachState::at(vec![0.5, 0.5, 0.5], 0.0)];
        let mut q = rig.nominal_q.clone();
        let ev = step_reach(&tree, &rig, &cfg, &mut states, &mut q, 0.1, &mut StdRng::seed_from_u64(2));
        assert_eq!(ev, ReachEvents { targets: 0, fallbacks: 1 });
        assert_eq!((states[0].from.clone(), states[0].to.clone()), (vec![0.5; 3], vec![0.0; 3]));
    }

    #[test]
    fn a_path_is_refused_through_the_ground_the_body_or_the_arm_itself() {
        let (tree, _, rig) = arm();
        let cfg = ReachConfig::default();
        // Forward, level: clear. Out and down: the forearm's box reaches 6 cm below the ground.
        assert!(clear(&tree, &rig, &cfg, [0.0, 1.5, 0.0], &[]));
        assert!(!clear(&tree, &rig, &cfg, [0.0, 1.5, 1.5], &[]));
        let mut low = rig.clone();
        low.reach[0].floor = -1.0;
        assert!(clear(&tree, &low, &cfg, [0.0, 1.5, 1.5], &[]));
        // Forward and a little down, the forearm's lowest corner 4 cm above the ground, 3 cm above the
        // group's floor; 5 cm lower with the body at the bottom of its range, below it.
        assert!(clear(&tree, &rig, &cfg, [0.0, 1.5, 0.9], &[]));
        let mut crouched = rig.clone();
        crouched.height_range[0] -= 0.05;
        assert!(!clear(&tree, &crouched, &cfg, [0.0, 1.5, 0.9], &[]));
        // A body that may pitch 0.6 rad lowers the forearm reaching out ahead 0.8·sin 0.6 = 0.45 m, below
        // the ground; rolling as far lowers it only by its width. Reaching out sideways, the roll does.
        let mut tilted = rig.clone();
        tilted.max_tilt = [0.6, 0.0];
        assert!(!clear(&tree, &tilted, &cfg, [0.0, 1.5, 0.0], &[]));
        tilted.max_tilt = [0.0, 0.6];
        assert!(clear(&tree, &tilted, &cfg, [0.0, 1.5, 0.0], &[]));
        assert!(!clear(&tree, &tilted, &cfg, [1.57, 1.5, 0.0], &[]));
        assert!(clear(&tree, &rig, &cfg, [1.57, 1.5, 0.0], &[]));
        // Folded down into the box: refused for the body unless the group already touches it stowed.
        assert_eq!(rig.swept.len(), 1);
        assert_eq!(rig.swept[0].link, link(&tree, "base"));
        assert!(!clear(&tree, &rig, &cfg, [0.0, 1.57, 2.7], &[]));
        let mut touching = rig.clone();
        touching.reach[0].tolerated = vec![true];
        assert!(clear(&tree, &touching, &cfg, [0.0, 1.57, 2.7], &[]));
        // Folded back onto the post: refused for the arm's own links, whatever the body and ground.
        touching.reach[0].floor = -1.0;
        assert!(!clear(&tree, &touching, &cfg, [0.0, 1.57, 3.0], &[]));
    }

    #[test]
    fn a_path_is_refused_through_another_groups_path_grown_by_the_margin() {
        let (tree, _, rig) = arm();
        let cfg = ReachConfig::default();
        let world = fk_root(&tree, &[0.0, 1.5, 0.0]);
        // The forearm's centre reaching forward, level.
        let fore = world[link(&tree, "fore")].transform_point(&Point3::new(0.0, 0.0, 0.2));
        let base = link(&tree, "base");
        let at = |dz: f32| cube([fore.x, fore.y, fore.z + dz], 0.05);
        assert!(!clear(&tree, &rig, &cfg, [0.0, 1.5, 0.0], &[(at(0.0), base)]));
        // 0.05 m of air between the forearm and a box below it (the path comes down from above): clear,
        // and refused with a 0.05 m margin.
        let below = -(0.02 + 0.05 + 0.05);
        assert!(clear(&tree, &rig, &cfg, [0.0, 1.5, 0.0], &[(at(below), base)]));
        // (The box the arm stands on is let go: the margin would close the upper arm's 7.5 cm over it.)
        let wide = ReachConfig { margin: 0.05, ..cfg.clone() };
        let mut on_box = rig.clone();
        on_box.reach[0].tolerated = vec![true];
        assert!(clear(&tree, &on_box, &cfg, [0.0, 1.5, 0.0], &[(at(below), base)]));
        assert!(!clear(&tree, &on_box, &wide, [0.0, 1.5, 0.0], &[(at(below), base)]));
        // A link the forearm is never checked against (its own upper arm) is no obstacle.
        assert!(clear(&tree, &rig, &cfg, [0.0, 1.5, 0.0], &[(at(0.0), link(&tree, "upper"))]));
    }

    #[test]
    fn home_windows_keep_each_joint_within_what_moves_the_tip_that_far() {
        let (tree, _, rig) = arm();
        let mut g = rig.reach[0].clone();
        let ReachKind::Arm(tip) = g.kind else { panic!("{:?}", g.kind) };
        assert_eq!(tip, link(&tree, "fore"));
        // The tip (the forearm's origin, at the elbow, 0.6 m up) is 0.5 m from the post's origin; a
        // quarter of that, 0.125 m, is 0.3125 rad of the shoulder (0.4 m below it). Neither the yaw (the
        // tip is on its axis) nor the elbow (the tip is at it) moves the tip: they keep their ranges.
        g.set_home_windows(&tree, &[0.0; 3], Some(0.25));
        let expect = [(-2.0, 2.0), (-0.3125, 0.3125), (-3.0, 3.0)];
        for (w, e) in g.windows.iter().zip(expect) {
            assert!((w.0 - e.0).abs() < 1e-3 && (w.1 - e.1).abs() < 1e-3, "{:?} against {expect:?}", g.windows);
        }
        // Near a limit the window stops at it. Stowed at 1.5 rad, the tip is (0.4·sin 1.5, 0.1 + 0.4·cos 1.5)
        // from the post's origin.
        g.set_home_windows(&tree, &[0.0, 1.5, 0.0], Some(0.25));
        let half = 0.25 * (0.4 * 1.5f32.sin()).hypot(0.1 + 0.4 * 1.5f32.cos()) / 0.4;
        assert!((g.windows[1].0 - (1.5 - half)).abs() < 1e-3 && g.windows[1].1 == 1.6, "{:?}", g.windows[1]);
        // Without a home reach, or for a group that is not an arm: the limits.
        g.set_home_windows(&tree, &[0.0; 3], None);
        assert_eq!(g.windows, [(-2.0, 2.0), (-1.6, 1.6), (-3.0, 3.0)]);
        g.kind = ReachKind::Misc;
        g.set_home_windows(&tree, &[0.0; 3], Some(0.25));
        assert_eq!(g.windows, [(-2.0, 2.0), (-1.6, 1.6), (-3.0, 3.0)]);
    }

    #[test]
    fn obstacles_the_stowed_arm_already_touches_are_tolerated() {
        let (tree, _, rig) = arm();
        let nominal = fk_root(&tree, &rig.nominal_q);
        // The upper arm's centre, straight up: 0.4 m above the box's centre.
        let upper = [0.0, 0.0, 0.4];
        let base = link(&tree, "base");
        let obstacle = |center: [f32; 3], link: usize| Obstacle { link, obb: cube(center, 0.05) };
        let mut g = rig.reach[0].clone();
        let gap = 0.025 + 0.05 + 0.03;
        let obstacles = [
            obstacle(upper, base),
            obstacle([gap, 0.0, 0.4], base),
            obstacle([2.0, 0.0, 0.4], base),
            obstacle(upper, link(&tree, "post")),
        ];
        g.tolerate(&rig.proxies, &nominal, &obstacles, 0.0);
        assert_eq!(g.tolerated, [true, false, false, false]);
        g.tolerate(&rig.proxies, &nominal, &obstacles, 0.05);
        assert_eq!(g.tolerated, [true, true, false, false]);
    }

    #[test]
    fn groups_take_each_arms_free_joints_then_the_rest_with_a_floor_below_where_they_stand() {
        let (tree, morph, rig) = arm();
        let standing = rig.standing.clone();
        let proxies = Proxies::new(&tree, &standing);
        let (post, upper, fore) = (link(&tree, "post"), link(&tree, "upper"), link(&tree, "fore"));
        let all = groups(&tree, &morph, &proxies, &standing, &[false; 3]);
        assert_eq!(all.len(), 1);
        assert_eq!((all[0].dofs.clone(), all[0].links.clone()), (vec![0, 1, 2], vec![post, upper, fore]));
        assert_eq!(all[0].floor, GROUND_MARGIN);
        // A DoF another part owns is not the arm's; the arm starts at its first free joint.
        let rest = groups(&tree, &morph, &proxies, &standing, &[true, false, false]);
        assert_eq!(rest.len(), 1);
        assert_eq!((rest[0].dofs.clone(), rest[0].links.clone()), (vec![1, 2], vec![upper, fore]));
        // Without a manipulator every free DoF is left over, in one group.
        let mut armless = morph.clone();
        armless.manipulators.clear();
        let misc = groups(&tree, &armless, &proxies, &standing, &[false, true, false]);
        assert_eq!(misc.len(), 1);
        assert!(matches!(misc[0].kind, ReachKind::Misc));
        assert_eq!((misc[0].dofs.clone(), misc[0].links.clone()), (vec![0, 2], vec![post, upper, fore]));
        // Standing with the post's foot 5 mm above the ground (the box sunk into it), the group may go
        // 1 mm lower than that.
        let mut sunk = standing.clone();
        sunk.root.translation.vector.z -= 0.195;
        let low = groups(&tree, &morph, &Proxies::new(&tree, &sunk), &sunk, &[false; 3]);
        assert!((low[0].floor - 0.004).abs() < 1e-5, "{}", low[0].floor);
    }
}
