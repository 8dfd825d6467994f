//! `ace demo`: the main job on the bundled defaults. For now (before the learning pipeline lands)
//! it loads a character and a human clip, prints their summaries, and writes `summary.json` and a
//! picture of the scene (`scene.png`: the clip's poses over time beside the character).

use std::path::Path;

use ace::models::nalgebra::Vector3;
use anyhow::{Context, Result};

use crate::{inspect, picture};

/// Runs the demo and writes its outputs into `out`.
pub fn run(character: &Path, clip_path: &Path, out: &Path) -> Result<()> {
    let (clip, clip_summary) = inspect::bvh_summary(clip_path)?;
    let (tree, _morphology, character_summary) = inspect::urdf_summary(character)?;
    println!("human clip\n{}", inspect::text(&clip_summary));
    println!("character\n{}", inspect::text(&character_summary));

    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let summary = serde_json::json!({ "clip": clip_summary, "character": character_summary });
    let summary_path = out.join("summary.json");
    std::fs::write(&summary_path, serde_json::to_string_pretty(&summary)?).with_context(|| format!("writing {}", summary_path.display()))?;

    let pose = tree.standing_pose();
    let mut segments = picture::character_segments(&tree, &pose, [214, 140, 30]);
    // The human stands 1.5 m to the character's left; its path is shifted so that it starts there.
    let start = clip.frames.first().context("the clip has no frames")?.positions[0];
    let offset = Vector3::new(-start.x, 1.5 - start.y, 0.0);
    const SAMPLES: usize = 5;
    for k in 0..SAMPLES {
        let t = clip.duration() * k as f32 / (SAMPLES - 1) as f32;
        let shade = (170.0 * (1.0 - k as f32 / (SAMPLES - 1) as f32)) as u8;
        segments.extend(picture::human_segments(&clip.frame_at(t), offset, [shade, shade.saturating_add(60), 235]));
    }
    // The grid goes underneath: drawn first, everything else over it.
    let mut scene = picture::ground_segments(&segments);
    scene.extend(segments);
    let picture_path = out.join("scene.png");
    picture::render(&scene, 1280, 720, 0.9, 0.35, &picture_path)?;
    println!("wrote {} and {}", summary_path.display(), picture_path.display());
    Ok(())
}
