"""The friction dam break of examples/dambreak_friction.toml, stepped from Python: the
position of the surge front (the largest x of the water particles) at a few times.

Run from the repository root, after `pip install ./python`:

    python python/examples/dambreak_front.py
"""

from __future__ import annotations

from pathlib import Path

import loam

SCENE = Path(__file__).resolve().parents[2] / "examples" / "dambreak_friction.toml"


def main() -> None:
    """Steps the dam break to its end time, printing the front at every 0.05 s."""
    sim = loam.Simulation(loam.Scene.from_file(SCENE))
    print(f"{'t (s)':>8} {'steps':>6} {'front x (m)':>12}")
    for k in range(9):
        sim.advance_to(0.05 * k)
        print(f"{sim.time:8.4f} {sim.steps:6d} {sim.positions[:, 0].max():12.4f}")


if __name__ == "__main__":
    main()
