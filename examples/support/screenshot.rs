//! The examples' `--screenshot`: saves the window once the clip has played a given time, then exits.

use std::path::PathBuf;

use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, save_to_disk};
use bevy_ace::prelude::HumanClipPlayer;

/// Where to save the window, and after how many seconds of the example's clip.
#[derive(Resource)]
pub struct ScreenshotAt(pub Option<(PathBuf, f32)>);

/// Saves the window once the (first) clip player has played the asked time, then exits a few frames
/// later, when the screenshot is written.
pub fn take_screenshot(
    mut commands: Commands,
    mut to: ResMut<ScreenshotAt>,
    players: Query<&HumanClipPlayer>,
    mut countdown: Local<Option<u32>>,
    mut exit: MessageWriter<AppExit>,
) {
    if let Some(n) = countdown.as_mut() {
        *n -= 1;
        if *n == 0 {
            exit.write(AppExit::Success);
        }
        return;
    }
    let Some((path, at)) = to.0.clone() else { return };
    if players.iter().next().is_some_and(|p| p.time >= at) {
        commands.spawn(Screenshot::primary_window()).observe(save_to_disk(path));
        to.0 = None;
        *countdown = Some(30);
    }
}
