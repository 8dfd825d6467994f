//! Rule-based reading of BVH joint names: namespace and rig prefixes are dropped, camelCase and
//! separators split into words, the side (left/right) recognised in any of the usual spellings
//! (`Left…`, `L_…`, `…_L`, `l…` glued to a body word), and the remaining body word classified with
//! synonyms (thigh/upleg/femur/hip, shin/calf/leg/knee/lowerleg, …).

/// Body side encoded in a joint name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    Left,
    Right,
    Centre,
}

/// What a joint name says the joint is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Part {
    Hips,
    Spine,
    Chest,
    Neck,
    Head,
    Collar,
    UpperArm,
    Forearm,
    Hand,
    Thigh,
    Shin,
    Foot,
    Toe,
    Finger,
    /// Twist/roll/share/mesh/end bones and other helpers: never picked automatically.
    Helper,
    Other,
}

/// A classified joint name.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NameInfo {
    pub side: Side,
    pub part: Part,
    /// The body word, lower case, without side, prefixes and digits (`upleg`, `forearm`, `spine`).
    pub word: String,
}

/// Rig and namespace prefixes that carry no meaning.
const NOISE: &[&str] = &[
    "mixamorig",
    "character",
    "character1",
    "cc",
    "base",
    "bip",
    "bip01",
    "bip001",
    "biped",
    "def",
    "org",
    "jnt",
    "joint",
    "bone",
    "bn",
    "b",
    "j",
    "sk",
    "skel",
    "ctrl",
    "c",
    "rig",
    "mch",
    "deform",
];

/// Words marking helper bones (twist, roll, mesh, end-of-chain nubs, IK targets).
const HELPER: &[&str] = &[
    "twist",
    "roll",
    "share",
    "sharebone",
    "rigmesh",
    "mesh",
    "helper",
    "nub",
    "end",
    "dummy",
    "adjust",
    "ik",
    "fk",
    "pole",
    "target",
    "aux",
    "correct",
    "corrective",
    "bend",
    "tip",
    "top",
    "radius",
    "ulna",
    "humerus",
    "femur2",
    "talus",
    "tibia",
    "fibula",
    "prop",
    "weapon",
    "eye",
    "jaw",
    "tongue",
    "teeth",
    "breast",
    "ribs",
    "facial",
    "nose",
    "ear",
    "hair",
    "brow",
    "lip",
    "cheek",
];

/// Body words that may follow a glued side letter (`lhand`, `rshldr`, `lthigh`).
const BODY_WORDS: &[&str] = &[
    "hand", "foot", "thigh", "shin", "shldr", "shoulder", "forearm", "arm", "leg", "upleg",
    "collar", "clavicle", "hip", "knee", "ankle", "elbow", "wrist", "toe", "toes", "toebase",
    "fingers", "finger", "thumb", "index", "buttock", "uparm", "lowarm", "calf", "upperarm",
    "lowerarm", "upperleg", "lowerleg", "hipjoint", "pinky", "ring", "mid", "middle", "eye",
];

/// Split a joint name into lower-case words (camelCase, separators, letter/digit boundaries).
pub fn words(name: &str) -> Vec<String> {
    // Drop namespaces (`mixamorig:Hips`) and DAG paths (`root|Hips`).
    let name = name.rsplit([':', '|']).next().unwrap_or(name);
    let mut out: Vec<String> = Vec::new();
    let chars: Vec<char> = name.chars().collect();
    let mut cur = String::new();
    for (i, &c) in chars.iter().enumerate() {
        if !c.is_alphanumeric() {
            if !cur.is_empty() {
                out.push(std::mem::take(&mut cur));
            }
            continue;
        }
        if let Some(&p) = cur.chars().last().as_ref() {
            let next_lower = chars.get(i + 1).is_some_and(|n| n.is_lowercase());
            let boundary = (p.is_lowercase() && c.is_uppercase())
                || (p.is_uppercase() && c.is_uppercase() && next_lower)
                || (p.is_ascii_digit() != c.is_ascii_digit());
            if boundary {
                out.push(std::mem::take(&mut cur));
            }
        }
        cur.push(c);
    }
    if !cur.is_empty() {
        out.push(cur);
    }
    out.iter().map(|w| w.to_lowercase()).collect()
}

/// Classify a BVH joint name.
pub fn classify(name: &str) -> NameInfo {
    classify_words(words(name))
}

/// Classify every joint name of a skeleton, without the leading words they all share (a rig's or an
/// exporter's prefix: `Armature_`, `Hero_`, `Ch01_`), which are no part of any joint's name.
pub fn classify_all(names: &[&str]) -> Vec<NameInfo> {
    let mut all: Vec<Vec<String>> = names.iter().map(|n| words(n)).collect();
    // A side is kept even when every name begins with it (a limb's joints alone).
    let meaningless = |w: &str| !matches!(w, "left" | "right" | "l" | "r" | "lft" | "rgt" | "rt");
    while all.len() > 1 {
        // The shared word; a name that is that word alone (a root named `Armature`) keeps it.
        let Some(first) = all.iter().find(|w| w.len() > 1).map(|w| w[0].clone()) else { break };
        if !(meaningless(&first) && all.iter().all(|w| w.first() == Some(&first))) {
            break;
        }
        all.iter_mut().filter(|w| w.len() > 1).for_each(|w| {
            w.remove(0);
        });
    }
    all.into_iter().map(classify_words).collect()
}

fn classify_words(all: Vec<String>) -> NameInfo {
    let mut side = Side::Centre;
    let mut body: Vec<String> = Vec::new();
    let n = all.len();
    for (i, w) in all.into_iter().enumerate() {
        let set_side = |s: Side, side: &mut Side| {
            if *side == Side::Centre {
                *side = s;
            }
        };
        match w.as_str() {
            "left" | "lft" => set_side(Side::Left, &mut side),
            "right" | "rgt" | "rt" => set_side(Side::Right, &mut side),
            // A lone `l`/`r` is a side marker anywhere (`L_Thigh`, `thigh_l`, `Bip01 L Foot`).
            "l" => set_side(Side::Left, &mut side),
            "r" => set_side(Side::Right, &mut side),
            _ if w.chars().all(|c| c.is_ascii_digit()) => {}
            _ if i + 1 < n && NOISE.contains(&w.as_str()) => {}
            _ if NOISE.contains(&w.as_str()) && !body.is_empty() => {}
            _ => {
                // Glued sides: `lefthand`, `rightfoot`, `lhand`, `rshldr`.
                let glued = [
                    ("left", Side::Left),
                    ("right", Side::Right),
                    ("l", Side::Left),
                    ("r", Side::Right),
                ]
                .into_iter()
                .find(|(p, _)| {
                    w.strip_prefix(p).is_some_and(|rest| {
                        BODY_WORDS
                            .iter()
                            .any(|b| rest == *b || (p.len() > 1 && rest.starts_with(b)))
                    })
                });
                // A side already read is kept, but the glued letter is still not part of the body
                // word (`Right_lfoot` is a foot).
                match glued {
                    Some((p, s)) => {
                        set_side(s, &mut side);
                        body.push(w[p.len()..].to_string());
                    }
                    None => body.push(w),
                }
            }
        }
    }
    let word: String = body.concat();
    let part = part_of(&body, &word);
    NameInfo { side, part, word }
}

fn part_of(body: &[String], word: &str) -> Part {
    const FINGERS: &[&str] = &[
        "thumb", "index", "middle", "mid", "ring", "pinky", "little", "finger", "fingers", "carpal",
    ];
    if body.iter().any(|w| HELPER.contains(&w.as_str())) || word.ends_with("end") {
        return Part::Helper;
    }
    if body.iter().any(|w| FINGERS.contains(&w.as_str())) {
        return Part::Finger;
    }
    if body.iter().any(|w| w.contains("toe")) {
        return Part::Toe;
    }
    match word {
        // `hip` with a side (LeftHip) is a thigh; see `NameInfo::part`.
        "hips" | "hip" | "pelvis" | "root" => Part::Hips,
        "spine" | "lowerback" | "abdomen" | "back" | "lumbar" | "waist" | "torso" => Part::Spine,
        "chest" | "upperchest" | "thorax" | "upperback" => Part::Chest,
        "neck" | "lowerneck" | "upperneck" | "necktwist" => Part::Neck,
        "head" => Part::Head,
        "collar" | "clavicle" | "shoulderblade" | "scapula" => Part::Collar,
        "upperarm" | "arm" | "shoulder" | "shldr" | "uparm" | "bicep" => Part::UpperArm,
        "forearm" | "lowerarm" | "elbow" | "lowarm" => Part::Forearm,
        "hand" | "wrist" => Part::Hand,
        "thigh" | "upleg" | "upperleg" | "femur" | "hipjoint" => Part::Thigh,
        "shin" | "calf" | "leg" | "knee" | "lowerleg" | "lowleg" | "crus" => Part::Shin,
        "foot" | "ankle" => Part::Foot,
        _ => Part::Other,
    }
}

impl NameInfo {
    /// Part with the side taken into account: a sided `hip` (`LeftHip`) is a thigh.
    pub fn part(&self) -> Part {
        match (self.part, self.side) {
            (Part::Hips, Side::Left | Side::Right) if self.word == "hip" => Part::Thigh,
            (p, _) => p,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(name: &str) -> (Side, Part) {
        let i = classify(name);
        (i.side, i.part())
    }

    /// A prefix every joint shares is no part of their names (the matcher once left every joint of an
    /// `Armature_` skeleton unmapped); a word only some share stays.
    #[test]
    fn the_words_every_joint_name_begins_with_are_dropped() {
        let names = ["Hips", "LeftUpLeg", "LeftLeg", "RightForeArm", "Spine1", "Head"];
        let want: Vec<(Side, Part)> = names.iter().map(|n| c(n)).collect();
        for prefix in ["Armature_", "Armature_Hero_", "Ch01_", "Skeleton:", "Genesis8 "] {
            let named: Vec<String> = names.iter().map(|n| format!("{prefix}{n}")).collect();
            let got: Vec<(Side, Part)> = classify_all(&named.iter().map(String::as_str).collect::<Vec<_>>()).iter().map(|i| (i.side, i.part())).collect();
            assert_eq!(got, want, "{prefix}");
        }
        // A root named as the prefix alone keeps its name.
        let rooted = classify_all(&["Armature", "Armature_Hips", "Armature_LeftFoot"]);
        assert_eq!(rooted.iter().map(|i| (i.side, i.part())).collect::<Vec<_>>(), [(Side::Centre, Part::Other), (Side::Centre, Part::Hips), (Side::Left, Part::Foot)]);
        // A side that begins every name is kept; a lone joint keeps its words.
        let some = classify_all(&["LeftFoot", "LeftHand"]);
        assert_eq!((some[0].side, some[0].part()), (Side::Left, Part::Foot));
        assert_eq!(classify_all(&["Hips"])[0].part(), Part::Hips);
    }

    #[test]
    fn splits_words() {
        assert_eq!(words("mixamorig:LeftUpLeg"), ["left", "up", "leg"]);
        assert_eq!(words("CC_Base_L_Thigh"), ["cc", "base", "l", "thigh"]);
        assert_eq!(words("LHipJoint"), ["l", "hip", "joint"]);
        assert_eq!(words("Spine1"), ["spine", "1"]);
        assert_eq!(words("Bip01 R Forearm"), ["bip", "01", "r", "forearm"]);
    }

    #[test]
    fn classifies_common_conventions() {
        use Part::*;
        use Side::*;
        assert_eq!(c("LeftUpLeg"), (Left, Thigh));
        assert_eq!(c("mixamorig:RightForeArm"), (Right, Forearm));
        assert_eq!(c("lShldr"), (Left, UpperArm));
        assert_eq!(c("rForeArm"), (Right, Forearm));
        assert_eq!(c("lhand"), (Left, Hand));
        assert_eq!(c("LeftWrist"), (Left, Hand));
        assert_eq!(c("LeftHip"), (Left, Thigh));
        assert_eq!(c("LeftKnee"), (Left, Shin));
        assert_eq!(c("LeftAnkle"), (Left, Foot));
        assert_eq!(c("CC_Base_R_Calf"), (Right, Shin));
        assert_eq!(c("CC_Base_L_CalfTwist01"), (Left, Helper));
        assert_eq!(c("CC_Base_L_KneeShareBone"), (Left, Helper));
        assert_eq!(c("UpperArm_L"), (Left, UpperArm));
        assert_eq!(c("LowerLeg_R"), (Right, Shin));
        assert_eq!(c("Foot_L"), (Left, Foot));
        assert_eq!(c("Toes_L"), (Left, Toe));
        assert_eq!(c("Character1_LeftFoot"), (Left, Foot));
        assert_eq!(c("L_Radius_RIGMESH"), (Left, Helper));
        assert_eq!(c("R_Femur_RIGMESH"), (Right, Helper));
        assert_eq!(c("LeftHandIndex1"), (Left, Finger));
        assert_eq!(c("LThumb"), (Left, Finger));
        assert_eq!(c("HeadTop_End"), (Centre, Helper));
        assert_eq!(c("Head"), (Centre, Head));
        assert_eq!(c("CC_Base_Head"), (Centre, Head));
        assert_eq!(c("Hips"), (Centre, Hips));
        assert_eq!(c("joint_Root"), (Centre, Hips));
        assert_eq!(c("lowerback"), (Centre, Spine));
        assert_eq!(c("thigh.L"), (Left, Thigh));
        assert_eq!(c("lowerneck"), (Centre, Neck));
        assert_eq!(c("leftEye"), (Left, Helper));
        // 3ds Max Biped and Unreal-style names.
        assert_eq!(c("Bip01 L Hand"), (Left, Hand));
        assert_eq!(c("Bip01 R UpperArm"), (Right, UpperArm));
        assert_eq!(c("Bip01 Head"), (Centre, Head));
        assert_eq!(c("calf_r"), (Right, Shin));
        assert_eq!(c("lowerarm_l"), (Left, Forearm));
        assert_eq!(c("upperarm_twist_01_l"), (Left, Helper));
        assert_eq!(c("Chest"), (Centre, Chest));
        assert_eq!(c("UpperChest"), (Centre, Chest));
        assert_eq!(c("LeftCollar"), (Left, Collar));
        assert_eq!(c("clavicle_r"), (Right, Collar));
        // Only a sided `hip` is a thigh.
        assert_eq!(c("pelvis_l"), (Left, Hips));
    }

    #[test]
    fn rig_words_are_dropped_around_a_body_word_and_kept_alone() {
        use Part::*;
        use Side::*;
        // Before a body word and after one.
        assert_eq!(c("jnt_Spine"), (Centre, Spine));
        assert_eq!(c("Spine_jnt"), (Centre, Spine));
        assert_eq!(c("L_Forearm_bn"), (Left, Forearm));
        // A name that is only a rig word keeps it as its body word.
        assert_eq!(classify("Bone").word, "bone");
        assert_eq!(classify("L_Base").word, "base");
        assert_eq!(classify("Spine_jnt").word, "spine");
    }

    #[test]
    fn a_glued_side_letter_needs_the_whole_body_word_and_the_first_side_wins() {
        use Side::*;
        // `left`/`right` glued to a longer word that begins with a body word.
        assert_eq!(classify("leftarmroll").side, Left);
        assert_eq!(classify("rightfootprint").side, Right);
        // A lone letter only before a whole body word: `lhandle` is not a left `handle`.
        assert_eq!(c("lhand"), (Left, Part::Hand));
        assert_eq!(classify("lhandle").side, Centre);
        assert_eq!(classify("rings").side, Centre);
        // A side already read is kept; the glued letter still leaves the body word.
        assert_eq!(c("Right_lfoot"), (Right, Part::Foot));
        assert_eq!(c("L_rhand"), (Left, Part::Hand));
        assert_eq!(c("Left_lthigh"), (Left, Part::Thigh));
    }
}
