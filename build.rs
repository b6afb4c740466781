//! Records the git commit the binary is built from, for the provenance of
//! every run folder (`case.resolved.json`): `NCFORM_GIT_COMMIT` is the
//! commit's hash, or "unknown" when the source is not a git checkout of
//! its own (a source archive, even unpacked inside another repository) or
//! git is missing. The build never fails for it.

use std::path::PathBuf;
use std::process::Command;

/// The output of `git <args>` in the package folder, trimmed, if git ran
/// and succeeded.
fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    if !out.status.success() {
        return None;
    }
    let text = String::from_utf8(out.stdout).ok()?;
    let text = text.trim();
    (!text.is_empty()).then(|| text.to_string())
}

/// Whether the package folder is the top of a git work tree (not a source
/// archive unpacked inside another repository).
fn in_own_checkout() -> bool {
    let Some(top) = git(&["rev-parse", "--show-toplevel"]) else {
        return false;
    };
    let here = std::env::var("CARGO_MANIFEST_DIR").unwrap_or_default();
    match (std::fs::canonicalize(top), std::fs::canonicalize(here)) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}

fn main() {
    let commit = if in_own_checkout() {
        git(&["rev-parse", "HEAD"])
    } else {
        None
    }
    .unwrap_or_else(|| "unknown".to_string());
    println!("cargo:rustc-env=NCFORM_GIT_COMMIT={commit}");
    // Rebuilt when HEAD moves (a commit, a checkout); without a git folder
    // only when this script changes.
    println!("cargo:rerun-if-changed=build.rs");
    if let Some(git_dir) = git(&["rev-parse", "--git-dir"]) {
        let git_dir = PathBuf::from(git_dir);
        let head = git_dir.join("HEAD");
        if head.exists() {
            println!("cargo:rerun-if-changed={}", head.display());
        }
        if let Some(reference) = git(&["symbolic-ref", "-q", "HEAD"]) {
            let common = git(&["rev-parse", "--git-common-dir"]).map_or(git_dir, PathBuf::from);
            let path = common.join(reference);
            if path.exists() {
                println!("cargo:rerun-if-changed={}", path.display());
            }
            let packed = common.join("packed-refs");
            if packed.exists() {
                println!("cargo:rerun-if-changed={}", packed.display());
            }
        }
    }
}
