//! Run output: particle frames for ParaView and the JSON run summary.
//!
//! - [`FrameWriter`] writes one `.vtu` file per frame ([`write_vtu`]) into an output folder
//!   and, after every frame, rewrites the `.pvd` collection ([`write_pvd`]) that lists them
//!   with their times, so a run that stops early still leaves a valid series. It first
//!   removes the files of an earlier run in that folder, so the folder never mixes two runs;
//!   a writer that [resumes](FrameWriter::resume) a run keeps that run's frames up to the
//!   saved state and removes only the later ones.
//! - [`write_summary`] writes a [`RunSummary`] as JSON.
//!
//! Every file (frames, the `.pvd`, the summary) is written to a temporary file in the same
//! folder (its name with `.tmp` appended) and renamed, so readers never see a half-written
//! file, and a run killed while writing leaves at most a `.tmp` file behind.

mod field;
mod pvd;
mod summary;
mod vtu;

pub use field::{Field, WaterTable, hencky_strain, pressure, von_mises};
pub use pvd::{PvdEntry, read_pvd, write_pvd};
pub use summary::{
    CheckpointNote, EnergySample, LoadStepSummary, ObstacleForceSample, ProbeHistory, RunStatus,
    RunSummary, write_obstacle_forces, write_summary,
};
pub use vtu::write_vtu;

use loam_core::Particles;
use nalgebra::SVector;
use std::path::{Path, PathBuf};

/// Why output could not be written.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// A file or folder could not be created or written.
    #[error("cannot write {}: {source}", path.display())]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// vtkio could not write a frame.
    #[error("cannot write {}: {source}", path.display())]
    Vtk {
        /// The frame file.
        path: PathBuf,
        /// vtkio's error.
        #[source]
        source: vtkio::Error,
    },
    /// The run summary could not be serialised.
    #[error("cannot serialise the run summary: {0}")]
    Json(#[source] serde_json::Error),
    /// A `.pvd` collection that is to be continued could not be read.
    #[error("{}: line {line}: {message}", path.display())]
    Series {
        /// The collection file.
        path: PathBuf,
        /// The 1-based line.
        line: usize,
        /// What is wrong with it.
        message: String,
    },
    /// A frame would hold a NaN or an infinity; nothing was written.
    #[error(
        "non-finite {field} in {} particle(s), first ids {:?}{hint}",
        ids.len(), &ids[..ids.len().min(8)]
    )]
    NonFinite {
        /// The field (`position` or a [`Field`] name).
        field: String,
        /// The particles, by id.
        ids: Vec<usize>,
        /// What it may mean (empty when nothing more is known).
        hint: String,
    },
    /// The initial positions passed for the displacement field do not match the particles.
    #[error("{given} initial positions were given for {particles} particles")]
    InitialPositions {
        /// Number of initial positions.
        given: usize,
        /// Number of particles.
        particles: usize,
    },
}

/// Writes `bytes` to `path` through a temporary file in the same folder and a rename.
fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    write_file_atomically(path, bytes).map_err(|source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Writes `bytes` to `path` through a temporary file (`path` + `.tmp`) and a rename, so a
/// reader (or a run killed while writing) never sees a half-written file.
pub(crate) fn write_file_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    std::fs::write(&tmp, bytes)?;
    std::fs::rename(&tmp, path)
}

/// Writes a series of particle frames, `frame_0000.vtu`, `frame_0001.vtu`, …, and the
/// collection [`FrameWriter::PVD_NAME`] listing them, into one folder.
#[derive(Debug)]
pub struct FrameWriter {
    dir: PathBuf,
    fields: Vec<Field>,
    entries: Vec<PvdEntry>,
    water: Option<WaterTable>,
}

impl FrameWriter {
    /// File name of the collection in the output folder.
    pub const PVD_NAME: &'static str = "particles.pvd";

    /// File name of the run summary in the output folder.
    pub const SUMMARY_NAME: &'static str = "summary.json";

    /// File name of the obstacles' forces of an explicit run in the output folder
    /// ([`write_obstacle_forces`]).
    pub const OBSTACLE_FORCES_NAME: &'static str = "obstacle_forces.csv";

    /// A writer into `dir` (created if missing) that writes the given point-data fields.
    ///
    /// The files of an earlier run in `dir` are removed first ([`FrameWriter::is_run_file`]:
    /// its frames, collection and summary, and temporaries of them); other files are left
    /// alone.
    pub fn create(dir: impl Into<PathBuf>, fields: &[Field]) -> Result<Self, OutputError> {
        let dir = dir.into();
        let io = |path: &Path| {
            let path = path.to_path_buf();
            move |source| OutputError::Io { path, source }
        };
        std::fs::create_dir_all(&dir).map_err(io(&dir))?;
        for entry in std::fs::read_dir(&dir).map_err(io(&dir))? {
            let entry = entry.map_err(io(&dir))?;
            let is_file = entry.file_type().is_ok_and(|t| t.is_file());
            if is_file && entry.file_name().to_str().is_some_and(Self::is_run_file) {
                std::fs::remove_file(entry.path()).map_err(io(&entry.path()))?;
            }
        }
        Ok(Self {
            dir,
            fields: fields.to_vec(),
            entries: Vec::new(),
            water: None,
        })
    }

    /// A writer that continues the series in `dir` from simulated time `until` on: the frames
    /// its collection lists up to `until` are kept, every other frame file of a run in `dir`
    /// (those listed after `until`, and any not listed) and temporaries are removed, and the
    /// next frame takes the next number. For a run resumed from a state saved at `until`, so
    /// the series has no duplicates. The summary is left for the resumed run to read and
    /// replace.
    pub fn resume(
        dir: impl Into<PathBuf>,
        fields: &[Field],
        until: f64,
    ) -> Result<Self, OutputError> {
        let dir = dir.into();
        let io = |path: &Path| {
            let path = path.to_path_buf();
            move |source| OutputError::Io { path, source }
        };
        let pvd = dir.join(Self::PVD_NAME);
        let mut entries = read_pvd(&pvd)?;
        let keep = entries.iter().take_while(|e| e.time <= until).count();
        entries.truncate(keep);
        for entry in std::fs::read_dir(&dir).map_err(io(&dir))? {
            let entry = entry.map_err(io(&dir))?;
            let name = entry.file_name();
            let Some(name) = name.to_str() else { continue };
            let kept = name == Self::PVD_NAME
                || name == Self::SUMMARY_NAME
                || entries.iter().any(|e| e.file == name);
            let is_file = entry.file_type().is_ok_and(|t| t.is_file());
            if is_file && Self::is_run_file(name) && !kept {
                std::fs::remove_file(entry.path()).map_err(io(&entry.path()))?;
            }
        }
        write_pvd(&pvd, &entries)?;
        Ok(Self {
            dir,
            fields: fields.to_vec(),
            entries,
            water: None,
        })
    }

    /// The water table of a coupled run, for the excess pore pressure of the frames.
    pub fn with_water_table(mut self, water: Option<WaterTable>) -> Self {
        self.water = water;
        self
    }

    /// Writes the next frame at simulated time `time` and rewrites the collection; returns
    /// the frame's path. `initial` (the initial positions) enables the displacement field.
    pub fn write_frame<const D: usize>(
        &mut self,
        time: f64,
        particles: &Particles<f64, D>,
        initial: Option<&[SVector<f64, D>]>,
    ) -> Result<PathBuf, OutputError> {
        let file = format!("frame_{:04}.vtu", self.entries.len());
        let path = self.dir.join(&file);
        write_vtu(&path, particles, initial, &self.fields, self.water)?;
        self.entries.push(PvdEntry { time, file });
        write_pvd(&self.pvd_path(), &self.entries)?;
        Ok(path)
    }

    /// Whether a file name is one a run writes: `frame_<digits>.vtu`, the collection
    /// [`FrameWriter::PVD_NAME`], the summary [`FrameWriter::SUMMARY_NAME`], the obstacles'
    /// forces [`FrameWriter::OBSTACLE_FORCES_NAME`], or one of these with `.tmp` appended.
    pub fn is_run_file(name: &str) -> bool {
        let name = name.strip_suffix(".tmp").unwrap_or(name);
        let frame = name
            .strip_prefix("frame_")
            .and_then(|rest| rest.strip_suffix(".vtu"))
            .is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()));
        frame
            || name == Self::PVD_NAME
            || name == Self::SUMMARY_NAME
            || name == Self::OBSTACLE_FORCES_NAME
    }

    /// The output folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Path of the collection file.
    pub fn pvd_path(&self) -> PathBuf {
        self.dir.join(Self::PVD_NAME)
    }

    /// The frames written so far, in order.
    pub fn entries(&self) -> &[PvdEntry] {
        &self.entries
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn run_files_are_recognised_by_name() {
        for name in [
            "frame_0000.vtu",
            "frame_12345.vtu",
            "frame_0003.vtu.tmp",
            "particles.pvd",
            "particles.pvd.tmp",
            "summary.json",
            "summary.json.tmp",
            "obstacle_forces.csv",
        ] {
            assert!(FrameWriter::is_run_file(name), "{name}");
        }
        for name in [
            "frame_.vtu",
            "frame_00a1.vtu",
            "notes.txt",
            "my_frame_0001.vtu",
        ] {
            assert!(!FrameWriter::is_run_file(name), "{name}");
        }
    }

    #[test]
    fn output_errors_can_cross_threads() {
        fn send_sync<T: Send + Sync + 'static>() {}
        send_sync::<OutputError>();
        send_sync::<crate::SceneError>();
    }
}
