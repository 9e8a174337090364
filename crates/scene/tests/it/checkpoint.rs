//! Checkpoint files: every particle field comes back with the same bits, and a damaged or
//! mismatched file is an error that names the problem.

use loam_core::{MaterialState, Particles};
use loam_scene::checkpoint::{
    CheckpointError, CheckpointHeader, read_checkpoint, scene_hash, write_checkpoint,
};
use nalgebra::{Matrix3, SMatrix, SVector};
use std::path::{Path, PathBuf};

/// Particles whose every field holds distinct values with full mantissas (and a NaN payload
/// and a negative zero, which a decimal round trip would lose).
fn particles<const D: usize>(n: usize) -> Particles<f64, D> {
    let mut p = Particles::default();
    let mut k = 0.0f64;
    let mut next = || {
        k += 1.0;
        (k * 0.1).sin() / 3.0 + k.sqrt()
    };
    for i in 0..n {
        let hw = SVector::<f64, D>::from_fn(|_, _| next());
        p.push(
            SVector::from_fn(|_, _| next()),
            SVector::from_fn(|_, _| next()),
            next(),
            hw,
            i as u32 % 3,
        );
        p.a[i] = SVector::from_fn(|_, _| next());
        p.f[i] = SMatrix::from_fn(|_, _| next());
        p.c[i] = SMatrix::from_fn(|_, _| next());
        p.stress[i] = Matrix3::from_fn(|_, _| next());
        p.state[i] = MaterialState {
            plastic_strain: next(),
            tensor: Matrix3::from_fn(|_, _| next()),
            hardening: next(),
        };
    }
    p.v[0][0] = f64::from_bits(0x7ff8_0000_dead_beef);
    p.stress[0][(2, 2)] = -0.0;
    p
}

fn header(n: usize, d: usize) -> CheckpointHeader {
    CheckpointHeader {
        dimension: d,
        particles: n,
        step: 1234,
        time: 0.1 + 0.2,
        scene_hash: scene_hash(b"[grid]\nlo = [0.0, 0.0]\n"),
        source: PathBuf::from("scenes/column.toml"),
    }
}

fn bits<const D: usize>(p: &Particles<f64, D>) -> Vec<u64> {
    let mut out: Vec<u64> = Vec::new();
    for i in 0..p.len() {
        let mut put = |it: &mut dyn Iterator<Item = &f64>| out.extend(it.map(|x| x.to_bits()));
        put(&mut p.x[i].iter());
        put(&mut p.v[i].iter());
        put(&mut p.a[i].iter());
        put(&mut p.f[i].iter());
        put(&mut p.c[i].iter());
        put(&mut p.stress[i].iter());
        put(&mut [p.mass[i], p.volume0[i], p.state[i].plastic_strain].iter());
        put(&mut p.half_width0[i].iter());
        put(&mut p.state[i].tensor.iter());
        out.push(p.material[i] as u64);
    }
    out
}

fn round_trip<const D: usize>() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("state.ckpt");
    let p = particles::<D>(37);
    let h = header(p.len(), D);
    write_checkpoint(&path, &h, &p).unwrap();
    assert!(!dir.path().join("state.ckpt.tmp").exists());
    let (back_header, back) = read_checkpoint::<D>(&path).unwrap();
    assert_eq!(back_header, h);
    assert_eq!(back_header.time.to_bits(), (0.1f64 + 0.2).to_bits());
    assert_eq!(bits(&back), bits(&p));
    assert_eq!(CheckpointHeader::peek(&path).unwrap(), h);
}

#[test]
fn every_field_round_trips_bit_for_bit_in_2d_and_3d() {
    round_trip::<2>();
    round_trip::<3>();
}

/// A valid 2D checkpoint of 5 particles and its bytes.
fn valid(dir: &Path) -> (PathBuf, Vec<u8>) {
    let path = dir.join("state.ckpt");
    let p = particles::<2>(5);
    write_checkpoint(&path, &header(5, 2), &p).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    (path, bytes)
}

fn read_error(path: &Path) -> CheckpointError {
    read_checkpoint::<2>(path).unwrap_err()
}

#[test]
fn a_truncated_file_is_reported_with_both_lengths() {
    let dir = tempfile::tempdir().unwrap();
    let (path, bytes) = valid(dir.path());
    std::fs::write(&path, &bytes[..bytes.len() - 100]).unwrap();
    let err = read_error(&path);
    assert!(
        matches!(err, CheckpointError::Length { expected, found, .. }
            if expected == bytes.len() as u64 && found == bytes.len() as u64 - 100),
        "{err}"
    );
    assert!(err.to_string().contains("truncated"), "{err}");
    // Cut inside the header: also a length error, from both readers.
    std::fs::write(&path, &bytes[..30]).unwrap();
    assert!(matches!(read_error(&path), CheckpointError::Length { .. }));
    assert!(matches!(
        CheckpointHeader::peek(&path).unwrap_err(),
        CheckpointError::Length { .. }
    ));
}

#[test]
fn bad_magic_and_an_unknown_version_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let (path, bytes) = valid(dir.path());
    let mut other = bytes.clone();
    other[..8].copy_from_slice(b"NOTLOAM!");
    std::fs::write(&path, &other).unwrap();
    let err = read_error(&path);
    assert!(
        matches!(err, CheckpointError::NotACheckpoint { .. }),
        "{err}"
    );
    assert!(err.to_string().contains("not a loam checkpoint"), "{err}");

    let mut newer = bytes.clone();
    newer[8..12].copy_from_slice(&7u32.to_le_bytes());
    std::fs::write(&path, &newer).unwrap();
    let err = read_error(&path);
    assert!(
        matches!(err, CheckpointError::Version { found: 7, .. }),
        "{err}"
    );
    assert!(err.to_string().contains("version 7"), "{err}");
}

#[test]
fn a_flipped_bit_in_the_particles_fails_the_checksum() {
    let dir = tempfile::tempdir().unwrap();
    let (path, mut bytes) = valid(dir.path());
    let at = bytes.len() / 2;
    bytes[at] ^= 0x10;
    std::fs::write(&path, &bytes).unwrap();
    let err = read_error(&path);
    assert!(matches!(err, CheckpointError::Checksum { .. }), "{err}");
    assert!(err.to_string().contains("checksum mismatch"), "{err}");
}

#[test]
fn a_checkpoint_of_another_dimension_count_or_scene_is_a_mismatch() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = valid(dir.path());
    let err = read_checkpoint::<3>(&path).unwrap_err();
    assert!(
        err.to_string()
            .contains("the dimension is 2D in the checkpoint but 3D in the scene"),
        "{err}"
    );
    let h = CheckpointHeader::peek(&path).unwrap();
    let hash = h.scene_hash;
    h.check_scene(&path, 2, 5, hash).unwrap();
    let err = h.check_scene(&path, 2, 6, hash).unwrap_err();
    assert!(
        err.to_string()
            .contains("the particle count is 5 in the checkpoint but 6 in the scene"),
        "{err}"
    );
    let err = h
        .check_scene(&path, 2, 5, scene_hash(b"edited"))
        .unwrap_err();
    assert!(err.to_string().contains("the scene hash is"), "{err}");
    let err = h.check_scene(&path, 3, 5, hash).unwrap_err();
    assert!(err.to_string().contains("the dimension"), "{err}");
}

#[test]
fn the_scene_hash_is_fnv1a() {
    // Published FNV-1a 64 test vectors.
    assert_eq!(scene_hash(b""), 0xcbf2_9ce4_8422_2325);
    assert_eq!(scene_hash(b"a"), 0xaf63_dc4c_8601_ec8c);
    assert_eq!(scene_hash(b"foobar"), 0x8594_4171_f739_67e8);
}
