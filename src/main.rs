//! `ace`: the command-line front of ACE retargeting.

mod demo;
mod inspect;
mod picture;

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
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Inspect { file, json } => inspect::run(&file, json),
        Command::Demo { character, clip, out } => demo::run(&character, &clip, &out),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
