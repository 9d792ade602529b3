//! `hairrecon import colmap|metashape|nerf`: a photogrammetry tool's calibration, its photos and
//! the raw mesh, written as a capture folder (`hairrecon_import`).
//!
//! The capture keeps the tool's frame and units (`"frame": "imported"`); the photos become
//! undistorted pinhole working copies `--height` pixels high.

use std::path::PathBuf;

use hairrecon_import::photo::Prefer;
use hairrecon_import::{import_capture, Source, WriteOptions};

use crate::CmdResult;

#[derive(Debug, clap::Subcommand)]
pub enum ImportCommand {
    /// A COLMAP sparse model folder (cameras, images, points3D as .txt or .bin).
    Colmap {
        /// The sparse model folder, e.g. `sparse/0`.
        sparse: PathBuf,
        #[command(flatten)]
        common: CommonArgs,
    },
    /// An Agisoft Metashape camera export (File > Export > Export Cameras, Agisoft XML).
    Metashape {
        /// The cameras .xml file.
        xml: PathBuf,
        #[command(flatten)]
        common: CommonArgs,
    },
    /// An instant-ngp or nerfstudio `transforms.json`.
    Nerf {
        /// The transforms.json file.
        transforms: PathBuf,
        #[command(flatten)]
        common: CommonArgs,
    },
}

#[derive(Debug, clap::Args)]
pub struct CommonArgs {
    /// The folder the calibration's photo names are relative to (default: the calibration's
    /// folder for Metashape and transforms.json; required for COLMAP).
    #[arg(long)]
    pub images: Option<PathBuf>,
    /// The raw mesh of the head and hair from the same tool (PLY or OBJ).
    #[arg(long)]
    pub mesh: PathBuf,
    /// The capture folder to write (must not exist or be empty).
    #[arg(long)]
    pub out: PathBuf,
    /// Height of the working photos in pixels.
    #[arg(long, default_value_t = 512)]
    pub height: u32,
    /// When a photo's stored pixels and its EXIF-rotated pixels both have the calibration's size,
    /// take the rotated ones (default: the stored pixels, as COLMAP reads them).
    #[arg(long)]
    pub exif_orientation: bool,
}

pub fn run(cmd: ImportCommand) -> CmdResult {
    let (source, common) = match cmd {
        ImportCommand::Colmap { sparse, common } => (Source::Colmap(sparse), common),
        ImportCommand::Metashape { xml, common } => (Source::Metashape(xml), common),
        ImportCommand::Nerf { transforms, common } => (Source::Nerf(transforms), common),
    };
    let images = match (&common.images, &source) {
        (Some(d), _) => d.clone(),
        (None, Source::Colmap(_)) => return Err("import colmap: give the photos' folder with --images".into()),
        (None, Source::Metashape(f) | Source::Nerf(f)) => {
            f.parent().map(PathBuf::from).unwrap_or_else(|| PathBuf::from("."))
        }
    };
    let opts = WriteOptions {
        images,
        mesh: common.mesh,
        height: common.height,
        prefer: if common.exif_orientation { Prefer::Exif } else { Prefer::Stored },
    };
    let bar = crate::progress::bar(0, "import");
    let progress = |done: usize, all: usize| {
        bar.set_length(all as u64);
        bar.set_position(done as u64);
        true
    };
    let out = import_capture(&source, &opts, &common.out, &progress)?;
    bar.finish_and_clear();
    for w in &out.warnings {
        eprintln!("hairrecon: warning: {w}");
    }
    println!("{}", out.capture_json.display());
    Ok(())
}
