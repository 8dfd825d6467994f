//! `ace dataset`: rolls out a character's kinematic controllers under random commands and writes the
//! motion dataset the motion prior learns from (paper §4, §7.1), optionally with a picture report.

use std::path::{Path, PathBuf};
use std::time::Instant;

use ace::models::dataset::{DatasetConfig, MotionSet, OwnClipsConfig, check_budget, check_config, generate};
use ace::models::kinematics::KinematicTree;
use ace::models::metrics::{UfrConfig, percent, ufr_episodes};
use ace::models::morphology::Morphology;
use anyhow::{Context, Result};

use crate::output::Outputs;
use crate::{characters, metrics, progress, report};

/// Options of `ace dataset`.
pub struct DatasetArgs {
    pub character: String,
    pub frames: Option<usize>,
    pub seed: Option<u64>,
    pub config: Option<PathBuf>,
    pub out: PathBuf,
    pub report: Option<PathBuf>,
    /// `--include-clips`: the creature's own clips, at the configuration's share or
    /// [`OwnClipsConfig::DEFAULT_SHARE`].
    pub include_clips: bool,
}

/// Share of a dataset's frames that the UFR detectors flag above which `ace dataset` warns: the
/// shipped characters' datasets stay under 0.5 %, and a prior learns whatever the dataset does.
pub const UNCLEAN_DATASET_UFR: f32 = 0.05;

/// Frames of a dataset [`unclean_warning`] scores at most (its first whole episodes): enough to tell a
/// share above [`UNCLEAN_DATASET_UFR`], at a tenth of the time the whole of a 200,000-frame dataset
/// takes (2.5 s beside 6 s of generation for the Fox).
pub const UNCLEAN_SAMPLE_FRAMES: usize = 20_000;

/// The warning for a dataset whose frames slide, collide or sink more than [`UNCLEAN_DATASET_UFR`]
/// of the time over its first [`UNCLEAN_SAMPLE_FRAMES`] (a profile that leaves legs hanging made
/// one of 93 % without a word); `None` otherwise.
pub fn unclean_warning(tree: &KinematicTree, morph: &Morphology, set: &MotionSet) -> Option<String> {
    let sample: Vec<_> = set
        .episodes
        .iter()
        .scan(0, |n, e| {
            let first = *n == 0;
            *n += e.len();
            (first || *n <= UNCLEAN_SAMPLE_FRAMES).then(|| e.clone())
        })
        .collect();
    let end = sample.last().map_or(0, |e| e.end);
    let poses: Vec<_> = (0..end).map(|i| set.pose(i)).collect();
    let r = ufr_episodes(tree, morph, &poses, &sample, set.fps, &UfrConfig::for_character(tree, morph)).rates;
    (r.ufr > UNCLEAN_DATASET_UFR).then(|| {
        format!(
            "{} of the dataset's frames are unnatural by the UFR detectors (feet sliding {}, self-collision {}, in \
             the ground {}): the controllers cannot move this body cleanly, and the prior would learn it. Check the \
             body plan with `ace inspect` (feet {}), and the profile if there is one",
            percent(r.ufr),
            percent(r.sliding),
            percent(r.self_collision),
            percent(r.penetration),
            morph.names(tree).feet.join(", ")
        )
    })
}

/// A dataset configuration file (TOML, any subset of [`DatasetConfig`]); errors name the file. Its
/// values are checked by [`check_with_options`] once the command line's are applied.
pub fn read_config(path: &Path) -> Result<DatasetConfig> {
    let text = crate::train::read_text(path)?;
    toml::from_str::<DatasetConfig>(&text).with_context(|| format!("{}: invalid dataset configuration", path.display()))
}

/// Checks a dataset configuration read from `file` (if any) with the command-line options applied,
/// its values and its size for the character, naming the file.
pub fn check_with_options(cfg: &DatasetConfig, file: Option<&Path>, tree: &KinematicTree, morph: &Morphology) -> Result<()> {
    check_config(cfg).and_then(|()| check_budget(cfg, tree, morph)).with_context(|| match file {
        Some(p) => format!("{} (with the command-line options)", p.display()),
        None => "the command-line options".to_string(),
    })
}

/// Runs `ace dataset`.
pub fn run(args: &DatasetArgs) -> Result<()> {
    let (path, tree, morph) = characters::load(&args.character)?;
    let mut outputs = Outputs::new();
    outputs.input_character(&path);
    let mut cfg = match &args.config {
        Some(p) => {
            outputs.input(p, "the dataset configuration");
            read_config(p)?
        }
        None => DatasetConfig::default(),
    };
    if let Some(n) = args.frames {
        cfg.frames = n;
    }
    if let Some(s) = args.seed {
        cfg.seed = s;
    }
    if args.include_clips && cfg.own_clips.share == 0.0 {
        cfg.own_clips.share = OwnClipsConfig::DEFAULT_SHARE;
    }
    // Bounds and outputs are checked before any work.
    check_with_options(&cfg, args.config.as_deref(), &tree, &morph)?;
    outputs.check(&args.out)?;
    if let Some(dir) = &args.report {
        outputs.check_dir(dir)?;
    }
    println!(
        "character {} ({}): {} DoF, {} feet, {} manipulators, {} wheels",
        tree.name,
        path.display(),
        tree.dof(),
        morph.feet.len(),
        morph.manipulators.len(),
        morph.wheels.len()
    );
    let bar = progress::bar(cfg.frames as u64, "frames");
    let start = Instant::now();
    let set = generate(&tree, &morph, &cfg, &mut |done| bar.set_position(done as u64))?;
    bar.finish_and_clear();
    let seconds = start.elapsed().as_secs_f32();
    if let Some(w) = unclean_warning(&tree, &morph, &set) {
        eprintln!("warning: {w}");
    }
    // The dataset and its report appear together, after both are written.
    let tmp = outputs.stage(&args.out)?;
    set.save(&tmp).with_context(|| format!("writing {}", args.out.display()))?;
    if let Some(dir) = &args.report {
        let m = metrics::dataset_metrics(&tree, &morph, &set, None);
        println!("{m}");
        let staged = outputs.stage_dir(dir)?;
        report::write(&staged, &tree, &morph, &set, &m).with_context(|| format!("writing the report into {}", dir.display()))?;
    }
    outputs.commit()?;
    println!(
        "wrote {}: {} frames in {} episodes, x^r of {} values, seed {}, generated in {:.1} s",
        args.out.display(),
        set.len(),
        set.episodes.len(),
        set.layout.dim(),
        set.seed,
        seconds
    );
    if let Some(dir) = &args.report {
        println!("report in {}", dir.display());
    }
    Ok(())
}
