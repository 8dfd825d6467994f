//! Ψ on tensors: the differentiable twin of [`crate::features`], used by the feature loss L_fea while
//! training the generator (paper §5.3, §6.3).
//!
//! [`Psi::features`] computes exactly what [`crate::features::character_features`] computes for each
//! row of a batch of *denormalised* character states — the same [`FeatureLayout`], the same 6D
//! orientation formula (the first and third columns of the root rotation from the normalised
//! quaternion, identity for a degenerate one), the same division by the body length — so the feature
//! loss during training and the L_fea metric afterwards measure one thing. [`feature_loss`] is the
//! batch mean of [`crate::features::feature_loss`].
//!
//! **End effectors by forward kinematics.** The motion prior predicts the end-effector positions of x^r
//! as numbers of their own, beside the joint positions; nothing ties the two together. On the
//! dataset they agree, but a generator chasing a human hand finds latents where the predicted entries
//! move as asked while the joints — what is shown, exported and sent to a robot — do something else:
//! on Spot the predicted gripper moved 2.7× the hand's amplitude, the gripper of the joints 4.5×.
//! [`Psi::with_kinematics`] computes the end-effector block from the joint positions instead (clamped
//! into the joint limits as the retargeter clamps them, through [`FkLayer`]), so L_fea scores the arm
//! that is shown. On consistent states, such as the dataset's, both give the same Ψ.
//!
//! **Root velocities from the root's motion.** The same holds for the root: a pose's root is carried
//! from frame to frame by the state's displacement and delta rotation
//! ([`crate::character_state::integrate_root`]), while x^r's velocity entries are numbers of their own
//! beside them. Trained on the velocity entries, the generator met the human's yaw rate there while the
//! character turned by its delta rotations: the shipped checkpoints turned a median 33–41° off the
//! human's heading over the held-out clips. [`Psi::with_root_motion`] computes the root's horizontal
//! linear velocity and its angular velocity from the displacement and the delta rotation instead (the
//! vertical velocity, which moves nothing, stays the entry's), in the current heading frame as x^r
//! holds them. On consistent states both agree to within the small difference between the delta
//! rotation's vertical component and the change of heading of a tilted root.

use tch::{Device, Kind, Tensor};

use super::ShapeError;
use super::fk::{FkLayer, quat_to_matrix};
use crate::character_state::CharacterLayout;
use crate::features::{EndEffectorMapping, FeatureLayout, FeatureWeights};
use crate::kinematics::KinematicTree;
use crate::morphology::Morphology;

/// Ψ of character states for one character, mapping and body length.
#[derive(Debug)]
pub struct Psi {
    layout: CharacterLayout,
    features: FeatureLayout,
    /// Columns of x^r holding the mapped end effectors' positions, in character order.
    ee_columns: Tensor,
    body_length: f64,
    /// Forward kinematics of the end effectors, when Ψ takes their positions from the joints
    /// ([`Psi::with_kinematics`]).
    kinematics: Option<EeKinematics>,
    /// Seconds per frame, when Ψ takes the root's velocities from its displacement and delta rotation
    /// ([`Psi::with_root_motion`]).
    root_motion_dt: Option<f64>,
}

/// [`FkLayer`] with the joint limits and the mapped end effectors' columns of its output.
#[derive(Debug)]
struct EeKinematics {
    fk: FkLayer,
    /// Joint limits `[1, dof]` (the float range for unlimited joints).
    lower: Tensor,
    upper: Tensor,
    /// Columns of [`FkLayer::ee_positions`] holding the mapped end effectors, in Ψ's order.
    columns: Tensor,
}

impl Psi {
    /// Ψ for states laid out by `layout`, with the end effectors `mapping` selects, for a character of
    /// `body_length` metres.
    ///
    /// # Panics
    /// If `mapping` does not have one entry per character end effector or `body_length` is not
    /// positive (as [`crate::features::character_features`]).
    pub fn new(
        layout: &CharacterLayout,
        mapping: &EndEffectorMapping,
        body_length: f32,
        device: Device,
    ) -> Psi {
        assert_eq!(
            mapping.human.len(),
            layout.end_effectors,
            "the end-effector mapping needs one entry per character end effector"
        );
        assert!(
            body_length > 0.0,
            "body length must be positive, got {body_length}"
        );
        let ee = layout.ee_positions().start as i64;
        let columns: Vec<i64> = mapping
            .selected()
            .flat_map(|(k, _)| (0..3).map(move |c| ee + 3 * k as i64 + c))
            .collect();
        Psi {
            layout: *layout,
            features: FeatureLayout::new(mapping),
            ee_columns: Tensor::from_slice(&columns).to_device(device),
            body_length: f64::from(body_length),
            kinematics: None,
            root_motion_dt: None,
        }
    }

    /// This Ψ with the end-effector block computed from the joint positions by forward kinematics of
    /// `tree` and `morph` (module docs) instead of read from the states' end-effector entries.
    ///
    /// # Panics
    /// If `tree` and `morph` are not the character of this Ψ's layout (other DoF or end-effector
    /// counts); callers check the character first.
    pub fn with_kinematics(mut self, tree: &KinematicTree, morph: &Morphology) -> Psi {
        assert_eq!(CharacterLayout::new(tree, morph), self.layout, "forward kinematics of another character than Ψ's");
        let device = self.ee_columns.device();
        let (lower, upper): (Vec<f32>, Vec<f32>) = (0..tree.dof())
            .map(|d| tree.limits(d).map_or((f32::MIN, f32::MAX), |l| (l.lower, l.upper)))
            .unzip();
        let limits = |v: &[f32]| Tensor::from_slice(v).view([1, -1]).to_device(device);
        self.kinematics = Some(EeKinematics {
            fk: FkLayer::new(tree, morph, device),
            lower: limits(&lower),
            upper: limits(&upper),
            columns: &self.ee_columns - self.layout.ee_positions().start as i64,
        });
        self
    }

    /// This Ψ with the root's velocities computed from the states' displacement and delta rotation over
    /// `dt` seconds per frame (module docs) instead of read from their velocity entries.
    ///
    /// # Panics
    /// If `dt` is not positive.
    pub fn with_root_motion(mut self, dt: f32) -> Psi {
        assert!(dt > 0.0, "seconds per frame must be positive, got {dt}");
        self.root_motion_dt = Some(f64::from(dt));
        self
    }

    /// The layout of the output.
    pub fn layout(&self) -> &FeatureLayout {
        &self.features
    }

    /// Width of Ψ.
    pub fn dim(&self) -> usize {
        self.features.dim()
    }

    /// Ψ `[B, F]` of denormalised states `x: [B, D]`; differentiable in `x`.
    pub fn features(&self, x: &Tensor) -> Result<Tensor, ShapeError> {
        let l = &self.layout;
        let size = x.size();
        if size.len() != 2 || size[1] != l.dim() as i64 {
            return Err(ShapeError::Tensor {
                expected: l.dim(),
                found: size,
            });
        }
        let cols = |r: std::ops::Range<usize>| x.narrow(1, r.start as i64, r.len() as i64);
        let inv = 1.0 / self.body_length;
        let height = cols(l.root_height()) * inv;
        let orientation = orientation_6d(&cols(l.root_orientation()));
        let (linear, angular) = match self.root_motion_dt {
            None => (cols(l.root_linear_velocity()), cols(l.root_angular_velocity())),
            Some(dt) => root_velocities(
                &cols(l.root_displacement()),
                &cols(l.root_delta_rotation()),
                &cols(l.root_linear_velocity()).narrow(1, 2, 1),
                dt,
            ),
        };
        let linear = linear * inv;
        let ees = match &self.kinematics {
            None => x.index_select(1, &self.ee_columns.to_device(x.device())),
            Some(k) => {
                let q = cols(l.joint_positions()).maximum(&k.lower).minimum(&k.upper);
                let root = quat_to_matrix(&cols(l.root_orientation()));
                k.fk.ee_positions(&root, &q).index_select(1, &k.columns)
            }
        } * inv;
        Ok(Tensor::cat(&[height, orientation, linear, angular, ees], 1))
    }
}

/// The root's linear and angular velocities `[B, 3]` each, in the current heading frame, from its
/// displacement `d: [B, 2]` (previous heading frame, m), its delta rotation `q: [B, 4]` (`w, x, y, z`,
/// any norm or sign; previous heading frame) and its vertical velocity `vz: [B, 1]`, over `dt`
/// seconds: the rotation's scaled axis over `dt`, and both turned by the change of heading (the
/// scaled axis's vertical component) into the current heading frame.
pub fn root_velocities(d: &Tensor, q: &Tensor, vz: &Tensor, dt: f64) -> (Tensor, Tensor) {
    // The same rotation with w ≥ 0, so that its angle is at most π.
    let q = q * (q.narrow(1, 0, 1).ge(0.0).to_kind(q.kind()) * 2.0 - 1.0);
    let (w, v) = (q.narrow(1, 0, 1), q.narrow(1, 1, 3));
    // |v| kept off 0, where the scaled axis is 2v/w and the square root's gradient is infinite.
    let n = (v.square().sum_dim_intlist(1, true, q.kind()) + 1e-12).sqrt();
    let omega = &v * (n.atan2(&w) * 2.0 / &n) / dt;
    let turn = omega.narrow(1, 2, 1) * dt;
    let (c, s) = (turn.cos(), turn.sin());
    // Rz(−turn): a vector of the previous heading frame in the current one.
    let back = |x: &Tensor, y: &Tensor| (&c * x + &s * y, -(&s * x) + &c * y);
    let (ox, oy) = back(&omega.narrow(1, 0, 1), &omega.narrow(1, 1, 1));
    let (vx, vy) = back(&(d.narrow(1, 0, 1) / dt), &(d.narrow(1, 1, 1) / dt));
    (Tensor::cat(&[vx, vy, vz.shallow_clone()], 1), Tensor::cat(&[ox, oy, omega.narrow(1, 2, 1)], 1))
}

/// The 6D orientation `[fwd, up]` (first and third rotation-matrix columns) of quaternions
/// `q: [B, 4]` (`w, x, y, z`, any norm), as in [`crate::features`]: the quaternion is normalised, and
/// one of norm below 1e-6 counts as the identity.
pub fn orientation_6d(q: &Tensor) -> Tensor {
    let identity = Tensor::from_slice(&[1.0f32, 0.0, 0.0, 0.0])
        .to_kind(q.kind())
        .to_device(q.device());
    let norm2 = q.square().sum_dim_intlist(1, true, q.kind());
    let regular = norm2.ge(1e-12);
    // The divisor of degenerate rows is replaced before the square root, so that no gradient passes
    // through √0 (whose derivative is infinite) even on the branch `where` discards.
    let norm = norm2.where_self(&regular, &norm2.ones_like()).sqrt();
    let q = q.where_self(&regular, &identity.unsqueeze(0)) / norm;
    let c = |i: i64| q.narrow(1, i, 1);
    let (w, x, y, z) = (c(0), c(1), c(2), c(3));
    let two = |a: &Tensor| a * 2.0;
    let fwd_x = 1.0 - two(&(y.square() + z.square()));
    let fwd_y = two(&(&x * &y + &w * &z));
    let fwd_z = two(&(&x * &z - &w * &y));
    let up_x = two(&(&x * &z + &w * &y));
    let up_y = two(&(&y * &z - &w * &x));
    let up_z = 1.0 - two(&(x.square() + y.square()));
    Tensor::cat(&[fwd_x, fwd_y, fwd_z, up_x, up_y, up_z], 1)
}

/// The per-entry weights of [`feature_loss`] as a `[1, F]` tensor ([`FeatureWeights::per_element`]).
pub fn weight_tensor(layout: &FeatureLayout, weights: &FeatureWeights, device: Device) -> Tensor {
    Tensor::from_slice(&weights.per_element(layout))
        .view([1, -1])
        .to_device(device)
}

/// The feature loss of a batch: the mean over rows of [`crate::features::feature_loss`], i.e. the
/// mean over all `[B, F]` entries of `w ⊙ (a − b)²` with `weights` from [`weight_tensor`]. A scalar.
pub fn feature_loss(a: &Tensor, b: &Tensor, weights: &Tensor) -> Tensor {
    ((a - b).square() * weights).mean(Kind::Float)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::{DatasetConfig, generate};
    use crate::features::{character_body_length, character_features, feature_loss as slice_loss};
    use crate::learn::rows_to_tensor;
    use crate::morphology::load_character;

    /// A bundled character's file: the robots' URDFs, the hound's glTF.
    fn character_file(name: &str) -> std::path::PathBuf {
        let file = if name == "hound" { "creatures/hound.glb".to_string() } else { format!("characters/{name}.urdf") };
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets").join(file)
    }

    fn generated(name: &str, frames: usize) -> (CharacterLayout, EndEffectorMapping, f32, Vec<Vec<f32>>) {
        let (tree, morph) = load_character(&character_file(name)).unwrap();
        let cfg = DatasetConfig {
            frames,
            seed: 11,
            ..DatasetConfig::default()
        };
        let set = generate(&tree, &morph, &cfg, &mut |_| {}).unwrap();
        let mut mapping = EndEffectorMapping::by_side(&tree, &morph);
        // Leave one end effector out so that the selection matters.
        mapping.human[1] = None;
        let rows = (0..set.len()).map(|i| set.state(i).to_vec()).collect();
        (set.layout, mapping, character_body_length(&tree, &morph), rows)
    }

    #[test]
    fn tensor_psi_and_loss_equal_the_slice_versions_on_generated_data() {
        for name in ["spot", "crab"] {
            let (layout, mapping, body, rows) = generated(name, 3000);
            let psi = Psi::new(&layout, &mapping, body, Device::Cpu);
            let x = rows_to_tensor(&rows, Device::Cpu).unwrap();
            let got = Vec::<f32>::try_from(psi.features(&x).unwrap().flatten(0, -1)).unwrap();
            let want: Vec<f32> = rows
                .iter()
                .flat_map(|r| character_features(&layout, r, body, &mapping))
                .collect();
            assert_eq!(got.len(), want.len());
            let worst = got
                .iter()
                .zip(&want)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f32, f32::max);
            assert!(worst < 1e-5, "{name}: largest difference {worst}");

            // The loss against the features of frames shifted by 7 (a real, non-zero difference).
            let weights = FeatureWeights {
                root_height: 2.0,
                root_orientation: 0.5,
                root_linear_velocity: 1.5,
                root_angular_velocity: 0.25,
                ee_positions: 3.0,
            };
            let (a, b) = (&want[..], &want[7 * psi.dim()..]);
            let n = b.len() / psi.dim();
            let f = psi.dim();
            let expected: f64 = (0..n)
                .map(|t| {
                    f64::from(slice_loss(
                        psi.layout(),
                        &a[t * f..(t + 1) * f],
                        &b[t * f..(t + 1) * f],
                        &weights,
                    ))
                })
                .sum::<f64>()
                / n as f64;
            let ta = Tensor::from_slice(&a[..n * f]).view([n as i64, f as i64]);
            let tb = Tensor::from_slice(b).view([n as i64, f as i64]);
            let got =
                feature_loss(&ta, &tb, &weight_tensor(psi.layout(), &weights, Device::Cpu)).double_value(&[]);
            assert!(expected > 1e-3, "{name}: the frames differ");
            assert!(
                (got - expected).abs() < 1e-5 * expected.max(1.0),
                "{name}: {got} vs {expected}"
            );
        }
    }

    #[test]
    fn kinematic_end_effectors_follow_the_joints_not_the_predicted_entries() {
        for name in ["spot", "crab", "hound"] {
            let (tree, morph) = load_character(&character_file(name)).unwrap();
            let (layout, mapping, body, rows) = generated(name, 600);
            let plain = Psi::new(&layout, &mapping, body, Device::Cpu);
            let fk = Psi::new(&layout, &mapping, body, Device::Cpu).with_kinematics(&tree, &morph);
            let x = rows_to_tensor(&rows, Device::Cpu).unwrap();
            let flat = |psi: &Psi, x: &Tensor| Vec::<f32>::try_from(psi.features(x).unwrap().flatten(0, -1)).unwrap();
            let worst = |a: &[f32], b: &[f32]| a.iter().zip(b).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
            // On the dataset the joints and the end-effector entries agree.
            let want = flat(&plain, &x);
            assert!(worst(&flat(&fk, &x), &want) < 1e-5, "{name}: {}", worst(&flat(&fk, &x), &want));

            // Predicted entries that disagree with the joints: the kinematic Ψ keeps the joints' points.
            let ee = layout.ee_positions();
            let shifted = x.shallow_clone().narrow(1, ee.start as i64, ee.len() as i64) + 0.3;
            let off = Tensor::cat(&[x.narrow(1, 0, ee.start as i64), shifted, x.narrow(1, ee.end as i64, x.size()[1] - ee.end as i64)], 1);
            assert!(worst(&flat(&plain, &off), &want) > 0.3 / body - 1e-4, "{name}: the plain Ψ reads the entries");
            assert!(worst(&flat(&fk, &off), &want) < 1e-5, "{name}: the kinematic Ψ ignores them");

            // Joints beyond their limits count as clamped, as the retargeter clamps them.
            let d = (0..tree.dof()).find(|&d| tree.limits(d).is_some_and(|l| l.upper < 10.0)).unwrap();
            let upper = tree.limits(d).unwrap().upper;
            let q = layout.joint_positions().start as i64 + d as i64;
            let at = |v: f64| {
                let y = x.copy();
                let _ = y.narrow(1, q, 1).fill_(v);
                flat(&fk, &y)
            };
            assert!(worst(&at(f64::from(upper) + 1.0), &at(f64::from(upper))) < 1e-6, "{name}: DoF {d} clamped");
            assert!(worst(&at(f64::from(upper) - 0.5), &at(f64::from(upper))) > 1e-3, "{name}: DoF {d} moves the points");
        }
    }

    #[test]
    fn root_velocities_follow_the_roots_motion_not_the_predicted_entries() {
        for name in ["spot", "crab", "hound"] {
            let (layout, mapping, body, rows) = generated(name, 600);
            let plain = Psi::new(&layout, &mapping, body, Device::Cpu);
            let moved = Psi::new(&layout, &mapping, body, Device::Cpu).with_root_motion(1.0 / 30.0);
            let x = rows_to_tensor(&rows, Device::Cpu).unwrap();
            let flat = |psi: &Psi, x: &Tensor| Vec::<f32>::try_from(psi.features(x).unwrap().flatten(0, -1)).unwrap();
            let worst = |a: &[f32], b: &[f32]| a.iter().zip(b).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
            // On the dataset the velocity entries and the root's motion agree (rad/s and body lengths
            // per second; the change of heading of a tilted root differs a little from the delta's
            // vertical component).
            let want = flat(&plain, &x);
            let got = flat(&moved, &x);
            assert!(worst(&got, &want) < 2e-3, "{name}: {}", worst(&got, &want));
            // (At 0.15 rad/s: the crab's sprawled feet on slow joints turn it at 0.35 rad/s at most.)
            assert!(want.chunks(plain.dim()).any(|r| r[plain.layout().root_angular_velocity()][2].abs() > 0.15), "{name}: the dataset turns");

            // Velocity entries that disagree with the motion: the root-motion Ψ keeps the motion's.
            let (lin, ang) = (layout.root_linear_velocity(), layout.root_angular_velocity());
            let y = x.copy();
            let _ = y.narrow(1, lin.start as i64, 2).g_add_scalar_(0.5);
            let _ = y.narrow(1, ang.start as i64, 3).g_add_scalar_(0.5);
            assert!(worst(&flat(&plain, &y), &want) > 0.49 / body.max(1.0), "{name}: the plain Ψ reads the entries");
            assert!(worst(&flat(&moved, &y), &got) < 1e-6, "{name}: the root-motion Ψ ignores them");
        }
        // A delta rotation of 0.1 rad about the vertical and a step of 3 cm ahead of the previous
        // heading: 3 rad/s, and the step seen from the new heading, 0.1 rad to the left of the old one.
        let (half, dt) = (0.05f32, 1.0 / 30.0);
        let q = Tensor::from_slice(&[half.cos(), 0.0, 0.0, half.sin()]).view([1, 4]);
        let d = Tensor::from_slice(&[0.03f32, 0.0]).view([1, 2]);
        let vz = Tensor::from_slice(&[0.2f32]).view([1, 1]);
        let (v, w) = root_velocities(&d, &q, &vz, dt);
        let (v, w) = (Vec::<f32>::try_from(v.flatten(0, -1)).unwrap(), Vec::<f32>::try_from(w.flatten(0, -1)).unwrap());
        let close = |a: &[f32], b: &[f32]| a.iter().zip(b).all(|(a, b)| (a - b).abs() < 1e-4);
        assert!(close(&w, &[0.0, 0.0, 3.0]), "{w:?}");
        assert!(close(&v, &[0.9 * 0.1f32.cos(), -0.9 * 0.1f32.sin(), 0.2]), "{v:?}");
        // The same rotation with the opposite sign, and gradients finite at no rotation at all.
        let neg = Tensor::from_slice(&[-half.cos(), 0.0, 0.0, -half.sin()]).view([1, 4]);
        assert!(close(&Vec::<f32>::try_from(root_velocities(&d, &neg, &vz, dt).1.flatten(0, -1)).unwrap(), &w));
        let still = Tensor::from_slice(&[1.0f32, 0.0, 0.0, 0.0]).view([1, 4]).set_requires_grad(true);
        root_velocities(&d, &still, &vz, dt).1.sum(Kind::Float).backward();
        assert!(Vec::<f32>::try_from(still.grad().flatten(0, -1)).unwrap().iter().all(|g| g.is_finite()));
    }

    #[test]
    fn orientation_is_sign_and_norm_invariant_and_degenerate_is_identity() {
        let q = Tensor::from_slice(&[0.9f32, 0.1, -0.3, 0.2, -1.8, -0.2, 0.6, -0.4, 0.0, 0.0, 0.0, 1e-8])
            .view([3, 4]);
        let r = Vec::<f32>::try_from(orientation_6d(&q).flatten(0, -1)).unwrap();
        for k in 0..6 {
            assert!(
                (r[k] - r[6 + k]).abs() < 1e-6,
                "entry {k}: {} vs {}",
                r[k],
                r[6 + k]
            );
        }
        assert_eq!(&r[12..], &[1.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
        // Gradients stay finite through the degenerate branch.
        let q = q.set_requires_grad(true);
        orientation_6d(&q).sum(Kind::Float).backward();
        assert!(
            Vec::<f32>::try_from(q.grad().flatten(0, -1))
                .unwrap()
                .iter()
                .all(|g| g.is_finite())
        );
    }
}
