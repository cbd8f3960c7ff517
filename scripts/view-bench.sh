#!/usr/bin/env bash
# hemi view in a real (virtual) window: frames per second orbiting the built-in scene (full
# and dynamic resolution) and Sponza, the Fox playing its animation, time from launch to the
# first frame, and input-to-frame latency of a mouse drag sent through the X server
# (xdotool). Prints a markdown table. Needs Xvfb and xdotool (apt-get install xvfb xdotool).
#
#   scripts/view-bench.sh [target/release/hemi] [threads]
set -euo pipefail
cd "$(dirname "$0")/.."
threads=${2:-2}
assets=../shared/assets
out=$(mktemp -d)
. scripts/fresh-copy.sh
hemi=$(fresh_copy "${1:-target/release/hemi}" "$out")
display=:$((90 + RANDOM % 100))
Xvfb "$display" -screen 0 1280x1024x24 >/dev/null 2>&1 &
xvfb=$!
trap 'kill $xvfb 2>/dev/null || true; rm -rf "$out"' EXIT
sleep 1
export DISPLAY=$display

run() { # name, then hemi view arguments
    local name=$1
    shift
    "$hemi" view "$@" --size 640x360 --threads "$threads" --stats-json "$out/$name.json" >/dev/null
}
run builtin-full --turntable 10 --no-dynamic-resolution --quit-after-frames 60
run builtin-dynamic --turntable 10 --quit-after-frames 150
run sponza "$assets/SponzaDabrovic/sponza.gltf" --turntable 10 --quit-after-frames 150
run fox "$assets/Fox/glTF-Binary/Fox.glb" --play --quit-after-frames 150

# Latency: drag the mouse across the window while it converges.
"$hemi" view --size 640x360 --threads "$threads" --quit-after-frames 200 --stats-json "$out/latency.json" &
view=$!
sleep 2
if command -v xdotool >/dev/null; then
    xdotool mousemove 100 100 mousedown 1
    for i in $(seq 1 40); do
        xdotool mousemove $((100 + 4 * i)) 100
        sleep 0.05
    done
    xdotool mouseup 1
fi
wait $view

python3 - "$out" "$threads" <<'PY'
import json, sys, os
out, threads = sys.argv[1], sys.argv[2]
print(f"640x360, {threads} threads, target 33 ms, in Xvfb\n")
print("| case | fps | full-res frames | mean internal res | launch to first frame s | latency ms (mean / max) |")
print("|---|---:|---:|---:|---:|---:|")
for name in ["builtin-full", "builtin-dynamic", "sponza", "fox", "latency"]:
    j = json.load(open(os.path.join(out, name + ".json")))
    f = j["frames"][1:]
    s = j["summary"]
    full = sum(1 for r in f if r["scale"] == 1) / max(len(f), 1)
    w = sum(r["width"] for r in f) / max(len(f), 1)
    h = sum(r["height"] for r in f) / max(len(f), 1)
    lat = "-" if s["mean_latency_ms"] is None else f'{s["mean_latency_ms"]:.0f} / {s["max_latency_ms"]:.0f}'
    print(f'| {name} | {s["mean_fps"]:.1f} | {100 * full:.0f} % | {w:.0f}x{h:.0f} | {s["first_frame_seconds"]:.2f} | {lat} |')
PY
