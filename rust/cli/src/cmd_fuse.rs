//! `hairrecon` subcommand (not built yet).

use crate::CmdResult;

#[derive(Debug, clap::Args)]
pub struct FuseDepthArgs {}

pub fn run(_args: FuseDepthArgs) -> CmdResult {
    Err("this subcommand is not built yet".into())
}
