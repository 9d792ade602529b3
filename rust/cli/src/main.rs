//! `hairrecon`: the command-line front of the hairrecon library.
//!
//! Each subcommand lives in its own module (`cmd_*.rs`) with a clap `Args` struct and a `run`
//! function. Errors end the program with one clear line on stderr and a non-zero exit code.

use clap::{Parser, Subcommand};

mod cmd_fit_head;
mod cmd_fuse;
mod cmd_import;
mod cmd_io;
mod cmd_masks;
mod cmd_reconstruct;
mod cmd_synth;
mod cmd_toy;
mod interrupt;
mod progress;

/// The error type of every subcommand: printed as one line.
pub type CmdResult = Result<(), Box<dyn std::error::Error + Send + Sync>>;

#[derive(Debug, Parser)]
#[command(name = "hairrecon", version, about = "Multi-view hair strand reconstruction (Dr.Hair method) on the CPU")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Compare predicted strands with ground truth: precision, recall and F1 per threshold.
    Eval(cmd_io::EvalArgs),
    /// Convert strands between .hair, .data, .ply and .obj (chosen by extension).
    Convert(cmd_io::ConvertArgs),
    /// Print strand and point counts, length statistics and the bounding box of a strand file.
    Info(cmd_io::InfoArgs),
    /// Generate a synthetic hairstyle on the bundled head.
    SynthHair(cmd_synth::SynthHairArgs),
    /// Fuse a capture's depth maps into a raw mesh (TSDF + surface extraction).
    FuseDepth(cmd_fuse::FuseDepthArgs),
    /// The anti-aliasing toy of the supplement (3.1): grow one segment by differentiable rendering.
    ToyAa(cmd_toy::ToyAaArgs),
    /// The letters demo of the supplement (3.2): grow letters from bundles of strands.
    ToyLetters(cmd_toy::ToyLettersArgs),
    /// Fit the head template to a capture's raw mesh: the similarity to the canonical frame, as JSON.
    FitHead(cmd_fit_head::FitHeadArgs),
    /// Hair masks of every view without ground truth: the raw mesh's hair region, matted.
    Masks(cmd_masks::MasksArgs),
    /// Reconstruct hair strands from a capture folder.
    Reconstruct(cmd_reconstruct::ReconstructArgs),
    /// Make a capture folder from a photogrammetry tool's calibration, photos and raw mesh.
    #[command(subcommand)]
    Import(cmd_import::ImportCommand),
}

fn main() {
    let cli = Cli::parse();
    interrupt::install();
    let result = match cli.command {
        Command::Eval(a) => cmd_io::eval(a),
        Command::Convert(a) => cmd_io::convert(a),
        Command::Info(a) => cmd_io::info(a),
        Command::SynthHair(a) => cmd_synth::run(a),
        Command::FuseDepth(a) => cmd_fuse::run(a),
        Command::ToyAa(a) => cmd_toy::run_aa(a),
        Command::ToyLetters(a) => cmd_toy::run_letters(a),
        Command::FitHead(a) => cmd_fit_head::run(a),
        Command::Masks(a) => cmd_masks::run(a),
        Command::Reconstruct(a) => cmd_reconstruct::run(a),
        Command::Import(c) => cmd_import::run(c),
    };
    if let Err(e) = result {
        eprintln!("hairrecon: error: {e}");
        std::process::exit(1);
    }
}
