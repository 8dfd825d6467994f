//! Asset types and loaders for `.urdf` characters and `.bvh` human clips.

use std::sync::Arc;

use ace_models::human::{HumanClip, ImportOptions};
use ace_models::kinematics::KinematicTree;
use ace_models::morphology::{Morphology, Profile};
use bevy::asset::{Asset, AssetLoader, LoadContext, io::Reader};
use bevy::reflect::TypePath;
use serde::{Deserialize, Serialize};

/// A character loaded from a URDF file: its kinematic tree and morphology.
///
/// When a profile file `<stem>.profile.toml` stands beside the URDF it sets the rest pose and
/// overrides the automatic morphology analysis (feet, manipulators, wheels, head), as
/// `ace_models::morphology::load_character` does for files. Mesh files are not read here, so
/// mesh-only links have no extent in the analysis.
#[derive(Asset, TypePath, Clone, Debug)]
pub struct UrdfAsset {
    /// Links in topological order, joints, geometry.
    pub tree: Arc<KinematicTree>,
    /// Feet, manipulators, wheels and head, as link indices into `tree`.
    pub morphology: Arc<Morphology>,
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
    #[error("could not read {path}: {source}")]
    Io { path: String, source: std::io::Error },
    /// The file is not UTF-8 text.
    #[error("{path} is not UTF-8 text")]
    NotText { path: String },
    /// The file's content was rejected by the importer.
    #[error("{path}: {message}")]
    Import { path: String, message: String },
}

async fn read_text(reader: &mut dyn Reader, ctx: &LoadContext<'_>) -> Result<String, AceAssetError> {
    let path = ctx.path().to_string();
    let mut bytes = Vec::new();
    reader.read_to_end(&mut bytes).await.map_err(|source| AceAssetError::Io { path: path.clone(), source })?;
    String::from_utf8(bytes).map_err(|_| AceAssetError::NotText { path })
}

/// Loads `.urdf` files into [`UrdfAsset`]s.
#[derive(Default, TypePath)]
pub struct UrdfLoader;

impl AssetLoader for UrdfLoader {
    type Asset = UrdfAsset;
    type Settings = ();
    type Error = AceAssetError;

    async fn load(
        &self,
        reader: &mut dyn Reader,
        _settings: &(),
        ctx: &mut LoadContext<'_>,
    ) -> Result<UrdfAsset, AceAssetError> {
        let xml = read_text(reader, ctx).await?;
        let path = ctx.path().to_string();
        let import = |message: String| AceAssetError::Import { path: path.clone(), message };
        let mut tree = KinematicTree::from_urdf_str(&xml).map_err(|e| import(e.to_string()))?;
        let profile_path = ctx.path().path().with_extension("profile.toml");
        let morphology = match ctx.read_asset_bytes(profile_path.clone()).await {
            Ok(bytes) => {
                let text = String::from_utf8(bytes)
                    .map_err(|_| import(format!("profile {} is not UTF-8 text", profile_path.display())))?;
                let profile = Profile::from_toml(&text, &profile_path.display().to_string()).map_err(|e| import(e.to_string()))?;
                profile.apply_rest_pose(&mut tree).map_err(|e| import(e.to_string()))?;
                Morphology::with_profile(&tree, &profile).map_err(|e| import(e.to_string()))?
            }
            Err(_) => Morphology::analyze(&tree),
        };
        Ok(UrdfAsset { tree: Arc::new(tree), morphology: Arc::new(morphology) })
    }

    fn extensions(&self) -> &[&str] {
        &["urdf"]
    }
}

/// Settings of the BVH loader (set them in a `.bvh.meta` file or with `load_with_settings`).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct BvhSettings {
    /// Resample the clip to this frame rate; `None` keeps the file's rate.
    pub fps: Option<f32>,
}

/// Loads `.bvh` files into [`BvhAsset`]s.
#[derive(Default, TypePath)]
pub struct BvhLoader;

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
        let text = read_text(reader, ctx).await?;
        let path = ctx.path().to_string();
        let name = ctx.path().path().file_stem().map_or_else(|| path.clone(), |s| s.to_string_lossy().into_owned());
        let opts = ImportOptions { fps: settings.fps, ..Default::default() };
        let clip = HumanClip::from_bvh_str(&text, &name, &opts)
            .map_err(|e| AceAssetError::Import { path, message: e.to_string() })?;
        Ok(BvhAsset { clip: Arc::new(clip) })
    }

    fn extensions(&self) -> &[&str] {
        &["bvh"]
    }
}
