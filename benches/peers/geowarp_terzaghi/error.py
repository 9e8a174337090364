#!/usr/bin/env python3
"""Pore-pressure error of GeoWarp's and loam's Terzaghi runs against Terzaghi's series.

Usage: error.py GEOWARP_RUN GEOWARP_IDENTITY_RUN LOAM_OUT LOAM_BDF2_OUT

GeoWarp's script (problems/consolidation/terzaghi_cpGIMP_everything_in_one_script.py) prints,
after the solves of its steps 54, 110, 221, 332 and 554, one line "<y> <p> ;" per particle
(current height above the base, pore pressure in kPa, compression positive), then
"Time: <t>"; its only file, terzaghi_particles_0.vtk, holds the initial positions. loam writes
a frame per step (`frames = 600`) with the particles' `pore_pressure` (Pa, compression
positive); frame_0000.vtu is the initial state. Both are compared at GeoWarp's five times with

    p/q = sum_m (2/M) sin(M z/H) exp(-M^2 T_v),   M = pi (2m + 1)/2,   T_v = c_v t / H^2,

z the depth of the particle's initial position below the drained top (the small-strain frame
of the series), H = 10 m, c_v = (k/gamma_w) E_oed = 1e-6 m^2/(kPa s) x 1800 kPa = 1.8e-3 m^2/s,
q = 1 kPa. GeoWarp's error is also given with z from the particles' current positions, and
for a run of a copy of its script whose particles start from F = I instead of the script's
F = diag(1 + 1e-7, 1 - 1e-6, 1); loam's for backward Euler and for BDF2.
"""
import math
import re
import sys
from pathlib import Path

import meshio
import numpy as np

H = 10.0  # m
Q_KPA = 1.0  # kPa
C_V = 1.0e-6 * 1500.0 * 0.75 / (1.25 * 0.5)  # m^2/s: mobility x E_oed


def terzaghi(z, tv):
    """p/q of Terzaghi's series at depths z (m) and time factor tv > 0."""
    terms = max(200, int(math.sqrt(60.0 / tv) / math.pi) + 10)
    m = np.arange(terms, dtype=float)
    big_m = math.pi * (2.0 * m + 1.0) / 2.0
    return np.sin(np.outer(np.asarray(z) / H, big_m)) @ ((2.0 / big_m) * np.exp(-big_m**2 * tv))


def legacy_vtk_heights(path):
    """Heights of the points of a binary legacy VTK file without cells (meshio writes it but
    cannot read it back)."""
    data = Path(path).read_bytes()
    found = re.search(rb"\nPOINTS\s+(\d+)\s+(double|float)\s*\n", data)
    n = int(found.group(1))
    dtype = np.dtype(">f8") if found.group(2) == b"double" else np.dtype(">f4")
    points = np.frombuffer(data, dtype=dtype, count=3 * n, offset=found.end())
    return points.reshape(n, 3)[:, 1].astype(float)


def geowarp_dumps(log):
    """[(t, y_current, p_kPa)] of the pressure dumps in GeoWarp's stdout."""
    dumps, y, p = [], [], []
    for line in Path(log).read_text(errors="replace").splitlines():
        row = re.fullmatch(r"\s*(\S+)\s+(\S+)\s+;\s*", line)
        if row:
            y.append(float(row.group(1)))
            p.append(float(row.group(2)))
        elif line.startswith("Time:") and y:
            dumps.append((float(line.split()[1]), np.array(y), np.array(p)))
            y, p = [], []
    return dumps


def loam_frames(out):
    """{t: frame file} from loam's particles.pvd (the last frame of each time)."""
    pvd = Path(out, "particles.pvd").read_text()
    frames = {}
    for t, file in re.findall(r'timestep="([^"]+)"[^>]*file="([^"]+)"', pvd):
        frames[round(float(t), 6)] = Path(out, file)
    return frames


def max_error(z, p_over_q, tv):
    """The largest |p/q - p_exact/q| over the particles and the depth where it is."""
    err = np.abs(p_over_q - terzaghi(z, tv))
    return err.max(), z[int(err.argmax())]


def loam_errors(out, times):
    """loam's largest error at each time of `times` (s)."""
    frames = loam_frames(out)
    z0 = H - meshio.read(Path(out, "frame_0000.vtu")).points[:, 1]
    errors = []
    for t in times:
        frame = meshio.read(frames[round(t, 6)])
        p = np.ravel(frame.point_data["pore_pressure"]) / (Q_KPA * 1e3)
        errors.append(max_error(z0, p, C_V * t / H**2)[0])
    return errors


def main():
    geowarp, identity, loam_be, loam_bdf2 = sys.argv[1:5]
    y0 = legacy_vtk_heights(Path(geowarp, "terzaghi_particles_0.vtk"))
    dumps = geowarp_dumps(Path(geowarp, "log.txt"))
    from_identity = geowarp_dumps(Path(identity, "log.txt"))
    times = [t for t, _, _ in dumps]
    columns = [
        loam_errors(loam_be, times),
        loam_errors(loam_bdf2, times),
        [max_error(H - y0, p / Q_KPA, C_V * t / H**2)[0] for t, _, p in dumps],
        [max_error(H - y, p / Q_KPA, C_V * t / H**2)[0] for t, y, p in dumps],
        [max_error(H - y0, p / Q_KPA, C_V * t / H**2)[0] for t, _, p in from_identity],
    ]
    print("max |p - p_exact|/q, z from the initial positions unless said otherwise")
    print("T_v      t (s)  loam, BE  loam, BDF2   GeoWarp  GeoWarp (current z)  GeoWarp from F = I")
    for k, t in enumerate(times):
        tv = C_V * t / H**2
        print(f"{tv:.4f} {t:9.0f}" + "".join(f"{c[k]:10.2e}" for c in columns[:3])
              + f"{columns[3][k]:21.2e}{columns[4][k]:20.2e}")


if __name__ == "__main__":
    main()
