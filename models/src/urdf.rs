//! URDF → [`KinematicTree`]: every conversion from `urdf_rs` types lives here (like the `k` crate), plus
//! the checks that turn a parsed robot into a well-formed tree and the errors they raise.
//!
//! Decisions, documented once:
//! - `rpy` is fixed-axis XYZ: R = Rz(yaw)·Ry(pitch)·Rx(roll), as in the URDF specification.
//! - Links are ordered depth-first from the root, children in the order their joints appear in the
//!   file; movable joints get DoF indices in that link order.
//! - `floating` and `planar` joints are treated as **fixed** with a warning in
//!   [`KinematicTree::warnings`] when they anchor the robot to a root link without geometry (a
//!   `world → base` anchor: the character root is already free, see
//!   [`crate::kinematics::CharacterPose::root`]). Anywhere else freezing them would change the robot,
//!   so they are errors, as are `spherical` and any other type. Inverted limits (lower > upper) are
//!   errors.
//! - A root link without geometry holding its only child by a fixed or free joint (ROS's
//!   `base_footprint`, a `world` link) is dropped with a warning: the character's root is the body.
//! - `<mimic>` joints get no DoF of their own: their position is `multiplier · q[target] + offset`.
//!   A mimic whose target is fixed or itself a mimic joint is an error.
//! - The axis of fixed joints is ignored (files often write `0 0 0` there); a movable joint with a zero
//!   axis is an error. Continuous joints have infinite position limits. A velocity or effort limit of
//!   0 (what an absent `<limit>` reads as) means "not given" and becomes +∞.
//! - Mesh files are not loaded, but [`KinematicTree::from_urdf_file`] reads the bounding box of STL/OBJ
//!   meshes it can find (see [`resolve_mesh_path`]) so that meshes have an extent for morphology.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion, Vector3};
use thiserror::Error;

use crate::geometry::{Geometry, Shape};
use crate::kinematics::{JointKind, JointSpec, KinematicTree, Limits, Link, Mimic};
use crate::mesh_file::read_mesh_bounds;

/// An error while importing a URDF: which file (or `<string>`), and what is wrong with it.
#[derive(Debug, Clone, Error, PartialEq)]
#[error("{file}: {problem}")]
pub struct UrdfError {
    /// The file the URDF came from, or `<string>`.
    pub file: String,
    /// What is wrong.
    pub problem: UrdfProblem,
}

/// The problems [`UrdfError`] reports.
#[derive(Debug, Clone, Error, PartialEq)]
pub enum UrdfProblem {
    #[error("cannot read the file: {0}")]
    Io(String),
    #[error("malformed URDF/XML: {0}")]
    Parse(String),
    #[error("the robot has no links")]
    NoLinks,
    #[error("the robot has {links} links, more than the {MAX_LINKS} supported")]
    TooManyLinks { links: usize },
    #[error("link `{0}` is defined more than once")]
    DuplicateLink(String),
    #[error("joint `{0}` is defined more than once")]
    DuplicateJoint(String),
    #[error("joint `{joint}` names parent link `{link}`, which is not defined")]
    MissingParent { joint: String, link: String },
    #[error("joint `{joint}` names child link `{link}`, which is not defined")]
    MissingChild { joint: String, link: String },
    #[error("link `{link}` is the child of several joints: {}", .joints.join(", "))]
    SeveralParents { link: String, joints: Vec<String> },
    #[error("kinematic cycle through links {}", .links.join(" → "))]
    Cycle { links: Vec<String> },
    #[error("no root link: every link is the child of some joint")]
    NoRoot,
    #[error("several root links (links that are no joint's child): {}", .links.join(", "))]
    MultipleRoots { links: Vec<String> },
    #[error(
        "joint `{joint}` has unknown type `{kind}` (expected revolute, continuous, prismatic, fixed, floating or planar)"
    )]
    UnknownJointType { joint: String, kind: String },
    #[error("joint `{joint}` has type `{kind}`, which is not supported")]
    UnsupportedJointType { joint: String, kind: String },
    #[error("non-finite value in {0} (values must be finite numbers within f32's range, ±3.4e38)")]
    NonFinite(String),
    #[error("{what} is {value}; {valid}")]
    OutOfRange { what: String, value: f32, valid: String },
    #[error("joint `{0}` is movable but its axis is zero")]
    ZeroAxis(String),
    #[error(
        "joint `{joint}` has inverted limits: lower {lower} > upper {upper}; the lower limit must not exceed the upper"
    )]
    InvertedLimits { joint: String, lower: f64, upper: f64 },
    #[error(
        "joint `{joint}` is {kind} between links `{parent}` and `{child}`: ACE would have to freeze it, which changes \
         what the robot can do; a {kind} joint is accepted only as the anchor of the robot to a root link \
         without geometry (e.g. `world` → `base`). Use revolute, continuous, prismatic or fixed joints inside \
         the body"
    )]
    FreeJointInBody { joint: String, kind: String, parent: String, child: String },
    #[error("joint `{joint}` mimics `{target}`, which is not a movable joint with its own DoF")]
    BadMimic { joint: String, target: String },
    #[error(
        "line {line}: `{what}` is xacro, not URDF: expand the file into a URDF first (`xacro FILE > robot.urdf`, \
         which ROS installs)"
    )]
    Xacro { line: usize, what: String },
    #[error(
        "line {line}: the `<limit>` of joint `{joint}` has no `velocity`, which URDF requires (`velocity=\"0\"` \
         says it is not known)"
    )]
    LimitWithoutVelocity { line: usize, joint: String },
}

impl UrdfProblem {
    /// Attaches the file name.
    pub fn in_file(self, file: impl Into<String>) -> UrdfError {
        UrdfError {
            file: file.into(),
            problem: self,
        }
    }
}

/// Name used in errors for URDFs that do not come from a file.
pub const STRING_SOURCE: &str = "<string>";

/// Parses URDF text and converts it. `file` only names the source in errors and `base_dir` (when
/// given) is where relative and `package://` mesh paths are looked for to read mesh bounds.
pub fn parse_urdf(xml: &str, file: &str, base_dir: Option<&Path>) -> Result<KinematicTree, UrdfError> {
    // The scans read the file once without its comments (its lines kept).
    let text = without_comments(xml);
    if let Some((line, what)) = xacro_use(&text) {
        return Err(UrdfProblem::Xacro { line, what }.in_file(file));
    }
    if let Some((line, joint)) = limit_without_velocity(&text) {
        return Err(UrdfProblem::LimitWithoutVelocity { line, joint }.in_file(file));
    }
    if let Some((joint, kind)) = scan_joint_types(&text)
        .into_iter()
        .find(|(_, k)| !KNOWN_TYPES.contains(&k.as_str()))
    {
        return Err(UrdfProblem::UnknownJointType { joint, kind }.in_file(file));
    }
    let robot = urdf_rs::read_from_string(xml).map_err(|e| {
        let message = e.to_string();
        if let Some(said) = bad_vector(xml, &message) {
            return UrdfProblem::Parse(said).in_file(file);
        }
        let where_ = unbalanced_tag(xml).map_or(String::new(), |w| format!(" ({w})"));
        UrdfProblem::Parse(format!("{message}{where_}")).in_file(file)
    })?;
    let mut tree = robot_to_tree(&robot).map_err(|p| p.in_file(file))?;
    if let Some(dir) = base_dir {
        load_mesh_bounds(&mut tree, dir);
    }
    Ok(tree)
}

/// Reads and converts a URDF file (a regular file of UTF-8 text: [`crate::input::read_text`]);
/// errors name the file.
pub fn read_urdf_file(path: &Path) -> Result<KinematicTree, UrdfError> {
    let file = path.display().to_string();
    let xml = crate::input::read_text(path).map_err(|e| UrdfProblem::Io(e.to_string()).in_file(&file))?;
    let mut tree = parse_urdf(&xml, &file, path.parent())?;
    tree.source = Some(path.to_path_buf());
    Ok(tree)
}

const KNOWN_TYPES: [&str; 7] = [
    "revolute",
    "continuous",
    "prismatic",
    "fixed",
    "floating",
    "planar",
    "spherical",
];

/// `(name, type)` of every `<joint … type="…">` tag of `text`, a file [`without_comments`]
/// (transmission `<joint>` tags have no type and are skipped). urdf-rs would otherwise only say
/// "unknown variant".
fn scan_joint_types(text: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(start) = rest.find("<joint") {
        rest = &rest[start + 6..];
        if !rest.starts_with(|c: char| c.is_whitespace()) {
            continue;
        }
        let tag = &rest[..rest.find('>').unwrap_or(rest.len())];
        if let Some(kind) = attribute(tag, "type") {
            out.push((attribute(tag, "name").unwrap_or_default(), kind));
        }
    }
    out
}

/// `xml` with its comments blanked out, line breaks kept (so that lines keep their numbers).
fn without_comments(xml: &str) -> String {
    let mut text = String::with_capacity(xml.len());
    let mut rest = xml;
    while let Some(start) = rest.find("<!--") {
        text.push_str(&rest[..start]);
        let end = rest[start..].find("-->").map_or(rest.len(), |end| start + end + 3);
        text.extend(rest[start..end].chars().filter(|&c| c == '\n'));
        rest = &rest[end..];
    }
    text.push_str(rest);
    text
}

/// The line and text of the first xacro construct in `text`, a file [`without_comments`]: a
/// `<xacro:…>` element, a `${…}` expression or a `$(…)` substitution. urdf-rs skips unknown elements,
/// so an unexpanded xacro file read as a URDF became a robot of one link.
fn xacro_use(text: &str) -> Option<(usize, String)> {
    let at = ["<xacro:", "${", "$("].iter().filter_map(|k| text.find(k)).min()?;
    let line = text[..at].matches('\n').count() + 1;
    let what: String = text[at..].chars().take_while(|&c| c != '\n').take(40).collect();
    Some((line, what.trim_end().to_string()))
}

/// urdf-rs's "Wrong vector element count, expected 3 found 0 for [0.3,0.06,0]" said again with the
/// line of the value and what is wrong with it (commas, a xacro expression, a missing number).
fn bad_vector(xml: &str, message: &str) -> Option<String> {
    let rest = message.split("Wrong vector element count, expected ").nth(1)?;
    let (want, rest) = rest.split_once(" found ")?;
    let (found, value) = rest.split_once(" for [")?;
    let value = value.rsplit_once(']')?.0;
    let line = ["\"", "'"]
        .iter()
        .find_map(|q| xml.find(&format!("{q}{value}{q}")))
        .map(|at| xml[..at].matches('\n').count() + 1)?;
    let hint = if value.contains(',') { "; URDF separates numbers by spaces, not commas" } else { "" };
    Some(format!("line {line}: `{value}` is not {want} numbers separated by spaces ({found} read as numbers){hint}"))
}

/// The line and joint of the first `<limit>` without a `velocity` in `text`, a file
/// [`without_comments`], which URDF requires (urdf-rs says only "missing field `velocity`", naming
/// neither).
fn limit_without_velocity(text: &str) -> Option<(usize, String)> {
    let mut at = 0;
    while let Some(i) = text[at..].find("<joint") {
        let start = at + i;
        let end = text[start..].find("</joint>").map_or(text.len(), |e| start + e);
        let body = &text[start..end];
        at = end.max(start + 6);
        let Some(l) = body.find("<limit") else { continue };
        let tag = &body[l..body[l..].find('>').map_or(body.len(), |e| l + e)];
        if attribute(tag, "velocity").is_none() {
            let name = attribute(&body[..body.find('>').unwrap_or(body.len())], "name").unwrap_or_default();
            return Some((text[..start + l].matches('\n').count() + 1, name));
        }
    }
    None
}

/// Where the tags of `xml` stop balancing, when they do: an end tag that closes nothing or another
/// element, or elements still open at the end of the file (a truncated file). The XML reader's own
/// message gives no position for those.
fn unbalanced_tag(xml: &str) -> Option<String> {
    let line_col = |at: usize| {
        let before = &xml[..at];
        let line = before.matches('\n').count() + 1;
        let col = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
        (line, col)
    };
    let mut open: Vec<(&str, usize)> = Vec::new();
    let mut at = 0;
    while let Some(i) = xml[at..].find('<') {
        let start = at + i;
        let rest = &xml[start..];
        let skip = if rest.starts_with("<!--") {
            Some("-->")
        } else if rest.starts_with("<![CDATA[") {
            Some("]]>")
        } else if rest.starts_with("<?") || rest.starts_with("<!") {
            Some(">")
        } else {
            None
        };
        if let Some(end) = skip {
            match rest.find(end) {
                Some(e) => at = start + e + end.len(),
                None => {
                    let (l, c) = line_col(start);
                    return Some(format!("the file ends inside the construct opened at line {l}, column {c}"));
                }
            }
            continue;
        }
        let Some(e) = rest.find('>') else {
            let (l, c) = line_col(start);
            return Some(format!("the file ends inside the tag opened at line {l}, column {c}"));
        };
        let tag = &rest[1..e];
        at = start + e + 1;
        let name_of = |t: &str| t.split(|c: char| c.is_whitespace() || c == '/').next().unwrap_or("").to_string();
        if let Some(closing) = tag.strip_prefix('/') {
            let name = closing.trim();
            match open.pop() {
                Some((o, _)) if o == name => {}
                Some((o, ol)) => {
                    let (l, c) = line_col(start);
                    let (l2, c2) = line_col(ol);
                    return Some(format!(
                        "`</{name}>` at line {l}, column {c} does not close `<{o}>` opened at line {l2}, column {c2}"
                    ));
                }
                None => {
                    let (l, c) = line_col(start);
                    return Some(format!("`</{name}>` at line {l}, column {c} closes no element"));
                }
            }
        } else if !tag.ends_with('/') {
            let name = name_of(tag);
            let name_start = start + 1;
            open.push((&xml[name_start..name_start + name.len()], start));
        }
    }
    let (o, ol) = open.last()?;
    let (l, c) = line_col(*ol);
    let (el, ec) = line_col(xml.len());
    Some(format!(
        "the file ends at line {el}, column {ec} with `<{o}>` (line {l}, column {c}) still open: is it truncated?"
    ))
}

/// Value of attribute `name` in the inside of a start tag.
fn attribute(tag: &str, name: &str) -> Option<String> {
    let mut rest = tag;
    while let Some(i) = rest.find(name) {
        let before_ok = i == 0 || rest[..i].ends_with(|c: char| c.is_whitespace());
        let after = rest[i + name.len()..].trim_start();
        rest = &rest[i + name.len()..];
        if !before_ok {
            continue;
        }
        if let Some(after) = after.strip_prefix('=') {
            let after = after.trim_start();
            let quote = after.chars().next()?;
            if quote == '"' || quote == '\'' {
                let body = &after[1..];
                return body.find(quote).map(|end| body[..end].to_string());
            }
        }
    }
    None
}

/// Largest length a URDF may give (m): an origin's offset, a shape's size.
pub const MAX_LENGTH_M: f32 = 1000.0;

/// `v` as f32, checked after the conversion (`1e39` is finite as f64 and infinite as f32).
fn finite3(v: &urdf_rs::Vec3, what: impl Fn() -> String) -> Result<Vector3<f32>, UrdfProblem> {
    let f = Vector3::new(v[0] as f32, v[1] as f32, v[2] as f32);
    if f.iter().all(|x| x.is_finite()) {
        Ok(f)
    } else {
        Err(UrdfProblem::NonFinite(what()))
    }
}

/// `v` as f32, checked after the conversion.
fn finite(v: f64, what: impl Fn() -> String) -> Result<f32, UrdfProblem> {
    let f = v as f32;
    if f.is_finite() {
        Ok(f)
    } else {
        Err(UrdfProblem::NonFinite(what()))
    }
}

/// `v` as a length of at most [`MAX_LENGTH_M`] in magnitude; a size (`positive`) must also be above 0.
fn length(v: f32, positive: bool, what: impl Fn() -> String) -> Result<f32, UrdfProblem> {
    if v.abs() <= MAX_LENGTH_M && (!positive || v > 0.0) {
        return Ok(v);
    }
    let valid = if positive {
        format!("a size must be greater than 0 and at most {MAX_LENGTH_M} m")
    } else {
        format!("an offset must be at most {MAX_LENGTH_M} m along each axis")
    };
    Err(UrdfProblem::OutOfRange { what: what(), value: v, valid })
}

/// URDF `<origin xyz rpy>` → isometry (rpy fixed-axis XYZ: R = Rz(y)·Ry(p)·Rx(r)).
pub fn pose_to_isometry(pose: &urdf_rs::Pose, what: &str) -> Result<Isometry3<f32>, UrdfProblem> {
    let t = finite3(&pose.xyz, || format!("the origin xyz of {what}"))?;
    for v in t.iter() {
        length(*v, false, || format!("the origin xyz of {what}"))?;
    }
    let r = finite3(&pose.rpy, || format!("the origin rpy of {what}"))?;
    Ok(Isometry3::from_parts(Translation3::from(t), rpy_to_quat(r.x, r.y, r.z)))
}

/// Roll-pitch-yaw (fixed axes X, Y, Z) → quaternion: R = Rz(yaw)·Ry(pitch)·Rx(roll).
pub fn rpy_to_quat(roll: f32, pitch: f32, yaw: f32) -> UnitQuaternion<f32> {
    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw)
        * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), pitch)
        * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), roll)
}

impl TryFrom<&urdf_rs::Geometry> for Shape {
    type Error = UrdfProblem;
    fn try_from(g: &urdf_rs::Geometry) -> Result<Self, UrdfProblem> {
        fn nf(what: &'static str) -> impl Fn() -> String {
            move || format!("{what} geometry")
        }
        let size = |v: f64, what: &'static str| length(finite(v, nf(what))?, true, nf(what));
        Ok(match g {
            urdf_rs::Geometry::Box { size: s } => {
                let s = finite3(s, nf("the size of box"))?;
                for v in s.iter() {
                    length(*v, true, nf("the size of box"))?;
                }
                Shape::Box { size: s }
            }
            urdf_rs::Geometry::Cylinder { radius, length } => Shape::Cylinder {
                radius: size(*radius, "the radius of cylinder")?,
                length: size(*length, "the length of cylinder")?,
            },
            urdf_rs::Geometry::Capsule { radius, length } => Shape::Capsule {
                radius: size(*radius, "the radius of capsule")?,
                length: size(*length, "the length of capsule")?,
            },
            urdf_rs::Geometry::Sphere { radius } => Shape::Sphere {
                radius: size(*radius, "the radius of sphere")?,
            },
            urdf_rs::Geometry::Mesh { filename, scale } => Shape::Mesh {
                filename: filename.clone(),
                scale: match scale {
                    Some(s) => {
                        let s = finite3(s, || format!("the scale of mesh {filename}"))?;
                        if s.iter().any(|v| *v == 0.0) {
                            return Err(UrdfProblem::OutOfRange {
                                what: format!("the scale of mesh {filename}"),
                                value: s.iter().copied().find(|v| *v == 0.0).unwrap_or(0.0),
                                valid: "a mesh's scale must be nonzero along each axis".into(),
                            });
                        }
                        s
                    }
                    None => Vector3::repeat(1.0),
                },
                bounds: None,
            },
        })
    }
}

fn geometry(origin: &urdf_rs::Pose, g: &urdf_rs::Geometry, what: &str) -> Result<Geometry, UrdfProblem> {
    let shape = Shape::try_from(g).map_err(|e| match e {
        UrdfProblem::NonFinite(s) => UrdfProblem::NonFinite(format!("{s} of {what}")),
        UrdfProblem::OutOfRange { what: w, value, valid } => UrdfProblem::OutOfRange { what: format!("{w} of {what}"), value, valid },
        e => e,
    })?;
    Ok(Geometry {
        origin: pose_to_isometry(origin, what)?,
        shape,
    })
}

impl TryFrom<&urdf_rs::Link> for Link {
    type Error = UrdfProblem;
    /// Converts geometry and mass; `parent` and `joint` are filled in by the tree builder.
    fn try_from(l: &urdf_rs::Link) -> Result<Self, UrdfProblem> {
        let what = |kind: &str| format!("a {kind} of link `{}`", l.name);
        Ok(Link {
            name: l.name.clone(),
            parent: None,
            joint: None,
            visuals: l
                .visual
                .iter()
                .map(|v| geometry(&v.origin, &v.geometry, &what("visual")))
                .collect::<Result<_, _>>()?,
            collisions: l
                .collision
                .iter()
                .map(|c| geometry(&c.origin, &c.geometry, &what("collision")))
                .collect::<Result<_, _>>()?,
            mass: finite(l.inertial.mass.value, || format!("the mass of link `{}`", l.name))?,
        })
    }
}

/// Converts one joint. Returns the spec (DoF and mimic unresolved) and, for floating/planar joints,
/// a warning. DoF indices and mimic targets are resolved by the tree builder.
pub fn convert_joint(j: &urdf_rs::Joint) -> Result<(JointSpec, Option<String>), UrdfProblem> {
    use urdf_rs::JointType as T;
    let mut warning = None;
    let kind = match j.joint_type {
        T::Revolute => JointKind::Revolute,
        T::Continuous => JointKind::Continuous,
        T::Prismatic => JointKind::Prismatic,
        T::Fixed => JointKind::Fixed,
        T::Floating | T::Planar => {
            warning = Some(format!(
                "joint `{}` is {:?}; it is treated as fixed (the character root is free already)",
                j.name, j.joint_type
            ));
            JointKind::Fixed
        }
        T::Spherical => {
            return Err(UrdfProblem::UnsupportedJointType {
                joint: j.name.clone(),
                kind: "spherical".into(),
            });
        }
    };
    let origin = pose_to_isometry(&j.origin, &format!("joint `{}`", j.name))?;
    let axis = if kind == JointKind::Fixed {
        Vector3::x_axis()
    } else {
        let a = finite3(&j.axis.xyz, || format!("the axis of joint `{}`", j.name))?;
        Unit::try_new(a, 1e-9).ok_or_else(|| UrdfProblem::ZeroAxis(j.name.clone()))?
    };
    let l = &j.limit;
    for (v, n) in [
        (l.lower, "lower"),
        (l.upper, "upper"),
        (l.velocity, "velocity"),
        (l.effort, "effort"),
    ] {
        if v.is_nan() {
            return Err(UrdfProblem::NonFinite(format!("the {n} limit of joint `{}`", j.name)));
        }
    }
    let given = |v: f64| if v > 0.0 { v as f32 } else { f32::INFINITY };
    let limits = match kind {
        JointKind::Fixed => None,
        JointKind::Continuous => Some(Limits {
            lower: f32::NEG_INFINITY,
            upper: f32::INFINITY,
            velocity: given(l.velocity),
            effort: given(l.effort),
        }),
        JointKind::Revolute | JointKind::Prismatic => {
            if l.lower > l.upper {
                return Err(UrdfProblem::InvertedLimits {
                    joint: j.name.clone(),
                    lower: l.lower,
                    upper: l.upper,
                });
            }
            if l.lower == 0.0 && l.upper == 0.0 {
                warning = Some(format!(
                    "joint `{}` has lower = upper = 0 (or no <limit>); it cannot move",
                    j.name
                ));
            }
            Some(Limits {
                lower: l.lower as f32,
                upper: l.upper as f32,
                velocity: given(l.velocity),
                effort: given(l.effort),
            })
        }
    };
    Ok((
        JointSpec {
            name: j.name.clone(),
            kind,
            origin,
            axis,
            limits,
            dof: None,
            mimic: None,
        },
        warning,
    ))
}

/// The most links a URDF may have. Real robots have tens to a few hundred; every link (and its DoF)
/// becomes a column of each dataset frame and a body of every collision check, so a file with
/// 100,000 links would take gigabytes before any error could be given.
pub const MAX_LINKS: usize = 1024;

/// Builds the tree: checks names and topology, orders links depth-first from the root, assigns DoFs
/// and resolves mimic joints.
pub fn robot_to_tree(robot: &urdf_rs::Robot) -> Result<KinematicTree, UrdfProblem> {
    if robot.links.is_empty() {
        return Err(UrdfProblem::NoLinks);
    }
    if robot.links.len() > MAX_LINKS {
        return Err(UrdfProblem::TooManyLinks { links: robot.links.len() });
    }
    let mut link_ix: HashMap<&str, usize> = HashMap::new();
    for (i, l) in robot.links.iter().enumerate() {
        if link_ix.insert(&l.name, i).is_some() {
            return Err(UrdfProblem::DuplicateLink(l.name.clone()));
        }
    }
    let mut joint_names: HashMap<&str, usize> = HashMap::new();
    // parent_joint[link] = index of the joint whose child it is.
    let mut parent_joint: Vec<Option<usize>> = vec![None; robot.links.len()];
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); robot.links.len()];
    for (ji, j) in robot.joints.iter().enumerate() {
        if joint_names.insert(&j.name, ji).is_some() {
            return Err(UrdfProblem::DuplicateJoint(j.name.clone()));
        }
        let p = *link_ix
            .get(j.parent.link.as_str())
            .ok_or_else(|| UrdfProblem::MissingParent {
                joint: j.name.clone(),
                link: j.parent.link.clone(),
            })?;
        let c = *link_ix
            .get(j.child.link.as_str())
            .ok_or_else(|| UrdfProblem::MissingChild {
                joint: j.name.clone(),
                link: j.child.link.clone(),
            })?;
        if let Some(other) = parent_joint[c] {
            return Err(UrdfProblem::SeveralParents {
                link: j.child.link.clone(),
                joints: vec![robot.joints[other].name.clone(), j.name.clone()],
            });
        }
        parent_joint[c] = Some(ji);
        children[p].push(c);
    }
    let roots: Vec<usize> = (0..robot.links.len()).filter(|&l| parent_joint[l].is_none()).collect();
    if roots.len() > 1 {
        return Err(UrdfProblem::MultipleRoots {
            links: roots.iter().map(|&l| robot.links[l].name.clone()).collect(),
        });
    }
    // Depth-first order from the root; anything unreached lies on (or hangs off) a cycle.
    let mut order = Vec::with_capacity(robot.links.len());
    let mut seen = vec![false; robot.links.len()];
    if let Some(&root) = roots.first() {
        let mut stack = vec![root];
        while let Some(l) = stack.pop() {
            order.push(l);
            seen[l] = true;
            stack.extend(children[l].iter().rev());
        }
    }
    if let Some(start) = (0..robot.links.len()).find(|&l| !seen[l]) {
        // Every unreached link has a parent; following parents must revisit a link: that loop is the cycle.
        let mut path = vec![start];
        let mut l = start;
        while let Some(j) = parent_joint[l] {
            l = link_ix[robot.joints[j].parent.link.as_str()];
            if let Some(pos) = path.iter().position(|&x| x == l) {
                // Parent → child order, starting at the link defined first in the file.
                let mut cyc: Vec<usize> = path[pos..].iter().rev().copied().collect();
                let first = (0..cyc.len()).min_by_key(|&i| cyc[i]).unwrap_or(0);
                cyc.rotate_left(first);
                cyc.push(cyc[0]);
                let cyc = cyc.into_iter().map(|x| robot.links[x].name.clone()).collect();
                return Err(UrdfProblem::Cycle { links: cyc });
            }
            path.push(l);
        }
        return Err(UrdfProblem::NoRoot);
    }
    // Frames above the body: root links without geometry, each holding only the next by a fixed
    // joint (or a free one, frozen), down to a link with geometry, as ROS's `base_footprint` and
    // `world` links do. The character's root is that body: the controllers move the root and the
    // state holds its pose, so a frame at the ground made the body pitch about the ground and scaled
    // its crouch by a standing height of zero. (Without geometry below, the links' origins are all the
    // robot has: none is dropped.)
    let shapeless = |l: usize| robot.links[l].visual.is_empty() && robot.links[l].collision.is_empty();
    let mut frames = 0;
    while let [l, c, ..] = order[frames..] {
        let joint = &robot.joints[parent_joint[c].expect("a child")];
        use urdf_rs::JointType as T;
        if !(shapeless(l) && children[l].len() == 1 && matches!(joint.joint_type, T::Fixed | T::Floating | T::Planar)) {
            break;
        }
        // Checked as if kept: a value the file gets wrong is an error wherever it is.
        Link::try_from(&robot.links[l])?;
        convert_joint(joint)?;
        frames += 1;
    }
    if order.get(frames).is_some_and(|&body| shapeless(body)) {
        frames = 0;
    }
    let root = &robot.links[order[frames]].name;
    let warnings: Vec<String> = order[..=frames]
        .windows(2)
        .map(|w| {
            let (l, c) = (w[0], w[1]);
            let joint = &robot.joints[parent_joint[c].expect("a child")];
            format!(
                "root link `{}` has no geometry and holds `{}` by its {} joint `{}`: it is a frame, and the \
                 character's root is `{root}`",
                robot.links[l].name,
                robot.links[c].name,
                format!("{:?}", joint.joint_type).to_lowercase(),
                joint.name,
            )
        })
        .collect();
    let order = &order[frames..];

    let mut new_ix = vec![0usize; robot.links.len()];
    for (n, &l) in order.iter().enumerate() {
        new_ix[l] = n;
    }
    let mut links = Vec::with_capacity(order.len());
    let mut warnings = warnings;
    let mut dof_links = Vec::new();
    let mut mimics: Vec<(usize, &urdf_rs::Mimic)> = Vec::new();
    for &l in order {
        let mut link = Link::try_from(&robot.links[l])?;
        if let Some(ji) = parent_joint[l].filter(|_| l != order[0]) {
            let j = &robot.joints[ji];
            if matches!(j.joint_type, urdf_rs::JointType::Floating | urdf_rs::JointType::Planar) {
                // Only an anchor from a root link without geometry (a `world` link) may be frozen: below
                // a body link, freezing a free joint changes the robot.
                let p = link_ix[j.parent.link.as_str()];
                let anchor = parent_joint[p].is_none()
                    && robot.links[p].visual.is_empty()
                    && robot.links[p].collision.is_empty();
                if !anchor {
                    return Err(UrdfProblem::FreeJointInBody {
                        joint: j.name.clone(),
                        kind: format!("{:?}", j.joint_type).to_lowercase(),
                        parent: j.parent.link.clone(),
                        child: j.child.link.clone(),
                    });
                }
            }
            let (mut spec, warning) = convert_joint(j)?;
            warnings.extend(warning);
            link.parent = Some(new_ix[link_ix[j.parent.link.as_str()]]);
            if let (Some(m), true) = (&j.mimic, spec.kind.is_movable()) {
                mimics.push((links.len(), m));
            } else if spec.kind.is_movable() {
                spec.dof = Some(dof_links.len());
                dof_links.push(links.len());
            }
            link.joint = Some(spec);
        }
        links.push(link);
    }
    for (li, m) in mimics {
        let target = links
            .iter()
            .find(|t| t.joint.as_ref().is_some_and(|j| j.name == m.joint));
        let dof = target.and_then(|t| t.joint.as_ref()).and_then(|j| j.dof);
        let joint = links[li].joint.as_mut().expect("mimic joints are joints");
        let Some(dof) = dof else {
            return Err(UrdfProblem::BadMimic {
                joint: joint.name.clone(),
                target: m.joint.clone(),
            });
        };
        let multiplier = finite(m.multiplier.unwrap_or(1.0), || {
            format!("the mimic multiplier of `{}`", joint.name)
        })?;
        let offset = finite(m.offset.unwrap_or(0.0), || {
            format!("the mimic offset of `{}`", joint.name)
        })?;
        joint.mimic = Some(Mimic {
            dof,
            multiplier,
            offset,
        });
    }
    Ok(KinematicTree::from_parts(robot.name.clone(), links, warnings))
}

/// Where a mesh `filename` from a URDF in `base_dir` lives on disk, if it can be found:
/// `package://pkg/rest` is looked for as `A/rest` for an ancestor `A` of `base_dir` named `pkg`, or as
/// `A/pkg/rest` for any ancestor `A`; `file://` paths are taken as they are; other paths are relative
/// to `base_dir`.
pub fn resolve_mesh_path(filename: &str, base_dir: &Path) -> Option<PathBuf> {
    let found = |p: PathBuf| p.is_file().then_some(p);
    if let Some(rest) = filename.strip_prefix("package://") {
        let (pkg, rel) = rest.split_once('/')?;
        for a in base_dir.ancestors() {
            if a.file_name().is_some_and(|n| n == pkg)
                && let Some(p) = found(a.join(rel))
            {
                return Some(p);
            }
            if let Some(p) = found(a.join(pkg).join(rel)) {
                return Some(p);
            }
        }
        None
    } else if let Some(abs) = filename.strip_prefix("file://") {
        found(PathBuf::from(abs))
    } else {
        found(base_dir.join(filename))
    }
}

/// The mesh files the URDF at `path` names that are found on disk ([`resolve_mesh_path`]), each once,
/// in the order the links give them, with the material files (`mtllib`) of OBJ meshes: what reading
/// the character reads besides the URDF (commands register them as inputs, never to be written
/// over). Empty when the URDF cannot be read.
pub fn mesh_files(path: &Path) -> Vec<PathBuf> {
    let Ok(xml) = crate::input::read_text(path) else {
        return Vec::new();
    };
    let Ok(tree) = parse_urdf(&xml, &path.display().to_string(), None) else {
        return Vec::new();
    };
    let base = path.parent().unwrap_or(Path::new("."));
    let mut files: Vec<PathBuf> = Vec::new();
    for link in &tree.links {
        for g in link.visuals.iter().chain(&link.collisions) {
            if let Shape::Mesh { filename, .. } = &g.shape
                && let Some(p) = resolve_mesh_path(filename, base)
                && !files.contains(&p)
            {
                let materials = obj_material_files(&p);
                files.push(p);
                for m in materials {
                    if m.is_file() && !files.contains(&m) {
                        files.push(m);
                    }
                }
            }
        }
    }
    files
}

/// The material files an OBJ mesh names (`mtllib a.mtl b.mtl`), relative to its folder; none for
/// other formats.
fn obj_material_files(mesh: &Path) -> Vec<PathBuf> {
    use std::io::BufRead;
    if !mesh.extension().is_some_and(|e| e.eq_ignore_ascii_case("obj")) {
        return Vec::new();
    }
    let Ok(f) = std::fs::File::open(mesh) else {
        return Vec::new();
    };
    let dir = mesh.parent().unwrap_or(Path::new("."));
    std::io::BufReader::new(f)
        .split(b'\n')
        .map_while(Result::ok)
        .filter_map(|line| {
            let line = String::from_utf8_lossy(&line).into_owned();
            line.trim_start().strip_prefix("mtllib").map(|rest| rest.split_whitespace().map(|m| dir.join(m)).collect::<Vec<_>>())
        })
        .flatten()
        .collect()
}

/// Fills in `bounds` of every mesh whose file can be found and read; warns about the others.
fn load_mesh_bounds(tree: &mut KinematicTree, base_dir: &Path) {
    let mut cache: HashMap<String, Option<crate::geometry::Aabb>> = HashMap::new();
    let mut missing = Vec::new();
    for link in &mut tree.links {
        for g in link.visuals.iter_mut().chain(link.collisions.iter_mut()) {
            if let Shape::Mesh { filename, bounds, .. } = &mut g.shape {
                *bounds = *cache.entry(filename.clone()).or_insert_with(|| {
                    let b = resolve_mesh_path(filename, base_dir).and_then(|p| read_mesh_bounds(&p).ok());
                    if b.is_none() {
                        missing.push(filename.clone());
                    }
                    b
                });
            }
        }
    }
    if !missing.is_empty() {
        tree.warnings.push(format!(
            "{} mesh file(s) not found or not readable as STL, OBJ or Collada (they have no extent): {}",
            missing.len(),
            missing.join(", ")
        ));
    }
    // A mesh in millimetres without `scale="0.001 0.001 0.001"` made an 80 m robot, or hid its feet.
    let mut huge: Vec<String> = Vec::new();
    for g in tree.links.iter().flat_map(|l| l.visuals.iter().chain(&l.collisions)) {
        if let Shape::Mesh { filename, scale, bounds: Some(b) } = &g.shape {
            let size = (b.max - b.min).component_mul(&scale.abs()).max();
            let note = format!("{filename} ({size:.0} m)");
            if size > MAX_MESH_SIZE_M && !huge.contains(&note) {
                huge.push(note);
            }
        }
    }
    if !huge.is_empty() {
        tree.warnings.push(format!(
            "mesh file(s) larger than {MAX_MESH_SIZE_M} m across with their scale: {}; a mesh in millimetres needs \
             scale=\"0.001 0.001 0.001\" on its <mesh>",
            huge.join(", ")
        ));
    }
}

/// The largest extent (metres, after its `scale`) a URDF mesh has without a warning.
pub const MAX_MESH_SIZE_M: f32 = 20.0;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rpy_is_fixed_axis_xyz() {
        let (r, p, y) = (0.3f32, -0.7, 1.1);
        let q = rpy_to_quat(r, p, y);
        let rx = nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), r);
        let ry = nalgebra::Rotation3::from_axis_angle(&Vector3::y_axis(), p);
        let rz = nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), y);
        let m = rz * ry * rx;
        assert!((q.to_rotation_matrix().matrix() - m.matrix()).norm() < 1e-5);
        let n = UnitQuaternion::from_euler_angles(r, p, y);
        assert!(q.angle_to(&n) < 1e-5);
    }

    #[test]
    fn joint_type_scan_skips_comments_and_transmissions() {
        // The second comment ends in two-byte characters right before `-->`.
        let xml = r#"<robot><!-- <joint name="x" type="bogus"/> --><!-- genou «plié»-->
            <joint name="a" type='revolute'><parent link="p"/></joint>
            <transmission><joint name="a"><hardwareInterface/></joint></transmission>
            <joint  type="ball"   name="b"/></robot>"#;
        assert_eq!(
            scan_joint_types(&without_comments(xml)),
            vec![
                ("a".to_string(), "revolute".to_string()),
                ("b".to_string(), "ball".to_string())
            ]
        );
    }

    /// An ASCII STL of one triangle reaching to (1, 2, 3).
    const TRIANGLE_STL: &str = "solid a\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 2 3\nvertex 1 0 0\nendloop\nendfacet\nendsolid a\n";

    /// Empty `<link>` elements named `names`.
    fn links(names: &[&str]) -> String {
        names.iter().map(|l| format!(r#"<link name="{l}"/>"#)).collect()
    }

    /// A mesh in millimetres without its scale made an 80 m robot without a word.
    #[test]
    fn a_mesh_larger_than_a_robot_can_be_is_warned_of() {
        let dir = std::env::temp_dir().join(format!("ace_urdf_mesh_size_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("a.stl"), TRIANGLE_STL).unwrap();
        let with_scale = |s: &str| {
            let urdf = dir.join(format!("r{s}.urdf"));
            let mesh = format!(r#"<geometry><mesh filename="a.stl" scale="{s} {s} {s}"/></geometry>"#);
            std::fs::write(&urdf, format!(r#"<robot name="r"><link name="base"><visual>{mesh}</visual><collision>{mesh}</collision></link></robot>"#)).unwrap();
            KinematicTree::from_urdf_file(&urdf).unwrap().warnings
        };
        // The triangle reaches 3 units up: 3 m, then 30 m.
        assert!(with_scale("1").iter().all(|w| !w.contains("larger than")), "{:?}", with_scale("1"));
        let w = with_scale("10");
        assert!(w.iter().any(|w| w == "mesh file(s) larger than 20 m across with their scale: a.stl (30 m); a mesh in millimetres needs scale=\"0.001 0.001 0.001\" on its <mesh>"), "{w:?}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn package_paths_resolve_against_ancestors() {
        let dir = std::env::temp_dir().join(format!("ace_urdf_pkg_{}", std::process::id()));
        let mesh = dir.join("my_pkg/meshes/a.stl");
        std::fs::create_dir_all(mesh.parent().unwrap()).unwrap();
        std::fs::write(&mesh, TRIANGLE_STL).unwrap();
        let urdf_dir = dir.join("my_pkg/urdf");
        std::fs::create_dir_all(&urdf_dir).unwrap();
        assert_eq!(
            resolve_mesh_path("package://my_pkg/meshes/a.stl", &urdf_dir),
            Some(mesh.clone())
        );
        assert_eq!(
            resolve_mesh_path("package://my_pkg/meshes/a.stl", &dir),
            Some(mesh.clone())
        );
        assert_eq!(
            resolve_mesh_path("../meshes/a.stl", &urdf_dir),
            Some(urdf_dir.join("../meshes/a.stl"))
        );
        let b = read_mesh_bounds(&mesh).unwrap();
        assert_eq!(b.max, nalgebra::Point3::new(1.0, 2.0, 3.0));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn unbalanced_tags_are_placed_by_line_and_column() {
        let cases = [
            (
                "<robot>\n  <link name=\"a\">\n  </joint>\n</robot>",
                Some("`</joint>` at line 3, column 3 does not close `<link>` opened at line 2, column 3"),
            ),
            ("<robot/>\n</robot>", Some("`</robot>` at line 2, column 1 closes no element")),
            (
                "<robot>\n  <!-- a comment that never ends\n</robot>",
                Some("the file ends inside the construct opened at line 2, column 3"),
            ),
            ("<robot>\n  <link name=\"a\"", Some("the file ends inside the tag opened at line 2, column 3")),
            (
                "<robot>\n<link>",
                Some("the file ends at line 2, column 7 with `<link>` (line 2, column 1) still open: is it truncated?"),
            ),
            // Declarations, comments and character data hold no tags, and what follows them is read
            // from their very end.
            ("<?xml version=\"1.0\"?>\n<robot>\n  <!-- </a> -->\n  <![CDATA[ </b> ]]>\n  <link/>\n</robot>\n", None),
            ("<robot>\n  <!-- where x<2 -->\n  <link name=\"base\">\n  </link>\n</robot>", None),
            ("<robot>\n  <!-- base -->\n  <link name=\"base\">\n    <visual/>\n  </link>\n</robot>", None),
        ];
        for (xml, want) in cases {
            assert_eq!(unbalanced_tag(xml).as_deref(), want, "{xml}");
        }
    }

    #[test]
    fn attributes_are_read_by_their_whole_name_in_either_quotes() {
        let tag = r#"joint subtype="x" name = 'hip'  type= "revolute""#;
        assert_eq!(attribute(tag, "type").as_deref(), Some("revolute"));
        assert_eq!(attribute(tag, "name").as_deref(), Some("hip"));
        assert_eq!(attribute(tag, "subtype").as_deref(), Some("x"));
        assert_eq!(attribute(r#"type="a""#, "type").as_deref(), Some("a"), "at the start of the tag");
        assert_eq!(attribute(r#"type="""#, "type").as_deref(), Some(""));
        assert_eq!(attribute("type=revolute", "type"), None, "unquoted");
        assert_eq!(attribute(r#"type="revolute"#, "type"), None, "unterminated");
        assert_eq!(attribute(r#"typed="a" type"#, "type"), None, "no value");
        assert_eq!(attribute(r#"name="a""#, "type"), None);
    }

    fn problem(xml: &str) -> UrdfProblem {
        parse_urdf(xml, STRING_SOURCE, None).map(|_| ()).unwrap_err().problem
    }

    #[test]
    fn links_are_ordered_depth_first_and_mimics_follow_a_joint_with_its_own_dof() {
        let limit = r#"<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/>"#;
        let joint = |name: &str, kind: &str, parent: &str, child: &str, extra: &str| {
            format!(r#"<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>{limit}{extra}</joint>"#)
        };
        let xml = format!(
            r#"<robot name="r">{}{}{}{}{}{}</robot>"#,
            links(&["base", "c", "b", "a", "m", "n"]),
            joint("ja", "revolute", "base", "a", ""),
            joint("jb", "prismatic", "base", "b", ""),
            joint("jc", "revolute", "b", "c", ""),
            joint("jm", "revolute", "a", "m", r#"<mimic joint="jc"/>"#),
            joint("jn", "fixed", "a", "n", r#"<mimic joint="ja"/>"#),
        );
        let tree = parse_urdf(&xml, STRING_SOURCE, None).unwrap();
        let names: Vec<&str> = tree.links.iter().map(|l| l.name.as_str()).collect();
        assert_eq!(names, ["base", "a", "m", "n", "b", "c"], "children in the order of their joints");
        assert_eq!(tree.dof_names(), ["ja", "jb", "jc"]);
        let jm = tree.links[2].joint.as_ref().unwrap();
        assert_eq!((jm.dof, jm.mimic), (None, Some(Mimic { dof: 2, multiplier: 1.0, offset: 0.0 })));
        let jn = tree.links[3].joint.as_ref().unwrap();
        assert_eq!((jn.dof, jn.mimic), (None, None), "a fixed joint's <mimic> is ignored");
        assert_eq!(tree.links[5].parent, Some(4));
        // A mimic of a fixed joint, of itself (a mimic) or of no joint at all.
        for target in ["jn", "jm", "nowhere"] {
            let bad = xml.replace(r#"<mimic joint="jc"/>"#, &format!(r#"<mimic joint="{target}"/>"#));
            let want = UrdfProblem::BadMimic { joint: "jm".into(), target: target.into() };
            assert_eq!(problem(&bad), want);
        }
    }

    #[test]
    fn topology_errors_name_the_links_and_joints() {
        let fixed = |name: &str, parent: &str, child: &str| {
            format!(r#"<joint name="{name}" type="fixed"><parent link="{parent}"/><child link="{child}"/></joint>"#)
        };
        // A cycle beside the root is listed parent to child from the link the file defines first.
        let cycle = format!(
            r#"<robot name="r">{}{}{}{}</robot>"#,
            links(&["root", "c", "a", "b"]),
            fixed("j1", "a", "b"),
            fixed("j2", "b", "c"),
            fixed("j3", "c", "a"),
        );
        assert_eq!(problem(&cycle), UrdfProblem::Cycle { links: ["c", "a", "b", "c"].map(String::from).to_vec() });
        let two_parents = format!(r#"<robot name="r">{}{}{}</robot>"#, links(&["a", "b", "c"]), fixed("j1", "a", "c"), fixed("j2", "b", "c"));
        assert_eq!(
            problem(&two_parents).to_string(),
            "link `c` is the child of several joints: j1, j2"
        );
        let same_name = format!(r#"<robot name="r">{}{}{}</robot>"#, links(&["a", "b", "c"]), fixed("j", "a", "b"), fixed("j", "a", "c"));
        assert_eq!(problem(&same_name), UrdfProblem::DuplicateJoint("j".into()));
        let no_parent = format!(r#"<robot name="r">{}{}</robot>"#, links(&["a"]), fixed("j", "x", "a"));
        assert_eq!(problem(&no_parent), UrdfProblem::MissingParent { joint: "j".into(), link: "x".into() });
    }

    #[test]
    fn a_free_joint_is_frozen_only_below_a_root_link_without_geometry() {
        let shape = "<geometry><box size=\"0.1 0.1 0.1\"/></geometry>";
        let robot = |root: &str, kind: &str| {
            format!(
                r#"<robot name="r"><link name="root">{root}</link><link name="body"><collision>{shape}</collision></link>
                   <joint name="free" type="{kind}"><parent link="root"/><child link="body"/></joint></robot>"#
            )
        };
        for kind in ["floating", "planar"] {
            // A `world` link holding only the body is a frame above the root.
            let tree = parse_urdf(&robot("", kind), STRING_SOURCE, None).unwrap();
            assert_eq!((tree.links.len(), tree.dof(), tree.links[0].name.as_str()), (1, 0, "body"));
            // Holding a camera's frame too, it stays the root and its anchor is frozen.
            let camera = r#"<link name="camera"/><joint name="c" type="fixed"><parent link="root"/><child link="camera"/></joint></robot>"#;
            let tree = parse_urdf(&robot("", kind).replace("</robot>", camera), STRING_SOURCE, None).unwrap();
            assert_eq!((tree.links.len(), tree.dof()), (3, 0), "a `world` anchor is frozen");
            assert!(tree.warnings.iter().any(|w| w.contains("joint `free` is")), "{:?}", tree.warnings);
            // A root link with a shape is part of the robot: freezing its free joint would weld two bodies.
            for root in [format!("<visual>{shape}</visual>"), format!("<collision>{shape}</collision>")] {
                let want = UrdfProblem::FreeJointInBody {
                    joint: "free".into(),
                    kind: kind.into(),
                    parent: "root".into(),
                    child: "body".into(),
                };
                assert_eq!(problem(&robot(&root, kind)), want, "{root}");
            }
        }
    }

    #[test]
    fn a_urdfs_mesh_files_are_listed_once_with_their_materials() {
        let dir = std::env::temp_dir().join(format!("ace_urdf_meshes_{}", std::process::id()));
        std::fs::create_dir_all(dir.join("meshes")).unwrap();
        std::fs::write(dir.join("meshes/body.obj"), "mtllib body.mtl extra.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        std::fs::write(dir.join("meshes/body.mtl"), "newmtl grey\nKd 0.5 0.5 0.5\n").unwrap();
        std::fs::write(dir.join("meshes/leg.stl"), TRIANGLE_STL).unwrap();
        let mesh = |f: &str| format!(r#"<visual><geometry><mesh filename="{f}"/></geometry></visual><collision><geometry><mesh filename="{f}"/></geometry></collision>"#);
        let urdf = format!(
            r#"<robot name="r"><link name="body">{}</link><link name="leg">{}{}</link>
               <joint name="j" type="fixed"><parent link="body"/><child link="leg"/></joint></robot>"#,
            mesh("meshes/body.obj"),
            mesh("meshes/leg.stl"),
            mesh("meshes/gone.stl"),
        );
        let path = dir.join("r.urdf");
        std::fs::write(&path, &urdf).unwrap();
        // The OBJ's second material file does not exist: not listed. The missing mesh neither.
        assert_eq!(
            mesh_files(&path),
            [dir.join("meshes/body.obj"), dir.join("meshes/body.mtl"), dir.join("meshes/leg.stl")]
        );
        let tree = read_urdf_file(&path).unwrap();
        assert_eq!(
            tree.warnings,
            ["1 mesh file(s) not found or not readable as STL, OBJ or Collada (they have no extent): meshes/gone.stl"]
        );
        let Shape::Mesh { bounds, .. } = &tree.links[1].collisions[0].shape else { panic!("a mesh") };
        assert_eq!(bounds.unwrap().max, nalgebra::Point3::new(1.0, 2.0, 3.0));
        std::fs::write(&path, "<robot").unwrap();
        assert!(mesh_files(&path).is_empty(), "an unreadable URDF names no files");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_joint_with_equal_limits_loads_and_one_without_room_is_named() {
        let robot = |limit: &str| {
            format!(
                r#"<robot name="r"><link name="a"/><link name="b"/><joint name="j" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>{limit}</joint></robot>"#
            )
        };
        let warnings = |limit: &str| parse_urdf(&robot(limit), STRING_SOURCE, None).unwrap().warnings;
        let stuck = "joint `j` has lower = upper = 0 (or no <limit>); it cannot move";
        assert_eq!(warnings(""), [stuck]);
        assert_eq!(warnings(r#"<limit lower="0" upper="0" effort="1" velocity="1"/>"#), [stuck]);
        assert!(warnings(r#"<limit lower="0.3" upper="0.3" effort="1" velocity="1"/>"#).is_empty(), "held at 0.3, no warning");
        assert!(warnings(r#"<limit lower="0" upper="1" effort="1" velocity="1"/>"#).is_empty());
        assert!(warnings(r#"<limit lower="-1" upper="0" effort="1" velocity="1"/>"#).is_empty());
    }

    #[test]
    fn a_package_path_is_not_found_in_another_package() {
        let dir = std::env::temp_dir().join(format!("ace_urdf_other_pkg_{}", std::process::id()));
        std::fs::create_dir_all(dir.join("other/meshes")).unwrap();
        std::fs::create_dir_all(dir.join("other/urdf")).unwrap();
        std::fs::write(dir.join("other/meshes/a.stl"), "solid a\nendsolid a\n").unwrap();
        assert_eq!(resolve_mesh_path("package://my_pkg/meshes/a.stl", &dir.join("other/urdf")), None);
        assert_eq!(
            resolve_mesh_path("package://other/meshes/a.stl", &dir.join("other/urdf")),
            Some(dir.join("other/meshes/a.stl"))
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
