//! The baselines of the paper's Table 1 (§7.3–§7.4) for `ace eval --baselines`: NKN
//! ([`ace::models::learn::nkn`]), ACE without the feature loss (`w_fea = 0`) and ACE without the
//! adversarial loss (`w_adv = 0`), each trained on the same data with the same budget as the ACE
//! checkpoint it is compared with.
//!
//! Every baseline reuses that checkpoint's motion prior (copied into its run directory), the prior's
//! character dataset (regenerated from the configuration its provenance records), the same human
//! clips and split, and ACE's correspondence and configuration: the ablations change one weight, NKN
//! takes ACE's steps, batch size, window, learning rates, D and seed ([`NknConfig::matching`]). Runs
//! live in `<runs>/<slug>` and resume when interrupted; a finished run is not trained again.

use std::path::{Path, PathBuf};
use std::time::Instant;

use ace::models::features::character_body_length;
use ace::models::kinematics::KinematicTree;
use ace::models::learn::ace::{AceConfig, AceRecord, read_record};
use ace::models::learn::checkpoint::PriorCheckpoint;
use ace::models::learn::nkn::{self, NKN_FILE, NKN_LOSSES_FILE, NknCheckpoint, NknConfig, train_nkn};
use ace::models::learn::train_ace::AceInputs;
use ace::models::morphology::Morphology;
use anyhow::{Context, Result};
use serde_json::json;

use crate::{humans, progress, train};

/// Steps of every baseline under `--quick`.
pub const QUICK_STEPS: usize = 20;

/// The systems, in the paper's order: row name and run-directory name.
pub const BASELINES: [(&str, &str); 3] =
    [("NKN", "nkn"), ("ACE w/o feature", "ace-no-feature"), ("ACE w/o adversarial", "ace-no-adversarial")];

/// A trained baseline, as `ace eval` scores it.
pub enum Baseline {
    /// An ACE ablation: a checkpoint directory the ACE retargeter loads.
    Ace(PathBuf),
    /// NKN.
    Nkn(Box<NknCheckpoint>),
}

/// Where the runs of a character go by default.
pub fn default_runs(character: &str, quick: bool) -> PathBuf {
    PathBuf::from(if quick { "out/baselines-quick" } else { "out/baselines" }).join(character)
}

/// The configuration of an ablation of `ace` (the compared checkpoint's).
fn ablation(ace: &AceConfig, slug: &str, quick: bool) -> AceConfig {
    let mut cfg = ace.clone();
    match slug {
        "ace-no-feature" => cfg.w_fea = 0.0,
        _ => cfg.w_adv = 0.0,
    }
    if quick {
        cfg.steps = cfg.steps.min(QUICK_STEPS);
    }
    cfg
}

fn nkn_config(ace: &AceConfig, quick: bool) -> NknConfig {
    let mut cfg = NknConfig::matching(ace);
    if quick {
        cfg.steps = cfg.steps.min(QUICK_STEPS);
    }
    cfg
}

/// Steps a run directory holds, from its record (0 when there is none yet).
fn steps_done(dir: &Path, slug: &str) -> usize {
    if slug == "nkn" {
        nkn::read_record(dir).map_or(0, |r| r.step)
    } else {
        read_record(dir).map_or(0, |r| r.step)
    }
}

/// A motion prior's files as the baselines compare them: the weights' bytes and `config.json` but for
/// its provenance (which a copy re-serialises).
struct PriorFiles {
    weights: Vec<u8>,
    record: serde_json::Value,
}

impl PriorFiles {
    /// The prior in `dir`, or `None` when `dir` holds neither of its files.
    fn read(dir: &Path) -> Result<Option<PriorFiles>> {
        use ace::models::input::{MAX_DATA_BYTES, read_regular, read_text};
        let (weights, config) = (dir.join("prior.safetensors"), dir.join("config.json"));
        if !weights.exists() && !config.exists() {
            return Ok(None);
        }
        let weights = read_regular(&weights, MAX_DATA_BYTES).map_err(|e| anyhow::anyhow!("{}: {e}", weights.display()))?;
        let text = read_text(&config).map_err(|e| anyhow::anyhow!("{}: {e}", config.display()))?;
        let mut record: serde_json::Value =
            serde_json::from_str(&text).with_context(|| format!("{}: not JSON", config.display()))?;
        if let Some(o) = record.as_object_mut() {
            o.remove("provenance");
        }
        Ok(Some(PriorFiles { weights, record }))
    }
}

/// Fails when a baseline run in `runs` was trained (or started) against another motion prior than
/// the checkpoint in `ace_dir`'s: its copy of the prior differs. A finished run of an earlier prior
/// would otherwise be scored as this checkpoint's baseline, against a dataset it never saw.
fn check_runs_share_the_prior(runs: &Path, ace_dir: &Path) -> Result<()> {
    let mut compared: Option<PriorFiles> = None;
    for (_, slug) in BASELINES {
        let run = runs.join(slug);
        let Some(copy) = PriorFiles::read(&run)? else { continue };
        if compared.is_none() {
            compared = PriorFiles::read(ace_dir)?;
        }
        let ours = compared.as_ref().with_context(|| format!("{}: no motion prior", ace_dir.display()))?;
        let differs = if copy.weights != ours.weights {
            Some("prior.safetensors")
        } else if copy.record != ours.record {
            Some("config.json")
        } else {
            None
        };
        if let Some(file) = differs {
            anyhow::bail!(
                "{}: this baseline was trained against another motion prior than {}'s ({file} differs); \
                 remove the folder to train it again, or give --runs another folder",
                run.display(),
                ace_dir.display()
            );
        }
    }
    Ok(())
}

/// The settings (top-level keys of two serialised configurations) on which `run` and `want` differ,
/// each as `key: <run's> in the run, <want's> here`.
fn differing_settings(run: &impl serde::Serialize, want: &impl serde::Serialize) -> Vec<String> {
    let (run, want) = (json!(run), json!(want));
    let (Some(r), Some(w)) = (run.as_object(), want.as_object()) else { return vec![] };
    w.iter()
        .filter(|(k, v)| r.get(*k) != Some(*v))
        .map(|(k, v)| format!("{k}: {} in the run, {v} here", r.get(k).unwrap_or(&serde_json::Value::Null)))
        .collect()
}

/// Fails when the baseline run in `run` (if there is one) was trained with settings other than those
/// the compared checkpoint gives it: another configuration (a weight, the seed, the steps), another
/// end-effector mapping or another split of the human clips. A finished run is not trained again, so
/// it would otherwise be scored as this checkpoint's baseline without a word.
fn check_run_matches(run: &Path, slug: &str, ace: &AceRecord, quick: bool) -> Result<()> {
    let (mut differs, split) = if slug == "nkn" {
        if !run.join(NKN_FILE).exists() {
            return Ok(());
        }
        let there = nkn::read_record(run)?;
        let want = nkn_config(&ace.config, quick);
        // Saving every so many steps changes nothing a run learns.
        let as_wanted = NknConfig { checkpoint_every: want.checkpoint_every, ..there.config };
        (differing_settings(&as_wanted, &want), there.human_split)
    } else {
        if !run.join(ace::models::learn::ace::ACE_FILE).exists() {
            return Ok(());
        }
        let there = read_record(run)?;
        let want = ablation(&ace.config, slug, quick);
        // Nor saving; and the device is where it ran, not how: a run made on the CPU stands for one
        // asked on `auto`.
        let as_wanted = AceConfig { device: want.device, checkpoint_every: want.checkpoint_every, ..there.config };
        let mut differs = differing_settings(&as_wanted, &want);
        if there.correspondence.mapping != ace.correspondence.mapping {
            differs.push("the end-effector mapping".into());
        }
        (differs, there.human_split)
    };
    if split != ace.human_split {
        differs.push("the held-out split of the human clips".into());
    }
    if !differs.is_empty() {
        anyhow::bail!(
            "{}: this baseline was trained with other settings than the compared checkpoint gives it ({}); \
             remove the folder to train it again, or give --runs another folder",
            run.display(),
            differs.join("; ")
        );
    }
    Ok(())
}

/// Trains every baseline of the checkpoint in `ace_dir` that `runs` does not hold finished (with
/// progress and wall times), then loads them all, in [`BASELINES`] order.
pub fn train_missing(
    tree: &KinematicTree,
    morph: &Morphology,
    ace_dir: &Path,
    runs: &Path,
    humans_arg: Option<&Path>,
    quick: bool,
) -> Result<Vec<(&'static str, Baseline)>> {
    let record = read_record(ace_dir).with_context(|| format!("{}: no ACE checkpoint to compare with", ace_dir.display()))?;
    let ace_cfg = &record.config;
    check_runs_share_the_prior(runs, ace_dir)?;
    for (_, slug) in BASELINES {
        check_run_matches(&runs.join(slug), slug, &record, quick)?;
    }
    let missing: Vec<(&str, &str)> = BASELINES
        .into_iter()
        .filter(|(_, slug)| {
            let steps = if *slug == "nkn" { nkn_config(ace_cfg, quick).steps } else { ablation(ace_cfg, slug, quick).steps };
            steps_done(&runs.join(slug), slug) < steps
        })
        .collect();
    if !missing.is_empty() {
        // The baselines train where the compared checkpoint's configuration says, as it did.
        let device = ace_cfg.device;
        device
            .check_available()
            .map_err(|e| anyhow::anyhow!("{}: {e}", ace_dir.join(ace::models::learn::ace::ACE_FILE).display()))?;
        let prior = PriorCheckpoint::load_for(ace_dir, device.device(), tree, morph)?;
        let data_cfg = train::prior_dataset_config(&prior)?;
        let set = train::generate_dataset(tree, morph, &data_cfg)?;
        let folder = humans::folder(humans_arg)?;
        let humans = humans::load(&folder)?;
        let provenance = train::provenance(json!({
            "humans": folder.display().to_string(),
            "compared_with": ace_dir.display().to_string(),
        }));
        let inputs = AceInputs {
            prior: &prior,
            dataset: &set,
            tree,
            morph,
            humans: &humans,
            correspondence: &record.correspondence,
            character_body_length: character_body_length(tree, morph),
            human_body_length: record.body_lengths.human_override,
            speed_scale: ace::models::dataset::speed_scale(tree, morph, &set.config)?,
            provenance: &provenance,
        };
        for (system, slug) in missing {
            let dir = runs.join(slug);
            crate::output::watch_dir(&dir);
            let clock = Instant::now();
            if slug == "nkn" {
                let cfg = nkn_config(ace_cfg, quick);
                let bar = progress::bar(cfg.steps as u64, "steps");
                train_nkn(&inputs, &cfg, &dir, &mut |p| {
                    bar.set_position(p.step as u64);
                    bar.set_message(format!("{system}: G {:.3} (adv {:.3}, cycle {:.3}), D {:.3}", p.g_loss, p.adv, p.cycle, p.d_loss));
                })?;
                bar.finish_and_clear();
                train::plot_losses(&dir.join(NKN_LOSSES_FILE), system, &["g_loss", "d_loss", "adv", "cycle", "gp"])?;
            } else {
                train::train_ace_with_progress(&inputs, &ablation(ace_cfg, slug, quick), &dir, system)?;
            }
            println!("{system}: trained in {:.0} s into {}", clock.elapsed().as_secs_f64(), dir.display());
        }
    }
    BASELINES
        .into_iter()
        .map(|(system, slug)| {
            let dir = runs.join(slug);
            let b = if slug == "nkn" {
                Baseline::Nkn(Box::new(NknCheckpoint::load(&dir, tree, morph, ace::models::learn::default_device())?))
            } else {
                Baseline::Ace(dir)
            };
            Ok((system, b))
        })
        .collect()
}
