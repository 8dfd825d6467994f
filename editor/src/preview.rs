//! The preview: the current clip retargeted offline (as `ace retarget` does) on a background thread,
//! scored, and shown on the character frame by frame at the clip player's time. Scrubbing is exact
//! because the whole motion is known.

use std::path::{Path, PathBuf};

use ace::models::cleanup::Cleanup;
use ace::models::features::human_body_length;
use ace::models::human::{HumanClip, ImportOptions};
use ace::models::human_set::PROJECT_FPS;
use ace::models::learn::ace::AceRecord;
use ace::models::morphology::load_character;
use ace::retarget::{Backend, Networks, Retargeted, retarget_and_score};
use ace::scoring::Scorer;
use anyhow::{Context, Result};
use bevy::prelude::*;
use bevy_ace::prelude::*;

use crate::jobs::Job;
use crate::series::{Series, SeriesInputs};
use crate::{Scene, Session};

/// What the preview was computed from.
#[derive(Clone, Debug, PartialEq)]
pub struct PreviewInputs {
    /// The character's file (URDF or glTF).
    pub character: PathBuf,
    pub checkpoint: PathBuf,
    pub clip: PathBuf,
    /// The cleanup's velocity limit is on ([`Session::limit_velocity`]).
    pub limit_velocity: bool,
}

/// A computed preview.
pub struct PreviewResult {
    pub inputs: PreviewInputs,
    pub retargeted: Retargeted,
    /// The checkpoint's record (configuration, correspondence with its KL scores).
    pub record: AceRecord,
    /// The clip at the project frame rate (what was retargeted and what an export writes).
    pub clip: HumanClip,
    /// The timeline's plots: root speeds and end-effector heights per frame.
    pub series: Series,
    pub seconds: f32,
}

/// The preview's state.
#[derive(Resource, Default)]
pub struct Preview {
    pub result: Option<PreviewResult>,
    pub error: Option<String>,
    job: Option<(PreviewInputs, Job<Result<PreviewResult, String>>)>,
}

impl Preview {
    /// Starts computing the preview of `inputs` (replacing any running one).
    pub fn compute(&mut self, inputs: PreviewInputs) {
        let i = inputs.clone();
        self.error = None;
        self.job = Some((inputs, Job::spawn("ace-preview", move |tx| {
            let _ = tx.send(compute(&i).map_err(|e| format!("{e:#}")));
        })));
    }

    /// Whether a computation is running.
    pub fn busy(&self) -> bool {
        self.job.is_some()
    }
}

/// Retargets and scores `inputs.clip` on the character with the checkpoint.
pub fn compute(inputs: &PreviewInputs) -> Result<PreviewResult> {
    let start = std::time::Instant::now();
    let (tree, morph) = load_character(&inputs.character)?;
    let mut retargeter = Networks::load(&inputs.checkpoint, Backend::Rust)?;
    retargeter.set_cleanup(Cleanup { velocity_limit: inputs.limit_velocity, ..Cleanup::default() });
    let scorer = Scorer::new(retargeter.record(), retargeter.character(), &inputs.checkpoint)?;
    let clip = HumanClip::from_bvh_file(&inputs.clip, &ImportOptions { fps: Some(PROJECT_FPS), mapping: None })
        .with_context(|| format!("opening {}", inputs.clip.display()))?;
    let retargeted = retarget_and_score(&retargeter, &scorer, &tree, &morph, &clip)?;
    let record = retargeter.record();
    let human_body = scorer.human_body(human_body_length(&clip));
    let series = Series::new(&SeriesInputs {
        tree: &tree,
        morph: &morph,
        poses: &retargeted.motion.poses,
        human: &retargeted.human,
        mapping: &record.correspondence.mapping.human,
        character_body: record.body_lengths.character,
        human_body,
        human_speed_factor: scorer.speed_factor(human_body),
        fps: PROJECT_FPS,
    });
    Ok(PreviewResult {
        inputs: inputs.clone(),
        retargeted,
        record: record.clone(),
        clip,
        series,
        seconds: start.elapsed().as_secs_f32(),
    })
}

/// The checkpoint shipped for a bundled character's file (`assets/characters/<name>.urdf` or
/// `assets/creatures/<name>.glb` → `assets/checkpoints/<name>`), when there is one.
pub fn checkpoint_beside(character: &Path) -> Option<PathBuf> {
    let name = character.file_stem()?;
    let dir = character.parent()?.parent()?.join("checkpoints").join(name);
    dir.join("ace.json").is_file().then_some(dir)
}

/// Takes finished computations.
pub fn poll(mut preview: ResMut<Preview>) {
    let Some((_, job)) = preview.job.as_mut() else { return };
    let messages = job.poll();
    let finished = job.finished();
    let panicked = job.panicked();
    for m in messages {
        match m {
            Ok(r) => {
                preview.result = Some(r);
                preview.error = None;
            }
            Err(e) => preview.error = Some(e),
        }
    }
    if finished {
        if let Some(e) = panicked {
            preview.error = Some(e);
        }
        preview.job = None;
    }
}

/// Shows the preview's pose at the clip player's time, once the preview is the shown character's.
pub fn show(
    mut commands: Commands,
    preview: Res<Preview>,
    session: Res<Session>,
    scene: Option<Res<Scene>>,
    players: Query<&HumanClipPlayer>,
    mut poses: Query<Option<&mut Pose>>,
) {
    let (Some(scene), Some(result)) = (scene, &preview.result) else { return };
    let poses_of = &result.retargeted.motion.poses;
    if result.inputs.character != session.character || poses_of.is_empty() {
        return;
    }
    let Ok(player) = players.get(scene.player) else { return };
    let frame = ((player.time * PROJECT_FPS).round() as usize).min(poses_of.len() - 1);
    match poses.get_mut(scene.character) {
        Ok(Some(mut pose)) => {
            if pose.0 != poses_of[frame] {
                pose.0 = poses_of[frame].clone();
            }
        }
        // A creature's scene has no Pose until the first one arrives (a robot gets its standing pose).
        Ok(None) => {
            commands.entity(scene.character).insert(Pose(poses_of[frame].clone()));
        }
        Err(_) => {}
    }
}
