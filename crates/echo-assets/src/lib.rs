//! Where Echo's files are found at run time, the same way for every binary and whatever the
//! working directory: model checkpoints (`models/…`) and the assets `scripts/setup` fetches
//! (`.cache/<name>`). Candidates, in order:
//!
//! 1. the environment: `$ECHO_MODELS` (models) or `$ECHO_CACHE/<name>` (assets);
//! 2. the installation: `<exe dir>/../share/echo/{models,<name>}`, and the checkout a
//!    `target/<profile>/` executable was built in (`<exe dir>/../../{models,.cache/<name>}`);
//! 3. the current directory and each of its parents;
//! 4. the checkout this crate was compiled in.
//!
//! A model given as an existing path is used as it is; a relative one that does not exist is
//! looked up under each candidate models directory (`models/hri` → `<dir>/hri`).

use std::path::{Component, Path, PathBuf};

/// A model checkpoint that is nowhere.
#[derive(Debug, thiserror::Error)]
#[error("model {stem} not found (looked in {searched}); set ECHO_MODELS to the models directory")]
pub struct NotFound {
    /// The name asked for.
    pub stem: String,
    /// Where it was looked for.
    pub searched: String,
}

/// The repository this crate was compiled in.
fn build_checkout() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Candidate roots after the environment: installation, `target/<profile>` checkout, working
/// directory and its parents, the build checkout. Each is paired with whether it is an
/// installation prefix (`share/echo`), whose layout has no `.cache`.
fn roots() -> Vec<(PathBuf, bool)> {
    let mut v = vec![];
    if let Some(exe_dir) = std::env::current_exe()
        .ok()
        .and_then(|e| e.parent().map(Path::to_path_buf))
    {
        v.push((exe_dir.join("../share/echo"), true));
        v.push((exe_dir.join("../.."), false));
    }
    if let Ok(cwd) = std::env::current_dir() {
        v.extend(cwd.ancestors().map(|d| (d.to_path_buf(), false)));
    }
    v.push((build_checkout(), false));
    v
}

/// Candidate directories of a fetched asset `name` (e.g. `onnxruntime`, `web`).
pub fn cache_dirs(name: &str) -> Vec<PathBuf> {
    let mut v = vec![];
    if let Ok(p) = std::env::var("ECHO_CACHE") {
        v.push(Path::new(&p).join(name));
    }
    for (root, installed) in roots() {
        v.push(match installed {
            true => root.join(name),
            false => root.join(".cache").join(name),
        });
    }
    v
}

/// Candidate models directories.
pub fn model_dirs() -> Vec<PathBuf> {
    let mut v = vec![];
    if let Ok(p) = std::env::var("ECHO_MODELS") {
        v.push(PathBuf::from(p));
    }
    v.extend(roots().into_iter().map(|(root, _)| root.join("models")));
    v
}

/// The deployment directory (profiles, Zenoh configs): `given` when it exists, else the first
/// `deploy` found by the same search as the models (`share/echo/deploy` when installed); `given`
/// itself when there is none (the caller's error names it).
pub fn deploy_dir(given: &Path) -> PathBuf {
    if given.is_dir() || given.is_absolute() {
        return given.to_path_buf();
    }
    roots()
        .into_iter()
        .map(|(root, _)| root.join("deploy"))
        .find(|d| d.join("profiles").is_dir())
        .unwrap_or_else(|| given.to_path_buf())
}

/// Whether a checkpoint stem exists (`<stem>.json`, `<stem>.safetensors`, or the path itself).
fn exists(stem: &Path) -> bool {
    stem.exists()
        || stem.with_extension("json").is_file()
        || stem.with_extension("safetensors").is_file()
}

/// The checkpoint `stem` names: itself when it exists or is absolute, else the first candidate
/// models directory that holds it (a leading `models/` is dropped first).
pub fn resolve_model(stem: &Path) -> Result<PathBuf, NotFound> {
    if exists(stem) || stem.is_absolute() {
        return Ok(stem.to_path_buf());
    }
    let mut parts = stem.components().peekable();
    while matches!(parts.peek(), Some(Component::CurDir)) {
        parts.next();
    }
    if matches!(parts.peek(), Some(Component::Normal(c)) if *c == "models") {
        parts.next();
    }
    let name: PathBuf = parts.collect();
    let dirs = model_dirs();
    dirs.iter()
        .map(|d| d.join(&name))
        .find(|p| exists(p))
        .ok_or_else(|| NotFound {
            stem: stem.display().to_string(),
            searched: dirs
                .iter()
                .map(|d| d.display().to_string())
                .collect::<Vec<_>>()
                .join(", "),
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_relative_model_resolves_from_anywhere_and_echo_models_comes_first() {
        // The shipped checkpoints are found from outside the repository.
        let elsewhere = tempfile::tempdir().unwrap();
        std::env::set_current_dir(elsewhere.path()).unwrap();
        let p = resolve_model(Path::new("models/forecaster")).unwrap();
        assert!(p.with_extension("json").is_file(), "{}", p.display());
        let p = resolve_model(Path::new("hri")).unwrap();
        assert!(p.with_extension("safetensors").is_file(), "{}", p.display());

        // ECHO_MODELS wins over the checkout.
        let mine = tempfile::tempdir().unwrap();
        std::fs::write(mine.path().join("forecaster.json"), "{}").unwrap();
        std::env::set_var("ECHO_MODELS", mine.path());
        let p = resolve_model(Path::new("models/forecaster")).unwrap();
        assert_eq!(p, mine.path().join("forecaster"));

        // A path that exists is taken as it is; a missing one is an error naming the search.
        let local = elsewhere.path().join("models");
        std::fs::create_dir_all(&local).unwrap();
        std::fs::write(local.join("forecaster.safetensors"), "").unwrap();
        assert_eq!(
            resolve_model(Path::new("models/forecaster")).unwrap(),
            Path::new("models/forecaster")
        );
        let e = resolve_model(Path::new("models/nonexistent")).unwrap_err();
        assert!(e.to_string().contains("ECHO_MODELS"), "{e}");
        assert!(e.searched.contains(&mine.path().display().to_string()));
        std::env::remove_var("ECHO_MODELS");
    }

    #[test]
    fn the_deployment_directory_is_found_from_anywhere() {
        let d = deploy_dir(Path::new("no/such/deploy"));
        assert!(d.join("profiles/demo.json").is_file(), "{}", d.display());
    }

    #[test]
    fn cache_dirs_start_with_echo_cache_and_end_at_the_checkout() {
        let d = cache_dirs("web");
        assert!(d.last().unwrap().ends_with(".cache/web"));
        assert!(d.iter().any(|p| p.ends_with("share/echo/web")));
    }
}
