//! Names of the skeleton conventions the importer recognises (reported in `HumanClip::convention`).
//! Recognition is by characteristic joint names; the mapping itself never depends on it.

use super::bvh::Bvh;

/// CMU conversions by cgspeed, MotionBuilder-friendly (Hips, LHipJoint, LeftUpLeg, Spine1, Neck1).
pub const CMU_CGSPEED_MB: &str = "cmu-cgspeed-mb";
/// CMU conversions by cgspeed, 3ds Max-friendly (Hips, LeftHip, LeftKnee, Chest2, LeftCollar).
pub const CMU_CGSPEED_MAX: &str = "cmu-cgspeed-max";
/// CMU conversions by cgspeed, Daz-friendly (hip, abdomen, chest, lThigh, rShldr).
pub const DAZ: &str = "daz";
/// Reallusion iClone / Character Creator (CC_Base_*).
pub const ICLONE: &str = "iclone";
/// Autodesk MotionBuilder HumanIK (Character1_Hips, …).
pub const HUMANIK: &str = "humanik";
/// Bandai Namco Research motion dataset (joint_Root, UpperLeg_L, …).
pub const BANDAI: &str = "bandai";
/// Adobe Mixamo (mixamorig:Hips, …, LeftToeBase).
pub const MIXAMO: &str = "mixamo";
/// Ubisoft LAFAN1 (Hips, Spine2, LeftToe, …).
pub const LAFAN1: &str = "lafan1";
/// No known convention; a user mapping supplied joints.
pub const USER_MAPPING: &str = "user-mapping";
/// No known convention; automatic rules mapped every joint.
pub const GENERIC: &str = "generic";

/// The recognised convention of `bvh`, if any.
pub fn detect(bvh: &Bvh) -> Option<&'static str> {
    let names: Vec<&str> = bvh.joints.iter().map(|j| j.name.as_str()).collect();
    let has = |n: &str| names.iter().any(|x| x.eq_ignore_ascii_case(n));
    if names.iter().any(|n| n.starts_with("CC_Base_")) {
        return Some(ICLONE);
    }
    if names
        .iter()
        .any(|n| n.to_ascii_lowercase().starts_with("mixamorig"))
    {
        return Some(MIXAMO);
    }
    if has("joint_Root") && has("UpperLeg_L") && has("LowerArm_R") {
        return Some(BANDAI);
    }
    // HumanIK: `<Character>_Hips` and `<Character>_LeftUpLeg` with the same prefix.
    let humanik = names.iter().any(|n| {
        n.strip_suffix("_Hips").is_some_and(|p| {
            !p.is_empty() && has(&format!("{p}_LeftUpLeg")) && has(&format!("{p}_Spine"))
        })
    });
    if humanik {
        return Some(HUMANIK);
    }
    if has("LHipJoint") && has("LeftUpLeg") && has("Spine1") {
        return Some(CMU_CGSPEED_MB);
    }
    if has("LHipJoint") && has("LeftHip") && has("LeftKnee") {
        return Some(CMU_CGSPEED_MAX);
    }
    if has("hip") && has("abdomen") && has("lThigh") && has("rShldr") {
        return Some(DAZ);
    }
    if has("Hips") && has("LeftUpLeg") && has("Spine2") {
        if has("LeftToe") && !has("LeftToeBase") {
            return Some(LAFAN1);
        }
        if has("LeftToeBase") || has("HeadTop_End") {
            return Some(MIXAMO);
        }
    }
    None
}
