//! A creature's joint limits: from the range its own clips turn each axis through, with a margin, and
//! never narrower than its role's defaults.

mod common;
use common::creatures;

use ace_models::character::body_plan::{MIN_CLIP_RANGE, Role, clip_limits, default_limits};
use ace_models::character::clips::clip_poses;
use ace_models::character::load_creature;

#[test]
fn clip_limits_widen_the_keyed_range_by_its_margin_and_hold_the_rest_pose() {
    let deg = |d: f32| d.to_radians();
    let angles = [[-0.2, 0.1, 0.0], [0.4, 0.3, 0.5 * MIN_CLIP_RANGE], [0.1, 0.2, 0.0]];
    let [yaw, pitch, roll] = clip_limits(&angles);
    // 15 % of the range and 3° on each side.
    let m = 0.15 * 0.6 + deg(3.0);
    let (lo, hi) = yaw.unwrap();
    assert!((lo - (-0.2 - m)).abs() < 1e-6 && (hi - (0.4 + m)).abs() < 1e-6, "{yaw:?}");
    // A range on one side of the rest pose still reaches back to it.
    let m = 0.15 * 0.2 + deg(3.0);
    let (lo, hi) = pitch.unwrap();
    assert!(lo == 0.0 && (hi - (0.3 + m)).abs() < 1e-6, "{pitch:?}");
    assert_eq!(roll, None, "an axis the clips barely turn is not a DoF");
    // An axis held still away from rest reaches where it is held (the default range once took over).
    let [yaw, pitch, _] = clip_limits(&[[0.5, -0.6 * MIN_CLIP_RANGE, 0.0]; 3]);
    let (lo, hi) = yaw.unwrap();
    assert!(lo == 0.0 && (hi - (0.5 + deg(3.0))).abs() < 1e-6, "{yaw:?}");
    assert_eq!(pitch, None, "held still near rest");
    // Never beyond a half turn.
    let [yaw, ..] = clip_limits(&[[-3.0, 0.0, 0.0], [3.0, 0.0, 0.0]]);
    assert_eq!(yaw, Some((-std::f32::consts::PI, std::f32::consts::PI)));
    assert_eq!(clip_limits(&[]), [None; 3]);
}

fn role_of(label: &str) -> Role {
    match label {
        "hip" => Role::Leg { first: true },
        "leg" => Role::Leg { first: false },
        "shoulder" => Role::Arm { first: true },
        "arm" => Role::Arm { first: false },
        "head" => Role::Head,
        "spine" => Role::Spine,
        "tail" => Role::Tail,
        other => panic!("unknown role {other}"),
    }
}

/// On the Fox, whose clips walk, run and look about: every DoF's range holds its role's default range,
/// and the clips played on the tree stay inside their limits with room to spare, except where a clip
/// turns a bone about an axis its role does not have.
#[test]
fn the_foxs_limits_hold_its_clips_and_its_roles_defaults() {
    let Some(dir) = creatures() else { return };
    let fox = load_creature(&dir.join("Fox/Fox.glb")).unwrap();
    let names = fox.tree.dof_names().iter().map(|s| s.to_string()).collect::<Vec<_>>();
    let mut wider = 0;
    for j in &fox.plan.joints {
        let name = &fox.rig.bones[j.bone].name;
        let Some(role) = fox.plan.roles.get(name).map(|l| role_of(l)) else { continue };
        for (k, dof) in j.dofs.iter().enumerate() {
            let Some(dof) = *dof else { continue };
            let l = fox.tree.limits(dof).unwrap();
            if let Some((lo, hi)) = default_limits(role)[k] {
                assert!(l.lower <= lo + 1e-6 && l.upper >= hi - 1e-6, "{}: {:?} inside the default {lo}..{hi}", names[dof], (l.lower, l.upper));
                wider += usize::from(l.lower < lo - 1e-3 || l.upper > hi + 1e-3);
            }
        }
    }
    assert!(wider >= 4, "the clips widen some joints beyond their defaults ({wider})");
    // Each clip, sampled at 30 fps, keeps every DoF at least 2° inside its limits where the clip set them.
    let mut closest = f32::INFINITY;
    for clip in 0..fox.rig.animations.len() {
        for pose in clip_poses(&fox, clip, 30.0) {
            for (d, &q) in pose.q.iter().enumerate() {
                let l = fox.tree.limits(d).unwrap();
                closest = closest.min((q - l.lower).min(l.upper - q));
            }
        }
    }
    println!("{wider} DoFs wider than their defaults; closest to a limit {closest} rad");
    assert!(closest >= 2f32.to_radians(), "a clip comes {closest} rad from a limit");
}
