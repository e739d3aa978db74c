//! Errors of scene loading. Every problem names the file, the field path (or line) and what
//! was expected, so a user can fix the scene without reading our code.

use std::fmt;
use std::path::PathBuf;

/// One thing wrong with a scene: where it is and what was expected there.
#[derive(Debug, Clone, PartialEq)]
pub struct Problem {
    /// The file the problem is in (the scene file, or a mesh/image it references).
    pub file: PathBuf,
    /// Field path inside the scene file (`shapes[3].radius`), or a position inside a referenced
    /// file (`vertex 12`); empty when the problem concerns the file as a whole.
    pub path: String,
    /// What is wrong and what was expected.
    pub message: String,
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.path.is_empty() {
            write!(f, "{}: {}", self.file.display(), self.message)
        } else {
            write!(
                f,
                "{}: {}: {}",
                self.file.display(),
                self.path,
                self.message
            )
        }
    }
}

/// Why a scene could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene (or a file it references) could not be read at all.
    #[error("{}: cannot read: {source}", file.display())]
    Io {
        file: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The scene was read but is not valid; all problems found are listed.
    #[error("{}", ProblemList(.0))]
    Invalid(Vec<Problem>),
}

impl SceneError {
    /// The problems of an invalid scene (empty for I/O errors).
    pub fn problems(&self) -> &[Problem] {
        match self {
            SceneError::Invalid(p) => p,
            SceneError::Io { .. } => &[],
        }
    }
}

struct ProblemList<'a>(&'a [Problem]);

impl fmt::Display for ProblemList<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            [] => write!(f, "invalid scene"),
            [one] => write!(f, "{one}"),
            many => {
                write!(f, "{} problems in the scene:", many.len())?;
                for p in many {
                    write!(f, "\n  {p}")?;
                }
                Ok(())
            }
        }
    }
}
