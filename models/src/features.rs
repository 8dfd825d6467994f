//! The features Ψ of the feature loss (paper §6.3) and of the DIV/FID metrics (§7.3).
//!
//! Ψ is built from a state vector — the human's x^h ([`crate::human::layout`]) or a character's x^r
//! ([`CharacterLayout`]) — and has the same layout for both, so that a human frame and a character frame
//! compare element for element ([`FeatureLayout`]):
//!
//! | block | values | unit |
//! |---|---|---|
//! | root height | 1 | body lengths |
//! | root orientation | 6: the root's forward (x) axis, then its up (z) axis, in the heading frame | — |
//! | root linear velocity | 3, heading axes | body lengths / s |
//! | root angular velocity | 3, heading axes | rad/s (angles need no normalisation) |
//! | end-effector positions | 3 per mapped end effector, heading frame (origin at the root) | body lengths |
//!
//! **Orientation.** The states store the root rotation relative to the heading frame as a quaternion
//! with `w ≥ 0`. Ψ uses two columns of its rotation matrix instead (the "6D" representation): it is
//! continuous everywhere — a quaternion with `w ≥ 0` jumps when the rotation passes 180° (a root upside
//! down) — and it does not depend on the quaternion's sign or norm, so a network output compares fairly.
//! For a quaternion `(w, x, y, z)` the columns are
//! `fwd = (1−2(y²+z²), 2(xy+wz), 2(xz−wy))` and `up = (2(xz+wy), 2(yz−wx), 1−2(x²+y²))`
//! (after normalising), which is what a tensor implementation of L_fea must compute. Since the heading
//! removes the yaw, `fwd.y` is 0 except where the heading is undefined (root pointing straight up).
//!
//! **Body length** (paper §7.2: the human ≈ 1.7 m, Spot ≈ 0.5 m): for a human it is the clip's standing
//! height ([`human_body_length`]); for a character it is its standing height without its manipulator
//! arms ([`character_body_length`]). A user scale setting multiplies either before it is passed here.
//!
//! **End effectors.** An [`EndEffectorMapping`] says which human end effector each character end effector
//! is compared with (paper §5.3); unmapped character end effectors are left out of Ψ on both sides.
//!
//! **Centring.** A human and a character do not share a rest pose: Spot's feet stand 0.3 body lengths
//! ahead of and behind its root where a human's stand under the pelvis, the crab's sprawl two body
//! lengths out, and a human pelvis stands at 0.55 body lengths where Spot's body is at 0.85. Compared
//! as they are, the feature loss asks for poses the character cannot or should not take. So L_fea
//! compares the root height and the end-effector positions as displacements from each body's mean:
//! the human's Ψ is shifted by a [`centring_offset`] (the character dataset's mean minus the human
//! training clips' mean, on those entries only) before it is compared. Ψ itself, and with it DIV and
//! FID, is unchanged: a common shift of the character's features would change neither.
//!
//! **Speed.** The character dataset's controller turns human-equivalent speeds into the character's
//! by a speed scale `s` (leg length over a human's 0.9 m for legged characters, height over 1.7 m
//! for wheeled ones; [`crate::controller::ScalingConfig`]), while Ψ divides speeds by body length.
//! The two disagree where legs are long for the height: a human's 1.2 m/s walk is 0.7 body lengths
//! per second, but the dataset's Spot trots that command at 1.2 and the crab scurries at 1.6. So
//! L_fea compares the root's linear velocity at the dataset's scale: the human's velocity entries
//! are multiplied by [`human_speed_factor`] `s·H / L` (`H` the human's body length, `L` the
//! character's), which makes them `v·s / L` — the character speed the dataset pairs with the
//! human's `v`, in the character's body lengths per second. For Stretch, whose scale is its
//! height over 1.7 m, the factor is 1. Ψ itself, and with it DIV and FID, is unchanged.

use std::ops::Range;

use nalgebra::{Isometry3, Vector3};
use serde::{Deserialize, Serialize};

use crate::character_state::{CharacterLayout, read_quat};
use crate::human::{EndEffector, HumanClip, layout as human_layout};
use crate::kinematics::KinematicTree;
use crate::morphology::Morphology;

/// The body length assumed for a human whose clip has no usable height (m).
pub const DEFAULT_HUMAN_HEIGHT: f32 = 1.7;

/// The five blocks of Ψ, in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FeatureBlock {
    RootHeight,
    RootOrientation,
    RootLinearVelocity,
    RootAngularVelocity,
    EePositions,
}

impl FeatureBlock {
    /// All blocks in Ψ order.
    pub const ALL: [FeatureBlock; 5] = [
        FeatureBlock::RootHeight,
        FeatureBlock::RootOrientation,
        FeatureBlock::RootLinearVelocity,
        FeatureBlock::RootAngularVelocity,
        FeatureBlock::EePositions,
    ];

    /// snake_case name.
    pub fn name(self) -> &'static str {
        match self {
            FeatureBlock::RootHeight => "root_height",
            FeatureBlock::RootOrientation => "root_orientation",
            FeatureBlock::RootLinearVelocity => "root_linear_velocity",
            FeatureBlock::RootAngularVelocity => "root_angular_velocity",
            FeatureBlock::EePositions => "ee_positions",
        }
    }
}

/// Index map of Ψ. The blocks are contiguous and in [`FeatureBlock::ALL`] order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FeatureLayout {
    /// Number of end effectors in Ψ (the mapped ones).
    pub end_effectors: usize,
}

impl FeatureLayout {
    /// The layout for the end effectors that `mapping` selects.
    pub fn new(mapping: &EndEffectorMapping) -> Self {
        FeatureLayout {
            end_effectors: mapping.selected().count(),
        }
    }
    /// Root height / body length, 1 value.
    pub fn root_height(&self) -> Range<usize> {
        0..1
    }
    /// Root forward axis (3) then up axis (3) in the heading frame, 6 values.
    pub fn root_orientation(&self) -> Range<usize> {
        1..7
    }
    /// Root linear velocity / body length, heading axes, 3 values.
    pub fn root_linear_velocity(&self) -> Range<usize> {
        7..10
    }
    /// Root angular velocity (rad/s), heading axes, 3 values.
    pub fn root_angular_velocity(&self) -> Range<usize> {
        10..13
    }
    /// End-effector positions / body length in the heading frame, 3 per mapped end effector in
    /// character end-effector order.
    pub fn ee_positions(&self) -> Range<usize> {
        13..13 + 3 * self.end_effectors
    }
    /// Length of Ψ.
    pub fn dim(&self) -> usize {
        self.ee_positions().end
    }
    /// The range of `block`.
    pub fn range(&self, block: FeatureBlock) -> Range<usize> {
        match block {
            FeatureBlock::RootHeight => self.root_height(),
            FeatureBlock::RootOrientation => self.root_orientation(),
            FeatureBlock::RootLinearVelocity => self.root_linear_velocity(),
            FeatureBlock::RootAngularVelocity => self.root_angular_velocity(),
            FeatureBlock::EePositions => self.ee_positions(),
        }
    }
    /// A name for every entry, e.g. `root_orientation.up.z`, `ee_pos[2].x`.
    pub fn entry_names(&self) -> Vec<String> {
        let xyz = ["x", "y", "z"];
        let mut n = vec!["root_height".to_string()];
        for axis in ["fwd", "up"] {
            n.extend(xyz.iter().map(|c| format!("root_orientation.{axis}.{c}")));
        }
        n.extend(xyz.iter().map(|c| format!("root_linear_velocity.{c}")));
        n.extend(xyz.iter().map(|c| format!("root_angular_velocity.{c}")));
        for k in 0..self.end_effectors {
            n.extend(xyz.iter().map(|c| format!("ee_pos[{k}].{c}")));
        }
        n
    }
}

/// Which human end effector each character end effector is compared with.
///
/// `human[k]` belongs to character end effector `k` in [`Morphology::end_effectors`] order (feet,
/// manipulators, head); `None` leaves that end effector out of Ψ. Several character end effectors may
/// map to the same human one (a hexapod's three left feet to the left foot).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct EndEffectorMapping {
    /// Human end effector per character end effector.
    pub human: Vec<Option<EndEffector>>,
}

impl EndEffectorMapping {
    /// A mapping from its per-character-end-effector entries.
    pub fn new(human: Vec<Option<EndEffector>>) -> Self {
        EndEffectorMapping { human }
    }

    /// A default mapping by side, for when no learned (KL) or manual mapping is at hand: at the
    /// standing pose, feet on the left (y ≥ 0 in the root frame) map to the left foot and the others
    /// to the right foot; manipulators left of the root's x–z plane map to the left hand, the others
    /// (including a centred arm, as on Spot) to the right hand; the head to the head.
    pub fn by_side(tree: &KinematicTree, morph: &Morphology) -> Self {
        let links = tree.forward_kinematics(&tree.neutral_pose(Isometry3::identity()));
        let y = |l: usize| morph.ee_point(l, &links).y;
        let mut human: Vec<Option<EndEffector>> = Vec::new();
        human.extend(morph.feet.iter().map(|&f| {
            Some(if y(f) >= 0.0 {
                EndEffector::LeftFoot
            } else {
                EndEffector::RightFoot
            })
        }));
        human.extend(morph.manipulators.iter().map(|&m| {
            Some(if y(m) > 1e-3 {
                EndEffector::LeftHand
            } else {
                EndEffector::RightHand
            })
        }));
        human.extend(morph.head.map(|_| Some(EndEffector::Head)));
        EndEffectorMapping { human }
    }

    /// Mapped pairs `(character end-effector index, human end effector)` in character order.
    pub fn selected(&self) -> impl Iterator<Item = (usize, EndEffector)> + '_ {
        self.human.iter().enumerate().filter_map(|(k, h)| h.map(|h| (k, h)))
    }
}

/// Per-block weights of the feature loss (the editor's per-feature sliders). Default 1 each.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FeatureWeights {
    pub root_height: f32,
    pub root_orientation: f32,
    pub root_linear_velocity: f32,
    pub root_angular_velocity: f32,
    pub ee_positions: f32,
}

impl Default for FeatureWeights {
    fn default() -> Self {
        FeatureWeights {
            root_height: 1.0,
            root_orientation: 1.0,
            root_linear_velocity: 1.0,
            root_angular_velocity: 1.0,
            ee_positions: 1.0,
        }
    }
}

impl FeatureWeights {
    /// `Err` naming the first weight that is negative or not finite (a negative weight would reward
    /// the generator for moving away from the human).
    pub fn check(&self) -> Result<(), String> {
        for b in FeatureBlock::ALL {
            let w = self.weight(b);
            if !(w.is_finite() && w >= 0.0) {
                return Err(format!(
                    "`feature_weights.{}` = {w} is out of range: expected a finite weight ≥ 0",
                    b.name()
                ));
            }
        }
        Ok(())
    }

    /// The weight of `block`.
    pub fn weight(&self, block: FeatureBlock) -> f32 {
        let mut w = *self;
        *w.weight_mut(block)
    }

    /// The weight of a block, to change it.
    pub fn weight_mut(&mut self, block: FeatureBlock) -> &mut f32 {
        match block {
            FeatureBlock::RootHeight => &mut self.root_height,
            FeatureBlock::RootOrientation => &mut self.root_orientation,
            FeatureBlock::RootLinearVelocity => &mut self.root_linear_velocity,
            FeatureBlock::RootAngularVelocity => &mut self.root_angular_velocity,
            FeatureBlock::EePositions => &mut self.ee_positions,
        }
    }

    /// These weights with every block but `block` at zero (that block's share of L_fea).
    pub fn only(&self, block: FeatureBlock) -> FeatureWeights {
        let mut only = FeatureWeights { root_height: 0.0, root_orientation: 0.0, root_linear_velocity: 0.0, root_angular_velocity: 0.0, ee_positions: 0.0 };
        *only.weight_mut(block) = self.weight(block);
        only
    }

    /// One weight per entry of Ψ (e.g. to build a weight tensor for training).
    pub fn per_element(&self, layout: &FeatureLayout) -> Vec<f32> {
        let mut w = vec![0.0; layout.dim()];
        for b in FeatureBlock::ALL {
            w[layout.range(b)].fill(self.weight(b));
        }
        w
    }
}

/// The feature loss of one frame: the weighted mean squared difference
/// `L = (1/D) Σ_k w_k (a_k − b_k)²` over the `D` entries of Ψ, where `w_k` is the weight of the block
/// of entry `k`. With the default weights this is the plain mean squared error.
///
/// # Panics
/// If `a` or `b` is not `layout.dim()` long.
pub fn feature_loss(layout: &FeatureLayout, a: &[f32], b: &[f32], weights: &FeatureWeights) -> f32 {
    let d = layout.dim();
    assert!(a.len() == d && b.len() == d, "feature vectors must have {d} entries");
    let mut sum = 0.0f32;
    for block in FeatureBlock::ALL {
        let r = layout.range(block);
        let s: f32 = a[r.clone()].iter().zip(&b[r]).map(|(x, y)| (x - y) * (x - y)).sum();
        sum += weights.weight(block) * s;
    }
    sum / d.max(1) as f32
}

/// [`feature_loss`] averaged over aligned frames (`a[t]` against `b[t]`); 0 for no frames.
///
/// # Panics
/// If the two sets differ in length or a row has the wrong width.
pub fn mean_feature_loss<R: AsRef<[f32]>, S: AsRef<[f32]>>(
    layout: &FeatureLayout,
    a: &[R],
    b: &[S],
    weights: &FeatureWeights,
) -> f32 {
    assert_eq!(a.len(), b.len(), "feature sets must be aligned frame for frame");
    if a.is_empty() {
        return 0.0;
    }
    let sum: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| f64::from(feature_loss(layout, x.as_ref(), y.as_ref(), weights)))
        .sum();
    (sum / a.len() as f64) as f32
}

/// The per-entry mean of feature rows (an empty vector for no rows).
pub fn mean_features<R: AsRef<[f32]>>(rows: impl IntoIterator<Item = R>) -> Vec<f32> {
    let mut sum: Vec<f64> = Vec::new();
    let mut n = 0usize;
    for r in rows {
        let r = r.as_ref();
        if sum.is_empty() {
            sum = vec![0.0; r.len()];
        }
        assert_eq!(r.len(), sum.len(), "feature rows of different lengths");
        for (s, v) in sum.iter_mut().zip(r) {
            *s += f64::from(*v);
        }
        n += 1;
    }
    sum.iter().map(|s| (s / n as f64) as f32).collect()
}

/// The offset added to a human's Ψ so that its root height and end-effector positions compare as
/// displacements from the mean pose (module docs, "Centring"): `character_mean − human_mean` on those
/// entries, zero on the orientation and velocities, whose means are shared (upright, at rest).
///
/// # Panics
/// If either mean is not [`FeatureLayout::dim`] long.
pub fn centring_offset(layout: &FeatureLayout, human_mean: &[f32], character_mean: &[f32]) -> Vec<f32> {
    let dim = layout.dim();
    assert!(
        human_mean.len() == dim && character_mean.len() == dim,
        "feature means must have {dim} entries, got {} and {}",
        human_mean.len(),
        character_mean.len()
    );
    let mut offset = vec![0.0; dim];
    for i in layout.root_height().chain(layout.ee_positions()) {
        offset[i] = character_mean[i] - human_mean[i];
    }
    offset
}

/// Adds `offset` ([`centring_offset`]) to a human's Ψ; an empty offset (a checkpoint trained without
/// centring) leaves it as it is.
///
/// # Panics
/// If `offset` is neither empty nor as long as `psi`.
pub fn centre_human_features(psi: &mut [f32], offset: &[f32]) {
    if offset.is_empty() {
        return;
    }
    assert_eq!(psi.len(), offset.len(), "the centring offset has the wrong length");
    for (v, o) in psi.iter_mut().zip(offset) {
        *v += o;
    }
}

/// The factor by which a human's root linear velocity in Ψ is multiplied to compare at the
/// character dataset's speed scale (module docs, "Speed"): `speed_scale · human_body / character_body`,
/// for a human of `human_body` metres, a character of `character_body` metres and the dataset
/// controller's human-equivalent `speed_scale` ([`crate::dataset::speed_scale`]).
pub fn human_speed_factor(speed_scale: f32, human_body: f32, character_body: f32) -> f32 {
    speed_scale * human_body / character_body
}

/// Multiplies the root linear velocity entries of a human's Ψ by `factor` ([`human_speed_factor`]).
pub fn scale_human_speed(psi: &mut [f32], layout: &FeatureLayout, factor: f32) {
    for v in &mut psi[layout.root_linear_velocity()] {
        *v *= factor;
    }
}

/// The body length of a human clip: its standing height, or [`DEFAULT_HUMAN_HEIGHT`] when the clip
/// has none.
pub fn human_body_length(clip: &HumanClip) -> f32 {
    if clip.height_m.is_finite() && clip.height_m > 0.0 {
        clip.height_m
    } else {
        DEFAULT_HUMAN_HEIGHT
    }
}

/// The body length of a character: the height of its geometry at the standing pose
/// ([`KinematicTree::standing_pose`]), leaving out manipulator arms — a human's height is measured
/// with the arms down, and a robot arm's neutral pose is arbitrary (Spot's points forward, another
/// may point up). A manipulator's arm is the branch that carries it and no other end effector or
/// wheel, from the first link below the root body (or below the last branching that leads to another
/// end effector). Links without known extent count with their origin. At least 1 mm.
///
/// Bundled characters: Spot ≈ 0.59 m (the top of its body box), the crab ≈ 0.19 m (its knees),
/// Stretch ≈ 1.3 m (its mast and head camera).
pub fn character_body_length(tree: &KinematicTree, morph: &Morphology) -> f32 {
    let links = tree.forward_kinematics(&tree.standing_pose());
    let arm = manipulator_arms(tree, morph);
    let bottom = tree.lowest_z(&links);
    let top = tree
        .links
        .iter()
        .zip(&links)
        .enumerate()
        .filter(|(i, _)| !arm[*i])
        .map(|(_, (l, p))| l.aabb(p).map_or(p.translation.vector.z, |b| b.max.z))
        .fold(f32::NEG_INFINITY, f32::max);
    let top = if top.is_finite() { top } else { tree.aabb(&links).max.z };
    (top - bottom).max(1e-3)
}

/// Marks the links of manipulator arms (see [`character_body_length`]).
fn manipulator_arms(tree: &KinematicTree, morph: &Morphology) -> Vec<bool> {
    let n = tree.links.len();
    // The root body: the root and every link fixed to it.
    let mut root_body = vec![false; n];
    for (i, l) in tree.links.iter().enumerate() {
        let fixed = l.joint.as_ref().is_none_or(|j| !j.kind.is_movable());
        root_body[i] = match l.parent {
            None => true,
            Some(p) => fixed && root_body[p],
        };
    }
    let others: Vec<usize> = morph
        .end_effectors()
        .into_iter()
        .chain(morph.wheels.iter().copied())
        .collect();
    let mut arm = vec![false; n];
    for &m in &morph.manipulators {
        let mut cur = m;
        while let Some(p) = tree.links[cur].parent {
            let shared = others.iter().any(|&o| o != m && tree.is_descendant(o, p));
            if root_body[p] || shared {
                break;
            }
            cur = p;
        }
        if !root_body[cur] {
            for (i, a) in arm.iter_mut().enumerate() {
                *a |= tree.is_descendant(i, cur);
            }
        }
    }
    arm
}

/// Writes Ψ from the pieces of a state vector. `ees` yields the 3 position values of each mapped end
/// effector.
fn write_features<'a>(
    height: f32,
    orientation: &[f32],
    linear: &[f32],
    angular: &[f32],
    ees: impl Iterator<Item = &'a [f32]>,
    body_length: f32,
    out: &mut [f32],
) {
    assert!(body_length > 0.0, "body length must be positive, got {body_length}");
    let inv = 1.0 / body_length;
    let r = read_quat(orientation);
    let (fwd, up) = (r * Vector3::x(), r * Vector3::z());
    out[0] = height * inv;
    out[1..4].copy_from_slice(fwd.as_slice());
    out[4..7].copy_from_slice(up.as_slice());
    for k in 0..3 {
        out[7 + k] = linear[k] * inv;
        out[10 + k] = angular[k];
    }
    let mut i = 13;
    for p in ees {
        for v in p {
            out[i] = v * inv;
            i += 1;
        }
    }
    assert_eq!(i, out.len(), "feature buffer has the wrong length");
}

/// Ψ of a character state x^r (laid out by `layout`) for a character of `body_length` metres.
///
/// # Panics
/// If `x_r` does not match `layout`, `mapping` does not have one entry per character end effector, or
/// `body_length` is not positive.
pub fn character_features(
    layout: &CharacterLayout,
    x_r: &[f32],
    body_length: f32,
    mapping: &EndEffectorMapping,
) -> Vec<f32> {
    let mut out = vec![0.0; FeatureLayout::new(mapping).dim()];
    character_features_into(layout, x_r, body_length, mapping, &mut out);
    out
}

/// [`character_features`] into `out` (length [`FeatureLayout::dim`]).
pub fn character_features_into(
    layout: &CharacterLayout,
    x_r: &[f32],
    body_length: f32,
    mapping: &EndEffectorMapping,
    out: &mut [f32],
) {
    assert_eq!(x_r.len(), layout.dim(), "x^r has the wrong length for its layout");
    assert_eq!(
        mapping.human.len(),
        layout.end_effectors,
        "the end-effector mapping needs one entry per character end effector"
    );
    let ee = layout.ee_positions().start;
    write_features(
        x_r[layout.root_height().start],
        &x_r[layout.root_orientation()],
        &x_r[layout.root_linear_velocity()],
        &x_r[layout.root_angular_velocity()],
        mapping.selected().map(|(k, _)| &x_r[ee + 3 * k..ee + 3 * k + 3]),
        body_length,
        out,
    );
}

/// Ψ of a human state x^h (92 values, [`crate::human::layout`]) for a human of `body_length` metres,
/// with the human end effectors that `mapping` pairs with the character's, in character order.
///
/// # Panics
/// If `x_h` is not 92 long or `body_length` is not positive.
pub fn human_features(x_h: &[f32], body_length: f32, mapping: &EndEffectorMapping) -> Vec<f32> {
    let mut out = vec![0.0; FeatureLayout::new(mapping).dim()];
    human_features_into(x_h, body_length, mapping, &mut out);
    out
}

/// [`human_features`] into `out` (length [`FeatureLayout::dim`]).
pub fn human_features_into(x_h: &[f32], body_length: f32, mapping: &EndEffectorMapping, out: &mut [f32]) {
    assert_eq!(
        x_h.len(),
        human_layout::DIM,
        "x^h must have {} values",
        human_layout::DIM
    );
    write_features(
        x_h[human_layout::ROOT_HEIGHT.start],
        &x_h[human_layout::ROOT_ORIENTATION],
        &x_h[human_layout::ROOT_LINEAR_VELOCITY],
        &x_h[human_layout::ROOT_ANGULAR_VELOCITY],
        mapping.selected().map(|(_, e)| &x_h[human_layout::ee_position(e)]),
        body_length,
        out,
    );
}
