//! glTF import.
use super::Scene;
use std::path::Path;

#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("{0}")]
    Other(String),
}

#[derive(Clone, Debug, Default)]
pub struct ImportOptions {
    /// `None` = auto (the axis of least extent).
    pub up: Option<super::UpAxis>,
}

pub fn import(_path: &Path, _opts: &ImportOptions) -> Result<Scene, SceneError> {
    Err(SceneError::Other("not implemented".into()))
}
