//! Embeds the git commit the library is built from (`HAIRRECON_GIT_COMMIT`, `unknown` outside a git
//! checkout), so that every run's `config.json` and `report.json` say which code made them.

use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    out.status.success().then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

fn main() {
    let commit = git(&["rev-parse", "--short=12", "HEAD"]).unwrap_or_else(|| "unknown".into());
    println!("cargo:rustc-env=HAIRRECON_GIT_COMMIT={commit}");
    if let Some(dir) = git(&["rev-parse", "--git-dir"]) {
        let dir = std::path::Path::new(&dir);
        for f in ["HEAD", "refs/heads", "packed-refs"] {
            if dir.join(f).exists() {
                println!("cargo:rerun-if-changed={}", dir.join(f).display());
            }
        }
    }
    if let Some(common) = git(&["rev-parse", "--git-common-dir"]) {
        let refs = std::path::Path::new(&common).join("refs/heads");
        if refs.exists() {
            println!("cargo:rerun-if-changed={}", refs.display());
        }
    }
    println!("cargo:rerun-if-changed=build.rs");
}
