//! The canonical 17-joint human skeleton and its five end effectors (paper §6.1).

use serde::{Deserialize, Serialize};

/// Number of canonical joints.
pub const JOINT_COUNT: usize = 17;

/// A joint of the canonical human skeleton. Positions are those of the joint centres: `LeftUpperArm` is
/// the shoulder (gleno-humeral) joint, `LeftForearm` the elbow, `LeftHand` the wrist, `LeftThigh` the
/// hip joint, `LeftShin` the knee, `LeftFoot` the ankle; `Head` is the head joint of the source skeleton
/// (skull base / upper neck), `Neck` the lower neck, `Chest` the spine joint the arms branch from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub enum Joint {
    Pelvis,
    Spine,
    Chest,
    Neck,
    Head,
    LeftUpperArm,
    LeftForearm,
    LeftHand,
    RightUpperArm,
    RightForearm,
    RightHand,
    LeftThigh,
    LeftShin,
    LeftFoot,
    RightThigh,
    RightShin,
    RightFoot,
}

impl Joint {
    /// All joints in index order (the order of [`crate::human::HumanFrame::positions`] and of the
    /// joint block of the state vector).
    pub const ALL: [Joint; JOINT_COUNT] = [
        Joint::Pelvis,
        Joint::Spine,
        Joint::Chest,
        Joint::Neck,
        Joint::Head,
        Joint::LeftUpperArm,
        Joint::LeftForearm,
        Joint::LeftHand,
        Joint::RightUpperArm,
        Joint::RightForearm,
        Joint::RightHand,
        Joint::LeftThigh,
        Joint::LeftShin,
        Joint::LeftFoot,
        Joint::RightThigh,
        Joint::RightShin,
        Joint::RightFoot,
    ];

    /// Position of this joint in [`Joint::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }

    /// snake_case name, as used in mapping files (`left_upper_arm`).
    pub fn name(self) -> &'static str {
        match self {
            Joint::Pelvis => "pelvis",
            Joint::Spine => "spine",
            Joint::Chest => "chest",
            Joint::Neck => "neck",
            Joint::Head => "head",
            Joint::LeftUpperArm => "left_upper_arm",
            Joint::LeftForearm => "left_forearm",
            Joint::LeftHand => "left_hand",
            Joint::RightUpperArm => "right_upper_arm",
            Joint::RightForearm => "right_forearm",
            Joint::RightHand => "right_hand",
            Joint::LeftThigh => "left_thigh",
            Joint::LeftShin => "left_shin",
            Joint::LeftFoot => "left_foot",
            Joint::RightThigh => "right_thigh",
            Joint::RightShin => "right_shin",
            Joint::RightFoot => "right_foot",
        }
    }

    /// The joint with this snake_case name.
    pub fn from_name(name: &str) -> Option<Joint> {
        Joint::ALL.into_iter().find(|j| j.name() == name)
    }

    /// Parent in the canonical tree (`None` for the pelvis).
    pub fn parent(self) -> Option<Joint> {
        use Joint::*;
        Some(match self {
            Pelvis => return None,
            Spine | LeftThigh | RightThigh => Pelvis,
            Chest => Spine,
            Neck | LeftUpperArm | RightUpperArm => Chest,
            Head => Neck,
            LeftForearm => LeftUpperArm,
            LeftHand => LeftForearm,
            RightForearm => RightUpperArm,
            RightHand => RightForearm,
            LeftShin => LeftThigh,
            LeftFoot => LeftShin,
            RightShin => RightThigh,
            RightFoot => RightShin,
        })
    }
}

/// The end effectors of the human state (feet, hands, head), each at a canonical joint.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EndEffector {
    LeftFoot,
    RightFoot,
    LeftHand,
    RightHand,
    Head,
}

impl EndEffector {
    /// All end effectors in state-vector order.
    pub const ALL: [EndEffector; 5] = [
        EndEffector::LeftFoot,
        EndEffector::RightFoot,
        EndEffector::LeftHand,
        EndEffector::RightHand,
        EndEffector::Head,
    ];

    /// The canonical joint this end effector sits at.
    pub fn joint(self) -> Joint {
        match self {
            EndEffector::LeftFoot => Joint::LeftFoot,
            EndEffector::RightFoot => Joint::RightFoot,
            EndEffector::LeftHand => Joint::LeftHand,
            EndEffector::RightHand => Joint::RightHand,
            EndEffector::Head => Joint::Head,
        }
    }

    /// snake_case name (`left_foot`, …, `head`).
    pub fn name(self) -> &'static str {
        self.joint().name()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn indices_names_and_parents_are_consistent() {
        for (i, j) in Joint::ALL.iter().enumerate() {
            assert_eq!(j.index(), i);
            assert_eq!(Joint::from_name(j.name()), Some(*j));
            // Parents come before children, so one pass in ALL order is a valid FK order.
            if let Some(p) = j.parent() {
                assert!(p.index() < i, "{:?}", j);
            }
        }
        assert_eq!(
            Joint::ALL.iter().filter(|j| j.parent().is_none()).count(),
            1
        );
        for e in EndEffector::ALL {
            assert_eq!(e.name(), e.joint().name());
        }
    }
}
