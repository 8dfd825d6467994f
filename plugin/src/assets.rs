//! Asset types and loaders for characters (`.urdf` robots, rigged `.glb`/`.gltf` creatures) and `.bvh`
//! human clips.
//!
//! **Which loader.** Bevy's own glTF loader claims `.glb` and `.gltf` too. The character loader claims
//! only `.urdf` by extension and is otherwise chosen by the asset type: `assets.load::<CharacterAsset>
//! ("Fox.glb")` (or a `Handle<CharacterAsset>` the call's type names) gets a [`CharacterAsset`], while
//! `"Fox.glb#Scene0"` and untyped loads of `.glb` stay Bevy's (a labelled path is resolved by its
//! extension only).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use ace_models::character::{RigPose, creature_from_document, gltf, is_gltf};
use ace_models::checkpoint::FileRecord;
use ace_models::human::clip::{decode_text, mapping_path_beside};
use ace_models::human::{HumanClip, ImportOptions, JointMapping};
use ace_models::kinematics::KinematicTree;
use ace_models::morphology::{Morphology, Profile};
use bevy::asset::io::{AssetReaderError, Reader};
use bevy::asset::{Asset, AssetLoader, AssetPath, AssetServer, AssetServerMode, LoadContext, ReadAssetBytesError};
use bevy::reflect::TypePath;
use serde::{Deserialize, Serialize};

/// A character: a URDF robot or a rigged glTF creature, as its kinematic tree and morphology.
///
/// When a profile file `<stem>.profile.toml` stands beside the file (in the same asset source) it
/// sets the rest pose and overrides the automatic morphology analysis (feet, manipulators, wheels,
/// head; for creatures also the scale, the facing axis and which bones move), as
/// `ace_models::morphology::load_character` does for files. A URDF's mesh files are not read here,
/// so mesh-only links have no extent in the analysis.
#[derive(Asset, TypePath, Clone, Debug)]
pub struct CharacterAsset {
    /// Links in topological order, joints, geometry.
    pub tree: Arc<KinematicTree>,
    /// Feet, manipulators, wheels and head, as link indices into `tree`.
    pub morphology: Arc<Morphology>,
    /// For a glTF creature, how a pose becomes its bone nodes' transforms (see
    /// [`ace_models::character::rig_pose`]); `None` for a URDF.
    pub rig: Option<Arc<RigPose>>,
    /// The file's size and checksum (named by its asset path; a `.gltf`'s own bytes, not its
    /// buffers'), compared with the file a checkpoint was trained with
    /// ([`crate::checkpoint::CheckpointAsset::character_file_difference`]).
    pub file: FileRecord,
}

/// A human clip loaded from a BVH file, mapped to the canonical 17-joint skeleton.
#[derive(Asset, TypePath, Clone, Debug)]
pub struct BvhAsset {
    /// The imported clip (metres, z up).
    pub clip: Arc<HumanClip>,
}

/// Errors of the asset loaders; each names the asset path.
#[derive(Debug, thiserror::Error)]
pub enum AceAssetError {
    /// The file could not be read.
    #[error("could not read {path}: {error}")]
    Io { path: String, error: std::io::Error },
    /// The file is not UTF-8 text (UTF-16, or invalid bytes): what it is instead.
    #[error("{path}: {problem}")]
    NotText { path: String, problem: String },
    /// The file's content was rejected by the importer.
    #[error("{path}: {message}")]
    Import { path: String, message: String },
}

/// `path` (inside an asset source) in the asset source of the file `ctx` loads: a file's siblings
/// (a profile, a glTF's buffers, a checkpoint's other files) are read from where the file came from
/// (`custom://characters/x.urdf`'s profile from `custom://`), not from the default source.
pub(crate) fn beside(ctx: &LoadContext<'_>, path: PathBuf) -> AssetPath<'static> {
    AssetPath::from_path_buf(path).with_source(ctx.path().source().clone_owned())
}

/// The bytes of `reader` (the file `path`), refused once more than `max` are read (the core's bound
/// for the file's kind, [`ace_models::input`]): an asset source need not know a file's size
/// beforehand, and a mistaken path must not fill memory. A seekable reader (a file source's) is
/// refused from its size before anything is read.
pub(crate) async fn read_bounded(reader: &mut dyn Reader, path: &str, max: u64) -> Result<Vec<u8>, AceAssetError> {
    use bevy::asset::AsyncReadExt;
    let too_big = || AceAssetError::Import { path: path.to_string(), message: too_big_message(max) };
    if size_of(reader).await.is_some_and(|size| size > max) {
        return Err(too_big());
    }
    let mut bytes = Vec::new();
    AsyncReadExt::take(&mut *reader, max + 1)
        .read_to_end(&mut bytes)
        .await
        .map_err(|error| AceAssetError::Io { path: path.to_string(), error })?;
    if bytes.len() as u64 > max {
        return Err(too_big());
    }
    Ok(bytes)
}

fn too_big_message(max: u64) -> String {
    format!("the file has more than the {max} bytes this kind of file may have")
}

/// The size of a seekable reader's file (left at its start), `None` when it cannot seek.
async fn size_of(reader: &mut dyn Reader) -> Option<u64> {
    use bevy::asset::AsyncSeekExt;
    let seekable = reader.seekable().ok()?;
    let end = seekable.seek(std::io::SeekFrom::End(0)).await.ok()?;
    seekable.seek(std::io::SeekFrom::Start(0)).await.ok()?;
    Some(end)
}

/// A file beside the one `ctx` loads (a profile, a glTF's buffer, a joint mapping, a checkpoint's
/// other files), from `path` ([`beside`]), with the bound of [`read_bounded`]: `Ok(None)` when it is
/// not there, `Err` with the problem otherwise. [`LoadContext::read_asset_bytes`] has no bound, so the
/// file is opened here first and its size checked; one within the bound is then read through the
/// context, which registers it as a dependency (an edited profile hot-reloads its character). A
/// source that cannot seek is read here, bounded, and not registered.
pub(crate) async fn read_beside(
    server: &AssetServer,
    ctx: &mut LoadContext<'_>,
    path: AssetPath<'static>,
    max: u64,
) -> Result<Option<Vec<u8>>, String> {
    let source = server.get_source(path.source()).map_err(|e| e.to_string())?;
    let reader = match server.mode() {
        AssetServerMode::Unprocessed => source.reader(),
        AssetServerMode::Processed => source.processed_reader().map_err(|e| e.to_string())?,
    };
    let mut file = match reader.read(path.path()).await {
        Ok(file) => file,
        Err(AssetReaderError::NotFound(_)) => return Ok(None),
        Err(e) => return Err(e.to_string()),
    };
    match size_of(&mut *file).await {
        Some(size) if size > max => Err(too_big_message(max)),
        Some(_) => {
            drop(file);
            ctx.read_asset_bytes(path).await.map(Some).map_err(|e| match e {
                // Gone between the two opens.
                ReadAssetBytesError::AssetReaderError(AssetReaderError::NotFound(_)) => "the file vanished while read".to_string(),
                e => e.to_string(),
            })
        }
        None => {
            let shown = path.path().display().to_string();
            read_bounded(&mut *file, &shown, max).await.map(Some).map_err(|e| match e {
                AceAssetError::Import { message, .. } => message,
                e => e.to_string(),
            })
        }
    }
}

async fn read_text(reader: &mut dyn Reader, ctx: &LoadContext<'_>) -> Result<String, AceAssetError> {
    let path = ctx.path().to_string();
    let bytes = read_bounded(reader, &path, ace_models::input::MAX_TEXT_BYTES).await?;
    ace_models::input::text_from_bytes(bytes).map_err(|e| AceAssetError::NotText { path, problem: e.to_string() })
}

/// Loads `.urdf` files, and `.glb`/`.gltf` files when a [`CharacterAsset`] is asked for (see the module
/// docs), into [`CharacterAsset`]s.
#[derive(TypePath)]
pub struct CharacterLoader {
    /// Reads the files beside a character ([`read_beside`]).
    pub(crate) server: AssetServer,
}

impl AssetLoader for CharacterLoader {
    type Asset = CharacterAsset;
    type Settings = ();
    type Error = AceAssetError;

    async fn load(
        &self,
        reader: &mut dyn Reader,
        _settings: &(),
        ctx: &mut LoadContext<'_>,
    ) -> Result<CharacterAsset, AceAssetError> {
        let path = ctx.path().to_string();
        let import = |message: String| AceAssetError::Import { path: path.clone(), message };
        let profile_path = Profile::path_beside(ctx.path().path());
        let profile_asset = beside(ctx, profile_path.clone());
        let profile = match read_beside(&self.server, ctx, profile_asset, ace_models::input::MAX_TEXT_BYTES).await {
            Ok(Some(bytes)) => {
                let text = ace_models::input::text_from_bytes(bytes)
                    .map_err(|e| import(format!("profile {}: {e}", profile_path.display())))?;
                Some(Profile::from_toml(&text, &profile_path.display().to_string()).map_err(|e| import(e.to_string()))?)
            }
            // No profile beside the file: the automatic body plan. A profile that is there but cannot
            // be read is an error, not a silently different body plan.
            Ok(None) => None,
            Err(e) => return Err(import(format!("profile {}: {e}", profile_path.display()))),
        };
        if is_gltf(ctx.path().path()) {
            return load_creature(&self.server, reader, ctx, profile.unwrap_or_default()).await;
        }
        let xml = read_text(reader, ctx).await?;
        let file = FileRecord::of(&path, xml.as_bytes());
        let mut tree = KinematicTree::from_urdf_str(&xml).map_err(|e| import(e.to_string()))?;
        let morphology = match profile {
            Some(profile) => {
                profile.check_urdf().map_err(|e| import(e.to_string()))?;
                profile.apply_rest_pose(&mut tree).map_err(|e| import(e.to_string()))?;
                Morphology::with_profile(&tree, &profile).map_err(|e| import(e.to_string()))?
            }
            None => Morphology::analyze(&tree),
        };
        Ok(CharacterAsset { tree: Arc::new(tree), morphology: Arc::new(morphology), rig: None, file })
    }

    fn extensions(&self) -> &[&str] {
        // Not "glb" or "gltf": those stay Bevy's for untyped and labelled loads (see the module docs).
        &["urdf"]
    }
}

/// A rigged glTF creature, its buffers in other files read through the asset reader.
async fn load_creature(
    server: &AssetServer,
    reader: &mut dyn Reader,
    ctx: &mut LoadContext<'_>,
    profile: Profile,
) -> Result<CharacterAsset, AceAssetError> {
    let path = ctx.path().to_string();
    let import = |message: String| AceAssetError::Import { path: path.clone(), message };
    let bytes = read_bounded(reader, &path, gltf::MAX_FILE_BYTES).await?;
    let file: PathBuf = ctx.path().path().to_path_buf();
    let dir = file.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut external = Vec::new();
    for uri in gltf::external_buffers(&bytes, &file).map_err(|e| import(e.problem.to_string()))? {
        if external.iter().any(|(u, _)| *u == uri) {
            // Listed twice: `open_bytes` refuses it; read once.
            continue;
        }
        let buffer = beside(ctx, dir.join(&uri));
        let data = read_beside(server, ctx, buffer, gltf::MAX_FILE_BYTES)
            .await
            .and_then(|bytes| bytes.ok_or_else(|| "no such file".to_string()));
        external.push((uri, data));
    }
    let find = |uri: &str| {
        external.iter().find(|(u, _)| u == uri).map_or_else(|| Err("not read".to_string()), |(_, d)| d.clone())
    };
    let (doc, buffers) = gltf::open_bytes(&bytes, &file, &find).map_err(|e| import(e.problem.to_string()))?;
    let creature = creature_from_document(&doc, &buffers, &file, &profile).map_err(|e| import(e.to_string()))?;
    let rig = RigPose::new(&creature, &doc).map_err(|e| import(e.to_string()))?;
    Ok(CharacterAsset {
        tree: Arc::new(creature.tree),
        morphology: Arc::new(creature.morphology),
        rig: Some(Arc::new(rig)),
        file: FileRecord::of(&path, &bytes),
    })
}

/// Settings of the BVH loader (set them in a `.bvh.meta` file or with `load_with_settings`).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct BvhSettings {
    /// Resample the clip to this frame rate; `None` keeps the file's rate.
    pub fps: Option<f32>,
    /// A joint-mapping file (asset path in the clip's asset source); `None` reads
    /// `<clip>.mapping.toml` beside the clip when there is one, as the CLI does.
    pub mapping: Option<PathBuf>,
}

/// The joint mapping of the clip `ctx` loads: `settings.mapping`'s, which must be there, or the one
/// beside the clip, if any.
async fn read_mapping(
    server: &AssetServer,
    settings: &BvhSettings,
    ctx: &mut LoadContext<'_>,
) -> Result<Option<JointMapping>, AceAssetError> {
    let (path, required) = match &settings.mapping {
        Some(p) => (p.clone(), true),
        None => (mapping_path_beside(ctx.path().path()), false),
    };
    let asset = beside(ctx, path.clone());
    let bytes = match read_beside(server, ctx, asset, ace_models::input::MAX_TEXT_BYTES).await {
        Ok(Some(bytes)) => bytes,
        Ok(None) if !required => return Ok(None),
        Ok(None) => return Err(AceAssetError::Import { path: path.display().to_string(), message: "no such file".into() }),
        // A mapping that is there but cannot be read is an error, not a clip read without it.
        Err(message) => return Err(AceAssetError::Import { path: path.display().to_string(), message }),
    };
    let file = path.display().to_string();
    let text = ace_models::input::text_from_bytes(bytes).map_err(|e| AceAssetError::NotText { path: file.clone(), problem: e.to_string() })?;
    JointMapping::parse(&text, &file).map(Some).map_err(|e| AceAssetError::Import { path: file, message: e.to_string() })
}

/// Loads `.bvh` files into [`BvhAsset`]s.
#[derive(TypePath)]
pub struct BvhLoader {
    /// Reads the joint mapping beside a clip ([`read_beside`]).
    pub(crate) server: AssetServer,
}

impl AssetLoader for BvhLoader {
    type Asset = BvhAsset;
    type Settings = BvhSettings;
    type Error = AceAssetError;

    async fn load(
        &self,
        reader: &mut dyn Reader,
        settings: &BvhSettings,
        ctx: &mut LoadContext<'_>,
    ) -> Result<BvhAsset, AceAssetError> {
        let path = ctx.path().to_string();
        let bytes = read_bounded(reader, &path, ace_models::input::MAX_BVH_BYTES).await?;
        // Decoded as the CLI decodes a clip (Latin-1 names read, UTF-16 refused with a hint).
        let text = decode_text(&bytes, &path).map_err(|e| AceAssetError::Import { path: path.clone(), message: e.to_string() })?;
        let name = ctx.path().path().file_stem().map_or_else(|| path.clone(), |s| s.to_string_lossy().into_owned());
        let opts = ImportOptions { fps: settings.fps, mapping: read_mapping(&self.server, settings, ctx).await? };
        let clip = HumanClip::from_bvh_str(&text, &name, &opts)
            .map_err(|e| AceAssetError::Import { path, message: e.to_string() })?;
        Ok(BvhAsset { clip: Arc::new(clip) })
    }

    fn extensions(&self) -> &[&str] {
        &["bvh"]
    }
}
