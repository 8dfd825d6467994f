//! The import pipeline: parse → map joints → forward kinematics → detect translation semantics, up
//! axis, rest-pose frame and unit → convert to metres, z up → root orientation per frame.

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

use super::bvh::Bvh;
use super::clip::{HumanClip, HumanFrame, ImportOptions};
use super::conventions;
use super::detect::{detect_translation, detect_up, leading_rest_frames, snap_fps};
use super::error::HumanImportError;
use super::fk::Translation;
use super::matching::SkeletonMap;
use super::skeleton::{JOINT_COUNT, Joint};
use super::tracks::{leg_length, lowest_foot, percentile, track};
use super::units::{NORMALISED_HEIGHT_M, detect_unit, parse_unit, parse_up};

/// Leg length (hip joint to ankle joint centre) as a fraction of standing height: hip joint at 0.530 H,
/// ankle at 0.039 H (Drillis & Contini 1966). Standing height is estimated from the legs because their
/// joint centres are anatomically the same in every rig, whereas the head joint sits anywhere from the
/// lower neck (CMU) to the skull base (Daz) and many rigs have no head-top end site.
pub const LEG_FRACTION_OF_HEIGHT: f32 = 0.491;

/// Percentile of the per-frame lowest foot point taken as the floor (robust to jumps and glitches).
pub const FLOOR_PERCENTILE: f32 = 0.05;

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

/// Import BVH text (see [`HumanClip::from_bvh_str`]), also returning what was detected.
pub fn import_with_report(
    text: &str,
    file: &str,
    opts: &ImportOptions,
) -> Result<(HumanClip, ImportReport), HumanImportError> {
    let bvh = Bvh::parse(text, file)?;
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
    let leg = leg_length(&tracks);
    if leg.is_nan() || leg <= 0.0 {
        return Err(HumanImportError::Skeleton {
            file: file.to_string(),
            message: "the legs have zero length".into(),
        });
    }
    let dropped = leading_rest_frames(&tracks, leg, user.and_then(|u| u.first_frame_is_rest_pose));
    tracks.joints.drain(..dropped);
    tracks.extra.drain(..dropped * tracks.extra_stride);

    let rot = up.to_z_up();
    let up_file = rot.transpose() * Vector3::z();
    let height_units = leg / LEG_FRACTION_OF_HEIGHT;
    let (unit, scale) = match user.and_then(|u| u.unit.as_deref()) {
        Some(s) => {
            let m = parse_unit(s).ok_or_else(|| HumanImportError::Mapping {
                file: file.to_string(),
                message: format!("unknown unit `{s}`"),
            })?;
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
    };
    if let Some(fps) = opts.fps {
        if !(fps.is_finite() && fps > 0.0) {
            return Err(HumanImportError::Skeleton {
                file: file.to_string(),
                message: format!("invalid target frame rate {fps}"),
            });
        }
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

pub(super) fn import(
    text: &str,
    file: &str,
    opts: &ImportOptions,
) -> Result<HumanClip, HumanImportError> {
    import_with_report(text, file, opts).map(|(clip, _)| clip)
}
