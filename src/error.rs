//! One error type for the whole toolkit.
//!
//! Every error renders as a single line that names the file (when there is one) and the item
//! (field, marker, joint, vertex) at fault, so the CLI can print it as is and exit non-zero.

use std::path::{Path, PathBuf};

/// The toolkit's error: what went wrong, where, and (in the message) what to do about it.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read or written at the operating-system level.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A file was read but its content is unusable; `msg` names the item at fault.
    #[error("{}: {msg}", path.display())]
    Input { path: PathBuf, msg: String },
    /// Data handed to a library function is unusable (no file involved), e.g. collinear points.
    #[error("{0}")]
    Invalid(String),
}

/// Shorthand used throughout the crate.
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// A bad-content error for `path`, with a message naming the item.
    pub fn input(path: impl AsRef<Path>, msg: impl Into<String>) -> Self {
        Error::Input {
            path: path.as_ref().to_path_buf(),
            msg: msg.into(),
        }
    }

    /// An I/O error for `path`.
    pub fn io(path: impl AsRef<Path>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.as_ref().to_path_buf(),
            source,
        }
    }

    /// A data error with no file.
    pub fn invalid(msg: impl Into<String>) -> Self {
        Error::Invalid(msg.into())
    }

    /// A TOML parse error of `text` (read from `path`) as one line: the parser's message with
    /// the line it points at.
    pub fn toml(path: impl AsRef<Path>, text: &str, e: &toml::de::Error) -> Self {
        let line = e
            .span()
            .map(|s| {
                let n = text[..s.start.min(text.len())].matches('\n').count() + 1;
                format!(" (line {n})")
            })
            .unwrap_or_default();
        Error::input(path, e.message().replace('\n', " ") + &line)
    }

    /// Add where the file was named (e.g. the key of a list that named it) to a content error,
    /// after its message in parentheses; other errors are returned as they are.
    pub fn named_by(self, by: impl std::fmt::Display) -> Self {
        match self {
            Error::Input { path, msg } => Error::Input {
                path,
                msg: format!("{msg} (named by {by})"),
            },
            other => other,
        }
    }

    /// Attach a file to an error raised without one (e.g. a mesh check on a file just read).
    pub fn in_file(self, path: impl AsRef<Path>) -> Self {
        match self {
            Error::Invalid(msg) => Error::input(path, msg),
            other => other,
        }
    }
}
