//! Differentiable forward kinematics on tensors: the end-effector points of a character, in its
//! heading frame, from its root orientation and joint positions — the twin of
//! [`KinematicTree::forward_kinematics`] plus [`Morphology::ee_point`] that gradients flow through
//! (NKN's forward-kinematics layer, [`super::nkn`]).

use tch::{Device, Kind, Tensor};

use crate::kinematics::{JointKind, KinematicTree};
use crate::morphology::Morphology;

/// How one link hangs from its parent, as constant tensors.
#[derive(Debug)]
struct LinkJoint {
    parent: usize,
    /// Rotation `[3, 3]` and translation `[3]` of the joint frame in the parent's frame.
    origin_rot: Tensor,
    origin_pos: Tensor,
    kind: JointKind,
    /// Unit axis `[3]`, its cross-product matrix `K` and `K²` (`[3, 3]`), for Rodrigues' formula.
    axis: Tensor,
    k: Tensor,
    k2: Tensor,
    /// Joint position = `multiplier · q[dof] + offset` (a plain DoF has 1 and 0).
    dof: Option<(usize, f64, f64)>,
}

/// The forward-kinematics layer of a character (see the module docs).
#[derive(Debug)]
pub struct FkLayer {
    /// One per link but the root, in link order (parents before children).
    joints: Vec<Option<LinkJoint>>,
    /// End-effector links (feet, manipulators, head, as in x^r) and their tip offsets `[3]`.
    end_effectors: Vec<(usize, Tensor)>,
    dof: usize,
}

fn mat3(m: &nalgebra::Matrix3<f32>, device: Device) -> Tensor {
    let v: Vec<f32> = (0..3).flat_map(|r| (0..3).map(move |c| m[(r, c)])).collect();
    Tensor::from_slice(&v).view([3, 3]).to_device(device)
}

fn vec3(v: &nalgebra::Vector3<f32>, device: Device) -> Tensor {
    Tensor::from_slice(v.as_slice()).to_device(device)
}

impl FkLayer {
    /// The layer of `tree`, with the end effectors of `morph` in x^r order.
    pub fn new(tree: &KinematicTree, morph: &Morphology, device: Device) -> FkLayer {
        let joints = tree
            .links
            .iter()
            .map(|link| {
                let (j, parent) = (link.joint.as_ref()?, link.parent?);
                let a = j.axis.into_inner();
                let k = nalgebra::Matrix3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0);
                let dof = match (j.dof, &j.mimic) {
                    (Some(d), _) => Some((d, 1.0, 0.0)),
                    (None, Some(m)) => Some((m.dof, f64::from(m.multiplier), f64::from(m.offset))),
                    _ => None,
                };
                Some(LinkJoint {
                    parent,
                    origin_rot: mat3(&j.origin.rotation.to_rotation_matrix().into_inner(), device),
                    origin_pos: vec3(&j.origin.translation.vector, device),
                    kind: j.kind,
                    axis: vec3(&a, device),
                    k: mat3(&k, device),
                    k2: mat3(&(k * k), device),
                    dof,
                })
            })
            .collect();
        let end_effectors = morph
            .feet
            .iter()
            .chain(&morph.manipulators)
            .chain(&morph.head)
            .map(|&l| (l, vec3(&morph.tip_offset(l), device)))
            .collect();
        FkLayer { joints, end_effectors, dof: tree.dof() }
    }

    /// Number of end effectors.
    pub fn end_effectors(&self) -> usize {
        self.end_effectors.len()
    }

    /// End-effector points `[N, E·3]` in the heading frame (origin at the root) of root orientations
    /// `root_rot` (`[N, 3, 3]`, relative to the heading) and joint positions `q` (`[N, dof]`).
    pub fn ee_positions(&self, root_rot: &Tensor, q: &Tensor) -> Tensor {
        let n = q.size()[0];
        assert_eq!(q.size()[1], self.dof as i64, "one joint position per DoF");
        let eye = Tensor::eye(3, (Kind::Float, q.device())).expand([n, 3, 3], false);
        let mut rot: Vec<Tensor> = Vec::with_capacity(self.joints.len());
        let mut pos: Vec<Tensor> = Vec::with_capacity(self.joints.len());
        for joint in &self.joints {
            let Some(j) = joint else {
                rot.push(root_rot.shallow_clone());
                pos.push(Tensor::zeros([n, 3], (Kind::Float, q.device())));
                continue;
            };
            let (pr, pp) = (&rot[j.parent], &pos[j.parent]);
            let r0 = pr.matmul(&j.origin_rot);
            let p0 = pp + pr.matmul(&j.origin_pos.view([3, 1])).squeeze_dim(-1);
            let x = j.dof.map(|(d, m, o)| q.select(1, d as i64) * m + o);
            let (r, p) = match (j.kind, x) {
                (JointKind::Revolute | JointKind::Continuous, Some(x)) => {
                    let x = x.view([n, 1, 1]);
                    let turn = &eye + x.sin() * &j.k + (1.0 - x.cos()) * &j.k2;
                    (r0.matmul(&turn), p0)
                }
                (JointKind::Prismatic, Some(x)) => {
                    let shift = r0.matmul(&j.axis.view([3, 1])).squeeze_dim(-1) * x.view([n, 1]);
                    (r0, p0 + shift)
                }
                _ => (r0, p0),
            };
            rot.push(r);
            pos.push(p);
        }
        let points: Vec<Tensor> = self
            .end_effectors
            .iter()
            .map(|(l, tip)| &pos[*l] + rot[*l].matmul(&tip.view([3, 1])).squeeze_dim(-1))
            .collect();
        Tensor::cat(&points, 1)
    }
}

/// Rotation matrices `[N, 3, 3]` of quaternions `[N, 4]` (`[w, x, y, z]`, normalised here).
pub fn quat_to_matrix(q: &Tensor) -> Tensor {
    let q = q / (q.square().sum_dim_intlist(1, true, Kind::Float) + 1e-8).sqrt();
    let c = |i: i64| q.select(1, i);
    let (w, x, y, z) = (c(0), c(1), c(2), c(3));
    let two = |a: &Tensor, b: &Tensor| a * b * 2.0;
    let rows = [
        1.0 - two(&y, &y) - two(&z, &z),
        two(&x, &y) - two(&w, &z),
        two(&x, &z) + two(&w, &y),
        two(&x, &y) + two(&w, &z),
        1.0 - two(&x, &x) - two(&z, &z),
        two(&y, &z) - two(&w, &x),
        two(&x, &z) - two(&w, &y),
        two(&y, &z) + two(&w, &x),
        1.0 - two(&x, &x) - two(&y, &y),
    ];
    Tensor::stack(&rows, 1).view([-1, 3, 3])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::character_state::{CharacterLayout, character_state};
    use crate::learn::prior::test_support::spot;
    use crate::learn::{rows_to_tensor, tensor_to_rows};

    #[test]
    fn matches_the_states_end_effector_points() {
        let (tree, morph, set) = spot();
        let layout = CharacterLayout::new(tree, morph);
        // A few frames of the dataset (arbitrary joint positions and tilts).
        let rows: Vec<&[f32]> = (0..set.len()).step_by(set.len() / 7).map(|i| set.state(i)).collect();
        let t = rows_to_tensor(&rows, Device::Cpu).unwrap();
        let narrow = |r: std::ops::Range<usize>| t.narrow(1, r.start as i64, r.len() as i64);
        let fk = FkLayer::new(tree, morph, Device::Cpu);
        let got = fk.ee_positions(&quat_to_matrix(&narrow(layout.root_orientation())), &narrow(layout.joint_positions()));
        let got = tensor_to_rows(&got, 3 * fk.end_effectors()).unwrap();
        for (row, g) in rows.iter().zip(&got) {
            for (a, b) in row[layout.ee_positions()].iter().zip(g) {
                assert!((a - b).abs() < 1e-3, "{a} vs {b}");
            }
        }
        // And the standing pose, through the state function itself.
        let standing = tree.standing_pose();
        let x = character_state(tree, morph, &standing, &standing, 1.0 / 30.0);
        let t = rows_to_tensor(&[x.clone()], Device::Cpu).unwrap();
        let narrow = |r: std::ops::Range<usize>| t.narrow(1, r.start as i64, r.len() as i64);
        let got = fk.ee_positions(&quat_to_matrix(&narrow(layout.root_orientation())), &narrow(layout.joint_positions()));
        let got = tensor_to_rows(&got, 3 * fk.end_effectors()).unwrap().remove(0);
        for (a, b) in x[layout.ee_positions()].iter().zip(&got) {
            assert!((a - b).abs() < 1e-4, "{a} vs {b}");
        }
    }
}
