//! Kinematic chains from the root link to one end effector, their forward kinematics relative to the
//! root, and damped-least-squares position IK that works for any chain (revolute and prismatic joints).
//!
//! Everything here is expressed in the **root frame** (the root link at the identity): targets far from
//! the world origin would otherwise lose precision in `f32`.

use nalgebra::{Isometry3, Matrix3, Point3, Vector3};

use crate::kinematics::{JointKind, KinematicTree};
use crate::morphology::Morphology;

/// The links from the root (exclusive) down to a tip link (inclusive), with the DoF each one owns.
#[derive(Clone, Debug)]
pub struct Chain {
    /// Path links, root side first.
    pub links: Vec<usize>,
    /// DoF of each path link (`None` for fixed and mimic joints, which IK leaves alone).
    pub dofs: Vec<Option<usize>>,
    /// The tip link.
    pub tip: usize,
    /// End-effector point in the tip's frame ([`Morphology::tip_offset`]).
    pub tip_offset: Vector3<f32>,
    /// Damping of the least-squares step (m); scaled to the chain's size.
    pub damping: f32,
}

/// Result of an IK solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IkResult {
    /// Remaining distance from the end effector to the target (m).
    pub error: f32,
    /// Iterations used.
    pub iterations: usize,
}

/// Reusable buffers for chain FK and IK (no allocation per call once sized).
#[derive(Clone, Debug, Default)]
pub struct ChainScratch {
    poses: Vec<Isometry3<f32>>,
    jac: Vec<Vector3<f32>>,
    pinned: Vec<bool>,
}

impl Chain {
    /// The chain from the root to `tip`, with the end-effector point of `tip` from `morph`.
    pub fn new(tree: &KinematicTree, morph: &Morphology, tip: usize) -> Chain {
        let mut links = Vec::new();
        let mut l = tip;
        while let Some(p) = tree.links[l].parent {
            links.push(l);
            l = p;
        }
        links.reverse();
        let dofs = links
            .iter()
            .map(|&l| tree.links[l].joint.as_ref().and_then(|j| j.dof))
            .collect();
        let mut c = Chain {
            links,
            dofs,
            tip,
            tip_offset: morph.tip_offset(tip),
            damping: 0.0,
        };
        let reach: f32 = c
            .links
            .iter()
            .filter_map(|&l| tree.links[l].joint.as_ref())
            .map(|j| j.origin.translation.vector.norm())
            .sum::<f32>()
            + c.tip_offset.norm();
        c.damping = 0.01 * reach.max(0.05);
        c
    }

    /// The chain from the root to a foot (or hand), `tip`, as a limb: the spine's DoFs on the path
    /// ([`Morphology::spine`]) are left out, so IK on the limb holds them. They bend with the body, and
    /// they carry the other limbs too: a solve that moved them to plant one foot would drag the others.
    /// Also says whether any were left out (the spine carries this limb's hip).
    pub fn limb(tree: &KinematicTree, morph: &Morphology, tip: usize) -> (Chain, bool) {
        let mut chain = Chain::new(tree, morph, tip);
        let mut on_spine = false;
        for d in chain.dofs.iter_mut() {
            if d.is_some_and(|d| morph.spine.contains(&d)) {
                *d = None;
                on_spine = true;
            }
        }
        (chain, on_spine)
    }

    /// The DoFs IK moves, root side first.
    pub fn active_dofs(&self) -> impl Iterator<Item = usize> + '_ {
        self.dofs.iter().flatten().copied()
    }

    /// Index in `links` of the first link that owns a DoF (the chain's first moving joint).
    pub fn first_moving(&self) -> Option<usize> {
        self.dofs.iter().position(Option::is_some)
    }

    /// Poses of the path links in the root frame, into `out` (same order as `links`).
    pub fn poses_into(&self, tree: &KinematicTree, q: &[f32], out: &mut Vec<Isometry3<f32>>) {
        out.clear();
        let mut prev = Isometry3::identity();
        for &l in &self.links {
            let j = tree.links[l].joint.as_ref().expect("non-root links have joints");
            prev *= j.transform(j.position(q));
            out.push(prev);
        }
    }

    /// End-effector point in the root frame for joint vector `q`.
    pub fn tip_point(&self, tree: &KinematicTree, q: &[f32], scratch: &mut ChainScratch) -> Point3<f32> {
        self.poses_into(tree, q, &mut scratch.poses);
        self.tip_from(&scratch.poses)
    }

    fn tip_from(&self, poses: &[Isometry3<f32>]) -> Point3<f32> {
        poses.last().map_or(Point3::from(self.tip_offset), |p| {
            p.transform_point(&Point3::from(self.tip_offset))
        })
    }

    /// Moves the chain's DoFs in `q` so that the end effector reaches `target` (root frame), by damped
    /// least squares with the analytic position Jacobian (`Δq = Jᵀ(JJᵀ + λ²I)⁻¹e`), clamping into the
    /// joint limits after every step; joints held at a limit the step pushes against drop out of that
    /// step. Stops when the error is below `tol` or after `max_iter` iterations; starts from `q` (a warm
    /// start keeps the branch, e.g. the knee direction).
    pub fn solve(
        &self,
        tree: &KinematicTree,
        q: &mut [f32],
        target: &Point3<f32>,
        tol: f32,
        max_iter: usize,
        scratch: &mut ChainScratch,
    ) -> IkResult {
        let mut it = 0;
        loop {
            self.poses_into(tree, q, &mut scratch.poses);
            let tip = self.tip_from(&scratch.poses);
            let e = target - tip;
            let err = e.norm();
            if err <= tol || it >= max_iter {
                return IkResult {
                    error: err,
                    iterations: it,
                };
            }
            it += 1;
            // Jacobian columns, one per active DoF.
            scratch.jac.clear();
            for (k, &l) in self.links.iter().enumerate() {
                if self.dofs[k].is_none() {
                    continue;
                }
                let j = tree.links[l].joint.as_ref().expect("joint");
                let pose = &scratch.poses[k];
                let axis = pose.rotation * j.axis.into_inner();
                scratch.jac.push(match j.kind {
                    JointKind::Prismatic => axis,
                    _ => axis.cross(&(tip.coords - pose.translation.vector)),
                });
            }
            // Damping grows with the error so that far (unreachable) targets do not make it jump.
            let lambda = self.damping * (1.0 + 4.0 * (err / (50.0 * self.damping)).min(1.0));
            // Joints pinned at a limit that the step would push further are taken out of the Jacobian
            // and the step solved again, so that the others do the work instead of stalling.
            scratch.pinned.clear();
            scratch.pinned.resize(scratch.jac.len(), false);
            let mut step = None;
            for _ in 0..3 {
                let mut jjt = Matrix3::<f32>::identity() * (lambda * lambda);
                for (col, &p) in scratch.jac.iter().zip(&scratch.pinned) {
                    if !p {
                        jjt += col * col.transpose();
                    }
                }
                let Some(y) = jjt.cholesky().map(|c| c.solve(&e)) else {
                    break;
                };
                let mut again = false;
                for ((d, col), p) in self.active_dofs().zip(&scratch.jac).zip(scratch.pinned.iter_mut()) {
                    if *p {
                        continue;
                    }
                    let x = q[d] + col.dot(&y);
                    if let Some(l) = tree.dof_joint(d).limits
                        && ((x < l.lower && q[d] <= l.lower + 1e-6) || (x > l.upper && q[d] >= l.upper - 1e-6))
                    {
                        *p = true;
                        again = true;
                    }
                }
                step = Some(y);
                if !again {
                    break;
                }
            }
            let Some(y) = step else {
                return IkResult {
                    error: err,
                    iterations: it,
                };
            };
            for ((d, col), &p) in self.active_dofs().zip(&scratch.jac).zip(&scratch.pinned) {
                if p {
                    continue;
                }
                let mut x = q[d] + col.dot(&y);
                if let Some(l) = tree.dof_joint(d).limits {
                    x = x.clamp(l.lower, l.upper);
                }
                q[d] = x;
            }
        }
    }

    /// [`Chain::solve`], and when it stalls with joints at their limits (a straight elbow at its stop
    /// cannot start bending), moves those joints 15 % into their range and tries again, up to
    /// `retries` times. This may change the branch (e.g. the elbow direction), so it is for targets
    /// without a good warm start — not for tracking a foot, where the branch must be kept.
    #[allow(clippy::too_many_arguments)]
    pub fn solve_unstuck(
        &self,
        tree: &KinematicTree,
        q: &mut [f32],
        target: &Point3<f32>,
        tol: f32,
        max_iter: usize,
        retries: usize,
        scratch: &mut ChainScratch,
    ) -> IkResult {
        let mut r = self.solve(tree, q, target, tol, max_iter, scratch);
        for _ in 0..retries {
            if r.error <= tol {
                break;
            }
            let mut moved = false;
            for d in self.active_dofs() {
                let Some(l) = tree
                    .dof_joint(d)
                    .limits
                    .filter(|l| l.lower.is_finite() && l.upper.is_finite())
                else {
                    continue;
                };
                let inset = 0.15 * (l.upper - l.lower);
                if q[d] <= l.lower + 1e-4 {
                    q[d] = l.lower + inset;
                    moved = true;
                } else if q[d] >= l.upper - 1e-4 {
                    q[d] = l.upper - inset;
                    moved = true;
                }
            }
            if !moved {
                break;
            }
            r = self.solve(tree, q, target, tol, max_iter, scratch);
        }
        r
    }
}
