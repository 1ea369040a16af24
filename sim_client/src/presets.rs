//! Planner configurations shipped with the project.

use std::path::Path;

use decision::PlannerConfig;

use crate::error::{Result, SimClientError};

/// `deploy/paper.toml`: the paper's formulation as literally as it can be run.
pub const PAPER_LITERAL_TOML: &str = include_str!("../../deploy/paper.toml");

/// Parses a planner TOML; `origin` names it in the error.
pub fn parse_planner_config(text: &str, origin: &str) -> Result<PlannerConfig> {
    PlannerConfig::from_toml_str(text).map_err(|e| SimClientError::Config(format!("planner config {origin}: {e}")))
}

/// The paper-literal preset: `file` when given, else the embedded `deploy/paper.toml`.
pub fn paper_literal(file: Option<&Path>) -> Result<PlannerConfig> {
    match file {
        None => parse_planner_config(PAPER_LITERAL_TOML, "deploy/paper.toml (embedded)"),
        Some(p) => {
            let text = std::fs::read_to_string(p).map_err(|e| SimClientError::io(p, e))?;
            parse_planner_config(&text, &p.display().to_string())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_paper_preset_parses_and_differs_from_the_defaults() {
        let paper = paper_literal(None).unwrap();
        assert_ne!(paper, PlannerConfig::default());
        assert!(paper_literal(Some(Path::new("/nonexistent/paper.toml"))).is_err());
        assert!(parse_planner_config("[cost]\nno_such_field = 1\n", "test").is_err());
    }
}
