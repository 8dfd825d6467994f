//! Characters driven by a trained checkpoint (feature `runtime`): the [`Retargeter`] component.
//!
//! A character entity ([`Character`]) with a [`Retargeter`], or a rigged glTF creature's scene (feature
//! `scene`, see `crate::scene`), follows a human source: an entity with a
//! [`HumanClipPlayer`] (play, pause, scrub and speed act on the player) or a [`LiveHuman`] fed by
//! [`LiveHumanFrame`] messages (a mocap stream, or frames made in code). One source can drive any
//! number of characters.
//!
//! **Timing.** The networks were trained at [`PROJECT_FPS`] (30 Hz), so a character advances in
//! ticks of the source's clock: tick `k` is source time `k / 30` s, and its x^h is sampled there
//! (with [`HumanState::sampled`], the rule `ace retarget` uses). Each frame, the ticks the source
//! passed since the last frame are sent to the checkpoint's worker thread (`worker`); the
//! pose of the last one is written to [`Pose`] in the next frame, so characters trail their source
//! by one frame and the networks run while the rest of the frame does. The result depends only on
//! the source's clock: under a fixed time step it is deterministic, and a clip played at 30 fps
//! gives exactly the poses `ace retarget` writes for it. When the source's time goes back (a loop, a
//! seek back) or jumps ahead by more than [`MAX_CATCH_UP`] ticks, the character starts again
//! standing at rest, as `ace retarget` does at a clip's first frame.
//!
//! **Errors** (a checkpoint that fails to load, one trained for another character, a source
//! that is no human) set [`RetargetStatus::Failed`] and are written once as a [`RetargetError`]
//! message; nothing panics. Changing the [`Retargeter`] component, or a reloaded checkpoint, starts
//! over.

use std::collections::{HashMap, HashSet, VecDeque};
use std::sync::Arc;

use ace_models::human::clip::HumanFrame;
use ace_models::human::state::HumanState;
use ace_models::human_set::{HumanRow, PROJECT_FPS};
use ace_models::checkpoint::CharacterInfo;
use ace_models::cleanup::Cleanup;
use bevy::asset::LoadState;
use bevy::prelude::*;

use crate::assets::{BvhAsset, CharacterAsset};
use crate::character::{Character, Pose};
use crate::checkpoint::CheckpointAsset;
use crate::human::HumanClipPlayer;
use crate::worker::{Job, Worker};

/// Source ticks a character catches up on in one frame before it starts over instead (half a second).
pub const MAX_CATCH_UP: i64 = 15;

/// Drives the [`Character`] or the glTF creature scene on the same entity from a human source with a
/// trained checkpoint (see the module docs).
#[derive(Component, Clone, Debug)]
#[require(RetargetStatus, Progress)]
pub struct Retargeter {
    /// The checkpoint, loaded from its `ace.json` (see [`crate::checkpoint`]).
    pub checkpoint: Handle<CheckpointAsset>,
    /// The entity holding the [`HumanClipPlayer`] or [`LiveHuman`].
    pub source: Entity,
    /// The cleanup of this character's poses ([`ace_models::cleanup`]): everything on by default, as
    /// `ace retarget` does; [`Cleanup::NONE`] shows the networks' raw output.
    pub cleanup: Cleanup,
}

impl Retargeter {
    /// A retargeter following `source` with `checkpoint`, with the default cleanup.
    pub fn new(checkpoint: Handle<CheckpointAsset>, source: Entity) -> Self {
        Self { checkpoint, source, cleanup: Cleanup::default() }
    }

    /// The same retargeter with `cleanup` instead (e.g. a robot that should not be steered onto the
    /// person's heading: `Cleanup { heading: None, ..Cleanup::default() }`).
    pub fn with_cleanup(self, cleanup: Cleanup) -> Self {
        Self { cleanup, ..self }
    }
}

/// Where a [`Retargeter`] stands.
#[derive(Component, Clone, Debug, Default, PartialEq)]
pub enum RetargetStatus {
    /// Waiting for the checkpoint, the character's file (and a scene's joints) or the source's clip.
    #[default]
    Loading,
    /// Driving: [`Pose`] holds the pose of source tick `tick` (time `tick / 30` s).
    Running {
        /// The tick whose pose is shown.
        tick: i64,
    },
    /// Stopped, with the reason (also sent as a [`RetargetError`]).
    Failed(String),
}

/// A retargeter stopped: which character and why.
#[derive(Message, Clone, Debug, PartialEq)]
pub struct RetargetError {
    /// The entity holding the [`Retargeter`].
    pub entity: Entity,
    /// What went wrong, naming the file or entity at fault.
    pub message: String,
}

/// A human source fed frame by frame ([`LiveHumanFrame`] messages or [`LiveHuman::push`]): the
/// frames of the last two seconds, interpolated at the ticks characters need.
#[derive(Component, Clone, Debug, Default)]
pub struct LiveHuman {
    frames: VecDeque<(f32, HumanFrame)>,
}

/// Seconds of frames a [`LiveHuman`] keeps.
const LIVE_WINDOW: f32 = 2.0;

/// Why a [`LiveHuman`] refused a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LiveFrameRefused {
    /// Its time is not a finite number.
    BadTime,
    /// It is not later than the newest frame held (out of order, or repeated).
    NotLater,
    /// A joint position or the root rotation is not finite.
    BadPose,
}

impl LiveHuman {
    /// Adds the frame at stream time `time` (seconds, increasing). A frame whose time or pose is not
    /// finite, or that is not later than the newest, is refused and changes nothing: one bad packet
    /// from a mocap stream must not reach the networks.
    pub fn push(&mut self, time: f32, frame: HumanFrame) -> Result<(), LiveFrameRefused> {
        if !time.is_finite() {
            return Err(LiveFrameRefused::BadTime);
        }
        if self.frames.back().is_some_and(|(t, _)| *t >= time) {
            return Err(LiveFrameRefused::NotLater);
        }
        let finite = frame.positions.iter().all(|p| p.iter().all(|v| v.is_finite()))
            && frame.root_rotation.coords.iter().all(|v| v.is_finite());
        if !finite {
            return Err(LiveFrameRefused::BadPose);
        }
        self.frames.push_back((time, frame));
        while self.frames.front().is_some_and(|(t, _)| *t < time - LIVE_WINDOW) && self.frames.len() > 2 {
            self.frames.pop_front();
        }
        Ok(())
    }

    /// Time of the newest frame.
    pub fn latest_time(&self) -> Option<f32> {
        self.frames.back().map(|(t, _)| *t)
    }

    /// The frame at `time`, interpolated, clamped to the frames held.
    pub fn frame_at(&self, time: f32) -> Option<HumanFrame> {
        let i = self.frames.partition_point(|(t, _)| *t <= time);
        match (i.checked_sub(1).map(|j| &self.frames[j]), self.frames.get(i)) {
            (Some((t0, a)), Some((t1, b))) => Some(a.lerp(b, (time - t0) / (t1 - t0))),
            (Some((_, a)), None) | (None, Some((_, a))) => Some(a.clone()),
            (None, None) => None,
        }
    }
}

/// One frame of a live human source, for the [`LiveHuman`] on entity `source`.
#[derive(Message, Clone, Debug)]
pub struct LiveHumanFrame {
    /// The entity holding the [`LiveHuman`].
    pub source: Entity,
    /// Stream time (seconds, increasing).
    pub time: f32,
    /// The pose (metres, z up; see [`HumanFrame`]).
    pub frame: HumanFrame,
}

/// A character's place in its source's ticks.
#[derive(Component, Clone, Debug, Default)]
pub(crate) struct Progress {
    /// The last tick sent to the worker; `None` before the first and after a restart.
    sent: Option<i64>,
}

/// The worker threads, one per checkpoint in use.
#[derive(Resource, Default)]
pub(crate) struct Workers(HashMap<AssetId<CheckpointAsset>, Worker>);

/// Hands [`LiveHumanFrame`] messages to their [`LiveHuman`]s.
pub(crate) fn receive_live_frames(mut frames: MessageReader<LiveHumanFrame>, mut live: Query<&mut LiveHuman>) {
    for f in frames.read() {
        match live.get_mut(f.source) {
            Ok(mut l) => {
                if let Err(why) = l.push(f.time, f.frame.clone()) {
                    warn_once!("a LiveHumanFrame for {} at time {} was refused: {why:?}", f.source, f.time);
                }
            }
            Err(_) => warn_once!("a LiveHumanFrame for {}, which has no LiveHuman", f.source),
        }
    }
}

/// A removed [`Retargeter`] leaves its character standing as it was; one added back later starts over
/// at its source's tick (the worker forgets the character in [`request_poses`]). Without this, the
/// character's place in the ticks outlived the component and one added back asked the worker to go on
/// with a character it had forgotten.
pub(crate) fn reset_removed(remove: On<Remove, Retargeter>, mut characters: Query<(&mut Progress, &mut RetargetStatus)>) {
    if let Ok((mut progress, mut status)) = characters.get_mut(remove.entity) {
        progress.sent = None;
        *status = RetargetStatus::Loading;
    }
}

/// Writes the poses the workers computed during the previous frame.
pub(crate) fn collect_poses(
    mut workers: ResMut<Workers>,
    mut characters: Query<(&mut Pose, &mut RetargetStatus)>,
    mut commands: Commands,
    mut errors: MessageWriter<RetargetError>,
) {
    for worker in workers.0.values_mut() {
        for (entity, outcome) in worker.collect() {
            match (outcome, characters.get_mut(entity)) {
                (Ok((pose, tick)), Ok((mut p, mut status))) => {
                    p.0 = pose;
                    *status = RetargetStatus::Running { tick };
                }
                (Ok((pose, tick)), Err(_)) => {
                    if let Ok(mut e) = commands.get_entity(entity) {
                        e.try_insert((Pose(pose), RetargetStatus::Running { tick }));
                    }
                }
                (Err(message), Ok((_, mut status))) => {
                    errors.write(RetargetError { entity, message: message.clone() });
                    *status = RetargetStatus::Failed(message);
                }
                (Err(_), Err(_)) => {}
            }
        }
    }
}

/// The system parameters [`request_poses`] reads assets through.
#[derive(bevy::ecs::system::SystemParam)]
pub(crate) struct RetargetAssets<'w> {
    server: Res<'w, AssetServer>,
    checkpoints: Res<'w, Assets<CheckpointAsset>>,
    characters: Res<'w, Assets<CharacterAsset>>,
    clips: Res<'w, Assets<BvhAsset>>,
}

/// A retargeter's glTF scene, with feature `scene`.
#[cfg(feature = "scene")]
type Scene = (Option<&'static crate::scene::CreatureScene>, Has<bevy::world_serialization::WorldAssetRoot>);
#[cfg(not(feature = "scene"))]
type Scene = ();

/// The scene's character asset and whether its joints are found; `None` without a bound scene.
#[cfg(feature = "scene")]
fn scene_handle<'a>(scene: (Option<&'a crate::scene::CreatureScene>, bool)) -> Option<(&'a Handle<CharacterAsset>, bool)> {
    scene.0.map(|s| (&s.asset, s.joints.is_some()))
}
#[cfg(not(feature = "scene"))]
fn scene_handle<'a>(_: ()) -> Option<(&'a Handle<CharacterAsset>, bool)> {
    None
}

/// Whether there is a scene that [`crate::scene`] has yet to bind, or has failed to.
#[cfg(feature = "scene")]
fn scene_pending(scene: (Option<&crate::scene::CreatureScene>, bool)) -> bool {
    scene.1
}
#[cfg(not(feature = "scene"))]
fn scene_pending(_: ()) -> bool {
    false
}

/// Sends each character's due ticks to its checkpoint's worker (see the module docs).
#[allow(clippy::too_many_arguments)]
pub(crate) fn request_poses(
    mut workers: ResMut<Workers>,
    mut characters: Query<(Entity, Ref<Retargeter>, Option<&Character>, Scene, &mut RetargetStatus, &mut Progress)>,
    players: Query<&HumanClipPlayer>,
    live: Query<&LiveHuman>,
    assets: RetargetAssets,
    mut checkpoint_events: MessageReader<AssetEvent<CheckpointAsset>>,
    mut removed: RemovedComponents<Retargeter>,
    mut errors: MessageWriter<RetargetError>,
    mut warned: Local<HashSet<(AssetId<CheckpointAsset>, AssetId<CharacterAsset>)>>,
) {
    // A reloaded or removed checkpoint: its worker goes, its characters start over.
    let mut stale = Vec::new();
    for event in checkpoint_events.read() {
        if let AssetEvent::Modified { id } | AssetEvent::Removed { id } = event {
            workers.0.remove(id);
            stale.push(*id);
        }
    }
    let mut forget: HashMap<AssetId<CheckpointAsset>, Vec<Entity>> = HashMap::new();
    let removed: Vec<Entity> = removed.read().collect();
    for worker_id in workers.0.keys() {
        forget.insert(*worker_id, removed.clone());
    }

    let mut jobs: HashMap<AssetId<CheckpointAsset>, Vec<Job>> = HashMap::new();
    for (entity, retargeter, character, scene, mut status, mut progress) in &mut characters {
        let id = retargeter.checkpoint.id();
        // (Not when just added: the defaults are that, and a scene found faulty this frame stays failed.)
        if (retargeter.is_changed() && !retargeter.is_added()) || stale.contains(&id) {
            progress.sent = None;
            *status = RetargetStatus::Loading;
            for list in forget.values_mut() {
                list.push(entity);
            }
        }
        if matches!(*status, RetargetStatus::Failed(_)) {
            continue;
        }
        let mut fail = |message: String, status: &mut RetargetStatus| {
            errors.write(RetargetError { entity, message: message.clone() });
            *status = RetargetStatus::Failed(message);
        };
        if let Some(LoadState::Failed(e)) = assets.server.get_load_state(id) {
            fail(format!("checkpoint failed to load: {e}"), &mut status);
            continue;
        }
        // The character's asset: the Character's, or a glTF scene's once its joints are found.
        let (handle, ready) = match (character, scene_handle(scene)) {
            (Some(c), _) => (&c.asset, true),
            (None, Some(s)) => s,
            (None, None) => {
                if !scene_pending(scene) {
                    fail(format!("{entity} has a Retargeter but neither a Character nor a glTF scene"), &mut status);
                }
                continue;
            }
        };
        if let Some(LoadState::Failed(e)) = assets.server.get_load_state(handle) {
            fail(format!("the character failed to load: {e}"), &mut status);
            continue;
        }
        if !ready {
            continue;
        }
        let (Some(checkpoint), Some(urdf)) = (assets.checkpoints.get(id), assets.characters.get(handle)) else {
            continue;
        };
        // The source's clock and frames.
        let (now, sample): (f32, Box<dyn Fn(f32) -> HumanFrame + '_>) =
            if let Ok(player) = players.get(retargeter.source) {
                if let Some(LoadState::Failed(e)) = assets.server.get_load_state(&player.clip) {
                    fail(format!("the source's clip failed to load: {e}"), &mut status);
                    continue;
                }
                let Some(clip) = assets.clips.get(&player.clip) else { continue };
                (player.time, Box::new(move |t| clip.clip.frame_at(t)))
            } else if let Ok(l) = live.get(retargeter.source) {
                let Some(latest) = l.latest_time() else { continue };
                (latest, Box::new(move |t| l.frame_at(t).expect("a live source with frames")))
            } else {
                fail(format!("source {} has neither a HumanClipPlayer nor a LiveHuman", retargeter.source), &mut status);
                continue;
            };
        let target = (now * PROJECT_FPS + 1e-3).floor() as i64;
        let dt = 1.0 / PROJECT_FPS;
        let row = |k: i64, first: bool| -> HumanRow { HumanState::sampled(&sample, k as f32 * dt, dt, first).0 };
        let job = match progress.sent {
            Some(sent) if target == sent => continue,
            Some(sent) if target > sent && target - sent <= MAX_CATCH_UP => {
                Job { entity, start: None, rows: (sent + 1..=target).map(|k| row(k, false)).collect(), last_tick: target }
            }
            _ => {
                if let Some(problem) = checkpoint.character.difference(&CharacterInfo::of_character(&urdf.tree, &urdf.morphology)) {
                    let kind = if urdf.rig.is_some() { "glTF creature" } else { "URDF character" };
                    fail(
                        format!(
                            "checkpoint {} does not fit character {} (a {kind}): {problem}",
                            checkpoint.dir().display(),
                            urdf.tree.name
                        ),
                        &mut status,
                    );
                    continue;
                }
                // Another version of the trained file (same joints and size) runs, with a warning once.
                if let Some(problem) = checkpoint.character_file_difference(urdf) {
                    if warned.insert((id, handle.id())) {
                        warn!("{problem}");
                    }
                }
                Job {
                    entity,
                    start: Some((Arc::clone(&urdf.tree), Arc::clone(&urdf.morphology), retargeter.cleanup)),
                    rows: vec![row(target, true)],
                    last_tick: target,
                }
            }
        };
        progress.sent = Some(target);
        jobs.entry(id).or_default().push(job);
    }

    for (id, jobs) in jobs {
        let Some(checkpoint) = assets.checkpoints.get(id) else { continue };
        let worker = workers.0.entry(id).or_insert_with(|| Worker::spawn(Arc::clone(&checkpoint.files)));
        worker.send(jobs, forget.remove(&id).unwrap_or_default());
    }
    for (id, forget) in forget {
        if let (Some(worker), false) = (workers.0.get_mut(&id), forget.is_empty()) {
            worker.send(Vec::new(), forget);
        }
    }
}
