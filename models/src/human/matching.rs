//! Which BVH joint each canonical joint comes from. User [`JointMapping`] entries come first; rules
//! fill in the rest, using names for the limb ends and the head and the hierarchy for everything else:
//! - hand / foot / head: the shallowest joint whose name says so (`LeftWrist`, `lhand`, `Foot_L`, …);
//! - forearm, upper arm (shin, thigh): walking up from the hand (foot), the nearest non-helper ancestor
//!   at a non-zero distance, preferring one whose name matches among the first three;
//! - pelvis: the joint where both legs and the spine meet; chest: where both arms and the neck meet;
//! - spine: the joint between pelvis and chest nearest half-way along the chain; neck: the first joint
//!   above the chest; either falls back to the midpoint of its neighbours when the chain has none.

use nalgebra::Vector3;

use super::bvh::Bvh;
use super::error::HumanImportError;
use super::fk::Pose;
use super::mapping::JointMapping;
use super::names::{NameInfo, Part, Side, classify_all};
use super::skeleton::{JOINT_COUNT, Joint};

/// Where a canonical joint's position comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// A BVH joint (index into [`Bvh::joints`]).
    Joint(usize),
    /// The midpoint of two BVH joints (used when a spine has no joint where one is needed).
    Midpoint(usize, usize),
}

/// The canonical skeleton's sources in one BVH file.
#[derive(Clone, Debug)]
pub struct SkeletonMap {
    pub sources: [Source; JOINT_COUNT],
}

impl SkeletonMap {
    /// Position of canonical joint `j` in `pose` (file axes and units).
    pub fn position(&self, pose: &Pose, j: Joint) -> Vector3<f32> {
        match self.sources[j.index()] {
            Source::Joint(i) => pose.pos[i],
            Source::Midpoint(a, b) => (pose.pos[a] + pose.pos[b]) * 0.5,
        }
    }

    /// BVH joint indices canonical joint `j` is computed from.
    pub fn indices(&self, j: Joint) -> Vec<usize> {
        match self.sources[j.index()] {
            Source::Joint(i) => vec![i],
            Source::Midpoint(a, b) => vec![a, b],
        }
    }

    /// BVH joint index of canonical joint `j` (the lower one for a midpoint).
    pub fn index(&self, j: Joint) -> usize {
        match self.sources[j.index()] {
            Source::Joint(i) | Source::Midpoint(_, i) => i,
        }
    }

    /// Human-readable source per canonical joint (`LeftUpLeg`, `midpoint(Hips, Spine1)`).
    pub fn source_names(&self, bvh: &Bvh) -> [String; JOINT_COUNT] {
        std::array::from_fn(|k| match self.sources[k] {
            Source::Joint(i) => bvh.joints[i].name.clone(),
            Source::Midpoint(a, b) => {
                format!("midpoint({}, {})", bvh.joints[a].name, bvh.joints[b].name)
            }
        })
    }

    /// Match `bvh`'s joints to the canonical skeleton; `user` entries take precedence.
    pub fn build(
        bvh: &Bvh,
        user: Option<&JointMapping>,
        file: &str,
    ) -> Result<SkeletonMap, HumanImportError> {
        Matcher::new(bvh).build(user, file)
    }
}

struct Matcher<'a> {
    bvh: &'a Bvh,
    info: Vec<NameInfo>,
    depth: Vec<usize>,
    eps: f32,
}

impl<'a> Matcher<'a> {
    fn new(bvh: &'a Bvh) -> Self {
        let info: Vec<NameInfo> = classify_all(&bvh.joints.iter().map(|j| j.name.as_str()).collect::<Vec<_>>());
        let mut depth = vec![0; bvh.joints.len()];
        let mut reach = vec![0.0f32; bvh.joints.len()];
        for (i, j) in bvh.joints.iter().enumerate() {
            if let Some(p) = j.parent {
                depth[i] = depth[p] + 1;
                reach[i] = reach[p] + j.offset.norm();
            }
        }
        let longest = reach.iter().cloned().fold(0.0f32, f32::max);
        Matcher {
            bvh,
            info,
            depth,
            eps: 1e-3 * longest.max(1e-12),
        }
    }

    fn ancestors(&self, j: usize) -> impl Iterator<Item = usize> + '_ {
        std::iter::successors(self.bvh.joints[j].parent, move |&a| {
            self.bvh.joints[a].parent
        })
    }

    fn is_ancestor(&self, anc: usize, j: usize) -> bool {
        self.ancestors(j).any(|a| a == anc)
    }

    /// Length of the hierarchy path from ancestor `anc` down to `j`.
    fn path_length(&self, anc: usize, j: usize) -> f32 {
        let mut len = 0.0;
        let mut k = j;
        while k != anc {
            len += self.bvh.joints[k].offset.norm();
            match self.bvh.joints[k].parent {
                Some(p) => k = p,
                None => break,
            }
        }
        len
    }

    fn helper(&self, j: usize) -> bool {
        matches!(self.info[j].part(), Part::Helper | Part::Finger | Part::Toe)
    }

    /// The shallowest joint on `side` whose name says `part`.
    fn shallowest(&self, side: Side, part: Part) -> Option<usize> {
        (0..self.bvh.joints.len())
            .filter(|&j| self.info[j].side == side && self.info[j].part() == part)
            .min_by_key(|&j| self.depth[j])
    }

    /// The limb joint above `child` on the limb of `side`: among the first three non-helper ancestors at
    /// a non-zero distance (and not on the other side), the nearest whose name says `want`, else the
    /// nearest. The side is the limb's, not `child`'s: a forearm's name need not say it.
    fn limb_parent(&self, child: usize, want: Part, side: Side) -> Option<usize> {
        let candidates: Vec<usize> = self
            .ancestors(child)
            .filter(|&a| !self.helper(a) && self.path_length(a, child) > self.eps)
            .take(3)
            .filter(|&a| self.info[a].side == side || self.info[a].side == Side::Centre)
            .collect();
        candidates
            .iter()
            .copied()
            .find(|&a| self.info[a].part() == want)
            .or(candidates.first().copied())
    }

    /// Lowest common ancestor (or self) of all `joints`.
    fn common_ancestor(&self, joints: &[usize]) -> Option<usize> {
        let first = *joints.first()?;
        std::iter::once(first)
            .chain(self.ancestors(first))
            .find(|&a| joints.iter().all(|&j| j == a || self.is_ancestor(a, j)))
    }

    /// Joints strictly between ancestor `top` and `bottom`, from `top` down.
    fn between(&self, top: usize, bottom: usize) -> Vec<usize> {
        let mut chain: Vec<usize> = self.ancestors(bottom).take_while(|&a| a != top).collect();
        chain.reverse();
        chain
    }

    fn build(
        &self,
        user: Option<&JointMapping>,
        file: &str,
    ) -> Result<SkeletonMap, HumanImportError> {
        let mut src: [Option<Source>; JOINT_COUNT] = [None; JOINT_COUNT];
        if let Some(user) = user {
            for j in Joint::ALL {
                if let Some(name) = &user.joints[j.index()] {
                    let i = self
                        .find_by_name(name)
                        .ok_or_else(|| HumanImportError::Mapping {
                            file: file.to_string(),
                            message: format!(
                                "{} = \"{name}\": no such BVH joint; available: {}",
                                j.name(),
                                self.names().join(", ")
                            ),
                        })?;
                    src[j.index()] = Some(Source::Joint(i));
                }
            }
        }
        let joint_of = |s: &[Option<Source>; JOINT_COUNT], j: Joint| match s[j.index()] {
            Some(Source::Joint(i)) => Some(i),
            _ => None,
        };
        use Joint::*;
        // Limb ends and head by name.
        for (j, side, part) in [
            (LeftHand, Side::Left, Part::Hand),
            (RightHand, Side::Right, Part::Hand),
            (LeftFoot, Side::Left, Part::Foot),
            (RightFoot, Side::Right, Part::Foot),
            (Head, Side::Centre, Part::Head),
        ] {
            if src[j.index()].is_none() {
                src[j.index()] = self.shallowest(side, part).map(Source::Joint);
            }
        }
        // Limb chains by hierarchy.
        for (j, below, part, side) in [
            (LeftForearm, LeftHand, Part::Forearm, Side::Left),
            (LeftUpperArm, LeftForearm, Part::UpperArm, Side::Left),
            (RightForearm, RightHand, Part::Forearm, Side::Right),
            (RightUpperArm, RightForearm, Part::UpperArm, Side::Right),
            (LeftShin, LeftFoot, Part::Shin, Side::Left),
            (LeftThigh, LeftShin, Part::Thigh, Side::Left),
            (RightShin, RightFoot, Part::Shin, Side::Right),
            (RightThigh, RightShin, Part::Thigh, Side::Right),
        ] {
            if src[j.index()].is_none() {
                src[j.index()] = joint_of(&src, below)
                    .and_then(|c| self.limb_parent(c, part, side))
                    .map(Source::Joint);
            }
        }
        // Torso by hierarchy.
        if src[Pelvis.index()].is_none()
            && let (Some(l), Some(r), Some(h)) = (
                joint_of(&src, LeftThigh),
                joint_of(&src, RightThigh),
                joint_of(&src, Head),
            )
        {
            src[Pelvis.index()] = self.common_ancestor(&[l, r, h]).map(Source::Joint);
        }
        if src[Chest.index()].is_none()
            && let (Some(l), Some(r), Some(h), Some(p)) = (
                joint_of(&src, LeftUpperArm),
                joint_of(&src, RightUpperArm),
                joint_of(&src, Head),
                joint_of(&src, Pelvis),
            )
        {
            src[Chest.index()] = self
                .common_ancestor(&[l, r, h])
                .filter(|&c| self.is_ancestor(p, c))
                .map(Source::Joint);
        }
        if src[Spine.index()].is_none()
            && let (Some(p), Some(c)) = (joint_of(&src, Pelvis), joint_of(&src, Chest))
            && self.is_ancestor(p, c)
        {
            src[Spine.index()] = Some(self.spine(p, c));
        }
        if src[Neck.index()].is_none()
            && let (Some(c), Some(h)) = (joint_of(&src, Chest), joint_of(&src, Head))
            && self.is_ancestor(c, h)
        {
            // In-chain joints are real articulations even when named like helpers (iClone's NeckTwist01).
            let first = self
                .between(c, h)
                .into_iter()
                .find(|&a| self.path_length(c, a) > self.eps && self.path_length(a, h) > self.eps);
            src[Neck.index()] = Some(first.map_or(Source::Midpoint(c, h), Source::Joint));
        }

        let missing: Vec<String> = Joint::ALL
            .iter()
            .filter(|j| src[j.index()].is_none())
            .map(|j| j.name().to_string())
            .collect();
        if !missing.is_empty() {
            // A skeleton whose arms are named but one of whose legs is not is missing that leg, not
            // in an unknown naming convention: say so. (A rig of generic names gets `Unmapped`.)
            let arms_named = (0..self.bvh.joints.len()).any(|j| {
                matches!(self.info[j].side, Side::Left | Side::Right)
                    && matches!(
                        self.info[j].part(),
                        Part::Hand | Part::Forearm | Part::UpperArm
                    )
            });
            let sides = if arms_named {
                &[(Side::Left, "left"), (Side::Right, "right")][..]
            } else {
                &[]
            };
            for &(side, label) in sides {
                let leg = (0..self.bvh.joints.len()).any(|j| {
                    self.info[j].side == side
                        && matches!(
                            self.info[j].part(),
                            Part::Foot | Part::Shin | Part::Thigh | Part::Toe
                        )
                });
                let user_named = user.is_some_and(|u| {
                    Joint::ALL.iter().any(|j| {
                        u.joints[j.index()].is_some()
                            && j.name().starts_with(label)
                            && matches!(j.name().split('_').nth(1), Some("foot" | "shin" | "thigh"))
                    })
                });
                if !leg && !user_named {
                    return Err(HumanImportError::Skeleton {
                        file: file.to_string(),
                        message: format!(
                            "the skeleton has no {label} leg: no joint is named like a {label} thigh, shin, foot or toe \
                             (BVH joints: {}); ACE needs both legs. If the leg is there under other names, \
                             name them in a joint-mapping file (--mapping FILE or `<clip>.mapping.toml` beside the clip)",
                            super::error::short_list(&self.names())
                        ),
                    });
                }
            }
            return Err(HumanImportError::Unmapped {
                file: file.to_string(),
                missing,
                available: self.names(),
            });
        }
        let sources = src.map(|s| s.expect("checked above"));
        self.validate(&sources, file)?;
        Ok(SkeletonMap { sources })
    }

    /// The spine joint between pelvis `p` and chest `c`: nearest half-way along the chain.
    fn spine(&self, p: usize, c: usize) -> Source {
        let total = self.path_length(p, c);
        self.between(p, c)
            .into_iter()
            .filter(|&a| self.path_length(p, a) > self.eps && self.path_length(a, c) > self.eps)
            .map(|a| (a, (self.path_length(p, a) / total - 0.5).abs()))
            .fold(None::<(usize, f32)>, |best, (a, d)| match best {
                Some((_, bd)) if bd <= d + 0.05 => best,
                _ => Some((a, d)),
            })
            .map_or(Source::Midpoint(p, c), |(a, _)| Source::Joint(a))
    }

    /// Each canonical joint must lie below its canonical parent, and no BVH joint may serve twice.
    fn validate(
        &self,
        sources: &[Source; JOINT_COUNT],
        file: &str,
    ) -> Result<(), HumanImportError> {
        let err = |message: String| HumanImportError::Mapping {
            file: file.to_string(),
            message,
        };
        let name = |i: usize| self.bvh.joints[i].name.as_str();
        for j in Joint::ALL {
            let (Source::Joint(c), Some(parent)) = (sources[j.index()], j.parent()) else {
                continue;
            };
            if let Source::Joint(p) = sources[parent.index()]
                && !self.is_ancestor(p, c)
            {
                return Err(err(format!(
                    "{} (`{}`) is not below {} (`{}`) in the BVH hierarchy",
                    j.name(),
                    name(c),
                    parent.name(),
                    name(p)
                )));
            }
        }
        for j in Joint::ALL {
            let Source::Joint(c) = sources[j.index()] else {
                continue;
            };
            if let Some(k) = Joint::ALL[..j.index()]
                .iter()
                .find(|k| sources[k.index()] == Source::Joint(c))
            {
                return Err(err(format!(
                    "{} and {} both map to `{}`",
                    k.name(),
                    j.name(),
                    name(c)
                )));
            }
        }
        Ok(())
    }

    fn find_by_name(&self, name: &str) -> Option<usize> {
        let js = &self.bvh.joints;
        js.iter()
            .position(|j| j.name == name)
            .or_else(|| js.iter().position(|j| j.name.eq_ignore_ascii_case(name)))
            .or_else(|| {
                js.iter()
                    .position(|j| j.name.rsplit(':').next() == Some(name))
            })
    }

    fn names(&self) -> Vec<String> {
        self.bvh.joints.iter().map(|j| j.name.clone()).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::human::fk::Translation;
    use crate::human::test_rig::{Spec, arms, body, bvh, leg, neck_and_head, rig, spine_to_head, torso};

    fn source(bvh: &Bvh, map: &SkeletonMap, j: Joint) -> String {
        map.source_names(bvh)[j.index()].clone()
    }

    fn index_of(bvh: &Bvh, name: &str) -> usize {
        bvh.joints.iter().position(|j| j.name == name).unwrap()
    }

    #[test]
    fn a_spine_or_neck_without_a_joint_is_the_midpoint_of_its_neighbours() {
        // The chest hangs off the hips with only a joint at the hips' place between them, and the
        // head straight off the chest.
        let spine = [
            ("LowerBack", Some("Hips"), [0.0, 0.0, 0.0]),
            ("Chest", Some("LowerBack"), [0.0, 30.0, 0.0]),
            ("Head", Some("Chest"), [0.0, 20.0, 4.0]),
        ];
        let b = bvh(&body(&[spine.to_vec(), arms()].concat()));
        let map = SkeletonMap::build(&b, None, "t.bvh").unwrap();
        let (hips, chest, head) = (index_of(&b, "Hips"), index_of(&b, "Chest"), index_of(&b, "Head"));
        assert_eq!(map.sources[Joint::Spine.index()], Source::Midpoint(hips, chest));
        assert_eq!(map.sources[Joint::Neck.index()], Source::Midpoint(chest, head));
        assert_eq!(source(&b, &map, Joint::Neck), "midpoint(Chest, Head)");
        assert_eq!((map.indices(Joint::Spine), map.index(Joint::Spine)), (vec![hips, chest], chest));
        let hand = index_of(&b, "LeftHand");
        assert_eq!((map.indices(Joint::LeftHand), map.index(Joint::LeftHand)), (vec![hand], hand));
        assert_eq!(map.index(Joint::RightFoot), index_of(&b, "RightFoot"));

        let mut pose = Pose::new(&b);
        pose.compute(&b, 0, &vec![Translation::Replace; b.joints.len()]);
        // The root's position channels (all 0) take the place of its offset.
        assert_eq!(map.position(&pose, Joint::Spine), Vector3::new(0.0, 15.0, 0.0));
        assert_eq!(map.position(&pose, Joint::Neck), Vector3::new(0.0, 40.0, 2.0));
        assert_eq!(map.position(&pose, Joint::LeftHand), Vector3::new(65.0, 30.0, 0.0));
    }

    #[test]
    fn a_forearm_is_the_nearest_ancestor_at_a_distance_that_is_not_a_helper() {
        // Neither forearm's name says what it is, nor the right one's side; the left hand hangs below a
        // twist bone, the right one at the very place of a joint above it.
        let b = bvh(&body(&[spine_to_head("Head"), vec![
            ("LeftArm", Some("Chest"), [15.0, 0.0, 0.0]),
            ("l_lower", Some("LeftArm"), [25.0, 0.0, 0.0]),
            ("LeftWristTwist", Some("l_lower"), [12.0, 0.0, 0.0]),
            ("LeftHand", Some("LeftWristTwist"), [13.0, 0.0, 0.0]),
            ("RightArm", Some("Chest"), [-15.0, 0.0, 0.0]),
            ("seg7", Some("RightArm"), [-25.0, 0.0, 0.0]),
            ("r_pivot", Some("seg7"), [-25.0, 0.0, 0.0]),
            ("RightHand", Some("r_pivot"), [0.0, 0.0, 0.0]),
        ]].concat()));
        let map = SkeletonMap::build(&b, None, "t.bvh").unwrap();
        let got: Vec<String> = [Joint::LeftForearm, Joint::LeftUpperArm, Joint::RightForearm, Joint::RightUpperArm, Joint::Spine, Joint::Neck]
            .map(|j| source(&b, &map, j))
            .to_vec();
        assert_eq!(got, ["l_lower", "LeftArm", "seg7", "RightArm", "Spine", "Neck"]);
    }

    #[test]
    fn a_missing_leg_is_named_and_a_rig_of_other_names_is_unmapped() {
        let err = |joints: &[Spec], user: Option<&JointMapping>| SkeletonMap::build(&bvh(joints), user, "t.bvh").unwrap_err();
        let no_right_leg = "t.bvh: the skeleton has no right leg: no joint is named like a right thigh, shin, foot or toe";
        let one_leg = rig(&[torso("Head"), leg(["LeftUpLeg", "LeftLeg", "LeftFoot"], 8.0)]);
        let head_only = JointMapping::default().with(Joint::Head, "Head");
        for user in [None, Some(&head_only)] {
            let e = err(&one_leg, user).to_string();
            assert!(e.starts_with(no_right_leg), "{e}");
        }

        // A right leg and a head under names that say nothing: the leg is missing until the mapping
        // names one of its joints; then what is left unmapped is listed, and with the head the rest is found.
        let generic = rig(&[torso("seg30"), leg(["LeftUpLeg", "LeftLeg", "LeftFoot"], 8.0), leg(["seg18", "seg19", "seg20"], -8.0)]);
        assert!(err(&generic, None).to_string().starts_with(no_right_leg));
        let foot = JointMapping::default().with(Joint::RightFoot, "seg20");
        match err(&generic, Some(&foot)) {
            HumanImportError::Unmapped { missing, .. } => assert_eq!(missing, ["pelvis", "spine", "chest", "neck", "head"]),
            e => panic!("{e}"),
        }
        let b = bvh(&generic);
        let map = SkeletonMap::build(&b, Some(&foot.with(Joint::Head, "seg30")), "t.bvh").unwrap();
        let got = [Joint::RightThigh, Joint::RightShin, Joint::RightFoot, Joint::Pelvis, Joint::Head].map(|j| source(&b, &map, j));
        assert_eq!(got, ["seg18", "seg19", "seg20", "Hips", "seg30"]);

        // No arm is named with a side (only the eyes are): not a missing leg, an unknown rig.
        let mut unnamed = rig(&[
            vec![("seg1", Some("Hips"), [0.0, 30.0, 0.0]), ("seg2", Some("seg1"), [0.0, 20.0, 0.0])],
            vec![("LeftEye", Some("seg2"), [3.0, 5.0, 5.0]), ("RightEye", Some("seg2"), [-3.0, 5.0, 5.0])],
            leg(["seg3", "seg4", "seg5"], 8.0),
        ]);
        unnamed[0].0 = "seg0";
        for j in &mut unnamed {
            if j.1 == Some("Hips") {
                j.1 = Some("seg0");
            }
        }
        match err(&unnamed, None) {
            HumanImportError::Unmapped { missing, .. } => assert_eq!(missing.len(), JOINT_COUNT),
            e => panic!("{e}"),
        }
    }

    #[test]
    fn the_spine_is_the_joint_nearest_half_way_preferring_the_lower_within_five_percent() {
        // `spines`: the joints from the hips to the chest and their lengths along the chain.
        let spine = |spines: &[(&'static str, f32)]| {
            let mut joints: Vec<Spec> = Vec::new();
            let mut parent = "Hips";
            for &(name, length) in spines {
                joints.push((name, Some(parent), [0.0, length, 0.0]));
                parent = name;
            }
            let mut joints = [joints, neck_and_head("Head"), arms()].concat();
            joints.push(("Chest", Some(parent), [0.0, 100.0 - spines.iter().map(|s| s.1).sum::<f32>(), 0.0]));
            let b = bvh(&body(&joints));
            let map = SkeletonMap::build(&b, None, "t.bvh").unwrap();
            source(&b, &map, Joint::Spine)
        };
        // At 0.45, 0.52 and 0.8 of the way: the lower of the two within 0.05 of each other.
        assert_eq!(spine(&[("Spine", 45.0), ("Spine1", 7.0), ("Spine2", 28.0)]), "Spine");
        // At 0.2 and 0.5: the one half-way.
        assert_eq!(spine(&[("Spine", 20.0), ("Spine1", 30.0)]), "Spine1");
    }
}
