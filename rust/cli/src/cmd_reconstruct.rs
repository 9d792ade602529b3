//! `hairrecon` subcommand (not built yet).

use crate::CmdResult;

#[derive(Debug, clap::Args)]
pub struct ReconstructArgs {}

pub fn run(_args: ReconstructArgs) -> CmdResult {
    Err("this subcommand is not built yet".into())
}
