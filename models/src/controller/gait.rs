//! Gait patterns built from the leg layout (any number of legs) and chosen by speed.
//!
//! A gait is a duty factor (fraction of the cycle a foot is on the ground) and, per leg, the phase of
//! the cycle at which it lifts off. Patterns come from where the feet are, not from names:
//! legs are split into left (y > 0) and right, each side ordered front to back.
//! - **wave**: one leg at a time, back to front on the left, then on the right (for four legs this is the
//!   lateral-sequence walk); duty `1 − 1/n`.
//! - **ripple** (three or more legs a side): each side a back-to-front wave, the sides half a cycle apart;
//!   duty 2/3.
//! - **alternating**: neighbours in antiphase — the trot for four legs, the tripod for six, alternating
//!   tetrapods for eight, walking and running for two.
//! - **bound** and **gallop** (two legs a side): front pair and hind pair half a cycle apart, in phase
//!   (bound) or split by a tenth of a cycle (transverse gallop).
//!
//! Gaits are chosen by Froude number `Fr = v²/(g·h)` (h the hip height), as animals choose them
//! ([`crate::dynamic_similarity`]): the walk (or wave and ripple) up to [`WALK_TROT_FROUDE`], the trot
//! (tripod, biped run) up to [`TROT_GALLOP_FROUDE`], then the gallop or bound. The speed includes
//! turning: `|v| + |ω|·R` with `R` the mean foot distance from the root, so that turning on the spot
//! also steps. Duty factors follow the same table; the hexapod patterns keep the duty their phase
//! pattern needs (a wave lifts one leg at a time: `1 − 1/n`).

use serde::{Deserialize, Serialize};

use crate::dynamic_similarity::{TROT_GALLOP_FROUDE, WALK_TROT_FROUDE};

/// The gait families (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GaitKind {
    /// One leg at a time (the quadruped walk).
    Wave,
    /// Waves on each side, half a cycle apart.
    Ripple,
    /// Neighbours in antiphase (trot, tripod, biped walk/run).
    Alternating,
    /// Front and hind pairs in antiphase.
    Bound,
    /// Bound with the pairs split (transverse gallop).
    Gallop,
}

/// One gait of a character.
#[derive(Clone, Debug, PartialEq)]
pub struct Gait {
    /// Family.
    pub kind: GaitKind,
    /// Name for reports ("walk", "trot", "tripod", …).
    pub name: &'static str,
    /// Lift-off phase of each leg in `[0, 1)`, in leg order.
    pub offsets: Vec<f32>,
    /// Duty factor at the Froude numbers `duty_froude` (interpolated in between, held outside).
    pub duty: [f32; 2],
    /// Froude numbers at which the duty factor is `duty[0]` and `duty[1]`.
    pub duty_froude: [f32; 2],
    /// Froude number from which this gait is used.
    pub from_froude: f32,
}

/// Froude span of the walks, the trots and the gallops (duty factors are interpolated over it).
const WALKS: [f32; 2] = [0.0, WALK_TROT_FROUDE];
const TROTS: [f32; 2] = [WALK_TROT_FROUDE, TROT_GALLOP_FROUDE];
const GALLOPS: [f32; 2] = [TROT_GALLOP_FROUDE, 2.0 * TROT_GALLOP_FROUDE];
/// The hexapods' ripple takes over from the wave at this Froude number (insects move from the wave to
/// the ripple well before the tripod, Wilson 1966).
const RIPPLE_FROUDE: f32 = 0.05;

/// Foot positions (root frame, x forward, y left) from which patterns are built.
pub fn build_gaits(feet_xy: &[[f32; 2]]) -> Vec<Gait> {
    let n = feet_xy.len();
    if n == 0 {
        return Vec::new();
    }
    if n == 1 {
        return vec![gait(GaitKind::Alternating, "hop", vec![0.0], [0.5, 0.4], TROTS, 0.0)];
    }
    let cx = feet_xy.iter().map(|p| p[0]).sum::<f32>() / n as f32;
    let mut left: Vec<usize> = (0..n).filter(|&i| feet_xy[i][1] > 0.0).collect();
    let mut right: Vec<usize> = (0..n).filter(|&i| feet_xy[i][1] <= 0.0).collect();
    // Front to back.
    let front_first = |v: &mut Vec<usize>| v.sort_by(|&a, &b| feet_xy[b][0].total_cmp(&feet_xy[a][0]).then(a.cmp(&b)));
    front_first(&mut left);
    front_first(&mut right);
    let mut out = Vec::new();
    if left.len() == right.len() {
        let k = left.len();
        // Wave: back to front on the left, then on the right.
        let mut wave = vec![0.0; n];
        for (rank, &leg) in left.iter().rev().chain(right.iter().rev()).enumerate() {
            wave[leg] = rank as f32 / n as f32;
        }
        let alternating: Vec<f32> = (0..n)
            .map(|leg| {
                let (side, idx) = match left.iter().position(|&l| l == leg) {
                    Some(i) => (0, i),
                    None => (1, right.iter().position(|&l| l == leg).unwrap_or(0)),
                };
                if (side + idx) % 2 == 0 { 0.0 } else { 0.5 }
            })
            .collect();
        match k {
            1 => {
                out.push(gait(
                    GaitKind::Alternating,
                    "walk",
                    alternating.clone(),
                    [0.65, 0.55],
                    WALKS,
                    0.0,
                ));
                out.push(gait(
                    GaitKind::Alternating,
                    "run",
                    alternating,
                    [0.42, 0.32],
                    TROTS,
                    WALK_TROT_FROUDE,
                ));
            }
            2 => {
                let front = |leg: usize| feet_xy[leg][0] > cx;
                let bound: Vec<f32> = (0..n).map(|l| if front(l) { 0.5 } else { 0.0 }).collect();
                let gallop: Vec<f32> = (0..n)
                    .map(|l| {
                        let split = if feet_xy[l][1] > 0.0 { 0.0 } else { 0.1 };
                        if front(l) { 0.45 + split } else { split }
                    })
                    .collect();
                out.push(gait(GaitKind::Wave, "walk", wave, [0.75, 0.6], WALKS, 0.0));
                out.push(gait(
                    GaitKind::Alternating,
                    "trot",
                    alternating,
                    [0.45, 0.35],
                    TROTS,
                    WALK_TROT_FROUDE,
                ));
                out.push(gait(
                    GaitKind::Gallop,
                    "gallop",
                    gallop,
                    [0.4, 0.25],
                    GALLOPS,
                    TROT_GALLOP_FROUDE,
                ));
                out.push(gait(
                    GaitKind::Bound,
                    "bound",
                    bound,
                    [0.4, 0.25],
                    GALLOPS,
                    TROT_GALLOP_FROUDE,
                ));
            }
            _ => {
                let mut ripple = vec![0.0; n];
                for (rank, &leg) in left.iter().rev().enumerate() {
                    ripple[leg] = rank as f32 / k as f32;
                }
                for (rank, &leg) in right.iter().rev().enumerate() {
                    ripple[leg] = (rank as f32 / k as f32 + 0.5).fract();
                }
                let wave_duty = 1.0 - 1.0 / n as f32;
                out.push(gait(GaitKind::Wave, "wave", wave, [wave_duty, wave_duty], WALKS, 0.0));
                out.push(gait(
                    GaitKind::Ripple,
                    "ripple",
                    ripple,
                    [0.67, 0.6],
                    [RIPPLE_FROUDE, WALK_TROT_FROUDE],
                    RIPPLE_FROUDE,
                ));
                out.push(gait(
                    GaitKind::Alternating,
                    if k == 3 { "tripod" } else { "alternating" },
                    alternating,
                    [0.55, 0.42],
                    TROTS,
                    WALK_TROT_FROUDE,
                ));
            }
        }
    } else {
        // Irregular layouts: order the feet by angle around their centroid.
        let cy = feet_xy.iter().map(|p| p[1]).sum::<f32>() / n as f32;
        let mut order: Vec<usize> = (0..n).collect();
        let angle = |i: usize| (feet_xy[i][1] - cy).atan2(feet_xy[i][0] - cx);
        order.sort_by(|&a, &b| angle(a).total_cmp(&angle(b)).then(a.cmp(&b)));
        let mut wave = vec![0.0; n];
        let mut alternating = vec![0.0; n];
        for (rank, &leg) in order.iter().enumerate() {
            wave[leg] = rank as f32 / n as f32;
            alternating[leg] = if rank % 2 == 0 { 0.0 } else { 0.5 };
        }
        let wave_duty = (1.0 - 1.0 / n as f32).max(0.6);
        out.push(gait(GaitKind::Wave, "wave", wave, [wave_duty, wave_duty], WALKS, 0.0));
        out.push(gait(
            GaitKind::Alternating,
            "alternating",
            alternating,
            [0.55, 0.45],
            TROTS,
            WALK_TROT_FROUDE,
        ));
    }
    out
}

fn gait(
    kind: GaitKind,
    name: &'static str,
    offsets: Vec<f32>,
    duty: [f32; 2],
    duty_froude: [f32; 2],
    from_froude: f32,
) -> Gait {
    Gait {
        kind,
        name,
        offsets,
        duty,
        duty_froude,
        from_froude,
    }
}

/// Picks the gait for a Froude number, with hysteresis, among gaits sorted by `from_froude`. When
/// several gaits share a threshold (bound and gallop), `variant` picks among them (it is drawn per
/// episode).
#[derive(Clone, Debug)]
pub struct GaitSelector {
    /// Index of the current gait.
    pub current: usize,
}

impl GaitSelector {
    /// Relative hysteresis band around each threshold.
    pub const BAND: f32 = 0.1;

    /// Updates the current gait for Froude number `froude`; returns true when it changed.
    pub fn update(&mut self, gaits: &[Gait], froude: f32, variant: usize) -> bool {
        let tiers = tiers(gaits);
        let tier_of = |g: usize| tiers.iter().position(|t| t.contains(&g)).unwrap_or(0);
        let mut tier = tier_of(self.current);
        while tier + 1 < tiers.len() && froude > gaits[tiers[tier + 1][0]].from_froude * (1.0 + Self::BAND) {
            tier += 1;
        }
        while tier > 0 && froude < gaits[tiers[tier][0]].from_froude * (1.0 - Self::BAND) {
            tier -= 1;
        }
        let choice = if tiers.is_empty() {
            0
        } else {
            tiers[tier][variant % tiers[tier].len()]
        };
        let changed = choice != self.current;
        self.current = choice;
        changed
    }
}

/// Gaits grouped by equal `from_froude`, in order.
fn tiers(gaits: &[Gait]) -> Vec<Vec<usize>> {
    let mut out: Vec<Vec<usize>> = Vec::new();
    for (i, g) in gaits.iter().enumerate() {
        match out.last_mut() {
            Some(t) if gaits[t[0]].from_froude == g.from_froude => t.push(i),
            _ => out.push(vec![i]),
        }
    }
    out
}

impl Gait {
    /// Duty factor at Froude number `froude`.
    pub fn duty_at(&self, froude: f32) -> f32 {
        let [a, b] = self.duty_froude;
        let t = if b > a {
            ((froude - a) / (b - a)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        self.duty[0] + (self.duty[1] - self.duty[0]) * t
    }

    /// Duty factor at Froude number `froude` ([`Gait::duty_at`]), lowered within the gait's own range
    /// (down to the smaller of its two duty factors) where a stance of `duty · stride` would not fit in
    /// `room` (m): a walk whose step region is short for the law's strides keeps its stride and spends
    /// less of it on the ground, as a walk does at its faster end, rather than stepping faster.
    pub fn duty_fitting(&self, froude: f32, stride: f32, room: f32) -> f32 {
        let duty = self.duty_at(froude);
        if stride <= 0.0 || duty * stride <= room {
            return duty;
        }
        (room / stride).max(self.duty[0].min(self.duty[1]).min(duty))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stance_too_long_for_the_step_region_lowers_the_duty_within_the_gait() {
        let g = &build_gaits(&[[0.3, 0.2], [0.3, -0.2], [-0.3, 0.2], [-0.3, -0.2]])[0];
        let (lo, hi) = (g.duty[0].min(g.duty[1]), g.duty[0].max(g.duty[1]));
        let fr = 0.1;
        let d = g.duty_at(fr);
        // Room for the whole stance: the gait's own duty.
        assert_eq!(g.duty_fitting(fr, 0.4, 1.0), d);
        // A little short: the stance fills the room exactly.
        let room = 0.4 * d * 0.95;
        let fitted = g.duty_fitting(fr, 0.4, room);
        assert!((fitted * 0.4 - room).abs() < 1e-6 && fitted < d, "{fitted} vs {d}");
        // Far too short: never below the gait's range.
        assert_eq!(g.duty_fitting(fr, 0.4, 0.01), lo.min(d));
        assert!(lo < hi);
    }

    fn close(a: &[f32], b: &[f32]) -> bool {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-6)
    }

    /// Every phase of the quadruped's gallop and bound, and the gallop's duty over its own Froude span
    /// (2.5 to 5), on a body whose feet are not centred on its origin.
    #[test]
    fn a_quadrupeds_gallop_splits_its_pairs_by_a_tenth_and_the_bound_by_front_and_hind() {
        // fl, fr, rl, rr, the body's origin 0.5 m behind the hind feet.
        let g = build_gaits(&[[1.1, 0.2], [1.1, -0.2], [0.5, 0.2], [0.5, -0.2]]);
        let (gallop, bound) = (&g[2], &g[3]);
        assert!(close(&gallop.offsets, &[0.45, 0.55, 0.0, 0.1]), "{:?}", gallop.offsets);
        assert_eq!(bound.offsets, [0.5, 0.5, 0.0, 0.0]);
        assert_eq!(gallop.duty_at(TROT_GALLOP_FROUDE), 0.4);
        assert!((gallop.duty_at(1.5 * TROT_GALLOP_FROUDE) - 0.325).abs() < 1e-6);
        assert_eq!(gallop.duty_at(2.0 * TROT_GALLOP_FROUDE), 0.25);
        assert_eq!((gallop.from_froude, bound.from_froude), (TROT_GALLOP_FROUDE, TROT_GALLOP_FROUDE));
    }

    /// Two legs walk and run in antiphase, with the walk's and the run's duty factors.
    #[test]
    fn a_biped_walks_and_runs_in_antiphase() {
        let g = build_gaits(&[[0.0, 0.1], [0.0, -0.1]]);
        let names: Vec<_> = g.iter().map(|g| g.name).collect();
        assert_eq!(names, ["walk", "run"]);
        assert_eq!((g[0].offsets.clone(), g[0].duty), (vec![0.0, 0.5], [0.65, 0.55]));
        assert_eq!((g[1].offsets.clone(), g[1].duty, g[1].from_froude), (vec![0.0, 0.5], [0.42, 0.32], WALK_TROT_FROUDE));
        // One leg hops.
        let hop = build_gaits(&[[0.0, 0.0]]);
        assert_eq!((hop.len(), hop[0].name, hop[0].offsets.clone()), (1, "hop", vec![0.0]));
    }

    /// The hexapod's wave lifts one leg at a time, back to front on the left, then on the right (duty
    /// 5/6); its ripple waves each side over a third of the cycle, the sides half a cycle apart.
    #[test]
    fn a_hexapods_wave_and_ripple_phases() {
        // lf, lm, lr, rf, rm, rr
        let hex = [[0.2, 0.2], [0.0, 0.25], [-0.2, 0.2], [0.2, -0.2], [0.0, -0.25], [-0.2, -0.2]];
        let g = build_gaits(&hex);
        let names: Vec<_> = g.iter().map(|g| g.name).collect();
        assert_eq!(names, ["wave", "ripple", "tripod"]);
        assert!(close(&g[0].offsets, &[2.0 / 6.0, 1.0 / 6.0, 0.0, 5.0 / 6.0, 4.0 / 6.0, 3.0 / 6.0]), "{:?}", g[0].offsets);
        assert!(close(&g[0].duty, &[5.0 / 6.0, 5.0 / 6.0]), "{:?}", g[0].duty);
        assert!(close(&g[1].offsets, &[2.0 / 3.0, 1.0 / 3.0, 0.0, 1.0 / 6.0, 5.0 / 6.0, 0.5]), "{:?}", g[1].offsets);
        assert_eq!((g[1].duty_froude, g[1].from_froude), ([RIPPLE_FROUDE, WALK_TROT_FROUDE], RIPPLE_FROUDE));
    }

    /// Feet that do not pair up left and right (three legs here) step in order around their centre.
    #[test]
    fn an_irregular_layout_steps_around_its_centre() {
        // A front foot on the right of the midline, a rear pair; the centre is off the origin.
        let g = build_gaits(&[[0.3, 0.1], [-0.2, 0.3], [-0.2, -0.1]]);
        let names: Vec<_> = g.iter().map(|g| g.name).collect();
        assert_eq!(names, ["wave", "alternating"]);
        // Around the centre from behind on the right: rear right, front, rear left.
        assert!(close(&g[0].offsets, &[1.0 / 3.0, 2.0 / 3.0, 0.0]), "{:?}", g[0].offsets);
        assert_eq!(g[1].offsets, [0.5, 0.0, 0.0]);
        // The same feet far from the body's origin (1 m behind it, 1.1 m to its left): the same order,
        // around their own centre.
        let far = build_gaits(&[[-0.7, 1.1], [-1.2, 1.3], [-1.2, 0.9]]);
        assert!(close(&far[0].offsets, &g[0].offsets), "{:?}", far[0].offsets);
        // A wave lifts one of n legs at a time (duty 1 − 1/n), but stands at least 0.6 of the cycle:
        // two legs on one side would otherwise spend half of it in the air.
        assert!(close(&g[0].duty, &[2.0 / 3.0, 2.0 / 3.0]));
        let two = build_gaits(&[[0.3, -0.1], [-0.3, -0.1]]);
        assert_eq!((two[0].name, two[0].duty), ("wave", [0.6, 0.6]));
        let five = build_gaits(&[[0.3, 0.2], [0.0, 0.25], [-0.3, 0.2], [0.3, -0.2], [-0.3, -0.2]]);
        assert!(close(&five[0].duty, &[0.8, 0.8]));
        assert_eq!(five[1].duty, [0.55, 0.45]);
    }

    #[test]
    fn quadruped_and_hexapod_patterns() {
        // fl, fr, rl, rr
        let quad = [[0.3, 0.2], [0.3, -0.2], [-0.3, 0.2], [-0.3, -0.2]];
        let g = build_gaits(&quad);
        let names: Vec<_> = g.iter().map(|g| g.name).collect();
        assert_eq!(names, ["walk", "trot", "gallop", "bound"]);
        // Walk: rl, fl, rr, fr.
        assert_eq!(g[0].offsets, [0.25, 0.75, 0.0, 0.5]);
        // Trot: diagonals together.
        assert_eq!(g[1].offsets[0], g[1].offsets[3]);
        assert_eq!(g[1].offsets[1], g[1].offsets[2]);
        assert_ne!(g[1].offsets[0], g[1].offsets[1]);
        // Bound: front pair together.
        assert_eq!(g[3].offsets, [0.5, 0.5, 0.0, 0.0]);
        let mut sel = GaitSelector { current: 0 };
        // Froude numbers: walk below 0.4, trot to 2.5, then gallop or bound.
        assert!(!sel.update(&g, 0.3, 0));
        assert!(!sel.update(&g, 0.43, 0), "within the hysteresis band");
        assert!(sel.update(&g, 0.5, 0));
        assert_eq!(g[sel.current].name, "trot");
        sel.update(&g, 4.0, 1);
        assert_eq!(g[sel.current].name, "bound");
        // Gallop and bound share a threshold: one tier, the episode's variant picks.
        sel.update(&g, 4.0, 0);
        assert_eq!(g[sel.current].name, "gallop");
        // Hysteresis: just under the threshold keeps the faster gait.
        sel.update(&g, 2.4, 1);
        assert_eq!(g[sel.current].name, "bound");
        sel.update(&g, 0.1, 0);
        assert_eq!(g[sel.current].name, "walk");
        // Duty factors fall with the Froude number: walk 0.75 → 0.6, trot 0.45 → 0.35.
        assert_eq!(g[0].duty_at(0.0), 0.75);
        assert!((g[0].duty_at(0.4) - 0.6).abs() < 1e-6);
        assert_eq!(g[1].duty_at(0.4), 0.45);
        assert!((g[1].duty_at(2.5) - 0.35).abs() < 1e-6);
        assert!(g[2].duty_at(5.0) < g[1].duty_at(2.5));

        let hex = [
            [0.2, 0.2],
            [0.0, 0.25],
            [-0.2, 0.2],
            [0.2, -0.2],
            [0.0, -0.25],
            [-0.2, -0.2],
        ];
        let g = build_gaits(&hex);
        let tripod = g.iter().find(|g| g.name == "tripod").unwrap();
        assert_eq!(tripod.offsets, [0.0, 0.5, 0.0, 0.5, 0.0, 0.5]);
        let wave = &g[0];
        let mut sorted = wave.offsets.clone();
        sorted.sort_by(f32::total_cmp);
        assert_eq!(sorted.len(), 6);
        assert!(sorted.windows(2).all(|w| w[1] > w[0]));
    }
}
