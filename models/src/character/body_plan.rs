//! The body plan of a rigged creature, and the [`KinematicTree`] and [`Morphology`] built from it.
//!
//! Works on the bones [`super::gltf::read`] found, at rest, in the character frame, with a capsule per
//! bone fitted to the vertices it deforms most, thinned where it would reach below the creature at rest
//! ([`super::proxy::above_floor`]). Nothing depends on bone names.
//!
//! # Limbs
//! A *branching* bone has two or more children. The children of the body root and of branching bones
//! start *limbs*: a limb runs down single-child bones to a leaf (or to a *hand*: a bone whose children
//! are all short chains of at most three bones reaching less than half as far as the limb, i.e. fingers
//! or toes). A limb that ends at another branching bone is *spine*, and its branches are limbs in turn.
//! Then, with `H` the creature's height, `S` its largest extent and `W` its width at rest:
//! - **Feet**: limbs of two or more bones whose lowest vertex (of the tip and its fingers/toes) is
//!   within `max(3 % H, 5 mm)` of the ground and whose first joint stands at least `H/4` above it.
//!   The foot point is that vertex (for a paw that an IK helper holds, the point under the helper's
//!   origin at that height: see [`super::helpers`]), and the foot's collision shape the sphere resting
//!   on it.
//! - **Head**: of the limbs whose tip is near the mid-plane (`|y| < 10 % W` from the body root) and
//!   that deform at least 30 % as many vertices as the largest such limb, the longest one whose tip
//!   lies ahead of the body root: the front of the body's axis, not a jaw or a tongue (short limbs off
//!   the skull, which may reach farther forward). With none ahead, the one whose tip is farthest
//!   forward.
//! - **Arms** (and wings): limbs of two or more bones whose tip is off the mid-plane with a mirror
//!   image among the other limbs (within `0.15 S`), whose length is at least `S/10` and which do not
//!   branch from the head's path close to the head (ears). Their end effector is the far end of the
//!   tip's capsule. They become manipulators.
//! - **Tails**: other limbs of two or more bones, without a mirror image, whose tip is behind the body
//!   root.
//! - **Spine**: the bones from the body root to the head that are neither, the other branching bones,
//!   and the bones above the feet (between the body root and the bones the legs hang from). Leg IK
//!   holds those, and the controllers bend them as a body ([`crate::controller::spine`]).
//! - Everything else (ears, jaws, tongues, fingers, toes) stays **at rest**.
//!
//! The morphology lists the spine's DoFs ([`Morphology::spine`]) and the body's axis from the head
//! through the body root to the longest tail ([`Morphology::body_axis`]), along which a legless
//! creature crawls ([`crate::controller::undulation`]).
//!
//! # Joints
//! Moving bones get up to three revolute DoFs (see [`super::gltf`]). Leg bones use the leg's axes: the
//! vertical, the knee hinge (the lateral axis for a leg that hangs below its hip, else the horizontal
//! normal of the vertical plane through hip and foot) and the leg's outward direction. With clips in the
//! file, each axis of those the role turns about ([`default_limits`]: three at a hip, shoulder or the
//! base of an arm, the hinge alone further down a limb, yaw and pitch along the spine, neck, head and
//! tail) gets the role's default range, widened to the clips' range over every keyframe (plus 15 % + 3°,
//! [`clip_limits`]) where the clips turn it further. The profile overrides every choice.

use std::collections::BTreeMap;

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, UnitQuaternion, Vector3};

use super::gltf::{Rig, fit_capsule};
use super::{helpers, proxy};
use crate::geometry::{Aabb, Geometry, Shape};
use crate::kinematics::{JointKind, JointSpec, KinematicTree, Limits, Link};
use crate::morphology::Morphology;

/// Largest radius of a foot's contact sphere, as a fraction of the creature's height at rest.
pub const FOOT_RADIUS: f32 = 0.01;

/// Smallest span (rad) of an axis' keyframes over a file's clips, the rest pose included, for which
/// the clips set its range ([`clip_limits`]; 5°).
pub const MIN_CLIP_RANGE: f32 = 0.0873;

/// What a moving bone is part of.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    Leg { first: bool },
    Arm { first: bool },
    Head,
    Spine,
    Tail,
}

impl Role {
    /// The role's name, as `ace inspect` shows it.
    pub fn label(self) -> &'static str {
        match self {
            Role::Leg { first: true } => "hip",
            Role::Leg { first: false } => "leg",
            Role::Arm { first: true } => "shoulder",
            Role::Arm { first: false } => "arm",
            Role::Head => "head",
            Role::Spine => "spine",
            Role::Tail => "tail",
        }
    }
}

/// The three axis names, in the order their DoFs are applied.
pub const AXES: [&str; 3] = ["yaw", "pitch", "roll"];

/// Default pitch range (±°) of a leg's first joint (hip, shoulder) in a creature without clips.
///
/// Dogs' legs swing through about 110° at the shoulder and the hip and fold through 120–165° at the
/// elbow, stifle, carpus and tarsus (goniometry of Labrador retrievers: Jaegger, Marcellin-Little and
/// Levine, Am. J. Vet. Res. 63, 2002); the Fox's and the T-Rex's own clips turn these joints 105–110°
/// one way. A bind pose stands anywhere in that range, and which way a joint folds is not known from
/// it, so each side gets most of the range. Narrower (±45° and ±60°), the Fox without its clips could
/// not crouch to its standing height and the T-Rex's dataset slid in a third of its frames.
pub const LEG_SWING_DEG: f32 = 75.0;
/// Default pitch range (±°) of a leg's further joints (elbow, knee, ankle, wrist); see [`LEG_SWING_DEG`].
pub const LEG_FOLD_DEG: f32 = 100.0;

/// Default limits (rad) of a bone of `role` with no keyframes, per axis (`None`: no DoF).
pub fn default_limits(role: Role) -> [Option<(f32, f32)>; 3] {
    let d = |deg: f32| Some((-deg.to_radians(), deg.to_radians()));
    match role {
        Role::Leg { first: true } => [d(10.0), d(LEG_SWING_DEG), d(20.0)],
        Role::Leg { first: false } => [None, d(LEG_FOLD_DEG), None],
        Role::Arm { first: true } => [d(45.0), d(45.0), d(45.0)],
        Role::Arm { first: false } => [None, d(75.0), None],
        Role::Head => [d(40.0), d(30.0), None],
        Role::Spine => [d(15.0), d(15.0), None],
        Role::Tail => [d(25.0), d(20.0), None],
    }
}

/// Limits from keyframe angles: axes whose keyframes span more than [`MIN_CLIP_RANGE`] with the rest
/// pose (0) among them, their range widened by 15 % + 3° on each side and always containing the rest
/// pose.
pub fn clip_limits(angles: &[[f32; 3]]) -> [Option<(f32, f32)>; 3] {
    let mut out = [None; 3];
    for (k, o) in out.iter_mut().enumerate() {
        let lo = angles.iter().map(|a| a[k]).fold(f32::INFINITY, f32::min);
        let hi = angles.iter().map(|a| a[k]).fold(f32::NEG_INFINITY, f32::max);
        let range = hi - lo;
        // Measured from the rest pose too: a bone the clips hold away from rest, however still,
        // must reach where they hold it.
        if range.is_finite() && hi.max(0.0) - lo.min(0.0) > MIN_CLIP_RANGE {
            let m = 0.15 * range + 3f32.to_radians();
            let pi = std::f32::consts::PI;
            *o = Some(((lo - m).min(0.0).max(-pi), (hi + m).max(0.0).min(pi)));
        }
    }
    out
}

/// Per-creature choices a profile may override (the glTF keys of [`crate::morphology::Profile`]).
#[derive(Clone, Debug, Default)]
pub struct Overrides {
    pub feet: Option<Vec<String>>,
    pub manipulators: Option<Vec<String>>,
    pub head: Option<String>,
    /// Bones that move (replaces the analysis).
    pub animated: Option<Vec<String>>,
    /// Bones held at rest.
    pub at_rest: Vec<String>,
    /// Bone → axes it keeps.
    pub dofs: BTreeMap<String, Vec<String>>,
    /// Joint (`bone:axis`) → limits (rad).
    pub limits: BTreeMap<String, [f32; 2]>,
    /// Bones that also slide along their rest axes (prismatic DoFs `bone:x`, `bone:y`, `bone:z`).
    pub translate: Vec<String>,
}

/// What the analysis decided, for `ace inspect` and the warnings.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct BodyPlan {
    /// The bone that is the tree's root link.
    pub body_root: String,
    /// Helper bones (outside the body, or deforming nothing below them): not DoFs.
    pub helpers: Vec<String>,
    /// Moving bones and their roles ([`Role::label`]).
    pub roles: BTreeMap<String, &'static str>,
    /// Body bones held at rest.
    pub at_rest: Vec<String>,
    /// Tail tips.
    pub tails: Vec<String>,
    /// Notes on what was assumed.
    pub warnings: Vec<String>,
    /// Index of the body root in the rig's bones.
    #[serde(skip)]
    pub root_bone: usize,
    /// Every body bone's link and DoFs, for turning the file's clips into poses.
    #[serde(skip)]
    pub joints: Vec<BoneJoint>,
}

/// A body bone in the tree: its link (the one named after it) and the DoF of each of its axes.
#[derive(Clone, Debug)]
pub struct BoneJoint {
    /// Index in the rig's bones.
    pub bone: usize,
    /// Its link.
    pub link: usize,
    /// DoF of its yaw, pitch and roll axis, where it has one.
    pub dofs: [Option<usize>; 3],
    /// DoF of its slide along the x, y and z axis of its rest frame (m), where it has one
    /// ([`Overrides::translate`]); applied before its turns.
    pub slides: [Option<usize>; 3],
    /// Its axes in the character frame at rest: columns roll (x), pitch (y), yaw (z).
    pub basis: Matrix3<f32>,
}

struct Limb {
    /// Bones from the limb's first bone to its tip.
    path: Vec<usize>,
    /// Bones below the tip (fingers, toes).
    digits: Vec<usize>,
    /// The bone whose child starts the limb.
    from: usize,
}

/// Checks what the overrides name before any is used: bones of the body, axes among [`AXES`], limits
/// keyed `bone:axis` on an axis the bone keeps. Each was skipped without a word (a `[dofs]` axis
/// spelled `Yaw` took every DoF from its bone; a limit on an axis `[dofs]` leaves out put it back).
fn check_overrides(ov: &Overrides, by_name: &dyn Fn(&str, &str) -> Result<usize, String>) -> Result<(), String> {
    let axis = |key: &str, a: &str| {
        if AXES.contains(&a) { Ok(()) } else { Err(format!("`{key}`: `{a}` is not an axis (they are {})", AXES.join(", "))) }
    };
    for (bone, axes) in &ov.dofs {
        let key = format!("dofs.\"{bone}\"");
        by_name(&key, bone)?;
        for a in axes {
            axis(&key, a)?;
        }
    }
    for joint in ov.limits.keys() {
        let key = format!("limits.\"{joint}\"");
        let Some((bone, a)) = joint.rsplit_once(':') else {
            return Err(format!("`{key}`: a limit is keyed `bone:axis`, the axis one of {}", AXES.join(", ")));
        };
        by_name(&key, bone)?;
        axis(&key, a)?;
        if ov.dofs.get(bone).is_some_and(|kept| !kept.iter().any(|k| k == a)) {
            return Err(format!("`{key}`: `dofs.\"{bone}\"` leaves the {a} axis out"));
        }
    }
    for bone in &ov.translate {
        by_name("translate", bone)?;
    }
    Ok(())
}

/// Builds the tree and morphology of a creature (see the module docs). `name` names the tree.
pub fn build(
    rig: &Rig,
    name: &str,
    ov: &Overrides,
) -> Result<(KinematicTree, Morphology, BodyPlan), String> {
    let nb = rig.bones.len();
    let mut children = vec![Vec::new(); nb];
    for (i, b) in rig.bones.iter().enumerate() {
        if let Some(p) = b.parent {
            children[p].push(i);
        }
    }
    // Vertices each bone and the bones below it deform. A bone below which nothing deforms (a prop
    // socket, an exporter's `_end` leaf bone) has no flesh to stand or reach with: it is no part of the
    // body, as a non-deforming helper is not, and would otherwise end a limb in place of the paw.
    let mut flesh: Vec<usize> = rig.bones.iter().map(|b| b.deforms).collect();
    let mut size = vec![1usize; nb];
    for i in (0..nb).rev() {
        if let Some(p) = rig.bones[i].parent {
            size[p] += size[i];
            flesh[p] += flesh[i];
        }
    }
    // Body root: down from the largest top-level bone past bones that deform little and have one large child.
    let total_vertices = rig.vertices.len().max(1);
    let mut root = (0..nb)
        .filter(|&i| rig.bones[i].parent.is_none())
        .max_by_key(|&i| (size[i], std::cmp::Reverse(i)))
        .ok_or("no bones")?;
    loop {
        let big: Vec<usize> = children[root]
            .iter()
            .copied()
            .filter(|&c| size[c] > 2 && flesh[c] > 0)
            .collect();
        if big.len() == 1 && rig.bones[root].deforms * 20 <= total_vertices {
            root = big[0];
        } else {
            break;
        }
    }
    let mut in_body = vec![false; nb];
    let mut stack = vec![root];
    while let Some(b) = stack.pop() {
        in_body[b] = true;
        stack.extend(children[b].iter().filter(|&&c| flesh[c] > 0));
    }
    let body: Vec<usize> = (0..nb).filter(|&i| in_body[i]).collect();
    let pos0 = |b: usize| rig.bones[b].rest.translation.vector;
    let mut plan = BodyPlan {
        root_bone: root,
        body_root: rig.bones[root].name.clone(),
        ..Default::default()
    };

    // Each vertex goes to its heaviest bone; a vertex that a helper deforms most (an IK foot hanging off
    // the root) goes to the helper's host: the end of a body chain nearest to the helper, which is where an
    // IK target sits; the helper then follows that bone as a fixed link, where the clips hold it
    // ([`super::helpers`]), and moves its vertices there with it.
    let leaves: Vec<usize> = body
        .iter()
        .copied()
        .filter(|&b| children[b].iter().all(|&c| !in_body[c]))
        .collect();
    let host_of = |h: usize| -> usize {
        let p = rig.bones[h].rest.translation.vector;
        leaves
            .iter()
            .copied()
            .min_by(|&a, &b| (pos0(a) - p).norm().total_cmp(&(pos0(b) - p).norm()))
            .unwrap_or(root)
    };
    let heaviest = |w: &[(usize, f32)]| w.iter().max_by(|a, b| a.1.total_cmp(&b.1)).map(|&(b, _)| b);
    let mut helper_host: BTreeMap<usize, usize> = BTreeMap::new();
    for (_, w) in &rig.vertices {
        if let Some(h) = heaviest(w).filter(|&h| !in_body[h]) {
            helper_host.entry(h).or_insert_with(|| host_of(h));
        }
    }
    let held = helpers::held_offsets(rig, &helper_host);
    // A helper's move from its bind offset, at rest in the character frame.
    let shift: BTreeMap<usize, Vector3<f32>> = held
        .iter()
        .map(|(&h, at)| {
            let host = &rig.bones[helper_host[&h]].rest;
            (h, host * Point3::from(*at) - Point3::from(rig.bones[h].rest.translation.vector))
        })
        .collect();
    let mut owned: Vec<Vec<Point3<f32>>> = vec![Vec::new(); nb];
    for (p, w) in &rig.vertices {
        let p = w.iter().filter_map(|(b, wb)| shift.get(b).map(|s| s * *wb)).fold(*p, |p, s| p + s);
        match heaviest(w) {
            Some(b) if in_body[b] => owned[b].push(p),
            Some(h) => owned[helper_host[&h]].push(p),
            None => {}
        }
    }
    for i in 0..nb {
        if !in_body[i] {
            plan.helpers.push(rig.bones[i].name.clone());
        }
    }
    for &b in &body {
        proxy::at_played_size(&mut owned[b], &rig.bones[b]);
    }
    let capsules: Vec<Option<Geometry>> = (0..nb)
        .map(|b| {
            if !in_body[b] {
                return None;
            }
            let inv = rig.bones[b].rest.inverse();
            let local: Vec<Point3<f32>> = owned[b].iter().map(|p| inv.transform_point(p)).collect();
            // The bone's own direction: towards the mean of its children's joints.
            let kids: Vec<Vector3<f32>> = children[b]
                .iter()
                .filter(|&&c| in_body[c])
                .map(|&c| inv.transform_point(&Point3::from(rig.bones[c].rest.translation.vector)).coords)
                .collect();
            let along = (!kids.is_empty()).then(|| kids.iter().sum::<Vector3<f32>>() / kids.len() as f32);
            fit_capsule(&local, along)
        })
        .collect();
    let capsule_ends = |b: usize| -> Option<(Point3<f32>, Point3<f32>, f32)> {
        let g = capsules[b].as_ref()?;
        let Shape::Capsule { radius, length } = g.shape else {
            return None;
        };
        let pose = rig.bones[b].rest * g.origin;
        Some((
            pose.transform_point(&Point3::new(0.0, 0.0, -0.5 * length)),
            pose.transform_point(&Point3::new(0.0, 0.0, 0.5 * length)),
            radius,
        ))
    };
    // The lowest vertex a set of bones deforms: where a foot touches the ground.
    let lowest_point = |bones: &[usize]| -> Option<Point3<f32>> {
        bones.iter().flat_map(|&b| owned[b].iter().copied()).min_by(|a, b| a.z.total_cmp(&b.z))
    };
    let mut bb = Aabb::empty();
    for &b in &body {
        for p in &owned[b] {
            bb.include(p);
        }
        bb.include(&Point3::from(rig.bones[b].rest.translation.vector));
    }
    let ground = bb.min.z;
    let height = (bb.max.z - bb.min.z).max(1e-3);
    let extent = (bb.max - bb.min).max().max(1e-3);
    let width = (bb.max.y - bb.min.y).max(1e-3);
    let tol = (0.03 * height).max(0.005);
    let pos = |b: usize| rig.bones[b].rest.translation.vector;
    let reach = |path: &[usize]| -> f32 {
        let mut r = 0.0;
        for w in path.windows(2) {
            r += (pos(w[1]) - pos(w[0])).norm();
        }
        let last = *path.last().expect("non-empty");
        r + capsule_ends(last).map_or(0.0, |(a, e, rad)| {
            ((a - Point3::from(pos(last))).norm()).max((e - Point3::from(pos(last))).norm()) + rad
        })
    };

    // Limbs.
    let body_kids = |b: usize| -> Vec<usize> {
        children[b]
            .iter()
            .copied()
            .filter(|&c| in_body[c])
            .collect()
    };
    let subtree = |b: usize| -> Vec<usize> {
        let mut out = vec![b];
        let mut i = 0;
        while i < out.len() {
            out.extend(children[out[i]].iter().copied().filter(|&c| in_body[c]));
            i += 1;
        }
        out
    };
    let mut limbs: Vec<Limb> = Vec::new();
    let mut spine: Vec<usize> = Vec::new();
    let mut todo: Vec<(usize, usize)> = body_kids(root).into_iter().map(|c| (root, c)).collect();
    while let Some((from, start)) = todo.pop() {
        let mut path = vec![start];
        loop {
            let k = body_kids(*path.last().expect("non-empty"));
            if k.len() == 1 {
                path.push(k[0]);
            } else {
                break;
            }
        }
        let tip = *path.last().expect("non-empty");
        let kids = body_kids(tip);
        if kids.is_empty() {
            limbs.push(Limb {
                path,
                digits: Vec::new(),
                from,
            });
            continue;
        }
        let r = reach(&path);
        let digits_only = path.len() >= 2
            && kids.iter().all(|&c| {
                let s = subtree(c);
                s.len() <= 3
                    && s.iter().all(|&x| body_kids(x).len() <= 1)
                    && (pos(*s.last().expect("non-empty")) - pos(tip)).norm() < 0.5 * r
            });
        if digits_only {
            let digits = kids.iter().flat_map(|&c| subtree(c)).collect();
            limbs.push(Limb { path, digits, from });
        } else {
            spine.extend(&path);
            todo.extend(kids.into_iter().map(|c| (tip, c)));
        }
    }
    limbs.sort_by_key(|l| l.path[0]);

    // The body bone `n` that profile key `key` names.
    let by_name = |key: &str, n: &str| -> Result<usize, String> {
        body.iter()
            .copied()
            .find(|&b| rig.bones[b].name == n)
            .ok_or_else(|| format!("`{key}`: no body bone named `{n}`"))
    };
    check_overrides(ov, &by_name)?;
    let mid_y = pos(root).y;
    let tip_of = |l: &Limb| *l.path.last().expect("non-empty");
    let midline = |l: &Limb| (pos(tip_of(l)).y - mid_y).abs() < 0.1 * width;
    // Feet.
    let mut feet: Vec<(usize, Point3<f32>)> = Vec::new();
    let mut foot_limbs = Vec::new();
    for (i, l) in limbs.iter().enumerate() {
        let mut bones = vec![tip_of(l)];
        bones.extend(&l.digits);
        let Some(low) = lowest_point(&bones) else {
            continue;
        };
        if l.path.len() >= 2 && low.z - ground <= tol && pos(l.path[0]).z - low.z >= 0.25 * height {
            feet.push((tip_of(l), low));
            foot_limbs.push(i);
        }
    }
    if let Some(names) = &ov.feet {
        feet.clear();
        foot_limbs.clear();
        for n in names {
            let b = by_name("feet", n)?;
            let p = lowest_point(&[b]).unwrap_or_else(|| Point3::from(pos(b)));
            feet.push((b, p));
            if let Some(i) = limbs.iter().position(|l| l.path.contains(&b)) {
                foot_limbs.push(i);
            }
        }
    }
    // A paw that a helper holds pivots about the helper's origin: its contact is under the pivot (the
    // top of the helpers on the foot, e.g. an IK foot rather than its toes).
    for (f, p) in feet.iter_mut() {
        let on_foot: Vec<usize> = helper_host.iter().filter(|&(_, &host)| host == *f).map(|(&h, _)| h).collect();
        let top = on_foot.iter().copied().find(|&h| rig.bones[h].parent.is_none_or(|q| !on_foot.contains(&q)));
        if let Some(h) = top {
            *p = helpers::under_pivot(&(rig.bones[*f].rest * Point3::from(held[&h])), p);
        }
    }
    if feet.is_empty() {
        plan.warnings.push(
            "no feet found (no limb reaches the ground from above it at rest): the creature is taken as legless; \
             name its feet in the profile if it has some"
                .into(),
        );
    }
    // Head.
    let root_x = pos(root).x;
    let dominant = |b: usize| owned[b].len();
    // The head: of the mid-plane limbs that are a substantial part of the body (at least 30 % of the
    // vertices of the largest such limb: a head, not a thin tongue), the longest one reaching ahead of
    // the body root — the front of the body's axis; a jaw or a tongue hanging off the skull is short
    // next to the body that carries the head (the Snake's skull bone, rigged as a sibling of its body,
    // holds a tongue that reaches farther forward than its head). With none ahead, the most forward.
    let flesh = |l: &Limb| l.path.iter().chain(&l.digits).map(|&b| dominant(b)).sum::<usize>();
    let mid: Vec<usize> = (0..limbs.len())
        .filter(|i| !foot_limbs.contains(i) && midline(&limbs[*i]))
        .collect();
    let most = mid
        .iter()
        .map(|&i| flesh(&limbs[i]))
        .max()
        .unwrap_or(0);
    let substantial: Vec<usize> = mid
        .iter()
        .copied()
        .filter(|&i| flesh(&limbs[i]) * 10 >= most * 3)
        .collect();
    let ahead: Vec<usize> = substantial
        .iter()
        .copied()
        .filter(|&i| pos(tip_of(&limbs[i])).x > pos(root).x)
        .collect();
    let head_limb = if ahead.is_empty() {
        substantial.iter().copied().max_by(|&a, &b| {
            pos(tip_of(&limbs[a]))
                .x
                .total_cmp(&pos(tip_of(&limbs[b])).x)
        })
    } else {
        ahead
            .iter()
            .copied()
            .max_by(|&a, &b| reach(&limbs[a].path).total_cmp(&reach(&limbs[b].path)))
    };
    let mut head = head_limb.map(|i| tip_of(&limbs[i]));
    if let Some(h) = &ov.head {
        head = if h.is_empty() {
            None
        } else {
            Some(by_name("head", h)?)
        };
    }
    // Tails and arms.
    let head_path: Vec<usize> = head.map_or(Vec::new(), |h| {
        let mut p = vec![h];
        while let Some(q) = rig.bones[*p.last().expect("non-empty")].parent {
            if !in_body[q] {
                break;
            }
            p.push(q);
        }
        p
    });
    // Ears, jaws and the like branch from the head's path close to the head.
    let near_head = |b: usize| {
        head.is_some_and(|h| head_path.contains(&b) && (pos(b) - pos(h)).norm() < 0.15 * extent)
    };
    // Arms and wings come in mirrored pairs; a limb off the mid-plane on its own is no arm.
    let paired = |i: usize| {
        let t = pos(tip_of(&limbs[i]));
        !midline(&limbs[i])
            && limbs.iter().enumerate().any(|(k, o)| {
                let u = pos(tip_of(o));
                k != i
                    && !foot_limbs.contains(&k)
                    && (Vector3::new(u.x, 2.0 * mid_y - u.y, u.z) - t).norm() < 0.15 * extent
            })
    };
    let mut tails = Vec::new();
    let mut arms: Vec<(usize, usize)> = Vec::new();
    for (i, l) in limbs.iter().enumerate() {
        if foot_limbs.contains(&i) || Some(i) == head_limb || l.path.len() < 2 {
            continue;
        }
        if paired(i) && reach(&l.path) >= 0.1 * extent && !near_head(l.from) {
            arms.push((i, tip_of(l)));
        } else if !paired(i) && pos(tip_of(l)).x < root_x {
            tails.push(i);
        }
    }
    let mut manipulators: Vec<usize> = arms.iter().map(|a| a.1).collect();
    if let Some(names) = &ov.manipulators {
        manipulators = names.iter().map(|n| by_name("manipulators", n)).collect::<Result<_, _>>()?;
    }

    // Roles of moving bones.
    let mut role: BTreeMap<usize, Role> = BTreeMap::new();
    let mut above_feet = vec![false; nb];
    for &i in &foot_limbs {
        let mut b = Some(limbs[i].from);
        while let Some(x) = b {
            above_feet[x] = true;
            b = rig.bones[x].parent;
        }
    }
    for &i in &foot_limbs {
        let l = &limbs[i];
        for (k, &b) in l.path.iter().enumerate() {
            role.insert(b, Role::Leg { first: k == 0 });
        }
    }
    for &m in &manipulators {
        if let Some(l) = limbs.iter().find(|l| l.path.contains(&m)) {
            for (k, &b) in l.path.iter().enumerate() {
                role.entry(b).or_insert(Role::Arm { first: k == 0 });
            }
        }
    }
    for &b in &head_path {
        if b != root && !above_feet[b] {
            role.entry(b).or_insert(if Some(b) == head {
                Role::Head
            } else {
                Role::Spine
            });
        }
    }
    for &i in &tails {
        for &b in &limbs[i].path {
            role.entry(b).or_insert(Role::Tail);
        }
        plan.tails.push(rig.bones[tip_of(&limbs[i])].name.clone());
    }
    for &b in &spine {
        if b != root {
            role.entry(b).or_insert(Role::Spine);
        }
    }
    // The bones above the feet (between the body root and the bones the legs hang from) are spine: the
    // controllers bend them as a body, and hold them in leg IK.
    for &b in &body {
        if above_feet[b] && b != root {
            role.insert(b, Role::Spine);
        }
    }
    role.remove(&root);
    if let Some(names) = &ov.animated {
        let keep: Vec<usize> = names.iter().map(|n| by_name("animated", n)).collect::<Result<_, _>>()?;
        role.retain(|b, _| keep.contains(b));
        for b in keep {
            role.entry(b).or_insert(Role::Spine);
        }
    }
    for n in &ov.at_rest {
        role.remove(&by_name("at_rest", n)?);
    }

    // Axes per moving bone: leg axes for legs, the character frame's elsewhere.
    let mut basis: BTreeMap<usize, Matrix3<f32>> = BTreeMap::new();
    for &i in &foot_limbs {
        let l = &limbs[i];
        let hip = pos(l.path[0]);
        let Some(&(_, foot)) = feet.iter().find(|(f, _)| l.path.contains(f)) else {
            continue;
        };
        let d = foot.coords - hip;
        let dh = Vector3::new(d.x, d.y, 0.0);
        let hinge = if dh.norm() > 0.5 * d.norm() {
            Vector3::z().cross(&dh).normalize()
        } else {
            Vector3::y()
        };
        let out = hinge.cross(&Vector3::z());
        for &b in &l.path {
            // Columns: roll (x), pitch (y), yaw (z) axes in the character frame.
            basis.insert(b, Matrix3::from_columns(&[out, hinge, Vector3::z()]));
        }
    }

    // Joints and links.
    let mut links: Vec<Link> = Vec::new();
    let mut link_of = vec![usize::MAX; nb];
    let mut dof = 0usize;
    let mut warnings = rig.warnings.clone();
    warnings.extend(plan.warnings.iter().cloned());
    for &b in &body {
        let bone = &rig.bones[b];
        // A proxy reaching below the creature at rest would be in the ground where the mesh is not (a
        // foot's becomes its contact sphere).
        let geometry: Vec<Geometry> = capsules[b]
            .iter()
            .map(|g| if feet.iter().any(|&(f, _)| f == b) { g.clone() } else { proxy::above_floor(g, &bone.rest, ground) })
            .collect();
        let mass = geometry.iter().map(|g| capsule_mass(&g.shape)).sum();
        if b == root {
            // The root link is upright at rest (the character frame at the body root); the root bone
            // hangs off it, fixed, so that every bone-named link has its bone's frame.
            let frame = Isometry3::from_parts(bone.rest.translation, UnitQuaternion::identity());
            links.push(Link {
                name: format!("{}:frame", bone.name),
                parent: None,
                joint: None,
                visuals: Vec::new(),
                collisions: Vec::new(),
                mass: 0.0,
            });
            link_of[b] = links.len();
            links.push(Link {
                name: bone.name.clone(),
                parent: Some(0),
                joint: Some(fixed(
                    format!("{}:fixed", bone.name),
                    frame.inverse() * bone.rest,
                )),
                visuals: Vec::new(),
                collisions: geometry,
                mass,
            });
            continue;
        }
        let p = bone
            .parent
            .expect("body bones below the root have a parent");
        let parent_link = link_of[p];
        let origin = rig.bones[p].rest.inverse() * bone.rest;
        let limits = match role.get(&b) {
            None => [None; 3],
            Some(&r) => axis_limits(rig, b, p, basis.get(&b), r),
        };
        let mut limits = limits;
        if let Some(axes) = ov.dofs.get(&bone.name) {
            for (k, a) in AXES.iter().enumerate() {
                if !axes.iter().any(|x| x == a) {
                    limits[k] = None;
                } else if limits[k].is_none() {
                    limits[k] = default_limits(role.get(&b).copied().unwrap_or(Role::Spine))[k]
                        .or(Some((-0.5, 0.5)));
                }
            }
        }
        for (k, a) in AXES.iter().enumerate() {
            if let Some(&[lo, hi]) = ov.limits.get(&format!("{}:{a}", bone.name)) {
                limits[k] = Some((lo, hi));
            }
        }
        let axes: Vec<usize> = (0..3).filter(|&k| limits[k].is_some()).collect();
        let slides = ov.translate.contains(&bone.name);
        if axes.is_empty() && !slides {
            if b != root && in_body[b] {
                plan.at_rest.push(bone.name.clone());
            }
            link_of[b] = links.len();
            links.push(Link {
                name: bone.name.clone(),
                parent: Some(parent_link),
                joint: Some(fixed(format!("{}:fixed", bone.name), origin)),
                visuals: Vec::new(),
                collisions: geometry,
                mass,
            });
            continue;
        }
        // Axes in the bone's rest frame: B's columns (x = roll, y = pitch, z = yaw) rotated into it.
        let m = basis.get(&b).copied().unwrap_or_else(Matrix3::identity);
        let to_bone = bone.rest.rotation.inverse();
        let mut parent_link = parent_link;
        // Joints in order: the slides along the rest frame's x, y, z, then the turns; the first carries
        // the bone's offset and the last link is the bone's own.
        let mut joints: Vec<BoneAxis> = Vec::new();
        if slides {
            let reach = 10.0 * extent;
            for (k, name) in ["x", "y", "z"].into_iter().enumerate() {
                joints.push(BoneAxis { name, slide: true, index: k, axis: Vector3::ith(k, 1.0), range: (-reach, reach) });
            }
        }
        for &k in &axes {
            let world_axis: Vector3<f32> = m.column(2 - k).into_owned();
            joints.push(BoneAxis {
                name: AXES[k],
                slide: false,
                index: k,
                axis: to_bone * world_axis,
                range: limits[k].expect("kept axis"),
            });
        }
        let mut dofs = [None; 3];
        let mut slide_dofs = [None; 3];
        let count = joints.len();
        for (n, BoneAxis { name: axis_name, slide, index, axis, range: (lo, hi) }) in joints.into_iter().enumerate() {
            let kind = if slide {
                slide_dofs[index] = Some(dof);
                JointKind::Prismatic
            } else {
                dofs[index] = Some(dof);
                JointKind::Revolute
            };
            let last = n + 1 == count;
            let link_name = if last {
                bone.name.clone()
            } else {
                format!("{}:{axis_name}", bone.name)
            };
            links.push(Link {
                name: link_name,
                parent: Some(parent_link),
                joint: Some(JointSpec {
                    name: format!("{}:{axis_name}", bone.name),
                    kind,
                    origin: if n == 0 {
                        origin
                    } else {
                        Isometry3::identity()
                    },
                    axis: nalgebra::Unit::new_normalize(axis),
                    limits: Some(Limits {
                        lower: lo,
                        upper: hi,
                        velocity: f32::INFINITY,
                        effort: f32::INFINITY,
                    }),
                    dof: Some(dof),
                    mimic: None,
                }),
                visuals: Vec::new(),
                collisions: if last { geometry.clone() } else { Vec::new() },
                mass: if last { mass } else { 0.0 },
            });
            dof += 1;
            parent_link = links.len() - 1;
        }
        link_of[b] = links.len() - 1;
        plan.joints.push(BoneJoint { bone: b, link: link_of[b], dofs, slides: slide_dofs, basis: m });
        plan.roles.insert(bone.name.clone(), role.get(&b).map_or("slide", |r| r.label()));
    }
    // Deforming helpers follow the body bone their vertices went to, where the clips hold them.
    for (&h, &host) in &helper_host {
        let mut origin = rig.bones[host].rest.inverse() * rig.bones[h].rest;
        origin.translation.vector = held[&h];
        links.push(Link {
            name: rig.bones[h].name.clone(),
            parent: Some(link_of[host]),
            joint: Some(fixed(format!("{}:fixed", rig.bones[h].name), origin)),
            visuals: Vec::new(),
            collisions: Vec::new(),
            mass: 0.0,
        });
    }
    let mut tree = KinematicTree::from_parts(name.to_owned(), links, warnings);
    // Bones that deform the same vertices (each with at least 10 % of a vertex) share flesh that
    // stretches and creases between them: their proxies may meet without a collision.
    let mut shared = std::collections::BTreeSet::new();
    for (_, w) in &rig.vertices {
        for &(a, wa) in w {
            for &(b, wb) in w {
                if a < b && wa >= 0.1 && wb >= 0.1 && in_body[a] && in_body[b] {
                    shared.insert((link_of[a], link_of[b]));
                }
            }
        }
    }
    tree.allowed_contacts = shared.into_iter().collect();

    let mut morph = Morphology::default();
    for &(f, p) in &feet {
        let l = link_of[f];
        morph.feet.push(l);
        let off = rig.bones[f].rest.inverse_transform_point(&p).coords;
        morph.tip_offsets.insert(l, off);
        // A foot's collision shape is a small sphere resting on its contact, as a robot's foot is: leg IK
        // places the foot point but leaves the paw's orientation free, and a long paw capsule (or a
        // large sphere) tilting about its contact would dip into the ground.
        if let Some(Shape::Capsule { radius, .. }) = capsules[f].as_ref().map(|g| g.shape.clone()) {
            let radius = radius.min(0.5 * (pos(f).z - p.z).max(1e-3)).min(FOOT_RADIUS * height);
            let centre = off + rig.bones[f].rest.inverse_transform_vector(&Vector3::z()) * radius;
            tree.links[l].collisions = vec![Geometry {
                origin: Isometry3::translation(centre.x, centre.y, centre.z),
                shape: Shape::Sphere { radius },
            }];
        }
    }
    for &m in &manipulators {
        let l = link_of[m];
        morph.manipulators.push(l);
        if let Some((a, e, _)) = capsule_ends(m) {
            let o = Point3::from(pos(m));
            let far = if (a - o).norm() > (e - o).norm() {
                a
            } else {
                e
            };
            morph
                .tip_offsets
                .insert(l, rig.bones[m].rest.inverse_transform_point(&far).coords);
        }
    }
    if let Some(h) = head {
        let l = link_of[h];
        morph.head = Some(l);
        if let Some((a, e, _)) = capsule_ends(h) {
            morph.tip_offsets.insert(
                l,
                rig.bones[h]
                    .rest
                    .inverse_transform_point(&nalgebra::center(&a, &e))
                    .coords,
            );
        }
    }
    // The spine's DoFs, and the body's axis from the head through the body root to the longest tail.
    let dofs_of = |b: usize| -> Vec<usize> {
        plan.joints
            .iter()
            .find(|j| j.bone == b)
            .map(|j| j.dofs.iter().flatten().copied().collect())
            .unwrap_or_default()
    };
    morph.spine = role
        .iter()
        .filter(|&(_, &r)| r == Role::Spine)
        .flat_map(|(&b, _)| dofs_of(b))
        .collect();
    morph.spine.sort_unstable();
    let tail = tails
        .iter()
        .filter(|&&i| limbs[i].from == root)
        .max_by(|&&a, &&b| reach(&limbs[a].path).total_cmp(&reach(&limbs[b].path)));
    // Without a head, the axis starts at the body root.
    let front = if head_path.is_empty() { vec![root] } else { head_path.clone() };
    morph.body_axis = front
        .iter()
        .chain(tail.map_or(&[][..], |&i| &limbs[i].path[..]))
        .map(|&b| dofs_of(b))
        .collect();
    morph.feet.sort_unstable();
    morph.manipulators.sort_unstable();
    tree.warnings.dedup();
    Ok((tree, morph, plan))
}

/// One joint of a moving bone: a slide along or a turn about an axis of its rest frame.
struct BoneAxis {
    /// Its name after the bone's (`x`, `y`, `z`, or one of [`AXES`]).
    name: &'static str,
    slide: bool,
    /// The axis' index among the slides (x, y, z) or the turns ([`AXES`]).
    index: usize,
    /// The axis in the bone's rest frame.
    axis: Vector3<f32>,
    /// Limits (m or rad).
    range: (f32, f32),
}

fn fixed(name: String, origin: Isometry3<f32>) -> JointSpec {
    JointSpec {
        name,
        kind: JointKind::Fixed,
        origin,
        axis: Vector3::z_axis(),
        limits: None,
        dof: None,
        mimic: None,
    }
}

/// Mass of a capsule of water density (kg): links need a mass for the controllers' balance.
fn capsule_mass(s: &Shape) -> f32 {
    match *s {
        Shape::Capsule { radius, length } => {
            1000.0 * std::f32::consts::PI * radius * radius * (length + 4.0 / 3.0 * radius)
        }
        _ => 0.0,
    }
}

/// Limits per axis of bone `b` (parent `p`): from its keyframes when it has any, else the role's defaults.
fn axis_limits(
    rig: &Rig,
    b: usize,
    p: usize,
    basis: Option<&Matrix3<f32>>,
    role: Role,
) -> [Option<(f32, f32)>; 3] {
    let keys = &rig.clip_rotations[b];
    let defaults = default_limits(role);
    if keys.is_empty() {
        return defaults;
    }
    // D = R_P · (L(t) · L_rest⁻¹) · R_P⁻¹ in the character frame (R_P maps the parent's file axes to
    // the character frame), then in the bone's axes.
    let rp = rig.bones[p].rest.rotation;
    let rest_inv = rig.bones[b].rest_local.rotation.inverse();
    let m = basis.copied().unwrap_or_else(Matrix3::identity);
    let bq = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m));
    let angles: Vec<[f32; 3]> = keys
        .iter()
        .map(|l| {
            let d = rp * (l * rest_inv) * rp.inverse();
            let e = bq.inverse() * d * bq;
            let (roll, pitch, yaw) = e.euler_angles();
            [yaw, pitch, roll]
        })
        .collect();
    // The clips set the ranges of the axes the role turns about (a knee stays a hinge even where an
    // artist's clip twists it a little).
    // Each of those axes gets at least the role's default range, so that the controllers can step and
    // turn even where the clips only walk straight ahead.
    let mut limits = clip_limits(&angles);
    for (l, d) in limits.iter_mut().zip(defaults) {
        *l = match (*l, d) {
            (_, None) => None,
            (None, d) => d,
            (Some((a, b)), Some((c, e))) => Some((a.min(c), b.max(e))),
        };
    }
    limits
}
