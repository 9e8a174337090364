//! Restartable explicit state: a small versioned binary file holding every particle field
//! bit for bit, the clock, and what it belongs to.
//!
//! The explicit solver's state is the particles plus the simulated time and the step count
//! (the grid is scratch rebuilt every step; see `docs/architecture.md`), so that is what a
//! checkpoint holds. Layout, all numbers little-endian:
//!
//! ```text
//! offset  size  field
//!  0       8    magic "LOAMCKPT"
//!  8       4    format version (u32, currently 3)
//! 12       4    dimension D (u32, 2 or 3)
//! 16       4    bytes per scalar (u32, 8: f64)
//! 20       4    length S of the scene path in bytes (u32)
//! 24       8    particle count N (u64)
//! 32       8    steps completed (u64)
//! 40       8    simulated time (f64)
//! 48       8    scene hash (u64, FNV-1a of the scene file's bytes, see [`scene_hash`])
//! 56       S    the scene file's path (UTF-8), for relative file references in the scene
//! 56 + S  ...   the particle fields, field after field, each for particles 0..N:
//!               x (N·D f64), v (N·D), a (N·D), F (N·D², column-major), C (N·D²),
//!               stress (N·9), mass (N), volume0 (N), half_width0 (N·D), material (N u32),
//!               plastic strain (N f64), state tensor (N·9), hardening variable (N),
//!               pore pressure (N)
//! end − 8  8    checksum (u64, FNV-1a 64 of every byte before it)
//! ```
//!
//! Numbers are written with `to_le_bytes` and read with `from_le_bytes`, so a value comes
//! back with the same bits (NaN payloads included). The format is written by hand rather
//! than through a serialisation crate: `Particles` holds nalgebra types whose serde forms
//! would tie the layout to a crate's encoding and feature flags, while a fixed layout with
//! a header that can be checked before anything is decoded gives precise errors (truncated,
//! wrong version, wrong dimension, checksum) in ~150 lines without a new dependency.
//!
//! Files are written to a temporary name and renamed into place, so a run killed while
//! writing leaves the previous checkpoint intact.

use crate::output::write_file_atomically;
use loam_core::{MaterialState, Particles};
use nalgebra::{SMatrix, SVector};
use std::io::Read;
use std::path::{Path, PathBuf};

/// The first bytes of every checkpoint file.
pub const MAGIC: [u8; 8] = *b"LOAMCKPT";

/// The format version this crate writes and reads.
pub const VERSION: u32 = 3;

/// Bytes of the fixed part of the header (before the scene path).
const HEADER_BYTES: usize = 56;

/// Bytes of the trailing checksum.
const CHECKSUM_BYTES: usize = 8;

/// Why a checkpoint could not be written, read or used.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    /// The file could not be read or written.
    #[error("cannot access checkpoint {}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The file does not start with [`MAGIC`].
    #[error("{} is not a loam checkpoint (bad magic bytes)", path.display())]
    NotACheckpoint {
        /// The file.
        path: PathBuf,
    },
    /// The format version is not [`VERSION`].
    #[error(
        "{}: checkpoint format version {found}, this loam reads version {VERSION}",
        path.display()
    )]
    Version {
        /// The file.
        path: PathBuf,
        /// The version in the file.
        found: u32,
    },
    /// The file is shorter or longer than its header announces.
    #[error(
        "{}: checkpoint is truncated or damaged: its header announces {expected} bytes, the \
         file has {found}",
        path.display()
    )]
    Length {
        /// The file.
        path: PathBuf,
        /// The length the header announces.
        expected: u64,
        /// The file's length.
        found: u64,
    },
    /// The stored checksum does not match the contents.
    #[error(
        "{}: checkpoint checksum mismatch (stored {stored:016x}, computed {computed:016x}): \
         the file is damaged",
        path.display()
    )]
    Checksum {
        /// The file.
        path: PathBuf,
        /// The checksum stored in the file.
        stored: u64,
        /// The checksum of the contents.
        computed: u64,
    },
    /// A header field holds a value no writer produces.
    #[error("{}: checkpoint header is damaged: {what}", path.display())]
    Header {
        /// The file.
        path: PathBuf,
        /// Which field and what it holds.
        what: String,
    },
    /// The checkpoint does not belong to the scene it is used with.
    #[error(
        "{}: checkpoint does not match the scene: {what} is {checkpoint} in the checkpoint \
         but {scene} in the scene",
        path.display()
    )]
    Mismatch {
        /// The file.
        path: PathBuf,
        /// What differs (`"the dimension"`, `"the particle count"`, `"the scene hash"`).
        what: &'static str,
        /// The checkpoint's value.
        checkpoint: String,
        /// The scene's value.
        scene: String,
    },
}

/// What a checkpoint says about itself besides the particles.
#[derive(Clone, Debug, PartialEq)]
pub struct CheckpointHeader {
    /// Spatial dimension, 2 or 3.
    pub dimension: usize,
    /// Number of particles.
    pub particles: usize,
    /// Steps completed when the state was saved.
    pub step: u64,
    /// Simulated time when the state was saved (s).
    pub time: f64,
    /// [`scene_hash`] of the scene file the run was started from.
    pub scene_hash: u64,
    /// Path of that scene file (relative file references in the scene resolve against it).
    pub source: PathBuf,
}

impl CheckpointHeader {
    /// Reads only the header of the checkpoint at `path` (magic, version and the fields);
    /// the particles and the checksum are checked by [`read_checkpoint`].
    pub fn peek(path: &Path) -> Result<Self, CheckpointError> {
        let io = |source| CheckpointError::Io {
            path: path.to_path_buf(),
            source,
        };
        let mut file = std::fs::File::open(path).map_err(io)?;
        let found = file.metadata().map_err(io)?.len();
        let mut fixed = [0u8; HEADER_BYTES];
        if let Err(e) = file.read_exact(&mut fixed) {
            return Err(match e.kind() {
                std::io::ErrorKind::UnexpectedEof => CheckpointError::Length {
                    path: path.to_path_buf(),
                    expected: (HEADER_BYTES + CHECKSUM_BYTES) as u64,
                    found,
                },
                _ => io(e),
            });
        }
        let source_len = check_fixed(path, &fixed)?;
        let mut source = vec![0u8; source_len];
        file.read_exact(&mut source)
            .map_err(|_| CheckpointError::Length {
                path: path.to_path_buf(),
                expected: (HEADER_BYTES + source_len + CHECKSUM_BYTES) as u64,
                found,
            })?;
        decode_header(path, &fixed, &source)
    }

    /// Checks that the checkpoint belongs to a scene of the given dimension, particle count
    /// and [`scene_hash`]; `path` names the checkpoint in the error.
    pub fn check_scene(
        &self,
        path: &Path,
        dimension: usize,
        particles: usize,
        scene_hash: u64,
    ) -> Result<(), CheckpointError> {
        let mismatch = |what, checkpoint: String, scene: String| {
            Err(CheckpointError::Mismatch {
                path: path.to_path_buf(),
                what,
                checkpoint,
                scene,
            })
        };
        if self.scene_hash != scene_hash {
            return mismatch(
                "the scene hash",
                format!("{:016x}", self.scene_hash),
                format!("{scene_hash:016x}"),
            );
        }
        if self.dimension != dimension {
            return mismatch(
                "the dimension",
                format!("{}D", self.dimension),
                format!("{dimension}D"),
            );
        }
        if self.particles != particles {
            return mismatch(
                "the particle count",
                self.particles.to_string(),
                particles.to_string(),
            );
        }
        Ok(())
    }
}

/// FNV-1a (64 bit) of `bytes`: the scene hash of a scene file's bytes and the checksum of a
/// checkpoint. Not cryptographic; it detects damage and edits, not tampering.
pub fn scene_hash(bytes: &[u8]) -> u64 {
    fnv1a(bytes)
}

fn fnv1a(bytes: &[u8]) -> u64 {
    const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
    const PRIME: u64 = 0x0000_0100_0000_01b3;
    bytes
        .iter()
        .fold(OFFSET, |h, &b| (h ^ u64::from(b)).wrapping_mul(PRIME))
}

/// The number of `f64` values a particle takes in the file: x, v, a (`D` each), F and C
/// (`D²` each), the stress (9), mass and reference volume, the half-widths (`D`), the plastic
/// strain, the state tensor (9), the hardening variable and the pore pressure.
fn scalars_per_particle(d: usize) -> usize {
    4 * d + 2 * d * d + 23
}

/// The file length a header announces, `None` on overflow (a damaged count).
fn file_length(d: usize, particles: u64, source_len: usize) -> Option<u64> {
    let per = (8 * scalars_per_particle(d) + 4) as u64;
    particles
        .checked_mul(per)?
        .checked_add((HEADER_BYTES + source_len + CHECKSUM_BYTES) as u64)
}

/// Writes the state of a run (after `header.step` steps, at `header.time`) to `path`,
/// atomically; `header.dimension` and `header.particles` are taken from the particles.
pub fn write_checkpoint<const D: usize>(
    path: &Path,
    header: &CheckpointHeader,
    particles: &Particles<f64, D>,
) -> Result<(), CheckpointError> {
    let n = particles.len();
    let source = header.source.to_string_lossy();
    let source = source.as_bytes();
    let mut out = Vec::with_capacity(
        HEADER_BYTES + source.len() + n * (8 * scalars_per_particle(D) + 4) + CHECKSUM_BYTES,
    );
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&(D as u32).to_le_bytes());
    out.extend_from_slice(&8u32.to_le_bytes());
    out.extend_from_slice(&(source.len() as u32).to_le_bytes());
    out.extend_from_slice(&(n as u64).to_le_bytes());
    out.extend_from_slice(&header.step.to_le_bytes());
    out.extend_from_slice(&header.time.to_le_bytes());
    out.extend_from_slice(&header.scene_hash.to_le_bytes());
    out.extend_from_slice(source);
    let p = particles;
    let put = |out: &mut Vec<u8>, values: &mut dyn Iterator<Item = f64>| {
        values.for_each(|x| out.extend_from_slice(&x.to_le_bytes()))
    };
    put(&mut out, &mut p.x.iter().flat_map(|x| x.iter().copied()));
    put(&mut out, &mut p.v.iter().flat_map(|x| x.iter().copied()));
    put(&mut out, &mut p.a.iter().flat_map(|x| x.iter().copied()));
    put(&mut out, &mut p.f.iter().flat_map(|x| x.iter().copied()));
    put(&mut out, &mut p.c.iter().flat_map(|x| x.iter().copied()));
    put(
        &mut out,
        &mut p.stress.iter().flat_map(|x| x.iter().copied()),
    );
    put(&mut out, &mut p.mass.iter().copied());
    put(&mut out, &mut p.volume0.iter().copied());
    put(
        &mut out,
        &mut p.half_width0.iter().flat_map(|x| x.iter().copied()),
    );
    for m in &p.material {
        out.extend_from_slice(&m.to_le_bytes());
    }
    put(&mut out, &mut p.state.iter().map(|s| s.plastic_strain));
    put(
        &mut out,
        &mut p.state.iter().flat_map(|s| s.tensor.iter().copied()),
    );
    put(&mut out, &mut p.state.iter().map(|s| s.hardening));
    put(&mut out, &mut p.pore_pressure.iter().copied());
    let checksum = fnv1a(&out);
    out.extend_from_slice(&checksum.to_le_bytes());
    write_file_atomically(path, &out).map_err(|source| CheckpointError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Reads a checkpoint of dimension `D`: checks the magic bytes, the version, the length the
/// header announces and the checksum, then decodes the particles bit for bit.
pub fn read_checkpoint<const D: usize>(
    path: &Path,
) -> Result<(CheckpointHeader, Particles<f64, D>), CheckpointError> {
    let bytes = std::fs::read(path).map_err(|source| CheckpointError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let found = bytes.len() as u64;
    let short = |expected| CheckpointError::Length {
        path: path.to_path_buf(),
        expected,
        found,
    };
    let fixed: &[u8; HEADER_BYTES] = bytes
        .get(..HEADER_BYTES)
        .and_then(|b| b.try_into().ok())
        .ok_or_else(|| short((HEADER_BYTES + CHECKSUM_BYTES) as u64))?;
    let source_len = check_fixed(path, fixed)?;
    let dimension = u32_at(fixed, 12) as usize;
    let count = u64_at(fixed, 24);
    let expected = file_length(dimension, count, source_len).unwrap_or(u64::MAX);
    if expected != found {
        return Err(short(expected));
    }
    let body = &bytes[..bytes.len() - CHECKSUM_BYTES];
    let stored = u64_at(&bytes, bytes.len() - CHECKSUM_BYTES);
    let computed = fnv1a(body);
    if stored != computed {
        return Err(CheckpointError::Checksum {
            path: path.to_path_buf(),
            stored,
            computed,
        });
    }
    let header = decode_header(path, fixed, &bytes[HEADER_BYTES..HEADER_BYTES + source_len])?;
    if header.dimension != D {
        return Err(CheckpointError::Mismatch {
            path: path.to_path_buf(),
            what: "the dimension",
            checkpoint: format!("{}D", header.dimension),
            scene: format!("{D}D"),
        });
    }
    let n = header.particles;
    let mut r = Reader {
        bytes: body,
        at: HEADER_BYTES + source_len,
    };
    let x = r.vectors::<D>(n);
    let v = r.vectors::<D>(n);
    let a = r.vectors::<D>(n);
    let f = r.tensors::<D>(n);
    let c = r.tensors::<D>(n);
    let stress = r.tensors::<3>(n);
    let mass = r.scalars(n);
    let volume0 = r.scalars(n);
    let half_width0 = r.vectors::<D>(n);
    let material = (0..n).map(|_| r.u32()).collect();
    let plastic = r.scalars(n);
    let tensors = r.tensors::<3>(n);
    let hardening = r.scalars(n);
    let pore_pressure = r.scalars(n);
    let state = (plastic.into_iter().zip(tensors).zip(hardening))
        .map(|((plastic_strain, tensor), hardening)| MaterialState {
            plastic_strain,
            tensor,
            hardening,
        })
        .collect();
    let particles = Particles {
        x,
        v,
        a,
        f,
        c,
        stress,
        mass,
        volume0,
        half_width0,
        material,
        state,
        pore_pressure,
    };
    Ok((header, particles))
}

/// Checks the magic bytes, the version and the scalar size of a fixed header; returns the
/// length of the scene path that follows it.
fn check_fixed(path: &Path, fixed: &[u8; HEADER_BYTES]) -> Result<usize, CheckpointError> {
    if fixed[..8] != MAGIC {
        return Err(CheckpointError::NotACheckpoint {
            path: path.to_path_buf(),
        });
    }
    let version = u32_at(fixed, 8);
    if version != VERSION {
        return Err(CheckpointError::Version {
            path: path.to_path_buf(),
            found: version,
        });
    }
    let header = |what: String| CheckpointError::Header {
        path: path.to_path_buf(),
        what,
    };
    let dimension = u32_at(fixed, 12);
    if !(2..=3).contains(&dimension) {
        return Err(header(format!("dimension {dimension} (expected 2 or 3)")));
    }
    let scalar = u32_at(fixed, 16);
    if scalar != 8 {
        return Err(header(format!(
            "{scalar} bytes per scalar (expected 8, f64)"
        )));
    }
    Ok(u32_at(fixed, 20) as usize)
}

/// The header fields of a checked fixed header and the scene path bytes.
fn decode_header(
    path: &Path,
    fixed: &[u8; HEADER_BYTES],
    source: &[u8],
) -> Result<CheckpointHeader, CheckpointError> {
    let header = |what: String| CheckpointError::Header {
        path: path.to_path_buf(),
        what,
    };
    let particles = usize::try_from(u64_at(fixed, 24))
        .map_err(|_| header(format!("particle count {}", u64_at(fixed, 24))))?;
    let source =
        std::str::from_utf8(source).map_err(|_| header("the scene path is not UTF-8".into()))?;
    Ok(CheckpointHeader {
        dimension: u32_at(fixed, 12) as usize,
        particles,
        step: u64_at(fixed, 32),
        time: f64::from_bits(u64_at(fixed, 40)),
        scene_hash: u64_at(fixed, 48),
        source: PathBuf::from(source),
    })
}

fn u32_at(bytes: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(std::array::from_fn(|k| bytes[at + k]))
}

fn u64_at(bytes: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(std::array::from_fn(|k| bytes[at + k]))
}

/// Reads the particle fields in order from a buffer whose length has been checked.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn f64(&mut self) -> f64 {
        let x = f64::from_bits(u64_at(self.bytes, self.at));
        self.at += 8;
        x
    }

    fn u32(&mut self) -> u32 {
        let x = u32_at(self.bytes, self.at);
        self.at += 4;
        x
    }

    fn scalars(&mut self, n: usize) -> Vec<f64> {
        (0..n).map(|_| self.f64()).collect()
    }

    fn vectors<const D: usize>(&mut self, n: usize) -> Vec<SVector<f64, D>> {
        (0..n)
            .map(|_| SVector::from_iterator((0..D).map(|_| self.f64())))
            .collect()
    }

    /// `n` matrices, each column-major (nalgebra's storage order, as written).
    fn tensors<const D: usize>(&mut self, n: usize) -> Vec<SMatrix<f64, D, D>> {
        (0..n)
            .map(|_| SMatrix::from_iterator((0..D * D).map(|_| self.f64())))
            .collect()
    }
}
