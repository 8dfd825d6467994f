//! Progress bars for everything in the CLI that runs longer than a few seconds.

use indicatif::{ProgressBar, ProgressStyle};

/// A bar counting `total` `unit`s with rate and time left; hidden when stderr is not a terminal.
pub fn bar(total: u64, unit: &str) -> ProgressBar {
    let bar = ProgressBar::new(total);
    let template = format!("{{elapsed_precise}} [{{wide_bar}}] {{human_pos}}/{{human_len}} {unit} ({{per_sec}}, {{eta}} left) {{msg}}");
    bar.set_style(ProgressStyle::with_template(&template).expect("valid progress template").progress_chars("=> "));
    bar
}
