//! TOML -> [`Scene`], with validation. (placeholder: being written)
use super::{Scene, SceneError};
use std::path::Path;

impl Scene {
    /// Reads and validates a scene file.
    pub fn from_file(path: &Path) -> Result<Scene, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|e| SceneError {
            file: path.display().to_string(),
            key: String::new(),
            reason: e.to_string(),
        })?;
        Scene::from_toml_str(&text, &path.display().to_string())
    }

    /// Parses and validates scene text; `origin` names it in errors.
    pub fn from_toml_str(_text: &str, _origin: &str) -> Result<Scene, SceneError> {
        unimplemented!("scene parser")
    }
}
