//! Work off the frame: a background thread that reports messages the UI polls each frame.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::mpsc::{Receiver, Sender, TryRecvError, channel};
use std::sync::{Arc, Mutex};
use std::thread;

/// A running background task sending `M`s; the last one ends it.
pub struct Job<M> {
    messages: Mutex<Receiver<M>>,
    finished: bool,
    /// What the thread panicked with, if it did: the UI shows it rather than the job just vanishing.
    panic: Arc<Mutex<Option<String>>>,
}

impl<M: Send + 'static> Job<M> {
    /// Runs `work` on its own thread; it reports through the sender it is given.
    pub fn spawn(name: &str, work: impl FnOnce(&Sender<M>) + Send + 'static) -> Job<M> {
        let (tx, rx) = channel();
        let panic = Arc::new(Mutex::new(None));
        let slot = panic.clone();
        thread::Builder::new()
            .name(name.to_string())
            .spawn(move || {
                if let Err(p) = catch_unwind(AssertUnwindSafe(|| work(&tx))) {
                    let what = p
                        .downcast_ref::<&str>()
                        .map(|s| s.to_string())
                        .or_else(|| p.downcast_ref::<String>().cloned())
                        .unwrap_or_else(|| "a panic without a message".into());
                    *slot.lock().unwrap_or_else(|e| e.into_inner()) = Some(what);
                }
                // `tx` drops here, after the panic is recorded: a poll that sees the job end sees why.
                drop(tx);
            })
            .expect("spawning a background thread");
        Job { messages: Mutex::new(rx), finished: false, panic }
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

    /// Once finished: the internal error the thread panicked with, if it did.
    pub fn panicked(&self) -> Option<String> {
        if !self.finished {
            return None;
        }
        self.panic.lock().unwrap_or_else(|e| e.into_inner()).as_ref().map(|p| format!("internal error: {p}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn until_finished<M: Send + 'static>(job: &mut Job<M>) -> Vec<M> {
        let mut all = Vec::new();
        while !job.finished() {
            all.extend(job.poll());
            thread::yield_now();
        }
        all
    }

    #[test]
    fn a_job_that_panics_reports_why_when_it_ends() {
        let mut job = Job::spawn("test-panic", |tx: &Sender<u32>| {
            tx.send(1).unwrap();
            panic!("the checkpoint's mapping names 9 links");
        });
        assert_eq!(until_finished(&mut job), vec![1]);
        assert_eq!(job.panicked().as_deref(), Some("internal error: the checkpoint's mapping names 9 links"));
        let mut fine = Job::spawn("test-fine", |tx: &Sender<u32>| tx.send(2).unwrap());
        assert_eq!(until_finished(&mut fine), vec![2]);
        assert_eq!(fine.panicked(), None);
    }
}
