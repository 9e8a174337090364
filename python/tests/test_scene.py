"""Scenes from files, TOML text and dicts: validation errors name the field."""

from __future__ import annotations

import subprocess
from pathlib import Path
from typing import Optional

import pytest

import loam
from conftest import REPO, block


def test_a_valid_scene_reports_its_dimension_and_solver() -> None:
    scene = loam.Scene.from_file(REPO / "examples" / "dambreak_friction.toml")
    assert scene.dim == 2
    assert scene.solver == "explicit"
    again = loam.Scene.from_dict(scene.to_dict())
    assert again.to_dict() == scene.to_dict()
    assert loam.Scene.from_toml(scene.to_toml()).to_dict() == scene.to_dict()
    assert loam.Scene.from_file(REPO / "examples" / "cantilever.toml").solver == "implicit"


def test_a_typo_in_a_field_names_the_field() -> None:
    scene = block()
    material = scene["materials"][0]
    material["densty"] = material.pop("density")
    with pytest.raises(loam.SceneError) as err:
        loam.Scene.from_dict(scene)
    assert isinstance(err.value, ValueError)
    assert "densty" in str(err.value)
    assert err.value.path is not None and err.value.path.startswith("materials[0]")


def test_a_negative_density_names_its_path() -> None:
    scene = block()
    scene["materials"][0]["density"] = -1000.0
    with pytest.raises(loam.SceneError) as err:
        loam.Scene.from_dict(scene)
    assert err.value.path == "materials[0].density"
    assert str(err.value).startswith("materials[0].density: ")
    assert ("materials[0].density", str(err.value).split(": ", 1)[1]) in err.value.issues


def test_a_missing_file_raises() -> None:
    with pytest.raises(loam.SceneError, match="cannot read the scene file"):
        loam.Scene.from_file(REPO / "examples" / "no_such_scene.toml")


def test_nan_in_a_dict_is_refused() -> None:
    scene = block()
    scene["loads"]["gravity"] = [0.0, float("nan")]
    with pytest.raises(ValueError, match="scene"):
        loam.Scene.from_dict(scene)


def test_the_message_is_what_loam_check_prints(
    tmp_path: Path, loam_binary: Optional[Path]
) -> None:
    if loam_binary is None:
        pytest.skip("no loam program built (cargo build --release -p loam-cli)")
    text = (REPO / "examples" / "elastic_block_drop.toml").read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace("density = ", "density = -", 1))
    with pytest.raises(loam.SceneError) as err:
        loam.Scene.from_file(bad)
    check = subprocess.run(
        [str(loam_binary), "check", str(bad)], capture_output=True, text=True, check=False
    )
    assert check.returncode == 2
    assert check.stderr.strip() == f"error: {err.value}"
