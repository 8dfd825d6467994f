//! `ace train-prior` and `ace train`: the two learning stages (paper §4 and §5) for one character, into
//! one checkpoint directory that `ace retarget`, the plugin and the editor load.
//!
//! The directory holds the prior (`config.json`, `prior.safetensors`), the generator and
//! discriminator (`ace.json`, `generator.safetensors`, `discriminator.safetensors`), the loss curves
//! (`prior_losses.csv`/`.png`, `ace_losses.csv`/`.png`) and `reference.json`, the Gaussian fit of the
//! character dataset's Ψ that FID is measured against. The character dataset is not stored (it is
//! large): its generator configuration and seed are recorded in the prior's provenance and `ace train`
//! regenerates it, byte for byte, unless `--dataset` gives the file.

use std::path::{Path, PathBuf};

use ace::models::correspondence::{Correspondence, EndEffectorStats};
use ace::models::dataset::{DatasetConfig, MotionSet, OwnClipsConfig, generate};
use ace::models::features::{FeatureLayout, character_body_length, character_features};
use ace::models::human_set::HumanSet;
use ace::models::kinematics::KinematicTree;
use ace::models::learn::ace::AceConfig;
use ace::models::checkpoint::FileRecord;
use ace::models::checkpoint::prior::WEIGHTS_FILE as PRIOR_WEIGHTS_FILE;
use ace::models::learn::checkpoint::PriorCheckpoint;
use ace::models::learn::prior::{PriorConfig, state_mask, train_prior_with};
use ace::models::learn::train_ace::{AceInputs, LOSSES_FILE, train_ace};
use ace::models::metrics::GaussianFit;
use ace::models::morphology::Morphology;
use anyhow::{Context, Result, bail};
use serde::de::DeserializeOwned;
use serde_json::{Value, json};

use ace::models::learn::checkpoint::LearnError;
use ace::plot::{Figure, LineChart, Series};
use crate::output::Outputs;
use crate::{characters, humans, progress};

/// The file beside the weights with the dataset's Ψ fit (for FID).
pub const REFERENCE_FILE: &str = "reference.json";

/// Options shared by both stages.
pub struct TrainArgs {
    pub character: String,
    pub out: Option<PathBuf>,
    pub dataset: Option<PathBuf>,
    pub frames: Option<usize>,
    pub seed: Option<u64>,
    pub config: Option<PathBuf>,
    pub paper: bool,
    pub humans: Option<PathBuf>,
    /// Generator settings for the dataset `train-prior` generates.
    pub dataset_config: Option<PathBuf>,
}

/// The checkpoint directory used when `--out`/`--checkpoint` is not given.
pub fn default_dir(character_arg: &str, tree: &KinematicTree) -> PathBuf {
    let name = if characters::BUNDLED.contains(&character_arg) { character_arg.to_string() } else { tree.name.clone() };
    PathBuf::from("out/checkpoints").join(name)
}

/// The text of a configuration file: a regular file, UTF-8 (a UTF-16 file gets a hint).
pub fn read_text(path: &Path) -> Result<String> {
    ace::models::input::read_text(path).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
}

/// The configuration `--config` gives (over the defaults, or the paper's with `--paper`), checked
/// with `check` before any work; errors name the file and the field.
fn read_config<T: DeserializeOwned + Default>(
    path: Option<&Path>,
    paper: impl FnOnce() -> T,
    use_paper: bool,
    check: impl Fn(&T) -> Result<(), LearnError>,
) -> Result<T> {
    let base = if use_paper { paper() } else { T::default() };
    let Some(path) = path else { return Ok(base) };
    if use_paper {
        bail!("--paper and --config both set the network sizes; put `paper` sizes in the config instead");
    }
    let text = read_text(path)?;
    let cfg: T = toml::from_str(&text).with_context(|| format!("{}: invalid configuration", path.display()))?;
    check(&cfg).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    Ok(cfg)
}

/// Fails when a file this stage writes into `dir` is one of its inputs (the character and the files
/// read with it, `--config`, `--dataset`).
fn check_outputs(dir: &Path, files: &[&str], character: &Path, inputs: &[(Option<&Path>, &str)]) -> Result<()> {
    let mut outputs = Outputs::new();
    outputs.input_character(character);
    for (p, what) in inputs {
        if let Some(p) = p {
            outputs.input(p, what);
        }
    }
    files.iter().try_for_each(|f| outputs.check(&dir.join(f)))
}

/// Loads `--dataset` or generates the dataset with `cfg` (progress bar).
pub fn dataset(tree: &KinematicTree, morph: &Morphology, urdf: &Path, file: Option<&Path>, cfg: &DatasetConfig) -> Result<MotionSet> {
    if let Some(file) = file {
        let set = MotionSet::load(file)?;
        characters::check_dataset(&set, file, tree, urdf)?;
        return Ok(set);
    }
    generate_dataset(tree, morph, cfg)
}

/// Generates the character dataset of `cfg` (progress bar).
pub fn generate_dataset(tree: &KinematicTree, morph: &Morphology, cfg: &DatasetConfig) -> Result<MotionSet> {
    let bar = progress::bar(cfg.frames as u64, "frames");
    bar.set_message("generating the character dataset");
    let set = generate(tree, morph, cfg, &mut |done| bar.set_position(done as u64))?;
    bar.finish_and_clear();
    Ok(set)
}

/// The character file's path, size and FNV-1a 64 checksum, for the checkpoint's provenance.
pub fn character_record(path: &Path) -> Result<Value> {
    let bytes = ace::models::input::read_regular(path, ace::models::input::MAX_MESH_BYTES).with_context(|| format!("{}: cannot read the character file", path.display()))?;
    Ok(serde_json::to_value(ace::models::learn::files::FileRecord::of(&path.display().to_string(), &bytes))?)
}

/// What the command line, data and code version were, for the checkpoint's provenance.
pub fn provenance(extra: Value) -> Value {
    let commit = git(&["rev-parse", "--short", "HEAD"]).map(|out| out.trim().to_string());
    // Uncommitted changes to tracked files mean the commit alone does not say which code ran.
    let modified = git(&["status", "--porcelain", "--untracked-files=no"]).map(|out| !out.is_empty());
    let mut v = json!({
        "command": std::env::args().collect::<Vec<_>>().join(" "),
        "commit": commit,
        "uncommitted_changes": modified,
        "ace_version": env!("CARGO_PKG_VERSION"),
    });
    if let (Some(v), Value::Object(extra)) = (v.as_object_mut(), extra) {
        v.extend(extra);
    }
    v
}

/// The standard output of a successful `git` command in the current directory.
fn git(args: &[&str]) -> Option<String> {
    std::process::Command::new("git")
        .args(args)
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).into_owned())
}

/// The generator configuration of the dataset a prior was trained on, as its provenance records it
/// (`ace train` regenerates the dataset from it, `ace eval` a fresh one with another seed).
pub fn prior_dataset_config(prior: &PriorCheckpoint) -> Result<DatasetConfig> {
    DatasetConfig::from_record(prior.provenance["dataset"]["config"].clone())
        .context("the prior's provenance does not record its dataset configuration")
}

/// Runs `ace train-prior`.
pub fn prior(args: &TrainArgs) -> Result<()> {
    let (urdf, tree, morph) = characters::load(&args.character)?;
    let dir = args.out.clone().unwrap_or_else(|| default_dir(&args.character, &tree));
    let cfg: PriorConfig = read_config(args.config.as_deref(), PriorConfig::paper, args.paper, |c: &PriorConfig| {
        c.check()?;
        c.device.check_available()
    })?;
    check_outputs(
        &dir,
        &["config.json", "prior.safetensors", "prior_losses.csv", "prior_losses.png"],
        &urdf,
        &[
            (args.config.as_deref(), "the configuration file"),
            (args.dataset.as_deref(), "the dataset"),
            (args.dataset_config.as_deref(), "the dataset configuration"),
        ],
    )?;
    check_no_ace_stage_over(&dir, cfg.steps)?;
    // Temporaries of killed runs go now, this run's on SIGINT or SIGTERM.
    crate::output::watch_dir(&dir);
    let mut data_cfg = match &args.dataset_config {
        Some(p) => crate::dataset::read_config(p)?,
        None => DatasetConfig::default(),
    };
    if let Some(n) = args.frames {
        data_cfg.frames = n;
    }
    if let Some(s) = args.seed {
        data_cfg.seed = s;
    }
    crate::dataset::check_with_options(&data_cfg, args.dataset_config.as_deref(), &tree, &morph)?;
    if data_cfg.own_clips.share > OwnClipsConfig::DEFAULT_SHARE {
        // Measured once and not understood yet: the user should know before an hour of training.
        eprintln!(
            "warning: {} of the dataset's frames are the creature's own clips (`[own_clips] share`); trained with a \
             tenth, the shared Fox's prior barely moved (random latents 0.006 m/s against 0.17 m/s without its \
             clips) and its retargeted fox hardly stepped, where with {} it walked (docs/datasets.md)",
            data_cfg.own_clips.share,
            OwnClipsConfig::DEFAULT_SHARE
        );
    }
    let set = dataset(&tree, &morph, &urdf, args.dataset.as_deref(), &data_cfg)?;
    println!("character {} ({}): dataset of {} frames, x^r of {} values", tree.name, urdf.display(), set.len(), set.layout.dim());
    let record = json!({
        "character_urdf": urdf.display().to_string(),
        "character_file": character_record(&urdf)?,
        "dataset": { "file": args.dataset.as_ref().map(|p| p.display().to_string()), "frames": set.len(), "config": set.config },
    });
    let bar = progress::bar(cfg.steps as u64, "steps");
    let mask = state_mask(&tree, &morph);
    train_prior_with(&set, &mask, &cfg, &dir, provenance(record), &mut |p| {
        bar.set_position(p.step as u64);
        bar.set_message(format!("loss {:.4} (recon {:.4}, kl {:.3})", p.loss, p.recon, p.kl));
    })?;
    bar.finish_and_clear();
    plot_losses(&dir.join("prior_losses.csv"), "Motion prior", &["total", "reconstruction", "kl"])?;
    println!("prior saved in {} (curves: prior_losses.csv, prior_losses.png)", dir.display());
    Ok(())
}

/// Fails when `dir` holds an ACE stage (`ace.json`) and training the prior to `steps` would change
/// the prior it was trained against: its `ace.json` records the prior's weights file, so the
/// checkpoint would no longer load. A prior already trained to `steps` is left as it is (rerunning a
/// finished `train-prior`, as the checkpoint script does, is allowed).
fn check_no_ace_stage_over(dir: &Path, steps: usize) -> Result<()> {
    use ace::models::checkpoint::ace::ACE_FILE;
    use ace::models::checkpoint::prior::CONFIG_FILE;
    if !dir.join(ACE_FILE).exists() {
        return Ok(());
    }
    let done = ace::models::input::read_text(&dir.join(CONFIG_FILE))
        .ok()
        .and_then(|t| serde_json::from_str::<Value>(&t).ok())
        .and_then(|v| v["step"].as_u64())
        .map(|s| s as usize);
    if done.is_some_and(|d| d >= steps) {
        return Ok(());
    }
    bail!(
        "{}: holds an ACE stage ({ACE_FILE}) trained against its prior ({}); training the prior to step {steps} would \
         replace the weights the generator was trained with, and the checkpoint would no longer load: use another \
         --checkpoint directory, or remove {ACE_FILE}, generator.safetensors and discriminator.safetensors first to \
         train the ACE stage again after",
        dir.display(),
        done.map_or(format!("no {CONFIG_FILE}"), |d| format!("trained to step {d}"))
    )
}

/// Runs `ace train` (the prior must be in the checkpoint directory).
pub fn ace(args: &TrainArgs) -> Result<()> {
    let (urdf, tree, morph) = characters::load(&args.character)?;
    let dir = args.out.clone().unwrap_or_else(|| default_dir(&args.character, &tree));
    let cfg: AceConfig = read_config(args.config.as_deref(), AceConfig::paper, args.paper, |c: &AceConfig| {
        c.check()?;
        c.device.check_available()?;
        // The manual mapping's link names need only the character: checked before the dataset and
        // the human clips are loaded.
        c.check_mapping_links(&morph.end_effector_links(&tree))
    })?;
    check_outputs(
        &dir,
        &["ace.json", "generator.safetensors", "discriminator.safetensors", "ace_losses.csv", "ace_losses.png", REFERENCE_FILE],
        &urdf,
        &[(args.config.as_deref(), "the configuration file"), (args.dataset.as_deref(), "the dataset")],
    )?;
    crate::output::watch_dir(&dir);
    // Training runs where the prior is loaded: on the configuration's device.
    let device = cfg.device.device();
    let prior = PriorCheckpoint::load_for(&dir, device, &tree, &morph)
        .with_context(|| format!("{} needs a motion prior: run `ace train-prior` first", dir.display()))?;
    if prior.step < prior.config.steps {
        eprintln!(
            "warning: the motion prior in {} trained {} of its {} steps: its training stopped early, and the \
             generator learns on it as it is; the same `ace train-prior` run again on the checkpoint finishes it",
            dir.display(),
            prior.step,
            prior.config.steps
        );
    }
    let data_cfg = prior_dataset_config(&prior).map_err(|e| anyhow::anyhow!("{e}; pass --dataset"))?;
    let set = dataset(&tree, &morph, &urdf, args.dataset.as_deref(), &data_cfg)?;
    if set.mean != prior.stats.mean || set.std != prior.stats.std {
        bail!("the dataset is not the one the prior in {} was trained on (its statistics differ)", dir.display());
    }

    let folder = humans::folder(args.humans.as_deref())?;
    let humans = humans::load(&folder)?;
    println!(
        "human clips from {}: {} for training, {} held out ({} frames in all)",
        folder.display(),
        humans.train_clips().count(),
        humans.held_out_clips().count(),
        humans.frames()
    );
    if humans.held_out_clips().next().is_none() {
        eprintln!(
            "warning: no clip of {} is held out, so `ace eval` will have nothing to score this checkpoint on (a folder \
             of one clip holds none out)",
            folder.display()
        );
    }

    let body = character_body_length(&tree, &morph);
    let correspondence = correspondence(&cfg, &set, &humans, body)?;
    println!("{correspondence}");

    let record = json!({ "humans": folder.display().to_string(), "character_file": character_record(&urdf)? });
    let inputs = AceInputs {
        prior: &prior,
        dataset: &set,
        tree: &tree,
        morph: &morph,
        humans: &humans,
        correspondence: &correspondence,
        character_body_length: body,
        human_body_length: None,
        speed_scale: ace::models::dataset::speed_scale(&tree, &morph, &set.config)?,
        provenance: &provenance(record),
    };
    train_ace_with_progress(&inputs, &cfg, &dir, "ACE")?;
    // Only once training succeeded: a run refused before it starts (implausible human statistics, a
    // directory trained against another prior) leaves the checkpoint there as it was.
    write_reference(&dir, &set, &correspondence, body)?;
    println!("generator and discriminator saved in {} (curves: ace_losses.csv, ace_losses.png)", dir.display());
    Ok(())
}

/// The end-effector correspondence of Ψ: the automatic one between the dataset's and the training
/// human clips' end-effector distributions, with `cfg`'s manual overrides.
pub fn correspondence(cfg: &AceConfig, set: &MotionSet, humans: &HumanSet, body: f32) -> Result<Correspondence> {
    let mut human_stats = EndEffectorStats::human();
    for c in humans.train_clips() {
        human_stats.add_human_states(&c.states, c.body_length);
    }
    let automatic = Correspondence::automatic(&EndEffectorStats::from_motion_set(set, body), &human_stats)?;
    Ok(cfg.resolve_mapping(automatic)?)
}

/// [`train_ace`] with a progress bar (its message starting with `label`), then plots the loss
/// curves.
pub fn train_ace_with_progress(inputs: &AceInputs<'_>, cfg: &AceConfig, dir: &Path, label: &str) -> Result<()> {
    let bar = progress::bar(cfg.steps as u64, "steps");
    train_ace(inputs, cfg, dir, &mut |p| {
        bar.set_position(p.step as u64);
        bar.set_message(format!("{label}: G {:.3} (fea {:.3}, adv {:.3}), D {:.3}", p.g_loss, p.fea, p.adv, p.d_loss));
    })?;
    bar.finish_and_clear();
    plot_losses(&dir.join(LOSSES_FILE), label, &["g_loss", "d_loss", "fea", "adv", "gp"])
}

/// Writes [`REFERENCE_FILE`]: the Gaussian fit of the dataset's Ψ under the chosen correspondence,
/// with what it was fitted for (the prior in `dir`, the mapping, the body length), so that a fit left
/// from another training is recognised ([`crate::scoring::Scorer::new`]).
pub fn write_reference(dir: &Path, set: &MotionSet, correspondence: &Correspondence, body: f32) -> Result<()> {
    let mapping = &correspondence.mapping;
    let psi: Vec<Vec<f32>> = (0..set.len()).map(|i| character_features(&set.layout, set.state(i), body, mapping)).collect();
    let fit = GaussianFit::fit(&psi);
    let prior_path = dir.join(PRIOR_WEIGHTS_FILE);
    let prior = ace::models::input::read_regular(&prior_path, ace::models::input::MAX_DATA_BYTES)
        .with_context(|| format!("{}: cannot read the prior", prior_path.display()))?;
    let v = json!({
        "features": FeatureLayout::new(mapping).entry_names(),
        "frames": set.len(),
        "prior": FileRecord::of(PRIOR_WEIGHTS_FILE, &prior),
        "mapping": mapping,
        "character_body_length": body,
        "fit": fit,
    });
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let path = dir.join(REFERENCE_FILE);
    ace::models::temporary::write_atomically(&path, serde_json::to_string(&v)?.as_bytes())
        .with_context(|| format!("writing {}", path.display()))
}

/// Plots the named columns of a loss CSV (first column: step) beside it as PNG, log scale.
pub fn plot_losses(csv: &Path, title: &str, columns: &[&str]) -> Result<()> {
    let text = std::fs::read_to_string(csv).with_context(|| format!("reading {}", csv.display()))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
    let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|x| x.trim().parse().unwrap_or(f64::NAN)).collect()).collect();
    // The chart sits beside its CSV: the file's name says which it is (a path would show the machine
    // it was trained on in every shipped checkpoint's chart).
    let file = csv.file_name().map_or_else(|| csv.display().to_string(), |n| n.to_string_lossy().into_owned());
    let mut chart = LineChart::new(format!("{title} losses ({file})"), "step", "loss").log_y(true);
    for (k, name) in columns.iter().enumerate() {
        let Some(c) = header.iter().position(|h| h == name) else { continue };
        let points = rows.iter().filter_map(|r| Some((*r.first()?, *r.get(c)?))).collect();
        chart.series.push(Series::new(*name, k, points));
    }
    let mut fig = Figure::new(1000);
    fig.push(chart, 500);
    fig.save(&csv.with_extension("png"))
}
