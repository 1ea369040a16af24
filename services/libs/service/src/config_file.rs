//! The planner's configuration file: the decision core's settings and the service's own
//! `[service]` table, which the decision core does not read (docs/service.md).

use std::path::{Path, PathBuf};

use decision::PlannerConfig;
use serde::Deserialize;
use thiserror::Error;

/// Why the planner configuration could not be loaded.
#[derive(Debug, Error)]
pub enum ConfigFileError {
    #[error("reading the planner configuration {path}")]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("planner configuration {path}")]
    Parse {
        path: PathBuf,
        #[source]
        source: decision::ConfigError,
    },
    #[error("planner configuration {path}, table [service]: {message}")]
    Service { path: PathBuf, message: String },
}

/// The service's own settings: the `[service]` table of the planner's configuration file,
/// which the decision core does not read (docs/service.md).
#[derive(Debug, Clone, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ServiceSection {
    /// The Ed25519 signing key (`planner keygen`); relative to the configuration file's
    /// directory. Absent: answers are not signed.
    pub signing_key: Option<PathBuf>,
    /// How far vehicle and planner clocks may disagree before a request counts as stale.
    pub clock_skew_tolerance_ms: Option<u64>,
}

/// The planner configuration in the TOML file at `path`, or the defaults without one. A
/// `[service]` table is the service's ([`planner_files`]) and ignored here.
pub fn planner_config(path: Option<&Path>) -> Result<PlannerConfig, ConfigFileError> {
    planner_files(path).map(|(config, _)| config)
}

/// The planner configuration and the `[service]` table of the TOML file at `path`; the
/// defaults without one.
pub fn planner_files(path: Option<&Path>) -> Result<(PlannerConfig, ServiceSection), ConfigFileError> {
    let Some(path) = path else {
        return Ok((PlannerConfig::default(), ServiceSection::default()));
    };
    let text = std::fs::read_to_string(path).map_err(|source| ConfigFileError::Read {
        path: path.to_owned(),
        source,
    })?;
    let parse = |text: &str| {
        PlannerConfig::from_toml_str(text).map_err(|source| ConfigFileError::Parse {
            path: path.to_owned(),
            source,
        })
    };
    // Only a file with a [service] table is re-written without it; any other file reaches
    // the decision core as it is (its errors keep their line numbers).
    let mut table = match text.parse::<toml::Table>() {
        Ok(table) if table.contains_key("service") => table,
        _ => return Ok((parse(&text)?, ServiceSection::default())),
    };
    let service_error = |message: String| ConfigFileError::Service {
        path: path.to_owned(),
        message,
    };
    let mut service: ServiceSection = table
        .remove("service")
        .map(|v| v.try_into().map_err(|e: toml::de::Error| service_error(e.to_string())))
        .transpose()?
        .unwrap_or_default();
    if let (Some(key), Some(dir)) = (&service.signing_key, path.parent()) {
        service.signing_key = Some(dir.join(key));
    }
    let rest = toml::to_string(&table).map_err(|e| service_error(e.to_string()))?;
    Ok((parse(&rest)?, service))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(name: &str, text: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("hmdp-config-file-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("planner.toml");
        std::fs::write(&path, text).unwrap();
        path
    }

    #[test]
    fn the_service_table_is_read_apart_from_the_planner_configuration() {
        let path = write(
            "ok",
            "[service]\nsigning_key = \"planner.key\"\nclock_skew_tolerance_ms = 20\n[solver]\nbackend = \"enumeration\"\n",
        );
        let (config, service) = planner_files(Some(&path)).unwrap();
        assert_eq!(service.signing_key, Some(path.parent().unwrap().join("planner.key")));
        assert_eq!(service.clock_skew_tolerance_ms, Some(20));
        assert_ne!(config, PlannerConfig::default());
        assert_eq!(planner_config(Some(&path)).unwrap(), config);
        let path = write("typo", "[service]\nsigning_kee = \"x\"\n");
        assert!(matches!(
            planner_files(Some(&path)),
            Err(ConfigFileError::Service { .. })
        ));
        let path = write("none", "[timing]\nhorizn = 3\n");
        assert!(matches!(planner_files(Some(&path)), Err(ConfigFileError::Parse { .. })));
        assert_eq!(planner_files(None).unwrap().1, ServiceSection::default());
    }
}
