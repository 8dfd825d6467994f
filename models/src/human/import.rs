//! The import pipeline: parse → map joints → forward kinematics → detect translation semantics, up
//! axis, rest-pose frame and unit → convert to metres, z up → root orientation per frame.

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

use super::bvh::Bvh;
use super::clip::{HumanClip, HumanFrame, ImportOptions};
use super::conventions;
use super::detect::{detect_translation, detect_up, leading_rest_frames, snap_fps};
use super::error::HumanImportError;
use super::fk::Translation;
use super::matching::{SkeletonMap, Source};
use super::skeleton::{JOINT_COUNT, Joint};
use super::tracks::{leg_length, lowest_foot, percentile, track};
use super::units::{NORMALISED_HEIGHT_M, UpAxis, detect_unit, parse_unit, parse_up};

/// Leg length (hip joint to ankle joint centre) as a fraction of standing height: hip joint at 0.530 H,
/// ankle at 0.039 H (Drillis & Contini 1966). Standing height is estimated from the legs because their
/// joint centres are anatomically the same in every rig, whereas the head joint sits anywhere from the
/// lower neck (CMU) to the skull base (Daz) and many rigs have no head-top end site.
pub const LEG_FRACTION_OF_HEIGHT: f32 = 0.491;

/// Percentile of the per-frame lowest foot point taken as the floor (robust to jumps and glitches).
pub const FLOOR_PERCENTILE: f32 = 0.05;

/// Farthest a joint may be from the clip's origin after conversion to metres. Mocap volumes are tens
/// of metres; anything beyond this is a corrupt value (1e30 in an OFFSET or a position channel), and
/// letting it through would poison every statistic computed from the clip.
pub const MAX_DISTANCE_M: f32 = 10_000.0;

/// Heights (m) a human may have with a mapping's `unit` override (the unit detection only picks
/// units giving [`super::units::PLAUSIBLE_HEIGHT_M`]): a wrong override made a 170 m human.
pub const HUMAN_HEIGHT_RANGE_M: (f32, f32) = (0.3, 3.0);

/// Largest OFFSET component or position value accepted in the file's own units: 10 km in
/// millimetres, the smallest unit files use. Checked before anything is inferred from the skeleton.
pub const MAX_FILE_LENGTH: f32 = 1e7;

/// Largest rotation channel value accepted, degrees (about 2,800 turns: a spinning root accumulating
/// its yaw stays far below it).
pub const MAX_ROTATION_DEG: f32 = 1e6;

/// Most frames a clip is resampled into ([`ImportOptions::fps`]): two hours at 60 fps. With the
/// reader's [`super::bvh::MAX_CLIP_SECONDS`] it bounds what resampling allocates whatever the target
/// frame rate; it is checked on the header, before any frame is computed.
pub const MAX_RESAMPLED_FRAMES: usize = 432_000;

/// What the importer detected about a file, for diagnostics and user-facing reports.
#[derive(Clone, Debug, PartialEq)]
pub struct ImportReport {
    /// How the root's position channels were read.
    pub root_translation: Translation,
    /// Up axis of the file (`y`, `-z`, …).
    pub up_axis: String,
    /// Metres per file unit.
    pub metres_per_unit: f32,
    /// Leading frames dropped as a rest (T-)pose and the blend out of it.
    pub dropped_rest_frames: usize,
    /// Height of the floor in the file, metres (after unit and axis conversion): the
    /// [`FLOOR_PERCENTILE`] of the lowest point of the feet (ankles, toes and their end sites) per frame.
    /// The clip was shifted down by this much, so that its floor is at z = 0.
    pub floor_m: f32,
    /// Standing height, metres (same as [`HumanClip::height_m`]).
    pub height_m: f32,
}

/// Pelvis orientation from the hips and lower spine: y from the right hip to the left hip, z towards
/// the spine (made orthogonal), x = y × z, the facing direction.
fn root_rotation(p: &[Vector3<f32>; JOINT_COUNT]) -> UnitQuaternion<f32> {
    use Joint::*;
    let y = (p[LeftThigh.index()] - p[RightThigh.index()])
        .try_normalize(1e-9)
        .unwrap_or(Vector3::y());
    let mut up = p[Spine.index()] - p[Pelvis.index()];
    if up.norm() < 1e-6 {
        up = p[Chest.index()] - p[Pelvis.index()];
    }
    let x = y.cross(&up).try_normalize(1e-9).unwrap_or(Vector3::x());
    let z = x.cross(&y);
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(Matrix3::from_columns(
        &[x, y, z],
    )))
}

/// Feet to head in the skeleton's rest pose (OFFSETs only, every rotation zero), normalised; `None`
/// unless one file axis clearly dominates it (at least 0.9 of its length), as in a standing rest pose.
fn rest_up(bvh: &Bvh, map: &SkeletonMap) -> Option<Vector3<f32>> {
    let mut p: Vec<Vector3<f32>> = Vec::with_capacity(bvh.joints.len());
    for j in &bvh.joints {
        let base = j.parent.map_or(Vector3::zeros(), |k| p[k]);
        p.push(base + j.offset);
    }
    let at = |joint: Joint| match map.sources[joint.index()] {
        Source::Joint(i) => p[i],
        Source::Midpoint(a, b) => (p[a] + p[b]) * 0.5,
    };
    let v = (at(Joint::Head) - (at(Joint::LeftFoot) + at(Joint::RightFoot)) * 0.5).try_normalize(1e-9)?;
    (v[v.iamax()].abs() >= 0.9).then_some(v)
}

/// Import BVH text (see [`HumanClip::from_bvh_str`]), also returning what was detected.
pub fn import_with_report(
    text: &str,
    file: &str,
    opts: &ImportOptions,
) -> Result<(HumanClip, ImportReport), HumanImportError> {
    let bvh = Bvh::parse(text, file)?;
    if let Some(fps) = opts.fps {
        check_resampling(&bvh, fps, file)?;
    }
    check_values(&bvh, file)?;
    let user = opts.mapping.as_ref();
    let map = SkeletonMap::build(&bvh, user, file)?;
    let convention = conventions::detect(&bvh).unwrap_or(
        if user.is_some_and(|u| u.joints.iter().any(Option::is_some)) {
            conventions::USER_MAPPING
        } else {
            conventions::GENERIC
        },
    );

    let modes = detect_translation(&bvh, &map);
    let all: Vec<usize> = (0..bvh.frame_count).collect();
    let mut tracks = track(&bvh, &map, &all, &modes);
    let up = match user.and_then(|u| u.up.as_deref()) {
        Some(s) => parse_up(s).ok_or_else(|| HumanImportError::Mapping {
            file: file.to_string(),
            message: format!("unknown up axis `{s}`"),
        })?,
        None => detect_up(&tracks),
    };
    // The skeleton's own up, from its rest pose: a skeleton that stands along +y there (BVH's up, as
    // most exporters build it) in a clip whose frames stand along another axis is a person lying or
    // crawling through most of it. (Rest poses along other axes say nothing: Bandai Namco's stands
    // along x, iClone's along -y, and both clips stand along y.)
    let skeleton_up = match user.and_then(|u| u.up.as_deref()) {
        Some(_) => None,
        None => rest_up(&bvh, &map)
            .map(|s| UpAxis::nearest(&s))
            .filter(|s| s.label() == "y" && *s != up)
            .map(|s| (s.label(), up.label())),
    };
    let leg = leg_length(&tracks);
    if leg.is_nan() || leg <= 0.0 {
        return Err(HumanImportError::Skeleton {
            file: file.to_string(),
            message: "the legs have zero length".into(),
        });
    }
    let dropped = leading_rest_frames(&tracks, leg, user.and_then(|u| u.first_frame_is_rest_pose));
    tracks.joints.drain(..dropped);
    tracks.feet.drain(..dropped);

    let rot = up.to_z_up();
    let up_file = rot.transpose() * Vector3::z();
    let height_units = leg / LEG_FRACTION_OF_HEIGHT;
    let (unit, scale) = match user.and_then(|u| u.unit.as_deref()) {
        Some(s) => {
            let m = parse_unit(s).ok_or_else(|| HumanImportError::Mapping {
                file: file.to_string(),
                message: format!("unknown unit `{s}`"),
            })?;
            let (lo, hi) = HUMAN_HEIGHT_RANGE_M;
            let height = height_units * m;
            if !(lo..=hi).contains(&height) {
                return Err(HumanImportError::Mapping {
                    file: file.to_string(),
                    message: format!(
                        "unit `{s}` makes the human {height} m tall; a human is {lo} to {hi} m tall: check the mapping's \
                         `unit`"
                    ),
                });
            }
            (s.to_string(), m)
        }
        None => match detect_unit(height_units) {
            Some((name, m)) => (name.to_string(), m),
            None => (
                format!("unknown (normalised to {NORMALISED_HEIGHT_M:.2} m)"),
                NORMALISED_HEIGHT_M / height_units,
            ),
        },
    };
    let to_world = rot * scale;
    // Ground the clip: the floor (a low percentile of the lowest foot point per frame) goes to z = 0.
    let floor = percentile(lowest_foot(&tracks, &up_file), FLOOR_PERCENTILE) * scale;
    let ground = Vector3::new(0.0, 0.0, floor);

    let frames: Vec<HumanFrame> = tracks
        .joints
        .iter()
        .map(|p| {
            let positions = p.map(|v| to_world * v - ground);
            HumanFrame {
                root_rotation: root_rotation(&positions),
                positions,
            }
        })
        .collect();
    check_positions(&frames, &map.source_names(&bvh), dropped, &unit, file)?;
    let source_fps = snap_fps(1.0 / bvh.frame_time);
    let height_m = height_units * scale;
    let mut clip = HumanClip {
        name: file.to_string(),
        convention: convention.to_string(),
        unit,
        source_fps,
        fps: source_fps,
        frames,
        height_m,
        mapped_joints: JOINT_COUNT,
        source_joints: map.source_names(&bvh),
        skeleton_up,
        other_skeletons: other_skeletons(&bvh, map.index(Joint::Pelvis)),
    };
    if let Some(fps) = opts.fps {
        clip = clip.resampled(fps);
    }
    let report = ImportReport {
        root_translation: modes[0],
        up_axis: up.label(),
        metres_per_unit: scale,
        dropped_rest_frames: dropped,
        floor_m: floor,
        height_m,
    };
    Ok((clip, report))
}

/// Refuses a target frame rate that is not a positive number, or that would resample the clip into
/// more than [`MAX_RESAMPLED_FRAMES`] frames, from the header alone (before anything is allocated).
fn check_resampling(bvh: &Bvh, fps: f32, file: &str) -> Result<(), HumanImportError> {
    let refuse = |message: String| {
        Err(HumanImportError::Skeleton {
            file: file.to_string(),
            message,
        })
    };
    if !(fps.is_finite() && fps > 0.0) {
        return refuse(format!("invalid target frame rate {fps}"));
    }
    // As `HumanClip::resampled` counts them (fewer when leading rest frames are dropped).
    let seconds = bvh.frame_count.saturating_sub(1) as f32 / snap_fps(1.0 / bvh.frame_time);
    let frames = f64::from((seconds * fps + 1e-3).floor()) + 1.0;
    if frames > MAX_RESAMPLED_FRAMES as f64 {
        return refuse(format!(
            "`Frames: {}` at `Frame Time: {}` ({seconds:.0} s) resampled to {fps} fps would be {frames:.0} \
             frames; at most {MAX_RESAMPLED_FRAMES} are made: split the clip",
            bvh.frame_count, bvh.frame_time
        ));
    }
    Ok(())
}

/// The `ROOT` joints of `bvh` other than the one above joint `used`.
fn other_skeletons(bvh: &Bvh, used: usize) -> Vec<String> {
    let mut root = used;
    while let Some(p) = bvh.joints[root].parent {
        root = p;
    }
    bvh.joints.iter().enumerate().filter(|(i, j)| j.parent.is_none() && *i != root).map(|(_, j)| j.name.clone()).collect()
}

/// Refuses skeletons without geometry and absurd rotation values, before any inference on them.
fn check_values(bvh: &Bvh, file: &str) -> Result<(), HumanImportError> {
    if let [root] = &bvh.joints[..] {
        return Err(HumanImportError::Skeleton {
            file: file.to_string(),
            message: format!(
                "the skeleton is one joint, `{}`: a person is a hierarchy of joints (pelvis, spine, legs, arms, head)",
                root.name
            ),
        });
    }
    let no_length = bvh
        .joints
        .iter()
        .skip(1)
        .all(|j| j.offset.norm() == 0.0 && j.end_sites.iter().all(|e| e.norm() == 0.0));
    if no_length {
        return Err(HumanImportError::Skeleton {
            file: file.to_string(),
            message: format!(
                "every OFFSET below the root is zero: the skeleton ({} joints) has no bone lengths, so its \
                 shape, unit and up axis cannot be read",
                bvh.joints.len()
            ),
        });
    }
    let implausible = |message: String| HumanImportError::Skeleton {
        file: file.to_string(),
        message: format!("implausible motion: {message}"),
    };
    for joint in &bvh.joints {
        let lengths = std::iter::once(&joint.offset).chain(&joint.end_sites);
        if let Some(o) = lengths.clone().find(|o| !(o.amax() <= MAX_FILE_LENGTH)) {
            return Err(implausible(format!(
                "joint `{}` (line {}) has an OFFSET of {:e} file units; lengths beyond {MAX_FILE_LENGTH:e} \
                 (10 km in millimetres) are not a human skeleton",
                joint.name,
                joint.line,
                o.amax()
            )));
        }
    }
    for (j, joint) in bvh.joints.iter().enumerate() {
        for (k, ch) in joint.channels.iter().enumerate() {
            let col = joint.first_channel + k;
            let value = |f: usize| bvh.values[f * bvh.channel_count + col];
            if matches!(ch, super::bvh::Channel::Position(_)) {
                if let Some(f) = (0..bvh.frame_count).find(|&f| value(f).abs() > MAX_FILE_LENGTH) {
                    return Err(implausible(format!(
                        "position channel {} of joint `{}` (line {}) is {:e} file units in frame {}; positions \
                         beyond {MAX_FILE_LENGTH:e} (10 km in millimetres) are not mocap",
                        k + 1,
                        joint.name,
                        joint.line,
                        value(f),
                        f + 1
                    )));
                }
                continue;
            }
            if let Some(f) = (0..bvh.frame_count)
                .find(|&f| bvh.values[f * bvh.channel_count + col].abs() > MAX_ROTATION_DEG)
            {
                return Err(HumanImportError::Skeleton {
                    file: file.to_string(),
                    message: format!(
                        "implausible motion: rotation channel {} of joint `{}` (line {}) is {:e}° in frame {}; \
                         rotations beyond ±{MAX_ROTATION_DEG:e}° are not mocap",
                        k + 1,
                        bvh.joints[j].name,
                        joint.line,
                        bvh.values[f * bvh.channel_count + col],
                        f + 1
                    ),
                });
            }
        }
    }
    Ok(())
}

/// Refuses a clip with a joint farther than [`MAX_DISTANCE_M`] from the origin (in metres, after unit
/// detection): a finite but absurd value in the file.
fn check_positions(
    frames: &[HumanFrame],
    sources: &[String; JOINT_COUNT],
    dropped: usize,
    unit: &str,
    file: &str,
) -> Result<(), HumanImportError> {
    for (t, f) in frames.iter().enumerate() {
        if let Some(j) = Joint::ALL
            .iter()
            .find(|j| !(f.positions[j.index()].amax() <= MAX_DISTANCE_M))
        {
            return Err(HumanImportError::Skeleton {
                file: file.to_string(),
                message: format!(
                    "implausible motion: {} (BVH joint `{}`) is {:e} m from the origin in frame {} \
                     (unit {unit}); a human clip stays within {MAX_DISTANCE_M} m: check the file's OFFSET \
                     and position values",
                    j.name(),
                    sources[j.index()],
                    f.positions[j.index()].amax(),
                    t + dropped + 1
                ),
            });
        }
    }
    Ok(())
}

pub(super) fn import(
    text: &str,
    file: &str,
    opts: &ImportOptions,
) -> Result<HumanClip, HumanImportError> {
    import_with_report(text, file, opts).map(|(clip, _)| clip)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::human::mapping::JointMapping;
    use crate::human::test_rig::{Spec, body, close, text, torso};

    /// Canonical joints all at the pelvis (0, 0, 1) but the thighs at `left` and `right` and the spine
    /// and chest at `spine` and `chest`.
    fn hips(left: [f32; 3], right: [f32; 3], spine: [f32; 3], chest: [f32; 3]) -> [Vector3<f32>; JOINT_COUNT] {
        let mut p = [Vector3::new(0.0, 0.0, 1.0); JOINT_COUNT];
        p[Joint::LeftThigh.index()] = Vector3::from(left);
        p[Joint::RightThigh.index()] = Vector3::from(right);
        p[Joint::Spine.index()] = Vector3::from(spine);
        p[Joint::Chest.index()] = Vector3::from(chest);
        p
    }

    fn facing(p: &[Vector3<f32>; JOINT_COUNT]) -> (Vector3<f32>, Vector3<f32>) {
        let r = root_rotation(p);
        (r * Vector3::x(), r * Vector3::z())
    }

    #[test]
    fn the_pelvis_faces_across_the_hips_and_stands_towards_the_spine() {
        // Left hip at +y: facing +x, upright.
        let (x, z) = facing(&hips([0.0, 0.1, 1.0], [0.0, -0.1, 1.0], [0.0, 0.0, 1.2], [0.0, 0.0, 1.4]));
        assert!(close(x, [1.0, 0.0, 0.0]) && close(z, [0.0, 0.0, 1.0]), "{x:?} {z:?}");
        // Left hip at −x: facing +y; a spine leaning forward tilts the pelvis, its y stays across the hips.
        let (x, z) = facing(&hips([-0.1, 0.0, 1.0], [0.1, 0.0, 1.0], [0.0, 0.2, 1.2], [0.0, 0.0, 1.4]));
        let h = 0.5f32.sqrt();
        assert!(close(x, [0.0, h, -h]) && close(z, [0.0, h, h]), "{x:?} {z:?}");
        // A spine at the pelvis' place: the chest, leaning forward, gives up.
        let (x, z) = facing(&hips([-0.1, 0.0, 1.0], [0.1, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.4, 1.4]));
        assert!(close(x, [0.0, h, -h]) && close(z, [0.0, h, h]), "{x:?} {z:?}");
        // Both hips at one place: y falls back to +y, so the pelvis faces +x.
        let (x, _) = facing(&hips([0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.2], [0.0, 0.0, 1.4]));
        assert!(close(x, [1.0, 0.0, 0.0]), "{x:?}");
    }

    /// A standing rig (a leg of 80 cm, the hips' OFFSET 90 up) turned `lean` degrees about the file's
    /// z at rest below the hips, and its BVH text of `n` frames whose root (in file order the first six
    /// values) has the values `root(frame)` and every other joint rotation zero.
    fn clip_text(lean: f32, n: usize, root: impl Fn(usize) -> [f32; 6]) -> String {
        clip_text_of(body(&torso("Head")), lean, n, root)
    }

    fn clip_text_of(rig: Vec<Spec>, lean: f32, n: usize, root: impl Fn(usize) -> [f32; 6]) -> String {
        let (s, c) = lean.to_radians().sin_cos();
        let joints: Vec<Spec> = rig
            .into_iter()
            .map(|(name, parent, [x, y, z])| match parent {
                None => (name, parent, [x, y, z]),
                Some(_) => (name, parent, [x * c - y * s, x * s + y * c, z]),
            })
            .collect();
        let frames: Vec<Vec<f32>> = (0..n)
            .map(|f| {
                let mut v = root(f).to_vec();
                v.resize(6 + 3 * (joints.len() - 1), 0.0);
                v
            })
            .collect();
        text(&joints, |i| i == 0, &frames)
    }

    fn import_error(text: &str, opts: &ImportOptions) -> String {
        import_with_report(text, "t.bvh", opts).unwrap_err().to_string()
    }

    #[test]
    fn a_skeleton_standing_along_y_at_rest_in_frames_lying_along_z_is_reported() {
        // Xrotation 90 turns the file's y to its z in every frame (Yrotation −90 its x to its z).
        let turned = |lean: f32, root: [f32; 6], opts: &ImportOptions| {
            import_with_report(&clip_text(lean, 3, |_| root), "t.bvh", opts).unwrap()
        };
        let lying = |lean: f32, opts: &ImportOptions| turned(lean, [0.0, 0.0, 90.0, 0.0, 90.0, 0.0], opts);
        let (clip, report) = lying(0.0, &ImportOptions::default());
        assert_eq!(report.up_axis, "z");
        assert_eq!(clip.skeleton_up, Some(("y".to_string(), "z".to_string())));
        // Leaning 20° at rest, y is still 0.94 of feet-to-head; at 30° (0.87) the rest pose says nothing.
        assert_eq!(lying(20.0, &ImportOptions::default()).0.skeleton_up, Some(("y".to_string(), "z".to_string())));
        assert_eq!(lying(30.0, &ImportOptions::default()).0.skeleton_up, None);
        // Standing along x at rest (as Bandai Namco's rigs do) says nothing either.
        let (clip, report) = turned(-90.0, [0.0, 0.0, 90.0, 0.0, 0.0, -90.0], &ImportOptions::default());
        assert_eq!((report.up_axis.as_str(), clip.skeleton_up), ("z", None));
        // A mapping's `up` is the user's word: no report.
        let up = ImportOptions { fps: None, mapping: Some(JointMapping::from_toml_str("up = \"z\"").unwrap()) };
        assert_eq!(lying(0.0, &up).0.skeleton_up, None);
        // Frames along y, as the rest pose: nothing to report.
        let standing = clip_text(0.0, 3, |_| [0.0, 90.0, 0.0, 0.0, 0.0, 0.0]);
        assert_eq!(import_with_report(&standing, "t.bvh", &ImportOptions::default()).unwrap().0.skeleton_up, None);
    }

    #[test]
    fn values_beyond_a_human_and_a_capture_volume_are_refused_naming_the_joint_channel_and_frame() {
        let opts = ImportOptions::default();
        // 10⁷ file units is accepted by the file check, but in centimetres it is 100 km from the origin.
        let far = clip_text(0.0, 3, |f| [if f == 1 { 1e7 } else { 0.0 }, 90.0, 0.0, 0.0, 0.0, 0.0]);
        assert_eq!(
            import_error(&far, &opts),
            "t.bvh: implausible motion: pelvis (BVH joint `Hips`) is 1e5 m from the origin in frame 2 (unit cm); a human \
             clip stays within 10000 m: check the file's OFFSET and position values"
        );
        let beyond = clip_text(0.0, 3, |f| [0.0, if f == 2 { 2e7 } else { 90.0 }, 0.0, 0.0, 0.0, 0.0]);
        assert!(import_error(&beyond, &opts).starts_with(
            "t.bvh: implausible motion: position channel 2 of joint `Hips` (line 2) is 2e7 file units in frame 3"
        ));
        // Rotations: a million degrees is a spinning root, more is not mocap.
        let spin = clip_text(0.0, 3, |f| [0.0, 90.0, 0.0, 1e6 * f as f32 / 2.0, 0.0, 0.0]);
        assert!(import_with_report(&spin, "t.bvh", &opts).is_ok());
        let beyond = clip_text(0.0, 3, |f| [0.0, 90.0, 0.0, 0.0, 0.0, if f == 1 { -1.5e6 } else { 0.0 }]);
        assert!(import_error(&beyond, &opts).starts_with(
            "t.bvh: implausible motion: rotation channel 6 of joint `Hips` (line 2) is -1.5e6° in frame 2"
        ));
    }

    #[test]
    fn offsets_beyond_ten_kilometres_in_millimetres_or_none_at_all_are_refused() {
        let opts = ImportOptions::default();
        let stand = clip_text(0.0, 1, |_| [0.0, 90.0, 0.0, 0.0, 0.0, 0.0]);
        let head = "OFFSET 0 8 0";
        assert!(stand.contains(head));
        let e = import_error(&stand.replacen(head, "OFFSET 0 2e7 0", 1), &opts);
        assert!(e.starts_with("t.bvh: implausible motion: joint `Head` (line "), "{e}");
        assert!(e.contains(") has an OFFSET of 2e7 file units"), "{e}");
        // An end site counts as a length too.
        let e = import_error(&stand.replace("OFFSET 0 1 0", "OFFSET 0 -3e7 0"), &opts);
        assert!(e.contains("has an OFFSET of 3e7 file units"), "{e}");
        // Every OFFSET and end site below the root zero: no bone lengths, whatever the root's.
        let flat: String = stand
            .lines()
            .enumerate()
            .map(|(i, l)| if l.starts_with("OFFSET") && i > 3 { "OFFSET 0 0 0".to_string() } else { l.to_string() })
            .collect::<Vec<_>>()
            .join("\n");
        assert!(flat.contains("OFFSET 0 90 0"));
        assert!(import_error(&flat, &opts).starts_with("t.bvh: every OFFSET below the root is zero: the skeleton (17 joints) has no bone lengths"));
        // A root alone (its end site a length) is not "every OFFSET zero".
        let alone = "HIERARCHY\nROOT Hips\n{\nOFFSET 0 90 0\nCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\nEnd Site\n{\nOFFSET 0 10 0\n}\n}\nMOTION\nFrames: 1\nFrame Time: 0.0333\n0 90 0 0 0 0\n";
        assert_eq!(
            import_error(alone, &opts),
            "t.bvh: the skeleton is one joint, `Hips`: a person is a hierarchy of joints (pelvis, spine, legs, arms, head)"
        );
        // Legs of no length (hip, knee and ankle at one place) in a body that has them.
        let mut rig = body(&torso("Head"));
        for joint in rig.iter_mut().filter(|j| matches!(j.0, "LeftLeg" | "LeftFoot" | "RightLeg" | "RightFoot")) {
            joint.2 = [0.0; 3];
        }
        // The matching does not take such legs, a mapping naming every joint does.
        let stubs = clip_text_of(rig, 0.0, 1, |_| [0.0, 90.0, 0.0, 0.0, 0.0, 0.0]);
        let names = [
            "Hips", "Spine", "Chest", "Neck", "Head", "LeftArm", "LeftForeArm", "LeftHand", "RightArm", "RightForeArm",
            "RightHand", "LeftUpLeg", "LeftLeg", "LeftFoot", "RightUpLeg", "RightLeg", "RightFoot",
        ];
        let mapping: String = Joint::ALL.iter().zip(names).map(|(j, n)| format!("{} = \"{n}\"\n", j.name())).collect();
        let named = ImportOptions { fps: None, mapping: Some(JointMapping::from_toml_str(&mapping).unwrap()) };
        assert_eq!(import_error(&stubs, &named), "t.bvh: the legs have zero length");
        // The end sites alone give lengths; the joints, all at one place, are then not a body.
        let sites = flat.replace("End Site\n{\nOFFSET 0 0 0", "End Site\n{\nOFFSET 0 1 0");
        let e = import_error(&sites, &opts);
        assert!(e.starts_with("t.bvh: unknown skeleton: could not map canonical joint(s) pelvis, spine"), "{e}");
    }

    #[test]
    fn a_target_frame_rate_must_be_positive_and_give_at_most_two_hours_at_sixty() {
        let t = clip_text(0.0, 3, |_| [0.0, 90.0, 0.0, 0.0, 0.0, 0.0]);
        let at = |fps: f32| ImportOptions { fps: Some(fps), mapping: None };
        for bad in [0.0, -30.0, f32::NAN, f32::INFINITY] {
            assert_eq!(import_error(&t, &at(bad)), format!("t.bvh: invalid target frame rate {bad}"));
        }
        // Three frames at 30 fps are 1/15 s: 7·10⁶ fps would make 466,667 frames.
        assert!(import_error(&t, &at(7e6)).contains("resampled to 7000000 fps would be 466667 frames; at most 432000"));
        assert_eq!(import_with_report(&t, "t.bvh", &at(600.0)).unwrap().0.frames.len(), 41);
        // The limit itself is allowed: three frames half a second apart are 1 s, 431,999 fps on them
        // 432,000 frames (checked on the header, without making them).
        let second = Bvh::parse(&t.replace("Frame Time: 0.0333333", "Frame Time: 0.5"), "t.bvh").unwrap();
        assert!(check_resampling(&second, 431_999.0, "t.bvh").is_ok());
        assert!(check_resampling(&second, 432_000.0, "t.bvh").is_err());
    }
}
