#!/usr/bin/env bash
# What one ambient-occlusion ray costs in each of some hemi builds, measured so that a shared,
# busy machine does not move the figures: cachegrind's instructions, L1 data misses and misses of
# a simulated 1 MiB 8-way L2 (Zen 4's), exact and repeatable; and with --cpu N, CPU time per ray
# (task-clock of one thread, median of N alternating rounds), which other processes' load moves
# far less than wall time. Each figure is the difference between a render at --spp and one at a
# quarter of it (loading, the build, camera rays and set-up cancel) over the difference in AO
# rays, on one thread. Under valgrind the CPU shows no AVX-512, so its counts are of the AVX2
# kernels (eight-ray packets).
#
#   scripts/ray-costs.sh [--spp N] [--size WxH] [--cpu ROUNDS] BUILD [BUILD ...] [SCENE ...]
#
# A BUILD is a hemi binary, optionally preceded by comma-separated environment settings
# ('HEMI_NO_AVX512=1,target/release/hemi'); anything else is a peer-scene name. Defaults: 64 spp,
# 128x128 for cachegrind (CPU time at the scene's own size), the scenes many_spheres and dragon.
# Needs valgrind, and perf for --cpu.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
scenes_dir="$root/../shared/peers/scenes"
spp=64
size=128x128
cpu=0
args=()
while [ $# -gt 0 ]; do
    case "$1" in
        --spp) spp="$2"; shift 2 ;;
        --size) size="$2"; shift 2 ;;
        --cpu) cpu="$2"; shift 2 ;;
        -h|--help) sed -n '2,16p' "$0"; exit 0 ;;
        *) args+=("$1"); shift ;;
    esac
done
[[ "$spp" =~ ^[1-9][0-9]*$ ]] && [ "$spp" -ge 4 ] || { echo "ray-costs: --spp wants a whole number of at least 4" >&2; exit 2; }
[[ "$cpu" =~ ^[0-9]+$ ]] || { echo "ray-costs: --cpu wants a whole number of rounds" >&2; exit 2; }
[[ "$size" =~ ^[1-9][0-9]*x[1-9][0-9]*$ ]] || { echo "ray-costs: --size wants WxH" >&2; exit 2; }
[ ${#args[@]} -ge 1 ] || { echo "ray-costs: want at least one build (see --help)" >&2; exit 2; }
command -v valgrind >/dev/null || { echo "ray-costs: valgrind not found" >&2; exit 1; }
[ "$cpu" = 0 ] || command -v perf >/dev/null || { echo "ray-costs: perf not found (needed for --cpu)" >&2; exit 1; }
[ -d "$scenes_dir" ] || { echo "ray-costs: $scenes_dir not found (../shared must sit beside the repo)" >&2; exit 1; }

python3 - "$scenes_dir" "$spp" "$size" "$cpu" "${args[@]}" <<'PY'
import json, os, statistics, subprocess, sys, tempfile

scenes_dir, spp, size, cpu, *args = sys.argv[1:]
spp, cpu = int(spp), int(cpu)
low = spp // 4
builds, scenes = [], []
for a in args:
    *env, binary = a.split(",")
    if os.path.isfile(binary) and os.access(binary, os.X_OK):
        builds.append((a, binary, dict(e.split("=", 1) for e in env)))
    elif os.path.isfile(f"{scenes_dir}/{a}.json"):
        scenes.append(a)
    else:
        sys.exit(f"ray-costs: '{a}' is neither an executable hemi binary nor a scene in {scenes_dir}")
if not builds:
    sys.exit("ray-costs: want at least one build (see --help)")
scenes = scenes or ["many_spheres", "dragon"]
out = tempfile.mkdtemp()

def render(build, scene, samples, prefix, extra):
    """Runs `prefix` + a one-thread render; returns its AO rays (from --stats-json)."""
    name, binary, env = build
    stats = f"{out}/stats.json"
    cmd = prefix + [binary, "render", f"{scenes_dir}/{scene}.json", "--spp", str(samples), "--threads", "1",
                    "--out", f"{out}/image.png", "--stats-json", stats] + extra
    done = subprocess.run(cmd, env={**os.environ, **env}, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if done.returncode != 0:
        sys.exit(f"ray-costs: {name} failed on {scene}: {done.stderr.strip().splitlines()[-1:]}")
    return json.load(open(stats))["total"]["rays"]["ao"]

def cachegrind(build, scene, samples):
    """Totals of the cachegrind events of one render, and its AO rays."""
    data = f"{out}/cachegrind.out"
    prefix = ["valgrind", "--tool=cachegrind", "--cache-sim=yes", "--D1=32768,8,64", "--LL=1048576,8,64",
              f"--cachegrind-out-file={data}"]
    rays = render(build, scene, samples, prefix, ["--size", size])
    events = summary = None
    for line in open(data):
        if line.startswith("events:"):
            events = line.split()[1:]
        elif line.startswith("summary:"):
            summary = [int(v) for v in line.split()[1:]]
    return dict(zip(events, summary)), rays

def cpu_ms(build, scene, samples):
    """Task-clock milliseconds of one render, and its AO rays."""
    clock = f"{out}/clock.csv"
    rays = render(build, scene, samples, ["perf", "stat", "-x,", "-e", "task-clock", "-o", clock, "--"], [])
    ms = next(float(l.split(",")[0]) for l in open(clock) if "task-clock" in l)
    return ms, rays

def more_rays(scene, hi, lo):
    """The AO rays the render at `spp` traced beyond the one at `low`."""
    if hi <= lo:
        sys.exit(f"ray-costs: {scene} traces no more AO rays at {spp} spp than at {low}")
    return hi - lo

print(f"per AO ray, {spp} spp less {low} spp, one thread; cachegrind at {size} (AVX2 kernels),"
      + (f" CPU time at the scene's size, median of {cpu} rounds" if cpu else ""))
print(f"{'scene':13s} {'build':30s} {'instructions':>12s} {'L1d misses':>10s} {'L2 misses':>9s}" + (f" {'CPU ns':>8s}" if cpu else ""))
for scene in scenes:
    ns = {}
    for r in range(cpu):
        for b in builds if r % 2 == 0 else builds[::-1]:
            (hi, hi_rays), (lo, lo_rays) = cpu_ms(b, scene, spp), cpu_ms(b, scene, low)
            ns.setdefault(b[0], []).append((hi - lo) * 1e6 / more_rays(scene, hi_rays, lo_rays))
    for b in builds:
        (hi, hi_rays), (lo, lo_rays) = cachegrind(b, scene, spp), cachegrind(b, scene, low)
        rays = more_rays(scene, hi_rays, lo_rays)
        per = lambda *keys: sum(hi[k] - lo[k] for k in keys) / rays
        row = f"{scene:13s} {b[0][-30:]:30s} {per('Ir'):12.1f} {per('D1mr', 'D1mw'):10.2f} {per('DLmr', 'DLmw'):9.3f}"
        if cpu:
            row += f" {statistics.median(ns[b[0]]):8.1f}"
        print(row)
PY
