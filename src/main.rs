//! `ace`: the command-line front of ACE retargeting.

use ace::{batch, dataset, demo, eval, inspect, metrics, retarget, train};

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "ace", version, about = "Retarget human motion capture onto nonhuman characters (ACE)")]
struct Cli {
    /// Threads libtorch may use [default: libtorch's choice, one per core]. On a machine shared with
    /// other heavy jobs, 1 is often much faster.
    #[arg(long, global = true, value_parser = clap::value_parser!(i32).range(1..=ace::limits::MAX_THREADS))]
    threads: Option<i32>,
    #[command(subcommand)]
    command: Command,
}

/// Options of `train-prior` and `train`.
#[derive(clap::Args)]
struct TrainOpts {
    /// A bundled character (spot, crab, stretch, hound), a URDF file or a rigged glTF creature (.glb, .gltf).
    #[arg(long)]
    character: String,
    /// Checkpoint directory [default: out/checkpoints/<character>].
    #[arg(long)]
    checkpoint: Option<PathBuf>,
    /// A dataset file from `ace dataset` [default: generate it (train-prior) or regenerate the
    /// prior's (train)].
    #[arg(long)]
    dataset: Option<PathBuf>,
    /// A TOML file with any subset of the training configuration.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Use the paper's network sizes and step counts (§6.4) instead of the CPU defaults.
    #[arg(long)]
    paper: bool,
}

#[derive(Subcommand)]
enum Command {
    /// Summarise a BVH clip, a URDF character or a rigged glTF creature.
    Inspect {
        /// A `.bvh`, `.urdf`, `.glb` or `.gltf` file.
        file: PathBuf,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
        /// A joint-mapping file (TOML) for a BVH skeleton the automatic matching cannot read
        /// [default: `<clip>.mapping.toml` beside the clip, when there is one].
        #[arg(long)]
        mapping: Option<PathBuf>,
    },
    /// The main job on the bundled defaults: retarget the bundled human clips onto the bundled
    /// characters with their shipped checkpoints; writes a glTF binary, the robot command trajectory
    /// and the metrics per pair, a report over all of them and a picture per character.
    Demo {
        /// Bundled characters to retarget onto.
        #[arg(long, value_delimiter = ',', default_value = "spot,crab,stretch,hound")]
        characters: Vec<String>,
        /// Human clips (BVH) [default: every clip in assets/motions].
        #[arg(long)]
        clip: Vec<PathBuf>,
        /// Output folder.
        #[arg(long, default_value = "out/demo")]
        out: PathBuf,
        /// A joint-mapping file (TOML) for every clip [default: `<clip>.mapping.toml` beside each
        /// clip, when there is one].
        #[arg(long)]
        mapping: Option<PathBuf>,
        /// What runs the networks: pure Rust, or libtorch for comparison.
        #[arg(long, value_enum, default_value_t = retarget::Backend::Rust)]
        backend: retarget::Backend,
    },
    /// Generate a character motion dataset by rolling out its kinematic controllers under random
    /// commands (the data the motion prior learns from).
    Dataset {
        /// A bundled character (spot, crab, stretch, hound), a URDF file or a rigged glTF creature (.glb, .gltf).
        #[arg(long)]
        character: String,
        /// Frames to generate [default: 200000, or the config's].
        #[arg(long, value_parser = ace::limits::frames)]
        frames: Option<usize>,
        /// Seed of the random commands [default: 0, or the config's].
        #[arg(long)]
        seed: Option<u64>,
        /// A TOML file with generator settings (any subset of the dataset configuration).
        #[arg(long)]
        config: Option<PathBuf>,
        /// Output file (safetensors).
        #[arg(long)]
        out: PathBuf,
        /// Also write pictures (gait diagram, commanded vs achieved velocity, foot heights) and the
        /// metrics into this folder.
        #[arg(long)]
        report: Option<PathBuf>,
        /// Add a rigged glTF creature's own animation clips (2 % of the frames, unless the config's
        /// `[own_clips] share` says), carried across the ground by their planted feet.
        #[arg(long)]
        include_clips: bool,
    },
    /// Train a character's motion prior (VAE encoder and mode-adaptive decoder) on its dataset.
    TrainPrior {
        #[command(flatten)]
        opts: TrainOpts,
        /// Frames of the generated dataset [default: 200000].
        #[arg(long, value_parser = ace::limits::frames)]
        frames: Option<usize>,
        /// Seed of the generated dataset [default: 0].
        #[arg(long)]
        seed: Option<u64>,
        /// A TOML file with generator settings for the generated dataset (any subset of the dataset
        /// configuration, as `ace dataset --config`).
        #[arg(long, conflicts_with = "dataset")]
        dataset_config: Option<PathBuf>,
    },
    /// Train ACE's generator and discriminator for a character whose prior is trained.
    Train {
        #[command(flatten)]
        opts: TrainOpts,
        /// Folder of human BVH clips [default: ../shared/data/human].
        #[arg(long)]
        humans: Option<PathBuf>,
    },
    /// Retarget a human clip onto a character: writes a glTF binary, the robot command trajectory
    /// (JSON, CSV) and the clip's metrics. Given a folder, retargets every BVH clip below it in
    /// parallel into the folder --out, with a summary.json.
    Retarget {
        /// The human clip (BVH), or a folder of clips (every .bvh below it, recursively).
        clip: PathBuf,
        /// A bundled character (spot, crab, stretch, hound), a URDF file or a rigged glTF creature (.glb, .gltf).
        #[arg(long)]
        character: String,
        /// Checkpoint directory [default: the bundled character's shipped one].
        #[arg(long)]
        checkpoint: Option<PathBuf>,
        /// Output glTF binary (.glb); the trajectory and metrics are written beside it. For a rigged glTF
        /// creature it is the creature's own model with the clip as a new animation on its skeleton.
        /// For a folder of clips, the output folder: each clip at its relative path, as a .glb.
        #[arg(long)]
        out: PathBuf,
        /// For a folder of clips: how many clips run at once, 1 to 256 [default: one per core].
        #[arg(long, value_parser = ace::limits::jobs)]
        jobs: Option<usize>,
        /// Leave the human skeleton out of the glTF (a glTF creature's model never has it).
        #[arg(long)]
        no_human: bool,
        /// glTF creatures: keep the model's own animations beside the retargeted clip.
        #[arg(long)]
        keep_animations: bool,
        /// glTF creatures: write only the skeleton, its skin and the clip (no meshes, materials or images).
        #[arg(long, conflicts_with = "keep_animations")]
        animation_only: bool,
        /// Write the networks' raw output: no cleanup at all (no heading steering, standing or
        /// end-effector hold, foot locking or collision guard).
        #[arg(long)]
        no_cleanup: bool,
        /// Leave these cleanup steps out (comma-separated or repeated); the others run.
        #[arg(long, value_enum, value_delimiter = ',', conflicts_with = "no_cleanup")]
        without: Vec<retarget::CleanupStep>,
        /// Also hold every joint to its velocity limit (URDF `<limit velocity>`; wheels excepted), so
        /// that a robot can execute the trajectory as written; joints held back catch up after.
        #[arg(long, conflicts_with = "no_cleanup")]
        limit_velocity: bool,
        /// A joint-mapping file (TOML) for a BVH skeleton the automatic matching cannot read
        /// [default: `<clip>.mapping.toml` beside the clip, when there is one].
        #[arg(long)]
        mapping: Option<PathBuf>,
        /// What runs the networks: pure Rust, or libtorch for comparison.
        #[arg(long, value_enum, default_value_t = retarget::Backend::Rust)]
        backend: retarget::Backend,
    },
    /// Evaluate a checkpoint on the human clips it never saw: DIV, FID, L_fea and UFR of the dataset,
    /// ACE and the prior driven by random latents (with --baselines also NKN and ACE without either
    /// loss, the paper's Table 1), plus long-rollout stability. Writes Markdown, CSV, JSON and a chart.
    Eval {
        /// A bundled character (spot, crab, stretch, hound), a URDF file or a rigged glTF creature (.glb, .gltf).
        #[arg(long)]
        character: String,
        /// Checkpoint directory [default: the bundled character's shipped one].
        #[arg(long)]
        checkpoint: Option<PathBuf>,
        /// Folder of human BVH clips the checkpoint was trained on [default: ../shared/data/human].
        #[arg(long)]
        humans: Option<PathBuf>,
        /// Output folder [default: out/eval/<character>].
        #[arg(long)]
        out: Option<PathBuf>,
        /// Seed of the random latents and of the fresh dataset.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Length of the stability rollouts in seconds.
        #[arg(long, default_value_t = 60.0, value_parser = ace::limits::seconds)]
        seconds: f32,
        /// Evaluate at most this many held-out clips [default: all].
        #[arg(long, value_parser = ace::limits::at_least_one)]
        max_clips: Option<usize>,
        /// Also score the paper's baselines (NKN, ACE without the feature loss, ACE without the
        /// adversarial loss), training those missing with the checkpoint's data and budget first.
        #[arg(long)]
        baselines: bool,
        /// Folder of the baselines' runs [default: out/baselines/<character>, or
        /// out/baselines-quick/<character> with --quick].
        #[arg(long, requires = "baselines")]
        runs: Option<PathBuf>,
        /// CI setting: baselines of 20 steps, at most 2 held-out clips, rollouts of at most 4 s.
        #[arg(long)]
        quick: bool,
        /// Score every system that is cleaned up (ACE, the prior with random latents, the baselines)
        /// with the velocity limit in its cleanup, as `ace retarget --limit-velocity` writes them: what
        /// a robot executing the trajectories would do.
        #[arg(long)]
        limit_velocity: bool,
    },
    /// Print the motion-quality metrics (UFR and its detectors, DIV, FID) of a motion file.
    Metrics {
        /// A motion file written by `ace dataset`.
        file: PathBuf,
        /// The character it belongs to [default: the bundled character of the file's name].
        #[arg(long)]
        character: Option<String>,
        /// A dataset of the same character to compute FID against.
        #[arg(long)]
        reference: Option<PathBuf>,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    ace::output::install_signal_cleanup();
    if let Some(n) = cli.threads {
        ace::models::learn::set_threads(n);
    }
    let result = match cli.command {
        Command::Inspect { file, json, mapping } => inspect::run(&file, json, mapping.as_deref()),
        Command::Demo { characters, clip, out, mapping, backend } => {
            demo::run(&characters, &clip, &out, mapping.as_deref(), backend)
        }
        Command::Dataset { character, frames, seed, config, out, report, include_clips } => dataset::run(&dataset::DatasetArgs {
            character,
            frames,
            seed,
            config,
            out,
            report,
            include_clips,
        }),
        Command::TrainPrior { opts, frames, seed, dataset_config } => {
            train::prior(&train::TrainArgs { dataset_config, ..train_args(opts, frames, seed, None) })
        }
        Command::Train { opts, humans } => train::ace(&train_args(opts, None, None, humans)),
        Command::Retarget {
            clip,
            character,
            checkpoint,
            out,
            jobs,
            no_human,
            keep_animations,
            animation_only,
            no_cleanup,
            without,
            limit_velocity,
            mapping,
            backend,
        } => {
            let one = retarget::RetargetArgs {
                clip,
                character,
                checkpoint,
                out,
                with_human: !no_human,
                rig: ace::models::export::RigClipOptions { name: None, keep_animations, animation_only },
                cleanup: ace::models::cleanup::Cleanup { velocity_limit: limit_velocity, ..retarget::cleanup_without(no_cleanup, &without) },
                mapping,
                backend,
            };
            if one.clip.is_dir() {
                batch::run(&batch::BatchArgs { one, jobs })
            } else if jobs.is_some() {
                Err(anyhow::anyhow!("--jobs is for a folder of clips; {} is one clip", one.clip.display()))
            } else {
                retarget::run(&one)
            }
        }
        Command::Eval { character, checkpoint, humans, out, seed, seconds, max_clips, baselines, runs, quick, limit_velocity } => eval::run(&eval::EvalArgs {
            character,
            checkpoint,
            humans,
            out,
            seed,
            seconds,
            max_clips,
            baselines,
            runs,
            quick,
            limit_velocity,
        }),
        Command::Metrics { file, character, reference, json } => {
            metrics::run(&file, character.as_deref(), reference.as_deref(), json)
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn train_args(o: TrainOpts, frames: Option<usize>, seed: Option<u64>, humans: Option<PathBuf>) -> train::TrainArgs {
    train::TrainArgs {
        character: o.character,
        out: o.checkpoint,
        dataset: o.dataset,
        frames,
        seed,
        config: o.config,
        paper: o.paper,
        humans,
        dataset_config: None,
    }
}
