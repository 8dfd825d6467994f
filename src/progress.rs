//! Progress bars for everything in the CLI that runs longer than a few seconds.
//!
//! On a terminal the bar redraws in place. When stderr is not a terminal (a log file, CI), the same
//! line is written as plain text at most every [`LOG_INTERVAL`], so long jobs still show how far they
//! are without filling the log with redraws.

use std::io::{IsTerminal, Write};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle, TermLike};

/// How often a bar writes a line when stderr is not a terminal.
pub const LOG_INTERVAL: Duration = Duration::from_secs(15);

/// A bar counting `total` `unit`s with rate and time left.
pub fn bar(total: u64, unit: &str) -> ProgressBar {
    let template = format!("{{elapsed_precise}} [{{wide_bar}}] {{human_pos}}/{{human_len}} {unit} ({{per_sec}}, {{eta}} left) {{msg}}");
    let style = ProgressStyle::with_template(&template)
        .expect("valid progress template")
        .progress_chars("=> ");
    let target = if std::io::stderr().is_terminal() {
        ProgressDrawTarget::stderr()
    } else {
        ProgressDrawTarget::term_like_with_hz(Box::new(LogLines::default()), 1)
    };
    ProgressBar::with_draw_target(Some(total), target).with_style(style)
}

/// A [`TermLike`] that writes each drawn line to stderr as a plain line, throttled.
#[derive(Debug, Default)]
struct LogLines {
    last: Mutex<Option<Instant>>,
}

impl LogLines {
    fn log(&self, line: &str) -> std::io::Result<()> {
        let line = line.trim();
        if line.is_empty() {
            return Ok(());
        }
        let mut last = self.last.lock().unwrap_or_else(|e| e.into_inner());
        if last.is_some_and(|t| t.elapsed() < LOG_INTERVAL) {
            return Ok(());
        }
        *last = Some(Instant::now());
        writeln!(std::io::stderr(), "{line}")
    }
}

impl TermLike for LogLines {
    fn width(&self) -> u16 {
        100
    }
    fn move_cursor_up(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn move_cursor_down(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn move_cursor_right(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn move_cursor_left(&self, _: usize) -> std::io::Result<()> {
        Ok(())
    }
    fn write_line(&self, s: &str) -> std::io::Result<()> {
        self.log(s)
    }
    fn write_str(&self, s: &str) -> std::io::Result<()> {
        self.log(s)
    }
    fn clear_line(&self) -> std::io::Result<()> {
        Ok(())
    }
    fn flush(&self) -> std::io::Result<()> {
        std::io::stderr().flush()
    }
}
