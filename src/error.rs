//! One error type for everything that can go wrong while loading a scene.
//!
//! Every error that comes from a file carries the file and, where there is one, the
//! line and column, so the CLI can print `scene.xml:12:5: ...` like a compiler does.

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A position in a source file (1-based line and column).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Loc {
    pub file: Arc<PathBuf>,
    pub line: u32,
    pub col: u32,
}

impl Loc {
    pub fn new(file: &Arc<PathBuf>, line: u32, col: u32) -> Self {
        Loc {
            file: file.clone(),
            line,
            col,
        }
    }

    /// A location naming only a file (for errors that have no line, e.g. a binary PLY).
    pub fn file_only(file: &Path) -> Self {
        Loc {
            file: Arc::new(file.to_path_buf()),
            line: 0,
            col: 0,
        }
    }
}

impl fmt::Display for Loc {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line == 0 {
            write!(f, "{}", self.file.display())
        } else {
            write!(f, "{}:{}:{}", self.file.display(), self.line, self.col)
        }
    }
}

/// A scene loading error: where, what, and (optionally) what to do about it.
#[derive(Debug, Clone)]
pub struct SceneError {
    pub loc: Option<Loc>,
    pub message: String,
    pub hint: Option<String>,
}

impl SceneError {
    pub fn new(loc: Option<Loc>, message: impl Into<String>) -> Self {
        SceneError {
            loc,
            message: message.into(),
            hint: None,
        }
    }

    pub fn at(loc: &Loc, message: impl Into<String>) -> Self {
        Self::new(Some(loc.clone()), message)
    }

    pub fn with_hint(mut self, hint: impl Into<String>) -> Self {
        self.hint = Some(hint.into());
        self
    }
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(loc) = &self.loc {
            write!(f, "{loc}: ")?;
        }
        write!(f, "{}", self.message)?;
        if let Some(hint) = &self.hint {
            write!(f, "\n  hint: {hint}")?;
        }
        Ok(())
    }
}

impl std::error::Error for SceneError {}

pub type Result<T> = std::result::Result<T, SceneError>;

/// Shorthand for `Err(SceneError::at(loc, msg))`.
pub fn err_at<T>(loc: &Loc, message: impl Into<String>) -> Result<T> {
    Err(SceneError::at(loc, message))
}
