//! `hairrecon eval`, `convert` and `info`.

use crate::CmdResult;

#[derive(Debug, clap::Args)]
pub struct EvalArgs {}
#[derive(Debug, clap::Args)]
pub struct ConvertArgs {}
#[derive(Debug, clap::Args)]
pub struct InfoArgs {}

pub fn eval(_a: EvalArgs) -> CmdResult {
    Err("not built yet".into())
}
pub fn convert(_a: ConvertArgs) -> CmdResult {
    Err("not built yet".into())
}
pub fn info(_a: InfoArgs) -> CmdResult {
    Err("not built yet".into())
}
