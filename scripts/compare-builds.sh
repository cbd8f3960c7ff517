#!/usr/bin/env bash
# Two hemi builds (or one build under two environments) on the same peer scenes, run after run
# in alternating order, so that a slow spell of a shared machine hits both alike; prints each
# one's medians (AO kernel, AO queries and trace Mrays/s, frame seconds, from --stats-json),
# B's ratios to A, and the range of B ÷ A's kernel ratio over the rounds.
#
#   scripts/compare-builds.sh [--spp N] [--threads N] [--rounds N] A B [SCENE ...]   (default: all five)
#
# A and B are hemi binaries (copy one aside before rebuilding; each is timed from a fresh copy,
# scripts/fresh-copy.sh), each optionally preceded by comma-separated environment settings:
# 'HEMI_NO_AVX512=1,target/release/hemi'. Defaults: 64 spp, 2 threads, 6 rounds. On this
# project's VM a median moves by ±5 % between runs of 4–8 rounds: read smaller differences as
# none.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
scenes_dir="$root/../shared/peers/scenes"
spp=64
threads=2
rounds=6
args=()
while [ $# -gt 0 ]; do
    case "$1" in
        --spp) spp="$2"; shift 2 ;;
        --threads) threads="$2"; shift 2 ;;
        --rounds) rounds="$2"; shift 2 ;;
        -h|--help) sed -n '2,13p' "$0"; exit 0 ;;
        *) args+=("$1"); shift ;;
    esac
done
[ ${#args[@]} -ge 2 ] || { echo "compare-builds: want two builds, A and B (see --help)" >&2; exit 2; }
for n in "$spp" "$threads" "$rounds"; do
    [[ "$n" =~ ^[1-9][0-9]*$ ]] || { echo "compare-builds: '$n' is not a positive whole number" >&2; exit 2; }
done
[ -d "$scenes_dir" ] || { echo "compare-builds: $scenes_dir not found (../shared must sit beside the repo)" >&2; exit 1; }

python3 - "$scenes_dir" "$spp" "$threads" "$rounds" "${args[@]}" <<'PY'
import json, os, statistics, subprocess, sys, tempfile

scenes_dir, spp, threads, rounds, a, b, *scenes = sys.argv[1:]
scenes = scenes or ["sphere_plane", "cornell", "many_spheres", "dragon", "sponza"]

# Removed, with the copies and what the runs wrote, when the script ends.
scratch = tempfile.TemporaryDirectory()
copies = os.path.join(scratch.name, "builds")
os.mkdir(copies)

def build(spec, name):
    *env, binary = spec.split(",")
    settings = dict(e.split("=", 1) for e in env)
    if not os.access(binary, os.X_OK):
        sys.exit(f"compare-builds: {binary} is not an executable hemi binary")
    # Timed from a fresh copy, as scripts/fresh-copy.sh explains.
    copy = os.path.join(copies, name)
    subprocess.run(["cp", binary, copy], check=True)
    return copy, settings

builds = {"A": build(a, "A"), "B": build(b, "B")}
for s in scenes:
    if not os.path.isfile(f"{scenes_dir}/{s}.json"):
        sys.exit(f"compare-builds: no scene {s} in {scenes_dir}")
out = os.path.join(scratch.name, "runs")
os.mkdir(out)
keys = ["ao_kernel_mrays_per_s", "ao_query_mrays_per_s", "ao_mrays_per_s", "seconds"]
runs = {}
for r in range(int(rounds)):
    for s in scenes:
        for name in ("A", "B") if r % 2 == 0 else ("B", "A"):
            binary, settings = builds[name]
            stats = f"{out}/{name}.json"
            cmd = [binary, "render", f"{scenes_dir}/{s}.json", "--spp", spp, "--threads", threads,
                   "--out", f"{out}/{name}.png", "--stats-json", stats]
            done = subprocess.run(cmd, env={**os.environ, **settings}, stdout=subprocess.DEVNULL,
                                  stderr=subprocess.PIPE, text=True)
            if done.returncode != 0:
                sys.exit(f"compare-builds: {name} failed on {s}: {done.stderr.strip().splitlines()[-1:]}")
            total = json.load(open(stats))["total"]
            runs.setdefault((s, name), []).append([total[k] for k in keys])

print(f"{rounds} alternating rounds at {spp} spp, {threads} threads; medians, B / A in brackets")
print(f"{'scene':13s} {'':2s} {'kernel':>15s} {'queries':>16s} {'trace':>15s} {'frame s':>15s}   B/A kernel by round")
for s in scenes:
    med = {n: [statistics.median(c) for c in zip(*runs[(s, n)])] for n in ("A", "B")}
    for n in ("A", "B"):
        cells = [f"{v:7.2f} ({v / base:.3f})" for v, base in zip(med[n][:3], med["A"][:3])]
        cells.append(f"{med[n][3]:7.3f} ({med[n][3] / med['A'][3]:.3f})")
        ratios = ""
        if n == "B":
            by_round = sorted(b[0] / a[0] for a, b in zip(runs[(s, "A")], runs[(s, "B")]))
            ratios = f"{by_round[0]:.3f}-{by_round[-1]:.3f}"
        print(f"{s:13s} {n:2s} {cells[0]:>15s} {cells[1]:>16s} {cells[2]:>15s} {cells[3]:>15s}   {ratios}".rstrip())
PY
