//! Trained checkpoints as assets (feature `runtime`): load `<dir>/ace.json` as a [`CheckpointAsset`]
//! and its sibling files come with it.
//!
//! ```no_run
//! # use bevy::prelude::*;
//! # use bevy_ace::prelude::*;
//! fn load(assets: Res<AssetServer>) {
//!     let checkpoint: Handle<CheckpointAsset> = assets.load("checkpoints/spot/ace.json");
//! }
//! ```
//!
//! The loader is chosen by the asset type (it claims no file extension, so other `.json` loaders are
//! unaffected). It reads the generator and the motion prior beside `ace.json` through the asset
//! reader, from the asset source `ace.json` came from (`custom://checkpoints/spot/ace.json`'s from
//! `custom://`), and loads them once to check that they belong together; a missing or broken file
//! fails the load with its path and the problem.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use ace_models::checkpoint::ace::{ACE_FILE, GENERATOR_FILE, other_character_file};
use ace_models::checkpoint::prior::{CONFIG_FILE, WEIGHTS_FILE};
use ace_models::checkpoint::{CharacterInfo, CheckpointFiles, FileRecord};
use ace_models::runtime::Retargeter;
use ace_models::input::{MAX_DATA_BYTES, MAX_TEXT_BYTES};
use bevy::asset::io::Reader;
use bevy::asset::{Asset, AssetLoader, AssetServer, LoadContext};
use bevy::reflect::TypePath;

use crate::assets::{AceAssetError, CharacterAsset, beside, read_beside};

/// The files of a trained checkpoint (prior and generator), checked to load and to belong together.
/// The networks themselves live in the plugin's worker threads, one per checkpoint in use.
#[derive(Asset, TypePath, Clone, Debug)]
pub struct CheckpointAsset {
    /// The checkpoint's files, in memory.
    pub files: Arc<CheckpointFiles>,
    /// The character the checkpoint was trained for.
    pub character: CharacterInfo,
    /// The character file it was trained with (its path then, size and checksum), when training
    /// recorded it.
    pub character_file: Option<FileRecord>,
    /// Set when the generator's training stopped before its configured steps
    /// ([`ace_models::checkpoint::ace::AceRecord::unfinished`]): the checkpoint runs, part-trained.
    /// The loader logs it as a warning.
    pub unfinished: Option<String>,
}

impl CheckpointAsset {
    /// The checkpoint directory (as the asset path names it).
    pub fn dir(&self) -> &Path {
        self.files.dir()
    }

    /// How `character`'s file differs from the one the checkpoint was trained with, when it does (see
    /// [`ace_models::checkpoint::ace::AceRecord::character_file_difference`]). The plugin logs it as
    /// a warning once per checkpoint and character; the checkpoint still runs.
    pub fn character_file_difference(&self, character: &CharacterAsset) -> Option<String> {
        other_character_file(self.character_file.as_ref()?, &character.file)
            .map(|problem| format!("checkpoint {}: {problem}", self.dir().display()))
    }
}

/// Loads a checkpoint's `ace.json` and its siblings into a [`CheckpointAsset`].
#[derive(TypePath)]
pub struct CheckpointLoader {
    /// Reads the files beside `ace.json` ([`crate::assets::read_beside`]).
    pub(crate) server: AssetServer,
}

/// The files inference needs besides `ace.json`.
const SIBLINGS: [&str; 3] = [CONFIG_FILE, WEIGHTS_FILE, GENERATOR_FILE];

impl AssetLoader for CheckpointLoader {
    type Asset = CheckpointAsset;
    type Settings = ();
    type Error = AceAssetError;

    async fn load(
        &self,
        reader: &mut dyn Reader,
        _settings: &(),
        ctx: &mut LoadContext<'_>,
    ) -> Result<CheckpointAsset, AceAssetError> {
        let path = ctx.path().to_string();
        let dir: PathBuf = ctx.path().path().parent().map(Path::to_path_buf).unwrap_or_default();
        let mut files = BTreeMap::new();
        let bytes = crate::assets::read_bounded(reader, &path, MAX_TEXT_BYTES).await?;
        files.insert(ACE_FILE.to_string(), bytes);
        for name in SIBLINGS {
            // From the asset source `ace.json` came from. A missing file is left out: loading names
            // it (`dir/<file>` is missing). A file that is there but cannot be read says why.
            let sibling = beside(ctx, dir.join(name));
            let max = if name.ends_with(".json") { MAX_TEXT_BYTES } else { MAX_DATA_BYTES };
            match read_beside(&self.server, ctx, sibling, max).await {
                Ok(Some(bytes)) => {
                    files.insert(name.to_string(), bytes);
                }
                Ok(None) => {}
                Err(e) => {
                    let message = format!("{}: {e}", dir.join(name).display());
                    return Err(AceAssetError::Import { path: path.clone(), message });
                }
            }
        }
        let files = CheckpointFiles::in_memory(&dir, files);
        let retargeter = Retargeter::load_files(&files)
            .map_err(|e| AceAssetError::Import { path: path.clone(), message: e.to_string() })?;
        let character = retargeter.character().clone();
        let character_file = retargeter.record().character_file();
        let unfinished = retargeter.record().unfinished().map(|w| format!("checkpoint {}: {w}", dir.display()));
        if let Some(w) = &unfinished {
            bevy::log::warn!("{w}");
        }
        Ok(CheckpointAsset { files: Arc::new(files), character, character_file, unfinished })
    }

    fn extensions(&self) -> &[&str] {
        &[]
    }
}
