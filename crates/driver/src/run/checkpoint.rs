//! Checkpoints of explicit runs: `loam run SCENE --checkpoint-every N` and
//! `loam run --resume DIR`.
//!
//! A run with checkpoints keeps, in `OUT/checkpoint/`, a copy of its scene file
//! (`scene.toml` or `scene.json`) and the state after the latest multiple of `N` steps
//! (`state.ckpt`, replaced atomically each time; the format is
//! [`loam_scene::checkpoint`]). Resuming reads both, checks that they belong together and to
//! the scene's particles, and continues the run in `DIR`.

use loam_core::Particles;
use loam_scene::checkpoint::{CheckpointHeader, read_checkpoint, scene_hash, write_checkpoint};
use loam_scene::output::CheckpointNote;
use loam_scene::{Scene, SceneFormat};
use std::path::{Path, PathBuf};

/// The folder, inside a run's output folder, that holds its checkpoint.
const FOLDER: &str = "checkpoint";
/// The state file in [`FOLDER`].
const STATE: &str = "state.ckpt";

/// The copy of the scene kept beside the state: `scene.toml` or `scene.json`, after the
/// scene file's format.
fn scene_copy(folder: &Path, source: &Path) -> PathBuf {
    let ext = match SceneFormat::from_path(source) {
        Some(SceneFormat::Json) => "json",
        _ => "toml",
    };
    folder.join(format!("scene.{ext}"))
}

/// Removes the checkpoint of an earlier run from an output folder, so that a later
/// `--resume` cannot continue a state that the frames there do not belong to.
pub fn clear(out_dir: &Path) -> Result<(), String> {
    match std::fs::remove_dir_all(out_dir.join(FOLDER)) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(format!(
            "cannot remove the earlier checkpoint in {}: {e}",
            out_dir.join(FOLDER).display()
        )),
        _ => Ok(()),
    }
}

/// Writes the state every `every` steps.
pub struct Checkpointer {
    state: PathBuf,
    every: usize,
    hash: u64,
    source: PathBuf,
    /// The last checkpoint written.
    pub last: Option<CheckpointNote>,
}

impl Checkpointer {
    /// Checkpoints into `out_dir/checkpoint/` every `every` steps, for a run of the scene
    /// file `source` whose contents are `text` (copied there now).
    pub fn create(out_dir: &Path, source: &Path, text: &str, every: usize) -> Result<Self, String> {
        let folder = out_dir.join(FOLDER);
        std::fs::create_dir_all(&folder)
            .map_err(|e| format!("cannot create {}: {e}", folder.display()))?;
        let copy = scene_copy(&folder, source);
        std::fs::write(&copy, text).map_err(|e| format!("cannot write {}: {e}", copy.display()))?;
        Ok(Self {
            state: folder.join(STATE),
            every,
            hash: scene_hash(text.as_bytes()),
            source: source.to_path_buf(),
            last: None,
        })
    }

    /// Steps from `step` to the next step at which a state is saved (a multiple of the
    /// interval, after `step`).
    pub fn steps_to_next(&self, step: usize) -> usize {
        self.every - step % self.every
    }

    /// Whether the state after step `step` is saved.
    pub fn due(&self, step: usize) -> bool {
        step.is_multiple_of(self.every)
    }

    /// After step `step` at `time`: writes the state when `step` is a multiple of the
    /// interval (replacing the previous one only once the new one is complete).
    pub fn after_step<const D: usize>(
        &mut self,
        step: usize,
        time: f64,
        particles: &Particles<f64, D>,
    ) -> Result<(), String> {
        if !self.due(step) {
            return Ok(());
        }
        let header = CheckpointHeader {
            dimension: D,
            particles: particles.len(),
            step: step as u64,
            time,
            scene_hash: self.hash,
            source: self.source.clone(),
        };
        write_checkpoint(&self.state, &header, particles).map_err(|e| e.to_string())?;
        self.last = Some(CheckpointNote {
            path: self.state.display().to_string(),
            step: step as u64,
            time,
        });
        Ok(())
    }
}

/// A checkpoint to continue from, with the scene it belongs to.
pub struct Resume {
    /// The state file.
    pub state: PathBuf,
    /// Its header.
    pub header: CheckpointHeader,
    /// The recorded scene's text (for further checkpoints).
    pub text: String,
}

impl Resume {
    /// Opens the checkpoint in the output folder `dir` and the scene recorded beside it; the
    /// scene is parsed as the file it was copied from (relative paths in it resolve as they
    /// did) and its fields checked (the run validates it as a fresh run does). The scene
    /// must be the one the state was saved from (same hash).
    pub fn open(dir: &Path) -> Result<(Self, Scene), String> {
        let folder = dir.join(FOLDER);
        let state = folder.join(STATE);
        if !state.exists() {
            return Err(format!(
                "no checkpoint to resume in {}: expected {} (written by `loam run SCENE \
                 --checkpoint-every N`)",
                dir.display(),
                state.display()
            ));
        }
        let header = CheckpointHeader::peek(&state).map_err(|e| e.to_string())?;
        let copy = scene_copy(&folder, &header.source);
        let text = std::fs::read_to_string(&copy).map_err(|e| {
            format!(
                "cannot read the scene recorded with the checkpoint, {}: {e}",
                copy.display()
            )
        })?;
        let hash = scene_hash(text.as_bytes());
        if hash != header.scene_hash {
            return Err(format!(
                "{}: the scene recorded beside the checkpoint has changed since the state was \
                 saved (scene hash {hash:016x}, the checkpoint's {:016x})",
                copy.display(),
                header.scene_hash
            ));
        }
        let scene = Scene::read_text_of(&header.source, &text).map_err(|e| e.to_string())?;
        Ok((
            Self {
                state,
                header,
                text,
            },
            scene,
        ))
    }

    /// Reads the saved particles, checked against the scene's dimension, particle count and
    /// hash.
    pub fn particles<const D: usize>(
        &self,
        scene_particles: usize,
    ) -> Result<Particles<f64, D>, String> {
        let (header, particles) = read_checkpoint::<D>(&self.state).map_err(|e| e.to_string())?;
        header
            .check_scene(
                &self.state,
                D,
                scene_particles,
                scene_hash(self.text.as_bytes()),
            )
            .map_err(|e| e.to_string())?;
        Ok(particles)
    }

    /// A note for a scene file that has been edited since the run started: the file at the
    /// path the run was started with now differs from the copy kept with the checkpoint,
    /// and the run continues with the copy (the state belongs to it), so the edit takes
    /// effect only in a fresh run. `None` when the file is unchanged, or gone.
    pub fn edited_source(&self) -> Option<String> {
        let now = std::fs::read_to_string(&self.header.source).ok()?;
        (now != self.text).then(|| {
            format!(
                "{} has changed since the run started; the run continues with the scene \
                 recorded with its checkpoint, {} (run the edited scene afresh, without \
                 --resume, to use it)",
                self.header.source.display(),
                scene_copy(
                    self.state.parent().unwrap_or(Path::new("")),
                    &self.header.source
                )
                .display()
            )
        })
    }

    /// The note the run summary keeps of where the run resumed.
    pub fn note(&self) -> CheckpointNote {
        CheckpointNote {
            path: self.state.display().to_string(),
            step: self.header.step,
            time: self.header.time,
        }
    }
}
