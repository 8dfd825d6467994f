//! Forward kinematics of a parsed BVH skeleton, in the file's own axes and units.

use nalgebra::{Matrix3, Vector3};

use super::bvh::{Axis, Bvh, Channel};

/// How position channels combine with a joint's OFFSET. Files disagree: most exporters write the
/// full local translation (Bandai, MotionBuilder), iClone writes a displacement added to the OFFSET.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Translation {
    /// Position channels replace the OFFSET components they name.
    Replace,
    /// Position channels are added to the OFFSET.
    AddToOffset,
}

/// Row-major 3×3 matrix. FK runs on plain arrays: it is the importer's inner loop and this keeps
/// unoptimised (debug/test) builds fast.
type M3 = [f32; 9];

const IDENTITY: M3 = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];

fn mul(a: &M3, b: &M3) -> M3 {
    let mut m = [0.0; 9];
    for r in 0..3 {
        for c in 0..3 {
            m[3 * r + c] = a[3 * r] * b[c] + a[3 * r + 1] * b[3 + c] + a[3 * r + 2] * b[6 + c];
        }
    }
    m
}

fn apply(a: &M3, v: &[f32; 3]) -> [f32; 3] {
    [
        a[0] * v[0] + a[1] * v[1] + a[2] * v[2],
        a[3] * v[0] + a[4] * v[1] + a[5] * v[2],
        a[6] * v[0] + a[7] * v[1] + a[8] * v[2],
    ]
}

/// Rotation of `deg` degrees about a file axis.
fn axis_rotation(axis: Axis, deg: f32) -> M3 {
    let (s, c) = deg.to_radians().sin_cos();
    match axis {
        Axis::X => [1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c],
        Axis::Y => [c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c],
        Axis::Z => [c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0],
    }
}

/// World positions and rotations of the joints at one frame.
#[derive(Clone, Debug)]
pub struct Pose {
    pub pos: Vec<Vector3<f32>>,
    rot: Vec<M3>,
    p: Vec<[f32; 3]>,
    /// Joints to compute (with all their ancestors); the others keep stale values.
    needed: Vec<bool>,
}

impl Pose {
    /// A pose buffer for `bvh` computing every joint.
    pub fn new(bvh: &Bvh) -> Pose {
        Self::for_joints(bvh, &(0..bvh.joints.len()).collect::<Vec<_>>())
    }

    /// A pose buffer for `bvh` computing only `joints` and their ancestors.
    pub fn for_joints(bvh: &Bvh, joints: &[usize]) -> Pose {
        let n = bvh.joints.len();
        let mut needed = vec![false; n];
        for &j in joints {
            let mut k = Some(j);
            while let Some(i) = k {
                if needed[i] {
                    break;
                }
                needed[i] = true;
                k = bvh.joints[i].parent;
            }
        }
        Pose {
            pos: vec![Vector3::zeros(); n],
            rot: vec![IDENTITY; n],
            p: vec![[0.0; 3]; n],
            needed,
        }
    }

    /// Pose of frame `frame` (rotations composed in the order the channels are listed); `modes[j]`
    /// says how joint `j`'s position channels combine with its OFFSET.
    pub fn compute(&mut self, bvh: &Bvh, frame: usize, modes: &[Translation]) {
        let values = bvh.frame(frame);
        for (j, joint) in bvh.joints.iter().enumerate() {
            if !self.needed[j] {
                continue;
            }
            let mut t = [joint.offset.x, joint.offset.y, joint.offset.z];
            let mut r = IDENTITY;
            for (k, ch) in joint.channels.iter().enumerate() {
                let v = values[joint.first_channel + k];
                match *ch {
                    Channel::Position(a) => match modes[j] {
                        Translation::Replace => t[a.index()] = v,
                        Translation::AddToOffset => t[a.index()] += v,
                    },
                    Channel::Rotation(a) => r = mul(&r, &axis_rotation(a, v)),
                }
            }
            match joint.parent {
                Some(p) => {
                    let pr = self.rot[p];
                    let d = apply(&pr, &t);
                    let pp = self.p[p];
                    self.p[j] = [pp[0] + d[0], pp[1] + d[1], pp[2] + d[2]];
                    self.rot[j] = mul(&pr, &r);
                }
                None => {
                    self.p[j] = t;
                    self.rot[j] = r;
                }
            }
            self.pos[j] = Vector3::from(self.p[j]);
        }
    }

    /// World position of a point given in joint `j`'s frame (e.g. an end site).
    pub fn point(&self, j: usize, local: &Vector3<f32>) -> Vector3<f32> {
        let d = apply(&self.rot[j], &[local.x, local.y, local.z]);
        self.pos[j] + Vector3::from(d)
    }

    /// World rotation of joint `j`.
    pub fn rotation(&self, j: usize) -> Matrix3<f32> {
        Matrix3::from_row_slice(&self.rot[j])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::human::test_rig::close;

    #[test]
    fn rotations_compose_in_listed_order() {
        // Z then X, 90° each, applied to the child's offset (0, 1, 0): Rz(90)·Rx(90)·(0,1,0) = Rz(90)·(0,0,1) = (0,0,1).
        let text = "HIERARCHY\nROOT a\n{\nOFFSET 0 0 0\nCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\nJOINT b\n{\nOFFSET 0 1 0\nCHANNELS 3 Zrotation Xrotation Yrotation\nEnd Site\n{\nOFFSET 0 1 0\n}\n}\n}\nMOTION\nFrames: 1\nFrame Time: 0.1\n1 2 3 90 90 0 0 0 0\n";
        let bvh = Bvh::parse(text, "t").unwrap();
        let mut pose = Pose::new(&bvh);
        pose.compute(&bvh, 0, &[Translation::Replace; 2]);
        let b = pose.pos[1] - Vector3::new(1.0, 2.0, 3.0);
        assert!((b - Vector3::new(0.0, 0.0, 1.0)).norm() < 1e-5, "{b:?}");
        pose.compute(&bvh, 0, &[Translation::AddToOffset; 2]);
        assert!((pose.pos[0] - Vector3::new(1.0, 2.0, 3.0)).norm() < 1e-6);
    }

    /// A root `a` at (1, 2, 3) turned by `root` (Z, X, Y degrees); its child `b` at (0, 1, 0) with
    /// position channels (10, 20, 30) and turned by `child`; below `b`, `c` at (0, 0, 2) with an end
    /// site (1, 0, 0); beside `b`, `d` at (5, 0, 0).
    fn chain(root: [f32; 3], child: [f32; 3]) -> Bvh {
        let text = format!(
            "HIERARCHY\nROOT a\n{{\nOFFSET 0 0 0\nCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n\
             JOINT b\n{{\nOFFSET 0 1 0\nCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n\
             JOINT c\n{{\nOFFSET 0 0 2\nCHANNELS 3 Zrotation Xrotation Yrotation\nEnd Site\n{{\nOFFSET 1 0 0\n}}\n}}\n}}\n\
             JOINT d\n{{\nOFFSET 5 0 0\nCHANNELS 3 Zrotation Xrotation Yrotation\nEnd Site\n{{\nOFFSET 0 1 0\n}}\n}}\n}}\n\
             MOTION\nFrames: 1\nFrame Time: 0.1\n1 2 3 {} {} {} 10 20 30 {} {} {} 0 0 0 0 0 0\n",
            root[0], root[1], root[2], child[0], child[1], child[2]
        );
        Bvh::parse(&text, "t").unwrap()
    }

    #[test]
    fn each_axis_turns_right_handed() {
        let modes = [Translation::AddToOffset; 4];
        let cases = [([90.0, 0.0, 0.0], [0.0, 0.0, 2.0], [0.0, 1.0, 0.0]), ([0.0, 90.0, 0.0], [0.0, -2.0, 0.0], [1.0, 0.0, 0.0]), ([0.0, 0.0, 90.0], [2.0, 0.0, 0.0], [0.0, 0.0, -1.0])];
        for (child, c, end) in cases {
            // `b`'s rotation turns `c`'s offset (0, 0, 2) and the end site (1, 0, 0) below it.
            let bvh = chain([0.0; 3], child);
            let mut pose = Pose::new(&bvh);
            pose.compute(&bvh, 0, &modes);
            let b = pose.pos[1];
            assert!(close(b, [11.0, 23.0, 33.0]), "{b:?}");
            assert!(close(pose.pos[2] - b, c), "{child:?}: {:?}", pose.pos[2] - b);
            assert!(close(pose.point(2, &Vector3::x()) - pose.pos[2], end), "{child:?}");
        }
    }

    #[test]
    fn a_joints_world_rotation_composes_its_ancestors_and_carries_its_children() {
        // The root turned 90° about Z, `b` 90° about X: `b`'s world rotation is Rz·Rx.
        let bvh = chain([90.0, 0.0, 0.0], [0.0, 90.0, 0.0]);
        let mut pose = Pose::new(&bvh);
        pose.compute(&bvh, 0, &[Translation::Replace; 4]);
        let want = Matrix3::new(0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0);
        assert!((pose.rotation(1) - want).norm() < 1e-5, "{}", pose.rotation(1));
        // Replace: `b` sits at its channels (10, 20, 30) turned by the root: (−20, 10, 30) from it.
        assert!(close(pose.pos[1], [-19.0, 12.0, 33.0]), "{:?}", pose.pos[1]);
        assert!(close(pose.pos[2], [-17.0, 12.0, 33.0]), "{:?}", pose.pos[2]);
        // `d` turns with the root only: (5, 0, 0) → (0, 5, 0).
        assert!(close(pose.pos[3], [1.0, 7.0, 3.0]), "{:?}", pose.pos[3]);
    }

    #[test]
    fn a_pose_for_some_joints_computes_them_and_their_ancestors_only() {
        let bvh = chain([0.0; 3], [0.0; 3]);
        let mut pose = Pose::for_joints(&bvh, &[2, 1]);
        pose.compute(&bvh, 0, &[Translation::AddToOffset; 4]);
        assert!(close(pose.pos[0], [1.0, 2.0, 3.0]));
        assert!(close(pose.pos[1], [11.0, 23.0, 33.0]));
        assert!(close(pose.pos[2], [11.0, 23.0, 35.0]));
        assert_eq!(pose.pos[3], Vector3::zeros(), "`d` is not asked for");
        let mut pose = Pose::for_joints(&bvh, &[3]);
        pose.compute(&bvh, 0, &[Translation::AddToOffset; 4]);
        assert!(close(pose.pos[3], [6.0, 2.0, 3.0]));
        assert_eq!(pose.pos[1], Vector3::zeros());
    }
}
