//! `ace inspect`: summaries of BVH clips, URDF robots and glTF creatures, as text or JSON.

use std::path::Path;

use ace::models::human::{HumanClip, ImportOptions, JointMapping};
use ace::models::kinematics::KinematicTree;
use ace::models::morphology::{Morphology, load_character};
use anyhow::{Result, bail};
use serde_json::{Value, json};

/// A BVH file's summary; `mapping` is a joint-mapping file for its skeleton.
pub fn bvh_summary(path: &Path, mapping: Option<&Path>) -> Result<(HumanClip, Value)> {
    let mapping = mapping.map(JointMapping::from_file).transpose()?;
    let clip = HumanClip::from_bvh_file(path, &ImportOptions { fps: None, mapping })?;
    let mapping: serde_json::Map<String, Value> = ace::models::human::Joint::ALL
        .iter()
        .map(|j| (j.name().to_string(), Value::from(clip.source_joints[j.index()].clone())))
        .collect();
    let v = json!({
        "kind": "bvh",
        "file": path.display().to_string(),
        "frames": clip.frames.len(),
        "fps": clip.fps,
        "duration_s": clip.duration(),
        "height_m": clip.height_m,
        "convention": clip.convention,
        "unit": clip.unit,
        "canonical_joints": clip.mapped_joints,
        "joint_mapping": mapping,
        "warnings": clip.posture_warning().into_iter().collect::<Vec<_>>(),
    });
    Ok((clip, v))
}

/// A URDF file's summary.
pub fn urdf_summary(path: &Path) -> Result<(KinematicTree, Morphology, Value)> {
    let (tree, morphology) = load_character(path)?;
    let names = |links: &[usize]| -> Vec<String> { links.iter().map(|&i| tree.links[i].name.clone()).collect() };
    let v = json!({
        "kind": "urdf",
        "file": path.display().to_string(),
        "name": tree.name,
        "links": tree.links.len(),
        "dof": tree.dof(),
        "dof_names": tree.dof_names(),
        "feet": names(&morphology.feet),
        "manipulators": names(&morphology.manipulators),
        "wheels": names(&morphology.wheels),
        "head": morphology.head.map(|h| tree.links[h].name.clone()),
        "standing_height_m": tree.standing_root_height(),
        "warnings": tree.warnings.clone(),
    });
    Ok((tree, morphology, v))
}

/// A glTF creature's summary: the URDF fields, plus its skins, clips, helper bones and the joints
/// left at rest.
pub fn gltf_summary(path: &Path) -> Result<Value> {
    let c = ace::models::character::load_creature(path)?;
    let (tree, m) = (&c.tree, &c.morphology);
    let names = |links: &[usize]| -> Vec<String> { links.iter().map(|&i| tree.links[i].name.clone()).collect() };
    Ok(json!({
        "kind": "gltf",
        "file": path.display().to_string(),
        "name": tree.name,
        "links": tree.links.len(),
        "dof": tree.dof(),
        "dof_names": tree.dof_names(),
        "feet": names(&m.feet),
        "manipulators": names(&m.manipulators),
        "wheels": names(&m.wheels),
        "head": m.head.map(|h| tree.links[h].name.clone()),
        "tails": c.plan.tails,
        "standing_height_m": tree.standing_root_height(),
        "scale_m_per_unit": c.scale,
        "body_root": c.plan.body_root,
        "skins": c.skins,
        "animations": c.animations,
        "moving_bones": c.plan.roles,
        "joints_at_rest": c.plan.at_rest,
        "helper_bones": c.plan.helpers,
        "warnings": tree.warnings,
    }))
}

fn kind_of(path: &Path) -> Result<&'static str> {
    match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
        Some("bvh") => Ok("bvh"),
        Some("urdf") => Ok("urdf"),
        Some("glb" | "gltf") => Ok("gltf"),
        _ => bail!("{}: unknown file type (expected .bvh, .urdf, .glb or .gltf)", path.display()),
    }
}

/// Human-readable lines of a summary.
pub fn text(v: &Value) -> String {
    let mut out = String::new();
    for (k, val) in v.as_object().into_iter().flatten() {
        let shown = match val {
            Value::String(s) => s.clone(),
            Value::Array(a) => a.iter().map(|x| x.as_str().map_or_else(|| x.to_string(), str::to_string)).collect::<Vec<_>>().join(", "),
            Value::Object(o) => o.iter().map(|(a, b)| format!("{a}={}", b.as_str().unwrap_or_default())).collect::<Vec<_>>().join(" "),
            Value::Number(n) if n.is_f64() => format!("{:.3}", n.as_f64().unwrap_or_default()),
            other => other.to_string(),
        };
        out.push_str(&format!("{k:>18}: {shown}\n"));
    }
    out
}

/// `ace inspect FILE [--json] [--mapping FILE]`.
pub fn run(path: &Path, as_json: bool, mapping: Option<&Path>) -> Result<()> {
    let v = match kind_of(path)? {
        "bvh" => bvh_summary(path, mapping)?.1,
        "gltf" => {
            let v = gltf_summary(path)?;
            for w in v["warnings"].as_array().into_iter().flatten() {
                eprintln!("warning: {}: {}", path.display(), w.as_str().unwrap_or_default());
            }
            v
        }
        _ => {
            let (tree, _, v) = urdf_summary(path)?;
            for w in &tree.warnings {
                eprintln!("warning: {}: {w}", path.display());
            }
            v
        }
    };
    if as_json {
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        print!("{}", text(&v));
    }
    Ok(())
}
