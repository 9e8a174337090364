"""Stepping from Python: the same bits as `loam run`, conservation, errors and Ctrl-C."""

from __future__ import annotations

import _thread
import os
import subprocess
import threading
from pathlib import Path
from typing import Optional

import numpy as np
import pytest

import loam
from conftest import REPO, block, dambreak, need


def test_stepping_gives_the_bits_of_loam_run(tmp_path: Path) -> None:
    scene = loam.Scene.from_dict(dambreak(tmp_path / "run"))
    summary = loam.run(scene)
    assert summary["status"] == "completed"
    times, frames = loam.read_series(summary["dir"])
    assert len(frames) == 4 and times[-1] == pytest.approx(0.09)

    sim = loam.Simulation(scene)
    assert sim.dim == 2
    first = frames[0]["position"]
    assert np.array_equal(first[:, :2], sim.positions) and not first[:, 2].any()
    sim.advance_to(0.09)
    assert sim.steps == summary["steps"] == 3000
    assert sim.time == times[-1]
    last = frames[-1]
    assert np.array_equal(last["position"][:, :2], sim.positions)
    assert np.array_equal(last["velocity"][:, :2], sim.velocities)
    assert np.array_equal(last["material_id"], sim.material)
    # The water moved: the comparison is not of the initial state.
    assert sim.positions[:, 0].max() > first[:, 0].max() + 0.03


def test_a_path_runs_as_the_loam_program_does(
    tmp_path: Path, loam_binary: Optional[Path]
) -> None:
    if loam_binary is None:
        pytest.skip("no loam program built (cargo build --release -p loam-cli)")
    file = tmp_path / "dambreak.toml"
    file.write_text(loam.Scene.from_dict(dambreak(tmp_path / "program")).to_toml())
    subprocess.run([str(loam_binary), "run", str(file), "--quiet"], check=True)
    python = loam.run(file, out=tmp_path / "python")
    _, ours = loam.read_series(python["dir"])
    _, theirs = loam.read_series(tmp_path / "program")
    assert len(ours) == len(theirs) == 4
    for a, b in zip(ours, theirs):
        assert a.keys() == b.keys()
        for name in a:
            assert np.array_equal(a[name], b[name]), name


def test_mass_is_constant_and_a_free_fall_has_velocity_g_t() -> None:
    sim = loam.Simulation(loam.Scene.from_dict(block(gravity=-9.8)))
    mass = sim.masses.sum()
    assert mass == pytest.approx(1000.0 * 0.2 * 0.2, rel=1e-12)
    sim.step(500)
    assert sim.steps == 500
    assert sim.time == pytest.approx(0.05, rel=1e-12)
    assert sim.masses.sum() == mass
    mean = (sim.masses[:, None] * sim.velocities).sum(axis=0) / mass
    assert mean[0] == pytest.approx(0.0, abs=1e-12)
    assert mean[1] == pytest.approx(-9.8 * sim.time, rel=1e-12)
    # A rigid fall: every particle moves with the mean, the block neither stretched nor
    # stressed.
    assert np.allclose(sim.velocities[:, 1], mean[1], rtol=1e-10)
    assert np.allclose(sim.deformation_gradient, np.eye(2), atol=1e-10)
    assert np.abs(sim.stress).max() < 1e-3
    assert sim.pore_pressure.shape == sim.masses.shape and not sim.pore_pressure.any()
    assert sim.masses.dtype == np.float64 and sim.material.dtype == np.int64


def test_velocities_set_from_python_step_as_a_scenes_initial_velocity() -> None:
    """A velocity set from Python steps to the same bits as the same velocity given in the
    scene (`bodies[0].velocity`): the setter replaces the state the solver integrates."""
    scene = block(gravity=-9.8)
    given = dict(scene, bodies=[dict(scene["bodies"][0], velocity=[0.75, -0.5])])
    reference = loam.Simulation(loam.Scene.from_dict(given))
    sim = loam.Simulation(loam.Scene.from_dict(scene))
    sim.velocities = np.tile([0.75, -0.5], (len(sim.masses), 1))
    np.testing.assert_array_equal(sim.velocities, reference.velocities)
    sim.step(100)
    reference.step(100)
    np.testing.assert_array_equal(sim.positions, reference.positions)
    np.testing.assert_array_equal(sim.velocities, reference.velocities)


def test_bad_velocities_raise_naming_them() -> None:
    sim = loam.Simulation(loam.Scene.from_dict(block()))
    n = len(sim.masses)
    with pytest.raises(ValueError, match=rf"velocities: expected shape \[{n}, 2\], got \[{n}, 3\]"):
        sim.velocities = np.zeros((n, 3))
    with pytest.raises(ValueError, match=r"velocities: expected shape"):
        sim.velocities = np.zeros(2 * n)
    with pytest.raises(TypeError, match="velocities: expected dtype float64, got float32"):
        sim.velocities = np.zeros((n, 2), dtype=np.float32)
    v = np.zeros((n, 2))
    v[3, 1] = np.inf
    with pytest.raises(ValueError, match=r"velocities\[3, 1\] = inf"):
        sim.velocities = v
    implicit = loam.Simulation(loam.Scene.from_file(REPO / "examples" / "column_compaction.toml"))
    with pytest.raises(loam.SimulationError, match="quasi-static"):
        implicit.velocities = np.zeros((len(implicit.masses), 2))


def test_a_fixed_step_never_passes_the_target_time() -> None:
    sim = loam.Simulation(loam.Scene.from_dict(block()))
    sim.advance_to(0.01049)
    assert sim.steps == 104
    sim.advance_to(0.0105)
    assert sim.steps == 105
    sim.advance_to(0.0)
    assert sim.steps == 105


def test_an_adaptive_step_ends_on_the_target_time() -> None:
    scene = block()
    scene["solver"]["time_step"] = {"type": "adaptive", "cfl": 0.4, "max_dt": 1e-3}
    sim = loam.Simulation(loam.Scene.from_dict(scene))
    sim.advance_to(0.0123)
    assert sim.time == pytest.approx(0.0123, rel=1e-12)


def test_a_particle_leaving_the_grid_raises_simulation_error() -> None:
    sim = loam.Simulation(loam.Scene.from_dict(block(end_time=1.0)))
    with pytest.raises(loam.SimulationError, match="grid"):
        sim.advance_to(1.0)


def test_bad_arguments_raise_errors_naming_them() -> None:
    scene = loam.Scene.from_dict(block())
    with pytest.raises(ValueError, match="device"):
        loam.Simulation(scene, device="tpu")
    sim = loam.Simulation(scene)
    with pytest.raises(ValueError, match="^t: "):
        sim.advance_to(float("nan"))
    with pytest.raises(ValueError, match="^n: "):
        sim.step(-1)
    with pytest.raises(TypeError, match="^scene: expected a loam.Scene"):
        loam.Simulation("examples/dam_break.toml")  # type: ignore[arg-type]
    with pytest.raises(FileNotFoundError, match="folder"):
        loam.read_series(REPO / "no_such_folder")


def test_an_implicit_scene_steps_by_load_steps() -> None:
    sim = loam.Simulation(loam.Scene.from_file(REPO / "examples" / "column_compaction.toml"))
    assert sim.load_factor == 0.0
    sim.step(1)
    assert sim.steps == 1 and 0.0 < (sim.load_factor or 0.0) <= 1.0
    with pytest.raises(NotImplementedError, match="load steps"):
        sim.advance_to(1.0)


def interrupt_after(seconds: float) -> threading.Timer:
    """A Ctrl-C (SIGINT, as the terminal sends it) to the main thread after ``seconds``."""
    timer = threading.Timer(seconds, _thread.interrupt_main)
    timer.start()
    return timer


def test_ctrl_c_stops_a_long_advance_at_a_completed_step() -> None:
    sim = loam.Simulation(loam.Scene.from_dict(block(gravity=0.0)))
    timer = interrupt_after(0.3)
    with pytest.raises(KeyboardInterrupt):
        sim.advance_to(1.0e3)
    timer.join()
    assert 0 < sim.steps < 10_000_000
    assert sim.time == pytest.approx(sim.steps * 1e-4, rel=1e-9)
    assert np.isfinite(sim.positions).all()
    sim.step(1)


def test_ctrl_c_stops_a_run_which_records_it(tmp_path: Path) -> None:
    scene = dambreak(tmp_path)
    scene["solver"]["end_time"] = 30.0
    scene["output"]["frames"] = 1000
    long = loam.Scene.from_dict(scene)
    timer = interrupt_after(0.5)
    with pytest.raises(KeyboardInterrupt):
        loam.run(long)
    timer.join()
    summary = (tmp_path / "summary.json").read_text()
    assert '"status": "interrupted"' in summary
    # The next run goes to its end.
    assert loam.run(loam.Scene.from_dict(dambreak(tmp_path)))["status"] == "completed"


def test_plot_frame_draws_each_particle_with_its_value(tmp_path: Path) -> None:
    """The scatter's points are the frame's positions and its colours the field's values:
    the speed for a vector, the compression-positive mean stress −tr σ/3 for the stress."""
    need("matplotlib").use("Agg")
    import matplotlib.pyplot as plt

    from loam.plot import plot_frame

    scene = dambreak(tmp_path)
    scene["output"]["fields"] = ["velocity", "stress"]
    loam.run(loam.Scene.from_dict(scene), out=tmp_path)
    _, frames = loam.read_series(tmp_path)
    frame = frames[-1]
    fig, (a, b) = plt.subplots(1, 2)
    speed = plot_frame(frame, "velocity", ax=a)
    np.testing.assert_array_equal(speed.get_offsets(), frame["position"][:, :2])
    np.testing.assert_allclose(speed.get_array(), np.linalg.norm(frame["velocity"], axis=1))
    p = plot_frame(frame, "stress", ax=b)
    mean = -np.trace(frame["stress"], axis1=1, axis2=2) / 3
    np.testing.assert_allclose(p.get_array(), mean)
    assert mean.max() > 0, "the water column presses on the floor: compression"
    with pytest.raises(KeyError, match="velocity"):
        plot_frame(frame, "speed")
    plt.close(fig)


def gpu_simulation(scene: loam.Scene) -> loam.Simulation:
    """``scene`` on the first GPU adapter; skips the test where there is none, except under
    CI (``CI=true``), which installs Mesa's software Vulkan driver for these tests."""
    try:
        return loam.Simulation(scene, device="gpu")
    except loam.SimulationError as e:
        if os.environ.get("CI") == "true":
            raise
        pytest.skip(f"no GPU adapter: {e}")


def test_a_gpu_simulation_steps_as_the_cpu_one_to_f32_round_off(tmp_path: Path) -> None:
    """The reduced friction dam-break, 600 fixed steps on the GPU (f32) and on the CPU
    (f64): the same step count and time (but for Δt's f32 rounding), and positions within
    1e-4 m. The GPU parity tests hold the GPU to the CPU's own f32 run, whose distance from the f64 run grows to about
    1e-5 m over 2,500 steps of this dam-break; 1e-4 m (a five-hundredth of a cell) leaves
    that a factor of ten and is far below any error in the physics (a wrong friction or
    pressure moves the front by millimetres in 600 steps)."""
    scene = loam.Scene.from_dict(dambreak(tmp_path))
    gpu = gpu_simulation(scene)
    cpu = loam.Simulation(scene)
    gpu.step(300)
    gpu.advance_to(0.018)
    cpu.step(300)
    cpu.advance_to(0.018)
    assert gpu.steps == cpu.steps == 600
    # The device steps by the f32 value of Δt = 3e-5 s (rounded by at most 2⁻²⁴ ≈ 6e-8 of it).
    assert gpu.time == pytest.approx(cpu.time, rel=6e-8)
    x = gpu.positions
    assert x.dtype == np.float64 and x.shape == cpu.positions.shape
    assert np.abs(x - cpu.positions).max() <= 1e-4
    assert np.abs(x - cpu.positions).max() > 0, "the GPU runs in f32"
    np.testing.assert_array_equal(gpu.material, cpu.material)


def test_the_gpu_refuses_an_implicit_scene_naming_the_device() -> None:
    scene = loam.Scene.from_file(REPO / "examples" / "consolidation" / "terzaghi.toml")
    with pytest.raises(ValueError, match="device"):
        loam.Simulation(scene, device="gpu")
