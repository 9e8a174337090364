//! Reading scenes from TOML or JSON text: the `from_*` loaders validate what they read, the
//! `read_*` loaders and [`Scene::parse_str`] check the fields only.
//!
//! Parsing goes through `serde_path_to_error`, so a field that is missing, unknown or of the
//! wrong type is reported with its path (`solver.sheme: unknown field ...`) and, where the
//! parser knows it, its line and column. Every unknown key is reported, not only the first
//! ([`keys`]).

use crate::error::{Issue, Location, SceneError, SceneFormat};
use crate::schema::Scene;
use serde::de::DeserializeOwned;
use std::path::Path;

mod keys;

impl Scene {
    /// Reads, parses and validates a scene file; the format follows the extension
    /// (`.toml` or `.json`).
    pub fn from_path(path: impl AsRef<Path>) -> Result<Self, SceneError> {
        let scene = Self::read_path(path)?;
        scene.validate()?;
        Ok(scene)
    }

    /// Reads and parses a scene file and checks its fields ([`Scene::check_fields`]), without
    /// generating particles: for a front end that [estimates](Scene::estimate) the size of a
    /// scene before it validates ([`Scene::validate`]) and builds it.
    pub fn read_path(path: impl AsRef<Path>) -> Result<Self, SceneError> {
        Self::read_path_with_text(path).map(|(scene, _)| scene)
    }

    /// [`Scene::read_path`], also returning the file's text (what a run that keeps a copy
    /// of its scene, such as one writing checkpoints, records).
    pub fn read_path_with_text(path: impl AsRef<Path>) -> Result<(Self, String), SceneError> {
        let path = path.as_ref();
        // The extension first, so a wrong one is reported before the file is read.
        SceneFormat::from_path(path).ok_or_else(|| SceneError::Extension {
            path: path.to_path_buf(),
        })?;
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::read_text_of(path, &text).map(|scene| (scene, text))
    }

    /// Parses `text` as the contents of the scene file `path` and checks its fields, as
    /// [`Scene::read_path`] does, without reading the file (the format follows its
    /// extension; errors name it, and relative paths in the scene resolve against its
    /// folder): for a scene kept elsewhere, such as the copy a checkpoint keeps beside the
    /// state.
    pub fn read_text_of(path: impl AsRef<Path>, text: &str) -> Result<Self, SceneError> {
        let path = path.as_ref();
        let format = SceneFormat::from_path(path).ok_or_else(|| SceneError::Extension {
            path: path.to_path_buf(),
        })?;
        let mut scene: Scene = parse(text, format).map_err(|e| e.in_file(path))?;
        scene.source = Some(path.to_path_buf());
        scene.check_fields()?;
        Ok(scene)
    }

    /// Parses a scene written in the given format and checks its fields, without generating
    /// particles (see [`Scene::read_path`]).
    pub fn parse_str(text: &str, format: SceneFormat) -> Result<Self, SceneError> {
        let scene: Scene = parse(text, format)?;
        scene.check_fields()?;
        Ok(scene)
    }

    /// Parses and validates a scene written in TOML.
    pub fn from_toml_str(text: &str) -> Result<Self, SceneError> {
        Self::from_str_in(text, SceneFormat::Toml)
    }

    /// Parses and validates a scene written in JSON.
    pub fn from_json_str(text: &str) -> Result<Self, SceneError> {
        Self::from_str_in(text, SceneFormat::Json)
    }

    /// Parses and validates a scene written in the given format.
    pub fn from_str_in(text: &str, format: SceneFormat) -> Result<Self, SceneError> {
        let scene: Scene = parse(text, format)?;
        scene.validate()?;
        Ok(scene)
    }
}

/// Parses the text of `path`, a file of loam's in the scene's formats other than a scene (an
/// inversion file), into `S` without validating it; errors name `path`, and every unknown key
/// is reported.
///
/// # Errors
/// A syntax error, or the fields that are missing, unknown or of the wrong type.
pub fn parse_file<S: DeserializeOwned>(
    path: &Path,
    text: &str,
    format: SceneFormat,
) -> Result<S, SceneError> {
    parse(text, format).map_err(|e| e.in_file(path))
}

/// Parses without validating (a scene, or another file of loam's in the scene's formats).
pub(crate) fn parse<S: DeserializeOwned>(text: &str, format: SceneFormat) -> Result<S, SceneError> {
    match format {
        SceneFormat::Toml => parse_toml(text),
        SceneFormat::Json => parse_json(text),
    }
}

fn parse_toml<S: DeserializeOwned>(text: &str) -> Result<S, SceneError> {
    let location =
        |span: Option<std::ops::Range<usize>>| span.map(|s| Location::from_offset(text, s.start));
    let root = toml::de::DeTable::parse(text).map_err(|e| SceneError::Syntax {
        file: None,
        format: SceneFormat::Toml,
        location: location(e.span()),
        message: e.message().trim_end().to_owned(),
    })?;
    let span = root.span();
    let mut document = toml::de::DeValue::Table(root.into_inner());
    every_problem(&mut document, |document| {
        let toml::de::DeValue::Table(table) = document else {
            unreachable!("the document is a table")
        };
        let de = toml::Deserializer::from(toml::Spanned::new(span.clone(), table.clone()));
        serde_path_to_error::deserialize(de).map_err(|e| Failure {
            at: location(e.inner().span()),
            message: e.inner().message().to_owned(),
            path: e.path().clone(),
        })
    })
}

fn parse_json<S: DeserializeOwned>(text: &str) -> Result<S, SceneError> {
    let mut de = serde_json::Deserializer::from_str(text);
    let first = serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let inner = e.inner();
        if inner.is_data() {
            Ok(Failure {
                at: json_location(inner),
                message: json_message(inner),
                path: e.path().clone(),
            })
        } else {
            Err(json_syntax_error(inner))
        }
    });
    let first = match first {
        Ok(scene) => {
            // Nothing but whitespace may follow the document.
            de.end().map_err(|e| json_syntax_error(&e))?;
            return Ok(scene);
        }
        Err(failure) => failure?,
    };
    // The text is well-formed JSON: look for the other problems in its value (they are
    // reported without a line, which only the text has).
    let mut document: serde_json::Value =
        serde_json::from_str(text).map_err(|e| json_syntax_error(&e))?;
    let mut first = Some(first);
    every_problem(&mut document, |document| match first.take() {
        Some(failure) => Err(failure),
        None => serde_path_to_error::deserialize(document.clone()).map_err(|e| Failure {
            at: None,
            message: json_message(e.inner()),
            path: e.path().clone(),
        }),
    })
}

/// Why deserializing a document failed: where, and the parser's message.
struct Failure {
    path: serde_path_to_error::Path,
    message: String,
    at: Option<Location>,
}

/// Deserializes `document` with `attempt` until it succeeds or fails on something other
/// than an unknown key, removing each unknown key it fails on ([`keys`]): every unknown key
/// is reported, each with its path, not only the first serde meets.
fn every_problem<S, N: keys::Node>(
    document: &mut N,
    mut attempt: impl FnMut(&N) -> Result<S, Failure>,
) -> Result<S, SceneError> {
    let mut issues = Vec::new();
    loop {
        let failure = match attempt(document) {
            Ok(scene) if issues.is_empty() => return Ok(scene),
            Ok(_) => return Err(SceneError::invalid(issues)),
            Err(failure) => failure,
        };
        issues.push(field_issue(&failure.path, &failure.message, failure.at));
        let removed = keys::unknown_key(&failure.message)
            .is_some_and(|key| keys::remove(document, &failure.path, key));
        if !removed || issues.len() >= keys::MOST {
            return Err(SceneError::invalid(issues));
        }
    }
}

fn json_syntax_error(e: &serde_json::Error) -> SceneError {
    SceneError::Syntax {
        file: None,
        format: SceneFormat::Json,
        location: json_location(e),
        message: json_message(e),
    }
}

fn json_location(e: &serde_json::Error) -> Option<Location> {
    (e.line() > 0).then(|| Location {
        line: e.line(),
        column: e.column(),
    })
}

/// serde_json's message without the " at line L column C" it appends (reported separately).
fn json_message(e: &serde_json::Error) -> String {
    let message = e.to_string();
    match message.rfind(" at line ") {
        Some(i) => message[..i].to_owned(),
        None => message,
    }
}

/// A missing, unknown or mistyped field, as one issue naming its path.
fn field_issue(path: &serde_path_to_error::Path, message: &str, at: Option<Location>) -> Issue {
    // The root (a missing or unknown section) has no useful path or location.
    let path = path.to_string();
    let (path, at) = if path == "." {
        (String::new(), None)
    } else {
        (path, at)
    };
    let message = match at {
        Some(at) => format!("{message} ({at})"),
        None => message.to_owned(),
    };
    Issue::new(path, message)
}
