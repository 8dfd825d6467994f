//! The per-frame series the timeline plots for a preview: the root's ground speed, its change of
//! heading and the heights of the mapped end-effector pairs, of the character and of the human, so
//! that an artist sees where the character stops following or leaves the human's path.
//!
//! Both bodies are measured in their own body lengths, as Ψ and the following metric
//! ([`ace::models::metrics::following()`]) compare them: the character's the checkpoint was trained with,
//! the human's the clip's standing height (or the checkpoint's fixed one). The human's speed is the
//! one L_fea asks of the character: its pelvis speed brought to the character dataset's speed scale
//! (`human_speed_factor`), in the character's body lengths per second, as the following metric's pace
//! compares them; a character that keeps the person's pace runs on the human's curve. The human's values come
//! from x^h, the generator's input (pelvis velocity, and end effectors in the heading frame at the
//! pelvis); the character's from the poses the preview shows (root translation, forward kinematics),
//! after the cleanup. Speeds follow x^h's rule: backward differences, the first frame the forward one.
//! Headings are degrees turned since the first frame (left positive): the character's from its root's
//! forward axis, the human's summed from x^h's yaw rates as the heading error of the following metric
//! sums them.

use ace::models::human::{EndEffector, layout};
use ace::models::human_set::HumanRow;
use ace::models::kinematics::{CharacterPose, KinematicTree};
use ace::models::metrics::turned_degrees;
use ace::models::frame::{heading_yaw, unwrap_angles};
use ace::models::morphology::Morphology;
use ace::models::nalgebra::Vector3;

/// One mapped pair's end-effector heights above the ground, per frame (body lengths).
#[derive(Clone, Debug, PartialEq)]
pub struct PairHeights {
    /// The character end effector (its link name).
    pub character: String,
    /// The human end effector it follows.
    pub human: EndEffector,
    pub character_height: Vec<f32>,
    pub human_height: Vec<f32>,
}

/// The timeline's series of one preview (see the module docs), one value per frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Series {
    /// Frames per second of the values.
    pub fps: f32,
    /// The character root's ground speed (character body lengths per second).
    pub character_speed: Vec<f32>,
    /// The speed L_fea asks of the character: the human pelvis's ground speed at the speed scale
    /// (character body lengths per second).
    pub human_speed: Vec<f32>,
    /// The character root's change of heading since the first frame (degrees, left positive).
    pub character_heading: Vec<f32>,
    /// The human's change of heading since the first frame (degrees, left positive).
    pub human_heading: Vec<f32>,
    /// The mapped pairs, in the character's end-effector order.
    pub pairs: Vec<PairHeights>,
}

/// What [`Series::new`] measures.
pub struct SeriesInputs<'a> {
    pub tree: &'a KinematicTree,
    pub morph: &'a Morphology,
    /// The character's pose per frame.
    pub poses: &'a [CharacterPose],
    /// x^h per frame, aligned with `poses`.
    pub human: &'a [HumanRow],
    /// The human end effector of each character end effector ([`Morphology::end_effectors`] order);
    /// `None` leaves it out.
    pub mapping: &'a [Option<EndEffector>],
    /// Body lengths (m).
    pub character_body: f32,
    pub human_body: f32,
    /// What the human's speed in its body lengths per second is multiplied by to be the speed asked
    /// of the character ([`ace::scoring::Scorer::speed_factor`]).
    pub human_speed_factor: f32,
    pub fps: f32,
}

impl Series {
    /// The series of a retargeted clip.
    ///
    /// # Panics
    /// If `human` and `poses` differ in length, `mapping` has not one entry per end effector, or a
    /// body length is not positive.
    pub fn new(i: &SeriesInputs<'_>) -> Series {
        assert_eq!(i.poses.len(), i.human.len(), "poses and human states must be aligned");
        let ees = i.morph.end_effectors();
        assert_eq!(ees.len(), i.mapping.len(), "one mapping entry per end effector");
        assert!(i.character_body > 0.0 && i.human_body > 0.0, "body lengths must be positive");
        assert!(i.human_speed_factor > 0.0, "the speed factor must be positive");
        let links: Vec<_> = i.poses.iter().map(|p| i.tree.forward_kinematics(p)).collect();
        let roots: Vec<[f32; 2]> = i.poses.iter().map(|p| [p.root.translation.vector.x, p.root.translation.vector.y]).collect();
        let character_speed = ground_speeds(&roots, i.fps).into_iter().map(|v| v / i.character_body).collect();
        let human_speed = i
            .human
            .iter()
            .map(|x| {
                let v = &x[layout::ROOT_LINEAR_VELOCITY];
                v[0].hypot(v[1]) / i.human_body * i.human_speed_factor
            })
            .collect();
        let mut yaws: Vec<f32> = i.poses.iter().map(|p| heading_yaw(&(p.root.rotation * Vector3::x()))).collect();
        unwrap_angles(&mut yaws);
        let character_heading = yaws.iter().map(|y| (y - yaws[0]).to_degrees()).collect();
        let human_heading = turned_degrees(i.human.iter().map(|x| x[layout::ROOT_ANGULAR_VELOCITY][2]), i.fps);
        let human_height = |x: &HumanRow, e: EndEffector| x[layout::ROOT_HEIGHT.start] + x[layout::ee_position(e)][2];
        let pairs = ees
            .iter()
            .zip(i.mapping)
            .filter_map(|(&link, human)| human.map(|h| (link, h)))
            .map(|(link, h)| PairHeights {
                character: i.tree.links[link].name.clone(),
                human: h,
                character_height: links.iter().map(|l| i.morph.ee_point(link, l).z / i.character_body).collect(),
                human_height: i.human.iter().map(|x| human_height(x, h) / i.human_body).collect(),
            })
            .collect();
        Series { fps: i.fps, character_speed, human_speed, character_heading, human_heading, pairs }
    }
}

/// Ground speed per frame of a track of ground positions sampled at `fps`: the backward difference,
/// the first frame the forward one (zero for a single frame).
pub fn ground_speeds(track: &[[f32; 2]], fps: f32) -> Vec<f32> {
    let step = |a: [f32; 2], b: [f32; 2]| (b[0] - a[0]).hypot(b[1] - a[1]) * fps;
    (0..track.len())
        .map(|t| match t {
            0 if track.len() > 1 => step(track[0], track[1]),
            0 => 0.0,
            _ => step(track[t - 1], track[t]),
        })
        .collect()
}
