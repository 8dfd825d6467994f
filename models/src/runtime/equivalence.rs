//! The pure-Rust [`Retargeter`] against the libtorch one (`crate::learn::retarget`) on every shipped
//! checkpoint (`assets/checkpoints`) over the whole bundled clips (`assets/motions`), cleanup on.
//!
//! Frame by frame — both networks given the same previous state, each path's states through its own
//! decoder — the poses put every link of the character within [`TOLERANCE`] body lengths of where
//! libtorch puts it. The two compute the same operations with float sums in other orders (libtorch's
//! matrix products against `gemm`'s), and an autoregressive rollout feeds each frame's rounding back
//! into the next: where the prior's dynamics amplify it (the crab's walk), whole rollouts drift apart by
//! up to about 10⁻³ body lengths after a hundred frames, which is why the strict comparison is made
//! frame by frame and whole rollouts are held to [`ROLLOUT_TOLERANCE`].
//!
//! Frame by frame, the networks' outputs must agree within [`STATE_TOLERANCE`] on every frame. The
//! cleanup's decisions are thresholds (a foot plants below a height and a speed), so a difference of
//! 10⁻⁶ can put one path's foot on the other side of one for a frame; which frames depends on the CPU's
//! libtorch kernels (one frame of the bundled clips' 408 for the crab on one machine, none on another). So at most
//! [`FLIPPED_SHARE`] of the frames may exceed [`TOLERANCE`], and those only up to
//! [`ROLLOUT_TOLERANCE`].

use std::path::{Path, PathBuf};

use tch::Device;

use super::decode::{self, StateDecoder};
use super::Retargeter;
use crate::features::character_body_length;
use crate::human::{HumanClip, ImportOptions};
use crate::human_set::HumanRow;
use crate::kinematics::{CharacterPose, KinematicTree};
use crate::learn::retarget::Retargeter as TchRetargeter;
use crate::morphology::{Morphology, load_character};

/// Largest distance between the two paths' link positions frame by frame, in body lengths (the issue's
/// bar).
const TOLERANCE: f32 = 1e-4;

/// Largest difference between the two networks' outputs (normalised state units) on any frame.
const STATE_TOLERANCE: f32 = 2e-5;

/// Largest share of frames on which a cleanup threshold may decide differently (module docs).
const FLIPPED_SHARE: f32 = 0.01;

/// Largest distance between whole rollouts' link positions, in body lengths: a tenth of a millimetre
/// per metre of body grown, at most, from rounding (see [`whole_rollouts_of_both_paths_stay_together`]).
const ROLLOUT_TOLERANCE: f32 = 1e-2;

/// The shipped checkpoints and their characters' files under `assets/`.
const SHIPPED: [(&str, &str); 4] = [
    ("spot", "characters/spot.urdf"),
    ("crab", "characters/crab.urdf"),
    ("stretch", "characters/stretch.urdf"),
    ("hound", "creatures/hound.glb"),
];

fn assets() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets")
}

fn bundled_clips() -> Vec<(String, HumanClip)> {
    ["walk", "wave", "reach"]
        .iter()
        .map(|c| {
            let path = assets().join(format!("motions/{c}.bvh"));
            (c.to_string(), HumanClip::from_bvh_file(&path, &ImportOptions::default()).unwrap())
        })
        .collect()
}

/// The largest distance between the same link in `a[t]` and `b[t]` over all frames and links, in body
/// lengths, and the frame it occurs at.
fn max_link_error(tree: &KinematicTree, a: &[CharacterPose], b: &[CharacterPose], body: f32) -> (f32, usize) {
    frame_errors(tree, a, b, body)
        .into_iter()
        .enumerate()
        // NaN counts as the worst error.
        .fold((0.0f32, 0), |worst, (t, d)| if d <= worst.0 { worst } else { (d, t) })
}

/// Per frame, the largest distance between the same link in `a[t]` and `b[t]`, in body lengths (NaN
/// where a pose is not finite).
fn frame_errors(tree: &KinematicTree, a: &[CharacterPose], b: &[CharacterPose], body: f32) -> Vec<f32> {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(pa, pb)| {
            let (la, lb) = (tree.forward_kinematics(pa), tree.forward_kinematics(pb));
            la.iter()
                .zip(&lb)
                .map(|(x, y)| (x.translation.vector - y.translation.vector).norm() / body)
                .fold(0.0f32, |m, d| if d <= m { m } else { d })
        })
        .collect()
}

fn shipped(name: &str, file: &str) -> (KinematicTree, Morphology, TchRetargeter, Retargeter) {
    let (tree, morph) = load_character(&assets().join(file)).unwrap();
    let dir = assets().join("checkpoints").join(name);
    let tch = TchRetargeter::load(&dir, Device::Cpu).unwrap();
    let runtime = Retargeter::load(&dir).unwrap();
    (tree, morph, tch, runtime)
}

/// Per frame, both paths' poses for the same previous state: libtorch's rollout drives both networks
/// (so that float rounding cannot feed back and grow, see the module docs), and each path's states go
/// through its own decoder with the cleanup on, as a rollout's do; and the largest difference between
/// the two networks' outputs.
fn frame_by_frame(
    tree: &KinematicTree,
    morph: &Morphology,
    tch: &TchRetargeter,
    runtime: &Retargeter,
    rows: &[HumanRow],
) -> (Vec<CharacterPose>, Vec<CharacterPose>, f32) {
    let decoder = || StateDecoder::new(tree, morph, &runtime.cleanup, &runtime.record.correspondence.mapping, runtime.root_height_range);
    let (mut ours, mut theirs) = (decoder(), decoder());
    let mut prev = runtime.start_state(tree, morph).unwrap();
    let (mut got, mut want, mut raw) = (Vec::new(), Vec::new(), 0.0f32);
    for x in rows {
        let next = tch.networks(&[*x], std::slice::from_ref(&prev)).unwrap().remove(0);
        let mut state = runtime.denormalise(&next);
        want.push(theirs.decode(tree, morph, &mut state, Some(x)));
        let mine = runtime.networks(&[*x], &prev);
        // NaN counts as the worst difference.
        raw = next.iter().zip(&mine).map(|(a, b)| (a - b).abs()).fold(raw, |m, d| if d <= m { m } else { d });
        let mut state = runtime.denormalise(&mine);
        got.push(ours.decode(tree, morph, &mut state, Some(x)));
        prev = next;
    }
    (got, want, raw)
}

#[test]
fn runtime_poses_match_libtorch_frame_by_frame_on_every_shipped_checkpoint_over_whole_clips() {
    crate::learn::set_threads(1);
    let clips = bundled_clips();
    let mut failures = Vec::new();
    for (name, file) in SHIPPED {
        let (tree, morph, tch, runtime) = shipped(name, file);
        assert_eq!(runtime.character(), &tch.prior().character);
        assert_eq!(runtime.cleanup(), crate::cleanup::Cleanup::default(), "the cleanup is on");
        let body = character_body_length(&tree, &morph);
        let (mut worst, mut flipped, mut frames) = (0.0f32, 0usize, 0usize);
        for (clip_name, clip) in &clips {
            let (got, want, raw) = frame_by_frame(&tree, &morph, &tch, &runtime, &decode::clip_rows(clip));
            if !(raw <= STATE_TOLERANCE) {
                failures.push(format!("{name}, {clip_name}: the networks' outputs differ by {raw:.3e}"));
            }
            let errors = frame_errors(&tree, &got, &want, body);
            frames += errors.len();
            for (t, &e) in errors.iter().enumerate() {
                worst = if e <= worst { worst } else { e };
                if !(e <= TOLERANCE) {
                    flipped += 1;
                    if !(e <= ROLLOUT_TOLERANCE) {
                        failures.push(format!("{name}, {clip_name}: {e:.3e} body lengths at frame {t}"));
                    }
                }
            }
        }
        if flipped as f32 > FLIPPED_SHARE * frames as f32 {
            failures.push(format!("{name}: {flipped} of {frames} frames beyond {TOLERANCE} body lengths"));
        }
        // The figures the report quotes (run with --nocapture).
        println!(
            "{name}: largest link error frame by frame over the bundled clips {worst:.2e} body lengths; \
             {flipped} of {frames} frames beyond {TOLERANCE}"
        );
    }
    assert!(failures.is_empty(), "{failures:?}");
}

/// Whole rollouts, each path feeding back its own states: float rounding (a matrix product summed in
/// another order) grows along a rollout where the prior's dynamics amplify it, so they agree less
/// closely than frame by frame — as libtorch's own rollouts of one character alone and in a batch do.
/// Still within [`ROLLOUT_TOLERANCE`] over the whole clips.
#[test]
fn whole_rollouts_of_both_paths_stay_together() {
    crate::learn::set_threads(1);
    let clips = bundled_clips();
    for (name, file) in SHIPPED {
        let (tree, morph, tch, runtime) = shipped(name, file);
        let body = character_body_length(&tree, &morph);
        let mut worst = (0.0f32, String::new());
        for (clip_name, clip) in &clips {
            let want = tch.retarget_clip(&tree, &morph, clip).unwrap();
            let got = runtime.retarget_clip(&tree, &morph, clip).unwrap();
            assert_eq!((got.poses.len(), got.fps), (want.poses.len(), want.fps), "{name}, {clip_name}");
            let (err, frame) = max_link_error(&tree, &got.poses, &want.poses, body);
            if !(err <= worst.0) {
                worst = (err, format!("{clip_name}, frame {frame}"));
            }
        }
        println!("{name}: largest link error of whole rollouts {:.2e} body lengths ({})", worst.0, worst.1);
        assert!(worst.0 <= ROLLOUT_TOLERANCE, "{name}: {:.3e} body lengths at {}", worst.0, worst.1);
    }
}

#[test]
fn runtime_streams_stepped_together_match_libtorch_streams() {
    crate::learn::set_threads(1);
    let (name, file) = SHIPPED[0];
    let (tree, morph, tch, runtime) = shipped(name, file);
    let body = character_body_length(&tree, &morph);
    let clips = bundled_clips();
    let rows: Vec<Vec<HumanRow>> = clips.iter().map(|(_, c)| decode::clip_rows(c)).collect();
    let frames = rows.iter().map(Vec::len).min().unwrap();
    let mut ours: Vec<_> = rows.iter().map(|_| runtime.stream(&tree, &morph).unwrap()).collect();
    let mut theirs: Vec<_> = rows.iter().map(|_| tch.stream(&tree, &morph).unwrap()).collect();
    let (mut got, mut want) = (vec![Vec::new(); rows.len()], vec![Vec::new(); rows.len()]);
    for t in 0..frames {
        let x: Vec<HumanRow> = rows.iter().map(|r| r[t]).collect();
        let a = runtime.step(&tree, &morph, &mut ours.iter_mut().collect::<Vec<_>>(), &x).unwrap();
        let b = tch.step(&tree, &morph, &mut theirs.iter_mut().collect::<Vec<_>>(), &x).unwrap();
        for (i, (fa, fb)) in a.into_iter().zip(b).enumerate() {
            got[i].push(fa.pose);
            want[i].push(fb.pose);
        }
    }
    for (i, (g, w)) in got.iter().zip(&want).enumerate() {
        let (err, frame) = max_link_error(&tree, g, w, body);
        assert!(err <= TOLERANCE, "{}: {err:.3e} body lengths at frame {frame}", clips[i].0);
    }
    // A stream alone is the whole-motion rollout itself.
    let whole = runtime.retarget_states(&tree, &morph, &rows[0][..frames]).unwrap();
    let mut alone = runtime.stream(&tree, &morph).unwrap();
    for (t, x) in rows[0][..frames].iter().enumerate() {
        let f = runtime.step(&tree, &morph, &mut [&mut alone], &[*x]).unwrap().remove(0);
        assert_eq!(f.pose, whole.poses[t], "frame {t}");
        assert_eq!(f.state, whole.states[t], "frame {t}");
    }
    let err = runtime.step(&tree, &morph, &mut [&mut alone], &[rows[0][0], rows[0][1]]).unwrap_err();
    assert!(err.to_string().contains("2 human states for 1 characters"), "{err}");
}
