#!/usr/bin/env bash
# Times two builds of the add-on against each other on one scene: the core's
# render seconds of build B over build A, as a median of paired ratios.
#
#   scripts/compare_builds.sh A_ADDON_DIR B_ADDON_DIR SCENE [--width 160] [--samples 64]
#       [--renders 4] [--rounds 3] [--threads 1]
#
# A_ADDON_DIR, B_ADDON_DIR: folders holding a built `tessera` package (this
# checkout's addon/, or another worktree's after scripts/build.sh there).
# With --threads 1 (default) each round runs A and B at the same time, one
# core each, so that load on the machine falls on both alike, and pairs their
# i-th renders; with --threads 0 (all cores) the builds take turns, the order
# swapped every round, and the medians are compared. Same seed for both, so
# the two render the same samples (the ray counts show whether they trace
# the same rays). Speed claims quote this script's medians, never one timing.
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -ge 3 ] || { sed -n 2,15p "$0"; exit 2; }
A=$1 B=$2 SCENE=$3
shift 3
WIDTH=160 SAMPLES=64 RENDERS=4 ROUNDS=3 THREADS=1
while [ $# -gt 0 ]; do
  case "$1" in
    --width) WIDTH=$2 ;; --samples) SAMPLES=$2 ;; --renders) RENDERS=$2 ;;
    --rounds) ROUNDS=$2 ;; --threads) THREADS=$2 ;;
    *) echo "compare_builds: unknown option $1" >&2; exit 2 ;;
  esac
  shift 2
done
for d in "$A" "$B"; do
  [ -f "$d/tessera/__init__.py" ] || { echo "compare_builds: no tessera add-on in $d (build it with scripts/build.sh)" >&2; exit 1; }
done
BLENDER=${BLENDER:-blender}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
run() {  # build-dir label round
  "$BLENDER" -b --factory-startup --python scripts/time_render.py -- "$1" "$SCENE" --width "$WIDTH" \
    --samples "$SAMPLES" --renders "$RENDERS" --threads "$THREADS" 2>/dev/null | grep '^TIME ' > "$out/$2_$3.txt" || true
}
for r in $(seq "$ROUNDS"); do
  if [ "$THREADS" = 1 ]; then
    run "$A" A "$r" & run "$B" B "$r" & wait
  elif [ $((r % 2)) = 1 ]; then
    run "$A" A "$r"; run "$B" B "$r"
  else
    run "$B" B "$r"; run "$A" A "$r"
  fi
done
python3 - "$out" "$ROUNDS" "$THREADS" <<'PY'
import statistics, sys
out, rounds, threads = sys.argv[1], int(sys.argv[2]), sys.argv[3]
def read(label, r):
    try:
        return [tuple(float(x) for x in l.split()[1:3]) for l in open(f"{out}/{label}_{r}.txt")]
    except OSError:
        return []
a = [read("A", r) for r in range(1, rounds + 1)]
b = [read("B", r) for r in range(1, rounds + 1)]
ta = [t for run in a for t, _ in run]
tb = [t for run in b for t, _ in run]
if not ta or not tb:
    sys.exit("compare_builds: a build rendered nothing (run time_render.py by hand to see why)")
ra = sorted({int(n) for run in a for _, n in run}); rb = sorted({int(n) for run in b for _, n in run})
print(f"A: median {statistics.median(ta):.3f} s ({min(ta):.3f}-{max(ta):.3f}, {len(ta)} renders), rays {ra}")
print(f"B: median {statistics.median(tb):.3f} s ({min(tb):.3f}-{max(tb):.3f}, {len(tb)} renders), rays {rb}")
if threads == "1":
    pairs = [y[0] / x[0] for ra_, rb_ in zip(a, b) for x, y in zip(ra_, rb_)]
    print(f"B/A: median of {len(pairs)} paired ratios {statistics.median(pairs):.4f} ({min(pairs):.3f}-{max(pairs):.3f})")
else:
    print(f"B/A: ratio of medians {statistics.median(tb) / statistics.median(ta):.4f}")
PY
