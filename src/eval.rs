//! `ace eval`: how a checkpoint does on the human clips it never saw, in the paper's metrics (§7.3).
//!
//! Rows (systems), each scored with the checkpoint's correspondence and body lengths ([`Scorer`]):
//! - **Dataset**: a fresh character dataset from the prior's generator configuration with another seed
//!   than training's, as many frames as the held-out clips: the realism and diversity reference (its
//!   FID is the floor sampling noise gives);
//! - **ACE**: the generator choosing latents for the prior from each held-out clip, with the default
//!   cleanup, and with `--limit-velocity` also the velocity limit (as `ace retarget --limit-velocity`);
//! - **ACE without cleanup**: the same without any cleanup step ([`ace::models::cleanup`]): the
//!   networks' raw output;
//! - **Prior with random z**: the same prior driven by latents drawn from N(0, I) for as many frames, with
//!   the cleanup: what the prior does without the generator, the reference L_fea and FID are judged
//!   against.
//!
//! - with `--baselines`, the systems of the paper's Table 1 ([`crate::baselines`]): **NKN**, **ACE w/o
//!   feature** and **ACE w/o adversarial**, trained first when missing, each scored exactly as ACE (the
//!   same scorer, correspondence, body lengths and cleanup).
//!
//! Columns: DIV, FID against the training dataset's Ψ fit, L_fea and following against the human (not
//! for the dataset) and UFR with its detectors; following is also broken down by end effector. Each learned system is also rolled out for `--seconds` (60 by
//! default) on the held-out clips played back to back, and checked for non-finite values and for the
//! root leaving a plausible height. Everything is written to `eval.md`, `eval.csv`, `eval.json` and
//! `eval.png` in the output folder.

use std::fmt::Write as _;
use std::ops::Range;
use std::path::{Path, PathBuf};

use ace::models::cleanup::Cleanup;
use ace::models::dataset::generate;
use ace::models::features::EndEffectorMapping;
use ace::models::human_set::{HumanRow, HumanSet, HumanSetClip, PROJECT_FPS};
use ace::models::kinematics::{CharacterPose, KinematicTree};
use ace::models::learn::nkn::NknCheckpoint;
use ace::models::learn::retarget::{RetargetedMotion, Retargeter};
use ace::models::metrics::{MetricsReport, percent};
use ace::models::metrics::following::MOVING_VERTICAL_M;
use ace::models::morphology::Morphology;
use ace::plot::{BarChart, Figure};
use anyhow::{Context, Result, bail};
use serde::Serialize;

use crate::baselines::{self, Baseline};
use crate::output::Outputs;
use crate::scoring::{FidSplit, HumanSource, Scorer};
use crate::{characters, humans, progress, retarget, train};

/// The FID table's row of the human clips themselves ([`Evaluation::source_fid`]).
pub const SOURCE_ROW: &str = "Human clips (L_fea = 0)";

/// The row of ACE's networks without the cleanup.
pub const ACE_RAW: &str = "ACE without cleanup";

/// Options of `ace eval`.
#[derive(Clone)]
pub struct EvalArgs {
    pub character: String,
    pub checkpoint: Option<PathBuf>,
    pub humans: Option<PathBuf>,
    pub out: Option<PathBuf>,
    /// Seed of the random latents and offset of the fresh dataset's seed.
    pub seed: u64,
    /// Length of the stability rollouts (s).
    pub seconds: f32,
    /// Evaluate at most this many held-out clips (all when `None`).
    pub max_clips: Option<usize>,
    /// Add the paper's baselines, training those missing.
    pub baselines: bool,
    /// Where the baselines' runs live [default: [`baselines::default_runs`]].
    pub runs: Option<PathBuf>,
    /// CI setting: baselines of [`baselines::QUICK_STEPS`] steps, at most [`QUICK_CLIPS`] clips
    /// (unless `max_clips` says), rollouts of at most [`QUICK_SECONDS`].
    pub quick: bool,
    /// Every cleaned-up system (ACE, the prior with random latents, the baselines) has the velocity
    /// limit in its cleanup ([`Cleanup::velocity_limit`]).
    pub limit_velocity: bool,
}

/// Held-out clips under `--quick` (unless `--max-clips` says).
pub const QUICK_CLIPS: usize = 2;
/// Longest stability rollout under `--quick` (s).
pub const QUICK_SECONDS: f32 = 4.0;

/// One row of the table.
#[derive(Clone, Debug, Serialize)]
pub struct Row {
    pub system: String,
    pub metrics: MetricsReport,
    /// L_fea split by feature block (empty for the dataset).
    pub feature_loss_by_block: Vec<(&'static str, f32)>,
    /// FID whole and by feature block (`None` without a reference).
    pub fid_split: Option<FidSplit>,
}

/// A long rollout's health.
#[derive(Clone, Debug, Serialize)]
pub struct Stability {
    pub system: String,
    pub seconds: f32,
    /// Every state and pose value finite.
    pub finite: bool,
    /// Lowest and highest root height (m).
    pub root_height: (f32, f32),
    /// Mean horizontal root speed (m/s).
    pub mean_speed: f32,
    /// Within bounds: finite, and the root between −0.5 m and 3 body lengths above the ground.
    pub stable: bool,
}

/// Everything `ace eval` measured, as `eval.json` holds it.
#[derive(Clone, Debug, Serialize)]
pub struct Evaluation {
    pub character: String,
    pub checkpoint: PathBuf,
    pub humans: PathBuf,
    pub held_out_clips: Vec<String>,
    pub frames: usize,
    pub seed: u64,
    /// The cleaned-up systems were held to their joints' velocity limits (`--limit-velocity`).
    pub limit_velocity: bool,
    pub rows: Vec<Row>,
    /// The FID of the held-out clips' own Ψ (the human's, centred as L_fea compares it): what a
    /// system that matched the human's features exactly (L_fea = 0) would score.
    pub source_fid: Option<FidSplit>,
    pub stability: Vec<Stability>,
}

/// The paper's Table 1 (Spot), for comparison: system, DIV, FID, L_fea, UFR (%).
pub const PAPER_SPOT: [(&str, f32, f32, Option<f32>, f32); 5] = [
    ("Dataset", 2.254, 0.000, None, 0.258),
    ("ACE", 2.483, 0.489, Some(0.606), 2.071),
    ("NKN", 1.718, 0.914, Some(0.912), 6.213),
    ("ACE w/o feature", 0.445, 0.976, Some(1.975), 0.517),
    ("ACE w/o adversarial", 3.077, 0.736, Some(0.553), 9.741),
];

/// Runs `ace eval`.
pub fn run(args: &EvalArgs) -> Result<()> {
    let (character, tree, morph) = characters::load(&args.character)?;
    let dir = match &args.checkpoint {
        Some(d) => d.clone(),
        None => retarget::default_checkpoint(&args.character)?,
    };
    retarget::warn_about_checkpoint(&ace::models::checkpoint::ace::read_record(&dir)?, &character)?;
    let out = args.out.clone().unwrap_or_else(|| PathBuf::from("out/eval").join(&tree.name));
    // (The human clip folder is read too, but only for `.bvh` files, which eval never writes.)
    let mut outputs = Outputs::new();
    outputs.input(&dir, "the checkpoint directory").input_character(&character);
    for f in ["eval.md", "eval.csv", "eval.json", "eval.png"] {
        outputs.check(&out.join(f))?;
    }
    // The baselines train into `<runs>/<system>`: never the checkpoint directory or a folder inside
    // it, nor a file of the character, checked before any work.
    let runs = args.runs.clone().unwrap_or_else(|| baselines::default_runs(&tree.name, args.quick));
    if args.baselines {
        for (_, slug) in baselines::BASELINES {
            outputs.check_dir(&runs.join(slug))?;
        }
        // A file named by `--runs` failed only when the first baseline was trained, after the clips were read.
        outputs.check_dir(&runs)?;
    }
    let mut args = args.clone();
    if args.quick {
        args.max_clips = Some(args.max_clips.unwrap_or(QUICK_CLIPS));
        args.seconds = args.seconds.min(QUICK_SECONDS);
    }
    let systems = if args.baselines {
        baselines::train_missing(&tree, &morph, &dir, &runs, args.humans.as_deref(), args.quick)?
    } else {
        Vec::new()
    };
    let eval = evaluate(&args, &dir, &tree, &morph, &systems)?;
    // The four files appear together or not at all.
    let staged = outputs.stage_dir(&out)?;
    write(&eval, &staged).with_context(|| format!("writing the evaluation into {}", out.display()))?;
    outputs.commit()?;
    print!("{}", markdown(&eval));
    println!("wrote {}/eval.md, eval.csv, eval.json and eval.png", out.display());
    Ok(())
}

/// Scores every system on the held-out clips (see the module docs).
pub fn evaluate(
    args: &EvalArgs,
    dir: &Path,
    tree: &KinematicTree,
    morph: &Morphology,
    baselines: &[(&str, Baseline)],
) -> Result<Evaluation> {
    let mut retargeter = Retargeter::load(dir, ace::models::learn::default_device())?;
    retargeter.check_character(tree, morph)?;
    let scorer = Scorer::new(&retargeter.ace().record, &retargeter.prior().character, dir)?;
    if !scorer.has_reference() {
        bail!("{}: no reference.json (the dataset's Ψ fit that FID needs); run `ace train` again", dir.display());
    }
    // Said before the clips are read (it said none of the "0 held-out clips" was in the folder).
    if retargeter.ace().record.human_split.held_out.is_empty() {
        bail!(
            "{}: the checkpoint holds out no clips (its human folder had too few), so there is nothing to evaluate it on; \
             train it on a folder of several clips",
            dir.display()
        );
    }
    let folder = humans::folder(args.humans.as_deref())?;
    let set = humans::load(&folder)?;
    let clips = held_out(&set, &retargeter, args.max_clips, &folder)?;
    let frames: usize = clips.iter().map(|c| c.states.len()).sum();
    println!(
        "{} on {} held-out clips ({frames} frames) from {}",
        tree.name,
        clips.len(),
        folder.display()
    );
    let bar = progress::bar(((3 + baselines.len()) * clips.len() + 1) as u64, "rollouts");
    let mut rows = vec![dataset_row(&retargeter, &scorer, tree, morph, frames, args.seed)?];
    bar.inc(1);

    // ACE and the random-latent prior on the same clips (the random rollouts as long as each clip).
    let mut systems: Vec<(&str, Vec<RetargetedMotion>)> =
        vec![("ACE", Vec::new()), (ACE_RAW, Vec::new()), ("Prior with random z", Vec::new())];
    let cleanup = Cleanup { velocity_limit: args.limit_velocity, ..retargeter.cleanup() };
    retargeter.set_cleanup(cleanup);
    for (k, clip) in clips.iter().enumerate() {
        systems[0].1.push(retargeter.retarget_states(tree, morph, &clip.states)?);
        retargeter.set_cleanup(Cleanup::NONE);
        systems[1].1.push(retargeter.retarget_states(tree, morph, &clip.states)?);
        retargeter.set_cleanup(cleanup);
        systems[2].1.push(retargeter.random_latent_rollout(tree, morph, clip.states.len(), args.seed.wrapping_add(k as u64))?);
        bar.inc(3);
    }
    // The baselines, with ACE's cleanup.
    let loaded: Vec<(&str, Runner)> = baselines
        .iter()
        .map(|(name, b)| Ok((*name, Runner::new(b, cleanup, &retargeter.ace().record.correspondence.mapping, tree, morph)?)))
        .collect::<Result<_>>()?;
    for (name, runner) in &loaded {
        let motions = clips.iter().map(|c| runner.retarget(tree, morph, &c.states)).collect::<Result<Vec<_>>>()?;
        bar.inc(clips.len() as u64);
        systems.push((name, motions));
    }
    bar.finish_and_clear();
    let human_psi: Vec<Vec<f32>> = clips.iter().flat_map(|c| scorer.human_psi(&c.states, c.body_length)).collect();
    let bodies: Vec<f32> = clips.iter().map(|c| scorer.human_body(c.body_length)).collect();
    let human = HumanSource { psi: &human_psi, bodies: &bodies };
    for (name, motions) in &systems {
        let (states, poses, episodes) = concat(motions);
        let psi = scorer.shown_psi(tree, morph, &states, &poses);
        rows.push(Row {
            system: name.to_string(),
            metrics: scorer.report(tree, morph, &psi, Some(human), &poses, &episodes),
            feature_loss_by_block: scorer.feature_loss_by_block(&psi, &human_psi),
            fid_split: scorer.fid_split(&psi),
        });
    }

    // Long rollouts: the held-out clips back to back.
    let long = (args.seconds * PROJECT_FPS).round() as usize;
    let looped: Vec<HumanRow> = clips.iter().flat_map(|c| c.states.iter().copied()).cycle().take(long).collect();
    let body = ace::models::features::character_body_length(tree, morph);
    let mut stability = vec![
        stability("ACE", &retargeter.retarget_states(tree, morph, &looped)?, body),
        stability("Prior with random z", &retargeter.random_latent_rollout(tree, morph, long, args.seed)?, body),
    ];
    for (name, runner) in &loaded {
        stability.push(self::stability(name, &runner.retarget(tree, morph, &looped)?, body));
    }
    Ok(Evaluation {
        character: tree.name.clone(),
        checkpoint: dir.to_path_buf(),
        humans: folder,
        held_out_clips: clips.iter().map(|c| c.relative.clone()).collect(),
        frames,
        seed: args.seed,
        limit_velocity: args.limit_velocity,
        rows,
        source_fid: scorer.fid_split(&human_psi),
        stability,
    })
}

/// A loaded baseline that retargets like ACE (same cleanup).
enum Runner<'a> {
    Ace(Retargeter),
    Nkn(&'a NknCheckpoint, Cleanup, EndEffectorMapping),
}

impl<'a> Runner<'a> {
    /// `mapping` pairs the end effectors for NKN's cleanup (NKN learns no correspondence of its own).
    fn new(b: &'a Baseline, cleanup: Cleanup, mapping: &EndEffectorMapping, tree: &KinematicTree, morph: &Morphology) -> Result<Runner<'a>> {
        Ok(match b {
            Baseline::Ace(dir) => {
                let mut r = Retargeter::load(dir, ace::models::learn::default_device())?;
                r.check_character(tree, morph)?;
                r.set_cleanup(cleanup);
                Runner::Ace(r)
            }
            Baseline::Nkn(n) => Runner::Nkn(n, cleanup, mapping.clone()),
        })
    }

    fn retarget(&self, tree: &KinematicTree, morph: &Morphology, x_h: &[HumanRow]) -> Result<RetargetedMotion> {
        Ok(match self {
            Runner::Ace(r) => r.retarget_states(tree, morph, x_h)?,
            Runner::Nkn(n, cleanup, mapping) => n.retarget_states(tree, morph, x_h, *cleanup, mapping)?,
        })
    }
}

/// The held-out clips the checkpoint recorded, found in `set`.
fn held_out<'s>(
    set: &'s HumanSet,
    retargeter: &Retargeter,
    max: Option<usize>,
    folder: &Path,
) -> Result<Vec<&'s HumanSetClip>> {
    let recorded = &retargeter.ace().record.human_split.held_out;
    let mut clips: Vec<&HumanSetClip> = set.clips.iter().filter(|c| recorded.contains(&c.relative)).collect();
    if clips.is_empty() {
        bail!(
            "{}: none of the {} held-out clips the checkpoint records (e.g. `{}`) is there; pass the folder it was trained on with --humans",
            folder.display(),
            recorded.len(),
            recorded.first().map_or("", String::as_str)
        );
    }
    if clips.len() < recorded.len() {
        eprintln!(
            "warning: {} of the {} held-out clips the checkpoint records are not in {}",
            recorded.len() - clips.len(),
            recorded.len(),
            folder.display()
        );
    }
    if let Some(n) = max {
        clips.truncate(n.max(1));
    }
    Ok(clips)
}

/// The Dataset row: a fresh dataset with the prior's generator settings and another seed.
fn dataset_row(
    retargeter: &Retargeter,
    scorer: &Scorer,
    tree: &KinematicTree,
    morph: &Morphology,
    frames: usize,
    seed: u64,
) -> Result<Row> {
    let mut cfg = train::prior_dataset_config(retargeter.prior())?;
    cfg.seed = cfg.seed.wrapping_add(1 + seed);
    cfg.frames = frames.max(3000);
    let set = generate(tree, morph, &cfg, &mut |_| {})?;
    let states: Vec<&[f32]> = (0..set.len()).map(|i| set.state(i)).collect();
    let poses: Vec<CharacterPose> = (0..set.len()).map(|i| set.pose(i)).collect();
    let psi = scorer.character_psi(&states);
    Ok(Row {
        system: "Dataset".into(),
        metrics: scorer.report(tree, morph, &psi, None, &poses, &set.episodes),
        feature_loss_by_block: Vec::new(),
        fid_split: scorer.fid_split(&psi),
    })
}

/// Motions back to back: states, poses and each one's frame range.
fn concat(motions: &[RetargetedMotion]) -> (Vec<Vec<f32>>, Vec<CharacterPose>, Vec<Range<usize>>) {
    let (mut states, mut poses, mut episodes) = (Vec::new(), Vec::new(), Vec::new());
    for m in motions {
        episodes.push(poses.len()..poses.len() + m.poses.len());
        states.extend(m.states.iter().cloned());
        poses.extend(m.poses.iter().cloned());
    }
    (states, poses, episodes)
}

fn stability(system: &str, m: &RetargetedMotion, body: f32) -> Stability {
    let finite = m.states.iter().flatten().all(|v| v.is_finite())
        && m.poses.iter().all(|p| {
            p.q.iter().all(|v| v.is_finite()) && p.root.translation.vector.iter().all(|v| v.is_finite())
        });
    let heights = m.poses.iter().map(|p| p.root.translation.z);
    let root_height = heights.fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), z| (lo.min(z), hi.max(z)));
    let distance: f32 = m
        .poses
        .windows(2)
        .map(|w| (w[1].root.translation.vector - w[0].root.translation.vector).xy().norm())
        .sum();
    let seconds = m.poses.len() as f32 / m.fps;
    Stability {
        system: system.into(),
        seconds,
        finite,
        root_height,
        mean_speed: distance / seconds.max(1e-6),
        stable: finite && root_height.0 > -0.5 && root_height.1 < 3.0 * body,
    }
}

/// A motion's following score (median over its clips), when it has a source human.
pub fn following_score(m: &MetricsReport) -> Option<f32> {
    m.following.as_ref().and_then(|f| f.score)
}

/// A motion's heading error (degrees, median over its clips), when it has a source human.
pub fn heading_error(m: &MetricsReport) -> Option<f32> {
    m.following.as_ref().and_then(|f| f.heading_error)
}

/// [`heading_error`] for a table, "38°", or "n/a" without a source human.
pub fn heading(m: &MetricsReport) -> String {
    heading_error(m).map_or("n/a".into(), |v| format!("{v:.0}°"))
}

/// A motion's pace (median over its clips where the human walks): the character's root travel over
/// the human's at the dataset's speed scale ([`ace::models::metrics::following()`]).
pub fn pace_ratio(m: &MetricsReport) -> Option<f32> {
    m.following.as_ref().and_then(|f| f.pace)
}

/// [`pace_ratio`] for a table, "0.82", or "n/a" where the human never walks.
pub fn pace(m: &MetricsReport) -> String {
    pace_ratio(m).map_or("n/a".into(), |v| format!("{v:.2}"))
}

/// How far the character travels and turns while the human stands
/// ([`ace::models::metrics::following()`]), "0.012 BL/s, 1.3°/s", or "n/a" where the human never stands.
pub fn standing(m: &MetricsReport) -> String {
    match m.following.as_ref().map(|f| (f.standing_travel, f.standing_turn)) {
        Some((Some(travel), Some(turn))) => format!("{travel:.3} BL/s, {turn:.1}°/s"),
        _ => "n/a".into(),
    }
}

/// A motion's share of frames into which some joint moves faster than its velocity limit
/// ([`ace::models::metrics::joint_limits()`]), for a character with limits.
pub fn over_velocity_share(m: &MetricsReport) -> Option<f32> {
    m.joint_limits.as_ref().filter(|j| j.has_velocity_limits()).map(|j| j.over_velocity)
}

/// [`over_velocity_share`] for a table with the joint fastest against its limit, "4.2 % (joint_lift
/// 5.6×)", "0.00 %", or "n/a" for a character without velocity limits.
pub fn velocity_limits(m: &MetricsReport) -> String {
    match m.joint_limits.as_ref().filter(|j| j.has_velocity_limits()) {
        None => "n/a".into(),
        Some(j) => match j.over().first() {
            Some(u) => format!("{:.2} % ({} {:.1}×)", 100.0 * j.over_velocity, u.joint, u.peak_ratio().unwrap_or(0.0)),
            None => format!("{:.2} %", 100.0 * j.over_velocity),
        },
    }
}

fn opt(v: Option<f32>) -> String {
    v.map_or("n/a".into(), |v| format!("{v:.3}"))
}

/// The report as Markdown.
pub fn markdown(e: &Evaluation) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "## {} — {} held-out clips, {} frames{}\n\n| system | DIV → | FID ↓ | L_fea ↓ | following ↑ | heading error ↓ | pace → 1 | UFR ↓ | self-collision | penetration | sliding | over a velocity limit ↓ |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        e.character,
        e.held_out_clips.len(),
        e.frames,
        if e.limit_velocity { ", joints held to their velocity limits (`--limit-velocity`)" } else { "" }
    );
    for r in &e.rows {
        let m = &r.metrics;
        let u = &m.ufr.rates;
        let _ = writeln!(
            s,
            "| {} | {:.3} | {} | {} | {} | {} | {} | {:.2} % | {:.2} % | {:.2} % | {:.2} % | {} |",
            r.system,
            m.div,
            opt(m.fid),
            opt(m.feature_loss),
            opt(following_score(m)),
            heading(m),
            pace(m),
            100.0 * u.ufr,
            100.0 * u.self_collision,
            100.0 * u.penetration,
            100.0 * u.sliding,
            velocity_limits(m)
        );
    }
    if e.rows.iter().any(|r| r.metrics.following.is_some()) {
        let _ = writeln!(
            s,
            "\nFollowing by end effector (`ace_models::metrics::following`; medians over the held-out clips): vertical correlation and amplitude ratio over the clips where the human's end effector moves ≥ {MOVING_VERTICAL_M} m vertically (their count in brackets), combined correlation over all clips, stillness (body lengths moved while the human's is still within 5 cm for 1 s):\n\n| system | end effector | human | vertical corr. ↑ | amplitude (1 = same) | combined ↑ | stillness ↓ |\n|---|---|---|---:|---:|---:|---:|"
        );
        for r in &e.rows {
            for p in r.metrics.following.iter().flat_map(|f| &f.pairs) {
                let _ = writeln!(
                    s,
                    "| {} | {} | {} | {} ({}) | {} | {} | {} |",
                    r.system,
                    p.character,
                    p.human.name(),
                    opt(p.vertical_correlation),
                    p.moving_clips,
                    opt(p.amplitude_ratio),
                    opt(p.combined),
                    opt(p.stillness)
                );
            }
        }
    }
    if e.rows.iter().any(|r| r.metrics.following.as_ref().is_some_and(|f| f.standing_clips > 0)) {
        let clips = e.rows.iter().filter_map(|r| r.metrics.following.as_ref()).map(|f| f.standing_clips).max().unwrap_or(0);
        let _ = writeln!(
            s,
            "\nStanding (medians over the {clips} held-out clips where the human's root stays within 5 cm and 10° for 1 s): how far the character's root travels (its body lengths per second) and turns meanwhile:\n\n| system | travel ↓ | turning ↓ |\n|---|---:|---:|"
        );
        for r in &e.rows {
            if let Some(f) = &r.metrics.following {
                let turn = f.standing_turn.map_or("n/a".into(), |v| format!("{v:.1}°/s"));
                let _ = writeln!(s, "| {} | {} | {turn} |", r.system, opt(f.standing_travel));
            }
        }
    }
    if e.rows.iter().any(|r| r.metrics.gait.is_some()) {
        let _ = writeln!(
            s,
            "\nGait (contacts from the UFR's band; pops: swings of 1–2 frames; micro-steps: swings under 0.1 body lengths; stride frequency against Alexander's law):\n\n| system | swings | median swing (frames) | pops | micro-steps | median duty | stride freq. / law |\n|---|---:|---:|---:|---:|---:|---:|"
        );
        for r in &e.rows {
            if let Some(g) = &r.metrics.gait {
                let _ = writeln!(
                    s,
                    "| {} | {} | {:.1} | {} | {} | {:.2} | {} |",
                    r.system,
                    g.swings,
                    g.median_swing_frames,
                    percent(g.pop_rate()),
                    percent(g.micro_step_rate()),
                    g.median_duty,
                    g.median_ratio.map_or("n/a".into(), |x| format!("{x:.2}×"))
                );
            }
        }
    }
    if let Some(first) = e.rows.iter().find(|r| !r.feature_loss_by_block.is_empty()) {
        let names: Vec<&str> = first.feature_loss_by_block.iter().map(|b| b.0).collect();
        let _ = writeln!(s, "\nL_fea by feature block:\n\n| system | {} |\n|---|{}", names.join(" | "), "---:|".repeat(names.len()));
        for r in e.rows.iter().filter(|r| !r.feature_loss_by_block.is_empty()) {
            let v: Vec<String> = r.feature_loss_by_block.iter().map(|b| format!("{:.3}", b.1)).collect();
            let _ = writeln!(s, "| {} | {} |", r.system, v.join(" | "));
        }
    }
    let splits: Vec<(&str, &FidSplit)> = e
        .rows
        .iter()
        .filter_map(|r| Some((r.system.as_str(), r.fid_split.as_ref()?)))
        .chain(e.source_fid.as_ref().map(|f| (SOURCE_ROW, f)))
        .collect();
    if let Some((_, first)) = splits.first() {
        let names: Vec<&str> = first.blocks.iter().map(|b| b.0).collect();
        let _ = writeln!(
            s,
            "\nFID by feature block (each block's marginal Gaussian alone, so the parts need not add up to FID):\n\n| system | FID | {} |\n|---|---:|{}",
            names.join(" | "),
            "---:|".repeat(names.len())
        );
        for (system, f) in &splits {
            let v: Vec<String> = f.blocks.iter().map(|b| format!("{:.3}", b.1)).collect();
            let _ = writeln!(s, "| {system} | {:.3} | {} |", f.total, v.join(" | "));
        }
    }
    let _ = writeln!(s, "\n| {:.0}-second rollout | finite | root height (m) | mean speed (m/s) | stable |\n|---|---|---|---:|---|", e.stability.first().map_or(0.0, |x| x.seconds));
    for x in &e.stability {
        let _ = writeln!(
            s,
            "| {} | {} | {:.2} … {:.2} | {:.2} | {} |",
            x.system,
            if x.finite { "yes" } else { "NO" },
            x.root_height.0,
            x.root_height.1,
            x.mean_speed,
            if x.stable { "yes" } else { "NO" }
        );
    }
    let _ = writeln!(
        s,
        "\nBeside the paper's Table 1 (Spot; its own data and metric implementation, so compare orderings, not values) — ours / paper's:\n\n| system | DIV | FID | L_fea | UFR |\n|---|---:|---:|---:|---:|"
    );
    for (name, div, fid, fea, ufr) in PAPER_SPOT {
        let ours = e.rows.iter().find(|r| r.system == name).map(|r| &r.metrics);
        let pair = |o: Option<String>, p: String| format!("{} / {p}", o.unwrap_or_else(|| "—".into()));
        let _ = writeln!(
            s,
            "| {name} | {} | {} | {} | {} |",
            pair(ours.map(|m| format!("{:.3}", m.div)), format!("{div:.3}")),
            pair(ours.map(|m| opt(m.fid)), format!("{fid:.3}")),
            pair(ours.map(|m| opt(m.feature_loss)), opt(fea)),
            pair(ours.map(|m| format!("{:.2} %", 100.0 * m.ufr.rates.ufr)), format!("{ufr:.3} %")),
        );
    }
    s
}

/// The table as CSV (one row per system).
pub fn csv(e: &Evaluation) -> String {
    let mut s = String::from("character,system,frames,div,fid,l_fea,following,heading_error_deg,pace,ufr,self_collision,penetration,sliding,over_velocity\n");
    for r in &e.rows {
        let m = &r.metrics;
        let u = &m.ufr.rates;
        let o = |v: Option<f32>| v.map_or(String::new(), |v| v.to_string());
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            e.character,
            r.system,
            m.frames,
            m.div,
            o(m.fid),
            o(m.feature_loss),
            o(following_score(m)),
            o(heading_error(m)),
            o(pace_ratio(m)),
            u.ufr,
            u.self_collision,
            u.penetration,
            u.sliding,
            o(over_velocity_share(m))
        );
    }
    s
}

/// Writes `eval.md`, `eval.csv`, `eval.json` and `eval.png` into `out`.
pub fn write(e: &Evaluation, out: &Path) -> Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let put = |name: &str, text: String| {
        let path = out.join(name);
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))
    };
    put("eval.md", markdown(e))?;
    put("eval.csv", csv(e))?;
    put("eval.json", serde_json::to_string_pretty(e)?)?;
    // One panel per metric: their scales differ by orders of magnitude.
    let v = |x: Option<f32>| x.map_or(f64::NAN, f64::from);
    let metrics: [(&str, fn(&MetricsReport) -> Option<f32>); 5] = [
        ("DIV (closest to the dataset's is best)", |m| Some(m.div)),
        ("FID (lower is better)", |m| m.fid),
        ("L_fea (lower is better)", |m| m.feature_loss),
        ("following (higher is better)", following_score),
        ("UFR % (lower is better)", |m| Some(100.0 * m.ufr.rates.ufr)),
    ];
    let mut fig = Figure::new(900);
    for (k, (title, get)) in metrics.iter().enumerate() {
        let heading = if k == 0 { format!("{}: held-out evaluation — {title}", e.character) } else { title.to_string() };
        let mut chart = BarChart::new(heading, "", vec![String::new()]);
        for r in &e.rows {
            chart = chart.with_series(r.system.clone(), vec![v(get(&r.metrics))]);
        }
        fig.push(chart, 230);
    }
    fig.save(&out.join("eval.png"))
}
