//! Reading scenes from TOML or JSON text: the `from_*` loaders validate what they read, the
//! `read_*` loaders and [`Scene::parse_str`] check the fields only.
//!
//! Parsing goes through `serde_path_to_error`, so a field that is missing, unknown or of the
//! wrong type is reported with its path (`solver.sheme: unknown field ...`) and, where the
//! parser knows it, its line and column.

use crate::error::{Issue, Location, SceneError, SceneFormat};
use crate::schema::Scene;
use serde::de::DeserializeOwned;
use std::path::Path;

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

/// Parses without validating (a scene, or another file of loam's in the scene's formats).
pub(crate) fn parse<S: DeserializeOwned>(text: &str, format: SceneFormat) -> Result<S, SceneError> {
    match format {
        SceneFormat::Toml => parse_toml(text),
        SceneFormat::Json => parse_json(text),
    }
}

fn parse_toml<S: DeserializeOwned>(text: &str) -> Result<S, SceneError> {
    let location = |e: &toml::de::Error| e.span().map(|s| Location::from_offset(text, s.start));
    let de = toml::Deserializer::parse(text).map_err(|e| SceneError::Syntax {
        file: None,
        format: SceneFormat::Toml,
        location: location(&e),
        message: e.message().trim_end().to_owned(),
    })?;
    serde_path_to_error::deserialize(de).map_err(|e| {
        let at = location(e.inner());
        field_error(e.path(), e.inner().message(), at)
    })
}

fn parse_json<S: DeserializeOwned>(text: &str) -> Result<S, SceneError> {
    let mut de = serde_json::Deserializer::from_str(text);
    let scene: S = serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let inner = e.inner();
        if inner.is_data() {
            field_error(e.path(), &json_message(inner), json_location(inner))
        } else {
            json_syntax_error(inner)
        }
    })?;
    // Nothing but whitespace may follow the document.
    de.end().map_err(|e| json_syntax_error(&e))?;
    Ok(scene)
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
fn field_error(
    path: &serde_path_to_error::Path,
    message: &str,
    at: Option<Location>,
) -> SceneError {
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
    SceneError::invalid(vec![Issue::new(path, message)])
}
