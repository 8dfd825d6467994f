//! Morphology: which links of a character are its feet, manipulators, wheels and head — found from
//! the kinematic tree and its geometry, never from link names — and the optional per-character
//! profile file that overrides the analysis.
//!
//! # Analysis ([`Morphology::analyze`])
//! The tree is posed at [`KinematicTree::neutral_q`] with the root at the origin. The *root body* is
//! the root link plus everything fixed to it; every movable joint hanging off the root body starts a
//! *limb*. Sizes below are relative to the character's neutral bounding box (height `H`, largest
//! extent `S`); "touching the ground" means within `max(1 cm, 3 % H)` of the lowest point.
//! - **Wheels**: limbs with a single joint that is continuous (or revolute with ≥ 2π range), whose axis
//!   is horizontal, whose geometry touches the ground and is centred on the axis.
//! - Every other limb is followed down its chain of movable joints to its **tips**. Where a chain
//!   branches after at least 3 joints into short branches (≤ 3 joints each) the branches are gripper
//!   fingers and the tip is the link before them; other branchings give one tip per branch (tips on
//!   branches under a quarter of the longest sibling's reach can only become the head).
//! - **Feet**: tips whose lowest geometry touches the ground, on chains with ≥ 2 rotational joints, on a
//!   character that rests neither on its root body (e.g. a caster) nor on two or more wheels. The foot
//!   point is the lowest point of the tip's geometry at the neutral pose (the bottom of a sphere, else
//!   the bottom centre of the lowest box), attached to the nearest link rigidly fixed to the tip.
//! - **Head**: the highest remaining tip in the top 30 % of the character whose chain after the limb's
//!   last branching (a neck) is short (reach < S/4) and has at most 3 joints, all rotational. The head
//!   end effector is the last moving link.
//! - **Manipulators**: remaining tips of chains with ≥ 2 joints and reach ≥ 0.15 S. The end effector is
//!   the link rigidly fixed to the tip that lies farthest from the tip's joint (a gripper's
//!   tool/grasp frame when the URDF has one).
//!
//! Feet, manipulators and wheels are listed in link order (the URDF's depth-first order).
//!
//! # Profile
//! A TOML file `<urdf stem>.profile.toml` beside the URDF ([`Profile::beside`]); every key optional:
//! ```toml
//! feet = ["fl_foot", "fr_foot"]      # replaces the analysed feet (link names)
//! manipulators = ["gripper_tip"]
//! wheels = []
//! head = ""                          # link name; "" = no head
//! [rest_pose]                        # joint name = position (rad or m); becomes neutral_q
//! fl_knee = -1.2
//! [tip_offsets]                      # end-effector point in the link frame (m)
//! fl_foot = [0.0, 0.0, -0.02]
//! ```
//! A rigged glTF creature's profile (`Fox.profile.toml` beside `Fox.glb`) takes the same keys, with
//! bone names for links, and these of its own (see [`crate::character`]):
//! ```toml
//! scale = 0.01                       # metres per file unit
//! forward = "+z"                     # the file axis the creature faces
//! up = "+y"                          # the file axis that points up ("+z": exported with z up)
//! animated = ["b_Neck_04", "b_Head_05"]   # the bones that move (replaces the analysis)
//! at_rest = ["b_Tail01_012"]         # bones held at rest
//! [dofs]                             # bone = the axes it turns about
//! b_Head_05 = ["yaw", "pitch"]
//! [limits]                           # joint = [lower, upper] (rad)
//! "b_Head_05:yaw" = [-0.5, 0.5]
//! ```
//! and `translate = ["Tail1"]`: bones that also slide along their rest axes (three prismatic DoFs
//! `bone:x`, `bone:y`, `bone:z`), for playing clips that move bones off their bind offsets.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Point3, Vector3};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::geometry::{Aabb, Shape};
use crate::kinematics::{JointKind, KinematicTree};
use crate::urdf::UrdfError;

/// End effectors and wheels of a character, as link indices.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Morphology {
    /// Feet (ground contacts of legs).
    pub feet: Vec<usize>,
    /// Manipulator end effectors (gripper or tool links).
    pub manipulators: Vec<usize>,
    /// Wheels (their links spin with the wheel).
    pub wheels: Vec<usize>,
    /// Head, if any.
    pub head: Option<usize>,
    /// Point that stands for an end effector, in its link's frame; links not listed use their origin.
    /// Use [`Morphology::ee_point`] rather than the link origin wherever end-effector positions matter
    /// (state vectors, IK targets, contact checks).
    pub tip_offsets: BTreeMap<usize, Vector3<f32>>,
    /// Rigged glTF creatures only (empty for a URDF): the DoFs of the spine bones
    /// ([`crate::character::body_plan`]'s spine role: the trunk from the body root to the head, the neck,
    /// and the bones above the feet), which the controllers bend as a body ([`crate::controller::spine`])
    /// rather than leave to leg IK or to reaching.
    pub spine: Vec<usize>,
    /// Rigged glTF creatures only (empty for a URDF): the bones along the body's axis, from the head
    /// (or the body root, without a head) through the body root to the tip of the longest tail, each as
    /// its DoFs (none for a bone at rest). A legless creature crawls by bending them
    /// ([`crate::controller::undulation`]), or is refused saying what it lacks.
    pub body_axis: Vec<Vec<usize>>,
}

/// [`Morphology`] with link names instead of indices.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct MorphologyNames {
    pub feet: Vec<String>,
    pub manipulators: Vec<String>,
    pub wheels: Vec<String>,
    pub head: Option<String>,
}

impl Morphology {
    /// Finds feet, manipulators, wheels and head from topology and geometry (see the module docs).
    pub fn analyze(tree: &KinematicTree) -> Morphology {
        Analysis::new(tree).run()
    }

    /// Analysis, then every field the profile sets replaces the analysed one. Also applies the
    /// profile's tip offsets (the rest pose is applied to the tree by [`Profile::apply_rest_pose`]).
    pub fn with_profile(tree: &KinematicTree, profile: &Profile) -> Result<Morphology, ProfileError> {
        let mut m = Morphology::analyze(tree);
        let err = |p: ProfileProblem| profile.error(p);
        let find = |n: &String| {
            tree.link_index(n)
                .ok_or_else(|| err(ProfileProblem::UnknownLink(n.clone())))
        };
        let list = |names: &Vec<String>| names.iter().map(find).collect::<Result<Vec<_>, _>>();
        if let Some(f) = &profile.feet {
            m.feet = list(f)?;
        }
        if let Some(f) = &profile.manipulators {
            m.manipulators = list(f)?;
        }
        if let Some(f) = &profile.wheels {
            m.wheels = list(f)?;
        }
        if let Some(h) = &profile.head {
            m.head = if h.is_empty() { None } else { Some(find(h)?) };
        }
        m.check_roles(tree).map_err(err)?;
        let ees = m.end_effectors();
        m.tip_offsets.retain(|l, _| ees.contains(l));
        profile.apply_tip_offsets(tree, &mut m)?;
        Ok(m)
    }

    /// Checks the roles a profile may have mixed up: an end effector has one role, once, and no foot
    /// hangs below another (a leg has one foot).
    fn check_roles(&self, tree: &KinematicTree) -> Result<(), ProfileProblem> {
        let bad = |key: &str, link: usize, valid: String| ProfileProblem::BadValue {
            key: key.into(),
            value: format!("\"{}\"", tree.links[link].name),
            valid,
        };
        let mut seen: Vec<(usize, &str)> = Vec::new();
        let roles = [("feet", &self.feet[..]), ("manipulators", &self.manipulators[..]), ("head", self.head.as_slice())];
        for (role, links) in roles {
            for &l in links {
                if let Some((_, other)) = seen.iter().find(|(s, _)| *s == l) {
                    let valid = if *other == role {
                        format!("it is listed twice in `{role}`")
                    } else {
                        format!(
                            "it is also in `{other}`: an end effector has one role (the roles a profile leaves out are the \
                             analysis' own, which `ace inspect` lists)"
                        )
                    };
                    return Err(bad(role, l, valid));
                }
                seen.push((l, role));
            }
        }
        for &w in &self.wheels {
            let turns = tree.links[w].joint.as_ref().is_some_and(|j| {
                j.dof.is_some() && matches!(j.kind, JointKind::Continuous | JointKind::Revolute)
            });
            if !turns {
                return Err(bad(
                    "wheels",
                    w,
                    "its joint does not turn (fixed, prismatic or none): a wheel turns on a continuous or revolute joint"
                        .into(),
                ));
            }
        }
        for &a in &self.feet {
            if let Some(&b) = self.feet.iter().find(|&&b| b != a && tree.is_descendant(b, a)) {
                return Err(bad(
                    "feet",
                    b,
                    format!("it hangs below `{}`, also a foot: a leg has one foot, at its end", tree.links[a].name),
                ));
            }
        }
        Ok(())
    }

    /// End-effector links in the order the character state uses: feet, then manipulators, then the head.
    pub fn end_effectors(&self) -> Vec<usize> {
        self.feet
            .iter()
            .chain(&self.manipulators)
            .chain(&self.head)
            .copied()
            .collect()
    }

    /// Link names of [`Morphology::end_effectors`], in the same order.
    pub fn end_effector_links(&self, tree: &KinematicTree) -> Vec<String> {
        self.end_effectors().iter().map(|&l| tree.links[l].name.clone()).collect()
    }

    /// The DoFs of the wheels' joints (a wheel whose joint is fixed has none).
    pub fn wheel_dofs(&self, tree: &KinematicTree) -> Vec<usize> {
        self.wheels.iter().filter_map(|&l| tree.links[l].joint.as_ref()?.dof).collect()
    }

    /// Number of end effectors (feet + manipulators + head).
    pub fn n_end_effectors(&self) -> usize {
        self.feet.len() + self.manipulators.len() + usize::from(self.head.is_some())
    }

    /// The point of end-effector link `link` (its tip offset, else origin) in its link frame.
    pub fn tip_offset(&self, link: usize) -> Vector3<f32> {
        self.tip_offsets.get(&link).copied().unwrap_or_else(Vector3::zeros)
    }

    /// World position of end-effector link `link` given all link poses (e.g. from forward kinematics).
    pub fn ee_point(&self, link: usize, link_poses: &[Isometry3<f32>]) -> Point3<f32> {
        link_poses[link].transform_point(&Point3::from(self.tip_offset(link)))
    }

    /// Link names of every role.
    pub fn names(&self, tree: &KinematicTree) -> MorphologyNames {
        let n = |v: &[usize]| v.iter().map(|&l| tree.links[l].name.clone()).collect();
        MorphologyNames {
            feet: n(&self.feet),
            manipulators: n(&self.manipulators),
            wheels: n(&self.wheels),
            head: self.head.map(|h| tree.links[h].name.clone()),
        }
    }
}

/// Per-character overrides read from TOML (see the module docs). Every field is optional.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Profile {
    /// Foot links replacing the analysed ones.
    pub feet: Option<Vec<String>>,
    /// Manipulator links replacing the analysed ones.
    pub manipulators: Option<Vec<String>>,
    /// Wheel links replacing the analysed ones.
    pub wheels: Option<Vec<String>>,
    /// Head link; `""` means no head.
    pub head: Option<String>,
    /// Rest pose: joint name → position; unnamed DoFs stay at zero (clamped).
    #[serde(default)]
    pub rest_pose: BTreeMap<String, f32>,
    /// End-effector points in their link frames: link name → `[x, y, z]`.
    #[serde(default)]
    pub tip_offsets: BTreeMap<String, [f32; 3]>,
    /// glTF creatures only: metres per file unit (replaces the unit detection).
    pub scale: Option<f32>,
    /// glTF creatures only: the file axis the creature faces (`"+z"`, the glTF convention, `"-z"`,
    /// `"+x"`, `"-x"`, `"+y"` or `"-y"`; `"-y"`, Blender's front, when `up` is along z).
    pub forward: Option<crate::character::gltf::Axis>,
    /// glTF creatures only: the file axis that points up (`"+y"`, the glTF convention; `"+z"` for a
    /// file exported with Blender's own axes).
    pub up: Option<crate::character::gltf::Axis>,
    /// glTF creatures only: the bones that move (replaces the analysis).
    pub animated: Option<Vec<String>>,
    /// glTF creatures only: bones held at rest.
    #[serde(default)]
    pub at_rest: Vec<String>,
    /// glTF creatures only: bone → the axes it turns about (`"yaw"`, `"pitch"`, `"roll"`).
    #[serde(default)]
    pub dofs: BTreeMap<String, Vec<String>>,
    /// glTF creatures only: joint (`"bone:axis"`) → `[lower, upper]` (rad).
    #[serde(default)]
    pub limits: BTreeMap<String, [f32; 2]>,
    /// glTF creatures only: bones that also slide along the three axes of their rest frame (DoFs
    /// `bone:x`, `bone:y`, `bone:z`, in metres), for playing clips that move them off their bind offsets.
    #[serde(default)]
    pub translate: Vec<String>,
    /// File the profile was read from (for error messages).
    #[serde(skip)]
    pub source: Option<String>,
}

/// An error reading or applying a profile: which file and what is wrong.
#[derive(Debug, Clone, Error, PartialEq)]
#[error("{file}: {problem}")]
pub struct ProfileError {
    pub file: String,
    pub problem: ProfileProblem,
}

/// What [`ProfileError`] reports.
#[derive(Debug, Clone, Error, PartialEq)]
pub enum ProfileProblem {
    #[error("cannot read the file: {0}")]
    Io(String),
    #[error("malformed profile TOML: {0}")]
    Parse(String),
    /// A creature's profile that names what its rig does not have.
    #[error("{0}")]
    Body(String),
    #[error("no link named `{0}`")]
    UnknownLink(String),
    #[error("no movable joint with its own DoF named `{0}`")]
    UnknownJoint(String),
    #[error("`{0}` applies to glTF creatures only, not to a URDF")]
    GltfOnly(&'static str),
    #[error("`{key}` = {value}: {valid}")]
    BadValue {
        /// The key, as TOML writes it (`limits."Thigh.L:pitch"`).
        key: String,
        value: String,
        /// What would be valid.
        valid: String,
    },
}

/// Range of a profile's `scale` (metres per file unit): from a tenth of a millimetre to 100 m per unit.
pub const PROFILE_SCALE_RANGE: (f32, f32) = (1e-4, 100.0);

impl Profile {
    /// Parses profile TOML; `file` names the source in errors.
    pub fn from_toml(text: &str, file: &str) -> Result<Profile, ProfileError> {
        let mut p: Profile = toml::from_str(text).map_err(|e| ProfileError {
            file: file.into(),
            problem: ProfileProblem::Parse(e.to_string()),
        })?;
        p.check().map_err(|problem| ProfileError { file: file.into(), problem })?;
        p.source = Some(file.into());
        Ok(p)
    }

    /// Checks the numbers the profile gives (TOML allows `nan` and `inf`): limits are finite with
    /// lower ≤ upper (the controllers clamp to them), rest positions and tip offsets finite, the scale
    /// in [`PROFILE_SCALE_RANGE`].
    fn check(&self) -> Result<(), ProfileProblem> {
        let bad = |key: String, value: String, valid: &str| {
            Err(ProfileProblem::BadValue { key, value, valid: valid.into() })
        };
        for (joint, &[lo, hi]) in &self.limits {
            if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                return bad(
                    format!("limits.\"{joint}\""),
                    format!("[{lo}, {hi}]"),
                    "a limit is [lower, upper] in radians, both finite, with lower ≤ upper",
                );
            }
        }
        for (joint, &v) in &self.rest_pose {
            if !v.is_finite() {
                return bad(format!("rest_pose.\"{joint}\""), v.to_string(), "a rest position must be finite");
            }
        }
        for (link, p) in &self.tip_offsets {
            if !p.iter().all(|v| v.is_finite()) {
                return bad(
                    format!("tip_offsets.\"{link}\""),
                    format!("{p:?}"),
                    "a tip offset is [x, y, z] in metres, each finite",
                );
            }
        }
        self.facing()?;
        if let Some(s) = self.scale {
            let (lo, hi) = PROFILE_SCALE_RANGE;
            if !(lo..=hi).contains(&s) {
                return bad(
                    "scale".into(),
                    s.to_string(),
                    &format!("the scale is metres per file unit, from {lo} to {hi}"),
                );
            }
        }
        Ok(())
    }

    /// The creature's axes in its file: `up` and `forward`, or glTF's; parallel ones are a bad `forward`.
    pub fn facing(&self) -> Result<crate::character::gltf::Facing, ProfileProblem> {
        crate::character::gltf::Facing::new(self.forward, self.up).map_err(|valid| ProfileProblem::BadValue {
            key: "forward".into(),
            value: format!("\"{}\"", self.forward.map_or("+z", |a| a.label())),
            valid,
        })
    }

    /// Reads a profile file (a regular file of UTF-8 text: [`crate::input::read_text`]).
    pub fn from_file(path: &Path) -> Result<Profile, ProfileError> {
        let file = path.display().to_string();
        let text = crate::input::read_text(path).map_err(|e| ProfileError {
            file: file.clone(),
            problem: ProfileProblem::Io(e.to_string()),
        })?;
        Profile::from_toml(&text, &file)
    }

    /// The conventional profile path of a URDF: `<stem>.profile.toml` in the same directory.
    pub fn path_beside(urdf_path: &Path) -> PathBuf {
        let stem = urdf_path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        urdf_path.with_file_name(format!("{stem}.profile.toml"))
    }

    /// Reads the profile beside `urdf_path` if there is one.
    pub fn beside(urdf_path: &Path) -> Result<Option<Profile>, ProfileError> {
        let p = Profile::path_beside(urdf_path);
        // One that is there but is not a regular file (a FIFO, a directory) is an error, not skipped.
        if p.exists() {
            Profile::from_file(&p).map(Some)
        } else {
            Ok(None)
        }
    }

    /// `problem` in this profile's file (`<profile>` for one not read from a file).
    fn error(&self, problem: ProfileProblem) -> ProfileError {
        ProfileError { file: self.source.clone().unwrap_or_else(|| "<profile>".into()), problem }
    }

    /// Fails if the profile sets a key that only glTF creatures have.
    pub fn check_urdf(&self) -> Result<(), ProfileError> {
        let key = [
            ("scale", self.scale.is_some()),
            ("forward", self.forward.is_some()),
            ("up", self.up.is_some()),
            ("animated", self.animated.is_some()),
            ("at_rest", !self.at_rest.is_empty()),
            ("dofs", !self.dofs.is_empty()),
            ("limits", !self.limits.is_empty()),
            ("translate", !self.translate.is_empty()),
        ]
        .into_iter()
        .find(|k| k.1);
        match key {
            Some((k, _)) => Err(self.error(ProfileProblem::GltfOnly(k))),
            None => Ok(()),
        }
    }

    /// Sets the end-effector points of `m` that the profile gives (`tip_offsets`). An offset on a link
    /// that is no end effector, or farther from its link than the whole body is big (a value in
    /// millimetres, a typo), is refused: the state and L_fea would carry it.
    pub fn apply_tip_offsets(&self, tree: &KinematicTree, m: &mut Morphology) -> Result<(), ProfileError> {
        let err = |problem| self.error(problem);
        if self.tip_offsets.is_empty() {
            return Ok(());
        }
        let ees = m.end_effectors();
        let size = Analysis::new(tree).size;
        for (name, o) in &self.tip_offsets {
            let link = tree.link_index(name).ok_or_else(|| err(ProfileProblem::UnknownLink(name.clone())))?;
            let bad = |valid: String| err(ProfileProblem::BadValue { key: format!("tip_offsets.\"{name}\""), value: format!("{o:?}"), valid });
            if !ees.contains(&link) {
                return Err(bad(format!("`{name}` is not an end effector (a foot, a manipulator or the head), so it has no tip")));
            }
            let o = Vector3::from(*o);
            if o.norm() > size {
                return Err(bad(format!(
                    "the tip would lie {:.3} m from its link, farther than the character is big ({size:.3} m): a tip offset is in metres, in the link's frame",
                    o.norm()
                )));
            }
            m.tip_offsets.insert(link, o);
        }
        Ok(())
    }

    /// Sets the tree's rest pose (its `neutral_q`) from `rest_pose`, if the profile has one.
    pub fn apply_rest_pose(&self, tree: &mut KinematicTree) -> Result<(), ProfileError> {
        if self.rest_pose.is_empty() {
            return Ok(());
        }
        let mut q = vec![0.0; tree.dof()];
        let err = |problem| self.error(problem);
        for (name, v) in &self.rest_pose {
            let d = tree.dof_index(name).ok_or_else(|| err(ProfileProblem::UnknownJoint(name.clone())))?;
            // Clamped into the limits, a value in degrees (or out of range) became another pose silently.
            if let Some(l) = tree.limits(d) {
                let tol = 1e-4 * (1.0 + l.upper.abs().max(l.lower.abs()));
                if *v < l.lower - tol || *v > l.upper + tol {
                    return Err(err(ProfileProblem::BadValue {
                        key: format!("rest_pose.\"{name}\""),
                        value: v.to_string(),
                        valid: format!(
                            "outside the joint's limits [{}, {}] (radians, or metres for a sliding joint)",
                            l.lower, l.upper
                        ),
                    }));
                }
            }
            q[d] = *v;
        }
        tree.set_rest_q(q);
        Ok(())
    }
}

/// An error loading a character (URDF plus optional profile).
#[derive(Debug, Clone, Error, PartialEq)]
pub enum CharacterError {
    #[error(transparent)]
    Urdf(#[from] UrdfError),
    #[error(transparent)]
    Profile(#[from] ProfileError),
    #[error(transparent)]
    Gltf(#[from] crate::character::GltfError),
}

/// Loads a character: a URDF robot, or a rigged glTF creature (`.glb`/`.gltf`, see
/// [`crate::character`]), with the profile beside it if any (rest pose and overrides), and its
/// morphology.
pub fn load_character(urdf_path: &Path) -> Result<(KinematicTree, Morphology), CharacterError> {
    if crate::character::is_gltf(urdf_path) {
        let c = crate::character::load_creature(urdf_path)?;
        return Ok((c.tree, c.morphology));
    }
    let mut tree = KinematicTree::from_urdf_file(urdf_path)?;
    let morph = match Profile::beside(urdf_path)? {
        Some(p) => {
            p.check_urdf()?;
            p.apply_rest_pose(&mut tree)?;
            Morphology::with_profile(&tree, &p)?
        }
        None => Morphology::analyze(&tree),
    };
    Ok((tree, morph))
}

/// Working data of [`Morphology::analyze`].
struct Analysis<'a> {
    tree: &'a KinematicTree,
    poses: Vec<Isometry3<f32>>,
    children: Vec<Vec<usize>>,
    boxes: Vec<Option<Aabb>>,
    ground: f32,
    height: f32,
    size: f32,
    tol: f32,
}

/// Joint counts along a chain.
#[derive(Clone, Copy, Debug, Default)]
struct Chain {
    /// Movable joints.
    joints: usize,
    /// How many of them rotate.
    rotational: usize,
}

impl Chain {
    fn with(self, kind: Option<JointKind>) -> Chain {
        Chain {
            joints: self.joints + 1,
            rotational: self.rotational + usize::from(kind.is_some_and(|k| k.is_rotational())),
        }
    }
}

/// A tip found by walking a limb.
struct Tip {
    link: usize,
    /// Joints from the limb root to `link` inclusive.
    limb: Chain,
    /// Potential reach of the whole limb (m).
    limb_reach: f32,
    /// Joints after the last branching of the limb (the whole limb if it does not branch).
    branch: Chain,
    /// Potential reach from the first joint after the last branching (m).
    branch_reach: f32,
    /// On a branch much shorter than its siblings (a sensor mount, a neck): can only be a head.
    minor: bool,
}

impl<'a> Analysis<'a> {
    fn new(tree: &'a KinematicTree) -> Self {
        let poses = tree.forward_kinematics(&tree.neutral_pose(Isometry3::identity()));
        let mut children = vec![Vec::new(); tree.links.len()];
        for (i, l) in tree.links.iter().enumerate() {
            if let Some(p) = l.parent {
                children[p].push(i);
            }
        }
        let boxes: Vec<_> = tree.links.iter().zip(&poses).map(|(l, p)| l.aabb(p)).collect();
        let all = tree.aabb(&poses);
        let ext = all.max - all.min;
        let height = ext.z.max(1e-3);
        Analysis {
            tree,
            children,
            boxes,
            ground: all.min.z,
            height,
            size: ext.max().max(1e-3),
            tol: (0.03 * height).max(0.01),
            poses,
        }
    }

    fn movable(&self, l: usize) -> bool {
        self.tree.links[l].joint.as_ref().is_some_and(|j| j.kind.is_movable())
    }

    /// `l` and every link fixed to it (below it).
    fn rigid_set(&self, l: usize) -> Vec<usize> {
        let mut out = vec![l];
        let mut i = 0;
        while i < out.len() {
            out.extend(self.children[out[i]].iter().filter(|&&c| !self.movable(c)));
            i += 1;
        }
        out
    }

    /// Movable links hanging off the rigid set of `l`.
    fn next_segments(&self, l: usize) -> Vec<usize> {
        let mut out: Vec<usize> = self
            .rigid_set(l)
            .iter()
            .flat_map(|&r| self.children[r].iter().copied())
            .filter(|&c| self.movable(c))
            .collect();
        out.sort_unstable();
        out
    }

    fn subtree(&self, l: usize) -> Vec<usize> {
        let mut out = vec![l];
        let mut i = 0;
        while i < out.len() {
            out.extend(self.children[out[i]].iter().copied());
            i += 1;
        }
        out
    }

    /// The lowest point of `links`' geometry; the lowest origin when none of them has any. A link
    /// without geometry beside ones with some is a frame, not a point of the body (ROS's
    /// `base_footprint` at the ground under a robot's body once made every robot with one rest on
    /// its body, without feet).
    fn lowest(&self, links: &[usize]) -> f32 {
        let shapes = links.iter().filter_map(|&l| self.boxes[l]).map(|b| b.min.z).fold(f32::INFINITY, f32::min);
        if shapes.is_finite() {
            return shapes;
        }
        links.iter().map(|&l| self.poses[l].translation.vector.z).fold(f32::INFINITY, f32::min)
    }

    /// Path length from the joint of `from` to the farthest point below it, counting prismatic
    /// travel and the geometry at the end of the chain.
    fn reach(&self, from: usize) -> f32 {
        let mut best = 0.0f32;
        let mut stack = vec![(from, 0.0f32)];
        while let Some((l, acc)) = stack.pop() {
            let link = &self.tree.links[l];
            let mut here = acc;
            if l != from
                && let Some(j) = &link.joint
            {
                here += j.origin.translation.vector.norm();
            }
            if let Some(j) = &link.joint
                && j.kind == JointKind::Prismatic
                && let Some(lim) = j.limits
            {
                let travel = lim.lower.abs().max(lim.upper.abs());
                here += if travel.is_finite() { travel } else { 0.0 };
            }
            let geom = link
                .extent_geometry()
                .iter()
                .filter_map(|g| g.bounding_sphere())
                .map(|(c, r)| c.coords.norm() + r)
                .fold(0.0, f32::max);
            best = best.max(here + geom);
            stack.extend(self.children[l].iter().map(|&c| (c, here)));
        }
        best
    }

    fn count_movable(&self, l: usize) -> usize {
        self.subtree(l).into_iter().filter(|&x| self.movable(x)).count()
    }

    /// Walks a limb from movable link `l`, pushing its tips. `branch` is the first movable link after
    /// the last branching and the joints since; `minor` marks tips on insignificant branches.
    fn collect_tips(
        &self,
        l: usize,
        limb: Chain,
        branch: (usize, Chain),
        minor: bool,
        limb_reach: f32,
        out: &mut Vec<Tip>,
    ) {
        let kind = self.tree.links[l].joint.as_ref().map(|j| j.kind);
        let (limb, branch) = (limb.with(kind), (branch.0, branch.1.with(kind)));
        let next = self.next_segments(l);
        if next.is_empty() || (next.len() > 1 && limb.joints >= 3 && next.iter().all(|&n| self.count_movable(n) <= 3)) {
            // End of the chain, or a gripper's fingers.
            out.push(Tip {
                link: l,
                limb,
                limb_reach,
                branch: branch.1,
                branch_reach: self.reach(branch.0),
                minor,
            });
        } else if next.len() == 1 {
            self.collect_tips(next[0], limb, branch, minor, limb_reach, out);
        } else {
            let reaches: Vec<f32> = next.iter().map(|&n| self.reach(n)).collect();
            let longest = reaches.iter().copied().fold(0.0, f32::max);
            for (n, r) in next.into_iter().zip(reaches) {
                self.collect_tips(
                    n,
                    limb,
                    (n, Chain::default()),
                    minor || r < 0.25 * longest,
                    limb_reach,
                    out,
                );
            }
        }
    }

    fn is_wheel(&self, l: usize) -> bool {
        let Some(j) = &self.tree.links[l].joint else {
            return false;
        };
        let spins = match j.kind {
            JointKind::Continuous => true,
            JointKind::Revolute => j
                .limits
                .is_some_and(|lim| lim.upper - lim.lower >= 2.0 * std::f32::consts::PI - 0.05),
            _ => false,
        };
        if !spins || self.count_movable(l) != 1 {
            return false;
        }
        let axis = self.poses[l].rotation * j.axis.into_inner();
        if axis.z.abs() > 0.3 {
            return false;
        }
        let sub = self.subtree(l);
        if self.lowest(&sub) - self.ground > self.tol {
            return false;
        }
        let mut b = Aabb::empty();
        for &s in &sub {
            if let Some(x) = self.boxes[s] {
                b.merge(&x);
            }
        }
        if b.is_empty() {
            // No extent known: accept a low axle.
            return self.poses[l].translation.vector.z - self.ground < 0.15 * self.height;
        }
        let d = b.center() - Point3::from(self.poses[l].translation.vector);
        let off_axis = (d - axis * d.dot(&axis)).norm();
        off_axis < 0.3 * b.half_extents().max() + 0.005
    }

    /// Lowest point of the geometry below `l` (bottom of a sphere when a sphere is lowest, else bottom
    /// centre of the lowest box, else the lowest link origin).
    fn contact_point(&self, l: usize) -> Point3<f32> {
        let mut best: Option<(f32, Point3<f32>, bool)> = None;
        for s in self.subtree(l) {
            let link = &self.tree.links[s];
            for g in link.extent_geometry() {
                let Some(b) = g.aabb(&self.poses[s]) else { continue };
                let is_sphere = matches!(g.shape, Shape::Sphere { .. });
                let p = Point3::new(b.center().x, b.center().y, b.min.z);
                let better = match best {
                    None => true,
                    Some((z, _, sph)) => b.min.z < z - 0.002 || (b.min.z < z + 0.002 && is_sphere && !sph),
                };
                if better {
                    best = Some((b.min.z, p, is_sphere));
                }
            }
        }
        best.map(|(_, p, _)| p).unwrap_or_else(|| {
            let s = self
                .subtree(l)
                .into_iter()
                .min_by(|&a, &b| {
                    self.poses[a]
                        .translation
                        .vector
                        .z
                        .total_cmp(&self.poses[b].translation.vector.z)
                })
                .unwrap_or(l);
            Point3::from(self.poses[s].translation.vector)
        })
    }

    fn run(&self) -> Morphology {
        let mut m = Morphology::default();
        let root_body = self.rigid_set(0);
        let resting_on_body = self.lowest(&root_body) - self.ground <= self.tol;
        let mut tips = Vec::new();
        for limb in self.next_segments(0) {
            if self.is_wheel(limb) {
                m.wheels.push(limb);
            } else {
                let reach = self.reach(limb);
                self.collect_tips(
                    limb,
                    Chain::default(),
                    (limb, Chain::default()),
                    false,
                    reach,
                    &mut tips,
                );
            }
        }
        let supported = resting_on_body || m.wheels.len() >= 2;
        let mut rest = Vec::new();
        for t in tips {
            let p = self.contact_point(t.link);
            if !supported && !t.minor && t.limb.rotational >= 2 && p.z - self.ground <= self.tol {
                // Foot point on the nearest link rigidly fixed to the tip.
                let host = self
                    .rigid_set(t.link)
                    .into_iter()
                    .min_by(|&a, &b| {
                        let da = (self.poses[a].translation.vector - p.coords).norm();
                        let db = (self.poses[b].translation.vector - p.coords).norm();
                        da.total_cmp(&db)
                    })
                    .unwrap_or(t.link);
                let offset = self.poses[host].inverse_transform_point(&p).coords;
                if offset.norm() > 1e-3 {
                    m.tip_offsets.insert(host, offset);
                }
                m.feet.push(host);
            } else {
                rest.push(t);
            }
        }
        let top = self.ground + 0.7 * self.height;
        let head = rest
            .iter()
            .filter(|t| t.branch.joints <= 3 && t.branch.rotational == t.branch.joints)
            .filter(|t| t.branch_reach < 0.25 * self.size)
            .filter(|t| self.poses[t.link].translation.vector.z >= top)
            .max_by(|a, b| {
                self.poses[a.link]
                    .translation
                    .vector
                    .z
                    .total_cmp(&self.poses[b.link].translation.vector.z)
            })
            .map(|t| t.link);
        m.head = head;
        for t in rest.iter().filter(|t| Some(t.link) != head) {
            if !t.minor && t.limb.joints >= 2 && t.limb_reach >= 0.15 * self.size {
                let origin = self.poses[t.link].translation.vector;
                let ee = self
                    .rigid_set(t.link)
                    .into_iter()
                    .max_by(|&a, &b| {
                        let da = (self.poses[a].translation.vector - origin).norm();
                        let db = (self.poses[b].translation.vector - origin).norm();
                        // Ties go to the earlier link.
                        da.total_cmp(&db).then(b.cmp(&a))
                    })
                    .unwrap_or(t.link);
                m.manipulators.push(ee);
            }
        }
        m.feet.sort_unstable();
        m.manipulators.sort_unstable();
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn joint(name: &str, kind: &str, parent: &str, child: &str, xyz: &str, axis: &str) -> String {
        format!(
            r#"<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>
               <origin xyz="{xyz}"/><axis xyz="{axis}"/><limit lower="-1" upper="1" velocity="1" effort="1"/></joint>"#
        )
    }

    fn link(name: &str, geometry: &str) -> String {
        format!(r#"<link name="{name}"><collision><geometry>{geometry}</geometry></collision></link>"#)
    }

    /// A box lying on the ground, a turning joint (0.1 m up) to `l1`, a 5 cm cube, and a joint of `kind`
    /// (0.3 m ahead, ±1) to `l2`, a sphere of 0.2 m.
    fn arm_on_a_box(kind: &str) -> KinematicTree {
        let mut x = String::from(r#"<robot name="arm">"#);
        x += &link("base", r#"<box size="0.4 0.4 0.2"/>"#);
        x += &joint("a", "revolute", "base", "l1", "0 0 0.1", "0 0 1");
        x += &link("l1", r#"<box size="0.05 0.05 0.05"/>"#);
        x += &joint("b", kind, "l1", "l2", "0.3 0 0", "0 1 0");
        x += &link("l2", r#"<sphere radius="0.2"/>"#);
        x += "</robot>";
        KinematicTree::from_urdf_str(&x).unwrap()
    }

    /// A humanoid: two legs from the pelvis; a waist joint carrying two arms with two-finger hands and a
    /// pan–tilt head. Exercises branching (waist → arms + neck) and gripper detection (fingers).
    fn humanoid() -> KinematicTree {
        let mut x = String::from(r#"<robot name="humanoid">"#);
        x += &link("pelvis", r#"<box size="0.3 0.3 0.1"/>"#);
        for (s, y) in [("l", 0.1), ("r", -0.1)] {
            x += &joint(
                &format!("{s}_hip"),
                "revolute",
                "pelvis",
                &format!("{s}_thigh"),
                &format!("0 {y} -0.05"),
                "0 1 0",
            );
            x += &link(&format!("{s}_thigh"), r#"<box size="0.1 0.1 0.4"/>"#);
            x += &joint(
                &format!("{s}_knee"),
                "revolute",
                &format!("{s}_thigh"),
                &format!("{s}_shin"),
                "0 0 -0.4",
                "0 1 0",
            );
            x += &link(&format!("{s}_shin"), r#"<box size="0.08 0.08 0.4"/>"#);
            x += &joint(
                &format!("{s}_ankle"),
                "revolute",
                &format!("{s}_shin"),
                &format!("{s}_foot"),
                "0 0 -0.4",
                "0 1 0",
            );
            x += &link(&format!("{s}_foot"), r#"<sphere radius="0.05"/>"#);
        }
        x += &joint("waist", "revolute", "pelvis", "chest", "0 0 0.1", "0 0 1");
        x += &link("chest", r#"<box size="0.25 0.35 0.4"/>"#);
        for (s, y) in [("l", 0.22), ("r", -0.22)] {
            x += &joint(
                &format!("{s}_sh_pitch"),
                "revolute",
                "chest",
                &format!("{s}_sh"),
                &format!("0 {y} 0.35"),
                "0 1 0",
            );
            x += &link(&format!("{s}_sh"), r#"<sphere radius="0.04"/>"#);
            x += &joint(
                &format!("{s}_sh_roll"),
                "revolute",
                &format!("{s}_sh"),
                &format!("{s}_upper"),
                "0 0 0",
                "1 0 0",
            );
            x += &link(&format!("{s}_upper"), r#"<box size="0.06 0.06 0.3"/>"#);
            x += &joint(
                &format!("{s}_elbow"),
                "revolute",
                &format!("{s}_upper"),
                &format!("{s}_fore"),
                "0 0 -0.3",
                "0 1 0",
            );
            x += &link(&format!("{s}_fore"), r#"<box size="0.05 0.05 0.25"/>"#);
            x += &joint(
                &format!("{s}_wrist"),
                "revolute",
                &format!("{s}_fore"),
                &format!("{s}_hand"),
                "0 0 -0.25",
                "1 0 0",
            );
            x += &link(&format!("{s}_hand"), r#"<box size="0.08 0.03 0.08"/>"#);
            for f in ["a", "b"] {
                let fy = if f == "a" { 0.02 } else { -0.02 };
                x += &joint(
                    &format!("{s}_finger_{f}"),
                    "prismatic",
                    &format!("{s}_hand"),
                    &format!("{s}_finger_{f}"),
                    &format!("0 {fy} -0.06"),
                    "0 1 0",
                );
                x += &link(&format!("{s}_finger_{f}"), r#"<box size="0.02 0.01 0.05"/>"#);
            }
        }
        x += &joint("neck_pan", "revolute", "chest", "neck", "0 0 0.42", "0 0 1");
        x += &link("neck", r#"<box size="0.05 0.05 0.05"/>"#);
        x += &joint("neck_tilt", "revolute", "neck", "head", "0 0 0.05", "0 1 0");
        x += &link("head", r#"<sphere radius="0.1"/>"#);
        x += "</robot>";
        KinematicTree::from_urdf_str(&x).unwrap()
    }

    #[test]
    fn humanoid_branches_into_arms_and_head() {
        let t = humanoid();
        let m = Morphology::analyze(&t);
        let n = m.names(&t);
        assert_eq!(n.feet, ["l_foot", "r_foot"]);
        assert_eq!(n.manipulators, ["l_hand", "r_hand"]);
        assert_eq!(n.head.as_deref(), Some("head"));
        assert!(n.wheels.is_empty());
        assert_eq!(m.end_effectors().len(), 5);
        assert_eq!(m.n_end_effectors(), 5);
        // Feet are sphere bottoms.
        let stand = t.forward_kinematics(&t.standing_pose());
        for &f in &m.feet {
            assert!(m.ee_point(f, &stand).z.abs() < 1e-4);
        }
    }

    #[test]
    fn a_wheeled_base_s_wheel_dofs_are_its_wheel_joints() {
        let (t, m) = crate::test_data::bundled_character("stretch");
        assert_eq!(m.wheels.len(), 2, "{:?}", m.names(&t).wheels);
        let dofs = m.wheel_dofs(&t);
        let expected: Vec<usize> = m.wheels.iter().map(|&l| t.links[l].joint.as_ref().unwrap().dof.unwrap()).collect();
        assert_eq!(dofs, expected);
        assert!(dofs.iter().all(|&d| t.dof_names()[d].contains("wheel")), "{dofs:?}");
        let (spot, legged) = crate::test_data::bundled_character("spot");
        assert!(legged.wheel_dofs(&spot).is_empty());
    }

    #[test]
    fn a_profile_s_numbers_are_checked_and_the_error_names_the_key() {
        let ok = "feet = [\"a\"]\nscale = 0.01\n[limits]\nknee = [-1.0, 1.0]\n[rest_pose]\nknee = 0.5\n[tip_offsets]\nfoot = [0.0, 0.0, -0.02]\n";
        let p = Profile::from_toml(ok, "good.profile.toml").unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((p.scale, p.source.as_deref()), (Some(0.01), Some("good.profile.toml")));
        for (text, key) in [
            ("[limits]\nknee = [1.0, -1.0]", "limits.\"knee\""),
            ("[limits]\nknee = [nan, 1.0]", "limits.\"knee\""),
            ("[limits]\nknee = [-1.0, inf]", "limits.\"knee\""),
            ("[rest_pose]\nknee = inf", "rest_pose.\"knee\""),
            ("[tip_offsets]\nfoot = [0.0, nan, 0.0]", "tip_offsets.\"foot\""),
            ("scale = 0.0", "scale"),
            ("scale = 1000.0", "scale"),
            ("scale = nan", "scale"),
        ] {
            let e = Profile::from_toml(text, "bad.profile.toml").unwrap_err();
            assert_eq!(e.file, "bad.profile.toml");
            assert!(matches!(&e.problem, ProfileProblem::BadValue { key: k, .. } if k == key), "{text}: {e}");
        }
        // From a file: the bundled hound's, and a missing one named in the error.
        let assets = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets/creatures");
        let hound = Profile::from_file(&assets.join("hound.profile.toml")).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(hound.at_rest, ["Spine", "Chest"]);
        assert!(hound.source.as_deref().is_some_and(|s| s.ends_with("hound.profile.toml")));
        let e = Profile::from_file(&assets.join("absent.profile.toml")).unwrap_err();
        assert!(e.file.ends_with("absent.profile.toml") && matches!(e.problem, ProfileProblem::Io(_)), "{e}");
        // A limit of no width is a joint held in place, not an error; the scale's range is inclusive.
        for text in ["[limits]\nknee = [0.3, 0.3]", "scale = 0.0001", "scale = 100.0"] {
            Profile::from_toml(text, "edge.profile.toml").unwrap_or_else(|e| panic!("{text}: {e}"));
        }
    }

    #[test]
    fn the_profile_beside_a_character_is_read_checked_for_its_kind_and_sets_the_rest_pose() {
        let assets = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../assets");
        let hound = Profile::beside(&assets.join("creatures/hound.glb")).unwrap().expect("the hound's profile");
        assert_eq!(hound.at_rest, ["Spine", "Chest"]);
        // A creature's key in a robot's profile is refused, naming it; a robot's keys are not.
        let e = hound.check_urdf().unwrap_err();
        assert!(matches!(e.problem, ProfileProblem::GltfOnly("at_rest")) && e.file.ends_with("hound.profile.toml"), "{e}");
        Profile::from_toml("feet = [\"a\"]\n[rest_pose]\nknee = 0.5", "robot").unwrap().check_urdf().unwrap();
        assert_eq!(Profile::beside(&assets.join("characters/spot.urdf")).unwrap(), None);
        // A folder where the profile would be is an error, not skipped.
        let dir = std::env::temp_dir().join(format!("ace-profile-beside-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("bot.profile.toml")).unwrap();
        let e = Profile::beside(&dir.join("bot.urdf")).unwrap_err();
        assert!(e.file.ends_with("bot.profile.toml"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);

        let (mut tree, _) = crate::test_data::bundled_character("spot");
        let joint = tree.dof_names()[2].to_string();
        let p = Profile::from_toml(&format!("[rest_pose]\n{joint} = 0.25"), "spot").unwrap();
        p.apply_rest_pose(&mut tree).unwrap();
        let q = tree.neutral_q();
        assert_eq!(q[2], 0.25);
        assert!(q.iter().enumerate().all(|(d, v)| d == 2 || *v == 0.0), "{q:?}");
        let p = Profile::from_toml("[rest_pose]\nno_such_joint = 0.1", "spot").unwrap();
        let e = p.apply_rest_pose(&mut tree).unwrap_err();
        assert!(matches!(&e.problem, ProfileProblem::UnknownJoint(j) if j == "no_such_joint"), "{e}");
    }

    #[test]
    fn a_limb_s_reach_counts_offsets_prismatic_travel_and_the_last_shape() {
        // The arm on a box with a prismatic second joint of ±1 m.
        let t = arm_on_a_box("prismatic");
        let a = Analysis::new(&t);
        let (l1, l2) = (t.link_index("l1").unwrap(), t.link_index("l2").unwrap());
        // From l1's joint: its own offset is not counted; l2's 0.3 m, its 1 m of travel, the sphere.
        assert!((a.reach(l1) - 1.5).abs() < 1e-6, "{}", a.reach(l1));
        assert!((a.reach(l2) - 1.2).abs() < 1e-6, "{}", a.reach(l2));
        assert_eq!((a.count_movable(l1), a.count_movable(l2)), (2, 1));
    }

    #[test]
    fn a_branch_under_a_quarter_of_its_longest_sibling_s_reach_is_no_manipulator() {
        // A box on the ground with a turning hub; from the hub a long arm rising 0.5 m and a 2 cm stub
        // of two joints, below the height a head would need.
        let mut x = String::from(r#"<robot name="stub">"#);
        x += &link("base", r#"<box size="0.4 0.4 0.2"/>"#);
        x += &joint("a", "revolute", "base", "hub", "0 0 0.1", "0 0 1");
        x += &link("hub", r#"<box size="0.05 0.05 0.05"/>"#);
        x += &joint("b", "revolute", "hub", "upper", "0.05 0 0", "0 1 0");
        x += &link("upper", r#"<box size="0.05 0.05 0.05"/>"#);
        x += &joint("c", "revolute", "upper", "fore", "0 0 0.5", "0 1 0");
        x += &link("fore", r#"<sphere radius="0.03"/>"#);
        x += &joint("s1", "revolute", "hub", "nub", "-0.03 0 0", "0 1 0");
        x += &link("nub", r#"<box size="0.01 0.01 0.01"/>"#);
        x += &joint("s2", "revolute", "nub", "nubtip", "-0.01 0 0", "0 1 0");
        x += &link("nubtip", r#"<sphere radius="0.005"/>"#);
        x += "</robot>";
        let t = KinematicTree::from_urdf_str(&x).unwrap();
        let n = Morphology::analyze(&t).names(&t);
        assert_eq!((n.feet.len(), n.head.as_deref()), (0, None), "{n:?}");
        assert_eq!(n.manipulators, ["fore"]);
        // Four times as large with a stub of 0.3 m against the arm's 2.2: still under a quarter.
        let big = x.replace("0 0 0.5", "0 0 2").replace("0.05 0 0", "0.2 0 0").replace("-0.01 0 0", "-0.25 0 0");
        let t = KinematicTree::from_urdf_str(&big).unwrap();
        let n = Morphology::analyze(&t).names(&t);
        assert_eq!((n.feet.len(), n.head.as_deref()), (0, None), "{n:?}");
        assert_eq!(n.manipulators, ["fore"]);
        // Exactly a quarter (0.1875 m against 0.75, both exact in binary) is not under it: a manipulator.
        let quarter = x
            .replace(r#"<sphere radius="0.03"/>"#, r#"<sphere radius="0.25"/>"#)
            .replace("-0.01 0 0", "-0.125 0 0")
            .replace(r#"<sphere radius="0.005"/>"#, r#"<sphere radius="0.0625"/>"#);
        let t = KinematicTree::from_urdf_str(&quarter).unwrap();
        let n = Morphology::analyze(&t).names(&t);
        assert_eq!(n.manipulators, ["fore", "nubtip"], "{n:?}");
    }

    #[test]
    fn wheels_spin_on_continuous_joints_or_revolute_ones_of_a_full_turn() {
        // A box on two ball wheels (one on a joint of ±π, a full turn as URDFs write it) and a caster; a
        // ball on a joint of ±2.8 rad is no wheel.
        let wheel = |name: &str, y: f32, limits: &str| {
            format!(
                r#"<joint name="{name}_joint" type="{}"><parent link="base"/><child link="{name}"/>
                   <origin xyz="0 {y} 0"/><axis xyz="0 1 0"/>{limits}</joint>{}"#,
                if limits.is_empty() { "continuous" } else { "revolute" },
                link(name, r#"<sphere radius="0.1"/>"#)
            )
        };
        let mut x = String::from(r#"<robot name="wheels">"#);
        x += &link("base", r#"<box size="0.4 0.3 0.1"/>"#);
        x += &wheel("left", 0.2, "");
        x += &wheel("right", -0.2, r#"<limit lower="-3.1416" upper="3.1416" velocity="1" effort="1"/>"#);
        x += &wheel("flap", 0.0, r#"<limit lower="-2.8" upper="2.8" velocity="1" effort="1"/>"#);
        // Spinning but no wheel: about a vertical axis, off the ground, or with its shape off its axis.
        let spinner = |name: &str, xyz: &str, axis: &str, shape_at: &str, radius: f32| {
            format!(
                r#"<joint name="{name}_joint" type="continuous"><parent link="base"/><child link="{name}"/>
                   <origin xyz="{xyz}"/><axis xyz="{axis}"/></joint>
                   <link name="{name}"><collision><origin xyz="{shape_at}"/><geometry><sphere radius="{radius}"/></geometry></collision></link>"#
            )
        };
        x += &spinner("turntable", "-0.1 0 0", "0 0 1", "0 0 0", 0.1);
        x += &spinner("fan", "0 0 0.05", "0 1 0", "0 0 0", 0.05);
        x += &spinner("crank", "0.1 0 0.05", "0 1 0", "0.08 0 0", 0.15);
        // A spinning link with no shape at all counts as a wheel when its axle is at the ground.
        x += r#"<joint name="axle_joint" type="continuous"><parent link="base"/><child link="axle"/>
                <origin xyz="0 0 -0.095"/><axis xyz="1 0 0"/></joint><link name="axle"/>"#;
        x += r#"<joint name="caster_joint" type="fixed"><parent link="base"/><child link="caster"/><origin xyz="0.15 0 -0.05"/></joint>"#;
        x += &link("caster", r#"<sphere radius="0.05"/>"#);
        x += "</robot>";
        let t = KinematicTree::from_urdf_str(&x).unwrap();
        let n = Morphology::analyze(&t).names(&t);
        assert_eq!(n.wheels, ["left", "right", "axle"], "{n:?}");
    }

    #[test]
    fn a_foot_touches_the_ground_with_its_lowest_shape_and_a_sphere_among_equals() {
        // Two legs of a hip and a knee; the left foot is a box with a sphere heel at the same depth
        // (the heel touches), the right a sphere with a box sole 1 cm deeper (the sole touches).
        let fixed = |parent: &str, child: &str, xyz: &str| {
            format!(r#"<joint name="{child}_fix" type="fixed"><parent link="{parent}"/><child link="{child}"/><origin xyz="{xyz}"/></joint>"#)
        };
        let shape = |name: &str, at: &str, geometry: &str| {
            format!(r#"<link name="{name}"><collision><origin xyz="{at}"/><geometry>{geometry}</geometry></collision></link>"#)
        };
        let mut x = String::from(r#"<robot name="soles">"#);
        x += &link("body", r#"<box size="0.4 0.3 0.1"/>"#);
        for (s, y) in [("l", 0.1), ("r", -0.1)] {
            x += &joint(&format!("{s}_hip"), "revolute", "body", &format!("{s}_thigh"), &format!("0 {y} -0.05"), "0 1 0");
            x += &link(&format!("{s}_thigh"), r#"<box size="0.05 0.05 0.3"/>"#);
            x += &joint(&format!("{s}_knee"), "revolute", &format!("{s}_thigh"), &format!("{s}_shin"), "0 0 -0.3", "0 1 0");
            x += &link(&format!("{s}_shin"), r#"<box size="0.04 0.04 0.3"/>"#);
            x += &fixed(&format!("{s}_shin"), &format!("{s}_foot"), "0 0 -0.3");
        }
        x += &shape("l_foot", "0.04 0 -0.02", r#"<box size="0.1 0.06 0.04"/>"#);
        x += &fixed("l_foot", "l_heel", "-0.03 0 -0.01");
        x += &shape("l_heel", "0 0 0", r#"<sphere radius="0.03"/>"#);
        x += &shape("r_foot", "0 0 0", r#"<sphere radius="0.03"/>"#);
        x += &fixed("r_foot", "r_sole", "0.05 0 -0.02");
        x += &shape("r_sole", "0 0 0", r#"<box size="0.06 0.06 0.04"/>"#);
        // Toes after them: a box as deep as the left heel (the sphere keeps it), and one 1 mm above the
        // right sole (the sole keeps it).
        x += &fixed("l_heel", "l_toe", "0.15 0 -0.02");
        x += &shape("l_toe", "0 0 0", r#"<box size="0.02 0.02 0.02"/>"#);
        x += &fixed("r_sole", "r_toe", "0.06 0 -0.009");
        x += &shape("r_toe", "0 0 0", r#"<box size="0.02 0.02 0.02"/>"#);
        x += "</robot>";
        let t = KinematicTree::from_urdf_str(&x).unwrap();
        let m = Morphology::analyze(&t);
        assert_eq!(m.names(&t).feet, ["l_heel", "r_sole"]);
        // Each foot point is the bottom of its shape, on the ground.
        let stand = t.forward_kinematics(&t.neutral_pose(nalgebra::Isometry3::identity()));
        let (l, r) = (m.ee_point(m.feet[0], &stand), m.ee_point(m.feet[1], &stand));
        assert!((l.z - r.z).abs() < 1e-5 && (l.x - -0.03).abs() < 1e-5 && (r.x - 0.05).abs() < 1e-5, "{l} {r}");
    }

    /// A short branch of turning joints high on a robot (above 70 % of its height) is its head, on a
    /// robot under a metre tall too; with a sliding joint in it, it is an arm.
    #[test]
    fn a_short_turning_branch_high_on_a_small_robot_is_its_head() {
        // A 0.4 m box on the ground (0.3 m tall), a neck of two joints from its top to a 3 cm skull:
        // 0.38 m tall, the skull 0.35 m up.
        let robot = |second: &str| {
            let mut x = String::from(r#"<robot name="small">"#);
            x += &link("base", r#"<box size="0.4 0.4 0.3"/>"#);
            x += &joint("n1", "revolute", "base", "neck", "0.15 0 0.15", "0 0 1");
            x += &link("neck", r#"<box size="0.02 0.02 0.02"/>"#);
            // A slide of ±1 cm, so that its reach keeps the branch short.
            x += &joint("n2", second, "neck", "skull", "0 0 0.05", "0 1 0").replace(r#"lower="-1" upper="1""#, r#"lower="-0.01" upper="0.01""#);
            x += &link("skull", r#"<sphere radius="0.03"/>"#);
            x += "</robot>";
            KinematicTree::from_urdf_str(&x).unwrap()
        };
        let t = robot("revolute");
        let n = Morphology::analyze(&t).names(&t);
        assert_eq!((n.head.as_deref(), n.manipulators.len()), (Some("skull"), 0), "{n:?}");
        let t = robot("prismatic");
        let n = Morphology::analyze(&t).names(&t);
        assert_eq!((n.head.as_deref(), &n.manipulators[..]), (None, &["skull".to_string()][..]), "{n:?}");
    }

    #[test]
    fn a_robot_resting_on_its_body_has_no_feet() {
        // A single arm on a box lying on the ground, with its tip touching the ground too.
        let t = arm_on_a_box("revolute");
        let m = Morphology::analyze(&t);
        assert!(m.feet.is_empty());
        assert_eq!(m.manipulators, [2]);
    }
}
