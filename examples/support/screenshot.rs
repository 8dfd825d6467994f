//! The examples' `--screenshot`: saves the window once the clip has played a given time, then exits;
//! and their error reporting, which ends such an unattended run when it cannot get there.

use std::path::PathBuf;

use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, save_to_disk};
use bevy_ace::prelude::{HumanClipPlayer, RetargetError};

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

/// Logs the retargeters' errors (a checkpoint, character or clip that failed to load, named with its
/// path). A run waiting for a screenshot then exits with an error: its clip would never play that far.
pub fn report_errors(mut errors: MessageReader<RetargetError>, to: Res<ScreenshotAt>, mut exit: MessageWriter<AppExit>) {
    let mut failed = false;
    for e in errors.read() {
        error!("{}: {}", e.entity, e.message);
        failed = true;
    }
    if failed && to.0.is_some() {
        exit.write(AppExit::error());
    }
}
