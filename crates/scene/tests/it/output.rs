//! Output round trip: frames written with `FrameWriter` read back with vtkio, the `.pvd`
//! lists every frame, and the run summary is valid JSON.

use loam_core::Particles;
use loam_scene::output::{
    CheckpointNote, EnergySample, Field, FrameWriter, ObstacleForceSample, OutputError, RunStatus,
    RunSummary, write_obstacle_forces, write_summary, write_vtu,
};
use nalgebra::{Matrix2, Matrix3, SVector, vector};
use vtkio::model::{Attribute, DataSet, IOBuffer, Piece, Vtk};

/// Three particles in 2D with distinct velocities, one stretched and stressed.
fn particles() -> Particles<f64, 2> {
    let mut p = Particles::default();
    for (i, x) in [[0.1, 0.2], [0.3, 0.4], [0.5, 0.6]].iter().enumerate() {
        let v = vector![i as f64, -2.0 * i as f64];
        p.push(
            vector![x[0], x[1]],
            v,
            1000.0,
            vector![0.005, 0.005],
            i as u32 % 2,
        );
    }
    p.f[1] = Matrix2::new(1.2, 0.0, 0.0, 1.0);
    p.stress[1] = Matrix3::new(1.0, 2.0, 0.0, 2.0, 3.0, 0.0, 0.0, 0.0, 4.0);
    p
}

/// The inline piece of an imported `.vtu`.
fn piece(vtk: Vtk) -> vtkio::model::UnstructuredGridPiece {
    let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        panic!("not an unstructured grid");
    };
    let Some(Piece::Inline(piece)) = pieces.into_iter().next() else {
        panic!("no inline piece");
    };
    *piece
}

fn array(piece: &vtkio::model::UnstructuredGridPiece, name: &str) -> Option<IOBuffer> {
    piece.data.point.iter().find_map(|a| match a {
        Attribute::DataArray(d) if d.name == name => Some(d.data.clone()),
        _ => None,
    })
}

#[test]
fn frames_read_back_and_the_series_lists_them_all() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let mut writer = FrameWriter::create(&out, &Field::ALL).unwrap();
    let mut p = particles();
    let x0: Vec<SVector<f64, 2>> = p.x.clone();
    for k in 0..3 {
        let path = writer.write_frame(0.5 * k as f64, &p, Some(&x0)).unwrap();
        assert!(path.exists());
        for x in &mut p.x {
            x[0] += 0.01;
        }
    }
    let names: Vec<&str> = writer.entries().iter().map(|e| e.file.as_str()).collect();
    assert_eq!(
        names,
        ["frame_0000.vtu", "frame_0001.vtu", "frame_0002.vtu"]
    );

    let pvd = std::fs::read_to_string(writer.pvd_path()).unwrap();
    assert_eq!(pvd.matches("<DataSet ").count(), 3);
    for (name, t) in names.iter().zip(["0", "0.5", "1"]) {
        assert!(pvd.contains(&format!(
            "timestep=\"{t}\" group=\"\" part=\"0\" file=\"{name}\""
        )));
    }
    assert!(!out.join("particles.pvd.tmp").exists());

    let last = piece(Vtk::import(out.join("frame_0002.vtu")).unwrap());
    assert_eq!(last.num_points(), 3);
    assert_eq!(last.cells.num_cells(), 3);
    let points: Vec<f64> = last.points.clone().into_vec().unwrap();
    assert!((points[3] - 0.32).abs() < 1e-12 && points[5] == 0.0);
    let v: Vec<f64> = array(&last, "velocity").unwrap().into_vec().unwrap();
    assert_eq!(v, [0.0, 0.0, 0.0, 1.0, -2.0, 0.0, 2.0, -4.0, 0.0]);
    let u: Vec<f64> = array(&last, "displacement").unwrap().into_vec().unwrap();
    assert!((u[3] - 0.02).abs() < 1e-12 && u[4].abs() < 1e-12);
    let s: Vec<f64> = array(&last, "stress").unwrap().into_vec().unwrap();
    assert_eq!(&s[9..18], &[1.0, 2.0, 0.0, 2.0, 3.0, 0.0, 0.0, 0.0, 4.0]);
    let e: Vec<f64> = array(&last, "strain").unwrap().into_vec().unwrap();
    assert!((e[9] - 1.2f64.ln()).abs() < 1e-14 && e[0].abs() < 1e-14);
    let vol: Vec<f64> = array(&last, "volume").unwrap().into_vec().unwrap();
    assert!((vol[1] - 1.2e-4).abs() < 1e-16 && (vol[0] - 1e-4).abs() < 1e-16);
    let pressure: Vec<f64> = array(&last, "pressure").unwrap().into_vec().unwrap();
    assert!((pressure[1] + 8.0 / 3.0).abs() < 1e-14);
    let ids: Vec<u32> = array(&last, "material_id").unwrap().into_vec().unwrap();
    assert_eq!(ids, [0, 1, 0]);
    let ids: Vec<u64> = array(&last, "id").unwrap().into_vec().unwrap();
    assert_eq!(ids, [0, 1, 2]);
    for field in Field::ALL {
        assert!(
            array(&last, field.name()).is_some(),
            "{} missing",
            field.name()
        );
    }
}

#[test]
fn a_resumed_series_drops_the_frames_after_the_saved_time_and_continues_the_numbering() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let p = particles();
    let mut writer = FrameWriter::create(&out, &[Field::Velocity]).unwrap();
    for k in 0..4 {
        writer.write_frame(0.25 * k as f64, &p, None).unwrap();
    }
    // Left by a run killed while writing frame 4, and a file of the user's.
    std::fs::write(out.join("frame_0004.vtu.tmp"), "partial").unwrap();
    std::fs::write(out.join("frame_0009.vtu"), "unlisted").unwrap();
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    // A state saved at t = 0.5 (the time of frame 2, which is kept): frame 3 goes, with the
    // unlisted frame and the temporary.
    let mut resumed = FrameWriter::resume(&out, &[Field::Velocity], 0.5).unwrap();
    let kept: Vec<&str> = resumed.entries().iter().map(|e| e.file.as_str()).collect();
    assert_eq!(kept, ["frame_0000.vtu", "frame_0001.vtu", "frame_0002.vtu"]);
    for gone in ["frame_0003.vtu", "frame_0004.vtu.tmp", "frame_0009.vtu"] {
        assert!(!out.join(gone).exists(), "{gone} left");
    }
    for name in &kept {
        assert!(out.join(name).exists(), "{name} removed");
    }
    assert!(out.join("notes.txt").exists());
    let pvd = std::fs::read_to_string(resumed.pvd_path()).unwrap();
    assert_eq!(pvd.matches("<DataSet ").count(), 3);
    let next = resumed.write_frame(0.6, &p, None).unwrap();
    assert!(next.ends_with("frame_0003.vtu"));
    let pvd = std::fs::read_to_string(resumed.pvd_path()).unwrap();
    assert!(pvd.contains("timestep=\"0.6\" group=\"\" part=\"0\" file=\"frame_0003.vtu\""));

    // A folder without a series cannot be continued.
    let err = FrameWriter::resume(dir.path().join("none"), &[Field::Velocity], 0.5).unwrap_err();
    assert!(err.to_string().contains("particles.pvd"), "{err}");
}

#[test]
fn a_field_subset_is_honoured_and_displacement_needs_initial_positions() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("one.vtu");
    let p = particles();
    write_vtu(
        &path,
        &p,
        None,
        &[Field::Velocity, Field::Displacement],
        None,
    )
    .unwrap();
    let piece = piece(Vtk::import(&path).unwrap());
    assert!(array(&piece, "velocity").is_some());
    assert!(array(&piece, "displacement").is_none());
    assert!(array(&piece, "stress").is_none());

    let err = write_vtu(&path, &p, Some(&p.x[..2]), &[Field::Velocity], None).unwrap_err();
    assert!(matches!(
        err,
        OutputError::InitialPositions {
            given: 2,
            particles: 3
        }
    ));
}

#[test]
fn a_3d_frame_keeps_the_z_components() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("3d.vtu");
    let mut p = Particles::<f64, 3>::default();
    p.push(
        vector![0.1, 0.2, 0.3],
        vector![1.0, 2.0, 3.0],
        1.0,
        vector![0.5, 0.5, 0.5],
        0,
    );
    write_vtu(&path, &p, None, &[Field::Velocity, Field::Mass], None).unwrap();
    let piece = piece(Vtk::import(&path).unwrap());
    assert_eq!(
        piece.points.clone().into_vec::<f64>().unwrap(),
        [0.1, 0.2, 0.3]
    );
    let v: Vec<f64> = array(&piece, "velocity").unwrap().into_vec().unwrap();
    assert_eq!(v, [1.0, 2.0, 3.0]);
    let m: Vec<f64> = array(&piece, "mass").unwrap().into_vec().unwrap();
    assert_eq!(m, [1.0]);
}

#[test]
fn a_non_finite_field_is_an_error_naming_it_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let mut writer = FrameWriter::create(&out, &Field::ALL).unwrap();
    let mut p = particles();
    writer.write_frame(0.0, &p, None).unwrap();
    // A NaN stress at particle 1.
    p.stress[1][(0, 1)] = f64::NAN;
    let err = writer.write_frame(0.5, &p, None).unwrap_err();
    match &err {
        OutputError::NonFinite { field, ids, .. } => {
            assert_eq!((field.as_str(), ids.as_slice()), ("stress", &[1][..]));
        }
        e => panic!("unexpected error {e}"),
    }
    // F = 0 at particle 2: F Fᵀ = 0, whose logarithm is −∞; the message gives det F.
    p.stress[1] = Matrix3::zeros();
    p.f[2] = Matrix2::zeros();
    let err = writer.write_frame(0.5, &p, None).unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.starts_with("non-finite strain in 1 particle(s), first ids [2]")
            && msg.contains("det F is down to 0.000e0"),
        "{msg}"
    );
    // The failed frames were not written; the series still lists the first one only.
    assert!(!out.join("frame_0001.vtu").exists() && !out.join("frame_0001.vtu.tmp").exists());
    let pvd = std::fs::read_to_string(writer.pvd_path()).unwrap();
    assert_eq!(pvd.matches("<DataSet ").count(), 1);
}

#[test]
fn a_new_writer_removes_an_earlier_runs_files_only() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let mut writer = FrameWriter::create(&out, &[Field::Velocity]).unwrap();
    let p = particles();
    for k in 0..3 {
        writer.write_frame(k as f64, &p, None).unwrap();
    }
    for name in [
        "summary.json",
        "frame_0007.vtu.tmp",
        "notes.txt",
        "frame_a.vtu",
    ] {
        std::fs::write(out.join(name), "x").unwrap();
    }
    let writer = FrameWriter::create(&out, &[Field::Velocity]).unwrap();
    assert!(writer.entries().is_empty());
    let mut left: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    left.sort();
    assert_eq!(left, ["frame_a.vtu", "notes.txt"]);
}

#[test]
fn writing_into_a_file_path_is_an_error_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("taken");
    std::fs::write(&file, "").unwrap();
    let err = FrameWriter::create(&file, &Field::ALL).unwrap_err();
    assert!(err.to_string().starts_with("cannot write"), "{err}");
}

#[test]
fn run_summary_is_written_as_json() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("summary.json");
    let summary = RunSummary {
        device: None,
        scene: "examples/disk_collision.toml".into(),
        dimension: 2,
        particles: 2000,
        steps: 4000,
        end_time: 4.0,
        time_unit: None,
        time_reached: 1.5,
        dt_min: 1e-3,
        dt_max: 1e-3,
        wall_time_s: 2.0,
        steps_per_second: 2000.0,
        particle_steps_per_second: 4.0e6,
        status: RunStatus::Failed,
        error: Some("particle 17 left the grid at step 1500".into()),
        warnings: vec![],
        energy: vec![EnergySample {
            step: 0,
            time: 0.0,
            kinetic: 1.0,
            strain: 0.0,
            gravity: 0.5,
            total: 1.5,
        }],
        frames: vec!["frame_0000.vtu".into()],
        load_steps: vec![],
        probes: vec![],
        obstacle_forces: vec![ObstacleForceSample {
            step: 200,
            time: 0.2,
            since: 0.1,
            forces: vec![vec![0.5, -120.0]],
            displacements: vec![vec![0.0, -0.01]],
        }],
        resumed_from: None,
        checkpoint: Some(CheckpointNote {
            path: "out/checkpoint/state.ckpt".into(),
            step: 1500,
            time: 1.5,
        }),
    };
    write_summary(&path, &summary).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("\"status\": \"failed\""));
    let back: RunSummary = serde_json::from_str(&text).unwrap();
    assert_eq!(back, summary);
}

/// The obstacles' forces as CSV: a header naming each obstacle's components, one row per
/// sample with the numbers as given.
#[test]
fn obstacle_forces_are_written_as_csv() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("obstacle_forces.csv");
    let sample = |step: u64, fy: f64| ObstacleForceSample {
        step,
        time: step as f64 / 1000.0,
        since: (step - 100) as f64 / 1000.0,
        forces: vec![vec![0.25, fy], vec![0.0, -1.5]],
        displacements: vec![vec![0.0, -(step as f64) / 1000.0], vec![0.0; 2]],
    };
    write_obstacle_forces(&path, &[sample(100, -20.0), sample(200, -40.0)]).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(
        lines[0],
        "step,time,since,obstacles[0].fx,obstacles[0].fy,obstacles[0].ux,obstacles[0].uy,\
         obstacles[1].fx,obstacles[1].fy,obstacles[1].ux,obstacles[1].uy"
    );
    assert_eq!(lines.len(), 3);
    let row: Vec<f64> = lines[2].split(',').map(|c| c.parse().unwrap()).collect();
    assert_eq!(
        row,
        [200.0, 0.2, 0.1, 0.25, -40.0, 0.0, -0.2, 0.0, -1.5, 0.0, 0.0]
    );
}
