//! What the importer infers from the posed skeleton: how position channels combine with OFFSETs,
//! the up axis, leading rest-pose frames, and the true frame rate.

use nalgebra::Vector3;

use super::bvh::{Bvh, Channel};
use super::fk::Translation;
use super::matching::SkeletonMap;
use super::skeleton::{JOINT_COUNT, Joint};
use super::tracks::{Tracks, leg_length, lowest_foot, median, track};
use super::units::UpAxis;

/// Up direction from the posture: feet-to-head, averaged over frames.
pub(super) fn detect_up(tracks: &Tracks) -> UpAxis {
    let mut sum = Vector3::zeros();
    for p in &tracks.joints {
        let feet = (p[Joint::LeftFoot.index()] + p[Joint::RightFoot.index()]) * 0.5;
        let v = p[Joint::Head.index()] - feet;
        if let Some(n) = v.try_normalize(1e-12) {
            sum += n;
        }
    }
    UpAxis::nearest(&sum)
}

/// Choose per joint how position channels combine with the OFFSET. Constant channels (Bandai writes
/// every bone's OFFSET again as channels) are full translations when they equal the OFFSET and
/// displacements when they are near zero. For channels that move (the root's), the reading that puts the
/// feet on the floor (file height 0) wins: iClone adds to an OFFSET of (0, 105, 0), while MotionBuilder,
/// Bandai and LAFAN1 write absolute positions next to an OFFSET equal to the first frame's.
pub(super) fn detect_translation(bvh: &Bvh, map: &SkeletonMap) -> Vec<Translation> {
    let n = bvh.frame_count;
    let mut modes = vec![Translation::Replace; bvh.joints.len()];
    let mut moving = Vec::new();
    for (j, joint) in bvh.joints.iter().enumerate() {
        let (mut to_offset, mut to_zero, mut range, mut any) = (0.0f32, 0.0f32, 0.0f32, false);
        for (k, c) in joint.channels.iter().enumerate() {
            let Channel::Position(axis) = c else { continue };
            any = true;
            let col = (0..n).map(|f| bvh.values[f * bvh.channel_count + joint.first_channel + k]);
            let (lo, hi, sum) = col
                .fold((f32::INFINITY, f32::NEG_INFINITY, 0.0), |(lo, hi, s), v| {
                    (lo.min(v), hi.max(v), s + v)
                });
            let mean = sum / n as f32;
            range = range.max(hi - lo);
            to_offset += (mean - joint.offset[axis.index()]).abs();
            to_zero += mean.abs();
        }
        let size = joint.offset.norm();
        if !any || size < 1e-6 {
            continue;
        }
        if range > 1e-3 * size {
            moving.push(j);
        } else if to_zero < to_offset {
            modes[j] = Translation::AddToOffset;
        }
    }
    if !moving.is_empty() {
        let samples: Vec<usize> = (0..n.min(24)).map(|k| k * n / n.min(24)).collect();
        let score = |modes: &[Translation]| {
            let t = track(bvh, map, &samples, modes);
            let up = detect_up(&t).to_z_up().transpose() * Vector3::z();
            median(lowest_foot(&t, &up)).abs() / leg_length(&t).max(1e-9)
        };
        let mut added = modes.clone();
        for &r in &moving {
            added[r] = Translation::AddToOffset;
        }
        if score(&added) < score(&modes) {
            modes = added;
        }
    }
    modes
}

/// Mean displacement of the joints relative to the pelvis from frame `t` to `t + 1`.
fn pose_step(tracks: &Tracks, t: usize) -> f32 {
    let (a, b) = (&tracks.joints[t], &tracks.joints[t + 1]);
    let (pa, pb) = (a[0], b[0]);
    (0..JOINT_COUNT)
        .map(|k| ((a[k] - pa) - (b[k] - pb)).norm())
        .sum::<f32>()
        / JOINT_COUNT as f32
}

/// Number of leading frames that are a rest pose and the blend out of it, not motion. cgspeed's CMU
/// conversions (some MotionBuilder ones, all Daz ones) start with a T-pose frame, the Daz ones then blend
/// into the motion over a few frames; iClone exports are documented to do the same. Frame 0 counts as a
/// rest pose when the pose (relative to the pelvis) jumps from it far more than the clip's typical
/// frame-to-frame motion (or when `forced`); the following frames are dropped while they keep jumping.
pub(super) fn leading_rest_frames(tracks: &Tracks, leg: f32, forced: Option<bool>) -> usize {
    let n = tracks.frame_count();
    if n < 3 || forced == Some(false) {
        return 0;
    }
    let steps: Vec<f32> = (0..n - 1).map(|t| pose_step(tracks, t)).collect();
    let typical = median(steps.clone());
    let jump = (5.0 * typical).max(0.02 * leg);
    let rest = forced == Some(true) || (steps[0] > 0.05 * leg && steps[0] > 8.0 * typical);
    if !rest {
        return 0;
    }
    // The blend: at most a quarter of the clip, while steps stay above the jump threshold.
    1 + steps[1..]
        .iter()
        .take(n / 4)
        .take_while(|&&s| s > jump)
        .count()
}

/// Frame rates are written as rounded frame times (0.008333 s); snap to the whole rate they round
/// (120 fps) when within 0.01 %, so that timestamps of resampled clips line up.
pub(super) fn snap_fps(fps: f32) -> f32 {
    let r = fps.round();
    if r > 0.0 && (fps - r).abs() < 1e-4 * fps {
        r
    } else {
        fps
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::human::test_rig::{body, file_order, parse, torso};

    #[test]
    fn constant_position_channels_are_translations_at_their_offset_and_displacements_near_zero() {
        // Every joint has position channels that hold still (as Bandai's do) while the rotations move;
        // most repeat their OFFSET, give or take 0.1 on each axis.
        let joints = body(&torso("Head"));
        let written = |name: &str, offset: [f32; 3], f: f32| -> [f32; 3] {
            match name {
                "Hips" => [0.0, 45.0, 0.0],
                "Spine" => [offset[0] + 0.1, offset[1] + 0.1, offset[2] + 0.1],
                "LeftUpLeg" => [0.5, 0.5, 0.0],
                "RightUpLeg" => [0.0; 3],
                // Near zero and moving by less than 10⁻³ of the 40-unit bone: still displacements,
                // although the feet would stand on the floor (file height 0) with them as translations.
                "LeftLeg" | "RightLeg" => [0.0, 0.002 * f, 0.0],
                // Half way between its OFFSET (0, 15, 0) and zero: a full translation.
                "Neck" => [0.0, 7.5, 0.0],
                _ => offset,
            }
        };
        let frames: Vec<Vec<f32>> = (0..4)
            .map(|f| {
                file_order(&joints)
                    .into_iter()
                    .flat_map(|i| {
                        let (name, _, offset) = joints[i];
                        let [x, y, z] = written(name, offset, f as f32);
                        [x, y, z, 3.0 * f as f32 + i as f32, 2.0 * f as f32, 0.0]
                    })
                    .collect()
            })
            .collect();
        let b = parse(&joints, |_| true, &frames);
        let map = SkeletonMap::build(&b, None, "t.bvh").unwrap();
        let added: Vec<&str> = detect_translation(&b, &map)
            .iter()
            .zip(&b.joints)
            .filter(|(m, _)| **m == Translation::AddToOffset)
            .map(|(_, j)| j.name.as_str())
            .collect();
        assert_eq!(added, ["LeftUpLeg", "LeftLeg", "RightUpLeg", "RightLeg"]);
    }

    #[test]
    fn the_floor_reading_of_a_moving_root_samples_the_whole_clip() {
        // The root's channels stand it at (0, 90, 0), its OFFSET, in every frame but the first, where it
        // is at 0 (a person crouching, or a glitch): read as full translations the feet stand on the
        // floor (file height 0) in nine frames of ten; added to the OFFSET, only in the first.
        let joints = body(&torso("Head"));
        let frames: Vec<Vec<f32>> = (0..10)
            .map(|f| {
                let mut v = vec![0.0, if f == 0 { 0.0 } else { 90.0 }, 0.5 * f as f32, 0.0, 0.0, 0.0];
                v.resize(6 + 3 * (joints.len() - 1), 0.0);
                v
            })
            .collect();
        let b = parse(&joints, |i| i == 0, &frames);
        let map = SkeletonMap::build(&b, None, "t.bvh").unwrap();
        assert_eq!(detect_translation(&b, &map)[0], Translation::Replace);
    }

    /// Tracks of 40 frames around a still pelvis whose 16 other joints move by `steps[t]` from frame
    /// `t` to `t + 1` (a pose step of 16/17 of it), and by `drift` a frame after the given steps.
    fn stepping(steps: &[f32], drift: f32) -> Tracks {
        let mut y = 0.0;
        let joints = (0..40)
            .map(|t| {
                let frame = std::array::from_fn(|k| Vector3::new(k as f32 * 0.1, if k == 0 { 0.0 } else { y }, 0.0));
                y += steps.get(t).copied().unwrap_or(drift);
                frame
            })
            .collect();
        Tracks { joints, feet: vec![[Vector3::zeros(); 2]; 40] }
    }

    /// Frame 0 standing `jump` (and a frame's drift of 0.001) away from frame 1, on a leg of 1.
    fn drifting(jump: f32) -> Tracks {
        stepping(&[jump + 0.001], 0.001)
    }

    #[test]
    fn frame_zero_is_a_rest_pose_only_when_it_jumps_a_twentieth_of_the_leg() {
        // A jump of 0.032 + 0.001 on 16 of the 17 joints: 0.031 on average, 33 times the clip's
        // typical step but under 0.05 legs.
        assert_eq!(leading_rest_frames(&drifting(0.032), 1.0, None), 0);
        assert_eq!(leading_rest_frames(&drifting(0.1), 1.0, None), 1);
        assert_eq!(leading_rest_frames(&drifting(0.032), 1.0, Some(true)), 1);
        assert_eq!(leading_rest_frames(&drifting(0.1), 1.0, Some(false)), 0);
    }

    /// Tracks `at(x)` for the first x in steps of 1/1024 from 0 whose pose step `t` is, in f32, exactly
    /// `fraction` of some leg; and that leg.
    fn exact_leg(at: impl Fn(f32) -> Tracks, t: usize, fraction: f32) -> (Tracks, f32) {
        (0..256)
            .find_map(|k| {
                let tracks = at(k as f32 / 1024.0);
                let step = pose_step(&tracks, t);
                let near = (step / fraction).to_bits();
                let leg = (near - 4..=near + 4).map(f32::from_bits).find(|&leg| fraction * leg == step)?;
                Some((tracks, leg))
            })
            .expect("a leg of which the step is exactly the fraction")
    }

    #[test]
    fn a_jump_of_exactly_a_twentieth_of_the_leg_or_eight_typical_steps_is_not_a_rest_pose() {
        // Steps of powers of two, so that every pose step is exact: a first jump of 1 against 0.125 a
        // frame is exactly eight typical steps (both 16/17 of the joints' step).
        let eight = stepping(&[1.0], 0.125);
        assert_eq!(pose_step(&eight, 0), 8.0 * pose_step(&eight, 1));
        assert_eq!(leading_rest_frames(&eight, 1.0, None), 0);
        assert_eq!(leading_rest_frames(&stepping(&[1.125], 0.125), 1.0, None), 1);
        // A leg whose twentieth is exactly the first jump (about 0.5, some sixty typical steps): a jump
        // of a few 1/1024 more than 0.5 whose f32 has a leg of exactly twenty times it.
        let (far, leg) = exact_leg(|x| stepping(&[0.5 + x], 0.0078125), 0, 0.05);
        assert_eq!(leading_rest_frames(&far, leg, None), 0);
        assert_eq!(leading_rest_frames(&far, 0.999 * leg, None), 1);
    }

    #[test]
    fn the_blend_out_of_a_rest_pose_is_the_frames_that_jump_a_fiftieth_of_the_leg() {
        // In centimetres (a leg of 100): after the rest frame, two steps of 3 and one of 1, then the
        // clip's own 0.1 a frame. Only steps above 2 (a fiftieth of the leg; five typical steps are
        // 0.47) are the blend.
        let t = stepping(&[20.0, 3.0, 3.0, 1.0], 0.1);
        assert_eq!(leading_rest_frames(&t, 100.0, None), 3);
        // On a leg of 10 the step of 1 jumps too (0.2 a fiftieth, the five typical steps above it).
        assert_eq!(leading_rest_frames(&t, 10.0, None), 4);
        // A step of exactly a fiftieth of the leg is not the blend: steps of about 0.25 after a jump of 1,
        // then 1/128 a frame (powers of two, exact), on a leg of exactly fifty of them.
        let (t, leg) = exact_leg(|x| stepping(&[1.0, 0.25 + x, 0.25 + x], 0.0078125), 1, 0.02);
        assert_eq!(leading_rest_frames(&t, leg, None), 1);
        assert_eq!(leading_rest_frames(&t, 0.999 * leg, None), 3);
        // The blend takes at most a quarter of the clip: 10 of the 39 steps after the rest frame.
        let blend: Vec<f32> = std::iter::once(20.0).chain(std::iter::repeat_n(3.0, 15)).collect();
        assert_eq!(leading_rest_frames(&stepping(&blend, 0.1), 100.0, None), 11);
    }

    #[test]
    fn a_clip_of_fewer_than_three_frames_keeps_every_frame() {
        let cut = |n: usize| {
            let t = drifting(0.1);
            Tracks { joints: t.joints[..n].to_vec(), feet: t.feet[..n].to_vec() }
        };
        assert_eq!(leading_rest_frames(&cut(1), 1.0, Some(true)), 0);
        assert_eq!(leading_rest_frames(&cut(2), 1.0, Some(true)), 0);
        // Three frames: forced, frame 0 goes (the blend may take none of them, a quarter of three).
        assert_eq!(leading_rest_frames(&cut(3), 1.0, Some(true)), 1);
    }

    #[test]
    fn frame_rates_snap_to_the_whole_rate_their_rounded_frame_time_gives() {
        assert_eq!(snap_fps(1.0 / 0.008333), 120.0);
        assert_eq!(snap_fps(1.0 / 0.0333333), 30.0);
        // Within 10⁻⁴ of the rate only: 120.011 snaps, 120.013 and NTSC's 29.97 do not.
        assert_eq!(snap_fps(120.011), 120.0);
        assert_eq!(snap_fps(120.013), 120.013);
        assert_eq!(snap_fps(29.97), 29.97);
        assert_eq!(snap_fps(0.00001), 0.00001);
    }
}
