//! Small BVH rigs written in the unit tests: a joint list (name, parent's name, offset) → a parsed
//! [`Bvh`], and the parts of a humanoid to assemble one from.

use nalgebra::Vector3;

use super::bvh::Bvh;

/// A joint: name, parent's name (`None` for the root), offset.
pub(crate) type Spec = (&'static str, Option<&'static str>, [f32; 3]);

const ROTATIONS: &str = "Zrotation Xrotation Yrotation";

/// A one-frame BVH at its rest pose of `joints` (listed parents first): the root with position and
/// rotation channels, the others with rotations.
pub(crate) fn bvh(joints: &[Spec]) -> Bvh {
    Bvh::parse(&rest_text(joints), "t.bvh").unwrap()
}

/// The text of [`bvh`]'s BVH.
pub(crate) fn rest_text(joints: &[Spec]) -> String {
    let channels: usize = 6 + 3 * (joints.len() - 1);
    text(joints, |i| i == 0, &[vec![0.0; channels]])
}

/// Indices (into `joints`) of joint `i`'s children, in list order.
fn children(joints: &[Spec], i: usize) -> Vec<usize> {
    (0..joints.len()).filter(|&k| joints[k].1 == Some(joints[i].0)).collect()
}

/// Indices of `joints` in the order [`parse`] writes them, which is the order of the parsed BVH's joints
/// and of each frame's values (depth first, children in list order).
pub(crate) fn file_order(joints: &[Spec]) -> Vec<usize> {
    fn visit(i: usize, joints: &[Spec], out: &mut Vec<usize>) {
        out.push(i);
        for k in children(joints, i) {
            visit(k, joints, out);
        }
    }
    let mut out = Vec::new();
    visit(0, joints, &mut out);
    out
}

/// A BVH of `joints` in which the joints `positioned` picks have position channels (before their
/// rotations) and the others rotations only, with `frames` holding each frame's values in file order
/// ([`file_order`]).
pub(crate) fn parse(joints: &[Spec], positioned: impl Fn(usize) -> bool, frames: &[Vec<f32>]) -> Bvh {
    Bvh::parse(&text(joints, positioned, frames), "t.bvh").unwrap()
}

/// The text of [`parse`]'s BVH.
pub(crate) fn text(joints: &[Spec], positioned: impl Fn(usize) -> bool, frames: &[Vec<f32>]) -> String {
    fn write(i: usize, joints: &[Spec], positioned: &dyn Fn(usize) -> bool, out: &mut String) {
        let (name, parent, [x, y, z]) = joints[i];
        let kind = if parent.is_none() { "ROOT" } else { "JOINT" };
        let channels =
            if positioned(i) { format!("6 Xposition Yposition Zposition {ROTATIONS}") } else { format!("3 {ROTATIONS}") };
        out.push_str(&format!("{kind} {name}\n{{\nOFFSET {x} {y} {z}\nCHANNELS {channels}\n"));
        let children = children(joints, i);
        for &k in &children {
            write(k, joints, positioned, out);
        }
        if children.is_empty() {
            out.push_str("End Site\n{\nOFFSET 0 1 0\n}\n");
        }
        out.push_str("}\n");
    }
    let mut text = String::from("HIERARCHY\n");
    write(0, joints, &positioned, &mut text);
    text.push_str(&format!("MOTION\nFrames: {}\nFrame Time: 0.0333333\n", frames.len()));
    for f in frames {
        let values: Vec<String> = f.iter().map(|v| v.to_string()).collect();
        text.push_str(&(values.join(" ") + "\n"));
    }
    text
}

/// Whether `a` is within 10⁻⁵ of `b`.
pub(crate) fn close(a: Vector3<f32>, b: [f32; 3]) -> bool {
    (a - Vector3::from(b)).norm() < 1e-5
}

/// A leg below the hips: thigh, shin and foot named `names`, the hip `x` to the side.
pub(crate) fn leg(names: [&'static str; 3], x: f32) -> Vec<Spec> {
    vec![(names[0], Some("Hips"), [x, -5.0, 0.0]), (names[1], Some(names[0]), [0.0, -40.0, 0.0]), (names[2], Some(names[1]), [0.0, -40.0, 0.0])]
}

/// Hips, then `parts`.
pub(crate) fn rig(parts: &[Vec<Spec>]) -> Vec<Spec> {
    let mut joints = vec![("Hips", None, [0.0, 90.0, 0.0])];
    joints.extend(parts.iter().flatten().copied());
    joints
}

/// Both legs, and a torso of `torso` between the hips and the arms and head.
pub(crate) fn body(torso: &[Spec]) -> Vec<Spec> {
    rig(&[torso.to_vec(), leg(["LeftUpLeg", "LeftLeg", "LeftFoot"], 8.0), leg(["RightUpLeg", "RightLeg", "RightFoot"], -8.0)])
}

/// A spine, a neck, a head named `head` and both arms.
pub(crate) fn torso(head: &'static str) -> Vec<Spec> {
    [spine_to_head(head), arms()].concat()
}

pub(crate) fn spine_to_head(head: &'static str) -> Vec<Spec> {
    [vec![("Spine", Some("Hips"), [0.0, 15.0, 0.0]), ("Chest", Some("Spine"), [0.0, 15.0, 0.0])], neck_and_head(head)].concat()
}

pub(crate) fn neck_and_head(head: &'static str) -> Vec<Spec> {
    vec![("Neck", Some("Chest"), [0.0, 15.0, 0.0]), (head, Some("Neck"), [0.0, 8.0, 0.0])]
}

/// Both arms from the chest.
pub(crate) fn arms() -> Vec<Spec> {
    vec![
        ("LeftArm", Some("Chest"), [15.0, 0.0, 0.0]),
        ("LeftForeArm", Some("LeftArm"), [25.0, 0.0, 0.0]),
        ("LeftHand", Some("LeftForeArm"), [25.0, 0.0, 0.0]),
        ("RightArm", Some("Chest"), [-15.0, 0.0, 0.0]),
        ("RightForeArm", Some("RightArm"), [-25.0, 0.0, 0.0]),
        ("RightHand", Some("RightForeArm"), [-25.0, 0.0, 0.0]),
    ]
}
