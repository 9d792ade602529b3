//! `hairrecon toy-aa` and `toy-letters` (not built yet).

use crate::CmdResult;

#[derive(Debug, clap::Args)]
pub struct ToyAaArgs {}

#[derive(Debug, clap::Args)]
pub struct ToyLettersArgs {}

pub fn run_aa(_args: ToyAaArgs) -> CmdResult {
    Err("this subcommand is not built yet".into())
}

pub fn run_letters(_args: ToyLettersArgs) -> CmdResult {
    Err("this subcommand is not built yet".into())
}
