#!/usr/bin/env bash
# GeoWarp's Terzaghi script and loam on the same configuration, side by side on this machine
# (docs/performance.md, "Terzaghi's column beside GeoWarp's script"). Run from anywhere:
#
#   benches/peers/geowarp_terzaghi/run.sh [WORK_DIR]      (default /tmp/loam-peers)
#
# It needs Python 3.10+ with pip access to PyPI, and GeoWarp's sources: cloned from GitHub at
# the commit below, or taken from GEOWARP_DIR (a checkout of that commit; the script's SHA-256
# is checked either way). GeoWarp runs unmodified on warp's CPU backend, one thread; its
# kernels are compiled once beforehand (by a one-step copy of the script in a scratch folder)
# so that the timed run measures the solver, not the compiler. loam runs the scene
# examples/consolidation/terzaghi.toml with GeoWarp's 600 steps (end_time 60,000 s) and a
# single frame, with one thread and with two, and once more with a frame per step; error.py
# then compares both pore-pressure fields with Terzaghi's series at GeoWarp's five output
# times, with GeoWarp also run from a copy of its script whose particles start undeformed.
set -euo pipefail

COMMIT=7f854125b074886c0886239d7f339316659e0046
SCRIPT=problems/consolidation/terzaghi_cpGIMP_everything_in_one_script.py
SHA256=ed521016ede214fd05dabead1ce442309080cc25698a1d1aa63ab30627456f1a
HERE=$(cd "$(dirname "$0")" && pwd)
ROOT=$(cd "$HERE/../../.." && pwd)
WORK=${1:-/tmp/loam-peers}
mkdir -p "$WORK"
WORK=$(cd "$WORK" && pwd)

# Python environment with GeoWarp's pinned versions (its requirements.txt; pypardiso unused).
if [ ! -x "$WORK/venv/bin/python" ]; then
    python3 -m venv "$WORK/venv"
    "$WORK/venv/bin/pip" install --quiet numpy==2.2.2 warp-lang==1.7.0 meshio==5.3.5 \
        scipy==1.14.1 pyamg==5.2.1
fi
PY="$WORK/venv/bin/python"

# GeoWarp's sources.
GEOWARP=${GEOWARP_DIR:-$WORK/GeoWarp}
if [ ! -f "$GEOWARP/$SCRIPT" ]; then
    git clone --quiet https://github.com/choo-group/GeoWarp "$GEOWARP"
    git -C "$GEOWARP" checkout --quiet "$COMMIT"
fi
echo "$SHA256  $GEOWARP/$SCRIPT" | sha256sum --check --quiet

# Compile warp's kernels once (a one-step copy), then time the unmodified script.
export OMP_NUM_THREADS=1 WARP_CACHE_PATH="$WORK/warpcache"
rm -rf "$WORK/warmup" "$WORK/geowarp"
mkdir -p "$WORK/warmup" "$WORK/geowarp"
sed 's/^for step in range(600):/for step in range(1):/' "$GEOWARP/$SCRIPT" > "$WORK/warmup/warmup.py"
(cd "$WORK/warmup" && "$PY" warmup.py > log.txt 2>&1)
(cd "$WORK/geowarp" && /usr/bin/time -f "%e s wall, %M KB peak" -o time.txt \
    "$PY" "$GEOWARP/$SCRIPT" > log.txt 2>&1)
echo "GeoWarp, 600 steps, 1 thread: $(cat "$WORK/geowarp/time.txt")"

# The same with the particles starting from F = I: the script starts them from
# F = diag(1 + 1e-7, 1 - 1e-6, 1), an initial strain that moves its pressure errors.
rm -rf "$WORK/geowarp_identity"
mkdir -p "$WORK/geowarp_identity"
sed -e 's/float64_one+ wp.float64(1e-7)/float64_one/' -e 's/float64_one-wp.float64(1e-6)/float64_one/' \
    "$GEOWARP/$SCRIPT" > "$WORK/geowarp_identity/identity.py"
(cd "$WORK/geowarp_identity" && "$PY" identity.py > log.txt 2>&1)

# loam on the same configuration: timed with one frame written (GeoWarp writes one file and
# prints its pressures five times), best of three, then run once more with a frame per step
# for the errors (output does not change the solution).
cargo build --quiet --release --manifest-path "$ROOT/Cargo.toml" -p loam-cli
LOAM="${CARGO_TARGET_DIR:-$ROOT/target}/release/loam"
mkdir -p "$WORK/loam"
scene() {
    sed -e 's/^end_time = .*/end_time = 60000.0/' -e "s/^frames = .*/frames = $1/" \
        -e 's#^dir = .*#dir = "out"#' "$ROOT/examples/consolidation/terzaghi.toml"
}
bdf2() { sed 's/^\[solver.consolidation\]/[solver.consolidation]\nscheme = "bdf2"/'; }
scene 1 > "$WORK/loam/timed.toml"
scene 600 > "$WORK/loam/frames.toml"
scene 1 | bdf2 > "$WORK/loam/timed_bdf2.toml"
scene 600 | bdf2 > "$WORK/loam/frames_bdf2.toml"
geowarp=$(cut -d' ' -f1 "$WORK/geowarp/time.txt")
for scheme in timed timed_bdf2; do
    for threads in 1 2; do
        best=
        for _ in 1 2 3; do
            (cd "$WORK/loam" && /usr/bin/time -f "%e" -o time.txt \
                "$LOAM" --threads "$threads" run "$scheme.toml" --quiet --out timed)
            t=$(cat "$WORK/loam/time.txt")
            best=$(python3 -c "print(min(float('$t'), float('${best:-inf}')))")
        done
        echo "loam ($scheme), 601 steps (the undrained one and 600), $threads thread(s):" \
            "$best s wall (best of 3), $(python3 -c "print(f'{$geowarp / $best:.1f}')")x faster"
    done
done
(cd "$WORK/loam" && "$LOAM" run frames.toml --quiet --out out \
    && "$LOAM" run frames_bdf2.toml --quiet --out out_bdf2)

"$PY" "$HERE/error.py" "$WORK/geowarp" "$WORK/geowarp_identity" "$WORK/loam/out" "$WORK/loam/out_bdf2"
