#!/usr/bin/env bash
# What one ambient-occlusion ray costs in each of some hemi builds and in native Embree 3,
# measured so that a shared, busy machine does not move the figures: cachegrind's instructions, L1
# data misses, misses of a simulated last level (Zen 4's 1 MiB 8-way L2; --llc MIB simulates a
# 16-way L3 of that size instead, whose misses go to memory) and mispredicted conditional branches
# of its simple branch predictor, exact and repeatable; and with
# --cpu N, CPU time per ray (task-clock of one thread, median of N alternating rounds), which
# other processes' load moves far less than wall time. Each figure is the difference between a
# render at --spp and one at a quarter of it (loading, the build, camera rays and set-up cancel)
# over the difference in AO rays, on one thread. Under valgrind the CPU shows no AVX-512, so its
# counts are of the AVX2 kernels (eight-ray packets).
#
#   scripts/ray-costs.sh [--spp N] [--size WxH] [--llc MIB] [--cpu ROUNDS] [--split N] BUILD [BUILD ...] [SCENE ...]
#
# A BUILD is a hemi binary, optionally preceded by comma-separated environment settings
# ('HEMI_NO_AVX512=1,target/release/hemi'), or 'native': native Embree 3's bench
# (../shared/peers/native, built by scripts/native-embree.sh) in its stream mode, its best on the
# deep meshes, or in the modes after a colon ('native:--robust --stream'), with its AVX2 build
# under cachegrind (valgrind runs no AVX-512) and where HEMI_NO_AVX512=1 precedes it. Anything
# else is a peer-scene name. Defaults: 64 spp, 128x128 for cachegrind (CPU time at the scene's own
# size), the scenes many_spheres and dragon. --split N also lists, under each hemi build's row,
# the N functions with the most instructions per AO ray, their last-level misses and
# mispredicts, each kernel named by the kernel it compiles (SceneLanes: the top level's packets;
# InstanceLanes: packets within an instance; PacketsBlock: a lone ray's leaf; OnTree: a lone ray
# entering a BLAS). Needs valgrind, binutils, and perf for --cpu.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
scenes_dir="$root/../shared/peers/scenes"
spp=64
size=128x128
cpu=0
split=0
llc=1
args=()
while [ $# -gt 0 ]; do
    case "$1" in
        --spp) spp="$2"; shift 2 ;;
        --size) size="$2"; shift 2 ;;
        --cpu) cpu="$2"; shift 2 ;;
        --split) split="$2"; shift 2 ;;
        --llc) llc="$2"; shift 2 ;;
        -h|--help) sed -n '2,25p' "$0"; exit 0 ;;
        *) args+=("$1"); shift ;;
    esac
done
[[ "$spp" =~ ^[1-9][0-9]*$ ]] && [ "$spp" -ge 4 ] || { echo "ray-costs: --spp wants a whole number of at least 4" >&2; exit 2; }
[[ "$cpu" =~ ^[0-9]+$ ]] || { echo "ray-costs: --cpu wants a whole number of rounds" >&2; exit 2; }
[[ "$split" =~ ^[0-9]+$ ]] || { echo "ray-costs: --split wants a whole number of functions" >&2; exit 2; }
[[ "$size" =~ ^[1-9][0-9]*x[1-9][0-9]*$ ]] || { echo "ray-costs: --size wants WxH" >&2; exit 2; }
[[ "$llc" =~ ^(1|2|4|8|16|32|64|128)$ ]] || { echo "ray-costs: --llc wants MiB, a power of two from 1 to 128" >&2; exit 2; }
[ ${#args[@]} -ge 1 ] || { echo "ray-costs: want at least one build (see --help)" >&2; exit 2; }
command -v valgrind >/dev/null || { echo "ray-costs: valgrind not found" >&2; exit 1; }
[ "$cpu" = 0 ] || command -v perf >/dev/null || { echo "ray-costs: perf not found (needed for --cpu)" >&2; exit 1; }
[ -d "$scenes_dir" ] || { echo "ray-costs: $scenes_dir not found (../shared must sit beside the repo)" >&2; exit 1; }

python3 - "$root" "$spp" "$size" "$cpu" "$split" "$llc" "${args[@]}" <<'PY'
import collections, functools, json, os, re, statistics, subprocess, sys, tempfile

root, spp, size, cpu, split, llc, *args = sys.argv[1:]
scenes_dir = f"{root}/../shared/peers/scenes"
spp, cpu, split, llc = int(spp), int(cpu), int(split), int(llc)
# The simulated last level: Zen 4's L2 (8-way) by default, else an L3 (16-way).
last_level = f"{llc << 20},{8 if llc == 1 else 16},64"
missed = "L2 misses" if llc == 1 else "L3 misses"
low = spp // 4
builds, scenes = [], []
for a in args:
    *env, binary = a.split(",")
    env = dict(e.split("=", 1) for e in env)
    if binary == "native" or binary.startswith("native:"):
        builds.append((a, binary, env, (binary.partition(":")[2] or "--stream").split()))
    elif os.path.isfile(binary) and os.access(binary, os.X_OK):
        builds.append((a, binary, env, None))
    elif os.path.isfile(f"{scenes_dir}/{a}.json"):
        scenes.append(a)
    else:
        sys.exit(f"ray-costs: '{a}' is neither an executable hemi binary, 'native', nor a scene in {scenes_dir}")
if not builds:
    sys.exit("ray-costs: want at least one build (see --help)")
scenes = scenes or ["many_spheres", "dragon"]
# Removed, with what the runs wrote there, when the script ends.
scratch = tempfile.TemporaryDirectory()
out = scratch.name

@functools.cache
def native_bench(scene, avx2, wh):
    """The native bench (its AVX2 build where `avx2`) and peer scene `scene` exported for it (at
    size `wh`, WxH, where given), each made on first use by native-embree.sh."""
    script = (f'peers_src="{root}/../shared/peers"; source "{root}/scripts/native-embree.sh"; '
              'echo "$native_bench"; native_scene "$1" $2 $3')
    width, height = wh.split("x") if wh else ("", "")
    env = {**os.environ, "HEMI_NO_AVX512": "1" if avx2 else ""}
    done = subprocess.run(["bash", "-c", script, "native", scene, width, height], env=env, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"ray-costs: the native bench failed to build or export {scene}: {done.stderr.strip()}")
    return tuple(done.stdout.split())

def render(build, scene, samples, prefix, extra, wh=None):
    """Runs `prefix` + a one-thread render (at size `wh`, WxH, where given, and with the
    native bench's AVX2 build then); returns its AO rays (from --stats-json, or the native
    bench's JSON line)."""
    name, binary, env, native_modes = build
    if native_modes is not None:
        bench, aoscene = native_bench(scene, wh is not None or env.get("HEMI_NO_AVX512") == "1", wh)
        cmd = prefix + [bench, aoscene, "--spp", str(samples), "--threads", "1", "--build-threads", "1",
                        "--repeat", "1"] + native_modes
        done = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        if done.returncode != 0:
            sys.exit(f"ray-costs: {name} failed on {scene}: {done.stderr.strip().splitlines()[-1:]}")
        return json.loads(done.stdout.strip().splitlines()[-1])["ao_rays"]
    stats = f"{out}/stats.json"
    cmd = prefix + [binary, "render", f"{scenes_dir}/{scene}.json", "--spp", str(samples), "--threads", "1",
                    "--out", f"{out}/image.png", "--stats-json", stats] + extra
    done = subprocess.run(cmd, env={**os.environ, **env}, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if done.returncode != 0:
        sys.exit(f"ray-costs: {name} failed on {scene}: {done.stderr.strip().splitlines()[-1:]}")
    return json.load(open(stats))["total"]["rays"]["ao"]

def cachegrind(build, scene, samples):
    """Totals of the cachegrind events of one render, its instructions, L2 misses and mispredicts
    by function (mangled names, which tell apart the copies of one generic function), and its AO
    rays."""
    data = f"{out}/cachegrind.out"
    prefix = ["valgrind", "--tool=cachegrind", "--cache-sim=yes", "--D1=32768,8,64", f"--LL={last_level}",
              "--branch-sim=yes", "--demangle=no", f"--cachegrind-out-file={data}"]
    rays = render(build, scene, samples, prefix, ["--size", size], size)
    events = summary = function = None
    by_function = collections.defaultdict(lambda: [0, 0, 0])
    for line in open(data):
        if line.startswith("events:"):
            events = line.split()[1:]
        elif line.startswith("summary:"):
            summary = [int(v) for v in line.split()[1:]]
        elif line.startswith("fn="):
            function = line[3:].strip()
        elif function and line[:1].isdigit():
            counts = dict(zip(events, map(int, line.split()[1:])))
            by_function[function][0] += counts.get("Ir", 0)
            by_function[function][1] += counts.get("DLmr", 0) + counts.get("DLmw", 0)
            by_function[function][2] += counts.get("Bcm", 0)
    return dict(zip(events, summary)), by_function, rays

@functools.cache
def symbols(binary):
    """`nm -S`'s lines for `binary`, read once."""
    return subprocess.run(["nm", "-S", binary], capture_output=True, text=True).stdout.splitlines()

def function_label(binary, mangled):
    """A readable name for `mangled` in `binary`: for a kernel compiled per instruction set
    (`compiled_v3`, …, all one name once demangled), the kernel type it compiles, read from
    the inlined frames at points inside it."""
    name = subprocess.run(["c++filt"], input=mangled, capture_output=True, text=True).stdout.strip()
    name = re.sub(r"::h[0-9a-f]{16}$", "", name)
    if "compiled" not in name:
        return name
    found = next((l.split() for l in symbols(binary) if l.endswith(" " + mangled)), None)
    if not found:
        return name
    start, length = int(found[0], 16), int(found[1], 16)
    for at in (start + length * k // 8 for k in range(1, 8)):
        frames = subprocess.run(["addr2line", "-f", "-i", "-C", "-e", binary, hex(at)],
                                capture_output=True, text=True).stdout
        kernels = re.findall(r"compiled\w*<([\w:]+)", frames)
        if kernels:
            return f"{name.split('::')[-1]}<{kernels[-1].split('::')[-1]}>"
    return name

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

print(f"per AO ray, {spp} spp less {low} spp, one thread; cachegrind at {size} (AVX2 kernels, {llc} MiB last level),"
      + (f" CPU time at the scene's size, median of {cpu} rounds" if cpu else ""))
print(f"{'scene':13s} {'build':30s} {'instructions':>12s} {'L1d misses':>10s} {missed:>9s} {'mispredicts':>11s}"
      + (f" {'CPU ns':>8s}" if cpu else ""))
for scene in scenes:
    ns = {}
    for r in range(cpu):
        for b in builds if r % 2 == 0 else builds[::-1]:
            (hi, hi_rays), (lo, lo_rays) = cpu_ms(b, scene, spp), cpu_ms(b, scene, low)
            ns.setdefault(b[0], []).append((hi - lo) * 1e6 / more_rays(scene, hi_rays, lo_rays))
    for b in builds:
        (hi, hi_fns, hi_rays), (lo, lo_fns, lo_rays) = cachegrind(b, scene, spp), cachegrind(b, scene, low)
        rays = more_rays(scene, hi_rays, lo_rays)
        per = lambda *keys: sum(hi[k] - lo[k] for k in keys) / rays
        row = (f"{scene:13s} {b[0][-30:]:30s} {per('Ir'):12.1f} {per('D1mr', 'D1mw'):10.2f} {per('DLmr', 'DLmw'):9.3f}"
               f" {per('Bcm'):11.2f}")
        if cpu:
            row += f" {statistics.median(ns[b[0]]):8.1f}"
        print(row)
        if split and b[3] is None:
            more = {f: [h - l for h, l in zip(c, lo_fns.get(f, [0, 0, 0]))] for f, c in hi_fns.items()}
            for mangled, (ir, l2, bcm) in sorted(more.items(), key=lambda fc: -fc[1][0])[:split]:
                label = function_label(b[1], mangled)[-44:]
                print(f"{'':13s}   {label:44s} {ir / rays:12.1f} {'':10s} {l2 / rays:9.3f} {bcm / rays:11.2f}")
PY
