#!/usr/bin/env bash
# Where a render's occlusion queries spend their time, by the traversal step each sample falls
# in: a sampled profile (perf, cpu-clock) of one render on one thread, each sample's address
# looked up with its inlined calls (addr2line -i), since the kernels inline the traversals
# into a few large functions that a plain profile cannot tell apart. Prints each step's share
# of the samples and of the queries' samples:
#
#   lone walks           rays traced on alone: their node tests and stack (occluded_from*)
#   lone leaf tests      their triangle packets (packet_hits outside a closest-hit walk)
#   lone entries         their moves into a placed instance's frame (instance_blocks, local_ray)
#   packet walks         node and triangle tests of rays in lanes (occluded_packet, ...)
#   packet entries       packets' moves into an instance's frame (local_lanes)
#
#   scripts/profile-split.sh [--spp N] [--size WxH] BUILD SCENE [SCENE ...]
#
# BUILD is a hemi binary (its symbols and line tables kept, as the release profile keeps them),
# optionally preceded by comma-separated environment settings ('HEMI_NO_AVX512=1,BIN'); a
# SCENE is a peer-scene name. Defaults: 64 spp, the scene's own size. Needs perf and binutils.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
scenes_dir="$root/../shared/peers/scenes"
spp=64
size=""
args=()
while [ $# -gt 0 ]; do
    case "$1" in
        --spp) spp="$2"; shift 2 ;;
        --size) size="$2"; shift 2 ;;
        -h|--help) sed -n '2,18p' "$0"; exit 0 ;;
        *) args+=("$1"); shift ;;
    esac
done
[[ "$spp" =~ ^[1-9][0-9]*$ ]] || { echo "profile-split: --spp wants a whole number" >&2; exit 2; }
[ -z "$size" ] || [[ "$size" =~ ^[1-9][0-9]*x[1-9][0-9]*$ ]] || { echo "profile-split: --size wants WxH" >&2; exit 2; }
[ ${#args[@]} -ge 2 ] || { echo "profile-split: want a build and at least one scene (see --help)" >&2; exit 2; }
for tool in perf addr2line readelf; do
    command -v "$tool" >/dev/null || { echo "profile-split: $tool not found" >&2; exit 1; }
done

python3 - "$scenes_dir" "$spp" "$size" "${args[@]}" <<'PY'
import collections, os, re, subprocess, sys, tempfile

scenes_dir, spp, size, build, *scenes = sys.argv[1:]
*env, binary = build.split(",")
env = dict(e.split("=", 1) for e in env)
binary = os.path.realpath(binary)
if not (os.path.isfile(binary) and os.access(binary, os.X_OK)):
    sys.exit(f"profile-split: '{binary}' is not an executable hemi binary")
for scene in scenes:
    if not os.path.isfile(f"{scenes_dir}/{scene}.json"):
        sys.exit(f"profile-split: no peer scene '{scene}' in {scenes_dir}")
# Removed, with what the runs wrote there, when the script ends.
scratch = tempfile.TemporaryDirectory()
out = scratch.name

# Where the binary's code lies in its file: a sample's address, less the mapping's start, plus
# this, is the address addr2line knows.
segments = subprocess.run(["readelf", "-lW", binary], capture_output=True, text=True, check=True).stdout
code = re.search(r"LOAD\s+(0x[0-9a-f]+)\s+(0x[0-9a-f]+)\s+\S+\s+\S+\s+\S+\s+R E", segments)
if not code:
    sys.exit(f"profile-split: no executable segment in {binary}")
vaddr_past_offset = int(code.group(2), 16) - int(code.group(1), 16)

# Each step with the inlined functions that mark it; the first that matches an address's calls
# names its step. A single ray's triangle packets (`packet_hits`) count as a lone ray's leaf
# test unless a closest-hit walk (a camera ray's) called them.
STEPS = [
    ("lone leaf tests", lambda text: "packet_hits" in text and "closest" not in text),
    ("lone walks", lambda text: "occluded_from" in text),
    ("lone entries", lambda text: "instance_blocks" in text or "local_ray" in text),
    ("packet walks", lambda text: any(m in text for m in ("occluded_packet", "packets_block_lanes", "entry_node"))),
    ("packet entries", lambda text: "local_lanes" in text),
]

def step_of(chain):
    """The traversal step of an address whose inlined calls are `chain`, or None."""
    text = " ".join(chain)
    return next((step for step, marks in STEPS if marks(text)), None)

for scene in scenes:
    data = f"{out}/{scene}.data"
    cmd = [binary, "render", f"{scenes_dir}/{scene}.json", "--spp", spp, "--threads", "1", "--out", f"{out}/image.png"]
    if size:
        cmd += ["--size", size]
    done = subprocess.run(["perf", "record", "-q", "-e", "cpu-clock", "-F", "4000", "-o", data] + cmd,
                          env={**os.environ, **env}, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if done.returncode != 0:
        sys.exit(f"profile-split: the render of {scene} failed: {done.stderr.strip().splitlines()[-1:]}")
    lines = subprocess.run(["perf", "script", "-i", data, "-F", "ip,dso", "--show-mmap-events"],
                           capture_output=True, text=True, check=True).stdout.splitlines()
    base, total, samples = None, 0, collections.Counter()
    for line in lines:
        if "MMAP" in line:
            m = re.search(r"\[(0x[0-9a-f]+)\((0x[0-9a-f]+)\) @ (0x[0-9a-f]+) .*r-xp " + re.escape(binary), line)
            if m:
                base = int(m.group(1), 16) - int(m.group(3), 16) - vaddr_past_offset
            continue
        fields = line.split()
        if len(fields) < 2:
            continue
        total += 1
        if base is not None and binary in fields[1]:
            samples[int(fields[0], 16) - base] += 1
    if not total:
        sys.exit(f"profile-split: perf recorded no samples of {scene}")
    addresses = sorted(samples)
    looked_up = subprocess.run(["addr2line", "-a", "-i", "-f", "-C", "-e", binary] + [hex(a) for a in addresses],
                               capture_output=True, text=True, check=True).stdout.splitlines()
    chains, address = collections.defaultdict(list), None
    for line in looked_up:
        if re.fullmatch(r"0x[0-9a-f]+", line):
            address = int(line, 16)
        elif address is not None and not line.startswith(("/", "??:")):
            chains[address].append(line)
    steps = collections.Counter()
    for a in addresses:
        steps[step_of(chains[a])] += samples[a]
    queries = sum(v for k, v in steps.items() if k)
    print(f"{scene}: {total} samples, {100 * queries / total:.1f} % in occlusion queries")
    for step, _ in STEPS:
        print(f"  {step:16s} {100 * steps[step] / total:5.1f} % of the samples, "
              f"{100 * steps[step] / max(queries, 1):5.1f} % of the queries'")
PY
