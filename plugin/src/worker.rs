//! One worker thread per checkpoint in use, so that the networks run beside the ECS's systems: each
//! worker owns a [`Retargeter`] (the pure-Rust runtime) and the [`CharacterStream`] of
//! every character it drives, and talks to the systems through channels. A request carries the
//! human states of one frame for all of the checkpoint's characters; the worker steps them together
//! (one batched pass of G and π per tick) and sends back each character's newest pose.

use std::collections::HashMap;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Mutex};
use std::thread;

use ace_models::human_set::HumanRow;
use ace_models::kinematics::{CharacterPose, KinematicTree};
use ace_models::checkpoint::CheckpointFiles;
use ace_models::cleanup::Cleanup;
use ace_models::runtime::{CharacterStream, Retargeter};
use ace_models::morphology::Morphology;
use bevy::prelude::Entity;

/// What one character needs this frame.
pub(crate) struct Job {
    pub entity: Entity,
    /// Start (or restart) the character standing at rest, as this character, with this cleanup.
    pub start: Option<(Arc<KinematicTree>, Arc<Morphology>, Cleanup)>,
    /// Tick `k`'s human state is `rows[k]`; the pose after the last one is sent back.
    pub rows: Vec<HumanRow>,
    /// The tick of the last row (reported back with the pose).
    pub last_tick: i64,
}

/// The result for one character: its pose and tick, or why there is none.
pub(crate) type Outcome = (Entity, Result<(CharacterPose, i64), String>);

struct Request {
    jobs: Vec<Job>,
    forget: Vec<Entity>,
}

/// The systems' end of a worker thread.
pub(crate) struct Worker {
    /// `None` once dropping.
    requests: Option<Sender<Request>>,
    outcomes: Mutex<Receiver<Vec<Outcome>>>,
    in_flight: usize,
    thread: Option<thread::JoinHandle<()>>,
}

impl Drop for Worker {
    /// Stops the thread and waits for it, so that no thread still steps while the app tears down.
    fn drop(&mut self) {
        self.requests = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Worker {
    /// Starts a thread that loads the checkpoint's networks from `files` (on the CPU) and serves
    /// requests until the worker is dropped.
    pub(crate) fn spawn(files: Arc<CheckpointFiles>) -> Worker {
        let (requests, incoming) = channel::<Request>();
        let (outgoing, outcomes) = channel();
        let thread = thread::Builder::new()
            .name(format!("ace-retarget {}", files.dir().display()))
            .spawn(move || serve(&files, incoming, outgoing))
            .expect("spawning a retargeting thread");
        Worker { requests: Some(requests), outcomes: Mutex::new(outcomes), in_flight: 0, thread: Some(thread) }
    }

    /// Queues a frame's jobs and the characters to drop; returns at once.
    pub(crate) fn send(&mut self, jobs: Vec<Job>, forget: Vec<Entity>) {
        let failed: Vec<Entity> = jobs.iter().map(|j| j.entity).collect();
        let sent = self.requests.as_ref().is_some_and(|r| r.send(Request { jobs, forget }).is_ok());
        if sent {
            self.in_flight += 1;
        } else {
            // The thread is gone (it only ends by panicking): report it on the next collect.
            let lost = failed.into_iter().map(|e| (e, Err("the retargeting thread stopped".to_string()))).collect();
            let (tx, rx) = channel();
            let _ = tx.send(lost);
            self.outcomes = Mutex::new(rx);
            self.in_flight = 1;
        }
    }

    /// Waits for the answers to every request sent so far (the work was done while the rest of
    /// the previous frame ran, so this rarely waits).
    pub(crate) fn collect(&mut self) -> Vec<Outcome> {
        let mut out = Vec::new();
        let outcomes = self.outcomes.get_mut().unwrap_or_else(|p| p.into_inner());
        while self.in_flight > 0 {
            match outcomes.recv() {
                Ok(o) => out.extend(o),
                Err(_) => break,
            }
            self.in_flight -= 1;
        }
        self.in_flight = 0;
        out
    }
}

struct Driven {
    stream: CharacterStream,
    tree: Arc<KinematicTree>,
    morph: Arc<Morphology>,
}

fn serve(files: &CheckpointFiles, requests: Receiver<Request>, outcomes: Sender<Vec<Outcome>>) {
    let retargeter = Retargeter::load_files(files).map_err(|e| e.to_string());
    let mut driven: HashMap<Entity, Driven> = HashMap::new();
    for Request { jobs, forget } in requests {
        for e in forget {
            driven.remove(&e);
        }
        let out = match &retargeter {
            Ok(r) => step(r, &mut driven, jobs),
            Err(e) => jobs.into_iter().map(|j| (j.entity, Err(e.clone()))).collect(),
        };
        if outcomes.send(out).is_err() {
            return;
        }
    }
}

/// Runs one request: starts the characters that need it, then steps tick by tick, all characters
/// with a row for that tick in one batch.
fn step(r: &Retargeter, driven: &mut HashMap<Entity, Driven>, jobs: Vec<Job>) -> Vec<Outcome> {
    let mut out: Vec<Outcome> = Vec::new();
    let mut ready: Vec<(Job, Driven)> = Vec::new();
    for mut job in jobs {
        let d = match job.start.take() {
            Some((tree, morph, cleanup)) => match r.stream_with(&tree, &morph, &cleanup) {
                Ok(stream) => Driven { stream, tree, morph },
                Err(e) => {
                    driven.remove(&job.entity);
                    out.push((job.entity, Err(e.to_string())));
                    continue;
                }
            },
            None => match driven.remove(&job.entity) {
                Some(d) => d,
                None => {
                    out.push((job.entity, Err("the character was not started".to_string())));
                    continue;
                }
            },
        };
        ready.push((job, d));
    }
    let ticks = ready.iter().map(|(j, _)| j.rows.len()).max().unwrap_or(0);
    let mut poses: Vec<Option<CharacterPose>> = vec![None; ready.len()];
    for k in 0..ticks {
        let active: Vec<usize> = (0..ready.len()).filter(|&i| ready[i].0.rows.len() > k).collect();
        let (tree, morph) = (ready[active[0]].1.tree.clone(), ready[active[0]].1.morph.clone());
        let rows: Vec<HumanRow> = active.iter().map(|&i| ready[i].0.rows[k]).collect();
        let mut streams: Vec<&mut CharacterStream> = ready
            .iter_mut()
            .enumerate()
            .filter(|(i, _)| active.contains(i))
            .map(|(_, (_, d))| &mut d.stream)
            .collect();
        match r.step(&tree, &morph, &mut streams, &rows) {
            Ok(frames) => {
                for (&i, frame) in active.iter().zip(frames) {
                    poses[i] = Some(frame.pose);
                }
            }
            Err(e) => {
                for &i in &active {
                    out.push((ready[i].0.entity, Err(e.to_string())));
                }
                return out;
            }
        }
    }
    for ((job, d), pose) in ready.into_iter().zip(poses) {
        if let Some(pose) = pose {
            out.push((job.entity, Ok((pose, job.last_tick))));
        }
        driven.insert(job.entity, d);
    }
    out
}
