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
        "warnings": clip.warnings(),
    });
    Ok((clip, v))
}

/// The fields every character summary has, URDF robot or glTF creature.
fn character_fields(kind: &str, path: &Path, tree: &KinematicTree, m: &Morphology) -> serde_json::Map<String, Value> {
    let names = |links: &[usize]| -> Vec<String> { links.iter().map(|&i| tree.links[i].name.clone()).collect() };
    let v = json!({
        "kind": kind,
        "file": path.display().to_string(),
        "name": tree.name,
        "links": tree.links.len(),
        "dof": tree.dof(),
        "dof_names": tree.dof_names(),
        "feet": names(&m.feet),
        "manipulators": names(&m.manipulators),
        "wheels": names(&m.wheels),
        "head": m.head.map(|h| tree.links[h].name.clone()),
        "standing_height_m": tree.standing_root_height(),
        "warnings": tree.warnings.clone(),
    });
    match v {
        Value::Object(o) => o,
        _ => unreachable!("a JSON object literal"),
    }
}

/// A URDF file's summary.
pub fn urdf_summary(path: &Path) -> Result<(KinematicTree, Morphology, Value)> {
    let (tree, morphology) = load_character(path)?;
    let v = Value::Object(character_fields("urdf", path, &tree, &morphology));
    Ok((tree, morphology, v))
}

/// A glTF creature's summary: the URDF fields, plus its tails, scale, skins, clips, moving bones,
/// helper bones and the joints left at rest.
pub fn gltf_summary(path: &Path) -> Result<Value> {
    let c = ace::models::character::load_creature(path)?;
    let mut v = character_fields("gltf", path, &c.tree, &c.morphology);
    let extra = json!({
        "tails": c.plan.tails,
        "scale_m_per_unit": c.scale,
        "body_root": c.plan.body_root,
        "skins": c.rig.skins,
        "animations": c.rig.animations,
        "moving_bones": c.plan.roles,
        "joints_at_rest": c.plan.at_rest,
        "helper_bones": c.plan.helpers,
    });
    if let Value::Object(o) = extra {
        v.extend(o);
    }
    Ok(Value::Object(v))
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
        kind => {
            let v = if kind == "gltf" { gltf_summary(path)? } else { urdf_summary(path)?.2 };
            for w in v["warnings"].as_array().into_iter().flatten() {
                eprintln!("warning: {}: {}", path.display(), w.as_str().unwrap_or_default());
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
