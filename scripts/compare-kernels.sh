#!/usr/bin/env bash
# hemi's and Embree's occlusion queries on exactly the same AO rays, one thread each, with
# nothing else timed: no sampling, shading or frame (compare-peers.sh times whole renders).
#
#   scripts/compare-kernels.sh [--rays-per-point N] [--rounds N] [--embree3] [SCENE ...]   (default: all five)
#
# For each scene, examples/kernel_rays.rs writes the rays (N per visible point, default 4) and
# times hemi four ways (one ray at a time in point order and shuffled; packets of 16 in point
# order and in sample order); scripts/embree_kernel.c, built against the libembree4 in the peers'
# venv (set up as compare-peers.sh does), traces the same file with rtcOccluded1 and
# rtcOccluded16; with --embree3, against the Embree 3 inside the venv's Mitsuba wheel instead
# (the one Mitsuba's renders use, a faster build than embreex's), at build quality HIGH as
# Mitsuba asks (EMBREE_QUALITY=medium for its default). Rays are as long as the scene's
# ao.max_distance. Both must block the same rays. The two programs alternate --rounds times
# (default 3); printed are each one's median Mrays/s and hemi / Embree.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
peers_src="$root/../shared/peers"
per_point=4
rounds=3
embree3=0
scenes=()
while [ $# -gt 0 ]; do
    case "$1" in
        --rays-per-point) per_point="$2"; shift 2 ;;
        --rounds) rounds="$2"; shift 2 ;;
        --embree3) embree3=1; shift ;;
        -h|--help) sed -n '2,15p' "$0"; exit 0 ;;
        *) scenes+=("$1"); shift ;;
    esac
done
[ ${#scenes[@]} -gt 0 ] || scenes=(sphere_plane cornell many_spheres dragon sponza)
[[ "$rounds" =~ ^[1-9][0-9]*$ ]] || { echo "compare-kernels: --rounds wants a positive whole number, not '$rounds'" >&2; exit 2; }
[ -d "$peers_src" ] || { echo "compare-kernels: $peers_src not found (../shared must sit beside the repo)" >&2; exit 1; }
. "$root/scripts/peers-venv.sh"
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
if [ "$embree3" = 1 ]; then
    mitsuba=$(ls -d "$work"/.venv/lib/python3*/site-packages/mitsuba 2>/dev/null | head -1)
    [ -f "$mitsuba/libembree3.so" ] || { echo "compare-kernels: no libembree3.so in $work/.venv's mitsuba" >&2; exit 1; }
    c++ -O2 -DMITSUBA_EMBREE3 -I"$mitsuba/include" -o "$out/embree_kernel" -x c++ "$root/scripts/embree_kernel.c" -x none \
        "$mitsuba/libembree3.so" -Wl,-rpath,"$mitsuba"
    engine=embree3
else
    lib=$(ls "$work"/.venv/lib/python3*/site-packages/embreex.libs/libembree4*.so* 2>/dev/null | head -1)
    [ -n "$lib" ] || { echo "compare-kernels: no libembree4 in $work/.venv (embreex's wheel ships it)" >&2; exit 1; }
    cc -O2 -o "$out/embree_kernel" "$root/scripts/embree_kernel.c" "$lib" -Wl,-rpath,"$(dirname "$lib")" -lm
    engine=embree
fi
(cd "$root" && cargo build --release -q --example kernel_rays)
for _ in $(seq "$rounds"); do
    for s in "${scenes[@]}"; do
        "$root/target/release/examples/kernel_rays" "$peers_src/scenes/$s.json" "$out/rays.bin" "$per_point" \
            | sed "s/^/$s /" >> "$out/runs.txt"
        "$out/embree_kernel" "$out/rays.bin" | sed "s/^/$s /" >> "$out/runs.txt"
    done
done
python3 - "$out/runs.txt" "$engine" <<'PY'
import re, statistics, sys
ways = ["single", "single shuffled", "packets of 16 (point order)", "packets of 16 (sample order)"]
runs, blocked = {}, {}
for line in open(sys.argv[1]):
    scene, engine, rest = line.split(maxsplit=2)
    hit = re.match(r"\d+ rays, (\d+) blocked", rest).group(1)
    blocked.setdefault(scene, set()).add(hit)
    for way in ways:
        rate = float(re.search(re.escape(way) + r" ([0-9.]+)", rest).group(1))
        runs.setdefault((scene, way), {}).setdefault(engine, []).append(rate)
print(f"Mrays/s, one thread, median of each engine's runs; hemi / {sys.argv[2]} in brackets")
print(f"{'scene':13s} | " + " | ".join(f"{w:29s}" for w in ways))
for scene in dict.fromkeys(s for s, _ in runs):
    if len(blocked[scene]) != 1:
        sys.exit(f"compare-kernels: hemi and embree block different numbers of rays on {scene}: {blocked[scene]}")
    cells = []
    for way in ways:
        h, e = (statistics.median(runs[(scene, way)][k]) for k in ("hemi", sys.argv[2]))
        cells.append(f"{h:6.2f} vs {e:6.2f} ({h / e:4.2f}x)".ljust(29))
    print(f"{scene:13s} | " + " | ".join(cells))
PY
