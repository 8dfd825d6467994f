//! `ace`: the command-line front of ACE retargeting.

mod characters;
mod dataset;
mod demo;
mod inspect;
mod metrics;
mod picture;
mod plot;
mod progress;
mod report;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "ace", version, about = "Retarget human motion capture onto nonhuman characters (ACE)")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Summarise a BVH clip or a URDF character.
    Inspect {
        /// A `.bvh` or `.urdf` file.
        file: PathBuf,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// The main job on the bundled defaults: load a character and a human clip, print their
    /// summaries and write a picture of the scene.
    Demo {
        /// Character URDF.
        #[arg(long, default_value = "assets/characters/spot.urdf")]
        character: PathBuf,
        /// Human clip (BVH).
        #[arg(long, default_value = "assets/motions/walk.bvh")]
        clip: PathBuf,
        /// Output folder.
        #[arg(long, default_value = "out")]
        out: PathBuf,
    },
    /// Generate a character motion dataset by rolling out its kinematic controllers under random
    /// commands (the data the motion prior learns from).
    Dataset {
        /// A bundled character (spot, crab, stretch) or a URDF file.
        #[arg(long)]
        character: String,
        /// Frames to generate [default: 200000, or the config's].
        #[arg(long)]
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
    let result = match cli.command {
        Command::Inspect { file, json } => inspect::run(&file, json),
        Command::Demo { character, clip, out } => demo::run(&character, &clip, &out),
        Command::Dataset { character, frames, seed, config, out, report } => dataset::run(&dataset::DatasetArgs {
            character,
            frames,
            seed,
            config,
            out,
            report,
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
