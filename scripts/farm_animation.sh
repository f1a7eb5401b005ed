#!/usr/bin/env bash
# Renders an animation with several `blender -b` processes in parallel on one
# output folder, the way farm workers share a shot: each process renders the
# whole range with Blender's placeholder and no-overwrite options
# (scene.render.use_placeholder = True, use_overwrite = False), so a frame whose
# file (or another worker's empty placeholder) exists is skipped.
#
#   scripts/farm_animation.sh FILE.blend OUTDIR [-s START] [-e END] [-w WORKERS]
#                             [--size WxH] [--samples N] [--addon DIR] [--stagger SECONDS]
#
# Frames are written as OUTDIR/frame_####.<ext> in the file's output format.
# With --addon DIR the workers start with --factory-startup and register DIR's
# add-on (one installed in the user preferences is not loaded).
# Exit status 0 only when every worker exited 0, no worker printed a Python
# traceback, and every frame START..END exists as a non-empty file; empty
# placeholders left by a failed worker are removed (so a rerun renders them)
# and reported. Worker logs: OUTDIR/.farm_logs/worker_N.log.
set -uo pipefail
BLENDER=${BLENDER:-blender}
usage() { sed -n '2,16s/^# \{0,1\}//p' "$0"; exit 2; }
[ $# -ge 2 ] || usage
blend=$(realpath "$1"); out=$(realpath -m "$2"); shift 2
start="" end="" workers=2 size="" samples="" addon="" stagger=0.5
while [ $# -gt 0 ]; do
  case $1 in
    -s) start=$2; shift 2 ;;
    -e) end=$2; shift 2 ;;
    -w) workers=$2; shift 2 ;;
    --size) size=$2; shift 2 ;;
    --samples) samples=$2; shift 2 ;;
    --addon) addon=$(realpath "$2"); shift 2 ;;
    --stagger) stagger=$2; shift 2 ;;
    *) usage ;;
  esac
done
mkdir -p "$out/.farm_logs"

# Settings applied in each worker before -a (options are processed in order).
setup="
import bpy, sys
addon = '$addon'
if addon:
    sys.path.insert(0, addon)
    import tessera
    if not hasattr(bpy.types.Scene, 'tessera'):
        tessera.register()
scene = bpy.context.scene
r = scene.render
r.engine = 'TESSERA'
r.use_placeholder = True
r.use_overwrite = False
size = '$size'
if size:
    r.resolution_x, r.resolution_y = (int(v) for v in size.lower().split('x'))
    r.resolution_percentage = 100
if '$samples':
    scene.tessera.samples = int('${samples:-0}')
if '$start':
    scene.frame_start = int('${start:-0}')
if '$end':
    scene.frame_end = int('${end:-0}')
print('FARM_RANGE', scene.frame_start, scene.frame_end, r.image_settings.file_format, flush=True)
"

# With --addon, the workers skip the user preferences: an add-on enabled there
# (another Tessera, or a dangling link to one) would otherwise be loaded
# instead of --addon's, or fail the worker with its traceback.
prefs=()
[ -n "$addon" ] && prefs=(--factory-startup)
pids=()
for ((i = 0; i < workers; i++)); do
  ((i > 0)) && sleep "$stagger"  # workers that start together race for the first frame's placeholder
  "$BLENDER" -b "${prefs[@]}" "$blend" --python-expr "$setup" -E TESSERA -o "$out/frame_####" -a \
    >"$out/.farm_logs/worker_$i.log" 2>&1 &
  pids+=($!)
done
status=0
for i in "${!pids[@]}"; do
  if ! wait "${pids[$i]}"; then
    echo "farm: worker $i exited non-zero; see $out/.farm_logs/worker_$i.log" >&2; status=1
  fi
  # An exception escaping a RenderEngine leaves Blender's exit status 0 (and a black frame).
  if grep -q -e "Traceback (most recent call last)" "$out/.farm_logs/worker_$i.log"; then
    echo "farm: worker $i printed a Python traceback:" >&2
    grep -A 12 "Traceback (most recent call last)" "$out/.farm_logs/worker_$i.log" | head -n 14 >&2; status=1
  fi
done

read -r _ first last _ < <(grep -h '^FARM_RANGE' "$out"/.farm_logs/worker_*.log | head -n 1)
[ -n "${first:-}" ] || { echo "farm: no worker read the scene" >&2; exit 1; }
missing=()
for ((f = first; f <= last; f++)); do
  files=("$out"/frame_$(printf '%04d' "$f").*)
  if [ ! -e "${files[0]}" ]; then
    missing+=("$f")
  elif [ ! -s "${files[0]}" ]; then
    rm -f "${files[0]}"; missing+=("$f")  # a placeholder a failed worker left behind
  fi
done
if ((${#missing[@]})); then
  echo "farm: frames not rendered: ${missing[*]} (rerun to render them)" >&2; status=1
fi
rendered=$(grep -h "^Saved:" "$out"/.farm_logs/worker_*.log | wc -l)
echo "farm: frames $first..$last in $out, $workers workers, $rendered renders saved" \
     "($(for l in "$out"/.farm_logs/worker_*.log; do grep -c '^Saved:' "$l"; done | paste -sd/))"
exit $status
