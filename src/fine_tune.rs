//! Fine-tuning a trained checkpoint briefly under changed settings: the editor's "Retrain briefly".
//!
//! The generator and discriminator of a checkpoint continue training for a few hundred steps with
//! other loss weights (w_adv, w_fea), feature weights or end-effector mapping, into a new checkpoint
//! directory beside the original (which is never changed). The character dataset is regenerated from
//! the prior's recorded configuration and the human clips are the ones the checkpoint was trained on,
//! as in `ace train`.

use std::collections::BTreeMap;
use std::path::PathBuf;

use ace::models::features::{FeatureWeights, character_body_length};
use ace::models::human::EndEffector;
use ace::models::learn::ace::{ACE_FILE, AceCheckpoint, read_record};
use ace::models::learn::checkpoint::PriorCheckpoint;
use ace::models::learn::train_ace::{AceInputs, AceProgress, start_fine_tune, train_ace};
use ace::models::morphology::load_character;
use anyhow::{Context, Result, bail};
use serde_json::json;

use crate::{humans, train};

/// The steps of a brief retraining by default (about a minute on two CPU cores).
pub const DEFAULT_STEPS: usize = 300;

/// What to fine-tune and how.
#[derive(Clone, Debug)]
pub struct FineTune {
    /// The character file (a URDF or a rigged glTF creature).
    pub urdf: PathBuf,
    /// The trained checkpoint directory to start from (left unchanged).
    pub from: PathBuf,
    /// The new checkpoint directory (must not hold a checkpoint yet).
    pub to: PathBuf,
    /// Generator steps to add.
    pub steps: usize,
    /// Weight of the adversarial loss.
    pub w_adv: f64,
    /// Weight of the feature loss.
    pub w_fea: f64,
    /// Per-block weights inside L_fea.
    pub feature_weights: FeatureWeights,
    /// Manual end-effector mapping (character link → human end effector or none), on top of the
    /// automatic one.
    pub end_effector_mapping: Option<BTreeMap<String, Option<EndEffector>>>,
    /// The human clips' folder; the project's default when `None`.
    pub humans: Option<PathBuf>,
}

/// Where a fine-tuning run is.
#[derive(Clone, Debug)]
pub enum Stage {
    /// Setting up (what is being done).
    Preparing(&'static str),
    /// After a generator step.
    Training(AceProgress),
}

/// Runs a fine-tuning (see the module docs), reporting its stages to `report`.
pub fn fine_tune(ft: &FineTune, report: &mut dyn FnMut(Stage)) -> Result<()> {
    if ft.steps == 0 {
        bail!("fine-tuning needs at least one step");
    }
    report(Stage::Preparing("loading the checkpoint"));
    let (tree, morph) = load_character(&ft.urdf)?;
    // Training runs on the device the checkpoint's configuration names, as `ace train` does.
    let ace_json = ft.from.join(ACE_FILE);
    let device = read_record(&ft.from)?.config.device;
    device.check_available().map_err(|e| anyhow::anyhow!("{}: {e}", ace_json.display()))?;
    let device = device.device();
    let prior = PriorCheckpoint::load_for(&ft.from, device, &tree, &morph)?;
    let stored = AceCheckpoint::load(&ft.from, prior.prior.latent_dim(), &prior.mask, device, true)?;
    let mut cfg = stored.record.config.clone();
    cfg.steps = stored.record.step + ft.steps;
    cfg.w_adv = ft.w_adv;
    cfg.w_fea = ft.w_fea;
    cfg.feature_weights = ft.feature_weights;
    cfg.end_effector_mapping = ft.end_effector_mapping.clone();
    cfg.check_mapping_links(&morph.end_effector_links(&tree))?;
    // A checkpoint from before speed matching keeps comparing body lengths per second.
    cfg.match_speed_scale = stored.record.speed_scale.is_some();

    report(Stage::Preparing("generating the character dataset"));
    let data_cfg = train::prior_dataset_config(&prior)?;
    let set = train::dataset(&tree, &morph, &ft.urdf, None, &data_cfg)?;
    if set.mean != prior.stats.mean || set.std != prior.stats.std {
        bail!("the regenerated dataset is not the one the prior in {} was trained on", ft.from.display());
    }
    report(Stage::Preparing("loading the human clips"));
    let folder = humans::folder(ft.humans.as_deref())?;
    let humans = humans::load(&folder)?;
    let body = character_body_length(&tree, &morph);
    let correspondence = train::correspondence(&cfg, &set, &humans, body)?;

    let human_body_length = stored.record.body_lengths.human_override;
    crate::output::watch_dir(&ft.to);
    start_fine_tune(&prior, stored, &ft.from, &ft.to, &cfg, &correspondence)
        .with_context(|| format!("starting to fine-tune {} into {}", ft.from.display(), ft.to.display()))?;
    train::write_reference(&ft.to, &set, &correspondence, body)?;
    let provenance = train::provenance(json!({ "humans": folder.display().to_string(), "fine_tuned_from": ft.from.display().to_string() }));
    let inputs = AceInputs {
        prior: &prior,
        dataset: &set,
        tree: &tree,
        morph: &morph,
        humans: &humans,
        correspondence: &correspondence,
        character_body_length: body,
        human_body_length,
        speed_scale: ace::models::dataset::speed_scale(&tree, &morph, &set.config)?,
        provenance: &provenance,
    };
    train_ace(&inputs, &cfg, &ft.to, &mut |p| report(Stage::Training(p.clone())))?;
    train::plot_losses(&ft.to.join("ace_losses.csv"), "ACE (fine-tuned)", &["g_loss", "d_loss", "fea", "adv", "gp"])?;
    Ok(())
}
