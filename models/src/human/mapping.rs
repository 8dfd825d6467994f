//! User joint-mapping files: TOML naming the BVH joint for canonical joints, plus unit, up-axis and
//! rest-frame overrides. The automatic matching that fills in the rest is in [`super::matching`].

use std::collections::BTreeMap;
use std::path::Path;

use super::error::HumanImportError;
use super::skeleton::{JOINT_COUNT, Joint};
use super::units::{parse_unit, parse_up};

/// A user mapping file (TOML) naming the BVH joint for canonical joints, e.g.
/// `pelvis = "Bip01_Pelvis"`; entries override or extend the automatic name matching.
///
/// Keys are the snake_case [`Joint::name`]s (at top level or in a `[joints]` table), plus optional:
/// - `unit`: `"cmu"`, `"cm"`, `"m"`, `"mm"`, `"inch"`, or metres per file unit as a number;
/// - `up`: the file's up axis, `"x"`, `"y"`, `"z"`, optionally signed (`"-z"`);
/// - `first_frame_is_rest_pose`: whether to drop frame 0 (otherwise detected).
#[derive(Clone, Debug, Default, PartialEq, serde::Deserialize)]
#[serde(try_from = "BTreeMap<String, toml::Value>")]
pub struct JointMapping {
    /// BVH joint name per canonical joint, indexed by [`Joint::index`].
    pub joints: [Option<String>; JOINT_COUNT],
    /// Unit override (validated when the mapping is read).
    pub unit: Option<String>,
    /// Up-axis override (validated when the mapping is read).
    pub up: Option<String>,
    /// Whether frame 0 is a rest pose to drop; `None` detects it.
    pub first_frame_is_rest_pose: Option<bool>,
}

impl JointMapping {
    /// Read a mapping file (a regular file of UTF-8 text: [`crate::input::read_text`]).
    pub fn from_file(path: &Path) -> Result<JointMapping, HumanImportError> {
        let file = path.display().to_string();
        let text = crate::input::read_text(path).map_err(|e| super::clip::read_error(&file, e))?;
        Self::parse(&text, &file)
    }

    /// Parse mapping TOML text.
    pub fn from_toml_str(s: &str) -> Result<JointMapping, HumanImportError> {
        Self::parse(s, "joint mapping")
    }

    /// Parse mapping TOML text read from `file` (named in errors).
    pub fn parse(text: &str, file: &str) -> Result<JointMapping, HumanImportError> {
        let table: BTreeMap<String, toml::Value> =
            toml::from_str(text).map_err(|e| HumanImportError::Mapping {
                file: file.to_string(),
                message: e.to_string(),
            })?;
        JointMapping::try_from(table).map_err(|message| HumanImportError::Mapping {
            file: file.to_string(),
            message,
        })
    }

    /// Map canonical `joint` to the BVH joint `bvh_name` (builder style).
    pub fn with(mut self, joint: Joint, bvh_name: &str) -> JointMapping {
        self.joints[joint.index()] = Some(bvh_name.to_string());
        self
    }
}

impl TryFrom<BTreeMap<String, toml::Value>> for JointMapping {
    type Error = String;

    fn try_from(table: BTreeMap<String, toml::Value>) -> Result<Self, String> {
        let mut m = JointMapping::default();
        let string = |k: &str, v: &toml::Value| -> Result<String, String> {
            match v {
                toml::Value::String(s) => Ok(s.clone()),
                toml::Value::Float(f) if k == "unit" => Ok(f.to_string()),
                toml::Value::Integer(i) if k == "unit" => Ok(i.to_string()),
                other => Err(format!(
                    "`{k}` must be a string, found {}",
                    other.type_str()
                )),
            }
        };
        let mut entries: Vec<(String, toml::Value)> = Vec::new();
        for (k, v) in table {
            match (k.as_str(), v) {
                ("joints", toml::Value::Table(t)) => entries.extend(t),
                (_, v) => entries.push((k, v)),
            }
        }
        for (k, v) in entries {
            match k.as_str() {
                "unit" => {
                    let s = string(&k, &v)?;
                    parse_unit(&s).ok_or_else(|| {
                        format!("unknown unit `{s}` (use cmu, cm, m, mm, inch or metres per unit as a number)")
                    })?;
                    m.unit = Some(s);
                }
                "up" => {
                    let s = string(&k, &v)?;
                    parse_up(&s).ok_or_else(|| {
                        format!("unknown up axis `{s}` (use x, y, z, -x, -y or -z)")
                    })?;
                    m.up = Some(s);
                }
                "first_frame_is_rest_pose" => match v {
                    toml::Value::Boolean(b) => m.first_frame_is_rest_pose = Some(b),
                    other => {
                        return Err(format!(
                            "`{k}` must be true or false, found {}",
                            other.type_str()
                        ));
                    }
                },
                name => {
                    let joint = Joint::from_name(name).ok_or_else(|| {
                        let valid: Vec<&str> = Joint::ALL.iter().map(|j| j.name()).collect();
                        format!(
                            "unknown key `{name}`; expected unit, up, first_frame_is_rest_pose or a canonical joint: {}",
                            valid.join(", ")
                        )
                    })?;
                    let bvh = string(&k, &v)?;
                    if m.joints[joint.index()].is_some() {
                        return Err(format!("`{name}` is given twice, at the top level and in `[joints]`"));
                    }
                    if let Some(other) = Joint::ALL.iter().find(|j| m.joints[j.index()].as_deref() == Some(bvh.as_str())) {
                        return Err(format!(
                            "`{}` and `{name}` both name the BVH joint `{bvh}`: each canonical joint is a joint of its own",
                            other.name()
                        ));
                    }
                    m.joints[joint.index()] = Some(bvh);
                }
            }
        }
        Ok(m)
    }
}
