//! `hairrecon` subcommand (not built yet).

use crate::CmdResult;

#[derive(Debug, clap::Args)]
pub struct SynthHairArgs {}

pub fn run(_args: SynthHairArgs) -> CmdResult {
    Err("this subcommand is not built yet".into())
}
