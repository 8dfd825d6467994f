//! Work off the frame: a background thread that reports messages the UI polls each frame.

use std::sync::Mutex;
use std::sync::mpsc::{Receiver, Sender, TryRecvError, channel};
use std::thread;

/// A running background task sending `M`s; the last one ends it.
pub struct Job<M> {
    messages: Mutex<Receiver<M>>,
    finished: bool,
}

impl<M: Send + 'static> Job<M> {
    /// Runs `work` on its own thread; it reports through the sender it is given.
    pub fn spawn(name: &str, work: impl FnOnce(&Sender<M>) + Send + 'static) -> Job<M> {
        let (tx, rx) = channel();
        thread::Builder::new()
            .name(name.to_string())
            .spawn(move || work(&tx))
            .expect("spawning a background thread");
        Job { messages: Mutex::new(rx), finished: false }
    }

    /// The messages sent since the last poll.
    pub fn poll(&mut self) -> Vec<M> {
        let rx = self.messages.get_mut().unwrap_or_else(|p| p.into_inner());
        let mut out = Vec::new();
        loop {
            match rx.try_recv() {
                Ok(m) => out.push(m),
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => {
                    self.finished = true;
                    break;
                }
            }
        }
        out
    }

    /// Whether the thread has ended (after a poll saw it go).
    pub fn finished(&self) -> bool {
        self.finished
    }
}
