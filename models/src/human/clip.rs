//! Imported human clips on the canonical skeleton: frames, timing, resampling and interpolation.

use std::path::Path;

use nalgebra::{UnitQuaternion, Vector3};

use super::error::HumanImportError;
use super::mapping::JointMapping;
use super::skeleton::{JOINT_COUNT, Joint};
use super::units::{NORMALISED_HEIGHT_M, PLAUSIBLE_HEIGHT_M};

/// The fastest a person's pelvis moves between two frames in a capture (m/s). A sprinter peaks at about
/// 12 m/s after some 40 m, farther than any capture volume; the shared clips stay under 8 m/s but for
/// one glitch of 14 m/s (a salsa clip whose root jumps 12 cm in one 120 fps frame).
pub const MAX_ROOT_SPEED: f32 = 10.0;

/// The lowest frame rate (frames per second) taken for motion capture without a warning
/// ([`HumanClip::frame_rate_warning`]).
pub const SLOWEST_MOCAP_FPS: f32 = 10.0;

/// One frame: world positions of the 17 canonical joints (metres, z up) and the pelvis' world
/// orientation (its local x = facing direction, z = up when standing upright).
#[derive(Clone, Debug, PartialEq)]
pub struct HumanFrame {
    pub positions: [Vector3<f32>; JOINT_COUNT],
    pub root_rotation: UnitQuaternion<f32>,
}

impl HumanFrame {
    /// Position of canonical joint `j`.
    pub fn position(&self, j: Joint) -> Vector3<f32> {
        self.positions[j.index()]
    }

    /// The facing direction: the pelvis' local x projected on the ground (not normalised; may be ~0
    /// when the pelvis faces straight up or down).
    pub fn forward(&self) -> Vector3<f32> {
        let x = self.root_rotation * Vector3::x();
        Vector3::new(x.x, x.y, 0.0)
    }

    /// Linear interpolation of positions and slerp of the root rotation, `s` in [0, 1].
    pub fn lerp(&self, other: &HumanFrame, s: f32) -> HumanFrame {
        HumanFrame {
            positions: std::array::from_fn(|k| self.positions[k].lerp(&other.positions[k], s)),
            root_rotation: self
                .root_rotation
                .try_slerp(&other.root_rotation, s, 1e-6)
                .unwrap_or(if s < 0.5 {
                    self.root_rotation
                } else {
                    other.root_rotation
                }),
        }
    }
}

/// Options of [`HumanClip::from_bvh_file`] and [`HumanClip::from_bvh_str`].
#[derive(Clone, Debug, Default)]
pub struct ImportOptions {
    /// Resample to this frame rate (frames per second); `None` keeps the file's rate.
    pub fps: Option<f32>,
    /// Joint names (and unit/up overrides) for skeletons the automatic matching cannot handle.
    pub mapping: Option<JointMapping>,
}

/// A human motion clip on the canonical 17-joint skeleton, in metres, z up.
#[derive(Clone, Debug)]
pub struct HumanClip {
    /// File stem (or the name given to [`HumanClip::from_bvh_str`]).
    pub name: String,
    /// Recognised skeleton convention (see [`crate::human::conventions`]), e.g. `cmu-cgspeed-mb`,
    /// `daz`, `iclone`, `humanik`, `bandai`, `mixamo`, `lafan1`, or `user-mapping` / `generic`.
    pub convention: String,
    /// Detected (or overridden) unit, e.g. `cmu`, `cm`, `m`, `inch`, or
    /// `unknown (normalised to 1.70 m)`.
    pub unit: String,
    /// Frame rate of the file.
    pub source_fps: f32,
    /// Frame rate of `frames`.
    pub fps: f32,
    pub frames: Vec<HumanFrame>,
    /// Standing height (feet to top of head), metres.
    pub height_m: f32,
    /// Number of canonical joints mapped (17 when import succeeded).
    pub mapped_joints: usize,
    /// The BVH joint each canonical joint came from, in [`Joint::ALL`] order
    /// (`midpoint(A, B)` where a joint was placed between two).
    pub source_joints: [String; JOINT_COUNT],
    /// When the skeleton stands along the file's +y axis (BVH's up) in its rest pose (every rotation
    /// zero) but the up axis taken from the clip's posture is another: `(skeleton's, taken)`, as the
    /// file's axes (`"y"`, `"-z"`). A person lying or crawling through most of a clip makes a
    /// horizontal axis look like up, and then the frames look upright ([`HumanClip::posture_warning`]
    /// says so). `None` when they agree, or when a joint mapping gives `up`.
    pub skeleton_up: Option<(String, String)>,
    /// The file's other skeletons (their `ROOT` joints), left out: a file of two performers is
    /// retargeted from the one the canonical joints were found on ([`HumanClip::skeletons_warning`]).
    pub other_skeletons: Vec<String>,
}

impl HumanClip {
    /// Import a BVH file. The clip is named after the file stem. Without a mapping in `opts`, a
    /// joint-mapping file beside the clip ([`mapping_path_beside`]) is used when there is one (one
    /// that is there but is not a regular file, such as a FIFO, is an error naming it, not skipped).
    pub fn from_bvh_file(path: &Path, opts: &ImportOptions) -> Result<HumanClip, HumanImportError> {
        let file = path.display().to_string();
        let bytes = read_regular_file(path)?;
        let text = decode_text(&bytes, &file)?;
        let beside;
        let opts = match &opts.mapping {
            None if mapping_path_beside(path).exists() => {
                beside = ImportOptions {
                    fps: opts.fps,
                    mapping: Some(JointMapping::from_file(&mapping_path_beside(path))?),
                };
                &beside
            }
            _ => opts,
        };
        let mut clip = super::import::import(&text, &file, opts)?;
        clip.name = path
            .file_stem()
            .map_or(file, |s| s.to_string_lossy().into_owned());
        Ok(clip)
    }

    /// Import BVH text; `name` names the clip and appears in error messages.
    pub fn from_bvh_str(
        text: &str,
        name: &str,
        opts: &ImportOptions,
    ) -> Result<HumanClip, HumanImportError> {
        super::import::import(text, name, opts)
    }

    /// Fraction of frames whose pelvis is upright: its up axis within 60° of vertical.
    pub fn upright_fraction(&self) -> f32 {
        let upright = self
            .frames
            .iter()
            .filter(|f| (f.root_rotation * Vector3::z()).z >= 0.5)
            .count();
        upright as f32 / self.frames.len().max(1) as f32
    }

    /// A warning when most of the clip's frames have the pelvis far from upright (a person lying or
    /// crawling): the human state is read in the pelvis' heading frame, and a character trained on
    /// upright humans turns such a clip into motion the user did not intend. Also when the person lies
    /// through most of the clip, which made the up axis taken from its posture horizontal
    /// ([`HumanClip::skeleton_up`]).
    pub fn posture_warning(&self) -> Option<String> {
        if let Some((skeleton, taken)) = &self.skeleton_up {
            let beside = self.mapping_file_name();
            return Some(format!(
                "{}: the person seems to lie or crawl through most of the clip: the skeleton stands along the \
                 file's {skeleton} axis in its rest pose, but the frames' feet-to-head direction is along its {taken} \
                 axis, which was taken as up. ACE is trained on upright humans, so a lying or crawling clip may drive \
                 the character in unintended ways (e.g. walking backwards); to import it as lying, give \
                 `up = \"{skeleton}\"` in a joint-mapping file (--mapping FILE or {beside})",
                self.name
            ));
        }
        let f = self.upright_fraction();
        (f < 0.5).then(|| {
            format!(
                "{}: the pelvis is upright (within 60° of vertical) in only {:.0} % of the frames; \
                 ACE is trained on upright humans, so a lying or crawling clip may drive the character \
                 in unintended ways (e.g. walking backwards)",
                self.name,
                100.0 * f
            )
        })
    }

    /// The largest jump of the pelvis between two frames: its speed (m/s) and the time (s) of the
    /// frame it jumps to.
    pub fn fastest_root_move(&self) -> Option<(f32, f32)> {
        let pelvis = Joint::Pelvis.index();
        self.frames
            .windows(2)
            .enumerate()
            .map(|(k, w)| ((w[1].positions[pelvis] - w[0].positions[pelvis]).norm() * self.fps, (k + 1) as f32 / self.fps))
            .max_by(|a, b| a.0.total_cmp(&b.0))
    }

    /// A warning when the pelvis moves faster than [`MAX_ROOT_SPEED`] between two frames: a cut, a
    /// mocap glitch or two takes joined, which the character would follow as a lurch.
    pub fn root_jump_warning(&self) -> Option<String> {
        let (speed, t) = self.fastest_root_move()?;
        (speed > MAX_ROOT_SPEED).then(|| {
            format!(
                "{}: the pelvis jumps {:.2} m in one frame at {t:.2} s ({speed:.0} m/s; a person moves at most \
                 {MAX_ROOT_SPEED} m/s): the clip is cut or glitched there, and the character will lurch",
                self.name,
                speed / self.fps
            )
        })
    }

    /// The name of the joint-mapping file read beside the clip ([`mapping_path_beside`]), for warnings.
    fn mapping_file_name(&self) -> String {
        mapping_path_beside(Path::new(&self.name)).file_name().map_or_else(String::new, |f| f.to_string_lossy().into_owned())
    }

    /// A warning when no length unit made the performer an adult's height, so that the skeleton was
    /// scaled to [`NORMALISED_HEIGHT_M`] ([`HumanClip::unit`] says `unknown`): a child, a very tall
    /// performer or a file rescaled by hand then has the steps and reach of someone 1.70 m tall.
    pub fn unit_warning(&self) -> Option<String> {
        self.unit.starts_with("unknown").then(|| {
            let beside = self.mapping_file_name();
            let (lo, hi) = PLAUSIBLE_HEIGHT_M;
            format!(
                "{}: no length unit (CMU's, cm, m, inch, mm) makes the performer {lo} to {hi} m tall, so the skeleton is \
                 scaled to {NORMALISED_HEIGHT_M:.2} m, and the character follows steps and reaches of that size; for a \
                 child, a very tall performer or a file rescaled by hand, give its `unit` (e.g. `unit = \"m\"`) in a \
                 joint-mapping file (--mapping FILE or {beside})",
                self.name
            )
        })
    }

    /// A warning when the file's frame rate is below [`SLOWEST_MOCAP_FPS`]: most often a `Frame Time`
    /// written in milliseconds (8.333333 for 120 fps made a clip of 149 frames last 21 minutes).
    pub fn frame_rate_warning(&self) -> Option<String> {
        (self.source_fps < SLOWEST_MOCAP_FPS).then(|| {
            let seconds = 1.0 / self.source_fps;
            format!(
                "{}: a `Frame Time` of {seconds:.4} s is {:.3} frames per second, where motion capture runs at 24 to 240, \
                 so the clip lasts {:.0} s; a frame time in milliseconds must be written in seconds ({:.6})",
                self.name,
                self.source_fps,
                self.duration(),
                seconds / 1000.0
            )
        })
    }

    /// A warning when the file holds other skeletons than the one retargeted (a capture of two people).
    pub fn skeletons_warning(&self) -> Option<String> {
        (!self.other_skeletons.is_empty()).then(|| {
            let others: Vec<String> = self.other_skeletons.iter().map(|r| format!("`{r}`")).collect();
            format!(
                "{}: the file holds {} skeletons; the one whose pelvis is `{}` is retargeted, and the one(s) of ROOT {} left \
                 out (a joint-mapping file naming another skeleton's joints, --mapping FILE or {}, selects it)",
                self.name,
                others.len() + 1,
                self.source_joints[Joint::Pelvis.index()],
                others.join(", "),
                self.mapping_file_name()
            )
        })
    }

    /// Every warning about the clip's content ([`HumanClip::unit_warning`],
    /// [`HumanClip::frame_rate_warning`], [`HumanClip::skeletons_warning`],
    /// [`HumanClip::posture_warning`], [`HumanClip::root_jump_warning`]).
    pub fn warnings(&self) -> Vec<String> {
        self.unit_warning()
            .into_iter()
            .chain(self.frame_rate_warning())
            .chain(self.skeletons_warning())
            .chain(self.posture_warning())
            .chain(self.root_jump_warning())
            .collect()
    }

    /// Seconds from the first to the last frame.
    pub fn duration(&self) -> f32 {
        self.frames.len().saturating_sub(1) as f32 / self.fps
    }

    /// The pose at time `t` seconds, interpolated between frames and clamped to the clip.
    ///
    /// # Panics
    /// If the clip has no frames (imported clips always have at least one).
    pub fn frame_at(&self, t: f32) -> HumanFrame {
        let last = self.frames.len() - 1;
        let mut x = (t * self.fps).clamp(0.0, last as f32);
        // Snap times that fall on a frame (up to rounding) onto it, so resampling reproduces frames exactly.
        if (x - x.round()).abs() < 1e-3 {
            x = x.round();
        }
        let i = (x.floor() as usize).min(last);
        let s = x - i as f32;
        if i == last || s <= 0.0 {
            self.frames[i].clone()
        } else {
            self.frames[i].lerp(&self.frames[i + 1], s)
        }
    }

    /// The clip resampled to `fps` frames per second (linear positions, slerp rotations). The first
    /// frame is kept; frames follow every 1/fps seconds up to the clip's duration.
    pub fn resampled(&self, fps: f32) -> HumanClip {
        assert!(
            fps.is_finite() && fps > 0.0,
            "resampled: fps must be positive, got {fps}"
        );
        // Tolerate rounding so that e.g. 120 → 30 fps keeps a last frame that falls exactly on the end.
        let count = (self.duration() * fps + 1e-3).floor() as usize + 1;
        let frames = (0..count).map(|k| self.frame_at(k as f32 / fps)).collect();
        HumanClip {
            name: self.name.clone(),
            convention: self.convention.clone(),
            unit: self.unit.clone(),
            source_fps: self.source_fps,
            fps,
            frames,
            height_m: self.height_m,
            mapped_joints: self.mapped_joints,
            source_joints: self.source_joints.clone(),
            skeleton_up: self.skeleton_up.clone(),
            other_skeletons: self.other_skeletons.clone(),
        }
    }
}

/// The joint-mapping file read with a clip when no mapping is given: `walk.mapping.toml` beside
/// `walk.bvh`.
pub fn mapping_path_beside(clip: &Path) -> std::path::PathBuf {
    let stem = clip
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    clip.with_file_name(format!("{stem}.mapping.toml"))
}

/// The bytes of `path`, which must be a regular file (a FIFO or device named `.bvh` would block the
/// reader or never end): [`crate::input::read_regular`].
pub fn read_regular_file(path: &Path) -> Result<Vec<u8>, HumanImportError> {
    crate::input::read_regular(path, crate::input::MAX_BVH_BYTES).map_err(|e| read_error(&path.display().to_string(), e))
}

/// A [`crate::input::ReadError`] of the human-motion file `file` (a clip or a joint mapping).
pub(crate) fn read_error(file: &str, e: crate::input::ReadError) -> HumanImportError {
    match e {
        crate::input::ReadError::Io(error) => HumanImportError::Io {
            file: file.to_string(),
            error,
        },
        other => HumanImportError::Skeleton {
            file: file.to_string(),
            message: other.to_string(),
        },
    }
}

/// BVH text from file bytes: UTF-8 (invalid bytes replaced, as in names from Latin-1 exporters),
/// but UTF-16 ([`crate::input::looks_utf16`]) is refused with a hint rather than read as NUL-riddled
/// garbage.
pub fn decode_text<'a>(
    bytes: &'a [u8],
    file: &str,
) -> Result<std::borrow::Cow<'a, str>, HumanImportError> {
    if crate::input::looks_utf16(bytes) {
        return Err(HumanImportError::Parse {
            file: file.to_string(),
            line: 1,
            message: crate::input::ReadError::Utf16.to_string(),
        });
    }
    Ok(String::from_utf8_lossy(bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A clip at `fps` whose pelvis is at `pelvis[t]` (every other joint at the origin) and turned by
    /// `tilt[t]` radians about x (0: upright).
    fn clip(fps: f32, pelvis: &[[f32; 3]], tilt: &[f32]) -> HumanClip {
        let frames = pelvis
            .iter()
            .zip(tilt)
            .map(|(p, &a)| {
                let mut positions = [Vector3::zeros(); JOINT_COUNT];
                positions[Joint::Pelvis.index()] = Vector3::from(*p);
                HumanFrame { positions, root_rotation: UnitQuaternion::from_euler_angles(a, 0.0, 0.0) }
            })
            .collect();
        HumanClip {
            name: "dir/take.bvh".into(),
            convention: "generic".into(),
            unit: "m".into(),
            source_fps: fps,
            fps,
            frames,
            height_m: 1.7,
            mapped_joints: JOINT_COUNT,
            source_joints: std::array::from_fn(|_| String::new()),
            skeleton_up: None,
            other_skeletons: Vec::new(),
        }
    }

    fn still(n: usize) -> Vec<[f32; 3]> {
        vec![[0.0; 3]; n]
    }

    #[test]
    fn a_clip_scaled_to_the_normalised_height_says_how_to_give_its_unit() {
        let mut c = clip(30.0, &still(2), &[0.0, 0.0]);
        assert_eq!(c.unit_warning(), None);
        c.unit = "unknown (normalised to 1.70 m)".into();
        let w = c.unit_warning().unwrap();
        assert!(w.starts_with("dir/take.bvh: no length unit (CMU's, cm, m, inch, mm) makes the performer 1.4 to 2 m tall, so the skeleton is scaled to 1.70 m"), "{w}");
        assert!(w.ends_with("joint-mapping file (--mapping FILE or take.mapping.toml)"), "{w}");
        assert_eq!(c.warnings(), [w]);
    }

    #[test]
    fn a_frame_time_in_milliseconds_is_warned_of() {
        // `Frame Time: 8.333333` (120 fps written in ms), 37 frames: 5 minutes.
        let c = clip(0.12, &still(37), &[0.0; 37]);
        let w = c.frame_rate_warning().unwrap();
        assert!(w.starts_with("dir/take.bvh: a `Frame Time` of 8.3333 s is 0.120 frames per second"), "{w}");
        assert!(w.contains("so the clip lasts 300 s") && w.ends_with("written in seconds (0.008333)"), "{w}");
        assert_eq!(c.warnings(), [w]);
        assert_eq!(clip(SLOWEST_MOCAP_FPS, &still(2), &[0.0; 2]).frame_rate_warning(), None);
        assert!(clip(9.9, &still(2), &[0.0; 2]).frame_rate_warning().is_some());
    }

    #[test]
    fn the_pelvis_is_upright_within_sixty_degrees_of_vertical() {
        let upright = clip(30.0, &still(4), &[0.0, 0.3, -1.0, 1.2]);
        assert_eq!(upright.upright_fraction(), 0.75);
        assert_eq!(upright.posture_warning(), None);
        let lying = clip(30.0, &still(4), &[0.0, 1.1, -1.1, 1.6]);
        assert_eq!(lying.upright_fraction(), 0.25);
        let warning = lying.posture_warning().unwrap();
        assert!(warning.starts_with("dir/take.bvh: the pelvis is upright (within 60° of vertical) in only 25 % of the frames"), "{warning}");
        // Half the frames upright is not "most of the clip" lying.
        assert_eq!(clip(30.0, &still(2), &[0.0, 1.6]).posture_warning(), None);
    }

    #[test]
    fn a_skeleton_standing_along_another_axis_than_its_frames_is_a_lying_clip() {
        let mut c = clip(30.0, &still(2), &[0.0, 0.0]);
        c.skeleton_up = Some(("y".into(), "-z".into()));
        let warning = c.posture_warning().unwrap();
        assert!(warning.starts_with("dir/take.bvh: the person seems to lie or crawl"), "{warning}");
        assert!(warning.contains("along the file's y axis in its rest pose, but the frames' feet-to-head direction is along its -z axis"), "{warning}");
        assert!(warning.ends_with("give `up = \"y\"` in a joint-mapping file (--mapping FILE or take.mapping.toml)"), "{warning}");
        assert_eq!(c.warnings(), [warning]);
    }

    #[test]
    fn the_fastest_root_move_is_the_largest_pelvis_jump_and_the_time_it_lands() {
        let c = clip(100.0, &[[0.0; 3], [0.01, 0.0, 0.0], [0.01, 0.3, 0.4], [0.01, 0.31, 0.4]], &[0.0; 4]);
        let (speed, t) = c.fastest_root_move().unwrap();
        assert!((speed - 50.0).abs() < 1e-3 && (t - 0.02).abs() < 1e-6, "{speed} m/s at {t} s");
        let warning = c.root_jump_warning().unwrap();
        assert!(warning.starts_with("dir/take.bvh: the pelvis jumps 0.50 m in one frame at 0.02 s (50 m/s"), "{warning}");
        assert_eq!(c.warnings(), [warning]);
        // 9 m/s is a sprint, not a jump; a clip of one frame does not move.
        let run = clip(100.0, &[[0.0; 3], [0.09, 0.0, 0.0], [0.18, 0.0, 0.0]], &[0.0; 3]);
        assert_eq!(run.root_jump_warning(), None);
        assert!(run.warnings().is_empty());
        // 10 m/s exactly (1 m in a tenth of a second) is still a person.
        let sprint = clip(10.0, &[[0.0; 3], [1.0, 0.0, 0.0]], &[0.0; 2]);
        assert_eq!(sprint.fastest_root_move(), Some((10.0, 0.1)));
        assert_eq!(sprint.root_jump_warning(), None);
        assert_eq!(clip(100.0, &still(1), &[0.0]).fastest_root_move(), None);
    }

    #[test]
    fn frames_between_samples_interpolate_positions_and_slerp_the_pelvis() {
        let c = clip(10.0, &[[0.0; 3], [1.0, 0.0, 0.0], [1.0, 2.0, 0.0]], &[0.0, 1.0, 1.0]);
        assert!((c.duration() - 0.2).abs() < 1e-6);
        assert_eq!(clip(10.0, &still(1), &[0.0]).duration(), 0.0);
        let f = c.frame_at(0.025);
        assert!((f.position(Joint::Pelvis) - Vector3::new(0.25, 0.0, 0.0)).norm() < 1e-5);
        assert!((f.root_rotation.angle() - 0.25).abs() < 1e-5);
        let f = c.frame_at(0.15);
        assert!((f.position(Joint::Pelvis) - Vector3::new(1.0, 1.0, 0.0)).norm() < 1e-5);
        // Within a thousandth of a frame of a sample: the sample itself.
        assert_eq!(c.frame_at(0.10001), c.frames[1]);
        assert_ne!(c.frame_at(0.1002), c.frames[1]);
        assert_eq!(c.frame_at(-1.0), c.frames[0]);
        assert_eq!(c.frame_at(0.2), c.frames[2]);
        assert_eq!(c.frame_at(5.0), c.frames[2]);
    }

    #[test]
    fn resampling_keeps_the_first_frame_and_steps_to_the_end() {
        let pelvis: Vec<[f32; 3]> = (0..121).map(|k| [k as f32 / 120.0, 0.0, 0.0]).collect();
        let c = clip(120.0, &pelvis, &[0.0; 121]);
        let slow = c.resampled(30.0);
        assert_eq!((slow.fps, slow.source_fps, slow.frames.len()), (30.0, 120.0, 31));
        assert_eq!(slow.frames[0], c.frames[0]);
        assert_eq!(slow.frames[30], c.frames[120]);
        assert!((slow.frames[7].position(Joint::Pelvis).x - 7.0 / 30.0).abs() < 1e-5);
        // 1 s at 8.5 fps: frames at 0, 1/8.5, …, 8/8.5 (the next, at 1.06 s, would pass the end).
        assert_eq!(c.resampled(8.5).frames.len(), 9);
    }

    #[test]
    fn the_mapping_file_beside_a_clip_is_named_after_its_stem() {
        assert_eq!(mapping_path_beside(Path::new("mocap/walk.bvh")), Path::new("mocap/walk.mapping.toml"));
        assert_eq!(mapping_path_beside(Path::new("run")), Path::new("run.mapping.toml"));
    }

    #[test]
    fn clip_text_is_utf8_with_bad_bytes_replaced_and_utf16_refused() {
        assert_eq!(decode_text(b"ROOT H\xe4fte", "a.bvh").unwrap(), "ROOT H\u{fffd}fte");
        let utf16: Vec<u8> = "HIERARCHY".encode_utf16().flat_map(u16::to_le_bytes).collect();
        match decode_text(&utf16, "a.bvh") {
            Err(HumanImportError::Parse { file, line: 1, message }) => {
                assert_eq!(file, "a.bvh");
                assert_eq!(message, crate::input::ReadError::Utf16.to_string());
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_mapping_file_beside_the_clip_is_read_with_it_unless_one_is_given() {
        use crate::human::test_rig::{body, rest_text, torso};
        let dir = std::env::temp_dir().join(format!("ace_clip_beside_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("stand.bvh");
        std::fs::write(&path, rest_text(&body(&torso("Head")))).unwrap();
        let plain = HumanClip::from_bvh_file(&path, &ImportOptions::default()).unwrap();
        assert_eq!((plain.name.as_str(), plain.unit.as_str()), ("stand", "cm"));
        std::fs::write(dir.join("stand.mapping.toml"), "unit = \"0.011\"\n").unwrap();
        let beside = HumanClip::from_bvh_file(&path, &ImportOptions::default()).unwrap();
        assert_eq!(beside.unit, "0.011");
        assert!((beside.height_m / plain.height_m - 1.1).abs() < 1e-4, "{} m", beside.height_m);
        let given = ImportOptions { fps: None, mapping: Some(JointMapping::from_toml_str("unit = \"cm\"").unwrap()) };
        assert_eq!(HumanClip::from_bvh_file(&path, &given).unwrap().unit, "cm");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
