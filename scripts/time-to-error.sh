#!/usr/bin/env bash
# Seconds to reach the error Mitsuba 3 reaches at 64 spp, on each peer scene: hemi (its default
# sampler, CMJ), Mitsuba 3 (llvm_ad_rgb, i.i.d. PCG32 samples) and native Embree 3 (best of its
# stream and packet modes, i.i.d. PCG hash samples), one after the other in one run.
#
#   scripts/time-to-error.sh [--threads N] [--spp N] [--max-spp N] [SCENE ...]   (default: all five)
#
# The target is the RMSE of Mitsuba's AO image at --spp (64) against the peers' 4096-spp Embree
# reference, over the reference's hit pixels (as `hemi compare` measures hemi's). Mitsuba's time
# is its AO kernel's (warm run). Native Embree renders --spp too; its time is scaled by
# (its RMSE / target)², the i.i.d. law, to the time at the target. hemi renders 1, 2, 4, …
# --max-spp (1024) spp until its RMSE (`hemi compare`) is at or below the target; its time is
# interpolated log-log between the two renders around the target, for its AO kernel time and for
# the whole trace stage (camera rays, AO, direct light and shading), from `--stats-json`.
# Scene load and acceleration build are left out for all three.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
peers_src="$root/../shared/peers"
threads=2
spp=64
max_spp=1024
scenes=()
while [ $# -gt 0 ]; do
    case "$1" in
        --threads) threads="$2"; shift 2 ;;
        --spp) spp="$2"; shift 2 ;;
        --max-spp) max_spp="$2"; shift 2 ;;
        -h|--help) sed -n '2,16p' "$0"; exit 0 ;;
        *) scenes+=("$1"); shift ;;
    esac
done
[ ${#scenes[@]} -gt 0 ] || scenes=(sphere_plane cornell many_spheres dragon sponza)
[ -d "$peers_src" ] || { echo "time-to-error: $peers_src not found (../shared must sit beside the repo)" >&2; exit 1; }

. "$root/scripts/peers-venv.sh"
. "$root/scripts/native-embree.sh"

(cd "$root" && cargo build --release -q)
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
. "$root/scripts/fresh-copy.sh"
hemi="$(fresh_copy "$root/target/release/hemi" "$out")"
json() { python3 -c "import json,sys; d=json.loads(sys.stdin.read().strip().splitlines()[-1]); print($1)"; }
# RMSE of an AO image (.ao.npy) against the scene's reference over the reference's hit pixels.
rmse() {
    "$work/.venv/bin/python" - "$peers_src/refs/$1" "$2" <<'PY'
import sys
import numpy as np
ref, stem = sys.argv[1:]
a, r, hit = np.load(stem + ".ao.npy").astype(np.float64), np.load(ref + ".ao.npy").astype(np.float64), np.load(ref + ".hit.npy")
print(float(np.sqrt(np.mean((a[hit] - r[hit]) ** 2))))
PY
}

printf '%-13s | %-9s | %-16s | %-24s | %-32s | %s\n' scene "target" "mitsuba: AO s" "native embree: AO s" "hemi: spp, AO s, trace s" "mitsuba / hemi, embree / hemi (AO s; trace s)"
for s in "${scenes[@]}"; do
    m_line=$(cd "$work" && .venv/bin/python mitsuba_ao.py "$peers_src/scenes/$s.json" --spp "$spp" --threads "$threads" \
        --repeat 2 --no-direct --no-png --out "$out/$s.mitsuba" 2>/dev/null | tail -1)
    target=$(rmse "$s" "$out/$s.mitsuba")
    m_ao=$(echo "$m_line" | json "d['ao_rays'] / d['ao_mrays_s'] / 1e6 if 'ao_rays' in d else d['ao_s']")
    e_line=$(native_best "$s" "$spp" "$threads" --out "$out/$s.native")
    e_rmse=$(rmse "$s" "$out/$s.native")
    e_ao=$(echo "$e_line" | json "d['ao_s'] * ($e_rmse / $target) ** 2")
    n=1
    : > "$out/$s.hemi"
    while [ "$n" -le "$max_spp" ]; do
        "$hemi" render "$peers_src/scenes/$s.json" --spp "$n" --threads "$threads" --out "$out/$s.png" \
            --stats-json "$out/$s.json" 2>/dev/null
        h_rmse=$("$hemi" compare "$peers_src/scenes/$s.json" --spp "$n" --threads "$threads" | awk 'NR == 2 { print $5 }')
        echo "$n $h_rmse $(json "d['total']['ao_seconds'], d['total']['trace_seconds']" < "$out/$s.json" | tr -d '(),')" >> "$out/$s.hemi"
        python3 -c "import sys; sys.exit(0 if $h_rmse <= $target else 1)" && break
        n=$((n * 2))
    done
    python3 - "$out/$s.hemi" "$s" "$target" "$m_ao" "$e_ao" "$e_rmse" <<'PY'
import math, sys
path, name, target, m_ao, e_ao, e_rmse = sys.argv[1], sys.argv[2], *map(float, sys.argv[3:])
runs = [tuple(map(float, l.split())) for l in open(path)]
def at_target(col):
    spp, err, t = runs[-1][0], runs[-1][1], runs[-1][col]
    if err > target:
        return None, None
    if len(runs) == 1:
        return spp, t
    (s0, e0, *r0), (s1, e1, *r1) = runs[-2], runs[-1]
    f = (math.log(target) - math.log(e0)) / (math.log(e1) - math.log(e0))
    lerp = lambda a, b: math.exp(math.log(a) + f * (math.log(b) - math.log(a)))
    return lerp(s0, s1), lerp(r0[col - 2], r1[col - 2])
spp, ao = at_target(2)
_, trace = at_target(3)
if ao is None:
    print(f"{name:13s} | {target:.3e} | {m_ao:10.3f} s     | hemi did not reach the target by {int(runs[-1][0])} spp")
else:
    print(f"{name:13s} | {target:.3e} | {m_ao:10.3f} s     | {e_ao:7.3f} s (rmse {e_rmse:.2e}) | "
          f"{spp:6.1f} spp {ao:7.3f} s {trace:7.3f} s | "
          f"{m_ao / ao:6.1f}x, {e_ao / ao:5.1f}x; {m_ao / trace:6.1f}x, {e_ao / trace:5.1f}x")
PY
done
echo "target: RMSE of Mitsuba's AO at $spp spp against the 4096-spp reference (hit pixels); times exclude load and build."
echo "mitsuba: AO kernel seconds (warm run); native embree: AO phase seconds of its best mode, scaled to the target by (rmse/target)^2;"
echo "hemi: AO kernel seconds and trace-stage seconds, interpolated log-log at the target between renders at powers of two spp."
