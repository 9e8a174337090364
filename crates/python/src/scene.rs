//! `loam.Scene`: a scene read from a file, TOML text or a Python dict, validated as
//! `loam check` validates it.

use crate::errors::scene_error;
use loam_scene::SolverKind;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use std::path::PathBuf;

/// A validated scene (`loam.Scene`).
#[pyclass(module = "loam", frozen)]
pub struct Scene {
    /// The scene, parsed and validated.
    pub inner: loam_scene::Scene,
}

impl Scene {
    /// Validates `scene` (particle generation included), turning an error into a
    /// `SceneError`.
    fn validated(py: Python<'_>, scene: loam_scene::Scene) -> PyResult<Self> {
        scene.validate().map_err(|e| scene_error(py, &e))?;
        Ok(Self { inner: scene })
    }

    /// The name the scene goes by in messages and summaries: its file, else `<scene>`.
    pub fn label(&self) -> PathBuf {
        (self.inner.source.clone()).unwrap_or_else(|| PathBuf::from("<scene>"))
    }
}

/// The argument `scene` as a [`Scene`], or a `TypeError` naming the argument and what was
/// given instead.
pub fn expect_scene<'py>(scene: &Bound<'py, PyAny>) -> PyResult<PyRef<'py, Scene>> {
    scene.extract().map_err(|_| {
        let given = (scene.get_type().name()).map_or_else(|_| "?".to_owned(), |n| n.to_string());
        PyTypeError::new_err(format!(
            "scene: expected a loam.Scene (from Scene.from_file, from_toml or from_dict), got \
             {given}"
        ))
    })
}

#[pymethods]
impl Scene {
    /// Reads and validates a scene file (`.toml` or `.json`).
    #[staticmethod]
    fn from_file(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let scene = loam_scene::Scene::read_path(&path).map_err(|e| scene_error(py, &e))?;
        Self::validated(py, scene)
    }

    /// Parses and validates a scene written in TOML.
    #[staticmethod]
    fn from_toml(py: Python<'_>, text: &str) -> PyResult<Self> {
        let scene = loam_scene::Scene::parse_str(text, loam_scene::SceneFormat::Toml)
            .map_err(|e| scene_error(py, &e))?;
        Self::validated(py, scene)
    }

    /// Validates a scene given as a dict of the file's sections (as `tomllib.load` reads
    /// a scene file); it goes through `json.dumps`, so NaN and infinities are refused.
    #[staticmethod]
    fn from_dict(py: Python<'_>, scene: &Bound<'_, PyAny>) -> PyResult<Self> {
        let kwargs = pyo3::types::PyDict::new(py);
        kwargs.set_item("allow_nan", false)?;
        let text: String = (py.import("json")?)
            .call_method("dumps", (scene,), Some(&kwargs))
            .map_err(|e| {
                PyValueError::new_err(format!("scene: not a JSON-like dict: {}", e.value(py)))
            })?
            .extract()?;
        let scene = loam_scene::Scene::parse_str(&text, loam_scene::SceneFormat::Json)
            .map_err(|e| scene_error(py, &e))?;
        Self::validated(py, scene)
    }

    /// The dimension, 2 or 3.
    #[getter]
    fn dim(&self) -> usize {
        self.inner.dim()
    }

    /// The solver, `"explicit"` or `"implicit"`.
    #[getter]
    fn solver(&self) -> &'static str {
        match self.inner.solver.kind {
            SolverKind::Explicit => "explicit",
            SolverKind::Implicit => "implicit",
        }
    }

    /// The file the scene was read from, or None.
    #[getter]
    fn source(&self) -> Option<PathBuf> {
        self.inner.source.clone()
    }

    /// The folder a run of the scene writes to (`output.dir`, else `out/<file stem>`, or
    /// `out/scene` for a scene not read from a file).
    #[getter]
    fn output_dir(&self) -> PathBuf {
        self.inner.output_dir()
    }

    /// The scene as JSON text, every section written out (defaults included where the
    /// scene format writes them).
    fn to_json(&self) -> PyResult<String> {
        serde_json::to_string(&self.inner).map_err(|e| PyValueError::new_err(e.to_string()))
    }

    /// The scene as a dict of its sections (what `from_dict` takes back).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        py.import("json")?.call_method1("loads", (self.to_json()?,))
    }

    /// The scene as TOML text.
    fn to_toml(&self) -> PyResult<String> {
        toml::to_string(&self.inner).map_err(|e| PyValueError::new_err(e.to_string()))
    }

    /// `Scene(<file>, <dim>D, <solver>)`.
    fn __repr__(&self) -> String {
        format!(
            "Scene({}, {}D, {})",
            self.label().display(),
            self.dim(),
            self.solver()
        )
    }
}
