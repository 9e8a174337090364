"""The friction gradient of examples/inverse/friction.toml from Python, next to the
`loam gradient` program's (`target/release/loam`, or the program LOAM_BIN names, when it is
built): the same code, so the same bits.

    python python/examples/friction_gradient.py
"""

from __future__ import annotations

import json
import os
import subprocess
import tempfile
from pathlib import Path

import loam

REPO = Path(__file__).resolve().parents[2]
FILE = REPO / "examples" / "inverse" / "friction.toml"


def main() -> None:
    g = loam.gradient(FILE)
    print(f"L = {g['loss']:.12e}")
    program = Path(os.environ.get("LOAM_BIN", REPO / "target" / "release" / "loam"))
    cli = None
    if program.is_file():
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "gradient.json"
            subprocess.run(
                [str(program), "gradient", str(FILE), "--json", str(out)],
                check=True,
                capture_output=True,
            )
            cli = json.loads(out.read_text())["gradient"]
    for k, name in enumerate(g["names"]):
        line = f"{name:12s} mu = {g['theta'][k]:.6f}  dL/dmu = {g['gradient'][k]:.15e}"
        if cli is not None:
            rel = abs(g["gradient"][k] - cli[k]) / abs(cli[k])
            line += f"  (loam gradient: {cli[k]:.15e}, relative difference {rel:.1e})"
        print(line)


if __name__ == "__main__":
    main()
