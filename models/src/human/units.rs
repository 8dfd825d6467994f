//! Length units and up axes of BVH files, and their conversion to metres, z up, right-handed.

use nalgebra::{Matrix3, Vector3};

/// Metres per CMU ASF length unit (1 unit = 1/0.45 inch).
pub const CMU_UNIT_M: f32 = 0.0254 / 0.45;

/// Candidate units, tried in this order: name and metres per file unit.
pub const UNITS: [(&str, f32); 5] = [
    ("cmu", CMU_UNIT_M),
    ("cm", 0.01),
    ("m", 1.0),
    ("inch", 0.0254),
    ("mm", 0.001),
];

/// Plausible standing height of an adult performer, metres.
pub const PLAUSIBLE_HEIGHT_M: (f32, f32) = (1.4, 2.0);

/// Height a clip of unknown unit is normalised to, metres.
pub const NORMALISED_HEIGHT_M: f32 = 1.70;

/// Metres per unit for a unit name (`cm`, `inch`, …) or a number of metres per unit.
pub fn parse_unit(s: &str) -> Option<f32> {
    let s = s.trim();
    let named = match s.to_ascii_lowercase().as_str() {
        "cmu" => Some(CMU_UNIT_M),
        "cm" | "centimeter" | "centimetre" | "centimeters" | "centimetres" => Some(0.01),
        "m" | "meter" | "metre" | "meters" | "metres" => Some(1.0),
        "mm" | "millimeter" | "millimetre" | "millimeters" | "millimetres" => Some(0.001),
        "in" | "inch" | "inches" => Some(0.0254),
        "ft" | "foot" | "feet" => Some(0.3048),
        _ => None,
    };
    named.or_else(|| s.parse::<f32>().ok().filter(|v| v.is_finite() && *v > 0.0))
}

/// The unit that makes a skeleton of `height` file units a plausible human, as (name, metres per unit);
/// `None` when no candidate does.
pub fn detect_unit(height: f32) -> Option<(&'static str, f32)> {
    UNITS.into_iter().find(|(_, m)| {
        let h = height * m;
        h >= PLAUSIBLE_HEIGHT_M.0 && h <= PLAUSIBLE_HEIGHT_M.1
    })
}

/// An up axis of the file: axis index (0 = x, 1 = y, 2 = z) and sign.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UpAxis {
    pub axis: usize,
    pub positive: bool,
}

impl UpAxis {
    /// The signed principal axis nearest to `v`.
    pub fn nearest(v: &Vector3<f32>) -> UpAxis {
        let axis = v.iamax();
        UpAxis {
            axis,
            positive: v[axis] >= 0.0,
        }
    }

    /// Label such as `y` or `-z`.
    pub fn label(&self) -> String {
        format!(
            "{}{}",
            if self.positive { "" } else { "-" },
            ["x", "y", "z"][self.axis]
        )
    }

    /// The proper rotation taking file axes to the crate's z-up axes: a cyclic permutation sending this
    /// axis to +z (for y-up: (x, y, z) → (z, x, y), so a BVH character facing +z faces +x), followed by
    /// a half turn about x when the axis points down. Never a reflection.
    pub fn to_z_up(&self) -> Matrix3<f32> {
        let perm = match self.axis {
            0 => Matrix3::new(0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0),
            1 => Matrix3::new(0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0),
            _ => Matrix3::identity(),
        };
        if self.positive {
            perm
        } else {
            Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0)) * perm
        }
    }
}

/// Parse an up-axis label (`y`, `+y`, `-z`, `Y`).
pub fn parse_up(s: &str) -> Option<UpAxis> {
    let s = s.trim().to_ascii_lowercase();
    let (positive, a) = match s.strip_prefix('-') {
        Some(rest) => (false, rest),
        None => (true, s.strip_prefix('+').unwrap_or(&s)),
    };
    let axis = match a {
        "x" => 0,
        "y" => 1,
        "z" => 2,
        _ => return None,
    };
    Some(UpAxis { axis, positive })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conversions_are_proper_rotations_taking_up_to_z() {
        for axis in 0..3 {
            for positive in [true, false] {
                let up = UpAxis { axis, positive };
                let m = up.to_z_up();
                assert!((m.determinant() - 1.0).abs() < 1e-6);
                let mut v = Vector3::zeros();
                v[axis] = if positive { 1.0 } else { -1.0 };
                assert_eq!(m * v, Vector3::z(), "{}", up.label());
                assert_eq!(parse_up(&up.label()), Some(up));
            }
        }
        // Y-up BVH facing +z faces +x.
        assert_eq!(
            parse_up("y").unwrap().to_z_up() * Vector3::z(),
            Vector3::x()
        );
    }

    #[test]
    fn units_are_unambiguous() {
        assert_eq!(detect_unit(170.0).unwrap().0, "cm");
        assert_eq!(detect_unit(1.7).unwrap().0, "m");
        assert_eq!(detect_unit(30.0).unwrap().0, "cmu");
        assert_eq!(detect_unit(67.0).unwrap().0, "inch");
        assert_eq!(detect_unit(1700.0).unwrap().0, "mm");
        assert!(detect_unit(1.1).is_none());
        assert_eq!(parse_unit("0.01"), Some(0.01));
        assert_eq!(parse_unit("Inch"), Some(0.0254));
        assert!(parse_unit("furlong").is_none());
    }

    #[test]
    fn every_unit_name_and_only_a_finite_positive_number_is_read() {
        for (names, metres) in [
            ("cmu CMU", CMU_UNIT_M),
            ("cm centimeter centimetre centimeters centimetres", 0.01),
            ("m meter metre meters Metres", 1.0),
            ("mm millimeter millimetre millimeters millimetres", 0.001),
            ("in inch inches", 0.0254),
            ("ft foot feet", 0.3048),
        ] {
            for name in names.split(' ') {
                assert_eq!(parse_unit(&format!(" {name} ")), Some(metres), "{name}");
            }
        }
        assert_eq!(parse_unit("2.5"), Some(2.5));
        for bad in ["0", "-0.01", "inf", "NaN", "1e39", ""] {
            assert_eq!(parse_unit(bad), None, "{bad}");
        }
    }
}
