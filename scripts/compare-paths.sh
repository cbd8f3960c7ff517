#!/usr/bin/env bash
# The peer-contract path against the paths users take, on the same peer scene, spp and camera:
# progressive frames, a sample count that is not a power of two, another sampler, AOVs on,
# adaptive sampling, and (where the scene is one mesh with unbounded AO) the mesh rendered as a
# glTF file (jittered pixels, the glTF occluder) with the peer camera given on the command line.
# Runs alternate round by round; prints each path's medians of the AO kernel rate and of all
# rays over the trace stage (Mrays/s, from --stats-json), and their ratios to the peer path,
# and the trace stage's time (ms) with the peer path's time over it.
#
#   scripts/compare-paths.sh [--spp N] [--threads N] [--rounds N] [BINARY] [SCENE ...]
#
# Defaults: 64 spp, 2 threads, 3 rounds, target/release/hemi, all five peer scenes.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
scenes_dir="$root/../shared/peers/scenes"
spp=64
threads=2
rounds=3
binary="$root/target/release/hemi"
scenes=()
while [ $# -gt 0 ]; do
    case "$1" in
        --spp) spp="$2"; shift 2 ;;
        --threads) threads="$2"; shift 2 ;;
        --rounds) rounds="$2"; shift 2 ;;
        -h|--help) sed -n '2,11p' "$0"; exit 0 ;;
        */*|hemi) binary="$1"; shift ;;
        *) scenes+=("$1"); shift ;;
    esac
done
for n in "$spp" "$threads" "$rounds"; do
    [[ "$n" =~ ^[1-9][0-9]*$ ]] || { echo "compare-paths: '$n' is not a positive whole number" >&2; exit 2; }
done
[ -x "$binary" ] || { echo "compare-paths: $binary is not an executable hemi binary" >&2; exit 1; }
[ -d "$scenes_dir" ] || { echo "compare-paths: $scenes_dir not found (../shared must sit beside the repo)" >&2; exit 1; }
copies="$(mktemp -d)"
trap 'rm -rf "$copies"' EXIT
. "$root/scripts/fresh-copy.sh"
binary="$(fresh_copy "$binary" "$copies")"

python3 - "$scenes_dir" "$spp" "$threads" "$rounds" "$binary" "${scenes[@]}" <<'PY'
import json, statistics, subprocess, sys, tempfile

scenes_dir, spp, threads, rounds, binary, *scenes = sys.argv[1:]
scenes = scenes or ["sphere_plane", "cornell", "many_spheres", "dragon", "sponza"]
n = int(spp)

def paths(scene):
    peer = json.load(open(f"{scenes_dir}/{scene}.json"))
    cam = peer["camera"]
    vec = lambda v: ",".join(repr(float(x)) for x in v)
    glb = [f"{scenes_dir}/{peer['mesh']}" if isinstance(peer["mesh"], str) else "", "--look-from", vec(cam["eye"]), "--look-at", vec(cam["target"]),
           "--up", vec(cam["up"]), "--fov", repr(float(cam["vfov_deg"])), "--size", f"{peer['width']}x{peer['height']}"]
    js = [f"{scenes_dir}/{scene}.json"]
    variants = {
        "peer": js + ["--spp", spp],
        "progressive": js + ["--spp", spp, "--spf", str(max(1, n // 4))],
        f"{n * 3 // 4} spp": js + ["--spp", str(max(1, n * 3 // 4))],
        "zsobol": js + ["--spp", spp, "--sampler", "zsobol"],
        "aov": js + ["--spp", spp, "--aov", "ao,direct,albedo,normal,depth"],
        "adaptive": js + ["--spp", spp, "--target-error", "0.002"],
    }
    # The glTF occluder reaches to infinity: only scenes whose own AO does are comparable.
    if isinstance(peer["mesh"], str) and peer["ao"].get("max_distance") is None:
        variants["glTF"] = glb + ["--spp", spp]
    return variants

# Removed, with what the runs wrote there, when the script ends.
scratch = tempfile.TemporaryDirectory()
out = scratch.name
runs = {}
for r in range(int(rounds)):
    for s in scenes:
        items = list(paths(s).items())
        for name, args in items if r % 2 == 0 else reversed(items):
            stats = f"{out}/stats.json"
            cmd = [binary, "render", *args, "--threads", threads, "--out", f"{out}/image.exr", "--stats-json", stats]
            done = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
            if done.returncode != 0:
                sys.exit(f"compare-paths: {name} failed on {s}: {done.stderr.strip().splitlines()[-1:]}")
            total = json.load(open(stats))["total"]
            runs.setdefault((s, name), []).append(
                (total["ao_kernel_mrays_per_s"], total["mrays_per_s"], 1000 * total["trace_seconds"]))

print(f"{rounds} alternating rounds at {spp} spp, {threads} threads; medians in Mrays/s, ratio to the peer path in brackets")
print(f"{'scene':13s} {'path':12s} {'AO kernel':>16s} {'all rays / trace':>18s} {'trace ms':>16s}")
for s in scenes:
    base = [statistics.median(c) for c in zip(*runs[(s, "peer")])]
    for name in paths(s):
        med = [statistics.median(c) for c in zip(*runs[(s, name)])]
        cells = [f"{v:7.2f} ({v / b:.2f})" for v, b in zip(med[:2], base[:2])]
        cells.append(f"{med[2]:7.1f} ({base[2] / med[2]:.2f})")
        print(f"{s:13s} {name:12s} {cells[0]:>16s} {cells[1]:>18s} {cells[2]:>16s}")
PY
