//! Errors of loading, validating and building a scene.

use std::fmt;
use std::path::{Path, PathBuf};

/// The text formats a scene file may be written in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneFormat {
    /// TOML (`.toml`), the usual format.
    Toml,
    /// JSON (`.json`), for generated scenes.
    Json,
}

impl SceneFormat {
    /// The format a file name's extension announces (`.toml` or `.json`, any case).
    pub fn from_path(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "toml" => Some(Self::Toml),
            "json" => Some(Self::Json),
            _ => None,
        }
    }
}

impl fmt::Display for SceneFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Toml => "TOML",
            Self::Json => "JSON",
        })
    }
}

/// A 1-based line and column in a scene file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Location {
    /// Line number, from 1.
    pub line: usize,
    /// Column number (in characters), from 1.
    pub column: usize,
}

impl Location {
    /// The location of a byte offset in `text` (clamped to the text, and to a character
    /// boundary).
    pub fn from_offset(text: &str, offset: usize) -> Self {
        let mut end = offset.min(text.len());
        while !text.is_char_boundary(end) {
            end -= 1;
        }
        let before = &text[..end];
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        Self {
            line: before.matches('\n').count() + 1,
            column: before[line_start..].chars().count() + 1,
        }
    }
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "line {}, column {}", self.line, self.column)
    }
}

/// One problem with one field of a scene: where it is and what was expected.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Issue {
    /// Field path in the scene, e.g. `bodies[1].material` (empty for the whole file).
    pub path: String,
    /// What is wrong and what was expected.
    pub message: String,
}

impl Issue {
    /// An issue at `path`.
    pub fn new(path: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            path: path.into(),
            message: message.into(),
        }
    }
}

impl fmt::Display for Issue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.path.is_empty() {
            f.write_str(&self.message)
        } else {
            write!(f, "{}: {}", self.path, self.message)
        }
    }
}

/// Why a scene could not be loaded, validated or built.
///
/// `Display` gives a readable message starting with the file name when it is known; an
/// invalid scene lists one issue per line.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read.
    #[error("{}: cannot read the scene file: {source}", path.display())]
    Read {
        /// The scene file.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The file name does not end in `.toml` or `.json`.
    #[error("{}: unknown scene file extension; expected `.toml` or `.json`", path.display())]
    Extension {
        /// The scene file.
        path: PathBuf,
    },
    /// The text is not well-formed TOML or JSON.
    #[error("{}{format} syntax error{}: {message}", FilePrefix(file), At(location))]
    Syntax {
        /// The scene file, when the scene was read from one.
        file: Option<PathBuf>,
        /// The format being parsed.
        format: SceneFormat,
        /// Where the parser stopped, when known.
        location: Option<Location>,
        /// The parser's message.
        message: String,
    },
    /// The text is well-formed but fields are missing, unknown, of the wrong type or out of
    /// range.
    #[error("{}", IssueList(file, issues))]
    Invalid {
        /// The scene file, when the scene was read from one.
        file: Option<PathBuf>,
        /// The problems found (at least one).
        issues: Vec<Issue>,
    },
    /// [`crate::Scene::build`] was asked for a dimension other than the scene's.
    #[error("the scene is {scene}D but was built as {requested}D")]
    Dimension {
        /// The scene's dimension, [`crate::Scene::dim`].
        scene: usize,
        /// The dimension asked for.
        requested: usize,
    },
}

impl SceneError {
    /// An invalid-scene error from the issues found (not read from a file yet).
    pub(crate) fn invalid(issues: Vec<Issue>) -> Self {
        Self::Invalid { file: None, issues }
    }

    /// Attaches the scene file name to errors about the file's content.
    pub(crate) fn in_file(mut self, path: &Path) -> Self {
        if let Self::Syntax { file, .. } | Self::Invalid { file, .. } = &mut self {
            *file = Some(path.to_path_buf());
        }
        self
    }

    /// The field-level issues of an invalid scene (empty for other errors).
    pub fn issues(&self) -> &[Issue] {
        match self {
            Self::Invalid { issues, .. } => issues,
            _ => &[],
        }
    }
}

/// `"<file>: "` when the file is known.
struct FilePrefix<'a>(&'a Option<PathBuf>);

impl fmt::Display for FilePrefix<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(path) => write!(f, "{}: ", path.display()),
            None => Ok(()),
        }
    }
}

/// `" at line L, column C"` when the location is known.
struct At<'a>(&'a Option<Location>);

impl fmt::Display for At<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(loc) => write!(f, " at {loc}"),
            None => Ok(()),
        }
    }
}

/// One line per issue, each starting with the file name when known.
struct IssueList<'a>(&'a Option<PathBuf>, &'a [Issue]);

impl fmt::Display for IssueList<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, issue) in self.1.iter().enumerate() {
            if i > 0 {
                f.write_str("\n")?;
            }
            write!(f, "{}{issue}", FilePrefix(self.0))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locations_are_one_based_and_count_characters() {
        let text = "a = 1\nbé = x\n";
        assert_eq!(
            Location::from_offset(text, 0),
            Location { line: 1, column: 1 }
        );
        // Offset of `x`: "a = 1\n" is 6 bytes, "bé = " is 6 bytes (é is 2).
        assert_eq!(
            Location::from_offset(text, 12),
            Location { line: 2, column: 6 }
        );
        // Past the end and inside a multi-byte character: clamped, no panic.
        assert_eq!(Location::from_offset(text, 1000).line, 3);
        assert_eq!(
            Location::from_offset(text, 8),
            Location { line: 2, column: 2 }
        );
    }

    #[test]
    fn invalid_scene_lists_each_issue_with_the_file_name() {
        let err = SceneError::invalid(vec![
            Issue::new("grid.cell_size", "must be positive, got -0.1"),
            Issue::new("", "missing field `grid`"),
        ])
        .in_file(Path::new("scene.toml"));
        assert_eq!(
            err.to_string(),
            "scene.toml: grid.cell_size: must be positive, got -0.1\n\
             scene.toml: missing field `grid`"
        );
        assert_eq!(err.issues().len(), 2);
    }
}
