//! Placement profiles — the pipeline as data (`deploy/profiles/*.json`): which services run,
//! from which program, with which flags. `echoctl up` starts a profile on a host; `echoctl
//! demo` starts the `demo` profile with the scenario's values filled in.
//!
//! Placeholders: `{key}` inside an argument is replaced by the key's values joined with `,`; an
//! argument that is exactly `{key}` becomes the values as separate arguments, and when there are
//! none it is left out together with a `--flag` right before it. An unknown key is an error.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;

/// One service of a profile (an unknown field, such as a misspelt `"arg"`, is an error).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ServiceSpec {
    /// Name (liveliness, log prefix, default TLS identity).
    pub name: String,
    /// Binary next to echoctl (a service, or echoctl itself with a verb first in `args`).
    pub program: String,
    /// Arguments, with placeholders.
    #[serde(default)]
    pub args: Vec<String>,
    /// TLS identity (certificate common name) when it is not the name.
    #[serde(default)]
    pub identity: Option<String>,
}

/// A placement profile.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Profile {
    /// What it is for.
    pub description: String,
    /// What runs, in start order.
    pub services: Vec<ServiceSpec>,
}

/// A profile that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ProfileError {
    /// Not readable.
    #[error("reading profile {path}: {source}")]
    Read {
        /// File.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// Not a profile.
    #[error("parsing {path}: {source}")]
    Parse {
        /// File.
        path: PathBuf,
        /// Cause.
        source: serde_json::Error,
    },
    /// Nothing to run.
    #[error("{0}: no services")]
    Empty(PathBuf),
    /// A placeholder without a value.
    #[error("service {service}: no value for placeholder {{{key}}}")]
    Unknown {
        /// Service.
        service: String,
        /// Placeholder.
        key: String,
    },
}

impl Profile {
    /// Load `name`: a file path, or a name under `<deploy>/profiles/`.
    pub fn load(name: &str, deploy: &Path) -> Result<Profile, ProfileError> {
        let path = if name.ends_with(".json") || name.contains('/') {
            PathBuf::from(name)
        } else {
            deploy.join("profiles").join(format!("{name}.json"))
        };
        let text = std::fs::read(&path).map_err(|source| ProfileError::Read {
            path: path.clone(),
            source,
        })?;
        let profile: Profile =
            serde_json::from_slice(&text).map_err(|source| ProfileError::Parse {
                path: path.clone(),
                source,
            })?;
        if profile.services.is_empty() {
            return Err(ProfileError::Empty(path));
        }
        Ok(profile)
    }

    /// The service named `name`.
    pub fn service(&self, name: &str) -> Option<&ServiceSpec> {
        self.services.iter().find(|s| s.name == name)
    }
}

/// Placeholder values.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Vars(BTreeMap<String, Vec<String>>);

impl Vars {
    /// No values.
    pub fn new() -> Vars {
        Vars::default()
    }

    /// `{key}` is `value`.
    pub fn set(mut self, key: &str, value: impl Into<String>) -> Vars {
        self.0.insert(key.to_string(), vec![value.into()]);
        self
    }

    /// `{key}` is these values (none: the argument, and its flag, are left out).
    pub fn set_all(mut self, key: &str, values: Vec<String>) -> Vars {
        self.0.insert(key.to_string(), values);
        self
    }
}

/// The arguments of `spec` with the placeholders filled.
pub fn expand(spec: &ServiceSpec, vars: &Vars) -> Result<Vec<String>, ProfileError> {
    let unknown = |key: &str| ProfileError::Unknown {
        service: spec.name.clone(),
        key: key.to_string(),
    };
    let mut out: Vec<String> = vec![];
    for a in &spec.args {
        if let Some(key) = a.strip_prefix('{').and_then(|k| k.strip_suffix('}')) {
            if !key.contains(['{', '}']) {
                let values = vars.0.get(key).ok_or_else(|| unknown(key))?;
                if values.iter().all(String::is_empty) {
                    // Nothing to pass: a flag right before goes too.
                    if out.last().is_some_and(|f| f.starts_with("--")) {
                        out.pop();
                    }
                } else {
                    out.extend(values.iter().cloned());
                }
                continue;
            }
        }
        let mut v = a.clone();
        while let Some(start) = v.find('{') {
            let Some(len) = v[start..].find('}') else {
                break;
            };
            let key = &v[start + 1..start + len];
            let value = vars.0.get(key).ok_or_else(|| unknown(key))?.join(",");
            v.replace_range(start..=start + len, &value);
        }
        out.push(v);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(args: &[&str]) -> ServiceSpec {
        ServiceSpec {
            name: "s".into(),
            program: "p".into(),
            args: args.iter().map(|a| a.to_string()).collect(),
            identity: None,
        }
    }

    #[test]
    fn placeholders_fill_split_and_drop() {
        let vars = Vars::new()
            .set("models", "/opt/echo/models")
            .set("serve", "r2,r3")
            .set_all("pair", vec!["x".into(), "y".into()])
            .set_all(
                "scenario",
                vec!["--capture".into(), "a.bvh".into(), "b.bvh".into()],
            )
            .set_all("t0", vec![]);
        let out = expand(
            &spec(&[
                "--model",
                "{models}/hri",
                "--robots",
                "{serve}",
                "--both={pair}",
                "{scenario}",
                "--t0-ns",
                "{t0}",
            ]),
            &vars,
        )
        .unwrap();
        assert_eq!(
            out,
            [
                "--model",
                "/opt/echo/models/hri",
                "--robots",
                "r2,r3",
                "--both=x,y",
                "--capture",
                "a.bvh",
                "b.bvh"
            ]
        );
        let e = expand(&spec(&["--x", "{nope}"]), &vars).unwrap_err();
        assert!(e.to_string().contains("{nope}"), "{e}");
    }

    #[test]
    fn every_shipped_profile_loads_and_a_misspelt_field_is_an_error() {
        let deploy = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../deploy");
        let names: Vec<String> = std::fs::read_dir(deploy.join("profiles"))
            .unwrap()
            .flatten()
            .filter_map(|e| {
                e.file_name()
                    .to_str()
                    .and_then(|n| n.strip_suffix(".json"))
                    .map(str::to_string)
            })
            .collect();
        assert!(
            names.iter().any(|n| n == "demo") && names.len() >= 5,
            "{names:?}"
        );
        for n in &names {
            Profile::load(n, &deploy).unwrap_or_else(|e| panic!("{n}: {e}"));
        }
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("typo.json");
        std::fs::write(
            &p,
            r#"{"description": "x", "services": [{"name": "a", "program": "b", "arg": []}]}"#,
        )
        .unwrap();
        let e = Profile::load(p.to_str().unwrap(), dir.path()).unwrap_err();
        assert!(e.to_string().contains("unknown field `arg`"), "{e}");
    }
}
