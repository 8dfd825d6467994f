//! A tree pose as the local transforms of a rigged creature's own bone nodes, in the file's frame and
//! units: the one conversion both the rig clip export ([`crate::export::rig`]) and the Bevy plugin
//! (which drives a glTF scene's joints every frame) use.
//!
//! Decisions, documented once:
//! - **Inverse of the import.** The import ([`super::gltf`]) folds the armature's transforms, the file's
//!   units (×100, ×300 armatures) and its axes into the z-up, metres character frame: a file point `p`
//!   is `C·p` there, with `C` the file → character rotation scaled by the creature's metres per unit. A
//!   bone's link in the tree has the bone's frame, so the tree's pose of bone `b` moves it by
//!   `Δ = W_b · R_b⁻¹` (its link's world pose times the inverse of its rest pose), and the bone's world
//!   matrix in the file becomes `C⁻¹ · Δ · C · F_b` (`F_b` its world matrix at rest). Its new local
//!   transform is its parent's world matrix (composed node by node, as a player or a scene does) inverted
//!   times that. Every scale (node scales, the armature's units) stays where it was.
//! - **Driven nodes.** Every bone that carries DoFs gets a rotation; bones held at rest keep their rest
//!   transform (the import's: the skin's bind pose, see [`super::gltf`]). The **body root's node** also gets a translation (root motion goes there, not on the
//!   armature root: the armature also holds the IK and pole helpers hanging off it, and its ×100 scale
//!   and axis change would have to be folded out of the motion). Deforming helpers (an IK-driven foot
//!   hanging off the armature root) follow their host bone in the tree, so they get a translation and a
//!   rotation that put them where the tree does.
//! - **Root motion elsewhere.** [`RigPose::root_motion`] splits a pose's ground travel (horizontal
//!   translation and heading) off, so that a caller can move the model's own placement with it (the
//!   plugin moves the entity carrying the scene); [`RigPose::in_file_frame`] gives that travel in the
//!   file's frame and units. The split is exact: the placement times the locals of the rest of the pose
//!   is the whole pose.
//!
//! Precompute a [`RigPose`] once per creature and file ([`RigPose::new`]), then write poses with
//! [`RigPose::write`].

use nalgebra::{Isometry3, Matrix3, Matrix4, Rotation3, UnitQuaternion, Vector3};

use super::Creature;
pub use super::gltf::NodeTransform;
use super::gltf::polar_rotation;
use crate::kinematics::{CharacterPose, KinematicTree};

/// Why a glTF document is not the creature's, or why a pose cannot be written onto it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct RigMismatch(pub String);

/// A node the pose moves.
#[derive(Clone, Debug, PartialEq)]
pub struct DrivenBone {
    /// Its index in the file's nodes.
    pub node: usize,
    /// Its name in the file (`node{index}` when it has none), which the rig bone has too.
    pub name: String,
    /// Its rig bone ([`super::gltf::Rig::bones`]) and tree link.
    pub bone: usize,
    pub link: usize,
    /// Whether its translation moves too (the body root, deforming helpers); otherwise only its rotation.
    pub translates: bool,
}

/// Working buffers of [`RigPose::write`], reused from pose to pose.
#[derive(Clone, Debug, Default)]
pub struct RigScratch {
    fk: Vec<Isometry3<f32>>,
    world: Vec<Matrix4<f32>>,
}

/// The precomputed conversion of a creature's tree poses into its file's bone node transforms (see
/// the module docs).
#[derive(Clone, Debug)]
pub struct RigPose {
    /// The file's node hierarchy at rest: parents, parents-first order, local transforms.
    parent: Vec<Option<usize>>,
    order: Vec<usize>,
    rest: Vec<NodeTransform>,
    driven: Vec<DrivenBone>,
    /// The skeleton's other nodes: index and name.
    held: Vec<(usize, String)>,
    /// Index into `driven` of each node.
    driven_of: Vec<Option<usize>>,
    /// `R_b⁻¹ · C · F_b` per driven bone: its rest taken out in the character frame.
    unrest: Vec<Matrix4<f32>>,
    /// `C⁻¹`.
    from_char: Matrix4<f32>,
    /// File → character rotation and metres per file unit (`C` = `to_character · scale`).
    to_character: Rotation3<f32>,
    scale: f32,
    /// Rest rotation of the body root's link (character frame): the heading's zero.
    root_rest: UnitQuaternion<f32>,
}

impl RigPose {
    /// The conversion for creature `c` and the glTF document it was read from, checked: one parent per
    /// node, no cycle, finite transforms, every rig bone at its node with its name, a tree link for
    /// every driven bone.
    pub fn new(c: &Creature, doc: &::gltf::Document) -> Result<RigPose, RigMismatch> {
        let not_it = |why: String| RigMismatch(why);
        let nodes: Vec<::gltf::Node> = doc.nodes().collect();
        let n = nodes.len();
        let mut parent = vec![None; n];
        for nd in &nodes {
            for ch in nd.children() {
                if parent[ch.index()].replace(nd.index()).is_some() || ch.index() == nd.index() {
                    return Err(not_it(format!("node {} has several parents", ch.index())));
                }
            }
        }
        let mut order = Vec::with_capacity(n);
        let mut stack: Vec<usize> = (0..n).filter(|&i| parent[i].is_none()).collect();
        while let Some(i) = stack.pop() {
            order.push(i);
            stack.extend(nodes[i].children().map(|c| c.index()));
        }
        if order.len() < n {
            return Err(not_it("its node hierarchy has a cycle".into()));
        }
        // At rest: the bones' rest (bind) transforms as the import found them, the other nodes' own.
        let mut rest: Vec<NodeTransform> = nodes.iter().map(NodeTransform::of).collect();
        for b in &c.rig.bones {
            if let Some(r) = rest.get_mut(b.node) {
                *r = b.rest_local;
            }
        }
        let mut world = vec![Matrix4::identity(); n];
        for &i in &order {
            let local = rest[i].matrix();
            world[i] = parent[i].map_or(local, |p| world[p] * local);
            if !world[i].iter().all(|v| v.is_finite()) {
                return Err(not_it(format!("node {i} has a non-finite transform")));
            }
        }

        let rig = &c.rig;
        for b in &rig.bones {
            let name = nodes.get(b.node).map(|nd| nd.name().map_or_else(|| format!("node{}", nd.index()), str::to_owned));
            if name.as_deref() != Some(b.name.as_str()) {
                return Err(not_it(format!("node {} is not the bone `{}`", b.node, b.name)));
            }
        }
        let link = |b: usize| {
            c.tree
                .link_index(&rig.bones[b].name)
                .ok_or_else(|| not_it(format!("the creature's tree has no link for bone `{}`", rig.bones[b].name)))
        };
        let bone = |b: usize, link: usize, translates: bool| DrivenBone {
            node: rig.bones[b].node,
            name: rig.bones[b].name.clone(),
            bone: b,
            link,
            translates,
        };
        let root = c.plan.root_bone;
        let mut driven = vec![bone(root, link(root)?, true)];
        for j in &c.plan.joints {
            if j.dofs.iter().any(Option::is_some) {
                driven.push(bone(j.bone, j.link, false));
            }
        }
        // Deforming helpers are the helpers that have a link (the others are dropped from the tree).
        for (b, rb) in rig.bones.iter().enumerate() {
            if c.plan.helpers.contains(&rb.name) && c.tree.link_index(&rb.name).is_some() {
                driven.push(bone(b, link(b)?, true));
            }
        }
        let mut driven_of = vec![None; n];
        for (k, d) in driven.iter().enumerate() {
            driven_of[d.node] = Some(k);
        }
        let mut skeleton = vec![false; n];
        for b in &rig.bones {
            let mut i = Some(b.node);
            while let Some(k) = i.filter(|&k| !skeleton[k]) {
                skeleton[k] = true;
                i = parent[k];
            }
        }
        let held = (0..n)
            .filter(|&i| skeleton[i] && driven_of[i].is_none())
            .map(|i| (i, nodes[i].name().map_or_else(|| format!("node{i}"), str::to_owned)))
            .collect();

        let s = rig.scale;
        let mut to_char = Matrix4::identity();
        to_char.fixed_view_mut::<3, 3>(0, 0).copy_from(&(rig.to_character.matrix() * s));
        let mut from_char = Matrix4::identity();
        from_char.fixed_view_mut::<3, 3>(0, 0).copy_from(&(rig.to_character.matrix().transpose() / s));
        let unrest = driven
            .iter()
            .map(|d| rig.bones[d.bone].rest.inverse().to_homogeneous() * to_char * world[d.node])
            .collect();
        Ok(RigPose {
            parent,
            order,
            rest,
            driven,
            held,
            driven_of,
            unrest,
            from_char,
            to_character: rig.to_character,
            scale: s,
            root_rest: rig.bones[root].rest.rotation,
        })
    }

    /// The nodes a pose moves; [`RigPose::write`]'s output follows this order. The first is the body
    /// root.
    pub fn driven(&self) -> &[DrivenBone] {
        &self.driven
    }

    /// The skeleton's nodes that poses do not move (the skin's other joints and every ancestor of a
    /// joint), as index and name (`node{index}` when unnamed): [`RigPose::write`] keeps them at rest.
    /// A player that owns the skeleton holds them at [`RigPose::rest`].
    pub fn held(&self) -> &[(usize, String)] {
        &self.held
    }

    /// The rest (file) transform of node `node`.
    pub fn rest(&self, node: usize) -> &NodeTransform {
        &self.rest[node]
    }

    /// Writes into `out` the local transform of each [`RigPose::driven`] node for `pose` of `tree` (the
    /// creature's tree, or one with the same links), every other node at rest. Fails only on a node
    /// whose transform degenerates (a zero scale above a driven bone).
    pub fn write(
        &self,
        tree: &KinematicTree,
        pose: &CharacterPose,
        scratch: &mut RigScratch,
        out: &mut Vec<NodeTransform>,
    ) -> Result<(), RigMismatch> {
        let degenerate =
            |node: usize| RigMismatch(format!("node {node} has a degenerate transform: its pose cannot be written"));
        out.clear();
        out.resize(self.driven.len(), self.rest[self.driven[0].node]);
        tree.forward_kinematics_into(pose, &mut scratch.fk);
        let world = &mut scratch.world;
        world.resize(self.parent.len(), Matrix4::identity());
        for &i in &self.order {
            let parent = self.parent[i].map_or_else(Matrix4::identity, |p| world[p]);
            let rest = &self.rest[i];
            let Some(k) = self.driven_of[i] else {
                world[i] = parent * rest.matrix();
                continue;
            };
            let d = &self.driven[k];
            let want = self.from_char * scratch.fk[d.link].to_homogeneous() * self.unrest[k];
            let local = parent.try_inverse().ok_or_else(|| degenerate(i))? * want;
            let translation = if d.translates { local.fixed_view::<3, 1>(0, 3).into_owned() } else { rest.translation };
            let unscale = Matrix3::from_diagonal(&rest.scale.map(|v| 1.0 / v));
            let rotation = polar_rotation(&(local.fixed_view::<3, 3>(0, 0) * unscale)).ok_or_else(|| degenerate(i))?;
            out[k] = NodeTransform { translation, rotation, scale: rest.scale };
            world[i] = parent * out[k].matrix();
        }
        Ok(())
    }

    /// The ground travel of `pose` (character frame; [`CharacterPose::ground_travel`] from the
    /// creature's rest root rotation). The pose `M⁻¹ · pose` ([`CharacterPose`]'s root premultiplied)
    /// stays over the origin, facing +x as at rest.
    pub fn root_motion(&self, pose: &CharacterPose) -> Isometry3<f32> {
        pose.ground_travel(&self.root_rest)
    }

    /// A rigid motion of the character frame as the same motion of the file's frame and units
    /// (`C⁻¹ · M · C`): translation divided by the metres per file unit, unit scale.
    pub fn in_file_frame(&self, m: &Isometry3<f32>) -> NodeTransform {
        let c = UnitQuaternion::from_rotation_matrix(&self.to_character);
        NodeTransform {
            translation: self.to_character.inverse() * m.translation.vector / self.scale,
            rotation: c.inverse() * m.rotation * c,
            scale: Vector3::repeat(1.0),
        }
    }
}
