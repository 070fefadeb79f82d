//! Scene errors that name the file, line and field at fault.

use super::model::SourceLoc;

/// A scene that cannot be rendered, with where and why.
///
/// Displays as `FILE:LINE: FIELD: MESSAGE`, for example
/// `scenes/x.toml:14: triangle.material: material 'gold' is not defined`.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{loc}: {field}: {message}")]
pub struct SceneError {
    /// File and line.
    pub loc: SourceLoc,
    /// Dotted path of the field (`render.width`, `material.diffuse`, ...).
    pub field: String,
    /// What is wrong, naming the bad value.
    pub message: String,
}

impl SceneError {
    /// Builds an error.
    pub fn new(loc: SourceLoc, field: impl Into<String>, message: impl Into<String>) -> Self {
        SceneError { loc, field: field.into(), message: message.into() }
    }
}
