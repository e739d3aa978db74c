//! Errors of the rendering core.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("{}: cannot write image: {message}", path.display())]
    Output { path: PathBuf, message: String },
    #[error("{}: cannot read image: {message}", path.display())]
    Input { path: PathBuf, message: String },
}
